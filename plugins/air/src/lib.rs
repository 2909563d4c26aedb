//! # `air` — drag, lift and wind
//!
//! One kind, `air`: the force of a moving medium on every surface triangle, curve edge and
//! isolated point of the objects the group is applied to. It is the paper's flag (Section 1):
//! "a flapping flag can be simulated using a simple directional wind field and an
//! inextensible piece of cloth. The flapping behavior emerges from the drag and lift
//! constraints battling the stretch constraint." There is no air-flow model beyond that: the
//! air does not see the cloth (no wake, no shadowing, no pressure field).
//!
//! ## The model
//!
//! Every element moves through the air at `v_rel = v_elem − w`, the mean velocity of its
//! vertices minus the mean wind at them (m/s). With `ρ` the air density (kg/m³), `u = |v_rel|`
//! and the dimensionless coefficients `C_d` (`drag`), `C_l` (`lift`) and
//! `C_t = tangential_drag · C_d`:
//!
//! **Triangles** (area `A`, unit normal `n̂` of the winding, `v_n = v_rel·n̂` the normal
//! component, `v_t = v_rel − v_n n̂` the tangential one):
//!
//! ```text
//! F_drag = −½ ρ C_d A |v_n| v_rel                  along −v_rel,        |F| = ½ρC_d A u |v_n|
//! F_lift = −½ ρ C_l A (v_n/u) (u² n̂ − v_n v_rel)    ⊥ v_rel, in the plane of v_rel and n̂,
//!                                                                       |F| = ½ρC_l A |v_n| |v_t|
//! F_tan  = −½ ρ C_t A |v_t| v_t                     in the surface (skin drag)
//! ```
//!
//! Drag is along the relative velocity and lift perpendicular to it, both scaled by the air
//! density, the area and the normal component of the relative speed. Face-on (`v_rel ∥ n̂`)
//! the drag is `½ ρ C_d A u²`, so a plate falling face-on reaches the terminal velocity
//! `v_t = sqrt(2 m g / (ρ C_d A))`. With `α` the angle between the plate and the flow,
//! `|v_n| = u sin α` and `|v_t| = u cos α`:
//!
//! ```text
//! drag = ½ ρ C_d A u² sin α,   lift = ½ ρ C_l A u² sin α cos α,   lift/drag = (C_l/C_d) cos α
//! ```
//!
//! — the flat plate's `sin α cos α` lift, zero face-on and edge-on. The lift points away from
//! the side the air comes from, like a pressure on the windward face. Flipping a triangle's
//! winding flips `n̂` and `v_n` together, so no term depends on which side faces the wind.
//!
//! **Curve edges** (length `L`, thickness `curve_width` = `b`, projected area `S = L b`,
//! `v_∥` along the edge and `v_⊥` across it) are yawed cylinders whose cross-flow and axial
//! flow act independently; a round section has no lift:
//!
//! ```text
//! F_drag = −½ ρ C_d S |v_⊥| v_⊥,    F_tan = −½ ρ C_t S |v_∥| v_∥
//! ```
//!
//! **Isolated points** (radius `particle_radius` = `r`, `S = π r²`) are spheres:
//! `F_drag = −½ ρ C_d S u v_rel`.
//!
//! All forces are in newtons. A triangle with area below [`aero::MIN_AREA`] (1e-24 m²), an
//! edge shorter than [`aero::MIN_LENGTH`] (1e-12 m), or a relative velocity of 0 feels
//! nothing, and an element whose force is not finite (absurd speeds) is skipped: degenerate
//! geometry never produces NaN.
//!
//! ## Applied at velocity level, in the force stage — and why
//!
//! The paper calls drag and lift constraints; here they are forces, applied in the `force`
//! stage (after gravity, before prediction), so the predicted positions `x0 + h v` already
//! carry the air's push and the stretch projection that follows battles it inside the same
//! substep — the paper's "battle of the constraints". Applied as velocity constraints after
//! the velocity update (`end_substep`), the air would act only after the positions were
//! solved: one substep late, and not re-projected by the stretch constraint until the next.
//! Air has no target state to project to, so a force is its natural form.
//!
//! Each element's force is split **equally over its vertices** (⅓ per triangle vertex, ½
//! per edge end), which with masses lumped by area (`density` in a scene) gives every vertex
//! of a uniform plate the same acceleration. The positions and velocities are those at the
//! start of the substep (after gravity's `v += h g`). Every dynamic particle then gets
//!
//! ```text
//! Δv = h w F / (1 + h w β)         w = 1/m,  β = Σ (element rate)/(vertices per element)
//! ```
//!
//! the backward-Euler step with the force's Jacobian approximated by `−β I`, where each
//! element's `β` (N·s/m) bounds how fast its force changes with its velocity:
//! `A ((k_d + k_l)(|v_n| + u) + 2 k_t |v_t|)` for a triangle, `2 S (k_d |v_⊥| + k_t |v_∥|)`
//! for an edge and `2 k_d S u` for a point, with `k = ½ ρ C`. As `h → 0` this is the explicit
//! step. Its fixed point is the explicit one to first order in `h`, and exactly the true
//! terminal velocity to second order when `β` is the exact rate along the motion (a plate
//! falling face-on with no lift, a point). And no drag can reverse the relative velocity it
//! acts on, whatever the time step or the mass: a light particle in a hurricane stays
//! stable. Kinematic particles (inverse mass 0) are never changed, but the air still acts on
//! them: a held object's load is computed and reported.
//!
//! ## Per-object coefficients
//!
//! Parameters belong to a group, and a scene may hold several `air` groups, each applied to
//! its own objects (`objects = [...]`, a `name` each): that is how a sail and a rope get
//! different coefficients. Give every group the same wind parameters (and seed) for one
//! shared wind field: the wind is a pure function of position and time, so they then see
//! the same gusts.
//!
//! ## Defaults and Maya
//!
//! The defaults are Maya's nCloth numbers — `drag` 0.05, `lift` 0, `tangential_drag` 0.1 —
//! and the nucleus node's wind (speed 0, direction +x, no noise). `tangential_drag` keeps
//! Maya's meaning, a fraction of the drag (0: no skin drag; 1: flow along the surface is
//! resisted like flow across it). Maya's Drag is not documented as a physical coefficient
//! (it acts through the solver's own scaling, e.g. its Space Scale); here `drag` and `lift`
//! are the dimensionless `C_d` and `C_l` of the SI formulas above, so Maya's 0.05 is a light
//! air resistance: a 0.1 kg, 1 m² cloth falling flat settles at 5.7 m/s. A physical flat
//! plate has `C_d ≈ 1.2` (the same cloth: 1.2 m/s). The air density defaults to the physical 1.2 kg/m³
//! (sea level, 20 °C) rather than Maya's 1.0, so textbook coefficients give textbook forces;
//! only the product `ρ C` matters, so a Maya scene is matched by `air_density = 1.0`.
//!
//! ## Wind
//!
//! `wind_speed` along `wind_direction` (normalised; zero is refused), plus a seeded, smooth
//! turbulence of amplitude `noise` (m/s), gust size `noise_scale` (m) and rate
//! `noise_frequency` (Hz), carried downstream with the wind: see [`wind`]. The same seed
//! gives bit-identical runs.
//!
//! ## Residual and report
//!
//! Air has nothing to satisfy; its residual is the relative speed `|v_rel|` of the elements
//! (m/s, max and rms): the speed the drag works to remove (at terminal velocity, the
//! terminal velocity). `report` gives, for the last substep of each frame, the total force
//! on the group `force_x`, `force_y`, `force_z` (N) and the size of the sum of each term,
//! `drag`, `lift` and `tangential` (N).
//!
//! ## Scheduling defaults
//!
//! The group has only a `force` stage (and `report`), so its order and importance are
//! unused: groups' force stages run once per substep, in scene order. Order 0, importance 1.

pub mod aero;
pub mod group;
pub mod wind;

#[cfg(test)]
mod tests;

pub use aero::{Coefficients, ElementForce};
pub use group::{AirGroup, AirParams, Totals};
pub use wind::Wind;

use nucleus_sdk::KindSpec;

/// The kinds this plugin provides: `air`.
pub fn kinds() -> Vec<KindSpec> {
    vec![KindSpec {
        name: "air",
        doc: "Drag, lift and skin drag of a moving air (wind with optional smooth, seeded \
              turbulence) on every surface triangle, curve edge and isolated particle of the \
              target objects, applied as forces in the force stage (before the prediction).",
        default_order: 0,
        default_importance: 1,
        residual_unit: "m/s",
        params: AirParams::specs(),
        factory: group::build,
    }]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: "air",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
