//! The paper's type-3 constraint: the dihedral angle of a hinge, as pure functions. Bend for
//! surfaces (two triangles sharing an edge), twist for curves (three consecutive edges).
//!
//! A hinge is four points `(i, j, k, l)`: the axis runs from `xi` to `xj`, and `xk`, `xl` are
//! the wing tips on either side. With `e = xj − xi`, `a = xk − xi`, `b = xl − xi`:
//!
//! ```text
//! n₁ = e × a,   n₂ = b × e                       (|n₁| = 2·area(i, j, k), |n₂| = 2·area(i, j, l))
//! φ  = atan2((n₁ × n₂)·ê, n₁ · n₂) ∈ (−π, π]     (signed: the rotation about ê taking n₁ to n₂)
//! C  = wrap(φ − φ₀) ∈ (−π, π]                    (rad; φ₀ from the rest shape)
//! ```
//!
//! For two triangles `(i, j, k)` and `(j, i, l)` wound consistently, `n₁` and `n₂` are their
//! normals (times twice the areas), `φ = 0` is flat, and `φ → ±π` folds the wings onto each
//! other; the sign says to which side. The paper's `acos(n̂₁ · n̂₂)` is `|φ|`.
//!
//! **Gradient** (the classical hinge formula; Bridson et al. 2003, Tamstorf & Grinspun 2013),
//! with `sₖ = a·e/|e|²` and `sₗ = b·e/|e|²` the positions of the wing tips' projections
//! along the axis:
//!
//! ```text
//! ∇xk φ = −|e| n₁/|n₁|²,   ∇xl φ = −|e| n₂/|n₂|²
//! ∇xi φ = −(1 − sₖ)∇xk φ − (1 − sₗ)∇xl φ,   ∇xj φ = −sₖ∇xk φ − sₗ∇xl φ
//! ```
//!
//! Every term is finite unless an element is degenerate: `|∇xk φ| = 1/hₖ` with `hₖ` the
//! height of `k` over the axis. An axis shorter than [`MIN_LENGTH`] or a wing of height below
//! [`MIN_LENGTH`] (a zero-area triangle, a curve folded onto a line) has no defined angle:
//! that constraint is skipped for the pass, never divided by zero.
//!
//! **Why signed, and why wrapped.** `acos` has an infinite derivative at 0 and π and returns
//! NaN when rounding pushes `n̂₁ · n̂₂` past ±1. Worse, `|φ|` cannot tell a hinge folded 30° up
//! from one folded 30° down: a pre-folded shape pushed through flat settles folded the wrong
//! way, and a rest angle of 0 has a kink where the gradient flips. The signed `atan2` angle is
//! smooth through flat. Its only discontinuity is at ±π (wings on top of each other), so the
//! difference to the rest angle is wrapped into (−π, π]: a hinge at rest at 170° that folds to
//! −175° is 15° away, not 345°. The constraint therefore always turns the hinge the short way
//! back to its rest angle, whatever that angle is.

use glam::DVec3;

use crate::step::{xpbd_correction, Correction};
use crate::trig::atan2;

/// Below this length (m) the hinge axis has no direction, and below this height (m) over
/// the axis a wing has no plane: the hinge is skipped for that pass.
pub const MIN_LENGTH: f64 = 1e-12;

/// `d` wrapped into `(−π, π]` (for `d` in `(−3π, 3π]`, which covers every difference of two
/// angles in `(−π, π]`). Non-finite input stays non-finite.
#[inline]
pub fn wrap_angle(d: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if d > PI {
        d - TAU
    } else if d <= -PI {
        d + TAU
    } else {
        d
    }
}

/// The intermediate quantities of a hinge, `None` if degenerate.
struct Hinge {
    e: DVec3,
    e_sq: f64,
    e_len: f64,
    a: DVec3,
    b: DVec3,
    n1: DVec3,
    n2: DVec3,
    n1_sq: f64,
    n2_sq: f64,
}

