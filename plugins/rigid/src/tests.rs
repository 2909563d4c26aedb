//! The `rigid` group in-process, exactly as the host drives it: whole scenes built by
//! `nucleus_core` with this plugin registered in-process (the same validation, adapter and
//! step as a dynamically loaded plugin), plus the factory's errors.

use glam::{DQuat, DVec3};
use nucleus_core::{Registry, Simulation};
use nucleus_sdk::prelude::*;
use nucleus_sdk::Stage;

use crate::{nucleus_plugin, RigidParams, REPORT_COLUMNS};

fn registry() -> Registry {
    let mut reg = Registry::default();
    reg.add_in_process(nucleus_plugin());
    reg
}

fn build(text: &str) -> Simulation {
    Simulation::from_toml(text, &registry()).unwrap_or_else(|e| panic!("build: {e}"))
}

fn build_err(text: &str) -> String {
    match Simulation::from_toml(text, &registry()) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

/// A 0.4 × 0.2 × 0.1 m box of tets (2 × 1 × 1 cells) and a rigid group with `params`.
fn box_scene(solver: &str, object_extra: &str, params: &str) -> String {
    format!(
        r#"
[solver]
{solver}
[[objects]]
name = "block"
density = 500.0
{object_extra}
[objects.tet_box]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.2, 0.1]
resolution = [2, 1, 1]

[[constraints]]
kind = "rigid"
params = {params}
"#
    )
}

fn report(sim: &mut Simulation) -> Vec<(String, f64)> {
    sim.reports().unwrap_or_else(|e| panic!("report: {e}"))
}

fn value(stats: &[(String, f64)], name: &str) -> f64 {
    stats
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no column {name} in {stats:?}"))
        .1
}

fn frames(sim: &mut Simulation, n: usize) {
    for _ in 0..n {
        sim.step_frame().unwrap_or_else(|e| panic!("step: {e}"));
    }
}

#[test]
fn kind_describes_itself() {
    let info = nucleus_plugin().info();
    assert_eq!(info.name.as_str(), "rigid");
    let [kind] = info.kinds.as_slice() else {
        panic!("one kind expected");
    };
    assert_eq!(kind.name.as_str(), "rigid");
    assert_eq!(kind.default_order, 10);
    assert_eq!(kind.default_importance, 1);
    assert_eq!(kind.residual_unit.as_str(), "m");
    let names: Vec<&str> = kind.params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["compliance", "initial_angular_velocity", "groups"]);
    for p in kind.params.iter() {
        assert!(!p.doc.is_empty(), "{} has no doc", p.name);
    }
    assert_eq!(kind.params[0].default.as_str(), "0.0");
    assert_eq!(kind.params[0].unit.as_str(), "s²");
    assert_eq!(kind.params[2].default.as_str(), "[]");
}

#[test]
fn every_target_object_is_one_body_by_default() {
    let text = format!(
        "{}\n[[objects]]\nname = \"dots\"\n[objects.particles]\nmin = [2.0, 0.0, 0.0]\nmax = [3.0, 1.0, 1.0]\ncount = [2, 2, 2]\n",
        box_scene("", "", "{}")
    );
    let mut sim = build(&text);
    assert_eq!(sim.groups[0].len, 2);
    assert_eq!(
        sim.groups[0].stages,
        Stages::PROJECT | Stages::END_SUBSTEP | Stages::REPORT | Stages::TAKES_PUSHES,
        "free rigid bodies answer the collisions' pushes"
    );
    let stats = report(&mut sim);
    assert_eq!(stats.len(), 2 * REPORT_COLUMNS.len());
    assert_eq!(stats[0].0, "rigid.block.tx");
    assert_eq!(stats[REPORT_COLUMNS.len()].0, "rigid.dots.tx");
}

#[test]
fn rest_pose_reports_the_identity_and_the_centre_of_mass() {
    let mut sim = build(&box_scene("", "", "{}"));
    let stats = report(&mut sim);
    for (col, expected) in [
        ("tx", 0.0),
        ("ty", 0.0),
        ("tz", 0.0),
        ("qw", 1.0),
        ("qx", 0.0),
        ("qy", 0.0),
        ("qz", 0.0),
        ("cx", 0.2),
        ("cy", 0.1),
        ("cz", 0.05),
        ("lx", 0.0),
    ] {
        let v = value(&stats, &format!("rigid.block.{col}"));
        assert!((v - expected).abs() < 1e-14, "{col} = {v}");
    }
}

