//! The aerodynamic force on one element — a triangle, a curve edge, a point — as pure
//! functions of its geometry and its velocity relative to the air, and the linearly implicit
//! velocity update that applies it. The group in [`crate::group`] only gathers, scatters and
//! sums; every formula lives, and is tested, here.
//!
//! See the [crate docs](crate) for the theory and the units.

use glam::DVec3;

/// Below this area (m²) a triangle has no defined normal: it feels no air.
pub const MIN_AREA: f64 = 1e-24;

/// Below this length (m) an edge has no defined direction: it feels no air.
pub const MIN_LENGTH: f64 = 1e-12;

/// The coefficients of one group, premultiplied by ½ρ: every force below is `k · S · (speed)²`
/// with `S` the element's reference area (m²), so each `k` is in kg/m³.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    /// `½ ρ C_d` (kg/m³): drag.
    pub drag: f64,
    /// `½ ρ C_l` (kg/m³): lift (triangles only).
    pub lift: f64,
    /// `½ ρ C_t` (kg/m³), `C_t = tangential_drag · C_d`: skin drag along a surface or a curve.
    pub tangential: f64,
}

impl Coefficients {
    /// From the air density ρ (kg/m³) and the dimensionless drag and lift coefficients, with
    /// the tangential coefficient given as a fraction of the drag coefficient (Maya's
    /// Tangential Drag).
    pub fn new(air_density: f64, drag: f64, lift: f64, tangential_drag: f64) -> Self {
        let half_rho = 0.5 * air_density;
        Self {
            drag: half_rho * drag,
            lift: half_rho * lift,
            tangential: half_rho * drag * tangential_drag,
        }
    }
}

/// The air's force on one element, split by term, and the rate that makes its application
/// linearly implicit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ElementForce {
    /// Drag (N).
    pub drag: DVec3,
    /// Lift (N), perpendicular to the relative velocity.
    pub lift: DVec3,
    /// Tangential (skin) drag (N).
    pub tangential: DVec3,
    /// `β` (N·s/m ≥ 0): a bound on how fast the force changes with the element's velocity,
    /// `|∂F/∂v| ≲ β`; see [`apply_impulse`].
    pub rate: f64,
}

impl ElementForce {
    /// No force.
    pub const ZERO: Self = Self {
        drag: DVec3::ZERO,
        lift: DVec3::ZERO,
        tangential: DVec3::ZERO,
        rate: 0.0,
    };

    /// The sum of the three terms (N).
    #[inline]
    pub fn total(&self) -> DVec3 {
        self.drag + self.lift + self.tangential
    }

    /// `self` if every number is finite, else [`ZERO`](Self::ZERO): an element whose force
    /// overflows (absurd speeds) is skipped rather than poisoning the state.
    #[inline]
    fn finite_or_zero(self) -> Self {
        if self.total().is_finite() && self.rate.is_finite() {
            self
        } else {
            Self::ZERO
        }
    }
}

/// The force on a triangle `x` (wound `x0 → x1 → x2`) moving at `v_rel` relative to the air.
///
/// With `A` the area, `n̂` the unit normal of the winding, `u = |v_rel|`, `v_n = v_rel·n̂` and
/// `v_t = v_rel − v_n n̂`:
///
/// ```text
/// F_drag = −k_d A |v_n| v_rel                         |F_drag| = k_d A u |v_n|
/// F_lift = −k_l A (v_n/u) (u² n̂ − v_n v_rel)           |F_lift| = k_l A |v_n| |v_t|
/// F_tan  = −k_t A |v_t| v_t
/// β      = A ((k_d + k_l) (|v_n| + u) + 2 k_t |v_t|)
/// ```
///
/// Flipping the winding flips `n̂` and `v_n` together, so nothing depends on which side faces
/// the wind. A triangle with area below [`MIN_AREA`], or a relative velocity of 0, feels
/// nothing; the result is never NaN for finite input.
#[inline]
pub fn triangle_force(x: [DVec3; 3], v_rel: DVec3, k: &Coefficients) -> ElementForce {
    let cross = (x[1] - x[0]).cross(x[2] - x[0]);
    let twice_area = cross.length();
    // NaN fails every comparison, so it is caught with the tiny ones.
    if twice_area.is_nan() || twice_area < 2.0 * MIN_AREA {
        return ElementForce::ZERO;
    }
    let u = v_rel.length();
    if u.is_nan() || u == 0.0 {
        return ElementForce::ZERO;
    }
    let area = 0.5 * twice_area;
    let n = cross / twice_area;
    let vn = v_rel.dot(n);
    let vt = v_rel - vn * n;
    let vt_len = vt.length();
    ElementForce {
        drag: -k.drag * area * vn.abs() * v_rel,
        lift: -k.lift * area * (vn / u) * (u * u * n - vn * v_rel),
        tangential: -k.tangential * area * vt_len * vt,
        rate: area * ((k.drag + k.lift) * (vn.abs() + u) + 2.0 * k.tangential * vt_len),
    }
    .finite_or_zero()
}

