//! Balloons through the dynamically loaded `pressure` and `stretch` plugins.
//!
//! * **Volume** (issue 6, test 4): a closed icosphere (r = 10 cm, 162 vertices) on a soft
//!   membrane, with the `pressure` kind's hard volume constraint at pressure scale
//!   s ∈ {1, 1.5, 2}, settles at the volume the model predicts, `s · V_rest` — to 1e-9
//!   (the issue asks for 0.5 %), measured by this test from the positions, not by the
//!   plugin — and comes to rest.
//! * **Momentum** (test 7): a free balloon, unequal vertex masses, a random velocity field,
//!   inflated by the `gas` kind or the `pressure` kind, keeps its linear momentum to 1e-9
//!   relative: every pressure step moves vertex `i` by `wᵢ gᵢ Δλ` with `Σ gᵢ = 0` on a closed
//!   surface.
//! * **Degenerate meshes** (test 8): a sphere flattened to a disc (zero volume, with zero-area
//!   triangles where its two halves meet), a mesh with every vertex at one point, and a
//!   tetrahedron with collinear faces, under both kinds: no NaN, finite residuals and
//!   reports.

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// The enclosed volume of the object's triangles, `Σ a·(b × c) / 6` about its first vertex.
fn volume(sim: &Simulation, object: &str) -> f64 {
    let o = sim.object(object).expect("object");
    let x = sim.positions();
    let r = x[o.first as usize];
    o.triangles
        .iter()
        .map(|t| {
            let p = |k: usize| x[t[k] as usize] - r;
            p(0).dot(p(1).cross(p(2))) / 6.0
        })
        .sum()
}

fn stat(sim: &mut Simulation, name: &str) -> f64 {
    let reports = sim.reports().expect("reports");
    reports
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, v)| *v)
        .unwrap_or_else(|| panic!("no stat {name} in {reports:?}"))
}

fn balloon(pressure_scale: f64) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]
damping = 2.0

[[objects]]
name = "balloon"
mass = 0.05
[objects.sphere]
center = [0.0, 1.0, 0.0]
radius = 0.1
subdivisions = 2

[[constraints]]
kind = "stretch"
params = {{ compliance = 1e-2, compression_compliance = 1e-2 }}

[[constraints]]
kind = "pressure"
params = {{ pressure_scale = {pressure_scale} }}
"#
    )
}

#[test]
fn balloons_settle_at_pressure_scale_times_rest_volume() {
    let mut pressures = Vec::new();
    for s in [1.0, 1.5, 2.0] {
        let mut sim = simulation(&balloon(s), &[]);
        let rest = volume(&sim, "balloon");
        let mut history = Vec::new();
        for _ in 0..90 {
            sim.step_frame().expect("step");
            history.push(volume(&sim, "balloon"));
        }
        let v = *history.last().expect("frames");
        // The issue asks for 0.5 %; the volume is solved exactly along the line of each
        // correction and the pressure group runs last in each column, so the hard volume
        // holds to rounding.
        let error = (v / (s * rest) - 1.0).abs();
        assert!(error < 1e-9, "s = {s}: V/V_rest = {}", v / rest);
        // Settled: the volume no longer moves and the membrane is at rest.
        let drift = (history[59] / v - 1.0).abs();
        assert!(drift < 1e-4, "s = {s}: still moving by {drift}");
        assert!(
            sim.kinetic_energy() < 1e-6,
            "s = {s}: {} J",
            sim.kinetic_energy()
        );
        // The group's own residual says the same.
        let r = sim.residuals().expect("residuals")[1];
        assert!((r.max - error).abs() < 1e-9, "{r:?} vs {error}");
        pressures.push(stat(&mut sim, "pressure.applied_pressure"));
        println!(
            "s = {s}: V/(s V_rest) - 1 = {:+.3e}, applied gauge pressure {:.1} Pa",
            v / (s * rest) - 1.0,
            pressures.last().expect("pushed")
        );
    }
    // No pressure at the rest volume, more for more volume.
    assert!(pressures[0].abs() < 1e-9, "{pressures:?}");
    assert!(
        0.0 < pressures[1] && pressures[1] < pressures[2],
        "{pressures:?}"
    );
}

/// Marsaglia's xorshift64.
struct XorShift(u64);

impl XorShift {
    fn symmetric(&mut self, half: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        half * (2.0 * ((self.0 >> 11) as f64 / (1u64 << 53) as f64) - 1.0)
    }
}

fn momentum(sim: &Simulation) -> DVec3 {
    sim.velocities()
        .iter()
        .zip(&sim.particles.mass)
        .map(|(v, m)| *v * *m)
        .sum()
}

