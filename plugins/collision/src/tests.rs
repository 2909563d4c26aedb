//! The group in whole scenes, in-process: the plugin (and `stretch`) registered with
//! `nucleus-core` exactly as the host registers loaded libraries, scenes built from TOML
//! text. Each test states one contract of the group: the fail-safe leaves no crossing when
//! the passes run out, a group in which nothing can collide is empty (never scheduled),
//! parameters are refused with errors naming the parameter and the object or collider, and
//! layers, flags and exclusions decide which primitives are ever paired.

use glam::DVec3;
use nucleus_core::{Registry, Simulation};

use crate::narrow_phase::distance;
use crate::nucleus_plugin;

fn registry() -> Registry {
    let mut reg = Registry::default();
    reg.add_in_process(nucleus_plugin());
    reg.add_in_process(nucleus_stretch::nucleus_plugin());
    reg
}

fn simulation(scene: &str) -> Result<Simulation, String> {
    Simulation::from_toml(scene, &registry()).map_err(|e| e.to_string())
}

/// The collision group's value `name` from the last frame's reports.
fn report(sim: &mut Simulation, name: &str) -> f64 {
    let key = format!("collision.{name}");
    sim.reports()
        .expect("reports")
        .into_iter()
        .find(|(k, _)| *k == key)
        .unwrap_or_else(|| panic!("no report {key}"))
        .1
}

/// Pairs of surface triangles (all objects) that share no vertex and intersect (exact test).
fn intersecting_triangle_pairs(sim: &Simulation) -> usize {
    let x = sim.positions();
    let tris: Vec<[u32; 3]> = sim
        .objects
        .iter()
        .flat_map(|o| o.surface_triangles.iter().copied())
        .collect();
    let mut count = 0;
    for (i, a) in tris.iter().enumerate() {
        let pa = a.map(|k| x[k as usize]);
        let (lo, hi) = (pa[0].min(pa[1]).min(pa[2]), pa[0].max(pa[1]).max(pa[2]));
        for b in &tris[i + 1..] {
            if a.iter().any(|v| b.contains(v)) {
                continue;
            }
            let pb = b.map(|k| x[k as usize]);
            let (lo_b, hi_b) = (pb[0].min(pb[1]).min(pb[2]), pb[0].max(pb[1]).max(pb[2]));
            if lo.cmpgt(hi_b).any() || lo_b.cmpgt(hi).any() {
                continue;
            }
            if distance::triangles_intersect(pa, pb) {
                count += 1;
            }
        }
    }
    count
}

/// `n` horizontal square cloths of `res × res` vertices and side `side`, stacked `gap` apart
/// above `y0`, each falling at `speed`.
fn cloth_stack(n: usize, res: u32, side: f64, y0: f64, gap: f64, speed: f64) -> String {
    let mut s = String::new();
    for k in 0..n {
        // Each layer turned a little, so that no two layers' edges are parallel.
        let shift = 0.013 * k as f64;
        s.push_str(&format!(
            "[[objects]]\nname = \"layer{k}\"\nmass = 0.05\nvelocity = [0.0, {v}, 0.0]\n\
             [objects.grid]\nsize = [{side}, {side}]\nresolution = [{res}, {res}]\nplane = \"xz\"\n\
             origin = [{o}, {y}, {o}]\n",
            v = -speed,
            o = -0.5 * side + shift,
            y = y0 + gap * k as f64,
        ));
    }
    s
}

