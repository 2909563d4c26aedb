//! The distance constraint of one edge as pure functions: its value and gradient, and one
//! XPBD step (optionally damped). The group in [`crate::group`] only loops over its batch and
//! calls [`project_distance`]; everything numerical lives, and is tested, here.
//!
//! See the [crate docs](crate) for the theory.

use glam::DVec3;

/// Below this length (m) the direction of an edge, and so the gradient of its constraint, is
/// undefined: the edge is skipped for that pass.
pub const MIN_LENGTH: f64 = 1e-12;

/// The material of an edge: how it resists stretch and compression, and how it is damped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeMaterial {
    /// Compliance α used when the edge is stretched or at its rest length, `C ≥ 0` (m/N).
    /// 0 is a hard constraint.
    pub compliance: f64,
    /// Compliance α used when the edge is compressed, `C < 0` (m/N). 0 is a hard constraint.
    pub compression_compliance: f64,
    /// Coefficient `c` of a linear damper in parallel with the edge (N·s/m): it resists the
    /// rate of change of the edge's length with the force `c·dC/dt`. Only acts on compliant
    /// edges (`α > 0`); 0 disables it.
    pub damping: f64,
}

impl EdgeMaterial {
    /// A hard, undamped edge: inextensible and incompressible.
    pub const HARD: Self = Self {
        compliance: 0.0,
        compression_compliance: 0.0,
        damping: 0.0,
    };

    /// The compliance for the constraint value `c`: [`compliance`](Self::compliance) when
    /// `c ≥ 0` (stretched), [`compression_compliance`](Self::compression_compliance) when
    /// `c < 0` (compressed).
    #[inline]
    pub fn compliance_for(&self, c: f64) -> f64 {
        if c >= 0.0 {
            self.compliance
        } else {
            self.compression_compliance
        }
    }
}

/// The change one XPBD step makes to an edge `(i, j)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// Displacement of particle `i` (m).
    pub dxi: DVec3,
    /// Displacement of particle `j` (m).
    pub dxj: DVec3,
    /// Increment of the edge's multiplier λ (N·s²).
    pub delta_lambda: f64,
}

/// `C = |xj − xi| − rest` (m) and `n = ∇_xj C = (xj − xi)/|xj − xi|` (so `∇_xi C = −n`).
///
/// `None` when `|xj − xi| < MIN_LENGTH` (or is not finite): the gradient is undefined there.
#[inline]
pub fn distance_constraint(xi: DVec3, xj: DVec3, rest: f64) -> Option<(f64, DVec3)> {
    let d = xj - xi;
    let len = d.length();
    if !len.is_finite() || len < MIN_LENGTH {
        return None;
    }
    Some((len - rest, d / len))
}

/// The smallest cosine between the current edge direction and its start-of-substep direction
/// for which the correction runs along the start direction (about 26°). Beyond it the edge is
/// turning fast within the substep and the plain XPBD direction converges better: measured on
/// the 32×32 drape at 1 substep × 1 pass, a 60° bound gave 1.43 mean RMS strain against 1.0
/// for 26° and 0.98 for never.
pub const START_DIRECTION_MIN_COS: f64 = 0.9;

