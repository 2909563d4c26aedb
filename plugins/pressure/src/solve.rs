//! The two pressure models as pure scalar functions of a chamber's volume `V`, its
//! generalized inverse mass `S = Σ wᵢ|gᵢ|²` and its multiplier `λ`. The group computes `V`,
//! `gᵢ` and `S` with [`crate::geometry::Surface`], calls one of these, and moves every
//! vertex by `Δxᵢ = wᵢ gᵢ Δλ`.
//!
//! See the [crate docs](crate) for the derivations and units.

use nucleus_sdk::xpbd;

use crate::geometry::Cubic;

/// The characteristic acoustic impedance of air, `ρc` (Pa·s/m): 1.204 kg/m³ × 343 m/s at
/// 20 °C. A hole of area `A` under a pressure difference `Δp` lets out the volume flow
/// `A Δp / (ρc)` (see [`leak_conductance`]).
pub const AIR_IMPEDANCE: f64 = 413.0;

/// `Δλ` of one XPBD step of the volume constraint `C = V − V_target − α p` with compliance
/// `α` (m³/Pa) and a constant gauge pressure `p` (Pa), given the multiplier `λ` (Pa·s²)
/// accumulated in this substep of length `h`. `λ/h²` is the gauge pressure the constraint
/// applies. 0 when no vertex can move (`S = 0`).
#[inline]
pub fn volume_delta_lambda(
    volume: f64,
    target: f64,
    alpha: f64,
    pressure: f64,
    s: f64,
    lambda: f64,
    h: f64,
) -> f64 {
    let c = volume - target - alpha * pressure;
    xpbd::delta_lambda(c, s, alpha, lambda, h)
}

/// `Δλ` of one Newton step of the ideal gas: the implicit equations of the substep
/// `M(x − x̃) = g λ` and `λ/h² = n/V(x) − p_atm`, linearized with `dV = gᵀΔx = S Δλ` and
/// `d(n/V)/dV = −n/V²`:
///
/// ```text
/// Δλ = (h² (n/V − p_atm) − λ) / (1 + h² (n/V²) S)
/// ```
///
/// This is the XPBD step of a volume constraint whose compliance is the gas's own, `α = V/p`
/// (its isothermal bulk modulus is `p`), so the gas is integrated implicitly: stable however
/// stiff the air. `volume` must be positive (the caller floors it); `amount` is `n = pV`
/// (Pa·m³).
#[inline]
pub fn gas_delta_lambda(
    volume: f64,
    amount: f64,
    ambient: f64,
    s: f64,
    lambda: f64,
    h: f64,
) -> f64 {
    if volume.is_nan() || volume <= 0.0 {
        return 0.0;
    }
    let pressure = amount / volume;
    let h2 = h * h;
    let denom = 1.0 + h2 * pressure / volume * s;
    if !denom.is_finite() {
        return 0.0;
    }
    (h2 * (pressure - ambient) - lambda) / denom
}

/// Newton's method on a scalar `f(t) = 0` from `t0`, at most [`LINE_ITERATIONS`] steps,
/// stopping when a step is below `1e-13 |t|`. `None` if a slope is not positive and finite or
/// the result does not reduce `|f|` below `|f(0)|`: the caller then keeps its linear step.
fn newton(f: impl Fn(f64) -> (f64, f64), t0: f64) -> Option<f64> {
    let (f_zero, _) = f(0.0);
    let mut t = t0;
    for _ in 0..LINE_ITERATIONS {
        let (value, slope) = f(t);
        if !(slope > 0.0 && slope.is_finite() && value.is_finite()) {
            return None;
        }
        let step = value / slope;
        t -= step;
        if step.abs() <= 1e-13 * t.abs() {
            break;
        }
    }
    let (value, _) = f(t);
    (t.is_finite() && value.abs() <= f_zero.abs()).then_some(t)
}

/// Newton steps taken along the line of a pass (each costs a few flops on the cubic, not a
/// pass over the mesh).
pub const LINE_ITERATIONS: usize = 8;

