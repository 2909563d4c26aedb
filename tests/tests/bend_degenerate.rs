//! Degenerate geometry never produces NaN or infinity, through the dynamically loaded `bend`
//! and `stretch` plugins: 1,000 substeps under gravity (the host checks every position and
//! velocity after every plugin call and stops the run on the first non-finite value) with
//!
//! * collinear edges: a straight rope under `bend` and `twist` — every joint angle is π, where
//!   the plane to bend in is undefined, and no chain has a twist plane;
//! * zero-area triangles and coincident vertices in the rest shape
//!   (`tests/data/bend/degenerate.obj`: a triangle with a vertex on its opposite edge, one with
//!   two vertices at the same point, and a sliver 1e-13 m high) under every kind;
//! * every vertex of a cloth and a rope collapsed onto one point while running.
//!
//! Degenerate constraints are skipped for the pass (reported as `skipped`) or, when the rest
//! shape itself is degenerate, never built (reported as `dropped`).

use std::path::PathBuf;

use nucleus_core::Simulation;
use nucleus_tests::*;

const KINDS: &str = r#"
[[constraints]]
kind = "stretch"

[[constraints]]
kind = "bend"
params = { compliance = 0.0 }

[[constraints]]
kind = "bend_isometric"
params = { compliance = 0.0 }

[[constraints]]
kind = "shear"

[[constraints]]
kind = "twist"
params = { compliance = 0.0 }
"#;

fn run_1000_steps(sim: &mut Simulation) {
    assert!(sim.settings.check_finite);
    for frame in 0..100 {
        if let Err(e) = sim.step_frame() {
            panic!("frame {frame}: {e}");
        }
    }
    assert!(sim
        .particles
        .x
        .iter()
        .chain(&sim.particles.v)
        .flatten()
        .all(|c| c.is_finite()));
    for r in sim.residuals().expect("residuals") {
        assert!(
            r.max.is_finite() && r.rms.is_finite() && r.energy.is_finite(),
            "{r:?}"
        );
    }
}

fn stat(sim: &mut Simulation, key: &str) -> f64 {
    sim.reports()
        .expect("reports")
        .into_iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("no {key}"))
        .1
}

#[test]
fn collinear_edges_produce_no_nan_over_1000_steps() {
    let text = format!(
        r#"
[solver]
substeps = 10
[[objects]]
name = "rope"
pins = ["start"]
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [0.0, -1.0, 0.0]
segments = 10
{KINDS}"#
    );
    let mut sim = simulation(&text, &[]);
    run_1000_steps(&mut sim);
    // The rope hangs straight down: every joint stays collinear, so every bend angle is
    // skipped (and is satisfied: C = φ − π = 0).
    assert_eq!(stat(&mut sim, "bend.skipped"), 9.0);
    assert_eq!(stat(&mut sim, "twist.dropped"), 8.0);
}

#[test]
fn zero_area_triangles_and_coincident_vertices_produce_no_nan_over_1000_steps() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/bend/degenerate.obj");
    let text = format!(
        r#"
[solver]
substeps = 10
[[objects]]
name = "junk"
mass = 0.1
pins = [{{ min = [-0.1, -0.1, -0.1], max = [1.1, 0.1, 0.1] }}]
[objects.mesh]
path = {path:?}
{KINDS}"#
    );
    let mut sim = simulation(&text, &[]);
    // Hinges with a zero-area or coincident-vertex triangle have no rest angle.
    assert!(stat(&mut sim, "bend.dropped") >= 2.0);
    assert!(stat(&mut sim, "bend_isometric.dropped") >= 2.0);
    run_1000_steps(&mut sim);
}

#[test]
fn a_cloth_and_a_rope_collapsed_onto_one_point_produce_no_nan_over_1000_steps() {
    let text = format!(
        r#"
[solver]
substeps = 10
[[objects]]
name = "cloth"
[objects.grid]
size = [1.0, 1.0]
resolution = [8, 8]
[[objects]]
name = "rope"
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [1.0, 0.0, 0.0]
segments = 8
{KINDS}"#
    );
    let mut sim = simulation(&text, &[]);
    for x in sim.particles.x.iter_mut() {
        *x = [0.25, 0.5, -0.125];
    }
    run_1000_steps(&mut sim);
    // Gravity moves every particle alike: they are still one point, every constraint of
    // every bend kind is skipped, and nothing else happened.
    for (name, g) in [("bend", 1), ("bend_isometric", 2), ("shear", 3)] {
        let len = sim.groups[g].len as f64;
        assert!(len > 0.0);
        assert_eq!(stat(&mut sim, &format!("{name}.skipped")), len, "{name}");
    }
}
