//! # `pressure` — pressure over a whole mesh's volume
//!
//! Two kinds, after Maya nCloth's two pressure methods. Each acts on **chambers**: the
//! connected components of the target objects' surfaces (a shell's triangles, or the boundary
//! faces of a tet mesh). One constraint per chamber couples *every* vertex of it — the SDK
//! serves more than pairwise position constraints.
//!
//! * `pressure` — *manual pressure*. A closed chamber keeps the volume
//!   `V_target = pressure_scale × V_rest` through an XPBD volume constraint with compliance; an
//!   open chamber (a sail) is pushed along its normals by a given gauge pressure.
//! * `gas` — the *volume tracking model*. Each chamber holds an ideal gas, `p V = n` (the
//!   amount `n` in Pa·m³, so at a fixed temperature `n ∝` moles), with a pump, leaks through
//!   its openings governed by the air tightness, an incompressibility (the gas's bulk
//!   modulus) and a start pressure.
//!
//! ## Topology: chambers, orientation, closedness
//!
//! [`topology::chambers`] splits each object's surface into connected components and orients
//! each consistently by a breadth-first search over the triangle pairs of the simplicial
//! complex (a neighbour traversing the shared edge the same way is flipped). A non-orientable
//! component (a Möbius strip) or a non-manifold surface is refused with an error naming the
//! object. Whether a chamber is closed comes from the complex's boundary edges, never from a
//! user flag; a closed chamber is then turned **outward** (positive rest volume; a closed
//! chamber of zero rest volume keeps the winding of its first triangle). An open chamber keeps
//! the winding of its first triangle for `pressure` (the sign of `pressure` or the winding
//! says which side is pushed) and is turned so its capped volume is positive for `gas` (the
//! gas is inside the bag).
//!
//! ## Geometry
//!
//! With every chamber oriented, [`geometry::Surface::measure`] computes
//!
//! ```text
//! V  = Σ_t (xa − r)·((xb − r) × (xc − r)) / 6                   (m³, r = first vertex)
//! gᵢ = Σ_{t = (i, j, k)} (xj − xi) × (xk − xi) / 6 = Σ_{t ∋ i} Aₜ nₜ / 3   (m²)
//! ```
//!
//! For a closed chamber `gᵢ = ∂V/∂xᵢ` exactly, `Σ gᵢ = 0` and `Σ xᵢ × gᵢ = 0`: a uniform
//! pressure pushes with no net force nor torque. An **open** chamber's volume is that of the
//! surface closed by a fan from each boundary loop's centroid `c` (cap triangles
//! `(xj, xi, c)` for each boundary edge `i → j`); its opening area is `Σ_loops |½ Σ (xi − c) ×
//! (xj − c)|`. The pressure normals `gᵢ` stay those of the surface itself — pressure pushes
//! the cloth, not the imaginary cap — so on an open chamber `Σ gᵢ = −(vector area of the
//! openings) ≠ 0`: a sail is pushed, and momentum is not conserved (the air outside takes
//! it). Off the boundary `gᵢ` is still the gradient of the capped volume.
//!
//! ## The substep: directions frozen, each correction exact along its line
//!
//! Every chamber's normals `gᵢ` are computed once per substep, in the `force` stage, at the
//! positions the substep starts from (`x0`), and every correction of the substep moves vertex
//! `i` along the same direction `uᵢ = wᵢ gᵢ` — the XPBD displacement `Δxᵢ = wᵢ ∇ᵢC Δλ` —
//! while the constraint is evaluated at the current positions.
//!
//! * **Momentum.** On a closed chamber `Σ gᵢ = 0` and `Σ x0ᵢ × gᵢ = 0`, so each correction
//!   leaves both discrete momenta of the step unchanged — linear `Σ mᵢ(xᵢ − x0ᵢ)/h` and
//!   angular `Σ mᵢ x0ᵢ × xᵢ / h` — with *any* masses (kinematic vertices, which do not move,
//!   are external). With normals taken at the current positions instead, the angular momentum
//!   changes by `−Σ mᵢ vᵢ × Δxᵢ` per correction: for a spinning, inflated balloon an outward
//!   push *adds* spin in proportion to the spin, and an inflated balloon left to itself spun up
//!   from rounding noise (its kinetic energy grew a hundredfold every third of a second at
//!   600 substeps/s).
//! * **Exact along the line.** The volume is a cubic polynomial of the positions, so along
//!   the line of a correction it is exactly `V(x + t u) = c₀ + c₁t + c₂t² + c₃t³`
//!   ([`geometry::Surface::volume_along`]): `c₀ = V(x)`, `c₁ = Σ ∇ᵢV(x)·uᵢ`, `c₂ = Σ (xᵢ −
//!   r)·mᵢ/6` with per-vertex moments `mᵢ = Σ_{t=(i,j,k)} uⱼ × uₖ` and `c₃ = Σₜ ua·(ub × uc)/6`,
//!   both fixed for the substep ([`geometry::Surface::line_moments`]). A pass costs three
//!   cross products per triangle; the scalar equation of the constraint along the line is then
//!   solved by Newton's method on the cubic ([`solve::volume_step_along`],
//!   [`solve::gas_step_along`]), starting from the linear XPBD step below. A hard volume is
//!   met exactly by one pass, however large the correction: with the linear step alone, a
//!   balloon held at twice its volume settled 0.17 % short (the stretch pass before it pulls
//!   the volume 7 % down every substep, and one linear step from there misses by the
//!   curvature); now to rounding.
//! * **Warm start.** `λ` is the total multiplier of the substep, accumulated over its passes.
//!   A soft chamber (the gas, or a compliant volume) starts it from the pressure it applied
//!   over the *last* substep: the `force` stage pushes with that pressure, `vᵢ += h p uᵢ` (so
//!   the prediction carries the impulse `h² p`), and `begin_substep` sets `λ = h² p`. The
//!   first projection moves `λ/h²` to a convex combination of the pressure it started from
//!   and the constraint's own pressure at the current positions, so it never exceeds the
//!   pressures the chamber has had. Without it, one pass per substep converges only across
//!   substeps, and against a membrane the gas pushes with about `(p − p_atm)/(1 + h² (p/V) S)`,
//!   `S = Σ wᵢ|gᵢ|²`, instead of `p − p_atm`: for real air in a 10 cm, 50 g balloon at 600
//!   substeps/s, about a twentieth of its pressure (in the Boyle test, with air 50 times
//!   softer, the applied pressure lagged Boyle's by 1.9 %; now it matches to rounding). A
//!   **hard** volume starts from `λ = 0`: its `λ` holds the impulses that removed violations
//!   (the first substep of an inflation to twice the volume pushes with tens of kPa), and
//!   pushing with those again made the balloon explode.
//!
//! ## `pressure`: the volume constraint (closed chambers)
//!
//! ```text
//! C = V(x) − V_target − α p,     ∇ᵢC = gᵢ,     α = compliance × V_rest
//! Δλ = (−C − α̃λ) / (Σᵢ wᵢ|gᵢ|² + α̃),   α̃ = α/h²,   Δxᵢ = wᵢ gᵢ Δλ,   λ ← λ + Δλ
//! ```
//!
//! is the linear XPBD step; the plugin takes the root of `C(x + Δλ u) + α̃(λ + Δλ) = 0` nearest
//! it, exactly along the line.
//!
//! **Units.** `C` in m³, `gᵢ` in m², so `λ` is in Pa·s² and `λ/h²` is the gauge pressure the
//! constraint applies (Pa; the force on vertex `i` is `gᵢ λ/h²`). The compliance `α` is in
//! m³/Pa; the parameter `compliance` is relative, in 1/Pa (the inverse of the chamber's bulk
//! modulus), so a scaled-up scene keeps its behaviour. `α = 0` is a hard constraint. `p` is
//! the `pressure` parameter: with `α > 0` it inflates the chamber to `V_target + α p`, with
//! the spring force `−C/α = (V_target − V)/α + p`; a hard constraint absorbs it.
//!
//! ## `pressure`: open chambers
//!
//! A force `fᵢ = p gᵢ` (`p A n / 3` from each triangle to each of its vertices), applied at
//! velocity level in the `force` stage: `vᵢ += h wᵢ p gᵢ`. There is no volume to keep, so no
//! stiffness to integrate implicitly; the normals follow the cloth each substep. The
//! `pressure_scale` and `compliance` parameters do not apply.
//!
//! ## `gas`: the volume tracking model
//!
//! **State.** Each chamber holds `n = p V` (Pa·m³), `p` its absolute pressure. The ambient
//! absolute pressure is `p_atm = incompressibility`: the isothermal bulk modulus of an ideal
//! gas, `−V dp/dV = p`, is its pressure, so "how stiffly pressure answers volume change" at
//! ambient *is* the ambient pressure (101325 Pa for air at sea level; lower values make softer
//! air). At the start `n = (p_atm + start_pressure) V_rest`. The surface feels the gauge
//! pressure `p − p_atm = n/V − p_atm`. With no pump and no leak `n` is constant, and
//! `p = p₀V₀/V` (Boyle).
//!
//! **Pump.** `n += pump_rate · h` at the start of each substep (exact for a constant rate).
//!
//! **Leak** ([`solve::leak_conductance`], [`solve::leaked_amount`]): through the openings
//! (the caps' area `A`) the volume flow out is
//!
//! ```text
//! Q = (1 − air_tightness) A (p − p_atm) / ρc,    ρc = 413 Pa·s/m (air's impedance)
//! ```
//!
//! a linear, acoustic-resistance law (a hole of area `A` conducts like a piston radiating into
//! open air), carrying the gas at the upwind pressure `p_up = max(p, p_atm)` (the inside
//! pressure going out, the outside one coming in): `dn/dt = −L (p − p_atm)` with the
//! conductance `L = (1 − air_tightness) A p_up / ρc` (m³/s), taken at the start of the
//! substep. It is integrated by backward Euler at the substep's *final* volume,
//! `n_end = n − hL (n_end/V − p_atm)`, i.e. `n_end = (n + p_atm hL) V/(V + hL)`: for the
//! substep the chamber is merged with the volume `hL` of ambient air. The gauge pressure then
//! never overshoots ambient however large the hole, and the leak goes on at the pressure the
//! surface sustains as it shrinks (freezing `V` over the substep instead, as in a rigid
//! bottle, leaks less by the factor `(1 − e^{−kh})/(kh)`, `k = L/V`: 0.9 for the holed
//! balloon of the tests at air tightness 0). A closed chamber has no
//! openings and never leaks, whatever its air tightness.
//!
//! **The gas step** ([`solve::gas_step_along`]): the substep's implicit equations are
//! `M(x − x̃) = g λ` and `λ/h² = n_end/V(x) − p_atm`; with the leak folded in, the chamber holds
//! `N = n + p_atm hL` in `V + hL`. Linearized with `dV = Σ gᵢ·Δxᵢ = S Δλ` and `dp/dV =
//! −N/(V + hL)²`, one Newton step is ([`solve::gas_delta_lambda`])
//!
//! ```text
//! Δλ = (h² (N/(V + hL) − p_atm) − λ) / (1 + h² N/(V + hL)² S),    Δxᵢ = wᵢ gᵢ Δλ
//! ```
//!
//! the XPBD step of a volume constraint whose compliance is the gas's own, `α = V/p`; the
//! plugin solves the same equation exactly along the line (`V(Δλ)` the cubic), starting from
//! it. The gas is integrated implicitly, so air as stiff as the real one (a 10 cm balloon of
//! 50 g answers a 1 % squeeze with 1 kPa) is stable at ordinary substeps, where an explicit
//! pressure force is not. `λ/h²` is the gauge pressure the step applied. After each pass `n`
//! is updated to the gas left at the volume the step moves the chamber to. A volume below
//! `10⁻⁶ A_rest^{3/2}` (a collapsed or inverted chamber) is taken at that floor, so `p` stays
//! finite.
//!
//! **Energy.** The group's `energy` is the work the gas can still do reaching ambient
//! pressure, `U = p_atm V − n − n ln(p_atm V / n) ≥ 0` (J), whose force is `−dU/dV = n/V −
//! p_atm`.
//!
//! ## Residual and reports
//!
//! Both kinds report a **relative volume** residual per closed constraint: `pressure`,
//! `|V − V_goal| / V_goal` (`V_goal = V_target + α p`); `gas`, `|V − V*| / V*` with
//! `V* = n / p_applied` the volume at which the gas would push with the pressure the last
//! substep applied (equivalently `|p_applied − p| / p`). Open `pressure` chambers carry no
//! constraint and no residual. Each frame the groups report (stats columns
//! `<group>.<name>`): `pressure` — `volume`, `target_volume`, `applied_pressure`; `gas` —
//! `volume`, `amount`, `pressure` (absolute), `gauge_pressure`, `applied_pressure`,
//! `open_area`, summed (or volume-weighted) over the group's chambers.
//!
//! ## Scheduling defaults
//!
//! **Order 10** (after `stretch`, at 0): the chambers' volume has the last word within each
//! column, so a hard volume constraint holds exactly at the end of the substep. **Importance
//! 1**: one Newton step per substep; XPBD's stiffness does not depend on the pass count.

