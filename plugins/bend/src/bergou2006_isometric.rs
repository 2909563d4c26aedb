//! Isometric (quadratic) bending: Bergou, Wardetzky, Harmon, Zorin, Grinspun, "A Quadratic
//! Bending Model for Inextensible Surfaces", SGP 2006 — as pure functions.
//!
//! For a hinge `(x₀, x₁; x₂, x₃)` (axis `x₀x₁`, wing tips `x₂`, `x₃`), with the edge vectors
//! `e₀ = x₁ − x₀, e₁ = x₂ − x₀, e₂ = x₃ − x₀, e₃ = x₂ − x₁, e₄ = x₃ − x₁` and `c₀ⱼ` the
//! cotangent of the angle between `e₀` (or `−e₀` for `j = 3, 4`) and `eⱼ`, Bergou's discrete
//! Laplacian weights of the hinge are
//!
//! ```text
//! K = (c₀₃ + c₀₄,  c₀₁ + c₀₂,  −c₀₁ − c₀₃,  −c₀₂ − c₀₄)
//! ```
//!
//! and the bending energy is quadratic in the positions, `E = ½ k Σ (3/(A₀+A₁)) |Σᵢ Kᵢ xᵢ|²`.
//! The weights depend only on the rest shape's angles, which an isometric (unstretched)
//! deformation keeps, so they are computed once. `Σᵢ Kᵢ = 0` and `Σᵢ Kᵢ xᵢ = 0` for any flat
//! configuration: the model's rest shape is **flat**.
//!
//! **As a constraint.** We scale the weights by the rest axis length, `K' = K/|e₀|`, and use
//!
//! ```text
//! v = Σᵢ K'ᵢ xᵢ,     C = |v|,     ∇xᵢ C = K'ᵢ v̂,     Σᵢ wᵢ|∇xᵢC|² = Σᵢ wᵢ K'ᵢ²
//! ```
//!
//! For a hinge bent isometrically by the dihedral angle θ, `|v| = 2 sin(θ/2)` exactly (a unit
//! test checks it), so `C ≈ |θ|` and the energy `½ C²/α` matches the dihedral model's
//! `½ θ²/α` for small angles: **both models take the same compliance** α (rad/(N·m)) per hinge,
//! and Bergou's stiffness is `k = 3|e₀|²/(α(A₀+A₁))`. The XPBD step needs no trigonometry,
//! no division by the current geometry and one square root: the fast model for nearly flat
//! cloth. Taking `C = |v|` (rather than the three components of `v`) keeps the correction
//! parallel to `v`, so every step conserves angular momentum (`Σ xᵢ × K'ᵢ v̂ = v × v̂ = 0`) as
//! well as linear momentum (`Σ K'ᵢ = 0`). Where `|v|` is below [`MIN_V`] the hinge is flat:
//! nothing to do, and the direction is undefined, so it is skipped for that pass.
//!
//! **Limits.** The weights assume small rotations of the wings relative to each other and a
//! flat rest shape: a pre-folded shape is flattened (use the dihedral `bend` for those), and
//! for large angles the restoring torque `∝ sin(θ/2)`-ish departs from the dihedral model's.

use glam::DVec3;

use crate::step::Correction;

/// Below this `|v|` (≈ angle in rad) the hinge is flat: skipped for that pass.
pub const MIN_V: f64 = 1e-14;

/// Below this `sin` of a rest-shape angle at the axis, a rest triangle is degenerate and its
/// cotangent unbounded: no weights.
pub const MIN_REST_SIN: f64 = 1e-9;

#[inline]
fn cot(u: DVec3, v: DVec3) -> Option<f64> {
    let sin = u.cross(v).length();
    if sin.is_nan() || sin < MIN_REST_SIN * u.length() * v.length() {
        return None;
    }
    let c = u.dot(v) / sin;
    c.is_finite().then_some(c)
}

/// The scaled weights `K' = K/|e₀|` (1/m) of the hinge `rest = [x₀, x₁, x₂, x₃]` in its rest
/// shape; `None` if an axis is shorter than 1e-12 m or a rest triangle is degenerate (an
/// angle at the axis with `sin` below [`MIN_REST_SIN`]).
pub fn isometric_weights(rest: &[DVec3; 4]) -> Option<[f64; 4]> {
    let [x0, x1, x2, x3] = *rest;
    let e0 = x1 - x0;
    let len = e0.length();
    if !(len >= 1e-12 && len.is_finite()) {
        return None;
    }
    let c01 = cot(e0, x2 - x0)?;
    let c02 = cot(e0, x3 - x0)?;
    let c03 = cot(-e0, x2 - x1)?;
    let c04 = cot(-e0, x3 - x1)?;
    Some([
        (c03 + c04) / len,
        (c01 + c02) / len,
        -(c01 + c03) / len,
        -(c02 + c04) / len,
    ])
}