/// `Δλ` of one XPBD step of the volume constraint `C = V − V_goal` (`V_goal = V_target + α p`),
/// solved *exactly* along the line the step moves the vertices on, `x + Δλ u` with
/// `uᵢ = wᵢ gᵢ`: `V(Δλ)` is the cubic `volume`, and `Δλ` is the root of
/// `C(Δλ) + α̃ (λ + Δλ) = 0` (`α̃ = α/h²`) nearest the linear step, found by Newton's method on
/// the cubic. A hard constraint (`α = 0`) is then met exactly by one pass, whatever the size of
/// the correction. Falls back to the linear step [`volume_delta_lambda`] where the line search
/// fails; 0 when the volume cannot move along the line.
pub fn volume_step_along(volume: &Cubic, goal: f64, alpha: f64, lambda: f64, h: f64) -> f64 {
    let s = volume.slope(0.0);
    let linear = xpbd::delta_lambda(volume.at(0.0) - goal, s, alpha, lambda, h);
    if linear == 0.0 {
        return 0.0;
    }
    let alpha_tilde = alpha / (h * h);
    let f = |t: f64| {
        (
            volume.at(t) - goal + alpha_tilde * (lambda + t),
            volume.slope(t) + alpha_tilde,
        )
    };
    newton(f, linear).unwrap_or(linear)
}

/// `Δλ` of one step of the ideal gas solved exactly along the line `x + Δλ u`: the root of
///
/// ```text
/// (λ + Δλ)/h² = N / (max(V(Δλ), V_min) + hL) − p_atm
/// ```
///
/// (`N = n + p_atm hL` the gas the chamber holds with its leak folded in, see
/// [`leaked_amount`]) nearest the linear step [`gas_delta_lambda`], by Newton's method on the
/// cubic `volume`. The left side grows with `Δλ` and the right side falls (`V` grows along
/// `u`), so the root is unique. Falls back to the linear step where the line search fails.
pub fn gas_step_along(
    volume: &Cubic,
    floor: f64,
    held: f64,
    leak_volume: f64,
    ambient: f64,
    lambda: f64,
    h: f64,
) -> f64 {
    let v0 = volume.at(0.0).max(floor);
    let linear = gas_delta_lambda(
        v0 + leak_volume,
        held,
        ambient,
        volume.slope(0.0),
        lambda,
        h,
    );
    if linear == 0.0 {
        return 0.0;
    }
    let inv_h2 = 1.0 / (h * h);
    let f = |t: f64| {
        let raw = volume.at(t);
        let (v, dv) = if raw > floor {
            (raw, volume.slope(t))
        } else {
            (floor, 0.0)
        };
        let total = v + leak_volume;
        (
            (lambda + t) * inv_h2 - held / total + ambient,
            inv_h2 + held * dv / (total * total),
        )
    };
    newton(f, linear).unwrap_or(linear)
}

/// The leak conductance of a chamber's openings, `L` in `dn/dt = −L (p − p_atm)` (m³/s):
/// through openings of total area `A` the volume flow out is `Q = (1 − τ) A (p − p_atm) / ρc` ([`AIR_IMPEDANCE`]), carrying the gas
/// at the upwind pressure `p_up` (`p` flowing out, `p_atm` flowing in), so
/// `L = (1 − τ) A p_up / ρc`.
pub fn leak_conductance(open_area: f64, air_tightness: f64, upwind_pressure: f64) -> f64 {
    ((1.0 - air_tightness) * open_area * upwind_pressure / AIR_IMPEDANCE).max(0.0)
}

/// The amount of gas left after a substep of length `h` through openings of conductance `L`
/// (see [`leak_conductance`]), by backward Euler on `dn/dt = −L (n/V − p_atm)` at the
/// substep's final volume `V`:
///
/// ```text
/// n_end = n − h L (n_end/V − p_atm)   ⇔   n_end = (n + p_atm hL) V / (V + hL)
/// ```
///
/// The chamber behaves as if merged, for the substep, with the volume `hL` of ambient air
/// (`leak_volume`, m³): the gauge pressure relaxes toward 0 and never overshoots it however
/// large the hole or the substep, and the leak carries on at the rate the surface's tension
/// sustains as the chamber shrinks. `amount` is the gas at the start of the substep (pump
/// included); `volume` must be positive.
pub fn leaked_amount(amount: f64, volume: f64, ambient: f64, leak_volume: f64) -> f64 {
    if leak_volume <= 0.0 {
        return amount;
    }
    (amount + ambient * leak_volume) * volume / (volume + leak_volume)
}

