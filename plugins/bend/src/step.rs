//! The XPBD step shared by every constraint of this plugin: given a constraint's value `C`,
//! its gradient with respect to each of its `N` particles and their inverse masses,
//!
//! ```text
//! Δλ = (−C − α̃λ) / (Σₖ wₖ|∇ₖC|² + α̃),   α̃ = α/h²,   Δxₖ = wₖ ∇ₖC Δλ
//! ```
//!
//! ([`nucleus_sdk::xpbd::delta_lambda`]). Every constraint here is invariant under
//! translations and rotations of its particles, so `Σₖ ∇ₖC = 0` and `Σₖ xₖ × ∇ₖC = 0`:
//! the mass-weighted corrections `mₖΔxₖ = ∇ₖC Δλ` carry no linear and no angular momentum.

use glam::DVec3;
use nucleus_sdk::xpbd;

/// The change one XPBD step makes to a constraint of `N` particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction<const N: usize> {
    /// Displacement of each particle (m), in the constraint's particle order.
    pub dx: [DVec3; N],
    /// Increment of the constraint's multiplier λ (N·m·s² for an angle constraint).
    pub delta_lambda: f64,
}

/// One XPBD step for the constraint value `c` with gradient `grad`, inverse masses `w`,
/// compliance `alpha`, the multiplier `lambda` accumulated so far in the substep and the
/// substep length `h`.
///
/// `None` when nothing can move: every particle has infinite mass, or the weighted gradient
/// norm is zero or not finite. Never returns NaN for finite input.
#[inline]
pub fn xpbd_correction<const N: usize>(
    c: f64,
    grad: &[DVec3; N],
    w: &[f64; N],
    alpha: f64,
    lambda: f64,
    h: f64,
) -> Option<Correction<N>> {
    let mut w_grad_sq = 0.0;
    for k in 0..N {
        w_grad_sq += w[k] * grad[k].length_squared();
    }
    // Written so that NaN fails the test too.
    if !(w_grad_sq > 0.0 && w_grad_sq.is_finite()) {
        return None;
    }
    let delta_lambda = xpbd::delta_lambda(c, w_grad_sq, alpha, lambda, h);
    Some(Correction {
        dx: std::array::from_fn(|k| grad[k] * (w[k] * delta_lambda)),
        delta_lambda,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hard_linear_constraint_is_solved_in_one_step() {
        // C = x1.x − x0.x − 1 at 1.5: one step closes it exactly.
        let grad = [DVec3::NEG_X, DVec3::X];
        let c = xpbd_correction(0.5, &grad, &[1.0, 3.0], 0.0, 0.0, 0.01).expect("movable");
        let closed = 0.5 + (c.dx[1] - c.dx[0]).x;
        assert!(closed.abs() < 1e-15, "{closed}");
        // The heavier particle (w = 1) moves three times less than the lighter one.
        assert!((c.dx[1].x / c.dx[0].x + 3.0).abs() < 1e-12);
    }

    #[test]
    fn pinned_or_gradient_free_constraints_are_skipped() {
        let grad = [DVec3::NEG_X, DVec3::X];
        assert_eq!(
            xpbd_correction(1.0, &grad, &[0.0, 0.0], 0.0, 0.0, 0.01),
            None
        );
        let flat = [DVec3::ZERO, DVec3::ZERO];
        assert_eq!(
            xpbd_correction(1.0, &flat, &[1.0, 1.0], 1.0, 0.0, 0.01),
            None
        );
        let nan = [DVec3::splat(f64::NAN), DVec3::X];
        assert_eq!(
            xpbd_correction(1.0, &nan, &[1.0, 1.0], 0.0, 0.0, 0.01),
            None
        );
    }
}
