//! Whole scenes in-process: the `pressure` and `gas` groups built by the core from scene text,
//! next to the real `stretch` plugin, stepped exactly as the host steps them. The quantitative
//! acceptance tests (balloon volumes, Boyle, pump and leak, momentum, degenerate meshes) go
//! through the dynamically loaded plugins in `tests/tests/pressure_*.rs`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};

use glam::DVec3;
use nucleus_core::error::BuildError;
use nucleus_core::{Registry, Simulation};
use nucleus_sdk::PluginError;

use crate::nucleus_plugin;

fn registry() -> Registry {
    let mut reg = Registry::default();
    reg.add_in_process(nucleus_plugin());
    reg.add_in_process(nucleus_stretch::nucleus_plugin());
    reg
}

fn simulation(text: &str) -> Simulation {
    Simulation::from_toml(text, &registry()).unwrap_or_else(|e| panic!("build: {e}"))
}

/// The plugin error a scene's build fails with.
fn build_error(text: &str) -> PluginError {
    match Simulation::from_toml(text, &registry()) {
        Ok(_) => panic!("the scene was accepted"),
        Err(BuildError::Plugin { error, .. }) => match *error {
            nucleus_core::error::PluginLoadError::Factory { error, .. } => *error,
            other => panic!("not a factory error: {other}"),
        },
        Err(e) => panic!("not a plugin error: {e}"),
    }
}

fn stat(sim: &mut Simulation, name: &str) -> f64 {
    let reports = sim.reports().expect("reports");
    reports
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, v)| *v)
        .unwrap_or_else(|| panic!("no stat {name} in {reports:?}"))
}