#[test]
fn reported_transform_carries_the_rest_pose_onto_the_body() {
    // A spinning, falling block: every particle is at q·rest + t, as a DCC would place a
    // high-resolution mesh modelled in the rest pose.
    let mut sim = build(&box_scene(
        "substeps = 4",
        "velocity = [1.0, 2.0, 0.0]",
        "{ initial_angular_velocity = [1.0, 3.0, -2.0] }",
    ));
    frames(&mut sim, 30);
    let stats = report(&mut sim);
    let t = DVec3::new(
        value(&stats, "rigid.block.tx"),
        value(&stats, "rigid.block.ty"),
        value(&stats, "rigid.block.tz"),
    );
    let q = DQuat::from_xyzw(
        value(&stats, "rigid.block.qx"),
        value(&stats, "rigid.block.qy"),
        value(&stats, "rigid.block.qz"),
        value(&stats, "rigid.block.qw"),
    );
    assert!((q.length() - 1.0).abs() < 1e-14);
    assert!(q.angle_between(DQuat::IDENTITY) > 0.5, "it turned");
    for (x, rest) in sim.particles.x.iter().zip(&sim.particles.rest) {
        let placed = q * DVec3::from_array(*rest) + t;
        assert!((placed - DVec3::from_array(*x)).length() < 1e-12);
    }
}

#[test]
fn initial_spin_gives_the_body_that_angular_velocity() {
    // L = I ω right after the first substep (no gravity): the spin is applied once, about
    // the centre of mass, and does not move the centre.
    let omega = DVec3::new(0.5, -2.0, 1.0);
    let mut sim = build(&box_scene(
        "gravity = [0.0, 0.0, 0.0]\nsubsteps = 20",
        "",
        "{ initial_angular_velocity = [0.5, -2.0, 1.0] }",
    ));
    assert!(sim.groups[0].stages.contains(Stages::FORCE));
    sim.substep(0).expect("substep");
    let p = &sim.particles;
    let m: Vec<f64> = p.inv_mass.iter().map(|w| 1.0 / w).collect();
    let total: f64 = m.iter().sum();
    let c =
        p.x.iter()
            .zip(&m)
            .map(|(x, m)| DVec3::from_array(*x) * *m)
            .sum::<DVec3>()
            / total;
    let momentum: DVec3 =
        p.v.iter()
            .zip(&m)
            .map(|(v, m)| DVec3::from_array(*v) * *m)
            .sum();
    assert!(momentum.length() < 1e-13 * total, "{momentum}");
    let c_rest = p
        .rest
        .iter()
        .zip(&m)
        .map(|(x, m)| DVec3::from_array(*x) * *m)
        .sum::<DVec3>()
        / total;
    let mut l = DVec3::ZERO;
    let mut inertia_omega = DVec3::ZERO;
    for (((x, v), m), rest) in p.x.iter().zip(&p.v).zip(&m).zip(&p.rest) {
        l += (DVec3::from_array(*x) - c).cross(DVec3::from_array(*v)) * *m;
        let r = DVec3::from_array(*rest) - c_rest;
        inertia_omega += r.cross(omega.cross(r)) * *m;
    }
    // L = I₀ω (the inertia of the rest pose, where the spin was given), kept by the first
    // substep to O((|ω|h)²) ≈ 5e-6 (|ω|h ≈ 2e-3 rad).
    assert!(
        (l - inertia_omega).length() < 1e-5 * inertia_omega.length(),
        "{l} vs {inertia_omega}"
    );
    // The other substeps add nothing.
    let before = l;
    for s in 1..20 {
        sim.substep(s).expect("substep");
    }
    let stats = report(&mut sim);
    let l_now = DVec3::new(
        value(&stats, "rigid.block.lx"),
        value(&stats, "rigid.block.ly"),
        value(&stats, "rigid.block.lz"),
    );
    assert!(
        (l_now - before).length() < 1e-3 * before.length(),
        "{l_now} vs {before}"
    );
}

#[test]
fn a_free_body_stays_exactly_rigid_under_gravity_and_spin() {
    let mut sim = build(&box_scene(
        "substeps = 3",
        "",
        "{ initial_angular_velocity = [4.0, 0.0, 1.0] }",
    ));
    frames(&mut sim, 20);
    let r = sim.residuals().expect("residual")[0];
    assert_eq!(r.count, sim.particles.len() as u64);
    assert!(r.max < 1e-12, "{r:?}");
    assert_eq!(r.energy, 0.0);
    // Centre of mass in free fall: y(t) = y0 + ½ g t² discretized by symplectic Euler.
    let stats = report(&mut sim);
    let (h, n) = (1.0 / 180.0, 60.0);
    let fall = -9.81 * h * h * n * (n + 1.0) / 2.0;
    assert!((value(&stats, "rigid.block.cy") - (0.1 + fall)).abs() < 1e-12);
}

