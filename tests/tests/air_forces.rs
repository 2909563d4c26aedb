//! The `air` plugin's model, through the real, dynamically loaded plugins: a plate falling
//! face-on reaches `v_t = sqrt(2 m g / (ρ C_d A))`; a plate held at an angle of attack feels
//! exactly the model's drag, lift and skin drag; a closed surface in a uniform wind with no
//! lift feels a force along the wind of exactly `½ ρ C_d U² Σ A|n̂·ŵ|` (twice its silhouette);
//! ropes and particles feel the wind too; degenerate triangles and zero-length edges give no
//! NaN; a gusty wind is bit-identical for a seed; groups give objects their own coefficients.

use std::f64::consts::PI;
use std::path::PathBuf;

use glam::DVec3;
use nucleus_core::{Scene, Simulation};
use nucleus_tests::*;

const RHO: f64 = 1.2;

/// The value of the report column `name` (e.g. `air.force_y`).
fn report(sim: &mut Simulation, name: &str) -> f64 {
    sim.reports()
        .expect("report")
        .into_iter()
        .find(|(n, _)| n == name)
        .map(|(_, v)| v)
        .unwrap_or_else(|| panic!("no report column {name}"))
}

fn force(sim: &mut Simulation, group: &str) -> DVec3 {
    DVec3::new(
        report(sim, &format!("{group}.force_x")),
        report(sim, &format!("{group}.force_y")),
        report(sim, &format!("{group}.force_z")),
    )
}

/// A scene read from `text` written to a fresh directory holding `files` (name, contents),
/// built with the staged plugins.
fn simulation_with_files(tag: &str, text: &str, files: &[(&str, String)]) -> Simulation {
    let dir = temp_dir(tag);
    for (name, contents) in files {
        std::fs::write(dir.join(name), contents).expect("write fixture");
    }
    let path: PathBuf = dir.join("scene.toml");
    std::fs::write(&path, text).expect("write scene");
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("scene: {e}"));
    Simulation::build(&scene, &registry(&[plugin_dir()])).unwrap_or_else(|e| panic!("build: {e}"))
}

#[test]
fn plate_falling_face_on_reaches_the_terminal_velocity() {
    // 1 m², 0.1 kg (density lumped by area, so face-on drag accelerates every vertex alike),
    // C_d = 1.2: v_t = sqrt(2 m g / (ρ C_d A)) = 1.167 m/s, reached with time constant
    // v_t/g = 0.12 s as v(t) = v_t tanh(g t / v_t).
    let (m, g, cd) = (0.1, 9.81, 1.2);
    let vt = (2.0 * m * g / (RHO * cd * 1.0)).sqrt();
    let mut sim = simulation(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
[[objects]]
name = "plate"
density = 0.1
[objects.grid]
size = [1.0, 1.0]
resolution = [5, 5]
plane = "xz"
[[constraints]]
kind = "stretch"
objects = ["plate"]
[[constraints]]
kind = "air"
objects = ["plate"]
params = { drag = 1.2, lift = 0.0, tangential_drag = 0.0 }
"#,
        &[],
    );
    let mean_vy = |sim: &Simulation| {
        let v = sim.velocities();
        v.iter().map(|v| v.y).sum::<f64>() / v.len() as f64
    };
    for frame in 1..=180 {
        sim.step_frame().expect("step");
        let t = frame as f64 / 60.0;
        let expected = -vt * (g * t / vt).tanh();
        // The transient lags the continuous solution by about one substep of gravity
        // (h g = 0.016 m/s, 1.4 % of v_t).
        let v = mean_vy(&sim);
        assert!(
            (v - expected).abs() < 0.03 * vt,
            "t = {t:.3} s: {v} vs {expected}"
        );
    }
    // Converged (25 time constants): the linearly implicit step keeps the terminal velocity to
    // ½ (h g / v_t)² ≈ 1e-4; the issue asks for 2 %.
    let v = mean_vy(&sim);
    assert!((v + vt).abs() < 1e-3 * vt, "{v} vs {vt}");
    // Face-on drag is uniform per unit mass: the plate stays flat and level.
    let y: Vec<f64> = sim.positions().iter().map(|p| p.y).collect();
    let spread =
        y.iter().cloned().fold(f64::MIN, f64::max) - y.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread < 1e-9, "the plate bent by {spread} m");
    // The reported load is the model's force where the force stage evaluates it, after the
    // substep's gravity kick: at v_t + h g, so m g (1 + h g / v_t)² (the implicit step then
    // applies exactly the weight's impulse).
    let f = force(&mut sim, "air");
    let h = 1.0 / 600.0;
    let expected = m * g * (1.0 + h * g / vt).powi(2);
    assert!(
        (f.y - expected).abs() < 1e-3 * expected,
        "{f} vs {expected}"
    );
}

