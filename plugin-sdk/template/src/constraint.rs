//! The attraction of one particle as pure functions: the constraint's value and gradient, and
//! one XPBD step of the one-sided constraint. The group in [`crate::group`] only loops over its
//! batch and calls [`project_attraction`]; everything numerical lives, and is tested, here.
//!
//! See the [crate docs](crate) for the theory.

use nucleus_sdk::prelude::*;
use nucleus_sdk::xpbd;

/// Below this distance (m) from the centre the direction of the pull, and so the gradient of
/// the constraint, is undefined: the particle is left alone for that pass.
pub const MIN_DISTANCE: f64 = 1e-12;

/// Where and how strongly particles are pulled: shared by every particle of a group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attractor {
    /// The point particles are pulled toward (m).
    pub center: DVec3,
    /// Particles closer to the centre than this are free (m, ≥ 0).
    pub radius: f64,
    /// Particles farther from the centre than this are not pulled (m); `f64::INFINITY` for no
    /// limit.
    pub reach: f64,
    /// `τ² = (T / 2π)²` (s²), `T` the natural period of the pull; 0 is a hard constraint. A
    /// particle of inverse mass `w` gets the compliance `α = w τ²`.
    pub tau_sq: f64,
}

impl Attractor {
    /// The attractor of natural period `period` (s).
    pub fn new(center: DVec3, radius: f64, reach: f64, period: f64) -> Self {
        let tau = period / std::f64::consts::TAU;
        Self {
            center,
            radius,
            reach,
            tau_sq: tau * tau,
        }
    }

    /// The compliance `α = w τ²` (m/N) of a particle of inverse mass `w` (1/kg): its spring
    /// stiffness is `k = 1/α = m (2π/T)²`, so every particle, whatever its mass, feels the same
    /// acceleration and swings with the same period `T`.
    #[inline]
    pub fn compliance(&self, w: f64) -> f64 {
        w * self.tau_sq
    }
}

/// `C = |x − c| − r` (m; > 0 outside the free ball) and `n = ∇ₓC = (x − c)/|x − c|`.
///
/// `None` when `|x − c| < MIN_DISTANCE` (or is not finite): the gradient is undefined there.
#[inline]
pub fn attraction_constraint(x: DVec3, center: DVec3, radius: f64) -> Option<(f64, DVec3)> {
    let d = x - center;
    let dist = d.length();
    if !dist.is_finite() || dist < MIN_DISTANCE {
        return None;
    }
    Some((dist - radius, d * dist.recip()))
}

/// The change one XPBD step makes to a particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// Displacement of the particle (m).
    pub dx: DVec3,
    /// Increment of the particle's multiplier λ (N·s²); the accumulated λ stays ≤ 0.
    pub delta_lambda: f64,
}

