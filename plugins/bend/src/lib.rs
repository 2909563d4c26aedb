//! # `bend` — the paper's type-2 and type-3 constraints
//!
//! Nucleus models every internal deformation with three constraint types (Stam 2009,
//! Section 5, Figures 7–8). Type 1 (stretch) is the `stretch` plugin; this plugin provides
//! the other two, plus a faster bending model for nearly flat cloth:
//!
//! | kind | constraint | on | model |
//! |---|---|---|---|
//! | `bend` | dihedral angle of two triangles sharing an edge (type 3) | surfaces | [`dihedral`] |
//! | `bend` | angle between two edges sharing a vertex (type 2) | curves | [`angle`] |
//! | `bend_isometric` | Bergou et al. 2006 quadratic bending | surfaces | [`bergou2006_isometric`] |
//! | `shear` | angle at each triangle corner (type 2) | surfaces | [`angle`] |
//! | `twist` | dihedral angle of three consecutive edges (type 3) | curves | [`dihedral`] |
//!
//! Rest angles come from the scene's rest shape, so pre-bent ropes and pre-folded cloth keep
//! their shape. "Surfaces" are triangles in no tetrahedron; "curves" are edges in no
//! triangle. An object with nothing of a kind contributes nothing to its group.
//!
//! ## The constraints
//!
//! * **Angle** (type 2) at `j` between the edges to `i` and `k`:
//!   `φ = atan2(|a × b|, a·b) ∈ [0, π]` with `a = xi − xj`, `b = xk − xj`; `C = φ − φ₀`.
//! * **Dihedral angle** (type 3) of the hinge with axis `i → j` and wings `k`, `l`:
//!   `φ = atan2((n₁ × n₂)·ê, n₁·n₂) ∈ (−π, π]` with `n₁ = e × (xk − xi)`,
//!   `n₂ = (xl − xi) × e`; `C = wrap(φ − φ₀)` into (−π, π]. Signed: 0 is flat, ±π folded
//!   flat onto itself. For a triangle pair the axis is the shared edge oriented by the first
//!   triangle's winding; for twist, the middle edge `b → c` of four consecutive curve points
//!   `a, b, c, d`, with wings `a` and `d`.
//! * **Isometric bending**: `C = |Σᵢ K'ᵢ xᵢ|` with Bergou's cotangent weights of the rest
//!   shape scaled by the rest axis length; `C = 2 sin(θ/2)` for a hinge bent isometrically by
//!   θ, so the energy matches the dihedral model's for small angles with the same compliance.
//!
//! Gradients, derivations and the treatment of 0, π and degenerate elements are in each
//! module. In short: no `acos` (its derivative is infinite at 0 and π, and it returns NaN
//! when rounding pushes a cosine past ±1); every angle is an `atan2` of unnormalised sine and
//! cosine, accurate over its whole range with gradients of magnitude 1/(edge length or
//! height). A constraint whose gradient is undefined — a zero-length edge, a zero-area
//! triangle, collinear edges for an angle, a flat hinge for the isometric model — is
//! **skipped for that pass**, never divided by zero. Constraints whose *rest* shape is
//! degenerate have no rest angle and are not built (the group reports how many as
//! `dropped`).
//!
//! **Twist without a material frame.** A position-based curve has points only, no frame
//! that turns about its centreline, so it has no torsion of a material to resist. `twist`
//! is the paper's definition: the dihedral angle between the planes `(a, b, c)` and
//! `(b, c, d)`, i.e. the discrete torsion of the *centreline*. It keeps a helix a helix and
//! resists a bent rope swinging its bend out of plane; it does nothing on a straight rope
//! (its planes are undefined: such rest chains are dropped, and chains that are straight in
//! the current state are skipped).
//!
//! ## The XPBD step (Macklin, Müller, Chentanez 2016)
//!
//! ```text
//! Δλ = (−C − α̃λ) / (Σₖ wₖ|∇ₖC|² + α̃),   α̃ = α/h²,   Δxₖ = wₖ ∇ₖC Δλ,   λ ← λ + Δλ
//! ```
//!
//! ([`step::xpbd_correction`]). `α` is the **compliance** (rad/(N·m)): the inverse of the
//! constraint's angular stiffness, so the stored energy is `½ C²/α` (J). `α = 0` is rigid in
//! that mode. **λ is accumulated over the passes of a substep and reset in
//! `begin_substep`**, as in `stretch`: `λ/h²` is the constraint's generalised force (the
//! torque about the hinge, N·m), and the stiffness depends neither on `h` nor on the pass
//! count. Every constraint is invariant under rigid motions, so `Σ∇ₖC = 0` and
//! `Σ xₖ × ∇ₖC = 0`: each step conserves linear and angular momentum, and a particle of
//! inverse mass 0 never moves.
//!
//! **What the compliance means.** For a cloth on a regular grid bent about a grid direction,
//! only the hinges across that direction turn, one per cell, each by `θ = κ·d` for a
//! curvature κ and spacing d: the energy per area is `½ κ²/α`, so `α = 1/D` with `D` the
//! bending rigidity (N·m) — independent of the resolution. For a curve of segment length `l`
//! and flexural rigidity `EI` (N·m²), `α = l/EI`. The presets in [`group::presets`] follow
//! from fabrics' Peirce bending lengths `c` through `D = ρ g c³`.
//!
//! ## Order of the projection
//!
//! Each pass projects the hinges, then the angles, in a fixed order built once: the
//! constraints are coloured greedily and listed colour by colour, so consecutive
//! constraints share no particle (as in `stretch`). Plain sequential Gauss-Seidel,
//! deterministic, no allocation per step; one call per group per pass. A colour of at least
//! 256 constraints is split into contiguous parts over the host's thread team; the bits do not
//! depend on the thread count.
//!
//! ## Cost
//!
//! **Four constraints per instruction** (`lanes`). Within a colour, the dihedral hinges (`bend`
//! on surfaces, and `twist`'s chains, which use the same kernel), the angles (`shear`'s triangle
//! corners, `bend` on curves) and the isometric hinges (`bend_isometric`) run four consecutive
//! constraints in AVX2's 256-bit lanes where the processor has AVX2 (checked once at run time);
//! the constraints left over after the last four of each part, the overflow colour (whose
//! constraints may share particles) and other processors take the one-at-a-time kernel. The
//! arithmetic is [`dihedral::project_dihedral`]'s, [`angle::project_edge_angle`]'s and
//! [`bergou2006_isometric::project_isometric`]'s operation for operation, without fused
//! multiply-adds, and every data-dependent branch (the degenerate and flatness tests, `atan2`'s
//! swap, range reduction, quadrant and sign, the hinge angle's wrap, the XPBD denominator's
//! guards) is computed both ways and selected per lane: every position, multiplier and skip
//! count has the same bits as the one-at-a-time kernel. Unit tests check this on random colours
//! with every degenerate case (for the angles also exactly at, and one ulp either side of, the
//! collinear and the length limits) and the lane `atan2` on 400,000 arguments.
//!
//! On one thread a pass costs about 26–31 ns a dihedral hinge, 20 ns an angle and 14 ns an
//! isometric hinge (`cargo bench -p nucleus-bend --bench bend`); the lanes made each three to
//! four times cheaper (`docs/decisions/simd-lanes.md`).
//!
//! More than four: besides doing each operation for four constraints, the lanes take no branch
//! on the data, and the one-at-a-time `atan2` branches on the quadrant and on the size of the
//! ratio, which a random-looking sequence of constraints mispredicts often.
//!
//! ## Residual and report
//!
//! Residual: `|C|` in rad for every constraint whose angle is defined; for
//! `bend_isometric`, the hinge's actual dihedral angle away from flat (so the two bend
//! models are measured alike). `energy` is `Σ ½ C²/α`. Reported per frame: `skipped`
//! (constraints skipped in the last pass) and `dropped` (left out at build).
//!
//! ## Scheduling defaults
//!
//! Order 1, importance 1: after `stretch` (order 0) in every column, so bending acts on the
//! structure stretch has just restored.