#[test]
fn the_fail_safe_leaves_no_crossing_when_one_pass_per_substep_cannot_resolve_a_stack() {
    // Four cloths stacked 6 mm apart slam at 6 m/s into a sheet pinned along its border,
    // with ONE collision pass per substep (importance 1) and one substep per frame: each
    // layer moves 10 cm per step, and one Gauss-Seidel pass cannot separate a stack of four
    // contacts. The fail-safe must freeze what still crosses: no two triangles ever
    // intersect at the end of a substep.
    let scene = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 1
gravity = [0.0, -9.81, 0.0]
[[objects]]
name = "sheet"
mass = 0.5
pins = ["edge:row0", "edge:rowN", "edge:col0", "edge:colN"]
[objects.grid]
size = [0.6, 0.6]
resolution = [9, 9]
plane = "xz"
origin = [-0.3, 0.0, -0.3]
{}
[[constraints]]
kind = "stretch"
params = {{ compliance = 0.0, compression_compliance = 1e-3 }}
[[constraints]]
kind = "collision"
importance = 1
params = {{ thickness = 0.002 }}
"#,
        cloth_stack(4, 6, 0.3, 0.05, 0.006, 6.0)
    );
    let mut sim = simulation(&scene).unwrap();
    assert_eq!(sim.groups[1].importance, 1);
    let sheet = sim.object("sheet").unwrap().triangles.clone();
    let (mut frozen, mut unresolved, mut worst, mut below) = (0.0, 0.0, 0, 0);
    for _ in 0..6 {
        sim.step_frame().unwrap();
        worst = worst.max(intersecting_triangle_pairs(&sim));
        frozen += report(&mut sim, "frozen");
        unresolved += report(&mut sim, "unresolved");
        // Every vertex of the stack is still above the sheet (pinned along its border, so a
        // vertex that tunnelled through would have no sheet below it): the segment from it
        // straight down meets the sheet.
        let x = sim.positions();
        for p in &x[81..] {
            let down = DVec3::new(p.x, -10.0, p.z);
            if !sheet
                .iter()
                .any(|t| distance::segment_triangle_intersect(*p, down, t.map(|i| x[i as usize])))
            {
                below += 1;
            }
        }
    }
    assert_eq!(
        worst, 0,
        "intersecting triangle pairs at the end of a substep"
    );
    assert_eq!(below, 0, "vertices of the stack below the sheet");
    assert_eq!(unresolved, 0.0);
    // The fail-safe did the work (this is not a scene the passes alone get right).
    assert!(frozen > 0.0, "the fail-safe never froze anything");
}

/// A scene of two single particles `a` and `b` and a collision group with `params`.
fn two_particles(params: &str) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 2
[[objects]]
name = "a"
mass = 1.0
[objects.particles]
min = [0.0, 1.0, 0.0]
max = [0.0, 1.0, 0.0]
count = [1, 1, 1]
[[objects]]
name = "b"
mass = 1.0
[objects.particles]
min = [0.0, 2.0, 0.0]
max = [0.0, 2.0, 0.0]
count = [1, 1, 1]
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#
    )
}

