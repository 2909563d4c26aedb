//! The `collision` plugin, loaded from its library like any user's plugin: particles and small
//! meshes against sheets, planes and each other. Each test states one contract of the issue:
//! no crossing at any speed (a particle at 1,000 m/s, a small stiff mesh at 100 m/s, one
//! substep per frame), the paper's Figure 20 (three particles colliding within one step end
//! separated and in order), a bouncing ball whose bounce heights fall by e² and which comes
//! to rest without jitter, Coulomb friction on an incline (sticks below the cone, slides at
//! g(sin θ − μd cos θ) above), and degenerate input that never produces a NaN.

#[path = "../../plugins/collision/src/narrow_phase/distance.rs"]
#[allow(dead_code)]
mod distance;

use glam::DVec3;
use nucleus_tests::*;

/// The signed distance of `p` to the closest triangle of `tris` (positive on the side its
/// winding's normal points to), and the distance itself.
fn signed_distance_to(p: DVec3, tris: &[[DVec3; 3]]) -> f64 {
    let mut best = (f64::INFINITY, 0.0);
    for t in tris {
        let (b, d2) = distance::point_triangle_closest(p, t[0], t[1], t[2]);
        if d2 < best.0 {
            let q = b[0] * t[0] + b[1] * t[1] + b[2] * t[2];
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            best = (d2, (p - q).dot(n).signum());
        }
    }
    best.1 * best.0.sqrt()
}

/// A 1 m sheet of 10 × 10 vertices in the xy plane at z = 0 (normal +z), pinned along its
/// whole border (so nothing can slip around it: reaching the other side means crossing it),
/// hard stretch, and a `collision` group over everything.
fn sheet_scene(extra_objects: &str, substeps: u32, frames: u32) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
frames = {frames}
substeps = {substeps}
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "sheet"
mass = 1.0
pins = ["edge:row0", "edge:rowN", "edge:col0", "edge:colN"]
[objects.grid]
size = [1.0, 1.0]
resolution = [10, 10]
plane = "xy"
{extra_objects}
[[constraints]]
kind = "stretch"
params = {{ compliance = 0.0 }}
[[constraints]]
kind = "collision"
params = {{ thickness = 0.002 }}
"#
    )
}

#[test]
fn a_particle_at_1000_m_per_s_never_crosses_a_pinned_sheet() {
    let text = sheet_scene(
        r#"
[[objects]]
name = "bullet"
mass = 0.001
velocity = [0.0, 0.0, -1000.0]
[objects.particles]
min = [0.47, 0.52, 0.5]
max = [0.47, 0.52, 0.5]
count = [1, 1, 1]
"#,
        1,
        30,
    );
    let mut sim = simulation(&text, &[]);
    let b = particles_of(&sim, "bullet").start;
    let mut min_side = f64::INFINITY;
    run(&mut sim, 30, |sim| {
        let side = signed_distance_to(sim.positions()[b], &triangles(sim, "sheet"));
        min_side = min_side.min(side);
    });
    // It stays on the +z side. (The thickness, 2 × 2 mm, is kept to within a fraction: the
    // last pass's Gauss-Seidel sweep against a sheet pulled back by hard stretch.)
    assert!(min_side > 0.002, "closest approach {min_side}");
    // It did hit: the sheet was pushed (momentum went somewhere).
    let sheet = particles_of(&sim, "sheet");
    let moved = sheet
        .map(|i| sim.positions()[i].z.abs())
        .fold(0.0, f64::max);
    assert!(moved > 1e-3, "the sheet never moved ({moved})");
}

#[test]
fn a_small_stiff_mesh_at_100_m_per_s_never_crosses_a_pinned_sheet() {
    let text = sheet_scene(
        r#"
[[objects]]
name = "shard"
mass = 0.05
velocity = [0.0, 0.0, -100.0]
[objects.grid]
size = [0.1, 0.1]
resolution = [3, 3]
plane = "xz"
origin = [0.43, 0.46, 0.3]
"#,
        1,
        30,
    );
    let mut sim = simulation(&text, &[]);
    let shard = particles_of(&sim, "shard");
    let mut worst = f64::INFINITY;
    let mut intersections = 0;
    run(&mut sim, 30, |sim| {
        let sheet = triangles(sim, "sheet");
        for i in shard.clone() {
            worst = worst.min(signed_distance_to(sim.positions()[i], &sheet));
        }
        for a in &triangles(sim, "shard") {
            for b in &sheet {
                if distance::triangles_intersect(*a, *b) {
                    intersections += 1;
                }
            }
        }
    });
    assert_eq!(intersections, 0);
    assert!(worst > 0.002, "closest approach {worst}");
}