/// Writes an OBJ file to a fresh temporary path.
fn obj(tag: &str, positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> PathBuf {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let n = COUNTER.fetch_add(1, Ordering::SeqCst);
    let dir = std::env::temp_dir().join(format!("nucleus-pressure-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(format!("{tag}-{n}.obj"));
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

/// An object table for a mesh file.
fn mesh_object(name: &str, path: &std::path::Path, extra: &str) -> String {
    format!(
        "[[objects]]\nname = \"{name}\"\nmass = 0.05\n{extra}\n[objects.mesh]\npath = \"{}\"\n",
        path.display()
    )
}

const SOLVER: &str = r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]
damping = 2.0
"#;

const SPHERE: &str = r#"
[[objects]]
name = "balloon"
mass = 0.05
[objects.sphere]
center = [0.0, 1.0, 0.0]
radius = 0.1
subdivisions = 2
"#;

const SOFT_STRETCH: &str = r#"
[[constraints]]
kind = "stretch"
params = { compliance = 1e-2, compression_compliance = 1e-2 }
"#;

fn with(kind: &str, params: &str) -> String {
    format!("[[constraints]]\nkind = \"{kind}\"\nobjects = [\"balloon\"]\nparams = {params}\n")
}

#[test]
fn kinds_describe_themselves() {
    let info = nucleus_plugin().info();
    assert_eq!(info.name.as_str(), "pressure");
    let names: Vec<&str> = info.kinds.iter().map(|k| k.name.as_str()).collect();
    assert_eq!(names, ["pressure", "gas"]);
    for kind in info.kinds.iter() {
        assert_eq!(kind.default_order, crate::DEFAULT_ORDER);
        assert_eq!(kind.default_importance, 1);
        assert_eq!(kind.residual_unit.as_str(), "relative volume");
        for p in kind.params.iter() {
            assert!(!p.doc.is_empty(), "{} has no doc", p.name);
        }
    }
    let params = |k: usize| -> Vec<(String, String)> {
        info.kinds[k]
            .params
            .iter()
            .map(|p| (p.name.to_string(), p.default.to_string()))
            .collect()
    };
    let pairs = |v: &[(&str, &str)]| -> Vec<(String, String)> {
        v.iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect()
    };
    assert_eq!(
        params(0),
        pairs(&[
            ("pressure_scale", "1.0"),
            ("compliance", "0.0"),
            ("pressure", "0.0")
        ])
    );
    assert_eq!(
        params(1),
        pairs(&[
            ("start_pressure", "0.0"),
            ("pump_rate", "0.0"),
            ("air_tightness", "1.0"),
            ("incompressibility", "101325.0")
        ])
    );
}

#[test]
fn bad_parameters_are_rejected_naming_them() {
    let scene = |kind: &str, params: &str| format!("{SOLVER}{SPHERE}{}", with(kind, params));
    let bad =
        |kind: &str, params: &str| match Simulation::from_toml(&scene(kind, params), &registry()) {
            Ok(_) => panic!("{params} accepted"),
            Err(e) => e.to_string(),
        };
    for (kind, params, name) in [
        ("gas", "{ air_tightness = 1.5 }", "air_tightness"),
        ("gas", "{ incompressibility = 0.0 }", "incompressibility"),
        ("pressure", "{ pressure_scale = -1.0 }", "pressure_scale"),
        ("pressure", "{ compliance = -1e-6 }", "compliance"),
        ("pressure", "{ pressure_sclae = 2.0 }", "pressure_sclae"),
    ] {
        let e = bad(kind, params);
        assert!(e.contains(name), "{params}: {e}");
    }
    // Below vacuum: the factory refuses it, naming the parameter.
    let e = build_error(&scene(
        "gas",
        "{ incompressibility = 1000.0, start_pressure = -1000.0 }",
    ));
    assert_eq!(e.code, PluginError::BAD_PARAMETER);
    assert_eq!(e.subject.as_str(), "start_pressure");
}

/// A Möbius strip of `n` quads (`2n` vertices) around a circle of radius 1.
fn moebius(n: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut x = Vec::new();
    for k in 0..n {
        let t = std::f64::consts::TAU * k as f64 / n as f64;
        let centre = DVec3::new(t.cos(), 0.0, t.sin());
        let across = (DVec3::new(t.cos(), 0.0, t.sin()) * (t / 2.0).cos()
            + DVec3::Y * (t / 2.0).sin())
            * 0.2;
        x.push((centre - across).to_array());
        x.push((centre + across).to_array());
    }
    let mut t = Vec::new();
    for k in 0..n {
        let (a, b) = (2 * k, 2 * k + 1);
        let (c, d) = if k + 1 < n {
            (2 * k + 2, 2 * k + 3)
        } else {
            (1, 0)
        };
        t.push([a, c, d]);
        t.push([a, d, b]);
    }
    (x, t)
}

#[test]
fn a_moebius_strip_is_refused_naming_the_object() {
    let (x, t) = moebius(12);
    let path = obj("moebius", &x, &t);
    for kind in ["pressure", "gas"] {
        let text = format!(
            "{SOLVER}{}[[constraints]]\nkind = \"{kind}\"\n",
            mesh_object("strip", &path, "")
        );
        let e = build_error(&text);
        assert_eq!(e.code, PluginError::BAD_OBJECT);
        assert_eq!(e.subject.as_str(), "strip");
        assert!(e.message.contains("not orientable"), "{e}");
    }
}

#[test]
fn a_non_manifold_mesh_is_refused_naming_the_object() {
    let x = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let path = obj("fin", &x, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]]);
    let text = format!(
        "{SOLVER}{}[[constraints]]\nkind = \"pressure\"\n",
        mesh_object("fins", &path, "")
    );
    let e = build_error(&text);
    assert_eq!(e.subject.as_str(), "fins");
    assert!(e.message.contains("not manifold"), "{e}");
}

#[test]
fn objects_without_triangles_are_skipped_and_shells_are_chambers() {
    let text = format!(
        r#"{SOLVER}{SPHERE}
[[objects]]
name = "rope"
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [1.0, 0.0, 0.0]
segments = 4

[[objects]]
name = "twin"
[objects.sphere]
center = [1.0, 1.0, 0.0]
radius = 0.2
subdivisions = 1

[[constraints]]
kind = "gas"
"#
    );
    let mut sim = simulation(&text);
    assert_eq!(sim.groups[0].len, 2, "two spheres, no rope");
    // The reported volume is the sum of both polyhedra's.
    let v = stat(&mut sim, "gas.volume");
    let expected = polyhedron_volume(icosphere(0.1, 2)) + polyhedron_volume(icosphere(0.2, 1));
    assert!((v - expected).abs() < 1e-12 * expected, "{v} vs {expected}");
}

/// The icosphere of the core, as (positions, triangles).
fn icosphere(radius: f64, subdivisions: u32) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let g = nucleus_core::shapes::icosphere([0.0, 0.0, 0.0], radius, subdivisions);
    (g.positions, g.triangles)
}