#[test]
fn a_group_in_which_nothing_can_collide_is_empty_and_never_scheduled() {
    for (why, params) in [
        (
            "disjoint layers",
            "objects_settings = { a = { layers = 1 }, b = { layers = 2 } }",
        ),
        ("excluded", r#"exclude = [["a", "b"]]"#),
        ("no layers", "layers = 0"),
        (
            "colliders on other layers",
            r#"layers = 1, objects_settings = { b = { layers = 2 } }, exclude = [["a", "b"]], colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0], layers = 4 }]"#,
        ),
        (
            "vertices off",
            "objects_settings = { a = { vertex = false }, b = { vertex = false } }",
        ),
    ] {
        let mut sim = simulation(&two_particles(params)).unwrap_or_else(|e| panic!("{why}: {e}"));
        assert_eq!(sim.groups[0].len, 0, "{why}");
        assert!(sim.calls.is_empty(), "{why}: scheduled {:?}", sim.calls);
        // And the particles fall straight through each other's place, untouched.
        for _ in 0..10 {
            sim.step_frame().unwrap();
        }
        assert!(
            sim.positions().iter().all(|p| p.x == 0.0 && p.z == 0.0),
            "{why}"
        );
    }
    // The control: the same particles with the defaults do make a scheduled group.
    let sim = simulation(&two_particles("")).unwrap();
    assert!(sim.groups[0].len > 0);
    assert!(!sim.calls.is_empty());
}

#[test]
fn a_collider_only_on_other_layers_makes_the_group_empty() {
    let params = r#"self_collision = false, exclude = [["a", "b"]], colliders = [{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 0.5, layers = 2 }]"#;
    let sim = simulation(&two_particles(params)).unwrap();
    assert_eq!(sim.groups[0].len, 0);
    let shared = params.replace("layers = 2", "layers = 3");
    let sim = simulation(&two_particles(&shared)).unwrap();
    assert!(sim.groups[0].len > 0);
}

#[test]
fn bad_parameters_are_refused_naming_the_parameter_and_the_object_or_collider() {
    let cases = [
        (
            "objects_settings = { a = { layers = -1 } }",
            &["objects_settings", "`a`", "layers", "-1"][..],
        ),
        (
            "objects_settings = { a = { layers = 4294967296 } }",
            &["objects_settings", "`a`", "layers"],
        ),
        (
            r#"objects_settings = { b = { layers = "one" } }"#,
            &["objects_settings", "`b`", "layers"],
        ),
        (
            "objects_settings = { c = { thickness = 0.1 } }",
            &["objects_settings", "`c` is not an object"],
        ),
        (
            "objects_settings = { a = { thickness = -0.1 } }",
            &["objects_settings", "`a`", "thickness"],
        ),
        (
            "objects_settings = { a = { thikness = 0.1 } }",
            &["objects_settings", "`a`", "thikness"],
        ),
        (
            r#"colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }, { type = "sphere", center = [0.0, 0.0, 0.0], radius = 1.0, layers = -3 }]"#,
            &["colliders", "colliders[1]", "layers"],
        ),
        (
            r#"colliders = [{ type = "capsule", a = [0.0, 0.0, 0.0], b = [1.0, 0.0, 0.0], radius = 0.0 }]"#,
            &["colliders", "colliders[0]", "radius"],
        ),
        (r#"exclude = [["a", "z"]]"#, &["exclude", "`z`"]),
        ("layers = -1", &["layers"]),
        // Sizes and positions beyond 1e6 m (a radius of 1e308 overflowed the contact maths).
        (
            r#"colliders = [{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 1e308 }]"#,
            &["colliders[0]", "`radius`", "1e308", "within 1e6 m"],
        ),
        (
            r#"colliders = [{ type = "box", center = [0.0, -2e6, 0.0], half_extents = [1.0, 1.0, 1.0] }]"#,
            &["colliders[0]", "`center`", "2e6"],
        ),
        (
            r#"colliders = [{ type = "capsule", a = [0.0, 0.0, 0.0], b = [1.0, 0.0, 0.0], radius = 0.1, pivot = [0.0, 1e7, 0.0] }]"#,
            &["colliders[0]", "`pivot`", "1e7"],
        ),
    ];
    // A plane's normal is a direction: any length is accepted, and a 1,000 km sphere is too.
    for ok in [
        r#"colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1e9, 0.0] }]"#,
        r#"colliders = [{ type = "sphere", center = [0.0, -1e6, 0.0], radius = 1e6 }]"#,
    ] {
        assert!(simulation(&two_particles(ok)).is_ok(), "refused {ok}");
    }
    for (params, words) in cases {
        let err = match simulation(&two_particles(params)) {
            Ok(_) => panic!("accepted {params}"),
            Err(e) => e,
        };
        for w in words {
            assert!(err.contains(w), "{params}: `{err}` does not mention {w}");
        }
    }
}

/// A self-colliding cloth thicker than four times its mean edge length is refused at build,
/// naming the object and the limit (it would keep hundreds of pairs a vertex with itself at
/// rest); the same thickness is accepted without self-collision, or on a kinematic object.
#[test]
fn a_self_colliding_cloth_much_thicker_than_its_edges_is_refused() {
    // A 1 m, 9 × 9 sheet: mean edge (144 × 0.125 + 64 × 0.177) / 208 = 0.141 m.
    let sheet = |pins: &str, params: &str| {
        format!(
            r#"
[[objects]]
name = "sheet"
pins = [{pins}]
[objects.grid]
size = [1.0, 1.0]
resolution = [9, 9]
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#
        )
    };
    assert!(
        simulation(&sheet("0", "thickness = 0.5")).is_ok(),
        "3.5 times"
    );
    let err = simulation(&sheet("0", "thickness = 0.6"))
        .err()
        .expect("4.3 times refused");
    for w in [
        "`sheet`",
        "thickness 0.6 m is 4.3 times",
        "at most 4 times",
        "5.637e-1 m",
        "self_collision",
    ] {
        assert!(err.contains(w), "`{err}` does not mention {w}");
    }
    assert!(simulation(&sheet("0", "thickness = 0.6, self_collision = false")).is_ok());
    assert!(simulation(&sheet("\"all\"", "thickness = 0.6")).is_ok());
}

/// A pinned 1 m sheet (9 × 9 vertices) at y = 0 and a particle `p` above its middle
/// (between vertices) falling at `speed`; returns the particle's height after 0.5 s.
fn particle_on_sheet(params: &str, speed: f64) -> f64 {
    let scene = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 4
[[objects]]
name = "sheet"
mass = 1.0
pins = ["all"]
[objects.grid]
size = [1.0, 1.0]
resolution = [9, 9]
plane = "xz"
origin = [-0.5, 0.0, -0.5]
[[objects]]
name = "p"
mass = 0.01
velocity = [0.0, {v}, 0.0]
[objects.particles]
min = [0.031, 0.3, 0.047]
max = [0.031, 0.3, 0.047]
count = [1, 1, 1]
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#,
        v = -speed
    );
    let mut sim = simulation(&scene).unwrap();
    for _ in 0..30 {
        sim.step_frame().unwrap();
    }
    sim.positions()[81].y
}

#[test]
fn per_object_thickness_sets_where_a_particle_rests() {
    // Kept r_p + r_sheet above the sheet.
    for (rp, rs) in [(0.01, 0.002), (0.03, 0.0), (0.005, 0.02)] {
        let y = particle_on_sheet(
            &format!("objects_settings = {{ p = {{ thickness = {rp} }}, sheet = {{ thickness = {rs} }} }}"),
            0.0,
        );
        assert!(
            (y - (rp + rs)).abs() < 1e-9,
            "rests at {y}, expected {}",
            rp + rs
        );
    }
}

#[test]
fn layers_exclusions_and_flags_decide_what_a_particle_passes_through() {
    let rests = |params: &str| particle_on_sheet(params, 5.0) > 0.0;
    assert!(rests("thickness = 0.005"));
    assert!(rests(
        "objects_settings = { p = { layers = 3 }, sheet = { layers = 6 } }"
    ));
    assert!(!rests(
        "objects_settings = { p = { layers = 1 }, sheet = { layers = 6 } }"
    ));
    assert!(!rests("layers = 0"));
    assert!(!rests(r#"exclude = [["sheet", "p"]]"#));
    // The particle meets the sheet only through its faces (vertex–face pairs): with the
    // sheet's faces or the particle's vertex switched off it falls through; switching the
    // sheet's edges off changes nothing.
    assert!(!rests("objects_settings = { sheet = { face = false } }"));
    assert!(!rests("objects_settings = { p = { vertex = false } }"));
    assert!(rests("objects_settings = { sheet = { edge = false } }"));
}

#[test]
fn rest_reach_keeps_far_pairs_at_the_thickness_and_close_ones_at_a_fraction_of_their_rest_distance()
{
    use crate::candidates::rest_pairs::{rest_reach, REST_FRACTION};
    assert_eq!(rest_reach(0.01, 0.02 * 0.02), Some(0.01));
    assert_eq!(rest_reach(0.01, 0.01 * 0.01), Some(0.01));
    let close = rest_reach(0.01, 0.006 * 0.006).unwrap();
    assert!((close - REST_FRACTION * 0.006).abs() < 1e-15);
    assert_eq!(rest_reach(0.01, 0.0), None);
}

#[test]
fn two_runs_are_bit_identical() {
    let scene = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 2
[[objects]]
name = "sheet"
mass = 0.5
pins = ["edge:row0", "edge:rowN"]
[objects.grid]
size = [0.6, 0.6]
resolution = [9, 9]
plane = "xz"
origin = [-0.3, 0.0, -0.3]
{}
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "collision"
params = {{ thickness = 0.003, colliders = [{{ type = "box", center = [0.0, -0.2, 0.0], half_extents = [0.1, 0.1, 0.1], rotation = [0.0, 30.0, 10.0] }}] }}
"#,
        cloth_stack(2, 6, 0.3, 0.05, 0.01, 2.0)
    );
    let run = || {
        let mut sim = simulation(&scene).unwrap();
        for _ in 0..20 {
            sim.step_frame().unwrap();
        }
        sim.positions()
            .iter()
            .flat_map(|p| p.to_array().map(f64::to_bits))
            .collect::<Vec<u64>>()
    };
    assert_eq!(run(), run());
}

/// One particle of 10 g at `at` (m) moving at `velocity` (m/s), no gravity, 4 substeps a
/// frame, the object's thickness 5 mm, in a collision group of parameters `params` (TOML).
fn lone_particle(at: [f64; 3], velocity: [f64; 3], params: &str) -> Simulation {
    let ([x, y, z], [vx, vy, vz]) = (at, velocity);
    let scene = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 4
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "p"
mass = 0.01
velocity = [{vx:?}, {vy:?}, {vz:?}]
[objects.particles]
min = [{x:?}, {y:?}, {z:?}]
max = [{x:?}, {y:?}, {z:?}]
count = [1, 1, 1]
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#
    );
    simulation(&scene).unwrap()
}

/// A particle started at `start` (m) from the centre of a 0.5 m sphere along x
/// ([`lone_particle`]): its distance from the centre and its velocity after each of `frames`
/// frames.
fn particle_in_sphere(
    start: f64,
    velocity: [f64; 3],
    push_out_speed: f64,
    frames: usize,
) -> Vec<(f64, DVec3)> {
    let params = format!(
        r#"push_out_speed = {push_out_speed:e}, colliders = [{{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 0.5 }}]"#
    );
    let mut sim = lone_particle([start, 0.0, 0.0], velocity, &params);
    (0..frames)
        .map(|_| {
            sim.step_frame().unwrap();
            (sim.positions()[0].length(), sim.velocities()[0])
        })
        .collect()
}

#[test]
fn a_particle_started_inside_a_collider_leaves_it_at_the_push_out_speed_and_stops_on_its_surface() {
    // From 0.1 m off the centre to the contact distance 0.505 m at 0.6 m/s: every substep
    // (h = 1/240 s) moves it out by exactly 0.6 h, so it is at 0.1 + 0.6 t, moving out at
    // 0.6 m/s, until it is out at t = 0.675 s (frame 40.5); then it rests on the surface: the
    // velocity the push gave is taken off once it is out.
    let r = particle_in_sphere(0.1, [0.0; 3], 0.6, 50);
    for (f, &(d, v)) in r.iter().enumerate() {
        let t = (f + 1) as f64 / 60.0;
        let (expected, speed) = if t <= 0.675 {
            (0.1 + 0.6 * t, 0.6)
        } else {
            (0.505, 0.0)
        };
        assert!(
            (d - expected).abs() < 1e-9,
            "frame {}: {d} m from the centre, expected {expected}",
            f + 1
        );
        assert!(
            (v - DVec3::new(speed, 0.0, 0.0)).length() < 1e-9,
            "frame {}: velocity {v}, expected {speed} m/s out",
            f + 1
        );
    }
    // An unbounded speed puts it on the surface in the first substep (0.405 m in 1/240 s),
    // where it stays; before the push's velocity was taken off it left at 97 m/s and was
    // 1.72 m out after one frame.
    let r = particle_in_sphere(0.1, [0.0; 3], 1e6, 3);
    for &(d, v) in &r {
        assert!((d - 0.505).abs() < 1e-9, "at {d} m, expected the surface");
        assert!(v.length() < 1e-9, "velocity {v} after a push-out");
    }
}

#[test]
fn a_push_out_takes_only_the_velocity_it_gave() {
    // Thrown out of the sphere at 2 m/s, faster than the push-out's 0.6 m/s: the push never
    // acts, and the particle keeps its speed through the surface and beyond.
    let r = particle_in_sphere(0.1, [2.0, 0.0, 0.0], 0.6, 30);
    for (f, &(d, v)) in r.iter().enumerate() {
        let t = (f + 1) as f64 / 60.0;
        assert!(
            (d - (0.1 + 2.0 * t)).abs() < 1e-9,
            "frame {}: {d} m from the centre, expected {}",
            f + 1,
            0.1 + 2.0 * t
        );
        assert!(
            (v - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-9,
            "velocity {v}"
        );
    }
    // Thrown *into* the sphere at 3 m/s from inside: the push still brings it out at
    // 0.6 m/s (the contact takes its inward speed), and it rests on the surface.
    let r = particle_in_sphere(0.3, [-3.0, 0.0, 0.0], 0.6, 30);
    let (d, v) = r[29];
    assert!(
        (d - 0.505).abs() < 1e-9,
        "at {d} m after 0.5 s, expected the surface"
    );
    assert!(v.length() < 1e-9, "velocity {v}");
}

#[test]
fn a_push_out_out_of_a_moving_collider_gives_no_velocity_of_its_own() {
    // A ground plane moving at 0.2 m/s along its normal, up or down, a particle at rest 0.1 m
    // under it, no gravity. The particle rises at the push-out speed relative to the plane
    // (0.5 m/s), gets out in the 51st substep (frame 13) 6.25 mm from it (one substep's push
    // beyond its 5 mm), and keeps only the velocity it would have had without the push: at
    // rest when the plane falls away (the plane's own motion gave it nothing), the plane's
    // 0.2 m/s when the plane rises into it (the contact would have carried it anyway).
    for plane_v in [-0.2f64, 0.2] {
        let mut sim = lone_particle(
            [0.0, -0.1, 0.0],
            [0.0; 3],
            &format!(
                r#"push_out_speed = 0.5, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0], velocity = [0.0, {plane_v:?}, 0.0] }}]"#
            ),
        );
        let after = plane_v.max(0.0);
        for f in 1..=30 {
            sim.step_frame().unwrap();
            let t = f as f64 / 60.0;
            let (x, v) = (sim.positions()[0], sim.velocities()[0]);
            let gap = x.y - plane_v * t;
            let (expected_gap, vy) = if f <= 12 {
                (-0.1 + 0.5 * t, 0.5 + plane_v)
            } else {
                // Out at t = 51/240 s.
                let out = 51.0 / 240.0;
                (-0.1 + 51.0 / 480.0 + (after - plane_v) * (t - out), after)
            };
            assert!(
                (gap - expected_gap).abs() < 1e-9,
                "plane at {plane_v} m/s, frame {f}: {gap} m from it, expected {expected_gap}"
            );
            assert!(
                (v - DVec3::new(0.0, vy, 0.0)).length() < 1e-9,
                "plane at {plane_v} m/s, frame {f}: velocity {v}, expected (0, {vy}, 0)"
            );
        }
    }
}

#[test]
fn a_push_out_keeps_the_motion_along_the_surface() {
    // A particle 0.1 m under a ground plane, sliding at 1 m/s along x, no friction: it rises
    // at the push-out speed (0.5 m/s, 1/480 m a substep) and slides on at 1 m/s. The substep
    // that takes it past its contact distance (5 mm; the 51st, in frame 13) ends at
    // −0.1 + 51/480 = 6.25 mm, within one substep's push of it, and there it stays.
    let mut sim = lone_particle(
        [0.0, -0.1, 0.0],
        [1.0, 0.0, 0.0],
        r#"push_out_speed = 0.5, friction_static = 0.0, friction_dynamic = 0.0, colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }]"#,
    );
    for f in 1..=30 {
        sim.step_frame().unwrap();
        let t = f as f64 / 60.0;
        let (x, v) = (sim.positions()[0], sim.velocities()[0]);
        let (y, vy) = if f <= 12 {
            (-0.1 + 0.5 * t, 0.5)
        } else {
            (-0.1 + 51.0 / 480.0, 0.0)
        };
        assert!(
            (x.x - t).abs() < 1e-9,
            "frame {f}: x = {}, expected {t}",
            x.x
        );
        assert!(
            (x.y - y).abs() < 1e-9,
            "frame {f}: y = {}, expected {y}",
            x.y
        );
        assert!(
            (v - DVec3::new(1.0, vy, 0.0)).length() < 1e-9,
            "frame {f}: velocity {v}, expected (1, {vy}, 0)"
        );
    }
}

/// A 16 × 16 self-colliding cloth of side 0.5 m in the plane y = 0, moving at `velocity`
/// without gravity, 10 substeps a frame, with more collision parameters `params` (TOML).
fn moving_cloth(velocity: [f64; 3], params: &str) -> Simulation {
    let [vx, vy, vz] = velocity;
    let params = match params {
        "" => "thickness = 0.004".to_string(),
        more => format!("thickness = 0.004, {more}"),
    };
    let scene = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "cloth"
mass = 0.1
velocity = [{vx:?}, {vy:?}, {vz:?}]
[objects.grid]
size = [0.5, 0.5]
resolution = [16, 16]
plane = "xz"
origin = [-0.25, 0.0, -0.25]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#
    );
    simulation(&scene).unwrap()
}

#[test]
fn a_cloth_moving_as_a_whole_has_the_candidates_of_a_cloth_at_rest() {
    // The broad phase's boxes follow the motion the vertices share (`shift`), so a cloth
    // carried fast has the candidates of one at rest. Without it, the 64 × 64 cloth of
    // `cloth_on_sphere` thrown at 20 m/s had 258,446 candidates a substep against 35,218
    // (and 441–473 against 125–128 ms a frame on 2 threads, the same bits).
    let candidates = |v: [f64; 3]| {
        let mut sim = moving_cloth(v, "");
        sim.step_frame().unwrap();
        report(&mut sim, "candidates")
    };
    let at_rest = candidates([0.0, 0.0, 0.0]);
    assert!(at_rest > 0.0);
    for v in [[20.0, 0.0, 0.0], [-13.0, 7.0, 29.0], [0.0, -300.0, 0.0]] {
        let moving = candidates(v);
        assert!(
            moving <= at_rest,
            "at {v:?} m/s: {moving} candidates against {at_rest} at rest"
        );
    }
}

#[test]
fn a_fast_cloth_thrown_at_a_sphere_is_caught_by_it() {
    // Thrown at 20 m/s (3.3 cm a substep, eight times its thickness) at a sphere 0.5 m
    // ahead: the shifted boxes still pair every vertex that reaches the sphere with it.
    let sphere = r#"colliders = [{ type = "sphere", center = [0.6, 0.0, 0.0], radius = 0.15 }]"#;
    let mut sim = moving_cloth([20.0, 0.0, 0.0], sphere);
    let centre = DVec3::new(0.6, 0.0, 0.0);
    for frame in 1..=6 {
        sim.step_frame().unwrap();
        let closest = sim
            .positions()
            .iter()
            .map(|p| p.distance(centre))
            .fold(f64::INFINITY, f64::min);
        assert!(
            closest > 0.154 - 1e-9,
            "frame {frame}: a vertex {closest} m from the sphere's centre"
        );
    }
    // The sphere caught it: without the sphere every vertex would be 2 m on, x ≥ 1.75.
    let most_x = sim
        .positions()
        .iter()
        .map(|p| p.x)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        most_x < 1.0,
        "the cloth went past the sphere (x up to {most_x})"
    );
}

#[test]
fn more_candidates_than_max_candidates_fail_the_substep_naming_the_object() {
    // The 16 × 16 cloth at rest holds 1,906 candidates (the test above).
    let mut sim = moving_cloth([0.0; 3], "max_candidates = 1000");
    let err = sim.step_frame().expect_err("over the budget").to_string();
    for part in [
        "`cloth`",
        "1906 candidate pairs",
        "budget of 1000",
        "max_candidates",
    ] {
        assert!(err.contains(part), "`{part}` missing from: {err}");
    }
    let mut sim = moving_cloth([0.0; 3], "max_candidates = 1906");
    sim.step_frame().expect("at the budget");
}