pub mod geometry;
pub mod group;
pub mod solve;
pub mod topology;

#[cfg(test)]
mod tests;

pub use geometry::{Measure, Surface};
pub use group::{Chambers, GasGroup, GasParams, PressureGroup, PressureParams};

use nucleus_sdk::KindSpec;

/// The default order of both kinds: after `stretch` (0).
pub const DEFAULT_ORDER: i32 = 10;

/// The kinds this plugin provides: `pressure` and `gas`.
pub fn kinds() -> Vec<KindSpec> {
    vec![
        KindSpec {
            name: "pressure",
            doc: "Manual pressure (Maya's Manual Pressure Setting): an XPBD volume constraint \
                  C = V - pressure_scale x V_rest on each closed mesh (one constraint over all \
                  its vertices), and a pressure along the normals on each open mesh (a sail).",
            default_order: DEFAULT_ORDER,
            default_importance: 1,
            residual_unit: "relative volume",
            params: PressureParams::specs(),
            factory: group::build_pressure,
        },
        KindSpec {
            name: "gas",
            doc: "Volume tracking model: an ideal gas p V = n in each mesh, integrated \
                  implicitly, with a pump, leaks through holes and open edges by air tightness, \
                  an incompressibility (bulk modulus = ambient pressure) and a start pressure.",
            default_order: DEFAULT_ORDER,
            default_importance: 1,
            residual_unit: "relative volume",
            params: GasParams::specs(),
            factory: group::build_gas,
        },
    ]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: "pressure",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
