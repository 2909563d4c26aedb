//! The `stretch_newton` kind: every edge of the target objects as a stiff spring, solved
//! **globally** — one Newton step on the substep's implicit-Euler problem per pass, its linear
//! system solved by conjugate gradients preconditioned by a multigrid V-cycle whose coarse
//! particles turn as well as move ([`crate::multigrid`]). The paper's linearised alternative to Gauss-Seidel (Goldenthal et
//! al. 2007 solve the same constraints' linearisation globally), for hard cloth where edge
//! passes need hundreds of substeps.
//!
//! ## The problem a pass solves
//!
//! With the positions `x̃` at the start of the substep's passes (the core's prediction), the
//! substep `h`, the masses `mᵢ` of the group's free particles and each edge's spring
//! `k = 1/α` (`α`: `compliance` when stretched, `compression_compliance` when compressed, m/N):
//!
//! ```text
//! Φ(x) = Σᵢ mᵢ |xᵢ − x̃ᵢ|² / (2h²) + Σₑ k (lₑ − Lₑ)² / 2
//! ```
//!
//! whose minimiser is the implicit-Euler substep of the springs (alone, it is exact: the
//! stationarity condition `M(x − x̃)/h² = −∇E` is the backward-Euler step). A pass is one
//! Newton step on `Φ` from the current positions:
//!
//! ```text
//! H s = −∇Φ,   H = M/h² + Σₑ [k̂ n nᵀ + k max(0, 1 − L/l)(I − n nᵀ)]  (edge blocks, ±)
//! ```
//!
//! with `k̂ = max(k_stretch, k_compress)` along the edge: the energy's curvature jumps at the rest
//! length, and a compressed edge modelled by a softer compression spring let the step overshoot
//! into stretch, where the line search stalled and the cloth blew up (stored energy 5e5 J on a
//! 12 × 12 cloth with `compression_compliance = 1e-4`); with the stiffer curvature the step is
//! shorter and safe (a compressed edge then converges linearly, by `1 − k_c/k̂` per pass when
//! alone). The geometric stiffness `(1 − L/l)(I − n nᵀ)` is kept only for a stretched edge
//! (clamped to tension), so `H` is always symmetric positive definite: the mass term alone
//! makes it so. `H s = −∇Φ` is solved approximately, by at most `cg_iterations` of
//! preconditioned conjugate gradients from `s = 0`, stopping once the residual is
//! `cg_tolerance` of the first or of `∇Φ` at the substep's first pass (so that a pass taken
//! once the substep has converged spends no iterations; on the stiff drape that point is not
//! reached, see below), and a backtracking line search halves the step until `Φ`
//! decreases (at most 30 halvings; no decrease, no move). Pins (inverse mass 0 at build time)
//! are not unknowns: they hold the cloth wherever the scene moves them.
//!
//! ## Extra steps where a step was shortened
//!
//! One step length serves the whole cloth, so a step that overshoots in one place (a fold
//! snapping through on the free hem, where three CG iterations leave the direction rough)
//! is halved everywhere, and the frame ends with that place's edges stretched. With
//! `extra_steps = k`, a pass whose step the line search shortened takes another Newton step
//! at once, up to `k` more, and stops at the first whole one; a pass of whole steps costs
//! nothing more. On the 128 × 128 drape (`newton_relaxed`'s setting, gravity 9.81003) one
//! frame's max strain was 12.4 % (the hem at column 22, gone the frame after), which put the
//! run's max over 1 % (1.02 %) with a 2.2 J energy spike; with `extra_steps = 1` five frames of
//! 120 took one extra step and the run held max 0.69 %, rise 0.36 J (README, "Extra steps
//! where the line search shortened one").
//!
//! ## Deep coarse operators kept through a substep
//!
//! Recomputing every level's Galerkin operator at every Newton step was about a quarter of a
//! 128 × 128 drape's frame. With `refresh_depth = d`, a substep's second and later Newton
//! steps recompute only the first `d` coarse levels ([`crate::multigrid::Hierarchy::update_to`]);
//! the deeper ones and the coarsest factor keep those of the latest full update: the
//! substep's first step always updates everything, and so does a step after one the line
//! search shortened (there the Hessian changes fast: without that rule `d = 1` made 0.59 J in
//! the drape's second frame, when the cloth starts to fall). On that drape (`newton_extra`'s
//! setting) `d = 2` held both strain bounds in fifteen runs of fifteen (max 0.58–0.94 %, rise
//! ≤ 0.32 J) with the updates at 4.2–4.6 against 5.7–6.1 ms a frame; `d = 1` went over in two
//! (README, "The deep coarse operators kept through a substep"). Default 64: every level.
//!
//! ## V-cycles that sweep only on the way up
//!
//! With `pre_smoothing = false` each level of the V-cycle skips its forward sweep and the
//! residual after it: it restricts its right-hand side as it is, takes the prolonged coarse
//! correction as its `x` and sweeps backward from there (a V(0,1) cycle,
//! [`crate::multigrid::Hierarchy::set_pre_smoothing`]). A level then reads its matrix about once
//! a cycle instead of twice (the forward sweep over the blocks before each row, the residual
//! over those after it, the backward sweep over all). The cycle is no longer symmetric, so CG
//! takes `β` in the flexible form, `−α (z·A p)/(z·r)_old`, one more dot product an iteration.
//! Run to a tight tolerance it needs about twice the iterations (a folded 33 × 33 cloth's
//! Hessian to 1e-11: 69 against 31), but its first three take off nearly as much (0.19 against
//! 0.15 of the residual), and three are what the drape's Newton steps use: on the 128 × 128
//! drape (`newton_refresh`'s setting, the `newton_post` variant) both strain bounds held in
//! fifteen runs of fifteen (max 0.66–0.93 %, RMS 0.026–0.032 %) in 0.83 of the time at the 10th
//! percentile of frames on 2 threads, with a larger energy rise, 0.58–0.85 J against 0.22–0.32
//! J (a swing between 0.6 and 0.9 s gains it back; none over 1 J; at N = 32 and 64 no larger
//! than the symmetric cycle's). With the sweeps alone (`relaxation = 1`) or four CG iterations
//! it did no better in single runs. Default `true`: the symmetric V(1,1) cycle (README,
//! "V-cycles that sweep only on the way up").

