//! The XPBD update shared by every compliant constraint (Macklin, Müller, Chentanez 2016).
//!
//! For a constraint `C(x) = 0` with compliance `α` (inverse stiffness, in the constraint's
//! unit per newton), substep `h` and the multiplier `λ` accumulated over the passes of the
//! substep, one Newton step gives
//!
//! ```text
//! Δλ = (−C − α̃ λ) / (Σᵢ wᵢ |∇ᵢC|² + α̃),   α̃ = α / h²,   Δxᵢ = wᵢ ∇ᵢC Δλ
//! ```
//!
//! With `α = 0` this is the hard (PBD) projection. The stiffness this produces does not depend
//! on `h` nor on the number of passes, which is what makes artists' parameters portable.

/// `Δλ` of one XPBD step; 0 when the constraint cannot move (all masses infinite or a
/// vanishing gradient), so a degenerate constraint is skipped, never NaN.
#[inline]
pub fn delta_lambda(c: f64, w_grad_sq: f64, alpha: f64, lambda: f64, h: f64) -> f64 {
    let alpha_tilde = alpha / (h * h);
    let denom = w_grad_sq + alpha_tilde;
    if denom <= f64::MIN_POSITIVE || !denom.is_finite() {
        return 0.0;
    }
    (-c - alpha_tilde * lambda) / denom
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hard_constraint_is_solved_in_one_step() {
        // Two unit masses, C = 0.5: the full correction is −0.5 shared by both.
        let dl = delta_lambda(0.5, 2.0, 0.0, 0.0, 0.01);
        assert!((dl * 2.0 + 0.5).abs() < 1e-15);
    }

    #[test]
    fn compliant_steps_converge_to_the_static_equilibrium() {
        // Repeated passes on one constraint with a fixed external "pull" converge to
        // λ = −C/α̃ balance: C + α̃ λ = 0.
        let (alpha, h, w) = (1e-3, 0.01, 1.0);
        let mut lambda = 0.0;
        let mut c = 1.0;
        for _ in 0..200 {
            let dl = delta_lambda(c, w, alpha, lambda, h);
            lambda += dl;
            c += w * dl; // the constraint moves by w ∇C Δλ with |∇C| = 1
        }
        assert!((c + alpha / (h * h) * lambda).abs() < 1e-12);
    }

    #[test]
    fn degenerate_constraint_is_skipped() {
        assert_eq!(delta_lambda(1.0, 0.0, 0.0, 0.0, 0.01), 0.0);
        assert_eq!(delta_lambda(1.0, f64::NAN, 0.0, 0.0, 0.01), 0.0);
    }
}