/// One XPBD step on the edge between `x = [xi, xj]` with inverse masses `w = [wi, wj]`,
/// given the edge's multiplier `lambda` accumulated so far in this substep of length `h`.
///
/// With `α = material.compliance_for(C)`, `α̃ = α/h²` and `γ = α·c/h` (`c` the damping):
///
/// ```text
/// Δλ = (−C − α̃λ − γ ∇C·(x − x0)) / ((1 + γ)(wi + wj)(n·d) + α̃)
/// Δxi = −wi d Δλ,   Δxj = +wj d Δλ
/// ```
///
/// The correction moves along `d`, the edge's direction at the start of the substep
/// `(xj0 − xi0)/|xj0 − xi0|` (as SHAKE does), not along the current gradient `n`: with the
/// velocity update `v = (x − x0)/h`, a correction changes the angular momentum by
/// `Δλ (xj0 − xi0) × d / h`, which vanishes only for `d ∥ xj0 − xi0`. So every step conserves
/// linear *and* angular momentum exactly, and the Newton step along `d` uses the directional
/// derivative `(wi + wj)(n·d)`. Where the edge turned by more than ~26° within the substep
/// (`n·d < 0.9`) or had no length at its start, `d = n` (the plain XPBD step).
///
/// `x0 = [xi0, xj0]` are the positions at the start of the substep.
///
/// It is computed with unnormalised vectors (see [`correction_direction`]) and both sides of the
/// update multiplied by `|xj − xi|`, so that one square root and one division lie between
/// loading the edge and storing its correction (see the crate docs' "Cost" section for what
/// that buys); the result is the same up to rounding.
///
/// `None` when the edge cannot be projected: its particles (nearly) coincide, so the gradient
/// is undefined, or both have infinite mass. Never returns NaN for finite input.
#[inline]
pub fn project_distance(
    x: [DVec3; 2],
    x0: [DVec3; 2],
    w: [f64; 2],
    rest: f64,
    material: &EdgeMaterial,
    lambda: f64,
    h: f64,
) -> Option<Correction> {
    project_distance_with(x, x0, w, rest, &material.terms(h), lambda)
}

/// The terms of the XPBD update that depend on the material and the substep only, for a
/// stretched edge (index 0, `C ≥ 0`) and a compressed one (index 1): `α̃ = α/h²` (N⁻¹·s⁻²·m)
/// and `γ = α·c/h` (dimensionless). A pass computes them once for all its edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct XpbdTerms {
    /// `α̃` when stretched, when compressed.
    pub alpha_tilde: [f64; 2],
    /// `γ` when stretched, when compressed (0 without damping or for a hard side).
    pub gamma: [f64; 2],
}

impl EdgeMaterial {
    /// The [`XpbdTerms`] of this material for substeps of length `h` (s).
    pub fn terms(&self, h: f64) -> XpbdTerms {
        let side = |alpha: f64| {
            if alpha == 0.0 {
                (0.0, 0.0)
            } else {
                let gamma = if self.damping > 0.0 {
                    alpha * self.damping / h
                } else {
                    0.0
                };
                (alpha / (h * h), gamma)
            }
        };
        let (a0, g0) = side(self.compliance);
        let (a1, g1) = side(self.compression_compliance);
        XpbdTerms {
            alpha_tilde: [a0, a1],
            gamma: [g0, g1],
        }
    }
}

/// [`project_distance`] with the material's terms for this substep computed beforehand.
#[inline]
pub fn project_distance_with(
    x: [DVec3; 2],
    x0: [DVec3; 2],
    w: [f64; 2],
    rest: f64,
    terms: &XpbdTerms,
    lambda: f64,
) -> Option<Correction> {
    let e = EdgeStep::new(x, x0, w)?;
    let c = e.len - rest;
    // Stretched or compressed: the terms of the sign of C, chosen without a branch on the chain.
    let k = usize::from(c < 0.0);
    let (alpha_tilde, gamma) = (terms.alpha_tilde[k], terms.gamma[k]);
    // Δλ = s |u| with n·u = (d·u)/|d|; both sides of the XPBD update multiplied by |d| so that
    // one division remains. With damping (Macklin et al. 2016, eq. (26)) the update is the
    // undamped one with C → C + γ n·(x − x0) and Σw|∇C|² → (1 + γ) Σw|∇C|².
    let mut numerator = -(c + alpha_tilde * lambda) * e.len;
    if gamma > 0.0 {
        numerator -= gamma * e.d.dot((x[1] - x0[1]) - (x[0] - x0[0]));
    }
    let denominator = (1.0 + gamma) * e.w_sum * e.du + alpha_tilde * e.u_len * e.len;
    if denominator <= f64::MIN_POSITIVE || !denominator.is_finite() {
        return None;
    }
    Some(e.correction(w, numerator / denominator))
}

