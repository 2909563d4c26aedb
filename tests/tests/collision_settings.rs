//! The `collision` plugin's per-object and per-pair settings, loaded from its library:
//! per-object thickness (where a cloth rests), the vertex / edge / face flags (which
//! primitives collide: switching one off lets exactly the contact it carries through),
//! excluded pairs, collision layers of objects and colliders (two things collide only if
//! their masks share a bit), a group in which nothing can collide (empty, never scheduled:
//! it costs nothing), and one object whose two layers are closer than twice its thickness in
//! the rest shape (they still collide, at a reduced distance, and never cross).

#[path = "../../plugins/collision/src/narrow_phase/distance.rs"]
#[allow(dead_code)]
mod distance;

use nucleus_core::Simulation;
use nucleus_tests::*;

fn run_frames(sim: &mut Simulation, frames: u32) {
    for _ in 0..frames {
        sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
    }
}

/// Lowest and highest y of an object's particles.
fn y_range(sim: &Simulation, name: &str) -> (f64, f64) {
    particles_of(sim, name)
        .map(|i| sim.positions()[i].y)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), y| {
            (l.min(y), h.max(y))
        })
}

/// A 0.3 m cloth of 5 × 5 vertices, flat at height `y` over the ground plane (y = 0), with hard
/// stretch and a collision group with `params` (which give the plane as a collider).
fn cloth_over_ground(y: f64, params: &str) -> Simulation {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 4
[[objects]]
name = "cloth"
mass = 0.1
[objects.grid]
size = [0.3, 0.3]
resolution = [5, 5]
plane = "xz"
origin = [-0.15, {y}, -0.15]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#
    );
    simulation(&text, &[])
}

/// Two 0.4 m cloths of 6 × 6 vertices: `lower` pinned entirely at y = 0, `upper` falling
/// from y = 0.05 at 2 m/s, offset so that no vertex is above another, and a collision group
/// with `params`.
fn two_cloths(params: &str) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 4
[[objects]]
name = "lower"
mass = 0.1
pins = ["all"]
[objects.grid]
size = [0.4, 0.4]
resolution = [6, 6]
plane = "xz"
origin = [-0.2, 0.0, -0.2]
[[objects]]
name = "upper"
mass = 0.1
velocity = [0.0, -2.0, 0.0]
[objects.grid]
size = [0.3, 0.3]
resolution = [6, 6]
plane = "xz"
origin = [-0.137, 0.05, -0.141]
[[constraints]]
kind = "stretch"
objects = ["upper"]
params = {{ compliance = 0.0, compression_compliance = 1e-3 }}
[[constraints]]
kind = "collision"
params = {{ {params} }}
"#
    )
}

/// Where the upper cloth ends after 0.5 s: `true` if it rests on the lower one (wholly
/// above it), `false` if it passed through (wholly below it).
fn upper_rests_on_lower(params: &str) -> bool {
    let mut sim = simulation(&two_cloths(params), &[]);
    run_frames(&mut sim, 30);
    let (lo, hi) = y_range(&sim, "upper");
    assert!(lo > 0.0 || hi < 0.0, "half through: {lo}..{hi}");
    lo > 0.0
}

#[test]
fn objects_collide_only_when_their_layers_share_a_bit_and_they_are_not_excluded() {
    assert!(upper_rests_on_lower("thickness = 0.004"));
    assert!(upper_rests_on_lower(
        "objects_settings = { lower = { layers = 3 }, upper = { layers = 2 } }"
    ));
    assert!(!upper_rests_on_lower(
        "objects_settings = { lower = { layers = 1 }, upper = { layers = 2 } }"
    ));
    assert!(!upper_rests_on_lower(r#"exclude = [["upper", "lower"]]"#));
    // Self-collision is not a layer matter: an object on no layer still collides with
    // itself, and with nothing else.
    assert!(!upper_rests_on_lower(
        "objects_settings = { upper = { layers = 0, self_collision = true } }"
    ));
}

#[test]
fn a_collider_only_stops_objects_sharing_one_of_its_layers() {
    // A cloth dropped on a plane on layer 2: on layer 1 it falls through, on layers 1 and 2
    // it lands.
    let scene = |cloth_layers: u32| {
        cloth_over_ground(
            0.1,
            &format!(
                r#"layers = {cloth_layers}, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0], layers = 2 }}]"#
            ),
        )
    };
    let mut through = scene(1);
    let mut lands = scene(3);
    run_frames(&mut through, 30);
    run_frames(&mut lands, 30);
    assert!(y_range(&through, "cloth").1 < -0.5);
    let (lo, _) = y_range(&lands, "cloth");
    assert!((lo - 0.005).abs() < 1e-9, "rests at {lo}");
}

#[test]
fn each_object_rests_at_its_own_thickness() {
    // Three cloths on the ground with thicknesses 2, 10 and 5 mm (the default), the ground
    // with 1 mm of its own: each rests flat at its thickness plus the ground's.
    let cloth = |name: &str, x: f64| {
        format!(
            "[[objects]]\nname = \"{name}\"\nmass = 0.05\n[objects.grid]\nsize = [0.2, 0.2]\n\
             resolution = [4, 4]\nplane = \"xz\"\norigin = [{x}, 0.03, 0.0]\n"
        )
    };
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 4
{}{}{}
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "collision"
params = {{ objects_settings = {{ thin = {{ thickness = 0.002 }}, thick = {{ thickness = 0.01 }} }}, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0], thickness = 0.001 }}] }}
"#,
        cloth("thin", -0.8),
        cloth("thick", -0.4),
        cloth("default", 0.0)
    );
    let mut sim = simulation(&text, &[]);
    run_frames(&mut sim, 40);
    for (name, r) in [("thin", 0.002), ("thick", 0.01), ("default", 0.005)] {
        let (lo, hi) = y_range(&sim, name);
        assert!(
            (lo - (r + 0.001)).abs() < 1e-9 && (hi - lo) < 1e-9,
            "{name}: {lo}..{hi}, expected {}",
            r + 0.001
        );
    }
}

