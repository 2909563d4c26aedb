//! The paper's unit spring (Stam, "Nucleus", Section 4.2), integrated by the core's step.
//!
//! One particle under `x'' = −x` (the `unit_spring` fixture with `k = 1`, gravity 0, no
//! damping) goes through the core's symplectic Euler, `v ← v − h x; x ← x + h v`. For the state
//! `(x, v)` of each axis that is the linear map
//!
//! ```text
//! M(h) = [ 1 − h²   h ]      det M = 1,   tr M = 2 − h²,   eigenvalues e^{±iθ}, cos θ = 1 − h²/2
//!        [  −h      1 ]
//! ```
//!
//! so the contract is exact arithmetic the step must reproduce:
//!
//! * `h = 1`: θ = π/3, `M⁶ = I` — the orbit is a hexagon and the particle is back at its start
//!   after exactly 6 steps;
//! * `h = √2`: θ = π/2, `M⁴ = I` — a quadrilateral, back after exactly 4 steps;
//! * `h < 2`: the quadratic `Q = |x|² + |v|² − h x·v` is conserved exactly by every step (the
//!   modified energy of symplectic Euler), and since `|x·v| ≤ (|x|² + |v|²)/2`,
//!   `Q/(1 + h/2) ≤ |x|² + |v|² ≤ Q/(1 − h/2)`: every orbit stays in that annulus forever —
//!   neither growing (explicit Euler would) nor decaying (implicit Euler would);
//! * `h > 2`: `|tr M| > 2`, a real eigenvalue of modulus > 1 — the orbit diverges. At
//!   `h = 2.1` that eigenvalue is ≈ −1.877, so `|x|` passes 1e6 in about 22 steps.
//!
//! The particle starts at `x = (1, 0, 0)`, `v = 0` (a particles block with `min = max`), and
//! `h` is set through `frame_rate` with one substep per frame, so one frame is one step.

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

/// A scene of `count` particles in the box `[min, max]` under the unit spring, with one
/// substep of length `h` per frame.
fn spring_scene(h: f64, min: [f64; 3], max: [f64; 3], count: [u32; 3]) -> Simulation {
    let text = format!(
        r#"
[solver]
frame_rate = {frame_rate:?}
substeps = 1
iterations = 1
gravity = [0.0, 0.0, 0.0]
damping = 0.0

[[objects]]
name = "p"
mass = 1.0
[objects.particles]
min = {min:?}
max = {max:?}
count = {count:?}

[[constraints]]
kind = "unit_spring"
params = {{ k = 1.0 }}
"#,
        frame_rate = 1.0 / h,
    );
    let sim = simulation(&text, &[fixture("spring")]);
    assert!(
        (sim.h() - h).abs() <= 4.0 * f64::EPSILON * h,
        "substep {} is not the intended {h}",
        sim.h()
    );
    sim
}

/// One particle at (1, 0, 0), at rest.
fn one_particle(h: f64) -> Simulation {
    spring_scene(h, [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1, 1, 1])
}

fn steps(sim: &mut Simulation, n: usize) {
    for _ in 0..n {
        sim.step_frame().expect("step");
    }
}

/// After `period` steps the particle is back at its start (to 1e-12), and not before.
fn closes_after(h: f64, period: usize) {
    let mut sim = one_particle(h);
    let start = sim.positions()[0];
    for k in 1..=period {
        steps(&mut sim, 1);
        let x = sim.positions()[0];
        let v = sim.velocities()[0];
        if k < period {
            let off = ((x - start).length_squared() + v.length_squared()).sqrt();
            assert!(
                off > 0.1,
                "h = {h}: back at the start (x, v) already after {k} steps"
            );
        } else {
            assert!(
                (x - start).length() < 1e-12,
                "h = {h}: after {period} steps x = {x}, expected {start}"
            );
            assert!(
                v.length() < 1e-12,
                "h = {h}: after {period} steps v = {v}, expected 0"
            );
        }
    }
}

