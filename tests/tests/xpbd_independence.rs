//! XPBD's promise: a compliant constraint's stiffness does not depend on the time step or on
//! the iteration count.
//!
//! A 1 kg particle hangs from a pinned point by one `stretch` edge of rest length 1 m and
//! compliance `α = 1e-3 m/N` (a spring of 1000 N/m) under `g = 9.81 m/s²`. The static
//! extension is `m g α = 9.81 mm`. The test checks the settled extension is that value
//! within 1% for every combination of 1, 4 and 16 substeps per frame and 1 and 10 iterations —
//! a 16× range of `h` and a 10× range of passes. Plain PBD (a stiffness per pass, or λ reset
//! every pass) would give a spring whose stiffness changes with both; so would an XPBD that
//! scaled the compliance by anything but `1/h²`.
//!
//! We let it *settle* under global damping (5/s) rather than average an undamped oscillation:
//! the equilibrium does not depend on the damping. At a fixed point of the step `x = x0`, so
//! the velocity the step produces is 0 and `v *= exp(−d h)` leaves it 0; the prediction is
//! `x̃ = x0 + h² g`, and XPBD's implicit equations `m (x − x̃) = ∇C λ`, `C + (α/h²) λ = 0` at
//! `x = x0` give `λ = −m g h²`, hence `C = α m g` whatever `h`, `d` or the number of passes.
//! (For a single edge to a pinned point the constraint is linear along the edge, so even one
//! pass solves those equations exactly.) Starting unstretched, the particle oscillates by
//! 9.81 mm about the equilibrium and the damping, helped by the implicit step's own
//! dissipation, shrinks that below 1e-8 m within the simulated 5 s.

use nucleus_core::Simulation;
use nucleus_tests::*;

const MASS: f64 = 1.0;
const G: f64 = 9.81;
const COMPLIANCE: f64 = 1e-3;

fn hanging_mass(substeps: u32, iterations: u32) -> Simulation {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = {substeps}
iterations = {iterations}
gravity = [0.0, {gy:?}, 0.0]
damping = 5.0

[[objects]]
name = "bob"
vertex_mass = {MASS:?}
pins = ["start"]
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [0.0, -1.0, 0.0]
segments = 1

[[constraints]]
kind = "stretch"
params = {{ compliance = {COMPLIANCE:?} }}
"#,
        gy = -G,
    );
    let sim = simulation(&text, &[]);
    assert_eq!(sim.particles.mass[1], MASS, "the hanging particle's mass");
    assert_eq!(sim.particles.inv_mass[0], 0.0, "the top particle is pinned");
    sim
}

/// The extension of the edge after `seconds` of simulated time.
fn settled_extension(substeps: u32, iterations: u32, seconds: f64) -> f64 {
    let mut sim = hanging_mass(substeps, iterations);
    let frames = (seconds * sim.settings.frame_rate).round() as usize;
    for _ in 0..frames {
        sim.step_frame().expect("step");
    }
    let speed = sim.velocities()[1].length();
    assert!(
        speed < 1e-6,
        "{substeps} substeps × {iterations} iterations: still moving at {speed:e} m/s"
    );
    let p = sim.positions();
    (p[1] - p[0]).length() - 1.0
}

#[test]
fn compliant_link_stretches_by_m_g_alpha_for_any_substeps_and_iterations() {
    let expected = MASS * G * COMPLIANCE;
    let mut report = Vec::new();
    for substeps in [1, 4, 16] {
        for iterations in [1, 10] {
            let e = settled_extension(substeps, iterations, 5.0);
            report.push((substeps, iterations, e, (e - expected) / expected));
        }
    }
    let table: String = report
        .iter()
        .map(|(s, i, e, r)| format!("\n  {s:2} substeps × {i:2} iterations: {e:.9} m ({r:+.2e})"))
        .collect();
    for &(_, _, _, relative) in &report {
        assert!(
            relative.abs() < 0.01,
            "extension should be m g α = {expected} m within 1%:{table}"
        );
    }
}

#[test]
fn extension_scales_with_compliance_not_with_the_step() {
    // The same check from the other side: a stiffer link under the same (coarsest and finest)
    // steps stretches proportionally less, so the test above is not passing by accident of
    // one particular compliance.
    let text = |substeps: u32| {
        format!(
            r#"
[solver]
frame_rate = 60.0
substeps = {substeps}
gravity = [0.0, {gy:?}, 0.0]
damping = 5.0

[[objects]]
name = "bob"
vertex_mass = {MASS:?}
pins = ["start"]
[objects.rope]
start = [0.0, 0.0, 0.0]
end = [0.0, -1.0, 0.0]
segments = 1

[[constraints]]
kind = "stretch"
params = {{ compliance = 1e-5 }}
"#,
            gy = -G,
        )
    };
    let expected = MASS * G * 1e-5;
    for substeps in [1, 16] {
        let mut sim = simulation(&text(substeps), &[]);
        for _ in 0..300 {
            sim.step_frame().expect("step");
        }
        let p = sim.positions();
        let e = (p[1] - p[0]).length() - 1.0;
        assert!(
            ((e - expected) / expected).abs() < 0.01,
            "{substeps} substeps, α = 1e-5 m/N: extension {e:e} m, expected {expected:e} m"
        );
    }
}