/// The force on a curve edge `x0 → x1` of thickness `width` (m) moving at `v_rel` relative
/// to the air: a yawed cylinder whose cross-flow and axial flow act independently.
///
/// With `L` the length, `t̂` the direction, `S = L·width` the projected area,
/// `v_∥ = (v_rel·t̂) t̂` and `v_⊥ = v_rel − v_∥`:
///
/// ```text
/// F_drag = −k_d S |v_⊥| v_⊥,   F_tan = −k_t S |v_∥| v_∥,   no lift,
/// β      = 2 S (k_d |v_⊥| + k_t |v_∥|)
/// ```
///
/// An edge shorter than [`MIN_LENGTH`] feels nothing.
#[inline]
pub fn edge_force(x: [DVec3; 2], v_rel: DVec3, width: f64, k: &Coefficients) -> ElementForce {
    let e = x[1] - x[0];
    let len = e.length();
    if len.is_nan() || len < MIN_LENGTH {
        return ElementForce::ZERO;
    }
    let t = e / len;
    let s = len * width;
    let along = v_rel.dot(t) * t;
    let across = v_rel - along;
    let (across_len, along_len) = (across.length(), along.length());
    ElementForce {
        drag: -k.drag * s * across_len * across,
        lift: DVec3::ZERO,
        tangential: -k.tangential * s * along_len * along,
        rate: 2.0 * s * (k.drag * across_len + k.tangential * along_len),
    }
    .finite_or_zero()
}

/// The force on a point of radius `radius` (m) moving at `v_rel` relative to the air: a
/// sphere of cross-section `S = π r²`,
///
/// ```text
/// F_drag = −k_d S |v_rel| v_rel,   β = 2 k_d S |v_rel|.
/// ```
#[inline]
pub fn point_force(v_rel: DVec3, radius: f64, k: &Coefficients) -> ElementForce {
    let s = std::f64::consts::PI * radius * radius;
    let u = v_rel.length();
    ElementForce {
        drag: -k.drag * s * u * v_rel,
        lift: DVec3::ZERO,
        tangential: DVec3::ZERO,
        rate: 2.0 * k.drag * s * u,
    }
    .finite_or_zero()
}

/// The velocity change of a particle of inverse mass `w` (1/kg) under the force `f` (N) over
/// a substep `h` (s), linearly implicit in the force's rate `β` (N·s/m):
///
/// ```text
/// Δv = h w f / (1 + h w β)
/// ```
///
/// This is the backward-Euler step of `m dv/dt = f(v)` with the Jacobian `∂f/∂v`
/// approximated by `−β I`: as `h → 0` it is the explicit step, its fixed point (a terminal
/// velocity) is the explicit one to first order in `h` — exactly when `β` is the true rate
/// along the motion, as for a plate falling face-on or a point — and a drag can never reverse
/// the relative velocity it acts on, however large `h w β`.
#[inline]
pub fn apply_impulse(w: f64, h: f64, f: DVec3, rate: f64) -> DVec3 {
    let hw = h * w;
    f * (hw / (1.0 + hw * rate))
}

#[cfg(test)]
mod tests {
    use super::*;

    use nucleus_sdk::testing::Rng;