/// The work the gas can do on its surroundings as it expands or contracts isothermally to
/// ambient pressure (J): `U(V) = p_atm V − n − n ln(p_atm V / n)`, the potential whose force
/// is `−dU/dV = n/V − p_atm`, shifted to 0 at equilibrium (`n/V = p_atm`). Never negative.
pub fn gas_energy(volume: f64, amount: f64, ambient: f64) -> f64 {
    if !(volume > 0.0 && amount > 0.0 && ambient > 0.0) {
        return 0.0;
    }
    let u = ambient * volume - amount - amount * (ambient * volume / amount).ln();
    u.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: f64 = 1.0 / 600.0;

    #[test]
    fn hard_volume_constraint_reaches_its_target_linearly_in_one_step() {
        // With V linear in λ (V = V0 + S λ), one step lands on the target exactly.
        let (v0, target, s) = (1.0, 1.5, 0.25);
        let dl = volume_delta_lambda(v0, target, 0.0, 0.0, s, 0.0, H);
        assert!((v0 + s * dl - target).abs() < 1e-15);
        // The applied pressure λ/h² is positive: the surface is pushed out.
        assert!(dl > 0.0);
    }

    #[test]
    fn compliant_volume_constraint_settles_where_pressure_balances_the_spring() {
        // An external spring k on the volume fights the constraint: V = V0 − p/k with p the
        // pressure the constraint applies; the equilibrium is p = (target + α p_c − V)/α.
        let (target, alpha, p_c, s) = (2.0, 1e-4, 500.0, 1e-3);
        let (mut v, mut lambda) = (1.0, 0.0);
        for _ in 0..2000 {
            let dl = volume_delta_lambda(v, target, alpha, p_c, s, lambda, H);
            lambda += dl;
            v += s * dl;
        }
        let p = lambda / (H * H);
        assert!((p - (target + alpha * p_c - v) / alpha).abs() < 1e-6 * p.abs());
    }

    #[test]
    fn gas_steps_converge_to_the_implicit_substep() {
        // A piston of generalized inverse mass S and nothing else: the substep's implicit
        // equations are V = V0 + S λ and λ/h² = n/V − p_atm. Newton steps with λ
        // accumulating converge to them quadratically.
        let (ambient, v0, s) = (1e5, 1e-3, 4e-2);
        let n = 1.3e5 * v0;
        let (mut v, mut lambda) = (v0, 0.0);
        let mut errors = Vec::new();
        for _ in 0..6 {
            let dl = gas_delta_lambda(v, n, ambient, s, lambda, H);
            lambda += dl;
            v = v0 + s * lambda;
            errors.push((lambda / (H * H) - (n / v - ambient)).abs() / ambient);
        }
        // Quadratic: each error at most the square of the one before (measured ratio 0.8).
        for k in 0..3 {
            assert!(errors[k + 1] <= errors[k] * errors[k], "{errors:?}");
        }
        assert!(errors[0] < 0.05 && errors[4] < 1e-14, "{errors:?}");
        // The piston moved out, and the gas is still above ambient (implicit, no overshoot).
        assert!(v > v0 && n / v > ambient);
    }

    /// The volume of a sphere of radius `r0 + t` for a unit outward speed: exact cubic.
    fn sphere_line(r0: f64) -> Cubic {
        let k = 4.0 / 3.0 * std::f64::consts::PI;
        Cubic {
            c: [k * r0.powi(3), 3.0 * k * r0 * r0, 3.0 * k * r0, k],
        }
    }

    #[test]
    fn a_hard_volume_is_met_exactly_along_its_line_in_one_step() {
        // Doubling a sphere's volume: the linear step misses by the cubic's curvature, the
        // step along the line does not.
        let line = sphere_line(1.0);
        let goal = 2.0 * line.at(0.0);
        let t = volume_step_along(&line, goal, 0.0, 0.0, H);
        assert!(
            (line.at(t) / goal - 1.0).abs() < 1e-14,
            "{}",
            line.at(t) / goal
        );
        let linear = volume_delta_lambda(line.at(0.0), goal, 0.0, 0.0, line.slope(0.0), 0.0, H);
        assert!((line.at(linear) / goal - 1.0).abs() > 0.05);
        // A compliant one lands where C + α̃λ = 0.
        let alpha = 1e-6;
        let t = volume_step_along(&line, goal, alpha, 0.0, H);
        assert!((line.at(t) - goal + alpha / (H * H) * t).abs() < 1e-12 * goal);
    }

    #[test]
    fn the_gas_step_along_its_line_solves_the_substep_exactly() {
        let line = sphere_line(0.1);
        let (ambient, hl) = (1e5, 1e-5);
        let held = 1.3e5 * line.at(0.0) + ambient * hl;
        let lambda = 2e-3 * H * H;
        let t = gas_step_along(&line, 1e-9, held, hl, ambient, lambda, H);
        let residual = (lambda + t) / (H * H) - (held / (line.at(t) + hl) - ambient);
        assert!(residual.abs() < 1e-9 * ambient, "{residual}");
        assert!(t > 0.0, "the gas pushes out");
    }

    #[test]
    fn line_steps_fall_back_to_zero_or_linear_not_nan() {
        let flat = Cubic::default();
        assert_eq!(volume_step_along(&flat, 1.0, 0.0, 0.0, H), 0.0);
        assert!(gas_step_along(&flat, 1e-9, 1.0, 0.0, 1e5, 0.0, H).is_finite());
        let nan = Cubic { c: [f64::NAN; 4] };
        assert_eq!(volume_step_along(&nan, 1.0, 0.0, 0.0, H), 0.0);
        assert_eq!(gas_step_along(&nan, 1e-9, 1.0, 0.0, 1e5, 0.0, H), 0.0);
    }

    #[test]
    fn gas_step_is_the_xpbd_step_with_the_gas_compliance() {
        let (v, n, ambient, s, lambda) = (2e-3, 250.0, 1e5, 3e-4, 1e-7);
        let p = n / v;
        let alpha = v / p;
        let c = -alpha * (p - ambient);
        let xpbd = xpbd::delta_lambda(c, s, alpha, lambda, H);
        let gas = gas_delta_lambda(v, n, ambient, s, lambda, H);
        assert!((xpbd - gas).abs() < 1e-12 * gas.abs(), "{xpbd} vs {gas}");
    }

    #[test]
    fn degenerate_gas_steps_are_zero_not_nan() {
        assert_eq!(gas_delta_lambda(0.0, 1.0, 1e5, 1.0, 0.0, H), 0.0);
        assert_eq!(gas_delta_lambda(-1.0, 1.0, 1e5, 1.0, 0.0, H), 0.0);
        assert_eq!(gas_delta_lambda(f64::NAN, 1.0, 1e5, 1.0, 0.0, H), 0.0);
        assert!(gas_delta_lambda(1e-300, 1e300, 1e5, 1.0, 0.0, H).is_finite());
        assert_eq!(volume_delta_lambda(1.0, 2.0, 0.0, 0.0, 0.0, 0.0, H), 0.0);
    }

    #[test]
    fn an_airtight_or_closed_chamber_keeps_its_gas() {
        assert_eq!(leak_conductance(0.5, 1.0, 1e5), 0.0, "airtight");
        assert_eq!(leak_conductance(0.0, 0.0, 1e5), 0.0, "no opening");
        assert_eq!(leaked_amount(100.0, 1e-3, 1e5, 0.0), 100.0);
    }

    #[test]
    fn leak_follows_the_rate_law_and_never_overshoots_ambient() {
        let (v, ambient, area, tight) = (2e-3, 1e5, 1e-4, 0.5);
        let p: f64 = 1.02e5;
        let n0 = p * v;
        let l = leak_conductance(area, tight, p.max(ambient));
        assert!((l - 0.5 * 1e-4 * p / AIR_IMPEDANCE).abs() < 1e-15);
        // Small steps: dn/dt = −L (p − p_atm).
        let dt = 1e-7;
        let n1 = leaked_amount(n0, v, ambient, l * dt);
        let rate = l * (p - ambient);
        assert!(((n0 - n1) / dt - rate).abs() < 1e-4 * rate);
        // A huge step: the gauge pressure vanishes, no further.
        let n = leaked_amount(n0, v, ambient, 1e6);
        assert!((n / v - ambient).abs() < 1e-6 * ambient, "{}", n / v);
        // Lower tightness leaks more; below ambient air comes in.
        let step = |t: f64| leaked_amount(n0, v, ambient, leak_conductance(area, t, p) * 0.01);
        assert!(step(0.1) < step(0.9) && step(0.9) < n0);
        let under = 0.9e5 * v;
        let l_in = leak_conductance(area, 0.5, ambient);
        assert!(leaked_amount(under, v, ambient, l_in * 0.01) > under);
    }

    #[test]
    fn gas_energy_is_zero_at_ambient_and_its_slope_is_the_gauge_pressure() {
        let (ambient, n) = (1e5, 200.0);
        let v_eq = n / ambient;
        assert!(gas_energy(v_eq, n, ambient).abs() < 1e-12);
        for v in [0.5 * v_eq, 0.9 * v_eq, 1.3 * v_eq] {
            assert!(gas_energy(v, n, ambient) > 0.0);
            let eps = 1e-9 * v;
            let slope =
                (gas_energy(v + eps, n, ambient) - gas_energy(v - eps, n, ambient)) / (2.0 * eps);
            let gauge = n / v - ambient;
            assert!(
                (-slope - gauge).abs() < 1e-4 * gauge.abs(),
                "{slope} vs {gauge}"
            );
        }
        assert_eq!(gas_energy(0.0, n, ambient), 0.0);
    }
}
