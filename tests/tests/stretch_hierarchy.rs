//! The `stretch_hierarchy` kind through the loaded plugin: it lowers the strain of a hanging
//! cloth at a given substep count, conserves linear momentum, and — with its default path
//! lengths — never resists an isometric motion of a folded rest shape (unfolding it), where
//! straight lengths do.

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// The drape of `scenes/drape.toml` at `n × n`, 10 substeps, with `extra` constraint tables.
fn drape(n: u32, frames: u32, extra: &str) -> Simulation {
    let constraints = format!("[[constraints]]\nkind = \"stretch\"\n{extra}");
    simulation(&drape_text(n, frames, 10, 1, &constraints), &[])
}

/// Mean over the last half of the frames of the stretch group's RMS strain.
fn mean_rms_strain(mut sim: Simulation) -> f64 {
    mean_rms_residual(&mut sim, 0, |_, _| {})
}

#[test]
fn on_a_hanging_cloth_the_hierarchy_lowers_the_strain() {
    let hierarchy = "[[constraints]]\nkind = \"stretch_hierarchy\"\n";
    let straight =
        "[[constraints]]\nkind = \"stretch_hierarchy\"\nparams = { straight_lengths = true }\n";
    let plain = mean_rms_strain(drape(32, 60, ""));
    let path = mean_rms_strain(drape(32, 60, hierarchy));
    let line = mean_rms_strain(drape(32, 60, straight));
    println!("32x32 drape, 10 substeps x 1 pass, mean RMS strain over the last 30 frames: plain {plain:.5}, hierarchy (path lengths) {path:.5}, (straight lengths) {line:.5}");
    assert!(path < 0.8 * plain, "path lengths: {path} vs {plain}");
    assert!(line < 0.5 * plain, "straight lengths: {line} vs {plain}");
}

#[test]
fn the_hierarchy_conserves_linear_momentum() {
    // A free 12 x 12 cloth, no gravity, pseudo-random velocities: every coarse correction and
    // the interpolation it drags along move mass-weighted sums by zero.
    let text = r#"
[solver]
substeps = 2
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "cloth"
density = 0.3
[objects.grid]
size = [1.0, 0.8]
resolution = [12, 12]
origin = [-0.5, 0.0, -0.4]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "stretch_hierarchy"
params = { coarsest = 4 }
"#;
    let mut sim = simulation(text, &[]);
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for v in sim.particles.v.iter_mut() {
        *v = [0.3 + noise(), 0.1 + noise(), -0.2 + noise()];
    }
    let momentum = |sim: &Simulation| -> DVec3 {
        sim.velocities()
            .iter()
            .zip(&sim.particles.mass)
            .map(|(&v, &m)| m * v)
            .sum()
    };
    let p0 = momentum(&sim);
    let mut worst = 0.0_f64;
    for _ in 0..250 {
        sim.step_frame().expect("step");
        worst = worst.max((momentum(&sim) - p0).length() / p0.length());
    }
    // The hierarchy really acted: its coarse edges exist and were stretched at the start.
    assert!(sim.groups[1].len > 0);
    assert!(worst < 1e-12, "linear momentum drifted by {worst:e}");
}

/// OBJ text of a 9 × 9 grid of 0.1 m cells in the xz plane, folded 90° up along x = 0.4:
/// vertices with x > 0.4 rise along y instead.
fn folded_obj() -> String {
    let mut s = String::new();
    for i in 0..9 {
        for j in 0..9 {
            let (x, z) = (0.1 * j as f64, 0.1 * i as f64);
            let (x, y) = if x > 0.4 { (0.4, x - 0.4) } else { (x, 0.0) };
            s += &format!("v {x} {y} {z}\n");
        }
    }
    for i in 0..8 {
        for j in 0..8 {
            let a = i * 9 + j + 1;
            s += &format!(
                "f {} {} {}\nf {} {} {}\n",
                a,
                a + 1,
                a + 10,
                a,
                a + 10,
                a + 9
            );
        }
    }
    s
}

/// The largest distance any particle moves in one substep when a folded rest shape starts
/// unfolded flat, at rest, without gravity, under `stretch_hierarchy` alone.
fn unfolding_motion(params: &str) -> f64 {
    let dir = temp_dir("hierarchy-fold");
    std::fs::write(dir.join("folded.obj"), folded_obj()).unwrap();
    let text = format!(
        r#"
[solver]
substeps = 1
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "sheet"
[objects.mesh]
path = "folded.obj"
[[constraints]]
kind = "stretch_hierarchy"
params = {params}
"#
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let scene = nucleus_core::Scene::load(&path).expect("scene");
    let mut sim = Simulation::build(&scene, &registry(&[plugin_dir()])).expect("build");
    let flat: Vec<[f64; 3]> = (0..81)
        .map(|k| [0.1 * (k % 9) as f64, 0.0, 0.1 * (k / 9) as f64])
        .collect();
    sim.particles.x = flat.clone();
    sim.particles.x0 = flat.clone();
    sim.step_frame().expect("step");
    sim.positions()
        .iter()
        .zip(&flat)
        .map(|(x, f)| x.distance(DVec3::from_array(*f)))
        .fold(0.0, f64::max)
}

#[test]
fn path_lengths_let_a_folded_rest_shape_unfold_where_straight_lengths_hold_it() {
    // Unfolding is isometric: every rest path keeps its length, so no coarse edge is
    // stretched and nothing moves (to rounding).
    let path = unfolding_motion("{ coarsest = 4 }");
    assert!(
        path < 1e-12,
        "path lengths resisted unfolding: moved {path} m"
    );
    // Straight rest lines across the fold are shorter than the unfolded distances.
    let straight = unfolding_motion("{ coarsest = 4, straight_lengths = true }");
    assert!(
        straight > 1e-3,
        "straight lengths did not act: moved {straight} m"
    );
}