    const K: Coefficients = Coefficients {
        drag: 0.6,
        lift: 0.45,
        tangential: 0.06,
    };

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * a.abs().max(b.abs()).max(1e-300)
    }

    /// A unit right triangle in the xy-plane, normal +z, area ½.
    fn xy_triangle() -> [DVec3; 3] {
        [DVec3::ZERO, DVec3::X, DVec3::Y]
    }

    #[test]
    fn coefficients_are_half_rho_times_the_dimensionless_ones() {
        let k = Coefficients::new(1.2, 1.5, 0.5, 0.1);
        assert!(close(k.drag, 0.9, 1e-15));
        assert!(close(k.lift, 0.3, 1e-15));
        assert!(close(k.tangential, 0.09, 1e-15));
    }

    #[test]
    fn face_on_drag_is_half_rho_cd_a_v_squared_against_the_motion() {
        // A plate falling face-on at 3 m/s: drag ½ρ C_d A v² upward, no lift, no skin drag.
        let k = Coefficients::new(1.2, 1.1, 0.8, 0.3);
        let f = triangle_force(xy_triangle(), DVec3::new(0.0, 0.0, -3.0), &k);
        let expected = 0.5 * 1.2 * 1.1 * 0.5 * 9.0;
        assert!(close(f.drag.z, expected, 1e-14), "{f:?}");
        assert_eq!((f.drag.x, f.drag.y), (0.0, 0.0));
        assert_eq!(f.lift, DVec3::ZERO);
        assert_eq!(f.tangential, DVec3::ZERO);
    }

    #[test]
    fn edge_on_flow_feels_only_skin_drag() {
        let f = triangle_force(xy_triangle(), DVec3::new(2.0, -1.0, 0.0), &K);
        assert_eq!(f.drag, DVec3::ZERO);
        assert_eq!(f.lift, DVec3::ZERO);
        let expected = -K.tangential * 0.5 * 5f64.sqrt() * DVec3::new(2.0, -1.0, 0.0);
        assert!((f.tangential - expected).length() < 1e-15);
    }

    #[test]
    fn magnitudes_and_directions_follow_the_model_at_any_angle() {
        let mut rng = Rng(11);
        for _ in 0..500 {
            let x = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
            let v = rng.vec3(20.0);
            let cross = (x[1] - x[0]).cross(x[2] - x[0]);
            if cross.length() < 1e-3 {
                continue;
            }
            let (area, n) = (0.5 * cross.length(), cross.normalize());
            let (u, vn) = (v.length(), v.dot(n));
            let vt = (v - vn * n).length();
            let f = triangle_force(x, v, &K);
            assert!(close(f.drag.length(), K.drag * area * u * vn.abs(), 1e-12));
            assert!(close(f.lift.length(), K.lift * area * vn.abs() * vt, 1e-9));
            assert!(close(
                f.tangential.length(),
                K.tangential * area * vt * vt,
                1e-12
            ));
            // Drag opposes the relative velocity; lift is perpendicular to it and lies in the
            // plane of the relative velocity and the normal; skin drag lies in the surface.
            assert!(f.drag.dot(v) <= 0.0);
            assert!(f.drag.cross(v).length() <= 1e-12 * f.drag.length() * u);
            assert!(f.lift.dot(v).abs() <= 1e-10 * f.lift.length() * u);
            assert!(f.lift.dot(v.cross(n)).abs() <= 1e-10 * f.lift.length() * u);
            assert!(f.tangential.dot(n).abs() <= 1e-12 * f.tangential.length());
            // Lift pushes the plate away from the side the air comes from, like a pressure.
            assert!(f.lift.dot(n) * vn <= 0.0);
        }
    }

    #[test]
    fn force_does_not_depend_on_the_winding() {
        let mut rng = Rng(5);
        for _ in 0..200 {
            let x = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
            let v = rng.vec3(10.0);
            let a = triangle_force(x, v, &K);
            let b = triangle_force([x[0], x[2], x[1]], v, &K);
            assert!((a.total() - b.total()).length() <= 1e-12 * a.total().length().max(1e-300));
            assert!(close(a.rate, b.rate, 1e-12));
        }
    }

    #[test]
    fn flat_plate_lift_over_drag_is_cl_over_cd_times_cos_alpha() {
        // A plate at angle of attack α in a horizontal wind: L/D = (C_l/C_d) cos α, lift up.
        for deg in [5.0f64, 15.0, 30.0, 45.0, 60.0, 80.0] {
            let alpha = deg.to_radians();
            // Chord from the leading edge (upwind, higher) down to the trailing edge.
            let chord = DVec3::new(alpha.cos(), -alpha.sin(), 0.0);
            let x = [DVec3::ZERO, chord, DVec3::Z];
            let wind = DVec3::new(10.0, 0.0, 0.0);
            // Without skin drag, the force is drag (downwind) plus lift (up).
            let k = Coefficients {
                tangential: 0.0,
                ..K
            };
            let f = triangle_force(x, -wind, &k);
            let drag = f.total().x;
            let lift = f.total().y;
            assert!(lift > 0.0 && drag > 0.0, "{deg}°: {f:?}");
            assert!(
                close(lift / drag, K.lift / K.drag * alpha.cos(), 1e-12),
                "{deg}°"
            );
        }
    }

    #[test]
    fn rate_bounds_the_jacobian_of_the_force() {
        // β ≥ ‖∂F/∂v‖ (spectral norm, from central differences): the implicit factor damps at
        // least as strongly as the force can change.
        let mut rng = Rng(3);
        for _ in 0..200 {
            let x = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
            if (x[1] - x[0]).cross(x[2] - x[0]).length() < 1e-2 {
                continue;
            }
            let v = rng.vec3(10.0);
            let f = |v: DVec3| triangle_force(x, v, &K).total();
            let eps = 1e-6;
            let cols: Vec<DVec3> = (0..3)
                .map(|a| {
                    let mut e = DVec3::ZERO;
                    e[a] = eps;
                    (f(v + e) - f(v - e)) / (2.0 * eps)
                })
                .collect();
            let jac = glam::DMat3::from_cols(cols[0], cols[1], cols[2]);
            // ‖J‖₂ ≤ Frobenius norm; check the sharper power iteration bound.
            let jtj = jac.transpose() * jac;
            let mut q = DVec3::new(1.0, 0.7, 0.3);
            for _ in 0..100 {
                q = (jtj * q).normalize();
            }
            let norm = (jtj * q).length().sqrt();
            let rate = triangle_force(x, v, &K).rate;
            assert!(norm <= rate * (1.0 + 1e-6), "‖J‖ {norm} > β {rate}");
        }
    }

    #[test]
    fn face_on_rate_is_the_exact_rate_along_the_motion() {
        // For a face-on plate (and a point) β equals −∂F/∂v along v: the implicit step then
        // keeps the explicit terminal velocity to second order in h.
        let v = DVec3::new(0.0, 0.0, -2.5);
        let eps = 1e-6;
        let f = |s: f64| triangle_force(xy_triangle(), v * s, &K).total().z;
        let d = (f(1.0 + eps) - f(1.0 - eps)) / (2.0 * eps * v.length());
        let rate = triangle_force(xy_triangle(), v, &K).rate;
        // K has lift, which vanishes face-on: its share 2 k_l A u is the part of β beyond
        // the drag's exact 2 k_d A u.
        let lift_share = 2.0 * K.lift * 0.5 * v.length();
        assert!(close(d, rate - lift_share, 1e-8), "{d} vs {rate}");
        let p = |s: f64| point_force(v * s, 0.1, &K).total().z;
        let d = (p(1.0 + eps) - p(1.0 - eps)) / (2.0 * eps * v.length());
        assert!(close(d, point_force(v, 0.1, &K).rate, 1e-8));
    }

    #[test]
    fn curve_edge_feels_cross_flow_drag_and_axial_skin_drag() {
        let x = [DVec3::ZERO, DVec3::new(0.0, 2.0, 0.0)];
        let width = 0.01;
        // Across: ½ρ C_d (L w) v².
        let f = edge_force(x, DVec3::new(-5.0, 0.0, 0.0), width, &K);
        assert!(close(f.drag.x, K.drag * 2.0 * width * 25.0, 1e-14));
        assert_eq!(f.tangential, DVec3::ZERO);
        // Along: skin drag only.
        let f = edge_force(x, DVec3::new(0.0, 3.0, 0.0), width, &K);
        assert_eq!(f.drag, DVec3::ZERO);
        assert!(close(
            f.tangential.y,
            -K.tangential * 2.0 * width * 9.0,
            1e-14
        ));
        // Yawed: the two act independently on their components.
        let v = DVec3::new(4.0, 3.0, 0.0);
        let f = edge_force(x, v, width, &K);
        assert!(close(f.drag.x, -K.drag * 2.0 * width * 16.0, 1e-14));
        assert!(close(
            f.tangential.y,
            -K.tangential * 2.0 * width * 9.0,
            1e-14
        ));
        assert_eq!(f.lift, DVec3::ZERO);
    }

    #[test]
    fn point_drag_is_half_rho_cd_pi_r_squared_v_squared() {
        let f = point_force(DVec3::new(0.0, -4.0, 3.0), 0.2, &K);
        let s = std::f64::consts::PI * 0.04;
        assert!((f.drag - (-K.drag * s * 5.0 * DVec3::new(0.0, -4.0, 3.0))).length() < 1e-14);
        assert!(close(f.rate, 2.0 * K.drag * s * 5.0, 1e-14));
    }

    #[test]
    fn degenerate_elements_and_still_air_feel_nothing() {
        let p = DVec3::new(0.3, -0.2, 0.1);
        let v = DVec3::new(1.0, 2.0, 3.0);
        // Coincident, collinear, and tiny triangles.
        for x in [
            [p, p, p],
            [p, p + DVec3::X, p + 2.0 * DVec3::X],
            [p, p + DVec3::splat(1e-13), p + DVec3::new(1e-13, 0.0, 0.0)],
        ] {
            assert_eq!(triangle_force(x, v, &K), ElementForce::ZERO);
        }
        assert_eq!(edge_force([p, p], v, 0.01, &K), ElementForce::ZERO);
        assert_eq!(
            edge_force([p, p + DVec3::splat(1e-13)], v, 0.01, &K),
            ElementForce::ZERO
        );
        assert_eq!(
            triangle_force(xy_triangle(), DVec3::ZERO, &K),
            ElementForce::ZERO
        );
        assert_eq!(
            edge_force([p, p + v], DVec3::ZERO, 0.01, &K),
            ElementForce::ZERO
        );
        assert_eq!(point_force(DVec3::ZERO, 0.1, &K), ElementForce::ZERO);
        // A tiny but non-zero relative speed is fine (v_n/u is bounded).
        let f = triangle_force(xy_triangle(), DVec3::splat(1e-300), &K);
        assert!(f.total().is_finite() && f.rate.is_finite());
    }

    #[test]
    fn non_finite_input_or_overflow_gives_no_force() {
        let nan = DVec3::splat(f64::NAN);
        assert_eq!(
            triangle_force([nan, DVec3::X, DVec3::Y], DVec3::X, &K),
            ElementForce::ZERO
        );
        assert_eq!(triangle_force(xy_triangle(), nan, &K), ElementForce::ZERO);
        assert_eq!(
            edge_force([DVec3::ZERO, DVec3::X], nan, 0.1, &K),
            ElementForce::ZERO
        );
        assert_eq!(point_force(nan, 0.1, &K), ElementForce::ZERO);
        // 1e200 m/s squared overflows: skipped, not infinite.
        let huge = DVec3::new(0.0, 0.0, 1e200);
        assert_eq!(triangle_force(xy_triangle(), huge, &K), ElementForce::ZERO);
        assert_eq!(point_force(huge, 0.1, &K), ElementForce::ZERO);
    }

    #[test]
    fn implicit_impulse_never_reverses_a_drag() {
        // A point in still air, one step from u: the implicit step keeps u' = u (1 + x)/(1 + 2x)
        // with x = h w k S u, in (u/2, u], however large x.
        let k = Coefficients::new(1.2, 1.0, 0.0, 0.0);
        for h in [1e-4, 1e-2, 1.0, 1e3] {
            let v = DVec3::new(0.0, -30.0, 0.0);
            let f = point_force(v, 0.5, &k);
            let v1 = v + apply_impulse(1e3, h, f.total(), f.rate);
            assert!(v1.y < 0.0 && v1.y.abs() > 0.5 * v.y.abs(), "h {h}: {v1}");
            assert!(v1.y.abs() <= v.y.abs(), "h {h}: {v1}");
            assert_eq!((v1.x, v1.z), (0.0, 0.0));
        }
        // And as h → 0 it is the explicit step.
        let f = point_force(DVec3::X, 0.1, &k);
        let dv = apply_impulse(2.0, 1e-9, f.total(), f.rate);
        assert!(close(dv.x, 1e-9 * 2.0 * f.total().x, 1e-8));
    }

    #[test]
    fn implicit_step_keeps_the_terminal_velocity() {
        // A point falling through still air, stepped as the core does it (gravity first, then
        // the air's force stage): it settles at v_t = sqrt(m g / (k S)) to O(h²).
        let (m, g, r) = (0.01, 9.81, 0.05);
        let k = Coefficients::new(1.2, 0.47, 0.0, 0.0);
        let s = std::f64::consts::PI * r * r;
        let vt = (m * g / (k.drag * s)).sqrt();
        for h in [1.0 / 60.0, 1.0 / 600.0] {
            let mut v = DVec3::ZERO;
            for _ in 0..(20.0 / h) as usize {
                v.y -= h * g;
                let f = point_force(v, r, &k);
                v += apply_impulse(1.0 / m, h, f.total(), f.rate);
            }
            let err = (v.y.abs() - vt).abs() / vt;
            // Second order: h·g/v_t ≈ 0.04 at 60 Hz; its square is what is left.
            assert!(
                err < (h * g / vt).powi(2),
                "h {h}: v {} vs {vt} ({err})",
                v.y
            );
        }
    }
}