/// Three single-particle objects on the x axis.
fn three_particles(va: f64, vb: f64, vc: f64, thickness: f64) -> String {
    let p = |name: &str, x: f64, v: f64| {
        format!(
            r#"
[[objects]]
name = "{name}"
mass = 1.0
velocity = [{v}, 0.0, 0.0]
[objects.particles]
min = [{x}, 0.0, 0.0]
max = [{x}, 0.0, 0.0]
count = [1, 1, 1]
"#
        )
    };
    format!(
        r#"
[solver]
frame_rate = 10.0
frames = 1
substeps = 1
gravity = [0.0, 0.0, 0.0]
{}{}{}
[[constraints]]
kind = "collision"
params = {{ thickness = {thickness} }}
"#,
        p("a", 0.0, va),
        p("b", 0.1, vb),
        p("c", 0.2, vc)
    )
}

#[test]
fn figure_20_three_particles_colliding_within_one_step_end_separated_in_order() {
    // a and c rush at b from both sides, each would pass b several times over in the step.
    for (va, vb, vc) in [(5.0, 0.0, -5.0), (8.0, 0.0, 0.0), (3.0, -1.0, -7.0)] {
        let mut sim = simulation(&three_particles(va, vb, vc, 0.01), &[]);
        for _ in 0..3 {
            sim.step_frame().unwrap();
            let x = sim.positions();
            let (a, b, c) = (x[0].x, x[1].x, x[2].x);
            assert!(a < b && b < c, "out of order: {a} {b} {c}");
            // Separated by the thickness (2 × 1 cm) to within 0.1 %: the chain is solved by
            // Gauss-Seidel, which converges geometrically over the passes.
            assert!(
                b - a >= 0.02 * 0.999 && c - b >= 0.02 * 0.999,
                "{a} {b} {c}"
            );
        }
    }
}

fn bouncing_ball(restitution: f64, substeps: u32) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
frames = 300
substeps = {substeps}
gravity = [0.0, -9.81, 0.0]
[[objects]]
name = "ball"
mass = 0.1
[objects.particles]
min = [0.0, 1.0, 0.0]
max = [0.0, 1.0, 0.0]
count = [1, 1, 1]
[[constraints]]
kind = "collision"
params = {{ thickness = 0.05, restitution = {restitution}, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }}] }}
"#
    )
}

#[test]
fn a_bouncing_ball_loses_e_squared_of_its_height_per_bounce_and_comes_to_rest() {
    let e: f64 = 0.5;
    let mut sim = simulation(&bouncing_ball(e, 20), &[]);
    let rest_height = 0.05;
    let mut apexes = Vec::new();
    let (mut prev_y, mut rising) = (1.0, false);
    let mut lowest: f64 = f64::INFINITY;
    let mut heights = Vec::new();
    run(&mut sim, 300, |sim| {
        let y = sim.positions()[0].y;
        lowest = lowest.min(y);
        if rising && y < prev_y {
            apexes.push(prev_y - rest_height);
        }
        rising = y > prev_y;
        prev_y = y;
        heights.push(y);
    });
    assert!(
        lowest >= rest_height - 1e-12,
        "went into the ground: {lowest}"
    );
    let first = 1.0 - rest_height;
    let mut previous = first;
    for (k, &a) in apexes.iter().take(3).enumerate() {
        let ratio = a / previous;
        assert!(
            (ratio / (e * e) - 1.0).abs() < 0.05,
            "bounce {k}: height ratio {ratio}, expected {} (apexes {apexes:?})",
            e * e
        );
        previous = a;
    }
    assert!(apexes.len() >= 3, "apexes {apexes:?}");
    // At rest well before the end (5 s): the last second is still to 1e-6 m, and the ball
    // sits at its thickness.
    let last_second = &heights[heights.len() - 20 * 60..];
    let (lo, hi) = last_second
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &y| {
            (l.min(y), h.max(y))
        });
    assert!(hi - lo < 1e-6, "jitter {} m at rest", hi - lo);
    assert!((lo - rest_height).abs() < 1e-6, "rests at {lo}");
    assert!(sim.velocities()[0].length() < 1e-6);
}

