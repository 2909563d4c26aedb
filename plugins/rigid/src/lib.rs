//! # `rigid` — rigid bodies as particles held by shape matching
//!
//! One kind, `rigid`. In Nucleus a rigid body is not a separate solver: it is ordinary
//! particles (an object, or a vertex group of one) that a constraint keeps in their rest shape
//! up to a rigid motion. So a rigid body collides through the collision plugin, can be pinned,
//! takes its mass from the scene's `density`, and interacts two-way with cloth, ropes and
//! everything else, for free (the paper's soccer ball kicked into a net).
//!
//! ## Shape matching (Müller, Heidelberger, Teschner, Gross 2005)
//!
//! A body has particles `i` with masses `mᵢ` and rest positions `rᵢ` relative to its rest
//! centre of mass (`Σ mᵢ rᵢ = 0`). The rigid motion that best fits the current positions `xᵢ`
//! minimizes `Σ mᵢ |xᵢ − (c + R rᵢ)|²`:
//!
//! ```text
//! c = Σ mᵢ xᵢ / Σ mᵢ                      (the current centre of mass)
//! A = Σ mᵢ (xᵢ − c) rᵢᵀ                   (the moment matrix)
//! R = argmax over rotations of tr(Rᵀ A)   (the rotation of the polar decomposition A = R S)
//! gᵢ = c + R rᵢ                           (each particle's goal)
//! ```
//!
//! **Momentum.** A full step `xᵢ → gᵢ` moves the particles by `Δxᵢ = gᵢ − xᵢ` with
//! `Σ mᵢ Δxᵢ = M c + R Σ mᵢ rᵢ − M c = 0` (linear momentum kept exactly), and
//! `Σ mᵢ xᵢ × Δxᵢ = Σ mᵢ (xᵢ − c) × R rᵢ`, the axial vector of the skew part of `R Aᵀ = R S Rᵀ`,
//! which is symmetric exactly when `R` is the polar rotation: each projection keeps angular
//! momentum exactly *iff* `R` is optimal. Both are unit-tested on the pure functions.
//!
//! **The rotation, robustly** — Horn's quaternion method (Horn 1987). For a unit quaternion
//! `q`, `tr(R(q)ᵀ A) = qᵀ N(A) q` with `N` a symmetric 4 × 4 matrix of the entries of `A`, so
//! the optimal rotation is the eigenvector of `N`'s largest eigenvalue. We build `N` from
//! `Rₕᵀ A`, `Rₕ` the body's rotation at its last fit (the warm start), in which the answer is
//! near `(1, 0, 0, 0)`; Rayleigh-quotient iteration from there converges cubically (two or
//! three 4 × 4 solves), and its eigenvalue is accepted only when a Cholesky factorization of
//! `(ρ + τ)I − N` proves it the largest. Otherwise (first fit, a violent turn, a hint a
//! half-turn away) cyclic Jacobi diagonalizes `N` fully (accurate to a few ulps of `|N|`).
//! No allocation, no branch on the data beyond these. Why this and not the alternatives the
//! issue names:
//!
//! * It maximizes over **proper** rotations: the result is a unit quaternion, never a
//!   reflection, and for an inverted body (`det A < 0`) it is the best proper rotation —
//!   exactly what an SVD with reflection handling (`R = U diag(1, 1, det UVᵀ) Vᵀ`) returns,
//!   without a 3 × 3 SVD's branches and without squaring the condition number as `AᵀA` would.
//! * **Flat** sets (`A` of rank 2) still have a simple largest eigenvalue (gap `2σ₂`): their
//!   rotation is unique and found to full precision.
//! * **Collinear** sets (rank 1) have a doubly repeated largest eigenvalue: their twist about
//!   their own line is free (it moves no particle). We take the member of the optimal family
//!   nearest the last frame's rotation (the projection of the last rotation on the top
//!   eigenspace — where Rayleigh-quotient iteration from it converges, and what the Jacobi
//!   path computes explicitly), so the reported transform stays continuous. `A = 0` (one
//!   particle) keeps the last rotation. A NaN input returns the last rotation: never NaN out.
//! * The iterative extraction of Müller et al. 2016 is cheaper per iteration but converges
//!   linearly (slowly for near-singular `A`), and momentum conservation needs the *exact*
//!   optimum, which both paths here reach to rounding.