pub mod angle;
pub mod bergou2006_isometric;
pub mod dihedral;
pub mod group;
mod lanes;
pub mod step;
pub mod trig;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod testutil;

pub use group::{presets, BendGroup, BendParams, Kind};

use nucleus_sdk::KindSpec;

fn spec(kind: Kind, doc: &'static str, factory: nucleus_sdk::Factory) -> KindSpec {
    KindSpec {
        name: kind.name(),
        doc,
        default_order: 1,
        default_importance: 1,
        residual_unit: "rad",
        params: BendParams::specs(kind),
        factory,
    }
}

/// The kinds this plugin provides: `bend`, `bend_isometric`, `shear`, `twist`.
pub fn kinds() -> Vec<KindSpec> {
    vec![
        spec(
            Kind::Bend,
            "XPBD bending towards the rest shape: the signed dihedral angle of every pair of \
             surface triangles sharing an edge (paper type 3), and the angle between every \
             two curve edges sharing a vertex (paper type 2). Pre-folded and pre-bent shapes \
             keep their shape; folding through flat never flips.",
            group::build_bend,
        ),
        spec(
            Kind::BendIsometric,
            "Bergou et al. 2006 isometric (quadratic) bending on every pair of surface \
             triangles: about half the cost of `bend` per hinge (no trigonometry), for nearly \
             flat cloth with a flat rest shape; same compliance meaning as `bend` for small angles.",
            group::build_isometric,
        ),
        spec(
            Kind::Shear,
            "XPBD shear: the angle at every corner of every surface triangle (paper type 2), \
             towards its rest value.",
            group::build_shear,
        ),
        spec(
            Kind::Twist,
            "XPBD twist for curves: the dihedral angle about the middle edge of every three \
             consecutive curve edges (paper type 3), the discrete torsion of the centreline \
             (curves have no material frame). Keeps helices coiled; no effect on straight \
             rest shapes.",
            group::build_twist,
        ),
    ]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: "bend",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