#[test]
fn at_unit_step_the_orbit_is_a_hexagon() {
    closes_after(1.0, 6);
}

#[test]
fn at_step_sqrt_2_the_orbit_is_a_quadrilateral() {
    closes_after(std::f64::consts::SQRT_2, 4);
}

#[test]
fn at_unit_step_the_hexagon_has_the_papers_vertices() {
    // x_{k+1} = (1 − h²) x_k + h v_k, v_{k+1} = v_k − h x_k at h = 1, from (1, 0).
    let expected = [
        (0.0, -1.0),
        (-1.0, -1.0),
        (-1.0, 0.0),
        (0.0, 1.0),
        (1.0, 1.0),
        (1.0, 0.0),
    ];
    let mut sim = one_particle(1.0);
    for (k, &(x, v)) in expected.iter().enumerate() {
        steps(&mut sim, 1);
        let got = (sim.positions()[0], sim.velocities()[0]);
        assert!(
            (got.0 - DVec3::new(x, 0.0, 0.0)).length() < 1e-12
                && (got.1 - DVec3::new(v, 0.0, 0.0)).length() < 1e-12,
            "step {}: (x, v) = {:?}, expected ({x}, {v})",
            k + 1,
            got
        );
    }
}

/// `Q = |x|² + |v|² − h x·v`, the invariant of symplectic Euler for `x'' = −x`.
fn invariant(x: DVec3, v: DVec3, h: f64) -> f64 {
    x.length_squared() + v.length_squared() - h * x.dot(v)
}

#[test]
fn below_step_2_every_orbit_stays_in_its_invariant_annulus() {
    for h in [0.5, 1.9] {
        // 12 particles on a 4×3 lattice, each with its own initial velocity: 12 orbits.
        let mut sim = spring_scene(h, [-1.0, -0.5, 0.0], [1.0, 0.5, 0.3], [4, 3, 1]);
        for (i, v) in sim.particles.v.iter_mut().enumerate() {
            let t = i as f64;
            *v = [0.7 * (t * 1.3).sin(), 0.4 * (t * 0.7).cos(), 0.2 - 0.05 * t];
        }
        let q0: Vec<f64> = sim
            .positions()
            .iter()
            .zip(sim.velocities())
            .map(|(&x, &v)| invariant(x, v, h))
            .collect();
        let (lo, hi) = (1.0 / (1.0 + h / 2.0), 1.0 / (1.0 - h / 2.0));
        let mut worst_q = 0.0_f64;
        for step in 1..=10_000 {
            steps(&mut sim, 1);
            for (i, (&x, &v)) in sim.positions().iter().zip(sim.velocities()).enumerate() {
                let r2 = x.length_squared() + v.length_squared();
                assert!(
                    r2 <= q0[i] * hi * (1.0 + 1e-9) && r2 >= q0[i] * lo * (1.0 - 1e-9),
                    "h = {h}, particle {i}, step {step}: |x|² + |v|² = {r2} left [{}, {}]",
                    q0[i] * lo,
                    q0[i] * hi
                );
                worst_q = worst_q.max((invariant(x, v, h) - q0[i]).abs() / q0[i]);
            }
        }
        assert!(
            worst_q < 1e-10,
            "h = {h}: the invariant drifted by {worst_q:e} (relative)"
        );
    }
}

#[test]
fn above_step_2_the_orbit_diverges() {
    let h = 2.1;
    let mut sim = one_particle(h);
    let mut diverged_at = None;
    for step in 1..=300 {
        steps(&mut sim, 1);
        if sim.positions()[0].length() > 1e6 {
            diverged_at = Some(step);
            break;
        }
    }
    let step = diverged_at.expect("h = 2.1: |x| stayed below 1e6 for 300 steps");
    // The growth factor per step is the eigenvalue modulus (2.41 + √(2.41² − 4))/2 ≈ 1.877.
    assert!(
        (15..=40).contains(&step),
        "h = 2.1: |x| passed 1e6 after {step} steps, expected about 22"
    );
}