/// `Σ a·(b × c) / 6` over the triangles.
fn polyhedron_volume((x, t): (Vec<[f64; 3]>, Vec<[u32; 3]>)) -> f64 {
    let p = |i: u32| DVec3::from_array(x[i as usize]);
    t.iter()
        .map(|&[a, b, c]| p(a).dot(p(b).cross(p(c))) / 6.0)
        .sum()
}

#[test]
fn an_inward_wound_closed_mesh_is_turned_outward() {
    // The sphere wound inward, with every other triangle flipped back: inconsistent and
    // inside out. The chamber is oriented through the complex and turned outward, so a
    // pressure scale of 1.3 inflates it.
    let (x, mut t) = icosphere(0.1, 2);
    for (k, tri) in t.iter_mut().enumerate() {
        if k % 2 == 0 {
            tri.swap(1, 2);
        }
    }
    let path = obj("inside-out", &x, &t);
    let text = format!(
        "{SOLVER}{}{SOFT_STRETCH}{}",
        mesh_object("balloon", &path, ""),
        with("pressure", "{ pressure_scale = 1.3 }")
    );
    let mut sim = simulation(&text);
    let v0 = stat(&mut sim, "pressure.volume");
    assert!(v0 > 0.9 * 4.0 / 3.0 * std::f64::consts::PI * 1e-3, "{v0}");
    for _ in 0..30 {
        sim.step_frame().expect("step");
    }
    let v = stat(&mut sim, "pressure.volume");
    assert!((v / v0 - 1.3).abs() < 1e-9, "{}", v / v0);
    assert!(stat(&mut sim, "pressure.applied_pressure") > 0.0);
}

#[test]
fn a_tet_solid_keeps_its_volume_under_gravity() {
    // A soft tet block pinned at its bottom sags under gravity; a hard volume constraint on
    // its boundary faces (the chamber of a solid) keeps its volume, which without it drops.
    let scene = |pressure: bool| {
        format!(
            r#"
[solver]
frame_rate = 60.0
substeps = 10
damping = 1.0

[[objects]]
name = "block"
mass = 1.0
pins = [{{ min = [-1.0, -0.01, -1.0], max = [1.0, 0.01, 1.0] }}]
[objects.tet_box]
min = [0.0, 0.0, 0.0]
max = [0.2, 0.4, 0.2]
resolution = [2, 4, 2]

[[constraints]]
kind = "stretch"
params = {{ compliance = 1e-2, compression_compliance = 1e-2 }}
{}"#,
            if pressure {
                "[[constraints]]\nkind = \"pressure\"\n"
            } else {
                ""
            }
        )
    };
    let volume_ratio = |pressure: bool| {
        let mut sim = simulation(&scene(pressure));
        let obj = sim.object("block").expect("block").clone();
        let volume = |sim: &Simulation| {
            let x = sim.positions();
            obj.tets
                .iter()
                .map(|t| {
                    let p = |i: u32| x[i as usize];
                    (p(t[1]) - p(t[0]))
                        .cross(p(t[2]) - p(t[0]))
                        .dot(p(t[3]) - p(t[0]))
                        / 6.0
                })
                .sum::<f64>()
        };
        let v0 = volume(&sim);
        for _ in 0..30 {
            sim.step_frame().expect("step");
        }
        volume(&sim) / v0
    };
    let free = volume_ratio(false);
    let kept = volume_ratio(true);
    assert!(
        free < 0.98,
        "the block should lose volume without pressure: {free}"
    );
    assert!((kept - 1.0).abs() < 1e-9, "{kept}");
}