/// `v = Σᵢ K'ᵢ xᵢ`, computed relative to `x₀` (exact for `Σ K' = 0`, and free of the
/// cancellation error of absolute coordinates far from the origin).
#[inline]
pub fn curvature_vector(x: &[DVec3; 4], k: &[f64; 4]) -> DVec3 {
    (x[1] - x[0]) * k[1] + (x[2] - x[0]) * k[2] + (x[3] - x[0]) * k[3]
}

/// `C = |v|` (≈ the hinge's angle away from flat, rad) and `v̂`; `None` if the hinge is flat
/// (`|v| < MIN_V`) or the input is not finite.
#[inline]
pub fn isometric_constraint(x: &[DVec3; 4], k: &[f64; 4]) -> Option<(f64, DVec3)> {
    let v = curvature_vector(x, k);
    let c = v.length();
    if !(c >= MIN_V && c.is_finite()) {
        return None;
    }
    Some((c, v / c))
}

/// One XPBD step flattening the hinge `x` with weights `k` (from [`isometric_weights`]), for
/// inverse masses `w`, compliance `alpha` (rad/(N·m)), the multiplier `lambda` accumulated in
/// this substep and the substep `h` (s).
///
/// `None` when the hinge is flat (nothing to do) or no particle can move. Never returns NaN
/// for finite input.
#[inline]
pub fn project_isometric(
    x: &[DVec3; 4],
    k: &[f64; 4],
    w: &[f64; 4],
    alpha: f64,
    lambda: f64,
    h: f64,
) -> Option<Correction<4>> {
    let v = curvature_vector(x, k);
    let c_sq = v.length_squared();
    if !(c_sq >= MIN_V * MIN_V && c_sq.is_finite()) {
        return None;
    }
    let c = c_sq.sqrt();
    // Σ wᵢ|∇ᵢC|² = Σ wᵢK'ᵢ², since |v̂| = 1.
    let w_grad_sq =
        w[0] * k[0] * k[0] + w[1] * k[1] * k[1] + w[2] * k[2] * k[2] + w[3] * k[3] * k[3];
    let alpha_tilde = alpha / (h * h);
    let denom = w_grad_sq + alpha_tilde;
    if !(denom > f64::MIN_POSITIVE && denom.is_finite() && w_grad_sq > 0.0) {
        return None;
    }
    // Δλ = (−C − α̃λ)/denom; Δxᵢ = wᵢK'ᵢ v̂ Δλ = wᵢK'ᵢ (Δλ/C) v: one division for both.
    let f = (-c - alpha_tilde * lambda) / (denom * c);
    Some(Correction {
        dx: [
            v * (w[0] * k[0] * f),
            v * (w[1] * k[1] * f),
            v * (w[2] * k[2] * f),
            v * (w[3] * k[3] * f),
        ],
        delta_lambda: f * c,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dihedral::dihedral_angle;
    use crate::testutil::{assert_conserves_momentum, Draws, Rng};
    use std::f64::consts::PI;

    const H: f64 = 1.0 / 600.0;

    /// A random flat hinge in the plane spanned by `(u, v)` and the same hinge with the wing
    /// `x₃` turned by `theta` about the axis (an isometric fold; right-handed about `u`).
    fn folded(rng: &mut Rng, theta: f64) -> ([DVec3; 4], [DVec3; 4]) {
        let (u, v) = rng.frame();
        let n = u.cross(v);
        let o = rng.vec3(2.0);
        let len = rng.range(0.2, 2.0);
        let (sk, hk) = (rng.range(-0.3, 1.3), rng.range(0.2, 1.2));
        let (sl, hl) = (rng.range(-0.3, 1.3), rng.range(0.2, 1.2));
        let flat = [
            o,
            o + u * len,
            o + u * (sk * len) + v * hk,
            o + u * (sl * len) - v * hl,
        ];
        let mut bent = flat;
        bent[3] = o + u * (sl * len) - (v * theta.cos() + n * theta.sin()) * hl;
        (flat, bent)
    }

    #[test]
    fn weights_sum_to_zero_and_annihilate_flat_configurations() {
        let mut rng = Rng(1);
        for _ in 0..200 {
            let (flat, _) = folded(&mut rng, 0.0);
            let k = isometric_weights(&flat).expect("regular");
            let scale: f64 = k.iter().map(|c| c.abs()).sum();
            assert!(k.iter().sum::<f64>().abs() < 1e-12 * scale);
            assert!(curvature_vector(&flat, &k).length() < 1e-12 * scale);
        }
    }

    #[test]
    fn weights_of_a_symmetric_diamond_are_bergous() {
        // Axis of length 2, wings at height 1 over its midpoint: every cotangent is 1.
        let x = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
        ];
        let k = isometric_weights(&x).expect("regular");
        assert_eq!(k, [1.0, 1.0, -1.0, -1.0]);
    }

    #[test]
    fn constraint_is_two_sin_half_the_fold_angle() {
        let mut rng = Rng(2);
        for _ in 0..200 {
            let theta = rng.range(-3.0, 3.0);
            let (flat, bent) = folded(&mut rng, theta);
            let k = isometric_weights(&flat).expect("regular");
            let (c, _) = isometric_constraint(&bent, &k).expect("bent");
            assert!(
                (c - 2.0 * (theta / 2.0).sin().abs()).abs() < 1e-12,
                "{c} vs θ = {theta}"
            );
            // And θ is the dihedral model's angle.
            let phi = dihedral_angle(&bent).expect("regular");
            assert!((phi - theta).abs() < 1e-12);
        }
    }

    #[test]
    fn gradient_matches_central_differences() {
        let mut rng = Rng(3);
        let eps = 1e-7;
        for case in 0..300 {
            let theta = if case % 2 == 0 {
                rng.range(-3.0, 3.0)
            } else {
                rng.range(1e-3, 2e-3)
            };
            let (flat, bent) = folded(&mut rng, theta);
            // Perturb off the isometric fold too: the constraint is defined everywhere.
            let x = bent.map(|p| p + rng.vec3(0.05));
            let k = isometric_weights(&flat).expect("regular");
            let (_, v_hat) = isometric_constraint(&x, &k).expect("bent");
            let c_at = |x: &[DVec3; 4]| isometric_constraint(x, &k).expect("bent").0;
            for p in 0..4 {
                for axis in 0..3 {
                    let mut plus = x;
                    let mut minus = x;
                    plus[p][axis] += eps;
                    minus[p][axis] -= eps;
                    let fd = (c_at(&plus) - c_at(&minus)) / (2.0 * eps);
                    let g = v_hat[axis] * k[p];
                    assert!(
                        (fd - g).abs() < 1e-5 * (1.0 + k[p].abs()),
                        "case {case}: {fd} vs {g}"
                    );
                }
            }
        }
    }

    #[test]
    fn projection_conserves_linear_and_angular_momentum() {
        let mut rng = Rng(4);
        for n in 0..500 {
            let theta = rng.range(-PI, PI);
            let (flat, bent) = folded(&mut rng, theta);
            let x = bent.map(|p| p + rng.vec3(0.05));
            let k = isometric_weights(&flat).expect("regular");
            let w = [
                rng.inv_mass(),
                rng.inv_mass(),
                rng.inv_mass(),
                rng.inv_mass(),
            ];
            let alpha = if n % 2 == 0 {
                0.0
            } else {
                rng.range(0.0, 10.0)
            };
            let lambda = rng.range(-1e-4, 1e-4);
            let c = project_isometric(&x, &k, &w, alpha, lambda, H).expect("bent");
            assert_conserves_momentum(&x, &w, &c.dx);
        }
    }

    #[test]
    fn hard_projection_flattens_in_one_step() {
        // C = |v| is linear along v̂, and the step moves v along v̂: exact in one step.
        let mut rng = Rng(6);
        for _ in 0..100 {
            let theta = rng.range(-2.0, 2.0);
            let (flat, bent) = folded(&mut rng, theta);
            let k = isometric_weights(&flat).expect("regular");
            let w = [rng.range(0.5, 2.0), rng.range(0.5, 2.0), 1.0, 1.0];
            let c = project_isometric(&bent, &k, &w, 0.0, 0.0, H).expect("bent");
            let x: [DVec3; 4] = std::array::from_fn(|i| bent[i] + c.dx[i]);
            assert!(curvature_vector(&x, &k).length() < 1e-12);
        }
    }

    #[test]
    fn degenerate_rest_triangles_have_no_weights_and_flat_hinges_are_skipped() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert_eq!(isometric_weights(&[p; 4]), None);
        // Wing k on the axis line: zero-area triangle.
        let x = [p, p + DVec3::X, p + DVec3::X * 2.0, p - DVec3::Y];
        assert_eq!(isometric_weights(&x), None);
        let nan = [p, p + DVec3::X, p + DVec3::Y, DVec3::splat(f64::NAN)];
        assert_eq!(isometric_weights(&nan), None);
        // A flat hinge, and every vertex coincident: nothing to do, no NaN.
        let good = [
            p,
            p + DVec3::X,
            p + DVec3::new(0.5, 1.0, 0.0),
            p + DVec3::new(0.5, -1.0, 0.0),
        ];
        let k = isometric_weights(&good).expect("regular");
        assert_eq!(project_isometric(&good, &k, &[1.0; 4], 0.0, 0.0, H), None);
        assert_eq!(
            project_isometric(&[p; 4], &k, &[1.0; 4], 1e-3, 0.5, H),
            None
        );
        assert_eq!(project_isometric(&nan, &k, &[1.0; 4], 0.0, 0.0, H), None);
    }
}