/// What both forms of the projection need of an edge: `d = xj − xi` and its length, the sum of
/// the inverse masses, and the correction direction `u` with `d·u` and `|u|` (see
/// [`correction_direction`]).
struct EdgeStep {
    d: DVec3,
    len: f64,
    w_sum: f64,
    u: DVec3,
    du: f64,
    u_len: f64,
}

impl EdgeStep {
    /// `None` when the edge cannot be projected: its particles (nearly) coincide, or both have
    /// infinite mass.
    #[inline]
    fn new(x: [DVec3; 2], x0: [DVec3; 2], w: [f64; 2]) -> Option<EdgeStep> {
        let d = x[1] - x[0];
        let len = d.length();
        if !len.is_finite() || len < MIN_LENGTH {
            return None;
        }
        let w_sum = w[0] + w[1];
        if w_sum.is_nan() || w_sum <= 0.0 {
            return None;
        }
        let (u, du, u_len) = correction_direction(d, len, x0);
        Some(EdgeStep {
            d,
            len,
            w_sum,
            u,
            du,
            u_len,
        })
    }

    /// The correction of the step `s` along `u`: `Δxi = −wi u s`, `Δxj = wj u s`, `Δλ = s |u|`.
    #[inline]
    fn correction(&self, w: [f64; 2], s: f64) -> Correction {
        let step = self.u * s;
        Correction {
            dxi: -w[0] * step,
            dxj: w[1] * step,
            delta_lambda: s * self.u_len,
        }
    }
}

/// The unnormalised direction `u` of the correction of an edge `d = xj − xi` of length `len`,
/// with `d·u` and `|u|`: the edge at the start of the substep `xj0 − xi0` when it has a length
/// and is within [`START_DIRECTION_MIN_COS`] of `d`, else `d` itself (the choice the docs of
/// [`project_distance`] state with unit vectors). No division: the cosine test is `d·u ≥ cos |d| |u|`.
#[inline]
pub fn correction_direction(d: DVec3, len: f64, x0: [DVec3; 2]) -> (DVec3, f64, f64) {
    let e0 = x0[1] - x0[0];
    let len0 = e0.length();
    let de = d.dot(e0);
    if len0 >= MIN_LENGTH && len0.is_finite() && de >= START_DIRECTION_MIN_COS * len * len0 {
        (e0, de, len0)
    } else {
        (d, len * len, len)
    }
}

/// [`project_distance`] for a hard edge (`material` [`EdgeMaterial::HARD`], or any material
/// whose two compliances are 0: damping has no effect on a hard edge): the same short chain of
/// dependent operations, without the compliance terms. Within a colour the edges are
/// independent, so the processor overlaps as many edges as its reorder window holds, and the
/// shorter the chain of each, the more it holds.
///
/// With `u` the unnormalised correction direction (`xj0 − xi0`, or `d = xj − xi`; see
/// [`correction_direction`]) and `n = d/|d|`, the Newton step along `u` is `s = −C/(Σw n·u)`, that
/// is `s = −C |d| / (Σw d·u)`, and `Δλ = s |u|`. The same step as [`project_distance`] up to
/// rounding.
#[inline]
pub fn project_distance_hard(
    x: [DVec3; 2],
    x0: [DVec3; 2],
    w: [f64; 2],
    rest: f64,
) -> Option<Correction> {
    let e = EdgeStep::new(x, x0, w)?;
    Some(e.correction(w, (rest - e.len) * e.len / (e.w_sum * e.du)))
}

#[cfg(test)]
mod tests {
    use super::*;

    use nucleus_sdk::testing::Rng;

    const H: f64 = 1.0 / 240.0;

    fn soft(alpha: f64) -> EdgeMaterial {
        EdgeMaterial {
            compliance: alpha,
            compression_compliance: alpha,
            damping: 0.0,
        }
    }

    fn project(x: [DVec3; 2], w: [f64; 2], rest: f64, m: &EdgeMaterial) -> Correction {
        project_distance(x, x, w, rest, m, 0.0, H).expect("a projectable edge")
    }