//! ## The preconditioner
//!
//! A multigrid built once from the target objects' edge graph over their free particles, as
//! [`crate::hierarchy`] coarsens it: each level keeps a maximal independent set of the finer
//! level's particles; a dropped particle is interpolated from its kept neighbours weighted by
//! inverse rest length. With `rotations` (the default) every coarse particle carries a
//! translation and a rotation about its *current* position, and a dropped particle moves by
//! its parents' rigid motions, `Σ w (t_c + θ_c × (x_f − x_c))` ([`crate::multigrid::Prolongation::rigid`]):
//! the rigid motions of the current shape, whole or piece by piece, are interpolated exactly,
//! so the coarse levels swing and fold the cloth as it is, not as it was at rest. The lever
//! arms are refitted to the positions at every Newton step. With `plain_levels = K` the first
//! `K` coarse levels translate only and the ones past them turn: on cloth the first coarse
//! level, turning, has as many 3 × 3 blocks as the fine one (two nodes a particle and a wider
//! stencil), so `plain_levels = 1` halves a V-cycle's work while the coarser levels still swing
//! the folded cloth's pieces (the 128 × 128 drape at compliance 1e-6, 1 × 3 × 4 CG: 31 against
//! 58 ms a frame on 2 threads, the same fall and swing within 2 cm, where no turns at all lose
//! the swing: `tests/newton_drape.rs`; two plain levels made 8.7 J of energy at 2 × 2).
//! Without `rotations` the same
//! weights move x, y and z alike (linear interpolation over the rest mesh). The coarse operators
//! are Galerkin products `Pᵀ H P`, recomputed from each step's Hessian through a map built
//! once; the coarsest level (at most about `4 × coarsest` particles) is solved by a dense
//! Cholesky factor. One V-cycle is a forward block Gauss-Seidel sweep, the coarse correction
//! and a backward sweep. Nothing is allocated after the group is built.
//!
//! ## Relaxation
//!
//! With `relaxation = ω` each row of the V-cycle's sweeps moves by ω times its Gauss-Seidel
//! update (forward then backward with one ω in (0, 2): still a symmetric positive definite
//! preconditioner). On the stiff 128 × 128 drape (compliance 1e-6, 1 × 3 after 10 start passes,
//! `plain_levels = 1`; fifteen runs under gravity changed by 1e-8..5e-6 of itself, README,
//! "Under-relaxed sweeps"), ω = 0.7 with 3 CG iterations a step held max ≤ 1 % in all fifteen
//! (0.70–0.90 %) where ω = 1 with 4 missed it in three (0.75–1.15 %), in 0.88–0.91 of the time
//! on 2 threads and 0.90 on one (alternating runs); after the next stop's rounding changes the
//! same setting went over in two runs of fifteen, each a fold snapping on the hem, and with
//! `extra_steps = 1` (below) in none;
//! at N = 32 the same 3 CG iterations make 0.6–1.1 J of energy where 4 make none, so check the
//! energy (`bench/motion.py`) before taking fewer iterations. Default 1: plain Gauss-Seidel.
//!
//! ## When to use it — and what the strain hides
//!
//! For cloth that must hardly stretch. Measured on the peers' drape (README, part 6 of the
//! benchmark; 2 threads), with rotations: two substeps of four Newton steps, each of five CG
//! iterations, move the cloth as plain `stretch` at 320 substeps does (mean height after 0.25 /
//! 0.5 s within a few cm, `bench/motion.py`) with about ten times less strain than plain
//! `stretch` at 320 × 4 in less time (N = 64, 3 CG a step: 54 ms a frame, max 0.056 %, RMS
//! 0.0024 %, against 85 ms, 0.30 % / 0.022 %); at N = 128 it costs 290–430 ms a frame
//! (README, part 6), far beyond the 16 ms target.
//!
//! **Softer springs converge faster, and 1e-6 m/N is still hard** (2026-11-27; README, "Softer
//! springs, cheaper Newton steps"). At the default 1e-8 the coarse space locks (below); at 1e-6
//! a 1 kg drape stretches about 0.1 % at its pins, and on the 128 × 128 drape (2 threads) one
//! substep of 3 Newton steps of 4 CG iterations after 10 start passes holds max 0.59 %, RMS
//! 0.013 % in 63.7 ms a frame with the reference's fall (2 × 2 × 4 in 77–86 ms, damping the
//! swing less), where 1e-8 needs 2 × 3 × 5 after 20 passes, 159 ms, to move right. Prefer the
//! softest compliance whose strain the scene can take.
//!
//! **Cheap settings can give low strain and the wrong motion.** Without rotations, 5 CG
//! iterations a step at 2 × 2 meet both strain bounds on the 128 × 128 drape in 42–49 ms (max
//! 0.61 %, RMS 0.023 %) but the cloth barely falls (mean height −0.09 m after 0.5 s, against
//! −0.49 m): linear interpolation over the rest mesh does not represent the folded cloth's
//! swinging, so truncated CG leaves it out — what the rotations fix (a swing of a folded
//! cloth: 0.8 % error after 5 iterations, 4.8 % without; `multigrid_tests.rs`). And with or
//! without rotations two Newton steps a substep do not converge it from the prediction (N = 64,
//! 2 × 2 with CG to 1e-8: −0.36 m at 0.5 s; four or more steps a substep are right; with
//! rotations at N = 128, 2 × 2 × 5 CG: −0.16 m) unless `start_passes` start them (below).
//! And a substep whose Newton iteration is not converged gains energy with stiff springs (the
//! stress suite, `docs/stress.md`: one pass at compliance 1e-8, +34 %/s of the energy in
//! play), where converged passes never do.
//!
//! The defaults (at most 50 CG iterations, to 1e-6) are the cautious end, not a converged
//! one: on the drape a substep's first Newton step gets to about 1e-4 of its residual in 50
//! iterations and later steps stall at 2e-2–8e-2, the gradient levelling off near 1 % of the
//! substep's first (N = 64, 2 × 4, with or without rotations). The iterations grow with the
//! springs' stiffness — on the first 3 frames at N = 64, mean CG iterations a step to 1e-6:
//! 11 at compliance 1e-5, 30 at 1e-6, 42 at 1e-7, stalled at 1e-8, and a 100 times softer
//! compression changes nothing — the mark of a coarse space that locks: interpolated coarse
//! motions stretch the stiff fine edges, so the nearly inextensible bending the cloth does is
//! left to the smoother. They
//! cost about seven times `scenes/drape_newton.toml`'s 5 iterations a step (N = 64, 2 × 4:
//! 423 against 64 ms a frame) for the same motion. The scene's setting — 2 × 4, 5 CG, rotations
//! — is the one measured to move the cloth right; fewer passes or iterations only with a check
//! of the motion (`bench/motion.py`).
//!
//! ## Start passes
//!
//! With `start_passes = K > 0` each substep first runs `K` Gauss-Seidel passes over the same
//! springs — the `stretch` kind's XPBD pass with this kind's two compliances (so a soft
//! compression keeps the buckling it allows), its colours split over the team — from the
//! prediction, before its first Newton step (`x̃` stays the prediction). The prediction
//! stretches every edge by about `g h²`; the passes take that local strain off for a fraction
//! of a Newton step's cost, and the steps started from there are left the global motion. Two Newton steps a substep then move the drape right for its first 30 frames where,
//! from the prediction, they hold it up (`bench/newton_pcg/primal.py --pbd-start K` shows the
//! same with direct solves; `tests/newton_drape.rs`). Measured (README, part 6; 2 threads, one
//! batch): at N = 128, 2 substeps of 3 Newton steps of 5 CG after 20 passes move the cloth
//! right in 332 ms a frame (max 0.112 %, RMS 0.0020 %, the energy rising by 0.42 J at most),
//! where the cheapest setting without them that makes as little energy, 1 × 8 × 5, takes 395 ms
//! (0.29 J). They do not make an unconverged substep safe: with two Newton steps a substep the
//! drape makes energy late in the run (N = 64, 2 × 2 × 5 after 10 passes: 8.6 J at frame 30),
//! and a 12 × 12 cloth at 2 passes gains 13.7 %/s of its energy with 10 start passes against
//! 1.66 %/s without (the stress suite, `docs/stress.md`); the energy a setting makes is erratic
//! (40 passes instead of 20: 7.6 J). Check a whole run's motion and energy (`bench/motion.py`)
//! before using a cheaper setting. Off by default.
//!
//! It is a penalty method: `compliance` must be positive. Its default, 1e-8 m/N, lets a
//! 1 m, 1 kg cloth hanging from two corners stretch about 1e-5 at the pins. The default order
//! and importance are those of `stretch` (0 and 1): a pass per substep is a Newton step.
//! Other groups (bend, collisions) run between the passes as usual; a pass measures inertia
//! from `x̃`, so it partly undoes what they moved within the substep in proportion to the
//! masses — as a spring force would.
//!
//! ## Residual and stats
//!
//! The residual is the strain `|l − L|/L` of the edges (dimensionless; for a zero rest
//! length, the length itself, m) and the springs' energy `Σ ½ k C²` (J). `report` gives the
//! last Newton step's CG iterations (`cg_iterations`) and residual reduction
//! (`cg_reduction`), the line search's halvings in the frame so far (`halvings`), the extra
//! steps taken in the frame so far (`extra_steps`), the Newton steps in the frame so far whose
//! update kept the deep coarse levels (`partial_updates`, `refresh_depth`) and the hierarchy's
//! levels and operator complexity.

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use serde::Deserialize;

