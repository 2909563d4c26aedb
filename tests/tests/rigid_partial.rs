//! Partial rigidity, through the dynamically loaded `rigid` plugin: under the same load the
//! deformation decreases strictly as the rigidity (the inverse of the `compliance`) increases.
//!
//! The load is gravity on a 0.4 × 0.2 × 0.1 m block of tets (4 × 2 × 1 cells, density
//! 500 kg/m³ lumped by tet volume, so the masses differ) held by the pins of its x = 0 face,
//! which alone fix its rigid frame. Each free particle is pulled to its goal by a spring of
//! stiffness `mᵢ/α`, so at rest it hangs exactly `α|g|` below it: the deformation (the
//! group's residual, the largest distance of a particle from its rigid goal) must match that
//! within 0.01 %, and with `α = 0` the block must stay rigid to rounding. Damping settles the
//! oscillation; the static balance does not depend on it.
//!
//! The same holds for a block held at a single corner (it swings, then hangs with its centre
//! of mass below the pin): a second load case, where the frame rotates.

use nucleus_tests::*;

/// The settled deformation (m) of the block under gravity with compliance `alpha` (s²).
fn settled_deformation(pins: &str, alpha: f64) -> f64 {
    let text = format!(
        r#"
[solver]
frame_rate = 60.0
substeps = 10
damping = 8.0
[[objects]]
name = "block"
density = 500.0
pins = [{pins}]
[objects.tet_box]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.2, 0.1]
resolution = [4, 2, 1]
[[constraints]]
kind = "rigid"
params = {{ compliance = {alpha:e} }}
"#
    );
    let mut sim = simulation(&text, &[]);
    for _ in 0..360 {
        sim.step_frame().unwrap_or_else(|e| panic!("step: {e}"));
    }
    let residual = sim.residuals().expect("residual")[0];
    assert!(residual.max.is_finite());
    residual.max
}

fn check(case: &str, pins: &str) {
    let compliances = [1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 1e-5, 0.0];
    let deformations: Vec<f64> = compliances
        .iter()
        .map(|&a| settled_deformation(pins, a))
        .collect();
    eprintln!("{case}: compliance (s²) -> deformation (m)");
    for (a, d) in compliances.iter().zip(&deformations) {
        eprintln!("  {a:8.0e} -> {d:.6e} (α|g| = {:.6e})", a * 9.81);
    }
    for w in deformations.windows(2) {
        assert!(
            w[1] < w[0],
            "{case}: not strictly decreasing: {deformations:?}"
        );
    }
    for (&a, &d) in compliances.iter().zip(&deformations) {
        if a > 0.0 {
            let expected = a * 9.81;
            assert!(
                (d - expected).abs() < 1e-4 * expected,
                "{case}: α = {a}: {d} vs α|g| = {expected}"
            );
        } else {
            assert!(d < 1e-12, "{case}: rigid block deformed by {d}");
        }
    }
}

#[test]
fn deformation_under_gravity_falls_with_rigidity_for_a_block_held_by_a_face() {
    check(
        "held by a face",
        "{ min = [-0.01, -1.0, -1.0], max = [0.01, 1.0, 1.0] }",
    );
}

#[test]
fn deformation_under_gravity_falls_with_rigidity_for_a_block_hanging_from_a_corner() {
    check("hanging from a corner", "0");
}
