//! A hanging chain settles to the catenary.
//!
//! A rope of 40 equal links and length `s = 1.5 m`, both ends pinned at `(0, 0, 0)` and
//! `(1, 0, 0)` (span `d = 1 m`), starts as a V below its ends and falls under gravity with
//! global damping; hard `stretch` edges with several substeps and iterations keep it nearly
//! inextensible. At rest it must lie on the catenary through its end points,
//!
//! ```text
//! y(x) = a cosh((x − d/2)/a) − a cosh(d/(2a)),   with a fixed by   2a sinh(d/(2a)) = s
//! ```
//!
//! (`a = T₀/(μg)`, the ratio of the horizontal tension to the weight per length; found here by
//! bisection, since `2a sinh(d/(2a))` decreases monotonically from ∞ to `d`). Every vertex
//! must be within 1% of the span (0.01 m) of that curve — the distance from the vertex to
//! the nearest point of the curve — once the kinetic energy has died away. A chain of `N`
//! equal links with lumped vertex masses is a discrete catenary that differs from the
//! continuous one by `O(1/N²)`; at `N = 40` that is about 0.2 mm (measured with 60 substeps ×
//! 40 iterations, strain 2e-5), far below the tolerance, which therefore measures the solver:
//! links that stretch (too few passes for the hard constraint) or masses lumped unevenly move
//! the curve. (The shape does not depend on `g` or on the total mass: only `a`'s tension does.)
//!
//! Measured at 60 frames/s with 10 substeps × 10 iterations after 8 s: largest distance
//! 1.1 mm (0.11% of the span), largest link strain 0.27%, kinetic energy 3e-10 J. The
//! deviation is the chain's stretch (its length is 1.5014 m, so it sags a little more):
//! 20 × 10 gives 0.43 mm, while 5 × 4 stretches 2.8% and sags 9.1 mm — at the edge of the
//! tolerance.

use glam::DVec3;
use nucleus_core::Simulation;
use nucleus_tests::*;

const SPAN: f64 = 1.0;
const LENGTH: f64 = 1.5;
const SEGMENTS: u32 = 40;
/// Simulated time before the check: the damping (2/s) takes the kinetic energy from the
/// fall's ~0.1 J to below 1e-9 J in about 8 s.
const SETTLE_SECONDS: f64 = 8.0;

/// The catenary parameter `a` with `2a sinh(SPAN/(2a)) = LENGTH`, by bisection.
fn catenary_parameter() -> f64 {
    let arc = |a: f64| 2.0 * a * (0.5 * SPAN / a).sinh();
    let (mut lo, mut hi) = (0.01, 100.0);
    assert!(arc(lo) > LENGTH && arc(hi) < LENGTH);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if arc(mid) > LENGTH {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The catenary through `(0, 0)` and `(SPAN, 0)` with parameter `a`.
fn catenary_y(a: f64, x: f64) -> f64 {
    a * ((x - 0.5 * SPAN) / a).cosh() - a * (0.5 * SPAN / a).cosh()
}

/// The distance from `(x, y)` to the catenary, minimising over the curve's abscissa by golden
/// section in a bracket around `x` (the squared distance is unimodal there).
fn distance_to_catenary(a: f64, x: f64, y: f64) -> f64 {
    let d2 = |t: f64| (t - x).powi(2) + (catenary_y(a, t) - y).powi(2);
    let (mut lo, mut hi) = (x - 0.1, x + 0.1);
    let r = 0.5 * (5.0_f64.sqrt() - 1.0);
    for _ in 0..100 {
        let (t1, t2) = (hi - r * (hi - lo), lo + r * (hi - lo));
        if d2(t1) < d2(t2) {
            hi = t2;
        } else {
            lo = t1;
        }
    }
    d2(0.5 * (lo + hi)).sqrt()
}

fn chain() -> Simulation {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
iterations = 10
gravity = [0.0, -9.81, 0.0]
damping = 2.0

[[objects]]
name = "chain"
mass = 1.0
pins = ["ends"]
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [{SPAN:?}, 0.0, 0.0]
segments = {SEGMENTS}
length = {LENGTH:?}

[[constraints]]
kind = "stretch"
params = {{ compliance = 0.0 }}
"#
    );
    simulation(&text, &[])
}

#[test]
fn catenary_parameter_solves_the_length_equation() {
    let a = catenary_parameter();
    assert!((2.0 * a * (0.5 / a).sinh() - 1.5).abs() < 1e-12);
    // The curve's own arc length, by a fine midpoint sum, is the chain's length.
    let n = 100_000;
    let arc: f64 = (0..n)
        .map(|k| {
            let x = (k as f64 + 0.5) / n as f64 * SPAN;
            (1.0 + ((x - 0.5 * SPAN) / a).sinh().powi(2)).sqrt() * SPAN / n as f64
        })
        .sum();
    assert!((arc - LENGTH).abs() < 1e-8, "arc length {arc}");
    assert!(catenary_y(a, 0.0).abs() < 1e-12 && catenary_y(a, SPAN).abs() < 1e-12);
}

#[test]
fn hanging_chain_settles_on_the_catenary() {
    let a = catenary_parameter();
    let mut sim = chain();
    let frames = (SETTLE_SECONDS * sim.settings.frame_rate).round() as usize;
    for _ in 0..frames {
        sim.step_frame().expect("step");
    }
    let kinetic = sim.kinetic_energy();
    assert!(
        kinetic < 1e-6,
        "after {SETTLE_SECONDS} s the chain still has {kinetic:e} J of kinetic energy"
    );
    let strain = sim.residuals().expect("residuals")[0].max;
    assert!(
        strain < 0.01,
        "the hard links stretched by {:.2}%: not the chain of length {LENGTH} m",
        100.0 * strain
    );
    let p = sim.positions();
    let (worst, at) = p
        .iter()
        .enumerate()
        .map(|(i, q)| (distance_to_catenary(a, q.x, q.y).hypot(q.z), i))
        .fold((0.0, 0), |best, d| if d.0 > best.0 { d } else { best });
    assert!(
        worst < 0.01 * SPAN,
        "vertex {at} at {} is {worst:.4} m from the catenary (a = {a:.6} m, sag {:.4} m)",
        p[at],
        -catenary_y(a, 0.5 * SPAN)
    );
    assert!(
        (p[0] - DVec3::ZERO).length() < 1e-12
            && (p[p.len() - 1] - DVec3::X * SPAN).length() < 1e-12,
        "the pinned ends moved"
    );
}