/// A 1 m × 1 m plate whose chord runs downwind (+x) from a leading edge raised by `alpha`.
fn tilted_plate_obj(alpha: f64) -> String {
    let (c, s) = (alpha.cos(), alpha.sin());
    format!("v 0 {s} 0\nv {c} 0 0\nv {c} 0 1\nv 0 {s} 1\nf 1 2 3\nf 1 3 4\n")
}

#[test]
fn plate_at_an_angle_of_attack_feels_the_model_lift_and_drag() {
    // Held (all pinned) in a 10 m/s wind along +x; with α the angle of attack:
    //   drag = ½ ρ C_d A U² sin α (downwind), lift = ½ ρ C_l A U² sin α cos α (up),
    //   lift/drag = (C_l/C_d) cos α.
    // The model is exact on a flat plate, so the tolerance is rounding, not the issue's 2 %.
    let (u, cd, cl) = (10.0, 1.2, 0.8);
    for deg in [5.0f64, 20.0, 45.0, 70.0] {
        let alpha = deg.to_radians();
        let mut sim = simulation_with_files(
            "air-lift",
            &format!(
                r#"
[solver]
frames = 1
[[objects]]
name = "plate"
pins = ["all"]
[objects.mesh]
path = "plate.obj"
[[constraints]]
kind = "air"
params = {{ drag = {cd}, lift = {cl}, tangential_drag = 0.0, wind_speed = {u} }}
"#
            ),
            &[("plate.obj", tilted_plate_obj(alpha))],
        );
        sim.step_frame().expect("step");
        let f = force(&mut sim, "air");
        let q = 0.5 * RHO * u * u;
        let drag = q * cd * alpha.sin();
        let lift = q * cl * alpha.sin() * alpha.cos();
        assert!(f.y > 0.0, "{deg}°: no upward force: {f}");
        assert!(
            (f.x - drag).abs() < 1e-12 * drag,
            "{deg}°: drag {} vs {drag}",
            f.x
        );
        assert!(
            (f.y - lift).abs() < 1e-12 * lift,
            "{deg}°: lift {} vs {lift}",
            f.y
        );
        assert!(f.z.abs() < 1e-12 * drag);
        let ratio = f.y / f.x;
        let predicted = cl / cd * alpha.cos();
        assert!(
            (ratio - predicted).abs() < 1e-12 * predicted,
            "{deg}°: L/D {ratio}"
        );
        assert!((report(&mut sim, "air.lift") - lift).abs() < 1e-12 * lift);
        assert!((report(&mut sim, "air.drag") - drag).abs() < 1e-12 * drag);
        // Held: nothing moved.
        assert!(sim.velocities().iter().all(|v| *v == DVec3::ZERO));
    }
}

#[test]
fn skin_drag_acts_along_the_plate_separately() {
    // The same plate with skin drag only (C_l = 0, C_t = τ C_d): the flow along the surface,
    // |v_t| = U cos α along the chord, adds ½ ρ C_t A U² cos² α down the chord.
    let (u, cd, tau, alpha) = (10.0f64, 1.0, 0.3, 30f64.to_radians());
    let mut sim = simulation_with_files(
        "air-skin",
        &format!(
            r#"
[solver]
frames = 1
[[objects]]
name = "plate"
pins = ["all"]
[objects.mesh]
path = "plate.obj"
[[constraints]]
kind = "air"
params = {{ drag = {cd}, lift = 0.0, tangential_drag = {tau}, wind_speed = {u} }}
"#
        ),
        &[("plate.obj", tilted_plate_obj(alpha))],
    );
    sim.step_frame().expect("step");
    let f = force(&mut sim, "air");
    let q = 0.5 * RHO * u * u;
    let chord = DVec3::new(alpha.cos(), -alpha.sin(), 0.0);
    let expected = q * cd * alpha.sin() * DVec3::X + q * tau * cd * alpha.cos().powi(2) * chord;
    assert!(
        (f - expected).length() < 1e-12 * expected.length(),
        "{f} vs {expected}"
    );
    let skin = report(&mut sim, "air.tangential");
    assert!((skin - q * tau * cd * alpha.cos().powi(2)).abs() < 1e-12 * skin);
}

