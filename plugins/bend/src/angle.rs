//! The paper's type-2 constraint: the angle between two edges sharing a vertex, as pure
//! functions. Bend for curves (the angle at each inner vertex of a polyline), shear for
//! surfaces (the angle at each corner of a triangle).
//!
//! For edges `a = xi − xj` and `b = xk − xj` meeting at `j`:
//!
//! ```text
//! φ = atan2(|a × b|, a · b) ∈ [0, π],        C = φ − φ₀   (rad)
//! n̂ = (a × b)/|a × b|
//! ∇xi φ = −(n̂ × a)/|a|²,   ∇xk φ = (n̂ × b)/|b|²,   ∇xj φ = −(∇xi φ + ∇xk φ)
//! ```
//!
//! `acos(â · b̂)` gives the same angle, but its derivative `−1/√(1 − t²)` is infinite at 0
//! and π, and rounding puts `â · b̂` outside `[−1, 1]` (NaN) for nearly collinear edges.
//! `atan2` of the (unnormalised) sine and cosine is accurate over the whole range, and the
//! gradient above has the finite magnitudes `1/|a|` and `1/|b|` everywhere. Only its
//! *direction* is undefined where the edges are collinear (φ = 0 or π): there the plane in
//! which to bend is not determined, so the projection skips the constraint for that pass.
//! A straight rest shape (φ₀ = π) is at that point exactly when the constraint is
//! satisfied, so nothing is lost; any other rest angle acts again as soon as the edges leave
//! the line. Edges shorter than [`MIN_LENGTH`] are skipped too.

use glam::DVec3;

use crate::step::{xpbd_correction, Correction};
use crate::trig::atan2;

/// Below this length (m) an edge has no direction: its angles are skipped for that pass.
pub const MIN_LENGTH: f64 = 1e-12;

/// Below this `sin φ` the two edges are taken as collinear: the plane of the angle, and so
/// the direction of the gradient, is undefined. (`|a × b|` is computed with an absolute
/// error of about `ε|a||b|`, so at this threshold the direction is still good to ~1e-6.)
pub const MIN_SIN: f64 = 1e-10;

/// The angle `φ ∈ [0, π]` (rad) at `x[1]` between the edges to `x[0]` and `x[2]`; `None`
/// if either edge is shorter than [`MIN_LENGTH`] or a coordinate is not finite. Defined,
/// unlike its gradient, for collinear edges.
#[inline]
pub fn edge_angle(x: &[DVec3; 3]) -> Option<f64> {
    let a = x[0] - x[1];
    let b = x[2] - x[1];
    let min_sq = MIN_LENGTH * MIN_LENGTH;
    if !(a.length_squared() >= min_sq && b.length_squared() >= min_sq) {
        return None;
    }
    let phi = atan2(a.cross(b).length(), a.dot(b));
    phi.is_finite().then_some(phi)
}

/// The angle `φ` at `x[1]` (as [`edge_angle`]) and its gradient with respect to
/// `x[0], x[1], x[2]`. `None` where the gradient is undefined: an edge shorter than
/// [`MIN_LENGTH`], collinear edges (`sin φ < MIN_SIN`), or non-finite input.
#[inline]
pub fn edge_angle_gradient(x: &[DVec3; 3]) -> Option<(f64, [DVec3; 3])> {
    let a = x[0] - x[1];
    let b = x[2] - x[1];
    let (a_sq, b_sq) = (a.length_squared(), b.length_squared());
    let min_sq = MIN_LENGTH * MIN_LENGTH;
    if !(a_sq >= min_sq && b_sq >= min_sq) {
        return None;
    }
    let n = a.cross(b);
    let n_sq = n.length_squared();
    // Collinear, or NaN.
    if n_sq.is_nan() || n_sq < MIN_SIN * MIN_SIN * a_sq * b_sq {
        return None;
    }
    let n_len = n_sq.sqrt();
    let phi = atan2(n_len, a.dot(b));
    // ∇xi φ = −(n × a)/(|n||a|²), ∇xk φ = (n × b)/(|n||b|²): one division for both.
    let r = 1.0 / (n_len * a_sq * b_sq);
    let gi = n.cross(a) * (-b_sq * r);
    let gk = n.cross(b) * (a_sq * r);
    let grad = [gi, -(gi + gk), gk];
    (phi.is_finite() && grad.iter().all(|g| g.is_finite())).then_some((phi, grad))
}