    fn length(x: [DVec3; 2]) -> f64 {
        (x[1] - x[0]).length()
    }

    /// The direction of the correction with unit vectors, as the docs of [`project_distance`]
    /// state it: the edge's direction at the start of the substep when it is defined and within
    /// [`START_DIRECTION_MIN_COS`] of the current one `n`, else `n`. The reference
    /// [`correction_direction`] must agree with.
    fn start_direction(x0: [DVec3; 2], n: DVec3) -> DVec3 {
        let e0 = x0[1] - x0[0];
        let len0 = e0.length();
        if len0 >= MIN_LENGTH && len0.is_finite() {
            let d = e0 / len0;
            if n.dot(d) >= START_DIRECTION_MIN_COS {
                return d;
            }
        }
        n
    }

    /// The XPBD update exactly as the docs of [`project_distance`] write it, with unit vectors
    /// and the SDK's `Δλ`: the reference the computed form must match.
    fn unit_vector_form(
        x: [DVec3; 2],
        x0: [DVec3; 2],
        w: [f64; 2],
        rest: f64,
        m: &EdgeMaterial,
        lambda: f64,
    ) -> Option<Correction> {
        let (c, n) = distance_constraint(x[0], x[1], rest)?;
        let d = start_direction(x0, n);
        let w_sum = (w[0] + w[1]) * n.dot(d);
        let alpha = m.compliance_for(c);
        let gamma = alpha * m.damping / H;
        let motion = n.dot((x[1] - x0[1]) - (x[0] - x0[0]));
        let dl = nucleus_sdk::xpbd::delta_lambda(
            c + gamma * motion,
            (1.0 + gamma) * w_sum,
            alpha,
            lambda,
            H,
        );
        Some(Correction {
            dxi: -w[0] * d * dl,
            dxj: w[1] * d * dl,
            delta_lambda: dl,
        })
    }