use crate::distance::{EdgeMaterial, MIN_LENGTH};
use crate::group::{edge_residual, Edges, StretchGroup, StretchParams};
use crate::multigrid::{BlockMatrix, CgStats, Hierarchy, Pcg, PARALLEL_MIN_ROWS};
use glam::DMat3;
use nucleus_sdk::team::{span, SharedArray, TeamRef};

/// Unknowns or edges per chunk of the line search's sums of `Φ`, each chunk summed in order and
/// the chunks' sums in order: the same bits whatever the thread count.
pub const CHUNK: usize = 2048;

/// The parameters of the `stretch_newton` kind.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NewtonParams {
    /// Compliance when stretched (m/N); positive.
    pub compliance: f64,
    /// Compliance when compressed (m/N); positive.
    pub compression_compliance: f64,
    /// Rest length as a multiple of the rest shape's edge length.
    pub rest_length_scale: f64,
    /// Most conjugate-gradient iterations per Newton step.
    pub cg_iterations: i64,
    /// CG stops once the residual is this fraction of the initial one.
    pub cg_tolerance: f64,
    /// Coarsening stops once a level would have fewer particles than this.
    pub coarsest: i64,
    /// Whether coarse particles carry rotations as well as translations.
    pub rotations: bool,
    /// With `rotations`, how many coarse levels, finest first, translate only.
    pub plain_levels: i64,
    /// Gauss-Seidel (XPBD) passes over the same springs from the prediction at the start of
    /// each substep, before its first Newton step (0: none).
    pub start_passes: i64,
    /// Relaxation weight of the multigrid's Gauss-Seidel sweeps, in (0, 2).
    pub relaxation: f64,
    /// After a Newton step whose line search shortened it, up to this many more Newton steps
    /// in the same pass (0: none).
    pub extra_steps: i64,
    /// At a substep's later Newton steps, how many coarse levels, finest first, get new
    /// Galerkin operators; the deeper ones keep those of the latest full update (the
    /// substep's first step, or one after a step the line search shortened; 64: all).
    pub refresh_depth: i64,
    /// Whether each level of the V-cycle sweeps before its coarse correction as well as after
    /// it (`false`: after only, a cheaper V(0,1) cycle with flexible CG).
    pub pre_smoothing: bool,
}

