//! A pre-folded cloth keeps its fold, through the dynamically loaded `bend` and `stretch`
//! plugins. `tests/data/bend/folded_90.obj` is a 0.5 m × 1 m cloth of 1 kg folded by 90° along
//! a line: panel A stands vertical, panel B sticks out horizontally from its top edge. Panel
//! A is held (every vertex below the fold line is pinned; the fold line itself is free) and
//! gravity pulls panel B down, so every hinge along the fold carries B's weight.
//!
//! * At high bend stiffness (α = 1e-3 rad/(N·m)) every hinge along the fold stays within 2° of
//!   its rest angle of 90° (0.74° measured with 20 substeps × 4 passes; the compliance alone
//!   would allow 0.01°, the rest is Gauss-Seidel's unconverged sag), and the flap keeps
//!   sticking out.
//! * The test can fail: at a soft, silk-like compliance the same flap droops far past 2°.

use std::path::PathBuf;

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// The signed dihedral angle of the hinge `x = [i, j, k, l]` (axis i→j, wings k and l).
fn dihedral(x: [DVec3; 4]) -> f64 {
    let e = x[1] - x[0];
    let n1 = e.cross(x[2] - x[0]);
    let n2 = (x[3] - x[0]).cross(e);
    (n1.cross(n2).dot(e) / e.length()).atan2(n1.dot(n2))
}

fn folded(compliance: f64) -> Simulation {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/bend/folded_90.obj");
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 20
iterations = 4
gravity = [0.0, -9.81, 0.0]
damping = 2.0

[[objects]]
name = "folded"
mass = 1.0
pins = [{{ min = [-1.0, -1.0, -0.01], max = [1.0, 0.49, 0.01] }}]
[objects.mesh]
path = {path:?}

[[constraints]]
kind = "stretch"

[[constraints]]
kind = "bend"
params = {{ compliance = {compliance:?} }}
"#
    );
    simulation(&text, &[])
}

/// The hinges along the fold (both axis vertices on the line y = 0.5, z = 0 at rest), as
/// `[i, j, k, l]` global indices.
fn fold_hinges(sim: &Simulation) -> Vec<[usize; 4]> {
    let rest = &sim.particles.rest;
    let on_fold = |i: u32| {
        let p = rest[i as usize];
        (p[1] - 0.5).abs() < 1e-9 && p[2].abs() < 1e-9
    };
    sim.objects[0]
        .triangle_pairs
        .iter()
        .filter(|p| on_fold(p.edge[0]) && on_fold(p.edge[1]))
        .map(|p| [p.edge[0], p.edge[1], p.opposite[0], p.opposite[1]].map(|i| i as usize))
        .collect()
}

/// The largest change of the fold's hinge angles from their rest value (rad, wrapped), and
/// the rest value.
fn fold_change(sim: &Simulation, hinges: &[[usize; 4]]) -> (f64, f64) {
    let angle = |x: &[[f64; 3]], h: &[usize; 4]| dihedral(h.map(|i| DVec3::from_array(x[i])));
    let mut worst: f64 = 0.0;
    let mut rest_angle = 0.0;
    for h in hinges {
        let rest = angle(&sim.particles.rest, h);
        let now = angle(&sim.particles.x, h);
        let d = (now - rest + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        worst = worst.max(d.abs());
        rest_angle = rest;
    }
    (worst, rest_angle)
}

#[test]
fn pre_folded_cloth_keeps_its_fold_within_two_degrees_at_high_bend_stiffness() {
    let mut sim = folded(1e-3);
    let hinges = fold_hinges(&sim);
    assert_eq!(hinges.len(), 10, "one hinge per cell along the 0.5 m fold");
    let (_, rest) = fold_change(&sim, &hinges);
    assert!(
        (rest.abs() - std::f64::consts::FRAC_PI_2).abs() < 1e-9,
        "the rest fold is 90°: {}",
        rest.to_degrees()
    );
    let mut worst: f64 = 0.0;
    for _ in 0..120 {
        sim.step_frame().expect("step");
        worst = worst.max(fold_change(&sim, &hinges).0);
    }
    assert!(
        worst < 2f64.to_radians(),
        "the fold opened by {:.2}°",
        worst.to_degrees()
    );
    // Panel B still sticks out: its far edge (z = 0.5 at rest) is still near y = 0.5.
    let x = sim.positions();
    let far_edge_drop = sim
        .particles
        .rest
        .iter()
        .zip(x)
        .filter(|(r, _)| (r[2] - 0.5).abs() < 1e-9)
        .map(|(r, p)| r[1] - p.y)
        .fold(0.0, f64::max);
    assert!(
        far_edge_drop < 0.05,
        "the flap's far edge dropped {far_edge_drop} m"
    );
}

#[test]
fn a_soft_fold_droops_past_two_degrees() {
    let mut sim = folded(1e5);
    let hinges = fold_hinges(&sim);
    for _ in 0..60 {
        sim.step_frame().expect("step");
    }
    let (worst, _) = fold_change(&sim, &hinges);
    assert!(
        worst > 10f64.to_radians(),
        "only {:.2}°",
        worst.to_degrees()
    );
}