    #[test]
    fn the_computed_forms_match_the_unit_vector_form_of_the_update() {
        let mut rng = Rng(0x5151_2026);
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-10 * scale;
        for k in 0..2000 {
            let x = [rng.vec3(1.0), rng.vec3(1.0)];
            // Half the edges barely turned within the substep (the start direction is used),
            // half turned anywhere (mostly beyond the cone: the current direction is used).
            let x0 = if k % 2 == 0 {
                [x[0] + rng.vec3(0.05), x[1] + rng.vec3(0.05)]
            } else {
                [rng.vec3(1.0), rng.vec3(1.0)]
            };
            let w = [rng.range(0.0, 3.0), rng.range(0.1, 3.0)];
            let rest = rng.range(0.0, 2.0);
            let lambda = rng.range(-1e-3, 1e-3);
            let materials = [
                EdgeMaterial::HARD,
                soft(rng.range(0.0, 1e-3)),
                EdgeMaterial {
                    compliance: rng.range(0.0, 1e-3),
                    compression_compliance: rng.range(0.0, 1e-1),
                    damping: rng.range(0.0, 10.0),
                },
            ];
            for m in &materials {
                let want = unit_vector_form(x, x0, w, rest, m, lambda).expect("projectable");
                let got = project_distance(x, x0, w, rest, m, lambda, H).expect("projectable");
                let scale = want.dxi.length().max(want.dxj.length()).max(1e-12);
                for (a, b) in [(got.dxi, want.dxi), (got.dxj, want.dxj)] {
                    for axis in 0..3 {
                        assert!(close(a[axis], b[axis], scale), "case {k}: {a} vs {b}");
                    }
                }
                let l_scale = want.delta_lambda.abs().max(1e-12);
                assert!(
                    close(got.delta_lambda, want.delta_lambda, l_scale),
                    "case {k}"
                );
            }
            let hard = project_distance_hard(x, x0, w, rest).expect("projectable");
            let want = unit_vector_form(x, x0, w, rest, &EdgeMaterial::HARD, 0.0).expect("ok");
            let scale = want.dxi.length().max(want.dxj.length()).max(1e-12);
            for (a, b) in [(hard.dxi, want.dxi), (hard.dxj, want.dxj)] {
                for axis in 0..3 {
                    assert!(close(a[axis], b[axis], scale), "hard case {k}: {a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn gradient_matches_central_differences() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let eps = 1e-6;
        for _ in 0..200 {
            let xi = rng.vec3(1.0);
            let xj = rng.vec3(1.0);
            if (xj - xi).length() < 1e-2 {
                continue;
            }
            let rest = rng.range(0.0, 1.0);
            let (c, n) = distance_constraint(xi, xj, rest).expect("separated");
            assert!((c - ((xj - xi).length() - rest)).abs() < 1e-15);
            let c_at = |xi: DVec3, xj: DVec3| distance_constraint(xi, xj, rest).expect("sep").0;
            for axis in 0..3 {
                let mut e = DVec3::ZERO;
                e[axis] = eps;
                let d_dxi = (c_at(xi + e, xj) - c_at(xi - e, xj)) / (2.0 * eps);
                let d_dxj = (c_at(xi, xj + e) - c_at(xi, xj - e)) / (2.0 * eps);
                assert!((d_dxi + n[axis]).abs() < 1e-7, "∇xi C, axis {axis}");
                assert!((d_dxj - n[axis]).abs() < 1e-7, "∇xj C, axis {axis}");
            }
        }
    }

    #[test]
    fn projection_conserves_linear_and_angular_momentum() {
        let mut rng = Rng(42);
        for k in 0..500 {
            let x = [rng.vec3(2.0), rng.vec3(2.0)];
            // Masses from 1 g to 1 t, so the ratio reaches 1e6.
            let w = [
                10f64.powf(rng.range(-3.0, 3.0)),
                10f64.powf(rng.range(-3.0, 3.0)),
            ];
            let rest = rng.range(0.0, 3.0);
            let material = EdgeMaterial {
                compliance: if k % 2 == 0 { 0.0 } else { 1e-4 },
                compression_compliance: if k % 3 == 0 { 0.0 } else { 1e-2 },
                damping: if k % 5 == 0 { 50.0 } else { 0.0 },
            };
            let x0 = [x[0] + rng.vec3(0.01), x[1] + rng.vec3(0.01)];
            let lambda = rng.range(-1e-3, 1e-3);
            let Some(corr) = project_distance(x, x0, w, rest, &material, lambda, H) else {
                continue;
            };
            let (mi, mj) = (1.0 / w[0], 1.0 / w[1]);
            // Scale of the momenta involved, for a relative tolerance.
            let p_scale = mi * corr.dxi.length() + mj * corr.dxj.length();
            let p = mi * corr.dxi + mj * corr.dxj;
            assert!(p.length() <= 1e-12 * p_scale, "linear: {p} vs {p_scale}");
            // With v = (x − x0)/h the step changes the angular momentum by
            // Σ m x0 × Δx / h: zero when the correction runs along the start direction.
            let l_scale =
                mi * x0[0].length() * corr.dxi.length() + mj * x0[1].length() * corr.dxj.length();
            let l = mi * x0[0].cross(corr.dxi) + mj * x0[1].cross(corr.dxj);
            assert!(l.length() <= 1e-12 * l_scale, "angular: {l} vs {l_scale}");
        }
    }

    #[test]
    fn correction_falls_back_to_the_current_direction_after_a_large_turn() {
        const _: () = assert!(START_DIRECTION_MIN_COS > 0.5 && START_DIRECTION_MIN_COS < 1.0);
        let x = [DVec3::ZERO, DVec3::new(0.0, 2.0, 0.0)];
        let x0 = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
        let corr = project_distance(x, x0, [1.0, 1.0], 1.0, &EdgeMaterial::HARD, 0.0, H).unwrap();
        assert!(corr.dxj.x.abs() < 1e-15 && corr.dxj.y < 0.0);
        // Within the bound, the start direction is used and the edge still reaches its length
        // after a few passes (Newton along d).
        let x0 = [DVec3::ZERO, DVec3::new(1.0, 0.2, 0.0)];
        let mut x = [DVec3::ZERO, DVec3::new(1.3, 0.5, 0.0)];
        for _ in 0..20 {
            let c = project_distance(x, x0, [1.0, 1.0], 1.0, &EdgeMaterial::HARD, 0.0, H).unwrap();
            x[0] += c.dxi;
            x[1] += c.dxj;
        }
        assert!(((x[1] - x[0]).length() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn infinite_mass_particle_does_not_move() {
        let x = [DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0)];
        for material in [EdgeMaterial::HARD, soft(1e-3)] {
            let corr = project(x, [0.0, 1.0], 1.0, &material);
            assert_eq!(x[0] + corr.dxi, x[0]);
            assert!(corr.dxj.x < 0.0);
            let corr = project(x, [1.0, 0.0], 1.0, &material);
            assert_eq!(x[1] + corr.dxj, x[1]);
            assert!(corr.dxi.x > 0.0);
        }
    }

    #[test]
    fn both_infinite_masses_are_skipped() {
        let x = [DVec3::ZERO, DVec3::X];
        assert_eq!(
            project_distance(x, x, [0.0, 0.0], 0.5, &soft(1e-3), 0.0, H),
            None
        );
    }

    #[test]
    fn hard_constraint_is_satisfied_after_one_projection() {
        let mut rng = Rng(7);
        for _ in 0..100 {
            let x = [rng.vec3(1.0), rng.vec3(1.0)];
            let w = [rng.range(0.1, 10.0), rng.range(0.1, 10.0)];
            let rest = rng.range(0.0, 2.0);
            let corr = project(x, w, rest, &EdgeMaterial::HARD);
            let after = [x[0] + corr.dxi, x[1] + corr.dxj];
            assert!((length(after) - rest).abs() < 1e-12, "{}", length(after));
        }
    }

    #[test]
    fn compliant_step_leaves_the_xpbd_fraction_of_the_violation() {
        // One step from λ = 0 on an isolated edge: C' = C · α̃ / (wi + wj + α̃).
        let (alpha, w) = (1e-4, [1.0, 3.0]);
        let x = [DVec3::ZERO, DVec3::new(1.5, 0.0, 0.0)];
        let corr = project(x, w, 1.0, &soft(alpha));
        let after = [x[0] + corr.dxi, x[1] + corr.dxj];
        let at = alpha / (H * H);
        let expected = 0.5 * at / (w[0] + w[1] + at);
        assert!((length(after) - 1.0 - expected).abs() < 1e-14);
        // λ/h² is the edge force: negative (tension) with magnitude C'/α.
        assert!((corr.delta_lambda / (H * H) + expected / alpha).abs() < 1e-9);
    }

    #[test]
    fn compliance_is_chosen_by_the_sign_of_c() {
        // Hard in stretch, very soft in compression: a stretched edge snaps back to its rest
        // length, a compressed one barely moves. The same with the roles swapped.
        let buckles = EdgeMaterial {
            compliance: 0.0,
            compression_compliance: 1.0,
            damping: 0.0,
        };
        let rigid_in_compression = EdgeMaterial {
            compliance: 1.0,
            compression_compliance: 0.0,
            damping: 0.0,
        };
        let stretched = [DVec3::ZERO, DVec3::new(0.0, 1.2, 0.0)];
        let compressed = [DVec3::ZERO, DVec3::new(0.0, 0.8, 0.0)];
        let after = |x: [DVec3; 2], m: &EdgeMaterial| {
            let c = project(x, [1.0, 1.0], 1.0, m);
            length([x[0] + c.dxi, x[1] + c.dxj])
        };
        assert!((after(stretched, &buckles) - 1.0).abs() < 1e-12);
        assert!((after(compressed, &buckles) - 0.8).abs() < 1e-4);
        assert!((after(compressed, &rigid_in_compression) - 1.0).abs() < 1e-12);
        assert!((after(stretched, &rigid_in_compression) - 1.2).abs() < 1e-4);
        // At the rest length exactly, C = 0 counts as stretched.
        assert_eq!(buckles.compliance_for(0.0), 0.0);
        assert_eq!(buckles.compliance_for(-1e-300), 1.0);
    }

    #[test]
    fn damped_step_is_backward_euler_of_a_spring_and_damper() {
        // An isolated edge along x, one step from λ = 0: XPBD with Macklin's damping solves
        // the backward-Euler step of a spring k = 1/α in parallel with a damper c, for the
        // length d = xj − xi (W = wi + wj, d̃ the predicted length, d0 the start length):
        //   d⁺ (1 + h²Wk + hWc) = d̃ + h²Wk·l + hWc·d0.
        let (alpha, c, w, l) = (1e-3, 20.0, [0.5, 2.0], 1.0);
        let x0 = [DVec3::new(0.1, 0.0, 0.0), DVec3::new(1.2, 0.0, 0.0)];
        let x = [DVec3::new(0.05, 0.0, 0.0), DVec3::new(1.4, 0.0, 0.0)];
        let material = EdgeMaterial {
            compliance: alpha,
            compression_compliance: alpha,
            damping: c,
        };
        let corr = project_distance(x, x0, w, l, &material, 0.0, H).expect("projectable");
        let d_after = (x[1] + corr.dxj).x - (x[0] + corr.dxi).x;
        let (ww, k) = (w[0] + w[1], 1.0 / alpha);
        let (d_pred, d0) = (x[1].x - x[0].x, x0[1].x - x0[0].x);
        let expected =
            (d_pred + H * H * ww * k * l + H * ww * c * d0) / (1.0 + H * H * ww * k + H * ww * c);
        assert!(
            (d_after - expected).abs() < 1e-14,
            "{d_after} vs {expected}"
        );
        // And without the damper it is the plain spring.
        let undamped = project(x, w, l, &soft(alpha));
        let d_spring = (x[1] + undamped.dxj).x - (x[0] + undamped.dxi).x;
        let expected = (d_pred + H * H * ww * k * l) / (1.0 + H * H * ww * k);
        assert!((d_spring - expected).abs() < 1e-14);
    }

    #[test]
    fn damping_does_not_change_a_hard_constraint() {
        let x0 = [DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0)];
        let x = [DVec3::new(0.0, 0.1, 0.0), DVec3::new(0.0, 0.0, 1.7)];
        let damped = EdgeMaterial {
            damping: 1e3,
            ..EdgeMaterial::HARD
        };
        let a = project_distance(x, x0, [1.0, 1.0], 1.0, &damped, 0.0, H);
        let b = project_distance(x, x0, [1.0, 1.0], 1.0, &EdgeMaterial::HARD, 0.0, H);
        assert_eq!(a, b);
    }

    #[test]
    fn coincident_particles_are_skipped_without_nan() {
        let p = DVec3::new(0.3, -0.2, 0.1);
        for m in [EdgeMaterial::HARD, soft(1e-3)] {
            assert_eq!(
                project_distance([p, p], [p, p], [1.0, 1.0], 0.0, &m, 0.0, H),
                None
            );
            assert_eq!(
                project_distance([p, p], [p, p], [1.0, 1.0], 1.0, &m, 0.0, H),
                None
            );
            let q = p + DVec3::splat(1e-13);
            assert_eq!(
                project_distance([p, q], [p, q], [1.0, 1.0], 1.0, &m, 0.0, H),
                None
            );
        }
        let nan = DVec3::splat(f64::NAN);
        assert_eq!(distance_constraint(p, nan, 1.0), None);
    }

    #[test]
    fn zero_rest_length_pulls_the_points_together() {
        let x = [DVec3::ZERO, DVec3::new(0.0, 0.0, 0.5)];
        let corr = project(x, [1.0, 1.0], 0.0, &EdgeMaterial::HARD);
        assert!((x[0] + corr.dxi - (x[1] + corr.dxj)).length() < 1e-15);
    }
}