#[inline]
fn hinge(x: &[DVec3; 4]) -> Option<Hinge> {
    let e = x[1] - x[0];
    let e_sq = e.length_squared();
    if !(e_sq >= MIN_LENGTH * MIN_LENGTH && e_sq.is_finite()) {
        return None;
    }
    let a = x[2] - x[0];
    let b = x[3] - x[0];
    let n1 = e.cross(a);
    let n2 = b.cross(e);
    let (n1_sq, n2_sq) = (n1.length_squared(), n2.length_squared());
    // Heights |n|/|e| of both wings at least MIN_LENGTH (false for NaN).
    let min_sq = MIN_LENGTH * MIN_LENGTH * e_sq;
    if !(n1_sq >= min_sq && n2_sq >= min_sq && n1_sq.is_finite() && n2_sq.is_finite()) {
        return None;
    }
    Some(Hinge {
        e,
        e_sq,
        e_len: e_sq.sqrt(),
        a,
        b,
        n1,
        n2,
        n1_sq,
        n2_sq,
    })
}

impl Hinge {
    /// `atan2((n₁ × n₂)·ê, n₁·n₂)`, with both arguments scaled by |e| (atan2 does not mind).
    #[inline]
    fn angle(&self) -> f64 {
        atan2(
            self.n1.cross(self.n2).dot(self.e),
            self.n1.dot(self.n2) * self.e_len,
        )
    }
}

/// The signed dihedral angle `φ ∈ (−π, π]` (rad) of the hinge `x = [xi, xj, xk, xl]` (see
/// the [module docs](self)); `None` if the axis or a wing is degenerate or the input is not
/// finite.
#[inline]
pub fn dihedral_angle(x: &[DVec3; 4]) -> Option<f64> {
    let phi = hinge(x)?.angle();
    phi.is_finite().then_some(phi)
}

/// The signed dihedral angle (as [`dihedral_angle`]) and its gradient with respect to
/// `xi, xj, xk, xl`; `None` where [`dihedral_angle`] is.
#[inline]
pub fn dihedral_angle_gradient(x: &[DVec3; 4]) -> Option<(f64, [DVec3; 4])> {
    let g = hinge(x)?;
    let phi = g.angle();
    // 1/|e|², 1/|n₁|² and 1/|n₂|² from one division.
    let r = 1.0 / (g.e_sq * g.n1_sq * g.n2_sq);
    let inv_e_sq = g.n1_sq * g.n2_sq * r;
    let gk = g.n1 * (-g.e_len * g.e_sq * g.n2_sq * r);
    let gl = g.n2 * (-g.e_len * g.e_sq * g.n1_sq * r);
    let sk = g.a.dot(g.e) * inv_e_sq;
    let sl = g.b.dot(g.e) * inv_e_sq;
    let gi = -(gk * (1.0 - sk) + gl * (1.0 - sl));
    let gj = -(gk * sk + gl * sl);
    let grad = [gi, gj, gk, gl];
    (phi.is_finite() && grad.iter().all(|v| v.is_finite())).then_some((phi, grad))
}

