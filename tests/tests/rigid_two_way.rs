//! Two-way coupling of a rigid body and cloth, through the dynamically loaded `rigid`,
//! `stretch` and `collision` plugins: the paper's motivating example, a ball kicked into a net.
//!
//! A ball (an icosphere of radius 0.11 m, 42 particles held rigid by shape matching) is
//! thrown at 8 m/s into a 2 m × 1.5 m net (15 × 11 particles, 0.5 kg, compliant and damped stretch edges)
//! pinned all around its border, under gravity. Nothing but the collision plugin couples
//! them: contacts push ball and net particles apart by their inverse masses, and shape
//! matching spreads each push over the whole ball, conserving momentum. So:
//!
//! * the ball never passes through the net, checked after every substep: no triangle of the
//!   ball intersects a triangle of the net (an exact triangle–triangle test), no net particle
//!   is inside the ball, the ball's centre never gets past the net's deepest point, and (at
//!   every frame) the collision group reports nothing unresolved;
//! * the ball slows down (below a fifth of its speed) and is turned back;
//! * the net is deflected (its deepest point more than 5 cm behind its frame);
//! * a heavier ball (1 kg instead of 0.43 kg) at the same speed deflects it more;
//! * the ball is exactly rigid whenever it touches nothing; in contact, the collision group
//!   (which runs after the rigid group) leaves its touching particles off their rigid goals
//!   at the end of a substep — the largest such offset is printed.

#[path = "../../plugins/collision/src/narrow_phase/distance.rs"]
#[allow(dead_code)]
mod distance;

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// Checks, after a substep, that the ball is nowhere through the net; returns the net's
/// deepest point.
fn check_not_through(sim: &Simulation, net: std::ops::Range<usize>, at: &str) -> f64 {
    let (c, _) = ball_state(sim);
    let x = sim.positions();
    let net_deepest = x[net.clone()]
        .iter()
        .map(|p| p.z)
        .fold(f64::INFINITY, f64::min);
    // The planes of the icosphere's faces are at least 0.934 R from its centre (and contacts
    // keep particles 2 × 5 mm off them): a net particle closer is inside.
    let closest = x[net]
        .iter()
        .map(|p| (*p - c).length())
        .fold(f64::INFINITY, f64::min);
    assert!(
        closest > 0.934 * RADIUS,
        "{at}: a net particle is {closest} m from the ball's centre"
    );
    assert!(
        c.z > net_deepest,
        "{at}: the ball's centre {c} is past the net (deepest {net_deepest})"
    );
    let ball = triangles(sim, "ball");
    for (k, n) in triangles(sim, "net").iter().enumerate() {
        for b in &ball {
            assert!(
                !distance::triangles_intersect(*n, *b),
                "{at}: net triangle {k} intersects the ball"
            );
        }
    }
    net_deepest
}

const RADIUS: f64 = 0.11;
const SPEED: f64 = 8.0;
/// 0.3 s: the ball reaches the net at 0.04 s, is stopped by 0.15 s and thrown back.
const FRAMES: usize = 18;

fn scene(ball_mass: f64) -> String {
    format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 5

[[objects]]
name = "net"
mass = 0.5
pins = ["edge:row0", "edge:rowN", "edge:col0", "edge:colN"]
[objects.grid]
size = [2.0, 1.5]
resolution = [15, 11]
plane = "xy"
origin = [-1.0, 0.0, 0.0]

[[objects]]
name = "ball"
mass = {ball_mass}
velocity = [0.0, 0.0, -{SPEED}]
[objects.sphere]
center = [0.03, 0.77, 0.4]
radius = {RADIUS}
subdivisions = 1

[[constraints]]
kind = "stretch"
objects = ["net"]
params = {{ compliance = 3e-4, compression_compliance = 1e-2, damping = 2.0 }}

[[constraints]]
kind = "rigid"
objects = ["ball"]

[[constraints]]
kind = "collision"
objects = ["net", "ball"]
"#
    )
}