fn incline(theta_deg: f64, mu_s: f64, mu_d: f64, object: &str) -> String {
    let t = theta_deg.to_radians();
    let n = [-t.sin(), t.cos(), 0.0];
    format!(
        r#"
[solver]
frame_rate = 60.0
frames = 60
substeps = 10
gravity = [0.0, -9.81, 0.0]
{object}
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "collision"
params = {{ thickness = 0.01, friction_static = {mu_s}, friction_dynamic = {mu_d}, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [{}, {}, {}] }}] }}
"#,
        n[0], n[1], n[2]
    )
}

/// A particle resting on the plane through the origin with normal `n(θ)`, at the thickness.
fn particle_on_incline(theta_deg: f64) -> String {
    let t = theta_deg.to_radians();
    let p = DVec3::new(-t.sin(), t.cos(), 0.0) * 0.01;
    format!(
        r#"
[[objects]]
name = "p"
mass = 1.0
[objects.particles]
min = [{x}, {y}, 0.0]
max = [{x}, {y}, 0.0]
count = [1, 1, 1]
"#,
        x = p.x,
        y = p.y
    )
}

/// Distance travelled along the incline after 1 s.
fn slide(theta_deg: f64, mu_s: f64, mu_d: f64) -> f64 {
    let mut sim = simulation(
        &incline(theta_deg, mu_s, mu_d, &particle_on_incline(theta_deg)),
        &[],
    );
    let start = sim.positions()[0];
    for _ in 0..60 {
        sim.step_frame().unwrap();
    }
    (sim.positions()[0] - start).length()
}

#[test]
fn friction_holds_a_particle_on_an_incline_below_the_static_cone() {
    // tan 20° = 0.364 < 0.5.
    let d = slide(20.0, 0.5, 0.3);
    assert!(d < 1e-9, "slid {d} m");
}

#[test]
fn friction_lets_a_particle_slide_at_g_sin_minus_mu_d_cos_above_the_cone() {
    for (theta, mu_s, mu_d) in [(35.0f64, 0.5, 0.3), (30.0, 0.2, 0.1), (45.0, 0.0, 0.0)] {
        let t = theta.to_radians();
        let a = 9.81 * (t.sin() - mu_d * t.cos());
        let want = 0.5 * a * 1.0 * 1.0;
        let got = slide(theta, mu_s, mu_d);
        assert!(
            (got / want - 1.0).abs() < 0.05,
            "θ = {theta}°: slid {got} m, expected {want} m"
        );
    }
}

#[test]
fn degenerate_geometry_stays_finite_over_10000_steps() {
    // Three coincident particles, a cloth with a collapsed row (zero-area triangles and
    // coincident vertices), all colliding with each other, themselves and the ground.
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
frames = 1000
substeps = 10
[[objects]]
name = "dust"
mass = 0.01
[objects.particles]
min = [0.2, 0.3, 0.2]
max = [0.2, 0.3, 0.2]
count = [3, 1, 1]
[[objects]]
name = "rag"
mass = 0.1
[objects.mesh]
path = "{}"
[[constraints]]
kind = "collision"
params = {{ thickness = 0.005, colliders = [{{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }}] }}
"#,
        degenerate_obj().display()
    );
    let mut sim = simulation(&text, &[]);
    for _ in 0..1000 {
        sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
    }
    assert!(sim.positions().iter().all(|p| p.is_finite()));
    assert!(sim.velocities().iter().all(|v| v.is_finite()));
    // Everything came to rest on the ground, above it.
    assert!(sim.positions().iter().all(|p| p.y >= 0.005 - 1e-9));
}

/// A 4 × 3 vertex patch whose middle row is collapsed onto its first row (coincident
/// vertices, zero-area triangles), plus a sliver triangle with three collinear vertices.
fn degenerate_obj() -> std::path::PathBuf {
    let dir = temp_dir("collision-degenerate");
    let mut obj = String::new();
    for r in 0..3 {
        for c in 0..4 {
            let z = if r == 1 { 0.0 } else { r as f64 * 0.1 };
            obj.push_str(&format!("v {} 0.2 {}\n", c as f64 * 0.1, z));
        }
    }
    obj.push_str("v 0.0 0.25 0.0\nv 0.1 0.25 0.0\nv 0.2 0.25 0.0\n");
    for r in 0..2 {
        for c in 0..3 {
            let a = r * 4 + c + 1;
            obj.push_str(&format!("f {} {} {}\n", a, a + 1, a + 5));
            obj.push_str(&format!("f {} {} {}\n", a, a + 5, a + 4));
        }
    }
    obj.push_str("f 13 14 15\n");
    let path = dir.join("degenerate.obj");
    std::fs::write(&path, obj).expect("write obj");
    path
}