impl NewtonParams {
    /// The parameter descriptions.
    pub fn specs() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number("compliance", 1e-8)
                .unit("m/N")
                .doc("compliance of each edge's spring when stretched (inverse stiffness); positive: a penalty method")
                .range(1e-15, 1e6),
            ParamSpec::number("compression_compliance", 1e-8)
                .unit("m/N")
                .doc("compliance when compressed; set it high to let cloth buckle")
                .range(1e-15, 1e6),
            ParamSpec::number("rest_length_scale", 1.0)
                .doc("rest length of each edge as a multiple of its length in the rest shape")
                .range(1e-6, 1e6),
            ParamSpec::integer("cg_iterations", 50)
                .doc("most preconditioned conjugate-gradient iterations per Newton step (one step per pass)")
                .range(1.0, 10000.0),
            ParamSpec::number("cg_tolerance", 1e-6)
                .doc("CG stops early once its residual is this fraction of the initial one, or of the gradient at the substep's first pass")
                .range(0.0, 1.0),
            ParamSpec::integer("coarsest", 16)
                .doc("the multigrid coarsens until a level would have fewer free particles than this; the coarsest level (up to about 4 times as many) is factored densely at every Newton step (at the first of each substep only, if refresh_depth does not reach it)")
                .range(2.0, 256.0),
            ParamSpec::boolean("rotations", true)
                .doc("each coarse particle of the multigrid carries a rotation about its current position as well as a translation, so that the coarse levels move the folded cloth's pieces rigidly (false: translations only, linear interpolation over the rest mesh, which leaves a cloth held up unless CG converges)"),
            ParamSpec::integer("plain_levels", 0)
                .doc("with rotations, the number of coarse levels, finest first, whose particles translate only: 1 halves a V-cycle's work on cloth (the first coarse level, with rotations, has as many 3 x 3 blocks as the fine one) and the coarser levels still turn the folded cloth's pieces")
                .range(0.0, 64.0),
            ParamSpec::integer("start_passes", 0)
                .doc("Gauss-Seidel passes over the same springs (the stretch kind's XPBD pass, with this kind's two compliances) from the prediction at the start of each substep: a start for the Newton steps that has the edges' local strain taken off, so that fewer steps converge")
                .range(0.0, 10000.0),
            ParamSpec::number("relaxation", 1.0)
                .doc("relaxation weight of the V-cycle's block Gauss-Seidel sweeps: each row moves by this times its Gauss-Seidel update (1: plain Gauss-Seidel; below 1 the sweeps damp instead of overshooting; the V-cycle stays symmetric for any weight in (0, 2)). On the stiff 128 x 128 drape, 0.7 with 3 CG iterations a Newton step held both strain bounds in 15 of 15 runs under perturbed gravity, where 1 with 4 missed the max in 3 (after later rounding changes, 13 of 15; with extra_steps = 1, 15 of 15); at N = 32 those 3 CG iterations make about 1 J of energy")
                .range(0.05, 1.95),
            ParamSpec::integer("extra_steps", 0)
                .doc("after a Newton step whose line search had to shorten it (the step overshot somewhere, so the whole cloth moved only part of the way), up to this many more Newton steps in the same pass: a frame where a fold snaps through costs more instead of leaving its edges stretched (0: never)")
                .range(0.0, 16.0),
            ParamSpec::integer("refresh_depth", 64)
                .doc("at a substep's second and later Newton steps, the number of coarse levels, finest first, whose Galerkin operators (and the coarsest level's dense factor, if it is among them) are recomputed for the new Hessian; the deeper levels keep those of the latest full update (a substep's first step, and any step after one the line search shortened, update every level): a coarse correction for a slightly older Hessian that still makes the V-cycle a symmetric positive definite preconditioner (64: every level, always). The stats' partial_updates counts the steps that kept levels")
                .range(0.0, 64.0),
            ParamSpec::boolean("pre_smoothing", true)
                .doc("each level of the V-cycle sweeps forward before its coarse correction as well as backward after it (a symmetric V(1,1) cycle); false: only after it (V(0,1)), which restricts the level's right-hand side as it is and reads each level's matrix about once a cycle instead of twice, with CG's step direction in the flexible form the unsymmetric cycle needs. On the stiff 128 x 128 drape (3 CG iterations a Newton step, relaxation 0.7) false took 0.83 of the time a frame and held both strain bounds in 15 of 15 runs under perturbed gravity, with a larger energy rise (0.58-0.85 J against 0.22-0.32 J)"),
        ]
    }
}

/// Most halvings of the line search before a step is abandoned.
pub const MAX_HALVINGS: u32 = 30;

/// An edge's spring: energy `k C²/2`, the force on its second end `−k C n` (its first end
/// gets the opposite), and the stiffness block `K` (the Hessian's `(b, b)` and `(a, a)`
/// blocks; `−K` off the diagonal): `max(k_stretch, k_compress) n nᵀ` along the edge plus, when
/// stretched, the geometric term `k (1 − L/l)(I − n nᵀ)` (see the module docs). `d = xb − xa`; `None` when the edge has no direction.
#[inline]
pub fn spring(d: DVec3, rest: f64, k_stretch: f64, k_compress: f64) -> Option<(f64, DVec3, DMat3)> {
    let l = d.length();
    if !(l > MIN_LENGTH && l.is_finite()) {
        return None;
    }
    // One division an edge (the assembly's edge loop is a few per cent of a drape's step).
    let inv_l = 1.0 / l;
    let n = d * inv_l;
    let c = l - rest;
    let k = if c >= 0.0 { k_stretch } else { k_compress };
    let across = (1.0 - rest * inv_l).max(0.0) * k;
    // Along the edge, the stiffer of the two springs: the piecewise quadratic energy's curvature
    // jumps at the rest length, and a compressed edge modelled by its soft spring lets the
    // step overshoot into stretch, where the line search then stalls.
    let along = k_stretch.max(k_compress);
    // `along n nᵀ + across (I − n nᵀ)`, as `(along − across) n nᵀ + across I`: exactly
    // symmetric (`nᵢ nⱼ = nⱼ nᵢ`), as the multigrid needs.
    let nn = DMat3::from_cols(n * n.x, n * n.y, n * n.z);
    let stiffness = nn * (along - across) + DMat3::from_diagonal(DVec3::splat(across));
    Some((
        spring_energy(c, k_stretch, k_compress),
        -n * (k * c),
        stiffness,
    ))
}

