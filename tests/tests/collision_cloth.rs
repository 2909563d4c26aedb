//! The `collision` plugin, loaded from its library, on cloth: draped over an analytic sphere
//! and box (no vertex ever inside by more than 1e-6 m beyond its thickness, checked after
//! every substep), piled into a heap of folds and twisted by two turning edges (no two
//! triangles ever intersect, by an exact triangle–triangle test), and the paper's rubber band
//! (Figures 10–12): the interleaved schedule leaves less strain where the band wraps the bars
//! than the sequential one.
//!
//! The scene-sized versions (`scenes/*.toml`) are measured by the ignored test
//! `scene_figures` (run it with `cargo test --release -p nucleus-tests --test collision_cloth
//! -- --ignored --nocapture` after `cargo xtask plugins --release`).

#[path = "../../plugins/collision/src/narrow_phase/distance.rs"]
#[allow(dead_code)]
mod distance;

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// Runs `frames` frames substep by substep, calling `check(sim, substep)` after every
/// substep.
fn run(sim: &mut Simulation, frames: u32, mut check: impl FnMut(&Simulation, u32)) {
    for _ in 0..frames {
        for s in 0..sim.settings.substeps {
            sim.substep(s).unwrap_or_else(|e| panic!("step: {e}"));
            check(sim, s);
        }
        sim.frame += 1;
    }
}

/// Number of pairs of triangles (of all objects) that share no vertex and intersect, by the
/// exact test. Broad phase: sort by the boxes' lower x and sweep.
pub fn intersecting_triangle_pairs(sim: &Simulation) -> usize {
    let x = sim.positions();
    let tris: Vec<[u32; 3]> = sim
        .objects
        .iter()
        .flat_map(|o| o.surface_triangles.iter().copied())
        .collect();
    let boxes: Vec<(DVec3, DVec3)> = tris
        .iter()
        .map(|t| {
            let p = t.map(|i| x[i as usize]);
            (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]))
        })
        .collect();
    let mut order: Vec<usize> = (0..tris.len()).collect();
    order.sort_by(|&a, &b| boxes[a].0.x.total_cmp(&boxes[b].0.x));
    let mut count = 0;
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if boxes[b].0.x > boxes[a].1.x {
                break;
            }
            let (ba, bb) = (boxes[a], boxes[b]);
            if ba.0.cmpgt(bb.1).any() || bb.0.cmpgt(ba.1).any() {
                continue;
            }
            if tris[a].iter().any(|v| tris[b].contains(v)) {
                continue;
            }
            let pa = tris[a].map(|i| x[i as usize]);
            let pb = tris[b].map(|i| x[i as usize]);
            if distance::triangles_intersect(pa, pb) {
                count += 1;
            }
        }
    }
    count
}

/// A `res × res` cloth of side 1 m, horizontal at height `y`, centred on the y axis.
fn cloth(res: u32, y: f64) -> String {
    format!(
        r#"
[[objects]]
name = "cloth"
mass = 0.3
[objects.grid]
size = [1.0, 1.0]
resolution = [{res}, {res}]
plane = "xz"
origin = [-0.5, {y}, -0.5]
"#
    )
}

const STRETCH: &str = r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
params = { compliance = 0.0, compression_compliance = 1e-3 }
"#;

fn drape(collider: &str, frames: u32) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
frames = {frames}
substeps = 8
{}
{STRETCH}
[[constraints]]
kind = "collision"
objects = ["cloth"]
params = {{ thickness = 0.005, friction_static = 0.3, friction_dynamic = 0.2, colliders = [{collider}] }}
"#,
        cloth(32, 0.35)
    )
}

/// Drapes the 32 × 32 cloth over `collider` for `frames` frames and returns the deepest
/// penetration beyond the thickness, measured by `depth(x)` (positive inside) after every
/// substep.
fn deepest(collider: &str, frames: u32, depth: impl Fn(DVec3) -> f64) -> f64 {
    let mut sim = simulation(&drape(collider, frames), &[]);
    let cloth = particles_of(&sim, "cloth");
    let mut worst = f64::NEG_INFINITY;
    run(&mut sim, frames, |sim, _| {
        for i in cloth.clone() {
            worst = worst.max(depth(sim.positions()[i]));
        }
    });
    // The cloth did reach the collider.
    let lowest = cloth
        .map(|i| sim.positions()[i].y)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest < 0.2, "the cloth never fell ({lowest})");
    worst
}

