//! A straight rope (a curve) bent into a U and released without gravity returns to straight,
//! through the dynamically loaded `bend` and `stretch` plugins: the curve's type-2 angle
//! constraints (rest angle π at every joint) unbend it, a little global damping takes out the
//! motion, and every joint ends within 1° of straight. `twist` is applied too: on a straight
//! rest shape it has nothing to hold (no rest plane), and it must not get in the way.

use std::f64::consts::PI;

use nucleus_tests::*;

const SEGMENTS: usize = 20;

/// The largest deviation from straight over the joints (rad).
fn worst_joint(x: &[glam::DVec3]) -> f64 {
    (1..SEGMENTS)
        .map(|k| {
            let (a, b) = (x[k - 1] - x[k], x[k + 1] - x[k]);
            PI - a.cross(b).length().atan2(a.dot(b))
        })
        .fold(0.0, f64::max)
}

#[test]
fn rope_bent_into_a_u_returns_to_straight_within_one_degree_per_joint() {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
gravity = [0.0, 0.0, 0.0]
damping = 2.0

[[objects]]
name = "rope"
mass = 0.1
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [1.0, 0.0, 0.0]
segments = {SEGMENTS}

[[constraints]]
kind = "stretch"

[[constraints]]
kind = "bend"
params = {{ compliance = 0.01 }}

[[constraints]]
kind = "twist"
params = {{ compliance = 0.01 }}
"#
    );
    let mut sim = simulation(&text, &[]);
    assert_eq!(sim.groups[1].len as usize, SEGMENTS - 1);
    // A U: a half circle of the rope's length, radius 1/π, in the xy plane.
    let radius = 1.0 / PI;
    for (k, p) in sim.particles.x.iter_mut().enumerate() {
        let t = PI * k as f64 / SEGMENTS as f64;
        *p = [radius * t.sin(), radius * (1.0 - t.cos()), 0.0];
    }
    let bent = worst_joint(sim.positions());
    assert!(
        (bent - PI / SEGMENTS as f64).abs() < 1e-9,
        "every joint starts bent by 9°: {bent}"
    );
    for _ in 0..360 {
        sim.step_frame().expect("step");
    }
    let worst = worst_joint(sim.positions());
    assert!(
        worst < 1f64.to_radians(),
        "a joint is still bent by {:.3}°",
        worst.to_degrees()
    );
    // It straightened into a rope of its own length, not a shorter one.
    let x = sim.positions();
    let span = (x[SEGMENTS] - x[0]).length();
    assert!((span - 1.0).abs() < 1e-3, "end to end {span} m");
}