//! ## Partial rigidity: XPBD compliance
//!
//! Each free particle carries the vector constraint `Cᵢ = xᵢ − gᵢ` with compliance `α/mᵢ`
//! (`α` = the `compliance` parameter, in s²). The goals are held fixed during a step: this is
//! exact for the gradient, because `c, R` minimize the same weighted least squares that
//! defines the energy `E = Σ ½ mᵢ |xᵢ − gᵢ|² / α`, so by the envelope theorem
//! `∂E/∂xᵢ = mᵢ (xᵢ − gᵢ)/α`. The XPBD step (Macklin et al. 2016) with `α̃ = α/h²` and
//! `μᵢ = wᵢλᵢ` (the displacement toward the goal applied so far in the substep, m):
//!
//! ```text
//! Δxᵢ = (−Cᵢ − α̃ μᵢ) / (1 + α̃),   μᵢ ← μᵢ + Δxᵢ
//! ```
//!
//! Every particle moves the same fraction of the way to its goal, so linear momentum is kept
//! exactly whatever the masses. `α = 0` puts the body exactly on its goals in one pass. The
//! stiffness per unit mass is `1/α`: a deformation springs back with angular frequency
//! `1/√α` (α = 1e-4 s²: 100 rad/s, 16 Hz), independent of the substep and of the number of
//! passes. A body whose frame is held by pins sags under gravity by exactly `α |g|` at rest
//! (the static balance `mᵢ (xᵢ − gᵢ)/α = mᵢ g`), which a test checks. **μ is reset to 0 in
//! `begin_substep`** and accumulated over the passes, as λ in every XPBD constraint: an
//! isolated body is not stiffened by extra passes.
//!
//! ## Rigid velocities (`end_substep`)
//!
//! After the core's velocity update `vᵢ = (xᵢ − x0ᵢ)/h`, the velocities of every fully rigid
//! body (`compliance = 0`) are projected onto the rigid motions in the mass metric:
//!
//! ```text
//! v̄ = Σ mᵢ vᵢ / M,   L = Σ mᵢ (xᵢ − c) × vᵢ,   I = Σ mᵢ (|rᵢ|² 1 − rᵢ rᵢᵀ),   ω = I⁻¹ L
//! vᵢ ← v̄ + ω × (xᵢ − c)
//! ```
//!
//! `P` and `L` are kept exactly and the kinetic energy can only fall: what goes is the
//! particles' motion relative to each other (the radial part of the chord velocities, the
//! internal jostling left by contacts), which a rigid body does not have. It halves the spin
//! lost in free flight (per substep `θ → atan(sin θ) ≈ θ − θ³/2` instead of `θ − θ³`, so
//! `|L|` drifts by `1 − exp(−T ω² h / 2)` over a time `T`) and takes some of the bounce out of
//! contacts. Bodies held at one point get the same projection relative to their pin; bodies
//! held along a line or by three pins, and compliant bodies, keep their velocities.
//!
//! ## Contacts against immovable things
//!
//! A contact against a collider moves a particle by all of its violation whatever the
//! particle's mass; shape matching alone would move the body by the particle's share, `1/N`
//! of it, and the penetration the body kept would come back as velocity (a ball with
//! `restitution = 0` rebounded 24–47 % of its drop). Such moves arrive in the SDK's `pushes`
//! (restitution's in `kicks`), and a fully rigid body answers them with its own mass
//! ([`matching::answer_pushes`]): the rigid motion `(t, θ)` that moves every pushed point
//! along its push `δ` by at least `|δ|`, each push only pushing, each impulse
//! `Δλ = (|δ| − n·(t + θ × r)) / w` with the body's inverse mass at that point,
//! `w = 1/M + (r × n)ᵀ I⁻¹ (r × n)` (Müller et al. 2020), swept by projected Gauss-Seidel.
//! A body held by pins at one point or along a line only turns about them
//! ([`matching::answer_pushes_about`]). The pushed particles first go back by their pushes,
//! then the whole body moves: at each pass before the fit, at the end of the substep before
//! the velocities are taken from the positions; a kick counts as the push `h Δv` it gave the
//! particle in the next substep's prediction. Each answer first takes back the substep's
//! earlier answers and answers the sum of the substep's pushes so far: friction
//! answered apart from the normal pushes would turn a sliding body about its base (a slab
//! slowed at 1.08 `μd g`; answered together, at `μd g`).