#[test]
fn cloth_draped_on_a_sphere_never_enters_it_beyond_1e_6_m() {
    let (r, thickness) = (0.25, 0.005);
    let worst = deepest(
        r#"{ type = "sphere", center = [0.0, 0.0, 0.0], radius = 0.25 }"#,
        40,
        |p| (r + thickness) - p.length(),
    );
    eprintln!("cloth on sphere: deepest penetration {worst:e} m");
    assert!(worst <= 1e-6, "{worst}");
    // Touching (the check is not vacuous).
    assert!(worst > -1e-3, "never touched: {worst}");
}

#[test]
fn cloth_draped_on_a_box_never_enters_it_beyond_1e_6_m() {
    let half = DVec3::new(0.2, 0.1, 0.2);
    let worst = deepest(
        r#"{ type = "box", center = [0.0, 0.0, 0.0], half_extents = [0.2, 0.1, 0.2] }"#,
        40,
        |p| {
            let d = p.abs() - half;
            let outside = d.max(DVec3::ZERO).length();
            let inside = d.max_element().min(0.0);
            0.005 - (outside + inside)
        },
    );
    eprintln!("cloth on box: deepest penetration {worst:e} m");
    assert!(worst <= 1e-6, "{worst}");
    assert!(worst > -1e-3, "never touched: {worst}");
}

#[test]
fn cloth_dropped_into_a_heap_never_intersects_itself() {
    // A vertical 20 × 20 cloth falls edge-first onto the ground; gravity leans a little
    // towards +z, so once friction holds its lower edge it topples and folds onto itself.
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
frames = 60
substeps = 8
gravity = [0.0, -9.81, 2.0]
[[objects]]
name = "cloth"
mass = 0.3
velocity = [0.0, -1.0, 0.0]
[objects.grid]
size = [0.6, 0.6]
resolution = [20, 20]
plane = "xy"
origin = [-0.3, 0.05, 0.0]
{STRETCH}
[[constraints]]
kind = "collision"
objects = ["cloth"]
params = {{ thickness = 0.004, friction_static = 0.8, friction_dynamic = 0.6, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }}] }}
"#
    );
    let mut sim = simulation(&text, &[]);
    let mut worst = 0;
    let mut frames_checked = 0;
    let cloth = particles_of(&sim, "cloth");
    run(&mut sim, 60, |sim, s| {
        if s + 1 == sim.settings.substeps {
            worst = worst.max(intersecting_triangle_pairs(sim));
            frames_checked += 1;
        }
    });
    assert_eq!(frames_checked, 60);
    assert_eq!(worst, 0, "intersecting triangle pairs");
    // It did fold: its height is far below its side.
    let top = cloth
        .map(|i| sim.positions()[i].y)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(top < 0.2, "still standing: top at {top}");
}

#[test]
fn cloth_twisted_by_two_turning_edges_never_intersects_itself() {
    // The strip's two short edges follow tests/data/collision/cloth_twist (half a turn per
    // second each, in opposite directions); one second is a full relative turn.
    let text = r#"
[solver]
frame_rate = 60.0
frames = 60
substeps = 8
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "cloth"
mass = 0.2
pins = [{ min = [-1.0, -1.0, -1.0], max = [0.001, 2.0, 1.0] }, { min = [0.999, -1.0, -1.0], max = [2.0, 2.0, 1.0] }]
[objects.mesh]
path = "data/collision/cloth_twist/twist_0000.obj"
sequence = "data/collision/cloth_twist/twist_{frame:04}.obj"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
params = { compliance = 0.0, compression_compliance = 1e-3 }
[[constraints]]
kind = "collision"
objects = ["cloth"]
params = { thickness = 0.004 }
"#;
    let mut sim = simulation(text, &[]);
    let mut worst = 0;
    run(&mut sim, 60, |sim, s| {
        if s + 1 == sim.settings.substeps {
            worst = worst.max(intersecting_triangle_pairs(sim));
        }
    });
    assert_eq!(worst, 0, "intersecting triangle pairs");
    // The middle of the strip did turn with its edges (it is twisted, not flat).
    let x = sim.positions();
    let spread = (0..8)
        .map(|i| x[i * 20 + 10].y)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), y| {
            (l.min(y), h.max(y))
        });
    assert!(spread.1 - spread.0 > 0.05, "not twisted: {spread:?}");
}

