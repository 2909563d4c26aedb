//! The rest state is an equilibrium, through the dynamically loaded `bend` and `stretch`
//! plugins: without gravity, a curve (a rope laid out as a V, so one joint is bent at rest),
//! a flat cloth and a cloth pre-folded by 90° (`tests/data/bend/folded_90.obj`) start at their
//! rest shape and must stay there — zero residual and zero motion for 1,000 substeps — under
//! every kind of the plugin with stiff compliances (where a wrong rest angle would show
//! most). Rest angles come from the rest shape, so nothing may move.

use std::path::PathBuf;

use nucleus_tests::*;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data/bend")
        .join(name)
}

#[test]
fn curve_flat_cloth_and_pre_folded_cloth_stay_at_rest_for_1000_steps() {
    let folded = data("folded_90.obj");
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]

[[objects]]
name = "rope"
mass = 0.2
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [1.0, 0.0, 0.0]
segments = 20
length = 1.4

[[objects]]
name = "cloth"
mass = 1.0
[objects.grid]
size = [1.0, 1.0]
resolution = [16, 16]
origin = [2.0, 0.0, 0.0]

[[objects]]
name = "folded"
mass = 0.5
[objects.mesh]
path = {folded:?}
translate = [4.0, 0.0, 0.0]

[[constraints]]
kind = "stretch"

[[constraints]]
kind = "bend"
params = {{ compliance = 1e-4 }}

[[constraints]]
kind = "bend_isometric"
objects = ["cloth"]
params = {{ compliance = 1e-4 }}

[[constraints]]
kind = "shear"

[[constraints]]
kind = "twist"
objects = ["rope"]
params = {{ compliance = 1e-4 }}
"#
    );
    let mut sim = simulation(&text, &[]);
    let names: Vec<&str> = sim.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(
        names,
        ["stretch", "bend", "bend_isometric", "shear", "twist"]
    );
    // Every group has work to do except twist: each chain of four points of the V rope
    // contains three collinear points, so none has a rest plane.
    for g in &sim.groups[..4] {
        assert!(g.len > 0, "{} is empty", g.name);
    }
    let rest = sim.particles.x.clone();
    let frames = 100; // × 10 substeps = 1,000 steps
    for _ in 0..frames {
        sim.step_frame().expect("step");
    }
    let moved = sim
        .particles
        .x
        .iter()
        .zip(&rest)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(moved < 1e-12, "the rest shape moved by {moved} m");
    let residuals = sim.residuals().expect("residuals");
    for (g, r) in sim.groups.iter().zip(residuals) {
        assert!(r.max < 1e-12 && r.energy < 1e-12, "{}: {r:?}", g.name);
    }
}
