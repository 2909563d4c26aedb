//! # `attract` — pull particles toward a point
//!
//! A complete constraint plugin, and the template `nucleus new-plugin` copies: one kind,
//! `attract`, that pulls every dynamic particle of the objects it is applied to toward a
//! point — a magnet for a particle cloud, a leash that keeps a cloth or a rope within reach
//! of a point, a "goal" that gathers debris. Replace the maths in [`constraint`] and the batch
//! in [`group`] with your own; keep the structure (see the plugin author's guide,
//! `plugin-sdk/README.md` in the Nucleus repository).
//!
//! ## The constraint
//!
//! For a particle at `x`, the centre `c` and the free radius `r`:
//!
//! ```text
//! C(x) = |x − c| − r          (m; > 0 outside the free ball)
//! ∇ₓC  = n = (x − c) / |x − c|,   so w |∇C|² = w
//! ```
//!
//! The constraint is one-sided, `C ≤ 0`: it pulls a particle that is outside the ball and
//! leaves alone one that is inside. `n` is undefined at the centre: a particle closer than
//! [`constraint::MIN_DISTANCE`] (1e-12 m) is skipped for that pass, never divided by zero.
//! Particles farther than `max_distance` from the centre are out of reach and not pulled.
//!
//! ## The XPBD step, with a compliance per particle
//!
//! A compliance `α` is an inverse stiffness, so one `α` for every particle would let a heavy
//! particle sag more and swing slower than a light one, and the look would change with the
//! resolution of the mesh. Instead the parameter is the **natural period** `T` of the pull:
//! with `τ = T/2π`, a particle of inverse mass `w` gets `α = w τ²` (m/N), i.e. the stiffness
//! `k = m (2π/T)²`, and every particle feels the same acceleration `−(2π/T)² C n`. With the
//! substep `h` and `α̃ = α/h²` ([`nucleus_sdk::xpbd::delta_lambda`]):
//!
//! ```text
//! Δλ* = (−C − α̃λ) / (w + α̃)
//! λ'  = min(λ + Δλ*, 0),   Δλ = λ' − λ,   Δx = w n Δλ
//! ```
//!
//! The clamp `λ ≤ 0` is what makes the constraint one-sided: the accumulated multiplier can
//! only pull; a pull applied by an earlier pass of the substep is released, down to nothing,
//! once the particle is back inside the ball. `T = 0` is a hard constraint: one step puts a
//! particle exactly on the sphere `|x − c| = r`.
//!
//! **Units.** `λ` is in N·s² (`λ/h²` is the pull, in N, negative toward the centre).
//!
//! **λ is accumulated over the passes of a substep and reset to 0 in `begin_substep`**, as in
//! every XPBD constraint of Nucleus: the stiffness then depends neither on `h` nor on the
//! group's importance. For a lone particle the first pass solves `C + α̃λ = 0` exactly and
//! later passes change nothing (a unit test checks it).
//!
//! **What the maths guarantees.** With `r = 0` the constraint is the zero-length spring
//! `k = m (2π/T)²` to `c`, and one step is exactly implicit Euler of it: a particle released
//! at `d` from the centre is at `d (1 + h²/τ²)^(−N/2) cos(N atan(h/τ))` after `N` substeps —
//! period `T` up to `O(h²/τ²)`, with implicit Euler's numerical damping of about
//! `exp(−π h/τ)` per period. Under gravity `g` a particle hangs `g τ²` beyond the sphere
//! (`= g (T/2π)²`, independent of its mass and of `h`). The correction is along `x − c`:
//! the pull is central and exerts no torque about the centre. It does **not** conserve
//! linear momentum — the attractor is an external body of infinite mass.
//!
//! ## Residual and report
//!
//! The residual is `max(C, 0)` (m) over the particles within reach: how far they still are
//! outside the ball; `energy` is `Σ ½ C²/α` over the soft pulls (J). The group reports
//! `mean_distance` (m), the mean distance of its particles from the centre, once per frame
//! (column `<group>.mean_distance` of `stats.csv`).
//!
//! ## Scheduling defaults
//!
//! * **Order −10**: a soft pull runs *before* the structure (stretch is order 0, collisions
//!   100) within each column of the schedule, so the constraints that must hold have the last
//!   word on the positions.
//! * **Importance 1**: the stiffness does not depend on the pass count (see above).

pub mod constraint;
pub mod group;

pub use constraint::{attraction_constraint, project_attraction, Attractor, Correction};
pub use group::{AttractGroup, AttractParams};

use nucleus_sdk::KindSpec;

/// The kind name as written in scenes (`kind = "attract"`); unique across all loaded plugins.
pub const KIND: &str = "attract";

/// The plugin's name, as `nucleus plugins` lists it.
pub const PLUGIN: &str = "nucleus-template-attract";

/// The kinds this plugin provides.
pub fn kinds() -> Vec<KindSpec> {
    vec![KindSpec {
        name: KIND,
        doc: "Pulls every dynamic particle of the target objects toward `center` until it is \
              within `radius`, as an XPBD one-sided constraint C = |x - c| - r <= 0 whose \
              compliance gives every particle the same natural period `period`, whatever its \
              mass; particles beyond `max_distance` are not pulled.",
        default_order: -10,
        default_importance: 1,
        residual_unit: "m",
        params: AttractParams::specs(),
        factory: group::build,
    }]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: PLUGIN,
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});

#[cfg(test)]
mod tests;
