//! Kinematic (pinned, inverse-mass-0) particles follow their target exactly: a constant
//! rigid motion, keyframes (linear translation, slerped rotation, held outside the keys), and
//! an animated OBJ sequence interpolated within each frame. Their velocity is the motion's.

use glam::{DQuat, DVec3};
use nucleus_tests::*;

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-12
}

#[test]
fn spinning_pins_follow_the_rigid_motion() {
    let text = r#"
[solver]
frame_rate = 10.0
frames = 5
substeps = 3
[[objects]]
name = "bar"
pins = ["all"]
pin_motion = { velocity = [1.0, 0.0, 0.0], angular_velocity = [0.0, 2.0, 0.0], pivot = [0.5, 0.0, 0.0] }
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [1.0, 0.0, 0.0]
segments = 4
"#;
    let mut sim = simulation(text, &[]);
    let rest: Vec<DVec3> = sim.positions().to_vec();
    for _ in 0..5 {
        sim.step_frame().unwrap();
    }
    let t = 0.5;
    let rot = DQuat::from_rotation_y(2.0 * t);
    for (x, r) in sim.positions().iter().zip(&rest) {
        let want =
            DVec3::new(0.5, 0.0, 0.0) + rot * (*r - DVec3::new(0.5, 0.0, 0.0)) + DVec3::X * t;
        assert!(close(*x, want), "{x} vs {want}");
    }
}

#[test]
fn keyframed_pins_interpolate_and_hold() {
    let text = r#"
[solver]
frame_rate = 10.0
frames = 30
substeps = 2
[[objects]]
name = "p"
pins = ["all"]
[[objects.pin_motion.keys]]
time = 0.0
[[objects.pin_motion.keys]]
time = 1.0
translate = [2.0, 0.0, 0.0]
rotate = [0.0, 0.0, 1.5707963267948966]
[objects.particles]
min = [1.0, 0.0, 0.0]
max = [1.0, 0.0, 0.0]
count = [1, 1, 1]
"#;
    let mut sim = simulation(text, &[]);
    for _ in 0..5 {
        sim.step_frame().unwrap();
    }
    // t = 0.5: half the translation, a quarter turn slerped halfway (45°).
    let want = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_4) * DVec3::X + DVec3::X;
    assert!(close(sim.positions()[0], want), "{}", sim.positions()[0]);
    for _ in 5..30 {
        sim.step_frame().unwrap();
    }
    // After the last key the transform holds.
    assert!(
        close(sim.positions()[0], DVec3::new(2.0, 1.0, 0.0)),
        "{}",
        sim.positions()[0]
    );
    assert!(sim.velocities()[0].length() < 1e-9);
}

#[test]
fn obj_sequence_drives_pinned_vertices() {
    let dir = temp_dir("sequence");
    for f in 0..3 {
        let y = f as f64 * 0.1;
        std::fs::write(
            dir.join(format!("plate_{f:04}.obj")),
            format!("v 0 {y} 0\nv 1 {y} 0\nv 0 {y} 1\nf 1 2 3\n"),
        )
        .unwrap();
    }
    let text = r#"
[solver]
frame_rate = 10.0
frames = 4
substeps = 4
[[objects]]
name = "plate"
pins = ["all"]
[objects.mesh]
path = "plate_0000.obj"
sequence = "plate_{frame:04}.obj"
"#;
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    let scene = nucleus_core::Scene::load(&dir.join("scene.toml")).unwrap();
    let mut sim = nucleus_core::Simulation::build(&scene, &registry(&[plugin_dir()])).unwrap();
    sim.substep(0).unwrap();
    // A quarter of frame 0 → 1: y = 0.025, velocity 1 m/s up.
    assert!((sim.positions()[1].y - 0.025).abs() < 1e-12);
    assert!((sim.velocities()[1].y - 1.0).abs() < 1e-9);
    for s in 1..4 {
        sim.substep(s).unwrap();
    }
    sim.frame += 1;
    for _ in 0..3 {
        sim.step_frame().unwrap();
    }
    // Frames past the last file hold its positions.
    assert!((sim.positions()[2].y - 0.2).abs() < 1e-12);
}

#[test]
fn pins_split_over_the_thread_team_follow_the_motion_with_the_bits_of_one_thread() {
    // 80 × 80 = 6,400 particles: the prediction (which moves the pins) is split over the team,
    // each part moving the pins of its own range. The pinned rows 0 and 79 and a free middle:
    // the pins are at the rigid motion's target, and one and two threads agree bit for bit.
    let text = r#"
[solver]
frame_rate = 10.0
frames = 4
substeps = 3
[[objects]]
name = "sheet"
pins = ["edge:row0", "edge:rowN"]
pin_motion = { velocity = [1.0, 0.0, 0.0], angular_velocity = [0.0, 2.0, 0.0], pivot = [0.5, 0.0, 0.0] }
[objects.grid]
size = [1.0, 1.0]
resolution = [80, 80]
"#;
    let run = |threads: usize| {
        let mut sim = simulation(text, &[]);
        sim.threads = threads;
        let rest: Vec<DVec3> = sim.positions().to_vec();
        for _ in 0..4 {
            sim.step_frame().unwrap();
        }
        (sim.positions().to_vec(), sim.velocities().to_vec(), rest)
    };
    let (x1, v1, rest) = run(1);
    let (x2, v2, _) = run(2);
    let bits = |a: &[DVec3]| {
        a.iter()
            .map(|p| p.to_array().map(f64::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&x1), bits(&x2));
    assert_eq!(bits(&v1), bits(&v2));
    let t = 0.4;
    let rot = DQuat::from_rotation_y(2.0 * t);
    let pivot = DVec3::new(0.5, 0.0, 0.0);
    let pinned: Vec<usize> = (0..80).chain(79 * 80..80 * 80).collect();
    for &i in &pinned {
        let want = pivot + rot * (rest[i] - pivot) + DVec3::X * t;
        assert!(close(x2[i], want), "pin {i}: {} vs {want}", x2[i]);
    }
    // The free particles fell: the prediction ran on every part.
    assert!(x2[40 * 80 + 40].y < -0.05, "{}", x2[40 * 80 + 40]);
}