#[test]
fn a_free_balloons_pressure_conserves_linear_momentum() {
    for constraint in [
        r#"kind = "gas"
params = { start_pressure = 6000.0 }"#,
        r#"kind = "pressure"
params = { pressure_scale = 1.6 }"#,
        r#"kind = "pressure"
params = { compliance = 1e-4, pressure = 2000.0 }"#,
    ] {
        // Unequal masses: density lumped by the area around each vertex of a level-1
        // icosphere (its triangles differ in size).
        let text = format!(
            r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]

[[objects]]
name = "balloon"
density = 0.2
[objects.sphere]
center = [0.3, -0.2, 0.1]
radius = 0.15
subdivisions = 1

[[constraints]]
kind = "stretch"
params = {{ compliance = 1e-3, compression_compliance = 1e-3 }}

[[constraints]]
{constraint}
"#
        );
        let mut sim = simulation(&text, &[]);
        let masses = &sim.particles.mass;
        let (lo, hi) = masses
            .iter()
            .fold((f64::MAX, 0.0_f64), |(a, b), &m| (a.min(m), b.max(m)));
        assert!(hi > 1.1 * lo, "masses should differ: {lo} .. {hi}");
        let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
        for v in &mut sim.particles.v {
            *v = [
                0.4 + rng.symmetric(0.3),
                -0.2 + rng.symmetric(0.3),
                0.1 + rng.symmetric(0.3),
            ];
        }
        let p0 = momentum(&sim);
        let v0 = volume(&sim, "balloon");
        let mut worst = 0.0_f64;
        let mut inflation = 0.0_f64;
        for _ in 0..60 {
            sim.step_frame().expect("step");
            worst = worst.max((momentum(&sim) - p0).length() / p0.length());
            inflation = inflation.max(volume(&sim, "balloon") / v0 - 1.0);
        }
        // The pressure did work: the balloon swelled by several percent.
        assert!(
            inflation > 0.03,
            "{constraint}: inflated by only {inflation}"
        );
        assert!(
            worst < 1e-9,
            "{constraint}: momentum drifted by {worst:e} (relative)"
        );
        println!(
            "{}: inflated by {:.1} %, worst relative momentum drift {worst:.2e}",
            constraint.replace('\n', " "),
            100.0 * inflation
        );
    }
}

/// Runs `frames` frames and checks every position, residual and report is finite.
fn runs_finite(sim: &mut Simulation, frames: usize, what: &str) {
    for f in 0..frames {
        if let Err(e) = sim.step_frame() {
            panic!("{what}: frame {f}: {e}");
        }
        assert!(
            sim.positions().iter().all(|p| p.is_finite()),
            "{what}: frame {f}"
        );
        for r in sim.residuals().expect("residuals") {
            assert!(
                r.max.is_finite() && r.rms.is_finite() && r.energy.is_finite(),
                "{what}: {r:?}"
            );
        }
        for (name, value) in sim.reports().expect("reports") {
            assert!(value.is_finite(), "{what}: {name} = {value}");
        }
    }
}

/// Writes `positions` and `triangles` as an OBJ file and returns its path.
fn write_obj(tag: &str, positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> std::path::PathBuf {
    let path = temp_dir(tag).join("mesh.obj");
    let mut text = String::new();
    for p in positions {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(&path, text).expect("write obj");
    path
}

#[test]
fn degenerate_and_zero_volume_meshes_produce_no_nan() {
    let sphere = nucleus_core::shapes::icosphere([0.0, 0.0, 0.0], 0.1, 2);
    // Flattened to a disc: zero volume; each vertex meets its mirror image, so the
    // triangles across the equator have zero area.
    let disc: Vec<[f64; 3]> = sphere.positions.iter().map(|p| [p[0], 0.0, p[2]]).collect();
    // Every vertex at one point: zero area, zero volume, zero normals.
    let point = vec![[0.2, 0.3, 0.4]; sphere.positions.len()];
    // A tetrahedron whose four vertices are collinear.
    let line: Vec<[f64; 3]> = (0..4).map(|k| [0.1 * k as f64, 0.0, 0.0]).collect();
    let tet = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    let meshes = [
        ("disc", write_obj("pressure-disc", &disc, &sphere.triangles)),
        (
            "point",
            write_obj("pressure-point", &point, &sphere.triangles),
        ),
        ("line", write_obj("pressure-line", &line, &tet)),
    ];
    for (name, path) in &meshes {
        for constraint in [
            "kind = \"pressure\"\nparams = { pressure_scale = 1.5 }",
            "kind = \"pressure\"\nparams = { compliance = 1e-3, pressure = 500.0 }",
            "kind = \"gas\"\nparams = { start_pressure = 1000.0, pump_rate = 5.0 }",
            "kind = \"gas\"\nparams = { start_pressure = -500.0, incompressibility = 1000.0 }",
        ] {
            let text = format!(
                r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, -9.81, 0.0]

[[objects]]
name = "{name}"
mass = 0.05
[objects.mesh]
path = "{}"

[[constraints]]
kind = "stretch"
params = {{ compliance = 1e-3, compression_compliance = 1e-3 }}

[[constraints]]
{constraint}
"#,
                path.display()
            );
            let mut sim = simulation(&text, &[]);
            runs_finite(&mut sim, 20, &format!("{name} / {constraint}"));
        }
    }
}

#[test]
fn the_balloon_and_sail_scenes_run() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let build = |name: &str| {
        let scene = nucleus_core::Scene::load(&dir.join(name)).unwrap_or_else(|e| panic!("{e}"));
        Simulation::build(&scene, &registry(&[plugin_dir()])).unwrap_or_else(|e| panic!("{e}"))
    };
    // The pump inflates the balloon.
    let mut balloon = build("balloon.toml");
    let v0 = volume(&balloon, "balloon");
    runs_finite(&mut balloon, 20, "balloon.toml");
    assert!(volume(&balloon, "balloon") > 1.2 * v0);
    // The sail billows along +z, its normal.
    let mut sail = build("sail.toml");
    runs_finite(&mut sail, 20, "sail.toml");
    let z_max = sail
        .positions()
        .iter()
        .map(|p| p.z)
        .fold(f64::MIN, f64::max);
    assert!(z_max > 0.05, "{z_max}");
}