#[test]
fn closed_surface_in_a_uniform_wind_without_lift_feels_only_drag_along_the_wind() {
    // A held icosphere (r = 0.5 m, 1280 triangles) in a wind along an arbitrary direction ŵ:
    // with C_l = 0 and no skin drag, every triangle's force is along the wind, so the total is
    // F = ½ ρ C_d U² ŵ Σ A|n̂·ŵ| exactly — no side force. For a closed convex surface
    // Σ A|n̂·ŵ| is twice its silhouette, so F ≈ ρ C_d U² π r²: twice a disc's drag.
    let (u, cd, r) = (8.0, 0.5, 0.5);
    let dir = DVec3::new(1.0, 0.3, -0.2).normalize();
    let mut sim = simulation(
        &format!(
            r#"
[solver]
frames = 1
[[objects]]
name = "ball"
pins = ["all"]
[objects.sphere]
center = [0.0, 1.0, 0.0]
radius = {r}
subdivisions = 3
[[constraints]]
kind = "air"
params = {{ drag = {cd}, lift = 0.0, tangential_drag = 0.0, wind_speed = {u}, wind_direction = [{}, {}, {}] }}
"#,
            dir.x, dir.y, dir.z
        ),
        &[],
    );
    sim.step_frame().expect("step");
    let f = force(&mut sim, "air");
    let ball = sim.object("ball").expect("ball");
    let x = sim.positions();
    let projected: f64 = ball
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| x[i as usize]);
            0.5 * (b - a).cross(c - a).dot(dir).abs()
        })
        .sum();
    let expected = 0.5 * RHO * cd * u * u * projected * dir;
    assert!(
        (f - expected).length() < 1e-12 * expected.length(),
        "{f} vs {expected}"
    );
    assert!(
        f.cross(dir).length() < 1e-12 * f.length(),
        "side force: {f}"
    );
    // The inscribed icosphere's silhouette is 0.5 % smaller than the disc.
    let disc = RHO * cd * u * u * PI * r * r;
    assert!(
        (f.length() - disc).abs() < 0.01 * disc,
        "{} vs {disc}",
        f.length()
    );
}

#[test]
fn particles_fall_at_the_sphere_terminal_velocity_and_ropes_feel_cross_flow() {
    // Points: v_t = sqrt(2 m g / (ρ C_d π r²)). A held rope across a wind: ½ ρ C_d (L b) U².
    let (m, r, cd) = (0.002, 0.02, 0.47);
    let vt = (2.0 * m * 9.81 / (RHO * cd * PI * r * r)).sqrt();
    let mut sim = simulation(
        &format!(
            r#"
[solver]
frame_rate = 60.0
substeps = 10
[[objects]]
name = "drops"
vertex_mass = {m}
[objects.particles]
min = [0.0, 0.0, 0.0]
max = [1.0, 0.0, 1.0]
count = [2, 1, 2]
[[objects]]
name = "rope"
pins = ["all"]
[objects.rope]
start = [0.0, 2.0, 0.0]
end = [0.0, 2.0, 1.5]
segments = 6
[[constraints]]
kind = "air"
name = "drops_air"
objects = ["drops"]
params = {{ drag = {cd}, particle_radius = {r} }}
[[constraints]]
kind = "air"
name = "rope_air"
objects = ["rope"]
params = {{ drag = 1.1, curve_width = 0.03, wind_speed = 6.0, wind_direction = [1.0, 0.0, 0.0] }}
"#
        ),
        &[],
    );
    for _ in 0..300 {
        sim.step_frame().expect("step");
    }
    for v in &sim.velocities()[..4] {
        assert!((v.y + vt).abs() < 1e-3 * vt, "{} vs {vt}", v.y);
    }
    let load = force(&mut sim, "rope_air");
    let expected = 0.5 * RHO * 1.1 * (1.5 * 0.03) * 36.0;
    assert!(
        (load.x - expected).abs() < 1e-12 * expected,
        "{load} vs {expected}"
    );
    assert!(load.y.abs() + load.z.abs() < 1e-12 * expected);
}