/// A rope of 8 segments pinned straight along x at y = 0 and a free rope of 8 segments
/// dropped across it along z, crossing it in the middle of an edge of each (so only an
/// edge–edge pair can stop it); `params` for the collision group. Returns the height of the
/// free rope's lowest vertex after 0.5 s: above −0.31 m (its half length and the
/// thicknesses) when it hangs on the bar, below −0.5 m when it fell through.
fn crossing_ropes(params: &str) -> f64 {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 8
[[objects]]
name = "bar"
mass = 0.1
pins = ["all"]
[objects.rope]
start = [-0.3, 0.0, 0.0375]
end = [0.3, 0.0, 0.0375]
segments = 8
[[objects]]
name = "rope"
mass = 0.05
[objects.rope]
start = [0.021, 0.05, -0.3]
end = [0.021, 0.05, 0.3]
segments = 8
[[constraints]]
kind = "stretch"
objects = ["rope"]
params = {{ compliance = 0.0 }}
[[constraints]]
kind = "collision"
params = {{ thickness = 0.005, friction_static = 0.5, friction_dynamic = 0.5, {params} }}
"#
    );
    let mut sim = simulation(&text, &[]);
    run_frames(&mut sim, 30);
    y_range(&sim, "rope").0
}

#[test]
fn switching_a_primitive_off_lets_through_exactly_the_contacts_it_carries() {
    // Two ropes touch only edge against edge: with the bar's edges off, the rope falls
    // through it; its vertices or faces (it has none) change nothing.
    let on = crossing_ropes("self_collision = false");
    assert!(on > -0.31, "the rope fell off the bar: {on}");
    assert!(crossing_ropes("objects_settings = { bar = { edge = false } }") < -0.5);
    assert!(crossing_ropes("objects_settings = { rope = { edge = false } }") < -0.5);
    let vertices_off = crossing_ropes(
        "self_collision = false, objects_settings = { bar = { vertex = false, face = false } }",
    );
    assert!((vertices_off - on).abs() < 1e-9, "{vertices_off} vs {on}");

    // A cloth meets the ground plane through its vertices only: with them off it falls
    // through; with its faces or edges off it still lands.
    let ground = |settings: &str| {
        let mut sim = cloth_over_ground(
            0.05,
            &format!(
                r#"objects_settings = {{ cloth = {{ {settings} }} }}, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }}]"#
            ),
        );
        run_frames(&mut sim, 30);
        y_range(&sim, "cloth").0
    };
    assert!((ground("vertex = true") - 0.005).abs() < 1e-9);
    assert!(ground("vertex = false") < -0.5);
    assert!((ground("face = false, edge = false") - 0.005).abs() < 1e-9);
}