#[test]
fn a_compliant_body_pinned_by_a_face_sags_by_compliance_times_gravity() {
    // The static balance of each free particle: mᵢ(xᵢ − gᵢ)/α = mᵢ g, so every free particle
    // hangs α|g| below its goal, whatever the substep. Damping settles the oscillation.
    for alpha in [1e-3, 1e-4] {
        let mut sim = build(&box_scene(
            "substeps = 10\ndamping = 30.0",
            "pins = [{ min = [-0.01, -1.0, -1.0], max = [0.01, 1.0, 1.0] }]",
            &format!("{{ compliance = {alpha} }}"),
        ));
        frames(&mut sim, 120);
        let r = sim.residuals().expect("residual")[0];
        let expected = alpha * 9.81;
        assert!(
            (r.max - expected).abs() < 1e-3 * expected
                && (r.rms - expected).abs() < 1e-3 * expected,
            "α = {alpha}: {r:?} vs {expected}"
        );
        // Energy Σ ½ m (α g)² / α = ½ M_free α g².
        let free_mass: f64 = sim
            .particles
            .inv_mass
            .iter()
            .filter(|&&w| w > 0.0)
            .map(|w| 1.0 / w)
            .sum();
        let energy = 0.5 * free_mass * alpha * 9.81 * 9.81;
        assert!(
            (r.energy - energy).abs() < 3e-3 * energy,
            "{} vs {energy}",
            r.energy
        );
    }
}

#[test]
fn a_body_pinned_at_one_vertex_swings_about_it() {
    // A rigid rod of 5 particles pinned at one end, released horizontal: a compound
    // pendulum. Every particle keeps its distance from the pin, the pin stays put.
    let text = r#"
[solver]
substeps = 10
[[objects]]
name = "rod"
mass = 1.0
pins = ["start"]
[objects.rope]
start = [0.0, 1.0, 0.0]
end = [1.0, 1.0, 0.0]
segments = 4

[[constraints]]
kind = "rigid"
"#;
    let mut sim = build(text);
    let mut lowest: f64 = 1.0;
    for _ in 0..40 {
        frames(&mut sim, 1);
        let x = sim.positions();
        assert_eq!(x[0], DVec3::new(0.0, 1.0, 0.0));
        for (k, p) in x.iter().enumerate() {
            assert!(((*p - x[0]).length() - 0.25 * k as f64).abs() < 1e-12);
        }
        lowest = lowest.min(x[4].y);
    }
    assert!(lowest < 0.1, "the tip swung down: {lowest}");
}

#[test]
fn vertex_groups_select_by_indices_and_by_box() {
    let text = r#"
[[objects]]
name = "cloth"
[objects.grid]
size = [1.0, 1.0]
resolution = [5, 5]

[[constraints]]
kind = "rigid"
params = { groups = [
    { object = "cloth", indices = [0, 1, 5, 6] },
    { object = "cloth", box = { min = [0.7, -1.0, 0.7], max = [1.1, 1.0, 1.1] }, name = "corner", compliance = 1e-4 },
] }
"#;
    let mut sim = build(text);
    assert_eq!(sim.groups[0].len, 2);
    assert!(
        sim.groups[0].stages.contains(Stages::BEGIN_SUBSTEP),
        "a compliant body"
    );
    let stats = report(&mut sim);
    // Default name of the first body: the object's; its centre: of vertices 0, 1, 5, 6.
    assert!((value(&stats, "rigid.cloth.cx") - 0.125).abs() < 1e-14);
    assert!((value(&stats, "rigid.cloth.cz") - 0.125).abs() < 1e-14);
    // The box holds the 2 × 2 vertices at 0.75 and 1.0.
    assert!((value(&stats, "rigid.corner.cx") - 0.875).abs() < 1e-14);
}