#[test]
fn a_hard_volume_constraint_holds_its_target_and_the_balloons_momentum() {
    let text = format!(
        "{SOLVER}{}{SOFT_STRETCH}{}",
        SPHERE.replace("mass = 0.05", "mass = 0.05\nvelocity = [0.5, -0.2, 0.1]"),
        with("pressure", "{ pressure_scale = 1.5 }")
    )
    .replace("damping = 2.0", "damping = 0.0");
    let mut sim = simulation(&text);
    let momentum = |sim: &Simulation| -> DVec3 {
        sim.velocities()
            .iter()
            .zip(&sim.particles.mass)
            .map(|(v, m)| *v * *m)
            .sum()
    };
    let v0 = stat(&mut sim, "pressure.volume");
    let p0 = momentum(&sim);
    for _ in 0..20 {
        sim.step_frame().expect("step");
        let p = momentum(&sim);
        assert!((p - p0).length() < 1e-12 * p0.length(), "{p} vs {p0}");
    }
    let v = stat(&mut sim, "pressure.volume");
    assert!((v / v0 - 1.5).abs() < 1e-9, "{}", v / v0);
    let r = sim.residuals().expect("residuals")[1];
    assert_eq!(r.count, 1);
    assert!(
        (r.max - (v / (1.5 * v0) - 1.0).abs()).abs() < 1e-12,
        "{r:?}"
    );
    assert_eq!(r.energy, 0.0, "a hard constraint stores no energy");
}

#[test]
fn a_compliant_volume_settles_where_the_membrane_balances_it() {
    // With compliance, the chamber is a spring on its volume: the applied gauge pressure is
    // (V_target + α p − V)/α at any moment, and the membrane pushes back with it.
    let text = format!(
        "{SOLVER}{SPHERE}{SOFT_STRETCH}{}",
        with(
            "pressure",
            "{ pressure_scale = 1.0, compliance = 1e-3, pressure = 200.0 }"
        )
    );
    let mut sim = simulation(&text);
    let v0 = stat(&mut sim, "pressure.volume");
    for _ in 0..90 {
        sim.step_frame().expect("step");
    }
    let v = stat(&mut sim, "pressure.volume");
    let applied = stat(&mut sim, "pressure.applied_pressure");
    let alpha = 1e-3 * v0;
    let spring = (v0 + alpha * 200.0 - v) / alpha;
    assert!(v > 1.02 * v0 && v < v0 * 1.2, "{}", v / v0);
    assert!(
        (applied - spring).abs() < 1e-6 * spring,
        "{applied} vs {spring}"
    );
    // The stored energy is ½ C²/α.
    let r = sim.residuals().expect("residuals")[1];
    let c = v - v0 - alpha * 200.0;
    assert!(
        (r.energy - 0.5 * c * c / alpha).abs() < 1e-9 * r.energy,
        "{r:?}"
    );
}

/// A free square sheet of side 1 m in the xz plane, normals +y.
fn sheet(params: &str, pins: &str) -> String {
    format!(
        r#"{SOLVER}
[[objects]]
name = "sail"
mass = 0.2
{pins}
[objects.grid]
size = [1.0, 1.0]
resolution = [9, 9]
plane = "xz"

[[constraints]]
kind = "stretch"

[[constraints]]
kind = "pressure"
params = {params}
"#
    )
}

#[test]
fn an_open_sheet_is_pushed_with_pressure_times_area() {
    // A free flat sheet: Σ gᵢ = A n (its vector area), so each substep adds h p A n to its
    // momentum. The grid's triangles are wound so n = U × V = x × z = −y.
    let mut sim =
        simulation(&sheet("{ pressure = 3.0 }", "").replace("damping = 2.0", "damping = 0.0"));
    assert!(sim.groups[1].stages.contains(nucleus_sdk::Stages::FORCE));
    let momentum = |sim: &Simulation| -> DVec3 {
        sim.velocities()
            .iter()
            .zip(&sim.particles.mass)
            .map(|(v, m)| *v * *m)
            .sum()
    };
    let push = DVec3::new(0.0, -3.0, 0.0) * sim.h();
    sim.substep(0).expect("substep");
    assert!((momentum(&sim) - push).length() < 1e-12 * push.length());
    // Then the sheet starts to curve (its edges get less push than its middle), and its
    // vector area shrinks at second order.
    sim.substep(1).expect("substep");
    sim.substep(2).expect("substep");
    let p = momentum(&sim);
    assert!(
        (p - 3.0 * push).length() < 1e-6 * p.length(),
        "{p} vs {}",
        3.0 * push
    );
    // No volume constraint on an open chamber: no residual.
    assert_eq!(sim.residuals().expect("residuals")[1].count, 0);
}