#[test]
fn a_group_in_which_nothing_can_collide_is_never_scheduled() {
    // Two cloths on disjoint layers without self-collision, and a ground plane on a third
    // layer: no pair can ever collide. The group is built, has no constraint, and the core
    // never calls it.
    let text = two_cloths(
        r#"self_collision = false, objects_settings = { lower = { layers = 1 }, upper = { layers = 2 } }, colliders = [{ type = "plane", point = [0.0, -0.2, 0.0], normal = [0.0, 1.0, 0.0], layers = 4 }]"#,
    );
    let mut sim = simulation(&text, &[]);
    let g = sim
        .groups
        .iter()
        .position(|g| g.kind == "collision")
        .expect("collision group");
    assert_eq!(sim.groups[g].len, 0);
    assert!(
        sim.calls.iter().all(|c| c.group as usize != g),
        "scheduled: {:?}",
        sim.calls
    );
    // It runs: the upper cloth falls through everything.
    run_frames(&mut sim, 30);
    assert!(y_range(&sim, "upper").1 < -0.5);
    // The control: the same scene with a shared layer schedules the group every pass.
    let sim = simulation(&two_cloths("thickness = 0.004"), &[]);
    let g = sim
        .groups
        .iter()
        .position(|g| g.kind == "collision")
        .unwrap();
    assert!(sim.groups[g].len > 0);
    assert_eq!(
        sim.calls.iter().filter(|c| c.group as usize == g).count(),
        4
    );
}

/// An OBJ holding one object made of two parallel grids (2 cm spacing) `gap` apart: the
/// lower one of 10 × 10 vertices at y = 0, the upper one of 8 × 8 at y = gap, shifted by a
/// cell and a third (within the lower one's footprint, no vertex above another).
fn two_layer_obj(gap: f64) -> std::path::PathBuf {
    let dir = temp_dir("collision-two-layers");
    let mut obj = String::new();
    for (n, y, shift) in [(10, 0.0, 0.0), (8, gap, 0.02 * 4.0 / 3.0)] {
        for r in 0..n {
            for c in 0..n {
                obj.push_str(&format!(
                    "v {} {y} {}\n",
                    c as f64 * 0.02 + shift,
                    r as f64 * 0.02 + shift
                ));
            }
        }
    }
    for (n, base) in [(10, 1), (8, 101)] {
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let a = base + r * n + c;
                obj.push_str(&format!("f {} {} {}\n", a, a + n, a + n + 1));
                obj.push_str(&format!("f {} {} {}\n", a, a + n + 1, a + 1));
            }
        }
    }
    let path = dir.join("two_layers.obj");
    std::fs::write(&path, obj).expect("write obj");
    path
}

#[test]
fn two_layers_of_one_object_closer_than_twice_its_thickness_still_collide() {
    // One object, two layers 6 mm apart, thickness 5 mm: every pair of one layer with the
    // other is closer than 2 × 5 mm in the rest shape. The lower layer is pinned, the upper
    // one thrown down at 3 m/s. Such pairs are kept half their rest distance apart (3 mm
    // straight across), not dropped: the upper layer lands on the lower one, and no two
    // triangles ever intersect.
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 4
[[objects]]
name = "quilt"
mass = 0.1
velocity = [0.0, -3.0, 0.0]
pins = [{{ min = [-1.0, -0.001, -1.0], max = [1.0, 0.001, 1.0] }}]
[objects.mesh]
path = "{}"
[[constraints]]
kind = "stretch"
params = {{ compliance = 0.0, compression_compliance = 1e-3 }}
[[constraints]]
kind = "collision"
params = {{ thickness = 0.005 }}
"#,
        two_layer_obj(0.006).display()
    );
    let mut sim = simulation(&text, &[]);
    let upper = 100..164;
    let tris: Vec<[u32; 3]> = sim.object("quilt").unwrap().triangles.clone();
    let (lower_tris, upper_tris) = tris.split_at(162);
    let mut worst = 0;
    let mut lowest = f64::INFINITY;
    for _ in 0..20 {
        for s in 0..sim.settings.substeps {
            sim.substep(s).unwrap();
            let x = sim.positions();
            for a in lower_tris {
                for b in upper_tris {
                    let pa = a.map(|i| x[i as usize]);
                    let pb = b.map(|i| x[i as usize]);
                    if distance::triangles_intersect(pa, pb) {
                        worst += 1;
                    }
                }
            }
            lowest = upper.clone().map(|i| x[i].y).fold(lowest, f64::min);
        }
        sim.frame += 1;
    }
    assert_eq!(worst, 0, "intersecting triangle pairs between the layers");
    // Above the lower layer (at y = 0) by at least half the rest gap, to rounding, and
    // resting on it, not bounced away.
    let (_, highest) = y_range(&sim, "quilt");
    eprintln!("two layers: the upper came down to {lowest} m, ends below {highest} m");
    assert!(
        lowest >= 0.003 - 1e-9,
        "the upper layer came down to {lowest}"
    );
    assert!(
        highest < 0.01,
        "the upper layer did not stay on the lower: {highest}"
    );
}