/// An edge's spring energy `k C²/2` at `C = l − L` (`k` the stretch spring when `C ≥ 0`, else
/// the compression one): [`spring`]'s, the objective's and the assembly's, one expression so
/// that their sums have the same bits.
#[inline]
fn spring_energy(c: f64, k_stretch: f64, k_compress: f64) -> f64 {
    let k = if c >= 0.0 { k_stretch } else { k_compress };
    0.5 * k * c * c
}

/// The `stretch_newton` group. Unknowns are the free particles of the target objects, in the
/// order of the objects and of their particles.
pub struct NewtonGroup {
    /// Global index of each unknown.
    dof: Vec<u32>,
    /// Edges (global particle indices) with at least one free end, and their rest lengths.
    edges: Vec<[u32; 2]>,
    rest: Vec<f64>,
    /// Per edge, the unknown of each end (`u32::MAX` for a pin).
    ends: Vec<[u32; 2]>,
    /// Per unknown `u`, `incident[incident_start[u]..incident_start[u + 1]]`: its edges, each
    /// with the slot of the block `(u, other end)` in the fine matrix (`u32::MAX` if the
    /// other end is a pin) and whether `u` is the edge's first end.
    incident_start: Vec<u32>,
    incident: Vec<(u32, u32, bool)>,
    /// Per edge, where its stiffness block goes: for an edge between two unknowns, the fine
    /// matrix's slots `(a, b)` and `(b, a)`, which it alone writes (`−K`); for an edge to a pin,
    /// `[u32::MAX, k]` with `k` its index in `pin_stiffness`.
    edge_slots: Vec<[u32; 2]>,
    /// Per edge, at the current positions: the force on its second end (zero for an edge
    /// without direction); per edge to a pin, its stiffness block `K`, which only the diagonal
    /// takes.
    edge_force: Vec<DVec3>,
    pin_stiffness: Vec<DMat3>,
    /// The objective's chunk sums.
    partial: Vec<f64>,
    /// The two compliances (for the residual), and the springs `k = 1/α` they give.
    material: EdgeMaterial,
    k_stretch: f64,
    k_compress: f64,
    cg_iterations: u32,
    cg_tolerance: f64,
    /// `x̃` of each unknown, set in `begin_substep`.
    target: Vec<DVec3>,
    /// `−∇Φ` at the positions of the last assembly: the Newton step's right-hand side.
    gradient: Vec<DVec3>,
    step: Vec<DVec3>,
    hierarchy: Hierarchy,
    pcg: Pcg,
    max_index: Option<u32>,
    last: CgStats,
    /// The norm of `∇Φ` at the substep's first pass (NaN before it): CG stops once a later
    /// step's residual is `cg_tolerance` of it.
    substep_gradient: f64,
    /// This frame's line-search halvings and extra Newton steps taken (the report's).
    halvings: u32,
    extra_taken: u32,
    /// Newton steps in the frame so far whose update kept the deep coarse levels.
    partial_updates: u32,
    extra_steps: u32,
    /// `refresh_depth`, and whether the next Newton step updates every level regardless: the
    /// substep's first, or one after a step the line search shortened.
    refresh_depth: usize,
    refresh_all: bool,
    last_frame: u64,
    /// The same edges and springs as a `stretch` group, for the `start_passes` (`None`
    /// without).
    start: Option<(StretchGroup, u32)>,
}