/// One XPBD step turning the hinge `x` towards its rest angle `rest` (rad, in (−π, π]),
/// for inverse masses `w`, compliance `alpha` (rad/(N·m)), the multiplier `lambda`
/// accumulated in this substep and the substep `h` (s). `C = wrap(φ − rest)`.
///
/// `None` when the hinge is skipped for this pass (degenerate) or no particle can move.
/// Never returns NaN for finite input.
#[inline]
pub fn project_dihedral(
    x: &[DVec3; 4],
    w: &[f64; 4],
    rest: f64,
    alpha: f64,
    lambda: f64,
    h: f64,
) -> Option<Correction<4>> {
    let (phi, grad) = dihedral_angle_gradient(x)?;
    xpbd_correction(wrap_angle(phi - rest), &grad, w, alpha, lambda, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{assert_conserves_momentum, Draws, Rng};
    use std::f64::consts::PI;

    const H: f64 = 1.0 / 600.0;

    /// A hinge with signed angle `phi`: axis from `o` along `u` (length `len`), wing `k` at
    /// height `hk` and axial position `sk`, wing `l` at height `hl` and position `sl`.
    #[allow(clippy::too_many_arguments)]
    fn make_hinge(
        o: DVec3,
        (u, v): (DVec3, DVec3),
        len: f64,
        phi: f64,
        (sk, hk): (f64, f64),
        (sl, hl): (f64, f64),
    ) -> [DVec3; 4] {
        // k on the +v side; l turned by φ about u (right-handed) from the flat position −v.
        let w = u.cross(v);
        let l_dir = -(v * phi.cos()) - w * phi.sin();
        [
            o,
            o + u * len,
            o + u * (sk * len) + v * hk,
            o + u * (sl * len) + l_dir * hl,
        ]
    }

    fn random_hinge(rng: &mut Rng, phi: f64) -> [DVec3; 4] {
        let o = rng.vec3(1.0);
        let frame = rng.frame();
        let len = rng.range(0.2, 2.0);
        let k = (rng.range(-0.5, 1.5), rng.range(0.2, 1.5));
        let l = (rng.range(-0.5, 1.5), rng.range(0.2, 1.5));
        make_hinge(o, frame, len, phi, k, l)
    }

    #[test]
    fn angle_sign_and_range() {
        let frame = (DVec3::X, DVec3::Y);
        let at = |phi: f64| {
            dihedral_angle(&make_hinge(
                DVec3::ZERO,
                frame,
                1.0,
                phi,
                (0.5, 1.0),
                (0.3, 0.7),
            ))
            .expect("defined")
        };
        assert_eq!(at(0.0), 0.0, "flat");
        for phi in [0.3, -0.3, 1.5, -1.5, 3.0, -3.0, PI - 1e-9, -PI + 1e-9] {
            assert!((at(phi) - phi).abs() < 1e-12, "{phi}: {}", at(phi));
        }
        // The wings folded onto each other: +π (the half-open end of the range).
        assert!((at(PI).abs() - PI).abs() < 1e-12);
        // Swapping the wings flips the sign.
        let x = make_hinge(DVec3::ZERO, frame, 1.0, 0.7, (0.5, 1.0), (0.3, 0.7));
        let swapped = [x[0], x[1], x[3], x[2]];
        assert!((dihedral_angle(&swapped).unwrap() + 0.7).abs() < 1e-12);
    }

    #[test]
    fn consistently_wound_flat_triangles_have_parallel_normals() {
        // Triangles (i, j, k) and (j, i, l) of a flat quad: n₁ and n₂ are their normals.
        let x = [
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, 1.0, 0.0),
            DVec3::new(0.5, -1.0, 0.0),
        ];
        let h = hinge(&x).expect("regular");
        let normal1 = (x[1] - x[0]).cross(x[2] - x[0]);
        let normal2 = (x[0] - x[1]).cross(x[3] - x[1]);
        assert!(h.n1.normalize().dot(normal1.normalize()) > 1.0 - 1e-15);
        assert!(h.n2.normalize().dot(normal2.normalize()) > 1.0 - 1e-15);
        assert_eq!(dihedral_angle(&x), Some(0.0));
    }

    #[test]
    fn wrap_takes_the_short_way() {
        assert_eq!(wrap_angle(0.5), 0.5);
        assert!((wrap_angle(1.9 * PI) + 0.1 * PI).abs() < 1e-15);
        assert!((wrap_angle(-1.9 * PI) - 0.1 * PI).abs() < 1e-15);
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        // Rest at 170°, now at −175°: 15° away.
        let d = wrap_angle((-175f64).to_radians() - 170f64.to_radians());
        assert!((d - 15f64.to_radians()).abs() < 1e-12, "{}", d.to_degrees());
        assert!(wrap_angle(f64::NAN).is_nan());
    }

    #[test]
    fn gradient_matches_central_differences_including_near_0_and_pi() {
        let mut rng = Rng(0x5eed);
        let eps = 1e-7;
        for case in 0..400 {
            let phi = match case % 4 {
                0 => rng.range(-PI, PI),
                1 => rng.range(-1e-3, 1e-3),      // near flat
                2 => PI - rng.range(1e-3, 2e-3),  // near folded, +
                _ => -PI + rng.range(1e-3, 2e-3), // near folded, −
            };
            let x = random_hinge(&mut rng, phi);
            let (value, grad) = dihedral_angle_gradient(&x).expect("regular");
            assert!((value - phi).abs() < 1e-9, "{value} vs {phi}");
            // |∇| ≤ about 1/h_min·(1 + |s|) with heights ≥ 0.2: a few units.
            for p in 0..4 {
                for axis in 0..3 {
                    let mut plus = x;
                    let mut minus = x;
                    plus[p][axis] += eps;
                    minus[p][axis] -= eps;
                    let d = wrap_angle(
                        dihedral_angle(&plus).unwrap() - dihedral_angle(&minus).unwrap(),
                    );
                    let fd = d / (2.0 * eps);
                    assert!(
                        (fd - grad[p][axis]).abs() < 1e-6,
                        "case {case}, φ = {phi}, particle {p} axis {axis}: {fd} vs {}",
                        grad[p][axis]
                    );
                }
            }
        }
    }

    #[test]
    fn gradient_is_finite_and_bounded_by_the_heights_near_degenerate_wings() {
        // A wing of height 1e-6 m: large but finite gradient, 1/h.
        let x = make_hinge(
            DVec3::ZERO,
            (DVec3::X, DVec3::Y),
            1.0,
            0.4,
            (0.5, 1e-6),
            (0.5, 1.0),
        );
        let (_, grad) = dihedral_angle_gradient(&x).expect("regular");
        assert!(
            (grad[2].length() - 1e6).abs() < 1e-3,
            "{}",
            grad[2].length()
        );
        assert!(grad.iter().all(|g| g.is_finite()));
    }

    #[test]
    fn projection_conserves_linear_and_angular_momentum() {
        let mut rng = Rng(99);
        for k in 0..500 {
            let phi = rng.range(-PI, PI);
            let x = random_hinge(&mut rng, phi);
            let w = [
                rng.inv_mass(),
                rng.inv_mass(),
                rng.inv_mass(),
                rng.inv_mass(),
            ];
            let alpha = if k % 2 == 0 {
                0.0
            } else {
                rng.range(0.0, 10.0)
            };
            let rest = rng.range(-PI, PI);
            let lambda = rng.range(-1e-4, 1e-4);
            let c = project_dihedral(&x, &w, rest, alpha, lambda, H).expect("regular");
            assert_conserves_momentum(&x, &w, &c.dx);
        }
    }

    fn apply(x: &mut [DVec3; 4], dx: [DVec3; 4]) {
        for (p, d) in x.iter_mut().zip(dx) {
            *p += d;
        }
    }

    #[test]
    fn hard_projection_reaches_any_rest_angle_the_short_way() {
        let mut rng = Rng(5);
        for _ in 0..200 {
            let rest = rng.range(-PI + 0.05, PI);
            // Start up to 120° away, possibly across ±π.
            let start = wrap_angle(rest + rng.range(-2.0, 2.0));
            let mut x = random_hinge(&mut rng, start);
            let w = [rng.range(0.5, 2.0), rng.range(0.5, 2.0), 1.0, 1.0];
            for _ in 0..12 {
                let c = project_dihedral(&x, &w, rest, 0.0, 0.0, H).expect("regular");
                apply(&mut x, c.dx);
            }
            let phi = dihedral_angle(&x).expect("regular");
            assert!(wrap_angle(phi - rest).abs() < 1e-9, "{phi} vs {rest}");
        }
    }

    #[test]
    fn a_fold_pushed_through_flat_comes_back_instead_of_flipping() {
        // Rest: folded +30°. Pushed through flat to −30°: |φ| is 30° in both, so an unsigned
        // (acos) constraint sees nothing to do; the signed one turns it back to +30°.
        let rest = 30f64.to_radians();
        let mut x = make_hinge(
            DVec3::ZERO,
            (DVec3::X, DVec3::Y),
            1.0,
            -rest,
            (0.5, 1.0),
            (0.5, 1.0),
        );
        let unsigned = dihedral_angle(&x).unwrap().abs();
        assert!((unsigned - rest).abs() < 1e-12);
        for _ in 0..12 {
            let c = project_dihedral(&x, &[1.0; 4], rest, 0.0, 0.0, H).expect("regular");
            apply(&mut x, c.dx);
        }
        assert!((dihedral_angle(&x).unwrap() - rest).abs() < 1e-9);
    }

    #[test]
    fn a_hinge_folded_past_pi_turns_back_the_short_way_through_pi() {
        // Rest 170°, now −175°: 15° away through ±π, 345° away through flat. One hard step
        // must cut the wrapped error, turning through ±π, never unfolding through flat.
        let rest = 170f64.to_radians();
        let start = (-175f64).to_radians();
        let x = make_hinge(
            DVec3::ZERO,
            (DVec3::X, DVec3::Y),
            1.0,
            start,
            (0.5, 1.0),
            (0.5, 1.0),
        );
        let c = project_dihedral(&x, &[1.0; 4], rest, 0.0, 0.0, H).expect("regular");
        let mut y = x;
        apply(&mut y, c.dx);
        let after = dihedral_angle(&y).unwrap();
        let error = wrap_angle(after - rest).abs();
        assert!(error < 0.3 * 15f64.to_radians(), "{}", after.to_degrees());
        assert!(after.abs() > 160f64.to_radians(), "{}", after.to_degrees());
    }

    #[test]
    fn compliant_step_on_an_isolated_hinge_is_the_implicit_spring_step() {
        // For one hinge whose angle is (locally) linear in the step, XPBD's first pass gives
        // Δφ = −C·|∇|²_w/(|∇|²_w + α/h²): the backward-Euler update of a spring 1/α.
        let x = make_hinge(
            DVec3::ZERO,
            (DVec3::X, DVec3::Y),
            1.0,
            0.5,
            (0.5, 1.0),
            (0.5, 1.0),
        );
        let (phi, grad) = dihedral_angle_gradient(&x).unwrap();
        let w = [1.0; 4];
        let s: f64 = grad.iter().map(|g| g.length_squared()).sum();
        let alpha = 2e-5;
        let c = project_dihedral(&x, &w, 0.0, alpha, 0.0, H).unwrap();
        let expected = -phi * s / (s + alpha / (H * H));
        let linear: f64 = grad.iter().zip(c.dx).map(|(g, d)| g.dot(d)).sum();
        assert!((linear - expected).abs() < 1e-14, "{linear} vs {expected}");
    }

    #[test]
    fn degenerate_hinges_are_skipped_without_nan() {
        let p = DVec3::new(0.1, 0.2, 0.3);
        let w = [1.0; 4];
        let cases: [[DVec3; 4]; 6] = [
            [p; 4],                                                       // all coincident
            [p, p, p + DVec3::Y, p - DVec3::Y],                           // zero-length axis
            [p, p + DVec3::X, p + DVec3::X * 0.5, p - DVec3::Y],          // wing k on the axis
            [p, p + DVec3::X, p + DVec3::Y, p + DVec3::X * 3.0],          // wing l collinear
            [p, p + DVec3::X, p + DVec3::Y, DVec3::splat(f64::NAN)],      // NaN
            [p, p + DVec3::X, DVec3::splat(f64::INFINITY), p - DVec3::Y], // infinity
        ];
        for (n, x) in cases.iter().enumerate() {
            assert_eq!(dihedral_angle(x), None, "case {n}");
            assert_eq!(project_dihedral(x, &w, 0.3, 0.0, 0.0, H), None, "case {n}");
            assert_eq!(project_dihedral(x, &w, 0.3, 1.0, 0.1, H), None, "case {n}");
        }
    }
}