/// One XPBD step of the one-sided constraint `C(x) ≤ 0` on a particle at `x` with inverse mass
/// `w`, given its multiplier `lambda` (≤ 0) accumulated so far in this substep of length `h`.
///
/// With `α = w τ²` and `α̃ = α/h²`:
///
/// ```text
/// Δλ* = (−C − α̃λ) / (w + α̃),   λ' = min(λ + Δλ*, 0),   Δλ = λ' − λ,   Δx = w n Δλ
/// ```
///
/// The clamp makes the constraint one-sided: it pulls, never pushes, and a pull applied by an
/// earlier pass of the substep is released (up to λ = 0) once the particle is back inside.
///
/// `None` when nothing changes: the particle is kinematic (`w = 0`), beyond the attractor's
/// reach, at the centre (undefined gradient), or inside the free ball with nothing to release.
/// Never returns NaN for finite input.
#[inline]
pub fn project_attraction(
    x: DVec3,
    w: f64,
    attractor: &Attractor,
    lambda: f64,
    h: f64,
) -> Option<Correction> {
    if w.is_nan() || w <= 0.0 {
        return None;
    }
    let (c, n) = attraction_constraint(x, attractor.center, attractor.radius)?;
    if c + attractor.radius > attractor.reach {
        return None;
    }
    let alpha = attractor.compliance(w);
    let unclamped = xpbd::delta_lambda(c, w, alpha, lambda, h);
    let delta_lambda = (lambda + unclamped).min(0.0) - lambda;
    if delta_lambda == 0.0 || !delta_lambda.is_finite() {
        return None;
    }
    Some(Correction {
        dx: w * delta_lambda * n,
        delta_lambda,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use nucleus_sdk::testing::Rng;

    const H: f64 = 1.0 / 600.0;

    fn attractor(radius: f64, period: f64) -> Attractor {
        Attractor::new(DVec3::new(0.3, -0.2, 0.5), radius, f64::INFINITY, period)
    }

    #[test]
    fn gradient_matches_central_finite_differences() {
        let mut rng = Rng(7);
        let eps = 1e-6;
        for _ in 0..200 {
            let center = rng.vec3(1.0);
            let x = center + rng.vec3(2.0);
            let radius = rng.range(0.0, 0.5);
            let Some((c, n)) = attraction_constraint(x, center, radius) else {
                continue;
            };
            assert!((c - ((x - center).length() - radius)).abs() < 1e-15);
            for axis in 0..3 {
                let e = DVec3::AXES[axis] * eps;
                let cp = attraction_constraint(x + e, center, radius).unwrap().0;
                let cm = attraction_constraint(x - e, center, radius).unwrap().0;
                let fd = (cp - cm) / (2.0 * eps);
                assert!(
                    (fd - n[axis]).abs() < 1e-7,
                    "axis {axis}: {fd} vs {}",
                    n[axis]
                );
            }
        }
    }

    #[test]
    fn a_hard_pull_puts_a_particle_on_the_sphere_in_one_step() {
        let a = attractor(0.25, 0.0);
        let mut rng = Rng(11);
        for _ in 0..100 {
            let x = a.center + rng.vec3(3.0);
            if (x - a.center).length() <= a.radius {
                continue;
            }
            let w = rng.range(0.1, 10.0);
            let c = project_attraction(x, w, &a, 0.0, H).unwrap();
            let dist = (x + c.dx - a.center).length();
            assert!((dist - a.radius).abs() < 1e-12, "{dist}");
        }
    }

    #[test]
    fn the_pull_is_central_so_it_exerts_no_torque_about_the_centre() {
        let a = attractor(0.1, 0.3);
        let mut rng = Rng(13);
        for _ in 0..100 {
            let x = a.center + rng.vec3(2.0);
            let Some(c) = project_attraction(x, 2.0, &a, 0.0, H) else {
                continue;
            };
            let r = x - a.center;
            assert!(r.cross(c.dx).length() <= 1e-14 * r.length() * c.dx.length().max(1e-300));
            assert!(c.dx.dot(r) < 0.0, "it pulls inward");
        }
    }

    #[test]
    fn one_step_is_implicit_euler_of_the_spring_whatever_the_mass() {
        // Radius 0: the constraint is the zero-length spring k = m (2π/T)² toward the centre,
        // and one XPBD step from λ = 0 is the implicit step x' − c = (x̃ − c) / (1 + h²/τ²).
        let period = 0.5;
        let a = attractor(0.0, period);
        let tau = period / std::f64::consts::TAU;
        let x = a.center + DVec3::new(0.4, -0.1, 0.2);
        for w in [1e-3, 1.0, 1e3] {
            let c = project_attraction(x, w, &a, 0.0, H).unwrap();
            let expected = a.center + (x - a.center) / (1.0 + H * H / (tau * tau));
            assert!((x + c.dx - expected).length() < 1e-14, "w = {w}");
        }
    }

    #[test]
    fn extra_passes_on_a_lone_particle_change_nothing() {
        // The gradient of a lone particle does not turn as it moves along it, so the first
        // pass solves C + α̃λ = 0 exactly and later passes add nothing: the stiffness does not
        // depend on the group's importance.
        let a = attractor(0.2, 0.4);
        let mut x = a.center + DVec3::new(1.0, 0.5, -0.3);
        let mut lambda = 0.0;
        let first = project_attraction(x, 0.5, &a, lambda, H).unwrap();
        x += first.dx;
        lambda += first.delta_lambda;
        for _ in 0..5 {
            if let Some(c) = project_attraction(x, 0.5, &a, lambda, H) {
                assert!(c.dx.length() < 1e-15, "{:?}", c.dx);
                x += c.dx;
                lambda += c.delta_lambda;
            }
        }
        let (c, _) = attraction_constraint(x, a.center, a.radius).unwrap();
        assert!((c + a.compliance(0.5) / (H * H) * lambda).abs() < 1e-13);
    }

    #[test]
    fn it_never_pushes_and_releases_an_earlier_pull_only_down_to_zero() {
        let a = attractor(0.5, 0.2);
        let mut rng = Rng(17);
        for _ in 0..200 {
            let x = a.center + rng.vec3(1.5);
            let lambda = -rng.range(0.0, 1e-4);
            let Some(c) = project_attraction(x, 1.0, &a, lambda, H) else {
                continue;
            };
            assert!(lambda + c.delta_lambda <= 0.0);
            if lambda == 0.0 {
                assert!(c.delta_lambda < 0.0, "from rest it only pulls");
            }
        }
        // Inside the free ball with nothing accumulated: untouched.
        assert_eq!(
            project_attraction(a.center + DVec3::X * 0.3, 1.0, &a, 0.0, H),
            None
        );
    }

    #[test]
    fn kinematic_distant_and_centred_particles_are_left_alone() {
        let a = Attractor::new(DVec3::ZERO, 0.0, 2.0, 0.5);
        let x = DVec3::new(1.0, 0.0, 0.0);
        assert_eq!(project_attraction(x, 0.0, &a, 0.0, H), None, "kinematic");
        assert_eq!(project_attraction(x, f64::NAN, &a, 0.0, H), None);
        assert!(project_attraction(x, 1.0, &a, 0.0, H).is_some(), "in reach");
        let far = DVec3::new(0.0, 2.5, 0.0);
        assert_eq!(
            project_attraction(far, 1.0, &a, 0.0, H),
            None,
            "beyond reach"
        );
        assert_eq!(project_attraction(DVec3::ZERO, 1.0, &a, 0.0, H), None);
    }

    #[test]
    fn non_finite_positions_give_no_correction_instead_of_nan() {
        let a = attractor(0.0, 0.5);
        for x in [DVec3::splat(f64::NAN), DVec3::new(f64::INFINITY, 0.0, 0.0)] {
            assert_eq!(project_attraction(x, 1.0, &a, 0.0, H), None);
        }
    }
}