impl NewtonGroup {
    /// Builds the unknowns, the edges, the fine matrix's pattern and the hierarchy.
    pub fn new(p: &NewtonParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        let rest_x = scene.rest_positions();
        let w = scene.inv_mass.as_slice();
        let mut unknown = vec![u32::MAX; rest_x.len().min(w.len())];
        let mut dof = Vec::new();
        let mut max_index = None;
        for (_, object) in scene.unique_targets()? {
            let range = object.particles();
            for i in range.clone() {
                if w[i] > 0.0 && unknown[i] == u32::MAX {
                    unknown[i] = dof.len() as u32;
                    dof.push(i as u32);
                }
            }
            if !range.is_empty() {
                max_index = max_index.max(Some(range.end as u32 - 1));
            }
        }
        // Checked as `stretch` checks them; an edge between two pins is dropped.
        let all = Edges::scaled(p.rest_length_scale, scene)?;
        let start = (p.start_passes > 0).then(|| {
            // XPBD on the same springs: stiff in stretch, and as soft in compression as the
            // kind, so that the start does not undo the buckling a soft compression allows.
            let springs = StretchParams {
                compliance: p.compliance,
                compression_compliance: p.compression_compliance,
                ..StretchParams::default()
            };
            let group = StretchGroup::from_edges(&springs, all.clone());
            (group, p.start_passes as u32)
        });
        let Edges {
            ids: edges, rest, ..
        } = all;
        let ends: Vec<[u32; 2]> = edges
            .iter()
            .map(|&[i, j]| [unknown[i as usize], unknown[j as usize]])
            .collect();
        let free_pairs: Vec<(u32, u32)> = ends
            .iter()
            .filter(|e| e[0] != u32::MAX && e[1] != u32::MAX)
            .map(|e| (e[0], e[1]))
            .collect();
        let fine = BlockMatrix::with_pattern(dof.len(), free_pairs.iter().copied());
        let mut lists: Vec<Vec<(u32, u32, bool)>> = vec![Vec::new(); dof.len()];
        for (e, &[a, b]) in ends.iter().enumerate() {
            let slot = |u: u32, v: u32| {
                if v == u32::MAX {
                    u32::MAX
                } else {
                    fine.slot(u, v).map_or(u32::MAX, |s| s as u32)
                }
            };
            if a != u32::MAX {
                lists[a as usize].push((e as u32, slot(a, b), true));
            }
            if b != u32::MAX {
                lists[b as usize].push((e as u32, slot(b, a), false));
            }
        }
        // Each free pair's two off-diagonal slots belong to its edge alone (the assembly's
        // edge loop writes them in parallel), so two edges may not join one pair (the core's
        // complexes never list one twice); an edge to a pin gets a stiffness of its own.
        let mut pairs: Vec<[u32; 2]> = edges.iter().map(|&[i, j]| [i.min(j), i.max(j)]).collect();
        pairs.sort_unstable();
        if let Some(w) = pairs.windows(2).find(|w| w[0] == w[1]) {
            let [i, j] = w[0];
            let targets = scene.unique_targets()?;
            let object = targets
                .iter()
                .find(|(_, o)| o.particles().contains(&(i as usize)))
                .map_or("", |(_, o)| o.name.as_str());
            return Err(PluginError::bad_object(
                object,
                format!("particles {i} and {j} are joined by two edges"),
            ));
        }
        let mut pins = 0u32;
        let edge_slots: Vec<[u32; 2]> = ends
            .iter()
            .map(|&[a, b]| {
                if a == u32::MAX || b == u32::MAX {
                    pins += 1;
                    [u32::MAX, pins - 1]
                } else {
                    [(a, b), (b, a)].map(|(u, v)| {
                        fine.slot(u, v).expect("the pattern holds every free pair") as u32
                    })
                }
            })
            .collect();
        let mut incident_start = vec![0u32];
        let mut incident = Vec::new();
        for list in lists {
            incident.extend(list);
            incident_start.push(incident.len() as u32);
        }
        // The free particles' edge graph, coarsened as the hierarchy kind does.
        let mut graph: Vec<Vec<(u32, f64)>> = vec![Vec::new(); dof.len()];
        for &(a, b) in &free_pairs {
            let len = (rest_x[dof[b as usize] as usize] - rest_x[dof[a as usize] as usize])
                .length()
                .max(MIN_LENGTH);
            graph[a as usize].push((b, len));
            graph[b as usize].push((a, len));
        }
        let coarsest = p.coarsest.max(2) as usize;
        let c = crate::hierarchy::coarsen(&graph, &[], 64, coarsest);
        let prolongations =
            crate::multigrid::prolongations(&dof, &c, p.rotations, p.plain_levels as usize);
        let n = dof.len();
        Ok(NewtonGroup {
            target: vec![DVec3::ZERO; n],
            gradient: vec![DVec3::ZERO; n],
            step: vec![DVec3::ZERO; n],
            hierarchy: {
                let mut hierarchy = Hierarchy::new(fine, prolongations);
                hierarchy.set_relaxation(p.relaxation);
                hierarchy.set_pre_smoothing(p.pre_smoothing);
                hierarchy
            },
            pcg: Pcg::new(n),
            dof,
            edges,
            rest,
            edge_force: vec![DVec3::ZERO; ends.len()],
            pin_stiffness: vec![DMat3::ZERO; pins as usize],
            edge_slots,
            partial: vec![0.0; n.div_ceil(CHUNK) + ends.len().div_ceil(CHUNK)],
            ends,
            incident_start,
            incident,
            material: EdgeMaterial {
                compliance: p.compliance,
                compression_compliance: p.compression_compliance,
                damping: 0.0,
            },
            k_stretch: 1.0 / p.compliance,
            k_compress: 1.0 / p.compression_compliance,
            cg_iterations: p.cg_iterations.max(1) as u32,
            cg_tolerance: p.cg_tolerance,
            max_index,
            last: CgStats::default(),
            substep_gradient: f64::NAN,
            halvings: 0,
            extra_taken: 0,
            partial_updates: 0,
            extra_steps: p.extra_steps as u32,
            refresh_depth: p.refresh_depth as usize,
            refresh_all: true,
            last_frame: u64::MAX,
            start,
        })
    }

    /// `Φ` at the positions `x` moved by `t · step` at the unknowns. The sum is taken in
    /// chunks of [`CHUNK`] unknowns or edges, each summed in order (the chunks split over the
    /// team), then the chunks' sums in order: the same bits whatever the thread count.
    fn objective(
        &self,
        team: TeamRef<'_>,
        x: &[DVec3],
        inv_mass: &[f64],
        h: f64,
        t: f64,
        partial: &mut [f64],
    ) -> f64 {
        let at = |i: u32, u: u32| {
            if u == u32::MAX {
                x[i as usize]
            } else {
                x[i as usize] + self.step[u as usize] * t
            }
        };
        let inertia_chunks = self.dof.len().div_ceil(CHUNK);
        let chunks = inertia_chunks + self.edges.len().div_ceil(CHUNK);
        assert!(partial.len() >= chunks);
        let scale = 1.0 / (2.0 * h * h);
        let chunk_sum = |c: usize| -> f64 {
            let mut sum = 0.0;
            if c < inertia_chunks {
                let range = c * CHUNK..((c + 1) * CHUNK).min(self.dof.len());
                for u in range {
                    let i = self.dof[u];
                    let m = mass(inv_mass[i as usize]) * scale;
                    sum += m * (at(i, u as u32) - self.target[u]).length_squared();
                }
            } else {
                let c = c - inertia_chunks;
                let range = c * CHUNK..((c + 1) * CHUNK).min(self.edges.len());
                for e in range {
                    let ([i, j], [a, b]) = (self.edges[e], self.ends[e]);
                    let c = (at(j, b) - at(i, a)).length() - self.rest[e];
                    sum += spring_energy(c, self.k_stretch, self.k_compress);
                }
            }
            sum
        };
        let sums = SharedArray::new(partial);
        let parts = team.parts();
        let run = |part: usize| {
            for c in span(part, parts, chunks) {
                // SAFETY: `c < chunks <= partial.len()` (asserted); each chunk is one part's.
                unsafe { *sums.at(c) = chunk_sum(c) };
            }
        };
        if parts > 1 && self.dof.len() + self.edges.len() >= 2 * PARALLEL_MIN_ROWS {
            team.run(&run);
        } else {
            (0..parts).for_each(run);
        }
        partial[..chunks].iter().sum()
    }