#[test]
fn vertex_group_errors_name_the_parameter() {
    let scene = |groups: &str| {
        format!(
            "[[objects]]\nname = \"cloth\"\n[objects.grid]\nsize = [1.0, 1.0]\nresolution = [3, 3]\n\
             [[constraints]]\nkind = \"rigid\"\nparams = {{ groups = {groups} }}\n"
        )
    };
    for (groups, needle) in [
        (
            r#"[{ object = "cloth", indices = [9] }]"#,
            "index 9 is outside",
        ),
        (
            r#"[{ object = "cloth", indices = [-1] }]"#,
            "index -1 is outside",
        ),
        (
            r#"[{ object = "net" }]"#,
            "not one of this constraint's objects",
        ),
        (
            r#"[{ object = "cloth", indices = [0], box = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] } }]"#,
            "not both",
        ),
        (
            r#"[{ object = "cloth", box = { min = [5.0, 5.0, 5.0], max = [6.0, 6.0, 6.0] } }]"#,
            "no vertex",
        ),
        (
            r#"[{ object = "cloth" }, { object = "cloth", name = "cloth" }]"#,
            "second body named `cloth`",
        ),
        (
            r#"[{ object = "cloth", indice = [0] }]"#,
            "unknown field `indice`",
        ),
        (
            r#"[{ object = "cloth", compliance = -1.0 }]"#,
            "compliance -1",
        ),
        (r#"[{ object = "cloth", name = "a,b" }]"#, "without commas"),
        (r#"{ object = "cloth" }"#, "expected a list"),
    ] {
        let e = build_err(&scene(groups));
        assert!(
            e.contains("`groups`") && e.contains(needle),
            "{groups}: {e}"
        );
    }
    let e = build_err(&box_scene("", "", "{ compliance = -1.0 }"));
    assert!(e.contains("compliance"), "{e}");
    let e = build_err(&box_scene("", "", "{ rigidity = 1.0 }"));
    assert!(e.contains("rigidity") && e.contains("unknown"), "{e}");
}

#[test]
fn parameters_given_in_rust_are_validated_too() {
    let params = RigidParams {
        compliance: f64::NAN,
        ..RigidParams::default()
    };
    let e = params.validate().expect_err("NaN accepted");
    assert_eq!(e.subject.as_str(), "compliance");
}

#[test]
fn a_fully_pinned_body_is_reported_but_never_moved() {
    let mut sim = build(&box_scene("", "pins = [\"all\"]", "{}"));
    let start = sim.particles.x.clone();
    frames(&mut sim, 3);
    assert_eq!(sim.particles.x, start);
    let stats = report(&mut sim);
    assert_eq!(value(&stats, "rigid.block.qw"), 1.0);
}

#[test]
fn flat_and_collinear_bodies_tumble_without_nan() {
    let text = r#"
[solver]
substeps = 4
[[objects]]
name = "sheet"
pins = [0]
[objects.grid]
size = [0.5, 0.3]
resolution = [4, 3]
[[objects]]
name = "stick"
velocity = [0.0, 3.0, 0.0]
[objects.rope]
start = [1.0, 0.0, 0.0]
end = [1.0, 0.0, 1.0]
segments = 5

[[constraints]]
kind = "rigid"
params = { initial_angular_velocity = [2.0, 1.0, 5.0] }
"#;
    let mut sim = build(text);
    frames(&mut sim, 60);
    let r = sim.residuals().expect("residual")[0];
    assert!(r.max < 1e-12, "{r:?}");
    let stats = report(&mut sim);
    assert!(stats.iter().all(|(_, v)| v.is_finite()), "{stats:?}");
}

#[test]
fn runs_are_bit_identical() {
    let run = || {
        let mut sim = build(&box_scene(
            "substeps = 3",
            "pins = [0]",
            "{ compliance = 1e-3, initial_angular_velocity = [1.0, 2.0, 3.0] }",
        ));
        frames(&mut sim, 30);
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
fn a_rigid_patch_of_a_hanging_cloth_stays_rigid_while_the_rest_drapes() {
    // A vertex group of a cloth, held rigid while the cloth (hard stretch edges, pinned at
    // two corners) falls and swings: the patch ends every substep exactly rigid (the rigid
    // group runs after stretch), moves with the cloth, and the cloth around it bends.
    let mut reg = registry();
    reg.add_in_process(nucleus_stretch::nucleus_plugin());
    let text = r#"
[solver]
substeps = 10
[[objects]]
name = "cloth"
mass = 1.0
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [11, 11]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "rigid"
params = { groups = [{ object = "cloth", box = { min = [0.35, -1.0, 0.35], max = [0.65, 1.0, 0.65] }, name = "patch" }] }
"#;
    let mut sim = Simulation::from_toml(text, &reg).unwrap_or_else(|e| panic!("build: {e}"));
    frames(&mut sim, 60);
    let p = &sim.particles;
    let patch: Vec<usize> = (0..p.len())
        .filter(|&i| (0.35..=0.65).contains(&p.rest[i][0]) && (0.35..=0.65).contains(&p.rest[i][2]))
        .collect();
    assert_eq!(patch.len(), 9);
    let at = |v: &[[f64; 3]], i: usize| DVec3::from_array(v[i]);
    for &i in &patch {
        for &j in &patch {
            let d0 = (at(&p.rest, j) - at(&p.rest, i)).length();
            let d = (at(&p.x, j) - at(&p.x, i)).length();
            assert!((d - d0).abs() < 1e-12, "patch pair ({i}, {j}): {d} vs {d0}");
        }
    }
    // The rest of the cloth is not held: its free corners have swung far from rest.
    for corner in [110, 120] {
        let moved = (at(&p.x, corner) - at(&p.rest, corner)).length();
        assert!(moved > 0.5, "corner {corner} moved {moved}");
    }
    let stats = report(&mut sim);
    let c = DVec3::new(
        value(&stats, "rigid.patch.cx"),
        value(&stats, "rigid.patch.cy"),
        value(&stats, "rigid.patch.cz"),
    );
    assert!(
        (c - DVec3::new(0.5, 0.0, 0.5)).length() > 0.2,
        "the patch moved with the cloth: {c}"
    );
}

/// The push a particle at `x` gets.
type PushOf = fn(DVec3) -> DVec3;

/// The block of [`box_scene`] without gravity, after one prediction, its particles moved by
/// `push(x)` and the moves written into the core's pushes before each of the calls `stages`
/// (in order), as a collision group would: its positions after.
fn answered(stages: &[(Stage, PushOf)]) -> Vec<DVec3> {
    let mut sim = build(&box_scene("gravity = [0.0, 0.0, 0.0]", "", "{}"));
    // No group gives pushes here, so the core keeps none: keep them as it would with one.
    assert!(
        sim.particles.pushes.is_empty(),
        "pushes kept without a giver"
    );
    let n = sim.particles.x.len();
    sim.particles.pushes = vec![[0.0; 3]; n];
    sim.particles.kicks = vec![[0.0; 3]; n];
    sim.predict_substep(0).unwrap();
    for (k, &(stage, push)) in stages.iter().enumerate() {
        // As the collision does: move the particles, and say so.
        for (p, x) in sim.particles.pushes.iter_mut().zip(&mut sim.particles.x) {
            let by = push(DVec3::from_array(*x));
            *x = (DVec3::from_array(*x) + by).to_array();
            *p = by.to_array();
        }
        sim.run_stage(0, stage, 0, k as u32).unwrap();
        assert!(
            sim.particles.pushes.iter().all(|p| *p == [0.0; 3]),
            "the pushes were not all taken"
        );
    }
    sim.positions().to_vec()
}

/// A block sliding on the ground: its bottom pushed up (the normal) and back (the friction).
fn normal(x: DVec3) -> DVec3 {
    if x.z < 1e-9 {
        DVec3::new(0.0, 0.0, 2e-5)
    } else {
        DVec3::ZERO
    }
}

fn friction(x: DVec3) -> DVec3 {
    if x.z < 2e-5 + 1e-9 {
        DVec3::new(-8e-6, 0.0, 0.0)
    } else {
        DVec3::ZERO
    }
}

fn both(x: DVec3) -> DVec3 {
    normal(x) + friction(x)
}

fn nothing(_: DVec3) -> DVec3 {
    DVec3::ZERO
}

#[test]
fn pushes_answered_in_parts_move_the_body_as_their_sum_answered_at_once() {
    // The block's base pushed up and back at once: it moves up and back as a whole.
    let at_once = answered(&[(Stage::Project, both)]);
    let start = answered(&[(Stage::Project, nothing)]);
    for (a, s) in at_once.iter().zip(&start) {
        let moved = *a - *s;
        assert!(
            (moved - DVec3::new(-8e-6, 0.0, 2e-5)).length() < 1e-15,
            "{moved}"
        );
    }
    // The normal pushes answered in a pass, the friction at the substep's end: the same.
    let in_parts = answered(&[(Stage::Project, normal), (Stage::EndSubstep, friction)]);
    for (a, b) in at_once.iter().zip(&in_parts) {
        assert!((*a - *b).length() < 1e-15, "{a} against {b}");
    }
}