//! ## Pinned particles
//!
//! Pinned particles (inverse mass 0) have infinite mass, and infinite masses dominate the
//! weighted fit: the frame is the best fit *subject to* matching the pins, by their shape in
//! the rest pose ([`matching::Anchor`]):
//!
//! * **one point** (one pin, or several at one place): the frame's centre follows the pin;
//!   the rotation fits the free particles about it — the body pivots about its pin;
//! * **a line**: the centre follows the pins' centroid and the rest axis through them follows
//!   their current line; the twist about it fits the free particles — a hinge;
//! * **a plane or more** (three non-collinear pins): the pins alone fix the frame (their own
//!   best fit); free particles simply follow.
//!
//! Pinned particles are never moved. The rest reference point of a pinned body is the
//! centroid of its pins.
//!
//! ## Per-frame transforms for a DCC
//!
//! A plugin does not write files (the host owns output): the `report` stage is the channel.
//! Per body, `stats.csv` gets the columns `<group>.<body>.tx, ty, tz, qw, qx, qy, qz` — the
//! rigid transform of the **rest pose**: a point `p` of a high-resolution mesh modelled in the
//! rest pose is at `q·p + t` (m) in that frame — plus `cx, cy, cz`, the centre of mass (m),
//! and `lx, ly, lz`, the angular momentum about it (kg·m²/s).
//!
//! ## Initial spin
//!
//! `initial_angular_velocity` (rad/s, per group or per body): in the `force` stage of the
//! first substep of the run (frame 0, substep 0), `vᵢ += ω × (xᵢ − c)` for the body's free
//! particles, `c` its centre of mass (its pins' centroid if pinned). The scene format has no
//! per-object angular velocity, and a plugin must not write velocities at build time.
//!
//! ## Residual
//!
//! The distance `|xᵢ − gᵢ|` (m) of every free particle from its goal in the frame fitted to the
//! current positions; `energy` is `Σ ½ mᵢ |xᵢ − gᵢ|² / α` over the compliant bodies (J).
//!
//! ## Scheduling defaults
//!
//! * **Order 10**: after the structural constraints (stretch at 0), so a rigid body that is
//!   also stretched ends each column rigid; collisions should come later still (a larger
//!   order) to have the last word on penetration, the body being re-matched next pass.
//! * **Importance 1**: with `compliance = 0` one pass puts the body exactly on its goals.

pub mod group;
pub mod matching;

#[cfg(test)]
mod tests;

pub use group::{BodySpec, RegionBox, RigidGroup, RigidParams, REPORT_COLUMNS};
pub use matching::{
    classify_pins, fit_frame, horn_matrix, optimal_rotation, project_goals, symmetric_eigen4,
    Anchor, BodyRef, Frame,
};

use nucleus_sdk::KindSpec;

/// The kinds this plugin provides: `rigid`.
pub fn kinds() -> Vec<KindSpec> {
    vec![KindSpec {
        name: "rigid",
        doc: "Rigid bodies by shape matching (Mueller et al. 2005): the particles of each target \
              object, or of each vertex group, keep their rest shape up to a rigid motion \
              (optimal rotation by Horn's quaternion method; no reflection, robust for flat \
              and collinear sets); partial rigidity by XPBD compliance; pinned particles \
              hold the frame; reports each body's rigid transform per frame.",
        default_order: 10,
        default_importance: 1,
        residual_unit: "m",
        params: RigidParams::specs(),
        factory: group::build,
    }]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: "rigid",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