/// The rubber band around two bars (capsules of radius 2 cm) that move apart at 0.1 m/s
/// each for 0.5 s; returns (maximum strain over the edges that wrap the bars, maximum strain
/// over all edges) at the end.
fn rubber_band(schedule: &str) -> (f64, f64) {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
frames = 30
substeps = 10
schedule = "{schedule}"
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "band"
mass = 0.01
[objects.mesh]
path = "data/collision/rubber_band.obj"
[[constraints]]
kind = "stretch"
objects = ["band"]
importance = 4
params = {{ compliance = 1e-4, compression_compliance = 1e-2 }}
[[constraints]]
kind = "collision"
objects = ["band"]
importance = 4
params = {{ thickness = 0.005, friction_static = 0.0, friction_dynamic = 0.0, colliders = [
  {{ type = "capsule", a = [-0.15, 0.0, -0.1], b = [-0.15, 0.0, 0.1], radius = 0.02, velocity = [-0.1, 0.0, 0.0] }},
  {{ type = "capsule", a = [0.15, 0.0, -0.1], b = [0.15, 0.0, 0.1], radius = 0.02, velocity = [0.1, 0.0, 0.0] }},
] }}
"#
    );
    let mut sim = simulation(&text, &[]);
    let rest: Vec<DVec3> = sim.positions().to_vec();
    for _ in 0..30 {
        sim.step_frame().unwrap();
    }
    let x = sim.positions();
    let bar_x = 0.15 + 0.1 * 0.5;
    let (mut ends, mut all) = (0.0f64, 0.0f64);
    for &[i, j] in &sim.object("band").expect("band").edges {
        let (i, j) = (i as usize, j as usize);
        let l0 = rest[i].distance(rest[j]);
        let strain = x[i].distance(x[j]) / l0 - 1.0;
        all = all.max(strain);
        let mid = 0.5 * (x[i] + x[j]);
        if (mid.x.abs() - bar_x).abs() < 0.04 {
            ends = ends.max(strain);
        }
    }
    (ends, all)
}

#[test]
fn rubber_band_interleaved_schedule_strains_the_ends_less_than_sequential() {
    let (inter_ends, inter_all) = rubber_band("interleaved");
    let (seq_ends, seq_all) = rubber_band("sequential");
    eprintln!(
        "rubber band: max strain at the ends interleaved {inter_ends:.4}, sequential \
         {seq_ends:.4}; over the band {inter_all:.4} / {seq_all:.4}"
    );
    assert!(
        inter_ends > 0.05,
        "the band was not stretched: {inter_ends}"
    );
    assert!(
        inter_ends < seq_ends,
        "interleaved {inter_ends} vs sequential {seq_ends}"
    );
}

/// Runs a scene file and returns (deepest thickness violation reported by the collision
/// group over all frames, most intersecting triangle pairs in any frame).
fn scene_figures(path: &str) -> (f64, usize) {
    let scene =
        nucleus_core::Scene::load(std::path::Path::new(path)).unwrap_or_else(|e| panic!("{e}"));
    let reg = registry(&[plugin_dir()]);
    let mut sim = Simulation::build(&scene, &reg).unwrap_or_else(|e| panic!("{e}"));
    let (mut pen, mut pairs) = (0.0f64, 0usize);
    for _ in 0..scene.file.solver.frames {
        sim.step_frame().unwrap_or_else(|e| panic!("{path}: {e}"));
        for (name, v) in sim.reports().expect("reports") {
            if name.ends_with("max_penetration") {
                pen = pen.max(v);
            }
        }
        pairs = pairs.max(intersecting_triangle_pairs(&sim));
    }
    (pen, pairs)
}

#[test]
#[ignore = "minutes in debug: run in release (see the file's docs)"]
fn scene_figures_for_the_closing_note() {
    for name in [
        "bullet",
        "bouncing_ball",
        "cloth_on_sphere",
        "cloth_heap",
        "cloth_twist",
        "rubber_band",
        "collision_sweep",
    ] {
        let t = std::time::Instant::now();
        let (pen, pairs) = scene_figures(&format!("../scenes/{name}.toml"));
        eprintln!(
            "{name}: worst penetration beyond the thickness {pen:e} m, most intersecting \
             triangle pairs in a frame {pairs} ({:.1} s)",
            t.elapsed().as_secs_f64()
        );
        assert_eq!(pairs, 0, "{name}");
    }
}