    /// Assembles `−∇Φ` (into `gradient`, the Newton step's right-hand side) and `H` (into the
    /// hierarchy's fine matrix): each
    /// edge's force and stiffness, its `−K` written straight into its two off-diagonal slots
    /// (each slot is one edge's), then each unknown's row — its diagonal block from its own
    /// row's slots and its gradient from its incident edges' forces. Both loops are split over
    /// the team by chunks of [`CHUNK`] edges or unknowns (every value computed by one part, in
    /// a fixed order). Returns `Φ` at `x`, summed as [`objective`](Self::objective) sums it at
    /// `t = 0` — the same bits for a finite step — from the chunks' sums, which the same loops
    /// take on the way.
    fn assemble(&mut self, team: TeamRef<'_>, x: &[DVec3], inv_mass: &[f64], h: f64) -> f64 {
        let (ks, kc) = (self.k_stretch, self.k_compress);
        let (edges, rest, edge_slots) = (&self.edges, &self.rest, &self.edge_slots);
        let inertia_chunks = self.dof.len().div_ceil(CHUNK);
        let chunks = inertia_chunks + edges.len().div_ceil(CHUNK);
        let fine = self.hierarchy.fine_mut();
        assert!(self.edge_force.len() == edges.len() && edge_slots.len() == edges.len());
        assert!(self.partial.len() >= chunks);
        let (vals_len, pins) = (fine.val.len(), self.pin_stiffness.len());
        let forces = SharedArray::new(&mut self.edge_force);
        let pin_stiffness = SharedArray::new(&mut self.pin_stiffness);
        let vals = SharedArray::new(&mut fine.val);
        let sums = SharedArray::new(&mut self.partial);
        // Split from `PARALLEL_MIN_ROWS` edges or unknowns on, as the multigrid's loops.
        let split = |items: usize| {
            if items >= PARALLEL_MIN_ROWS {
                1
            } else {
                usize::MAX
            }
        };
        team.for_ranges(chunks - inertia_chunks, split(edges.len()), &|range| {
            for c in range {
                let mut energy = 0.0;
                for e in c * CHUNK..((c + 1) * CHUNK).min(edges.len()) {
                    let [i, j] = edges[e];
                    let d = x[j as usize] - x[i as usize];
                    // The spring's energy is `objective`'s expression; an edge without
                    // direction has no force or stiffness but still its energy there.
                    let (edge_energy, f, k) = spring(d, rest[e], ks, kc).unwrap_or_else(|| {
                        let c = d.length() - rest[e];
                        (spring_energy(c, ks, kc), DVec3::ZERO, DMat3::ZERO)
                    });
                    energy += edge_energy;
                    let [ab, ba] = edge_slots[e];
                    // Checked here, edge by edge, rather than in a serial pass over every edge
                    // at each step.
                    assert!(if ab == u32::MAX {
                        (ba as usize) < pins
                    } else {
                        (ab.max(ba) as usize) < vals_len
                    });
                    // SAFETY: every index is in bounds (`e < edges.len()`, the forces' length
                    // too, asserted above; the edge's slots or pin index, just asserted); each
                    // part writes its own edges, and each edge's slots (or pin stiffness) are
                    // its alone (checked when the group was built).
                    unsafe {
                        *forces.at(e) = f;
                        if ab == u32::MAX {
                            *pin_stiffness.at(ba as usize) = k;
                        } else {
                            // `0 − K`: the bits of the sum the rows took before (a zero stays +0).
                            *vals.at(ab as usize) = DMat3::ZERO - k;
                            *vals.at(ba as usize) = DMat3::ZERO - k;
                        }
                    }
                }
                // SAFETY: `inertia_chunks + c < chunks <= partial.len()` (asserted); each
                // chunk is one part's.
                unsafe { *sums.at(inertia_chunks + c) = energy };
            }
        });
        let inv_h2 = 1.0 / (h * h);
        let scale = 1.0 / (2.0 * h * h);
        let (forces, pin_stiffness) = (&self.edge_force, &self.pin_stiffness);
        let (dof, target) = (&self.dof, &self.target);
        let (start, incident) = (&self.incident_start, &self.incident);
        assert!(self.gradient.len() == dof.len() && fine.n() == dof.len());
        let gradient = SharedArray::new(&mut self.gradient);
        let diag = &fine.diag;
        let vals = SharedArray::new(&mut fine.val);
        team.for_ranges(inertia_chunks, split(dof.len()), &|range| {
            for c in range {
                let mut inertia = 0.0;
                for u in c * CHUNK..((c + 1) * CHUNK).min(dof.len()) {
                    let i = dof[u] as usize;
                    let (mass_i, moved) = (mass(inv_mass[i]), x[i] - target[u]);
                    inertia += mass_i * scale * moved.length_squared();
                    let m = mass_i * inv_h2;
                    let mut g = moved * m;
                    let mut d = DMat3::from_diagonal(DVec3::splat(m));
                    // SAFETY (every access below): the slots of row `u` are in bounds (the
                    // pattern was built with these rows and slots, and every edge's slots and
                    // pin index were asserted above); the edge loop has joined, this part alone
                    // writes row `u`'s diagonal, `gradient[u]` and the chunk's sum, and
                    // `c < chunks <= partial.len()` (asserted).
                    for &(e, slot, first) in &incident[start[u] as usize..start[u + 1] as usize] {
                        let f = forces[e as usize];
                        g += if first { f } else { -f };
                        d += if slot == u32::MAX {
                            pin_stiffness[edge_slots[e as usize][1] as usize]
                        } else {
                            -unsafe { *vals.at(slot as usize) }
                        };
                    }
                    unsafe {
                        *vals.at(diag[u] as usize) = d;
                        *gradient.at(u) = -g;
                    }
                }
                unsafe { *sums.at(c) = inertia };
            }
        });
        self.partial[..chunks].iter().sum()
    }