/// One XPBD step on the angle at `x[1]` towards the rest angle `rest` (rad), for inverse
/// masses `w`, compliance `alpha` (rad/(N·m)), the multiplier `lambda` accumulated in this
/// substep and the substep `h` (s). `C = φ − rest` (rad).
///
/// `None` when the constraint is skipped for this pass (see [`edge_angle_gradient`]) or no
/// particle can move. Never returns NaN for finite input.
#[inline]
pub fn project_edge_angle(
    x: &[DVec3; 3],
    w: &[f64; 3],
    rest: f64,
    alpha: f64,
    lambda: f64,
    h: f64,
) -> Option<Correction<3>> {
    let (phi, grad) = edge_angle_gradient(x)?;
    xpbd_correction(phi - rest, &grad, w, alpha, lambda, h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{assert_conserves_momentum, Draws, Rng};
    use std::f64::consts::PI;

    const H: f64 = 1.0 / 600.0;

    /// Three points whose angle at the middle one is `phi`, with edge lengths `la`, `lb`,
    /// in a random orientation.
    fn hinge(rng: &mut Rng, phi: f64, la: f64, lb: f64) -> [DVec3; 3] {
        let (u, v) = rng.frame();
        let j = rng.vec3(1.0);
        [j + u * la, j, j + (u * phi.cos() + v * phi.sin()) * lb]
    }

    #[test]
    fn angle_of_known_configurations() {
        let o = DVec3::ZERO;
        let right = edge_angle(&[DVec3::X, o, DVec3::Y]).expect("defined");
        assert!((right - PI / 2.0).abs() < 1e-15);
        let straight = edge_angle(&[DVec3::X, o, DVec3::NEG_X * 3.0]).expect("defined");
        assert_eq!(straight, PI);
        let folded = edge_angle(&[DVec3::X, o, DVec3::X * 0.5]).expect("defined");
        assert_eq!(folded, 0.0);
        // acos loses this angle entirely: 1 − cos(1e-9) rounds to 0.
        let tiny = edge_angle(&[DVec3::X, o, DVec3::new(1.0, 1e-9, 0.0)]).expect("defined");
        assert!((tiny - 1e-9).abs() < 1e-22, "{tiny}");
        assert_eq!(
            (DVec3::X.dot(DVec3::new(1.0, 1e-9, 0.0).normalize())).acos(),
            0.0
        );
    }

    #[test]
    fn gradient_matches_central_differences_including_near_0_and_pi() {
        let mut rng = Rng(7);
        let eps = 1e-7;
        for case in 0..300 {
            // A third of the cases within 1e-3 rad of 0 or π.
            let phi = match case % 3 {
                0 => rng.range(0.05, PI - 0.05),
                1 => rng.range(1e-3, 2e-3),
                _ => PI - rng.range(1e-3, 2e-3),
            };
            let (la, lb) = (rng.range(0.2, 2.0), rng.range(0.2, 2.0));
            let x = hinge(&mut rng, phi, la, lb);
            let (value, grad) = edge_angle_gradient(&x).expect("projectable");
            assert!((value - phi).abs() < 1e-9, "{value} vs {phi}");
            for p in 0..3 {
                for axis in 0..3 {
                    let mut plus = x;
                    let mut minus = x;
                    plus[p][axis] += eps;
                    minus[p][axis] -= eps;
                    let fd =
                        (edge_angle(&plus).unwrap() - edge_angle(&minus).unwrap()) / (2.0 * eps);
                    // Relative to the gradient's scale 1/|edge| ≤ 5; near 0 and π the
                    // curvature is ~1/(|edge| sin φ), so the central difference error is
                    // O(eps²/sin³φ).
                    assert!(
                        (fd - grad[p][axis]).abs() < 2e-5,
                        "case {case}, φ = {phi}, particle {p} axis {axis}: {fd} vs {}",
                        grad[p][axis]
                    );
                }
            }
        }
    }

    #[test]
    fn projection_conserves_linear_and_angular_momentum() {
        let mut rng = Rng(11);
        for k in 0..500 {
            let phi = rng.range(1e-4, PI - 1e-4);
            let (la, lb) = (rng.range(0.01, 2.0), rng.range(0.01, 2.0));
            let x = hinge(&mut rng, phi, la, lb);
            let w = [rng.inv_mass(), rng.inv_mass(), rng.inv_mass()];
            let alpha = if k % 2 == 0 {
                0.0
            } else {
                rng.range(0.0, 10.0)
            };
            let lambda = rng.range(-1e-4, 1e-4);
            let rest = rng.range(0.0, PI);
            let c = project_edge_angle(&x, &w, rest, alpha, lambda, H).expect("projectable");
            assert_conserves_momentum(&x, &w, &c.dx);
        }
    }

    #[test]
    fn hard_projection_reaches_the_rest_angle() {
        // The angle is not linear in the positions, so one step lands close, a few exactly.
        let mut rng = Rng(3);
        for _ in 0..100 {
            let (phi, lb) = (rng.range(0.3, 2.8), rng.range(0.5, 1.5));
            let mut x = hinge(&mut rng, phi, 1.0, lb);
            let w = [1.0, rng.range(0.5, 2.0), 1.0];
            let rest = rng.range(0.3, 2.8);
            for _ in 0..8 {
                let c = project_edge_angle(&x, &w, rest, 0.0, 0.0, H).expect("projectable");
                for (p, d) in x.iter_mut().zip(c.dx) {
                    *p += d;
                }
            }
            let phi = edge_angle(&x).expect("defined");
            assert!((phi - rest).abs() < 1e-10, "{phi} vs {rest}");
        }
    }

    #[test]
    fn straight_rest_shape_straightens_a_bent_joint() {
        let mut x = [DVec3::NEG_X, DVec3::new(0.0, 0.3, 0.0), DVec3::X];
        for _ in 0..10 {
            let c = project_edge_angle(&x, &[1.0; 3], PI, 0.0, 0.0, H).expect("bent");
            for (p, d) in x.iter_mut().zip(c.dx) {
                *p += d;
            }
            if edge_angle_gradient(&x).is_none() {
                break; // straight: the gradient direction is undefined and C = 0
            }
        }
        assert!((edge_angle(&x).expect("defined") - PI).abs() < 1e-9);
    }

    #[test]
    fn degenerate_configurations_are_skipped_without_nan() {
        let p = DVec3::new(0.2, -0.4, 1.0);
        let w = [1.0; 3];
        // Coincident vertices: no angle at all.
        assert_eq!(edge_angle(&[p, p, p + DVec3::X]), None);
        assert_eq!(
            project_edge_angle(&[p, p, p + DVec3::X], &w, 1.0, 0.0, 0.0, H),
            None
        );
        assert_eq!(project_edge_angle(&[p; 3], &w, 1.0, 1e-3, 0.0, H), None);
        // Collinear edges: the angle is defined, the plane to bend in is not.
        let straight = [p - DVec3::X, p, p + DVec3::X];
        assert_eq!(edge_angle(&straight), Some(PI));
        assert_eq!(project_edge_angle(&straight, &w, 1.0, 0.0, 0.0, H), None);
        let back = [p + DVec3::X, p, p + DVec3::X * 2.0];
        assert_eq!(edge_angle(&back), Some(0.0));
        assert_eq!(project_edge_angle(&back, &w, 1.0, 0.0, 0.0, H), None);
        // Non-finite input.
        let nan = [p, p + DVec3::X, DVec3::splat(f64::NAN)];
        assert_eq!(edge_angle(&nan), None);
        assert_eq!(project_edge_angle(&nan, &w, 1.0, 0.0, 0.0, H), None);
        let inf = [p, p + DVec3::X, DVec3::splat(f64::INFINITY)];
        assert_eq!(project_edge_angle(&inf, &w, 1.0, 0.0, 0.0, H), None);
    }

    #[test]
    fn infinite_mass_particles_do_not_move() {
        let x = [DVec3::X, DVec3::ZERO, DVec3::Y];
        let c = project_edge_angle(&x, &[0.0, 1.0, 0.0], 2.0, 0.0, 0.0, H).expect("movable");
        assert_eq!(c.dx[0], DVec3::ZERO);
        assert_eq!(c.dx[2], DVec3::ZERO);
        assert!(c.dx[1].length() > 0.0);
        assert_eq!(project_edge_angle(&x, &[0.0; 3], 2.0, 0.0, 0.0, H), None);
    }
}