struct Outcome {
    /// Deepest point of the net over the run (m, negative behind the frame).
    deepest: f64,
    /// Smallest speed of the ball over the run (m/s).
    min_speed: f64,
    /// z velocity of the ball at the end (m/s).
    final_vz: f64,
    /// Largest distance of a ball particle from its rigid goal at the end of a frame (m).
    deformed: f64,
}

fn ball_state(sim: &Simulation) -> (DVec3, DVec3) {
    let ball = sim.object("ball").expect("ball");
    let range = ball.first as usize..(ball.first + ball.count) as usize;
    let n = range.len() as f64;
    let x: DVec3 = sim.positions()[range.clone()]
        .iter()
        .copied()
        .sum::<DVec3>()
        / n;
    let v: DVec3 = sim.velocities()[range].iter().copied().sum::<DVec3>() / n;
    (x, v)
}

fn throw(ball_mass: f64) -> Outcome {
    let mut sim = simulation(&scene(ball_mass), &[]);
    let net = sim.object("net").expect("net").clone();
    let net_range = net.first as usize..(net.first + net.count) as usize;
    let rigid = sim
        .groups
        .iter()
        .position(|g| g.kind == "rigid")
        .expect("rigid group");
    let mut deepest: f64 = 0.0;
    let mut deformed: f64 = 0.0;
    let mut min_speed = f64::INFINITY;
    for frame in 0..FRAMES {
        for s in 0..sim.settings.substeps {
            sim.substep(s)
                .unwrap_or_else(|e| panic!("frame {frame} substep {s}: {e}"));
            let at = format!("frame {frame} substep {s}");
            deepest = deepest.min(check_not_through(&sim, net_range.clone(), &at));
        }
        sim.frame += 1;
        let (_, v) = ball_state(&sim);
        min_speed = min_speed.min(v.length());
        let stats = sim.reports().expect("reports");
        let stat = |name: &str| {
            stats
                .iter()
                .find(|(n, _)| n == &format!("collision.{name}"))
                .map(|(_, v)| *v)
        };
        assert_eq!(
            stat("unresolved"),
            Some(0.0),
            "frame {frame}: unresolved collisions"
        );
        // The collision group runs after the rigid group (the kinds' default orders), so in
        // contact the ball's touching particles end a substep pushed off their rigid goals
        // (each contact moves one light particle; the next substep's match spreads the push
        // over the whole ball, momentum intact). Out of contact it is exactly rigid.
        let r = sim.residuals().expect("residuals")[rigid];
        if stat("contacts") == Some(0.0) {
            assert!(
                r.max < 1e-12,
                "frame {frame}: ball deformed out of contact {r:?}"
            );
        }
        deformed = deformed.max(r.max);
    }
    let (_, v) = ball_state(&sim);
    Outcome {
        deepest,
        min_speed,
        final_vz: v.z,
        deformed,
    }
}

#[test]
fn a_ball_thrown_into_a_net_is_caught_and_a_heavier_ball_deflects_it_more() {
    let light = throw(0.43);
    let heavy = throw(1.0);
    for (name, o) in [("0.43 kg", &light), ("1 kg", &heavy)] {
        eprintln!(
            "{name}: net deflection {:.3} m, slowest {:.2} m/s, v_z {:+.2} m/s after {:.2} s, \
             largest deformation at a frame end in contact {:.1} mm",
            -o.deepest,
            o.min_speed,
            o.final_vz,
            FRAMES as f64 / 60.0,
            1e3 * o.deformed
        );
        assert!(
            o.deepest < -0.05,
            "{name}: the net did not give: {}",
            o.deepest
        );
        assert!(
            o.min_speed < 0.2 * SPEED,
            "{name}: not slowed: {}",
            o.min_speed
        );
        assert!(o.final_vz > 0.0, "{name}: not turned back: {}", o.final_vz);
    }
    assert!(
        heavy.deepest < light.deepest - 0.05,
        "heavier ball {} vs lighter {}",
        heavy.deepest,
        light.deepest
    );
}