    /// One Newton step on `Φ`: assembly, Galerkin update, preconditioned CG, line search.
    /// Returns the line search's halvings (over [`MAX_HALVINGS`]: no move).
    fn newton_step(&mut self, ctx: &mut SolveContext<'_>, h: f64) -> Result<u32, PluginError> {
        let team = ctx.team;
        let p = ctx.particles();
        let f0 = self.assemble(team, p.x, p.inv_mass, h);
        self.hierarchy.refit(p.x);
        // Deep levels are kept only at a later step, and only if there are levels past the depth.
        let keep =
            !self.refresh_all && self.refresh_depth.saturating_add(1) < self.hierarchy.depth();
        self.refresh_all = false;
        self.partial_updates += u32::from(keep);
        let depth = if keep { self.refresh_depth } else { usize::MAX };
        if !self.hierarchy.update_to(team, depth) {
            return Err(PluginError::new(
                PluginError::FAILED,
                "",
                "stretch_newton: the Hessian is not positive definite (non-finite positions or masses?)",
            ));
        }
        if self.substep_gradient.is_nan() {
            let squared: f64 = self.gradient.iter().map(|g| g.length_squared()).sum();
            self.substep_gradient = squared.sqrt();
        }
        let mut step = std::mem::take(&mut self.step);
        self.last = self.pcg.solve(
            team,
            &mut self.hierarchy,
            &self.gradient,
            &mut step,
            self.cg_iterations,
            self.cg_tolerance,
            self.cg_tolerance * self.substep_gradient,
        );
        self.step = step;
        let mut partial = std::mem::take(&mut self.partial);
        let mut t = 1.0;
        let mut halvings = 0;
        // Halves while Φ does not decrease, or is NaN (a step through coincident particles).
        loop {
            if self.objective(team, p.x, p.inv_mass, h, t, &mut partial) <= f0 {
                break;
            }
            halvings += 1;
            if halvings > MAX_HALVINGS {
                t = 0.0;
                break;
            }
            t *= 0.5;
        }
        self.partial = partial;
        self.halvings += halvings.min(MAX_HALVINGS);
        // A shortened step: the Hessian is changing fast here, so the next step updates every
        // level (kept deep operators made 0.59 J at the drape's second frame otherwise).
        if halvings > 0 {
            self.refresh_all = true;
        }
        if t > 0.0 {
            let (dof, step) = (&self.dof, &self.step);
            assert!(dof.len() == step.len());
            let particles = p.x.len();
            let x = SharedArray::new(p.x);
            team.for_ranges(dof.len(), PARALLEL_MIN_ROWS, &|range| {
                for u in range {
                    let i = dof[u] as usize;
                    assert!(i < particles);
                    // SAFETY: in bounds (asserted); each particle is one unknown's (`dof` lists
                    // distinct particles) and each unknown one part's.
                    unsafe { *x.at(i) += step[u] * t };
                }
            });
        }
        Ok(halvings)
    }
}

/// The mass of a particle of inverse mass `w`; a particle pinned since the group was built
/// counts as very heavy, so the step leaves it (almost) in place.
#[inline]
fn mass(w: f64) -> f64 {
    if w > 0.0 {
        1.0 / w
    } else {
        1e30
    }
}

impl ConstraintGroup for NewtonGroup {
    fn stages(&self) -> Stages {
        Stages::PROJECT | Stages::BEGIN_SUBSTEP | Stages::REPORT
    }

    fn len(&self) -> usize {
        if self.dof.is_empty() {
            0
        } else {
            self.edges.len()
        }
    }

    /// Records `x̃`, the positions the substep's inertia is measured from.
    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        ctx.check_holds(self.max_index)?;
        let x = ctx.positions();
        for (t, &i) in self.target.iter_mut().zip(&self.dof) {
            *t = x[i as usize];
        }
        self.substep_gradient = f64::NAN;
        self.refresh_all = true;
        if let Some((group, passes)) = self.start.as_mut() {
            group.begin_substep(ctx)?;
            for _ in 0..*passes {
                group.project(ctx)?;
            }
        }
        Ok(())
    }

    /// One Newton step on `Φ` (`NewtonGroup::newton_step`), and up to `extra_steps` more
    /// while the line search shortens them.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        ctx.check_holds(self.max_index)?;
        let h = ctx.substep_length()?;
        if ctx.frame != self.last_frame {
            self.last_frame = ctx.frame;
            self.halvings = 0;
            self.extra_taken = 0;
            self.partial_updates = 0;
        }
        let mut extra = 0;
        loop {
            let halvings = self.newton_step(ctx, h)?;
            // A full step, or none at all (another would be the same): done.
            if halvings == 0 || halvings > MAX_HALVINGS || extra == self.extra_steps {
                return Ok(());
            }
            extra += 1;
            self.extra_taken += 1;
        }
    }

    /// Strain `|l − L|/L` of the edges (the length itself for a zero rest length) and the
    /// springs' energy.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        edge_residual(&self.edges, &self.rest, &self.material, ctx.positions())
    }

    fn report(&self, _ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        out.push(("cg_iterations".into(), self.last.iterations as f64));
        out.push(("cg_reduction".into(), self.last.reduction));
        out.push(("halvings".into(), self.halvings as f64));
        out.push(("extra_steps".into(), self.extra_taken as f64));
        out.push(("partial_updates".into(), self.partial_updates as f64));
        out.push(("levels".into(), self.hierarchy.depth() as f64));
        out.push((
            "operator_complexity".into(),
            self.hierarchy.operator_complexity(),
        ));
    }
}

/// The factory of the `stretch_newton` kind.
pub fn build(json: &str, scene: &SceneView<'_>) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let p: NewtonParams = params::parse(json)?;
    Ok(Box::new(NewtonGroup::new(&p, scene)?))
}
#[cfg(test)]
#[path = "newton_tests.rs"]
mod tests;