#[test]
fn a_sail_billows_to_the_side_its_pressure_says() {
    for (pressure, sign) in [(20.0, -1.0), (-20.0, 1.0)] {
        let mut sim = simulation(&sheet(
            &format!("{{ pressure = {pressure} }}"),
            "pins = [\"edge:row0\", \"edge:rowN\"]",
        ));
        for _ in 0..30 {
            sim.step_frame().expect("step");
        }
        // The middle of the sail moved along the pushed side; the pins did not.
        let mid = sim.positions()[40];
        assert!(mid.y * sign > 0.02, "pressure {pressure}: {mid}");
        assert_eq!(sim.positions()[0], DVec3::ZERO);
    }
}

#[test]
fn the_gas_pump_adds_exactly_its_rate_and_reports_the_state() {
    let text = format!(
        "{SOLVER}{SPHERE}{SOFT_STRETCH}{}",
        with("gas", "{ start_pressure = 100.0, pump_rate = 20.0 }")
    );
    let mut sim = simulation(&text);
    let n0 = stat(&mut sim, "gas.amount");
    let v0 = stat(&mut sim, "gas.volume");
    assert!((n0 - (101_325.0 + 100.0) * v0).abs() < 1e-9 * n0);
    for _ in 0..12 {
        sim.step_frame().expect("step");
    }
    let n = stat(&mut sim, "gas.amount");
    assert!((n - n0 - 20.0 * 0.2).abs() < 1e-9 * n0, "{}", n - n0);
    let v = stat(&mut sim, "gas.volume");
    let p = stat(&mut sim, "gas.pressure");
    assert!((p - n / v).abs() < 1e-9 * p);
    assert!((stat(&mut sim, "gas.gauge_pressure") - (p - 101_325.0)).abs() < 1e-6);
    assert_eq!(stat(&mut sim, "gas.open_area"), 0.0);
    // A closed chamber never leaks, whatever its air tightness.
    let leaky = format!(
        "{SOLVER}{SPHERE}{SOFT_STRETCH}{}",
        with("gas", "{ start_pressure = 100.0, air_tightness = 0.0 }")
    );
    let mut sim = simulation(&leaky);
    let n0 = stat(&mut sim, "gas.amount");
    sim.step_frame().expect("step");
    assert_eq!(stat(&mut sim, "gas.amount"), n0);
}

#[test]
fn runs_are_bit_identical() {
    let text = format!(
        "{SOLVER}{SPHERE}{SOFT_STRETCH}{}",
        with(
            "gas",
            "{ start_pressure = 300.0, incompressibility = 5000.0 }"
        )
    );
    let run = || {
        let mut sim = simulation(&text);
        for _ in 0..10 {
            sim.step_frame().expect("step");
        }
        sim.particles
            .x
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(run(), run());
}

#[test]
fn a_state_too_small_for_the_group_is_an_error_not_a_panic() {
    let text = format!(
        "{SOLVER}{SPHERE}{}",
        with("gas", "{ start_pressure = 300.0 }")
    );
    let mut sim = simulation(&text);
    let group = &mut sim.groups[0].group;
    let mut state =
        nucleus_sdk::testing::CoreState::at_rest(vec![[0.0; 3]; 4], vec![1.0; 4], 1.0 / 600.0);
    let mut ctx = state.ctx();
    for e in [
        group.force(&mut ctx).into_result(),
        group.project(&mut ctx).into_result(),
    ] {
        assert_eq!(e.expect_err("ran").code, PluginError::FAILED);
    }
}

#[test]
fn gas_in_a_flat_open_sheet_stays_finite_and_leaks_to_ambient() {
    // A flat sail has no capped volume: the gas sits at the volume floor, its opening is the
    // whole sheet, and with air tightness 0.5 it leaks to ambient without NaN or overshoot.
    let text = format!(
        r#"{SOLVER}
[[objects]]
name = "sail"
mass = 0.2
pins = ["edge:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [6, 6]

[[constraints]]
kind = "stretch"

[[constraints]]
kind = "gas"
params = {{ start_pressure = 1000.0, air_tightness = 0.5 }}
"#
    );
    let mut sim = simulation(&text);
    assert!((stat(&mut sim, "gas.open_area") - 1.0).abs() < 1e-12);
    for _ in 0..30 {
        sim.step_frame().expect("step");
        assert!(sim.positions().iter().all(|p| p.is_finite()));
    }
    let gauge = stat(&mut sim, "gas.gauge_pressure");
    assert!(gauge.is_finite() && gauge.abs() < 1.0, "{gauge}");
}