#[test]
fn each_group_gives_its_objects_their_own_coefficients() {
    // Two identical held plates in the same wind, one group each: the forces scale with
    // each group's C_d.
    let mut sim = simulation(
        r#"
[solver]
frames = 1
[[objects]]
name = "a"
pins = ["all"]
[objects.grid]
size = [1.0, 1.0]
resolution = [3, 3]
plane = "yz"
[[objects]]
name = "b"
pins = ["all"]
[objects.grid]
size = [1.0, 1.0]
resolution = [3, 3]
plane = "yz"
origin = [2.0, 0.0, 0.0]
[[constraints]]
kind = "air"
name = "air_a"
objects = ["a"]
params = { drag = 0.4, wind_speed = 5.0 }
[[constraints]]
kind = "air"
name = "air_b"
objects = ["b"]
params = { drag = 1.2, wind_speed = 5.0 }
"#,
        &[],
    );
    sim.step_frame().expect("step");
    let (a, b) = (force(&mut sim, "air_a"), force(&mut sim, "air_b"));
    let q = 0.5 * RHO * 25.0;
    assert!(
        (a.x - q * 0.4).abs() < 1e-12 && (b.x - q * 1.2).abs() < 1e-12,
        "{a} {b}"
    );
}

#[test]
fn degenerate_triangles_and_zero_length_edges_give_no_nan() {
    // Zero-area triangles (coincident and collinear vertices) and a rope whose ends coincide
    // (four zero-length edges), free to move in a gusty wind with lift and skin drag: the run
    // completes (the host stops on any NaN or infinity), and the degenerate elements feel
    // nothing — their particles fall freely — while the one healthy triangle is blown away.
    // (A zero-length `l` line in the OBJ would be the same, but the OBJ loader turns lines
    // into degenerate faces the scene rejects: see the closing note.)
    let obj = "v 0 1 0\nv 0 1 0\nv 0 1 0\n\
               v 1 1 0\nv 2 1 0\nv 3 1 0\n\
               v 0 3 0\nv 1 3 0\nv 0 3 1\n\
               f 1 2 3\nf 4 5 6\nf 7 8 9\n";
    let mut sim = simulation_with_files(
        "air-degenerate",
        r#"
[solver]
frames = 60
substeps = 4
[[objects]]
name = "junk"
mass = 0.01
[objects.mesh]
path = "junk.obj"
[[objects]]
name = "knot"
mass = 0.01
[objects.rope]
start = [1.0, 1.0, 1.0]
end = [1.0, 1.0, 1.0]
segments = 4
[[constraints]]
kind = "air"
params = { drag = 1.0, lift = 1.0, tangential_drag = 1.0, wind_speed = 30.0, noise = 10.0, noise_frequency = 5.0 }
"#,
        &[("junk.obj", obj.to_string())],
    );
    for _ in 0..60 {
        sim.step_frame().expect("no NaN");
    }
    assert!(sim
        .positions()
        .iter()
        .chain(sim.velocities())
        .all(|v| v.is_finite()));
    let free_fall = DVec3::new(0.0, -9.81, 0.0);
    for i in [0, 1, 2, 3, 4, 5, 9, 10, 11, 12, 13] {
        let v = sim.velocities()[i];
        assert!((v - free_fall).length() < 1e-9, "particle {i}: {v}");
    }
    for i in [6, 7, 8] {
        let v = sim.velocities()[i];
        assert!(
            v.x > 1.0,
            "the healthy triangle's particle {i} was not blown: {v}"
        );
    }
    let r = sim.residuals().expect("residual");
    assert!(r.iter().all(|r| r.max.is_finite() && r.rms.is_finite()));
}

#[test]
fn gusty_wind_is_bit_identical_for_a_seed_and_differs_for_another() {
    let run = |seed: u32| {
        let mut sim = simulation(
            &format!(
                r#"
[solver]
substeps = 5
[[objects]]
name = "cloth"
density = 0.15
pins = ["edge:col0"]
[objects.grid]
size = [1.0, 0.6]
resolution = [6, 4]
plane = "xy"
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "air"
params = {{ drag = 0.1, lift = 0.3, wind_speed = 8.0, noise = 3.0, noise_frequency = 2.0, noise_scale = 0.5, seed = {seed} }}
"#
            ),
            &[],
        );
        for _ in 0..30 {
            sim.step_frame().expect("step");
        }
        sim.positions()
            .iter()
            .flat_map(|p| p.to_array())
            .map(f64::to_bits)
            .collect::<Vec<_>>()
    };
    assert_eq!(run(3), run(3));
    assert_ne!(run(3), run(4));
}
