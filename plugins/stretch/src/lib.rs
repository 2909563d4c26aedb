//! # `stretch` — the paper's type-1 constraint
//!
//! One kind, `stretch`: an XPBD distance constraint on **every edge** of the objects the group
//! is applied to — curve edges, and the edges of triangles and tetrahedra alike (the scene
//! view lists every 1-simplex). Stretch and compression are resisted separately, as in Maya's
//! nCloth: cloth buckles rather than compresses.
//!
//! Two more kinds help hard stretch converge, each only where a scene asks for it: `tether`
//! ([`tether`]: long-range attachments to the pins, Kim et al. 2012) and `stretch_hierarchy`
//! ([`hierarchy`]: hierarchical position-based dynamics, Müller 2008), and `stretch` itself
//! can accelerate its passes ([Chebyshev](#chebyshev-acceleration-optional)). A fourth kind,
//! `stretch_newton` ([`newton`], its linear algebra in [`multigrid`]), replaces `stretch`: every
//! edge a stiff spring, a global Newton step per pass solved by conjugate gradients
//! preconditioned by a multigrid whose coarse particles turn as well as move. Their costs
//! and what they buy on the peers' drape are measured in `docs/peers.md`, below and in the
//! README.
//!
//! ## The constraint
//!
//! For an edge `(i, j)` with rest length `l` (the scene's rest-shape length times
//! `rest_length_scale`):
//!
//! ```text
//! C(x)   = |xj − xi| − l                    (m; > 0 stretched, < 0 compressed)
//! ∇xj C  = n = (xj − xi) / |xj − xi|,   ∇xi C = −n,   so Σ wₖ|∇ₖC|² = wi + wj
//! ```
//!
//! `n` is undefined when the particles coincide: an edge shorter than
//! [`distance::MIN_LENGTH`] (1e-12 m) is skipped for that pass, never divided by zero. A zero
//! rest length is allowed and pulls the two particles together.
//!
//! ## The XPBD step (Macklin, Müller, Chentanez 2016)
//!
//! With the substep `h`, the compliance `α` chosen by the sign of `C` (`compliance` when
//! `C ≥ 0`, `compression_compliance` when `C < 0`; both in m/N) and `α̃ = α/h²`:
//!
//! ```text
//! Δλ = (−C − α̃λ) / ((wi + wj)(n·d) + α̃)
//! Δxi = −wi d Δλ,   Δxj = +wj d Δλ,   λ ← λ + Δλ
//! ```
//!
//! computed by [`nucleus_sdk::xpbd::delta_lambda`], where `d` is the edge's direction at the
//! start of the substep (SHAKE; `d = n` if the edge turned by more than ~26° within the substep or had no length).
//! `α = 0` is a hard constraint. Both corrections are weighted by the inverse masses and lie
//! along the start direction, so with `v = (x − x0)/h` every step conserves linear *and*
//! angular momentum exactly (a correction along the current `n` changes `L` by
//! `Δλ (x0j − x0i) × n / h`), and a hard link integrates its motion to second order without
//! draining energy (the pendulum test: −0.03% period error at one substep per frame, against
//! −13% for corrections along `n`). A particle with inverse mass 0 never moves. The two compliances make the force a continuous,
//! monotone, piecewise-linear function of `C`, so the iteration stays well posed when an edge
//! crosses its rest length between passes.
//!
//! **Units.** `λ` is in N·s²: `λ/h²` is the edge's force over the substep (N, negative in
//! tension) and `λ/h` its impulse (N·s).
//!
//! **λ is accumulated over the passes of a substep and reset to 0 in `begin_substep`.** Each
//! substep solves the implicit equations `M(x − x̃) = ∇Cᵀλ`, `C(x) + α̃λ = 0` by Newton steps,
//! and `λ` is the *total* multiplier applied so far in the substep: at its start the positions
//! are the prediction `x̃`, to which no constraint force has been applied, so `λ = 0`. Each
//! pass adds an increment. Carrying `λ` into the next substep would count a force that the
//! new prediction never received; resetting it every *pass* instead (plain PBD) would apply
//! the full spring force once per pass, so an edge would stiffen with the pass count. With
//! the accumulation, an isolated compliant edge is unchanged by extra passes, and the
//! stiffness depends neither on `h` nor on the group's importance.
//!
//! A **hard** material (both compliances 0) keeps no `λ`: its step `Δλ = −C/Σw|∇C|²` never
//! reads it, so the group stores none, resets none, and has no `begin_substep` stage (unless
//! Chebyshev acceleration is on). [`StretchGroup::lambdas`] is then empty.
//!
//! ## Damping (optional)
//!
//! `damping` is the coefficient `c` (N·s/m) of a linear damper in parallel with each edge's
//! spring `k = 1/α`: the edge force becomes `−k·C − c·dC/dt`, which resists changes of the
//! edge's length only (no drag on rigid motion). Macklin et al. 2016 (§3.5, eq. 26) solve it
//! in the same step with `γ = α·c/h`, `dC/dt ≈ ∇C·(x − x0)/h`:
//!
//! ```text
//! Δλ = (−C − α̃λ − γ ∇C·(x − x0)) / ((1 + γ)(wi + wj) + α̃)
//! ```
//!
//! For one pass on an isolated edge this is exactly the backward-Euler step of the spring and
//! damper (a unit test checks it). A hard edge (`α = 0`) has no spring to damp: `γ = 0`.
//!
//! ## Order of the projection
//!
//! `project` is plain sequential Gauss-Seidel over the batch in its index order: deterministic,
//! and every edge sees the corrections of the edges before it. The batch is built in a fixed
//! order in which consecutive edges share no particle: the edges are coloured greedily and
//! listed colour by colour (each colour in the scene's order). Edges of one colour are
//! independent, so their relative order does not change the result, and the processor can
//! overlap the square roots and divisions of consecutive edges instead of waiting for each
//! position write. On a 128 × 128 cloth this halves the time of a pass; the residual after a
//! fixed number of passes is a little higher than in the scene's order in some scenes, and
//! lower at equal time. The colours are also the independent sets the threaded projection splits
//! over the host's thread team (`ctx.team`; bit-identical for any thread count; see
//! [`nucleus_sdk::team`]): one team for the core and every group of every plugin.
//!
//! ## Cost
//!
//! One pass over the 48,641 edges of a 128 × 128 cloth, through the plugin's ABI exactly as
//! the host calls it, on a thread team of `RAYON_NUM_THREADS` lent as the host lends its own
//! (`cargo bench -p nucleus-stretch`; 2-core Xeon VM, 2026-11-23):
//!
//! | material | 1 thread | per edge | 2 threads |
//! |---|---:|---:|---:|
//! | hard (the default) | 410 µs | 8.4 ns | 219 µs |
//! | compliant and damped | 888 µs | 18.3 ns | 460 µs |
//!
//! A pass is bound by the chain of dependent operations of an edge, not by memory: within a
//! colour the edges are independent, and the processor overlaps as many as its reorder window
//! holds. So [`distance::project_distance`] is computed with unnormalised vectors — one square
//! root and one division between loading an edge and storing its correction — and a hard
//! material takes [`distance::project_distance_hard`], without the compliance terms. The form
//! with unit vectors (two square roots, a dot product and a division between them, and three
//! divisions per normalisation) took 749 µs for the hard pass on one thread.
//!
//! The hard kernel neither reads nor writes a multiplier (431 µs when it still accumulated
//! one that nothing read). One square root per edge instead of two (the start-direction test
//! on squares) was measured and not kept: 445 µs against 436, no gain.
//!
//! **Four edges per instruction** (`lanes`, since 2026-11-24). Within a colour, both kernels
//! run four consecutive edges in AVX2's 256-bit lanes where the processor has AVX2 (checked
//! once at run time; the edges left over, and other processors, take the one-edge kernels:
//! `cargo clippy --workspace --all-targets --target aarch64-unknown-linux-gnu -- -D warnings`
//! is clean, checked 2026-11-24; the tests have run on x86_64 only).
//! The arithmetic is the one-edge kernels', operation for operation and without fused
//! multiply-adds, so every position and multiplier has the same bits. Unit tests check this
//! on random colours with every degenerate case, and scenes give byte-identical frames. Same
//! benchmark, the build before and after run alternately three times in one session, one
//! thread, on a machine then about 1.5× slower than the table above:
//!
//! | material | one edge at a time | four lanes | ratio |
//! |---|---:|---:|---:|
//! | hard | 589–681 µs | 396–437 µs | 1.5× |
//! | compliant and damped | 1,093–1,317 µs | 514–574 µs | 2.2× |
//!
//! The lanes load each particle's `x, y` as one 16-byte load (two unpacks interleave four
//! particles) and `z` alone, and store the same way. An earlier form, measured against 436 µs
//! and not kept, gathered a colour 32 edges at a time into one array per component first: it
//! took 547–600 µs, the gather and scatter costing more than the vector arithmetic saved. The
//! lane code also has to be inlined into its loop: as a function (a `target_feature` function
//! cannot be `inline(always)`) it returned its lanes through the stack and gained nothing.
//!
//! In scenes, 2 threads, A/B in one session: the 128 × 128 drape at 40 × 1 steps in 20.6 ms a
//! frame against 26.5; with `tether` at 640 × 1 (both of the benchmark issue's strain bounds)
//! 327 against 382 ms; `scenes/sail.toml` (soft in compression) 3.0 against 3.8 ms.
//!
//! **Tethers four at a time** (since 2026-11-27). A `tether` group keeps its batch in rounds
//! (each particle's first tether, then each one's second, …), so a round moves distinct
//! particles and four of its tethers share AVX2's lanes, each particle's tethers still in its
//! own order: the same bits as one at a time particle after particle (unit tests, and the
//! drape's frames). Most tethers of a hanging cloth are slack, and four are dismissed by one
//! comparison. One pass over the 128 × 128 drape's 32,768 tethers, one thread
//! (`cargo bench -p nucleus-stretch -- project_tether`, the build before as criterion's
//! baseline, AMD EPYC VM): 48.8 µs against 97.5 µs. In the drape with `tether` at 640 × 1 on
//! one thread the tether pass fell from 15.5 % to 9 % of the CPU samples (`perf`, 6 frames: 7,473
//! samples against 8,660); whole frames on 2 threads moved within the machine's noise.
//!
//! **The multigrid's blocks in the lanes** (`block_lanes`, since 2026-11-27). `stretch_newton`'s
//! V-cycle Gauss-Seidel rows and its matrix products take each 3 × 3 block's product in one
//! register (three multiplies and two adds of four lanes), in glam's order and without fused
//! multiply-adds: the drape's frames are byte-identical, and unit tests compare the bits with
//! the scalar fallback. The 128 × 128 drape at 1 × 3 Newton steps of 4 CG: 30.8 against
//! 32.3 ms a frame on 2 threads and 59.0 against 76.1 ms on one (`docs/peers_newton.md`; runs
//! of the two builds alternating: 7 % less on 2 threads, 10–15 % on one). Each Gauss-Seidel
//! row also asks for the blocks of the row 8 ahead (`block_lanes`' docs): 24.0 ms on 2
//! threads and 54.8 ms on one in the sweep at commit c63de95; with the Galerkin sums in the
//! lanes too, 26.3 and 43.9 ms at f0899bd (2-thread runs of the two alternating: the same
//! time).

//! ## Blocks: one edge at a time, or a particle's star at once
//!
//! `blocks` chooses what one Gauss-Seidel step solves. `"edges"` (the default): one edge, as
//! above. `"stars"` ([`star`]): all the edges at one particle at once — one Newton step on the
//! star's linearised equations, reduced to a 3 × 3 system, with a trust region and a line
//! search.
//!
//! Edge by edge, a load carried through a light particle stalls: each edge moves the light
//! particle, almost never the heavy ones behind it (one pass closes about `m_light/m_heavy` of
//! the gap). The stress suite's cloth carried through columns 10⁶ times lighter tears under
//! edge passes (max strain 39 %, energy +38 %/s with tethers) and holds with stars (max strain
//! 0.40 %, +0.21 %/s; `docs/stress.md`).
//!
//! Stars are not the default: they do not pay on uniform cloth. On the 64 × 64 drape (2
//! threads, hard stretch, the peers' metrics), at 20 / 40 / 80 substeps of one pass,
//!
//! | blocks | ms/frame | max strain | RMS strain |
//! |---|---|---|---|
//! | `edges` | 1.57 / 3.14 / 6.17 | 71.8 / 25.4 / 7.9 % | 4.07 / 1.34 / 0.43 % |
//! | `stars` | 13.4 / 27.0 / 56.4 | 28.2 / 8.6 / 3.1 % | 1.63 / 0.50 / 0.18 % |
//!
//! a star pass takes about as much strain off as two edge passes, at nine times the cost (each
//! edge is solved twice, and a star's step costs far more than the edge kernel's one square
//! root and one division). In a violent catch (a curtain whose 1,000-times-heavier hem falls
//! 2 m onto its tethers; the stress suite's weighted-hem pair) stars hold the energy (+0.07 %/s)
//! but leave the curtain looser than edge passes (max strain 98 % against 40 %). Tried and not
//! kept: stars only at the particles 10 times lighter than a neighbour, edges elsewhere — it
//! passed the light-column case but the weighted hem exploded (strain 1,200 %, with the earlier,
//! wider trust region), where stars everywhere did not. Retried 2026-11-23 with the narrower
//! trust region: the light-column case passes (max strain 0.53 %, +0.21 %/s; 0.04 s against
//! stars' 0.07 s, one run) and the weighted hem no longer gains energy (0 %/s), but ends five
//! times looser than under edge passes (max strain 205 % against 40 %, RMS 21 % against 5.8 %;
//! max speed 115 m/s against 31). Our reading, not measured further: the edge passes and the
//! light stars beside them move the same particles in one pass, each against the other's
//! linearisation. Not kept: the one realistic scene with such mass ratios (a weighted hem) is
//! better served by edges.
//!
//! ## Chebyshev acceleration (optional)
//!
//! `chebyshev_rho > 0` accelerates the passes *within* a substep with the Chebyshev
//! semi-iterative method of Wang 2015 ([`chebyshev`]): after each pass beyond the first
//! `chebyshev_delay`, the group's particles are moved to a weighted combination of the pass's
//! result and the two previous iterates. It only acts with more passes per substep than the
//! delay, and costs two copies of the group's positions per pass. Measured on the 64 × 64
//! drape (one thread; `nucleus run scenes/drape.toml --set 'objects.0.grid.resolution=[64,64]'
//! --set constraints.0.params.chebyshev_rho=ρ --substeps S --iterations I`, the peers'
//! metrics):
//!
//! | S × I | ms/frame | ρ = 0 (off) max / RMS | ρ = 0.9 | ρ = 0.95 |
//! |---|---:|---|---|---|
//! | 10 × 8 | 16 | 42.6 % / 2.30 % | 21.5 % / 1.18 % | 19.9 % / 1.06 % |
//! | 20 × 4 | 16 | 25.0 % / 1.28 % | 15.7 % / 0.82 % | 58 % / 7.4 % (unstable) |
//! | 20 × 8 | 33 | 13.7 % / 0.70 % | 7.2 % / 0.39 % | 5.7 % / 0.31 % |
//! | 40 × 4 | 33 | 7.7 % / 0.41 % | 4.9 % / 0.26 % | 58 % / 7.3 % (unstable) |
//! | 80 × 1 | 18 | 7.8 % / 0.42 % | — | — |
//! | 160 × 1 | 35 | 2.7 % / 0.16 % | — | — |
//!
//! It halves the strain at a given substeps × passes, but the same work spent on substeps
//! (the last two rows) does better still, and `ρ` near 1 diverges with few passes. So it is
//! off by default; it pays where passes cannot be traded for substeps.
//!
//! ## Residual
//!
//! The strain `|l − l0| / l0` of each edge (dimensionless; `l` its current length, `l0` its
//! rest length); for a zero rest length, where strain is undefined, the length `l` itself
//! (m) — the distance still to close. `energy` is `Σ ½ C²/α` over the edges whose active
//! compliance is positive (J); hard edges store none.
//!
//! ## Scheduling defaults
//!
//! * **Order 0.** Stretch is the structure everything else acts on; kinds with a larger order
//!   (bend, attachments, collisions) run after it within each column of the schedule and so
//!   have the last word on the positions.
//! * **Importance 1** (one pass per substep). XPBD's stiffness does not depend on the pass
//!   count, and many substeps of one pass converge better per unit of work than few substeps
//!   of many passes (Macklin et al. 2019, "Small steps in physics simulation"). A hard edge is
//!   only exactly satisfied in the limit of passes: raise the importance (or the substeps)
//!   for cloth that must not stretch at all.

mod block_lanes;
pub mod chebyshev;
pub mod distance;
pub mod group;
pub mod hierarchy;
mod lanes;
pub mod multigrid;
pub mod newton;
pub mod star;
pub mod tether;

#[cfg(test)]
mod tests;

pub use distance::{distance_constraint, project_distance, Correction, EdgeMaterial};
pub use group::{StretchGroup, StretchParams};

use nucleus_sdk::KindSpec;

/// The kinds this plugin provides: `stretch`, `tether`, `stretch_hierarchy` and
/// `stretch_newton`.
pub fn kinds() -> Vec<KindSpec> {
    vec![
        KindSpec {
            name: "stretch",
            doc: "XPBD distance constraint C = |xj - xi| - l on every edge of the target objects \
              (curves, and the edges of triangles and tetrahedra), with separate compliances \
              for stretch and compression and an optional damper along each edge; edge by \
              edge, or all the edges at each particle at once (blocks = \"stars\").",
            default_order: 0,
            default_importance: 1,
            residual_unit: "strain",
            params: StretchParams::specs(),
            factory: group::build,
        },
        KindSpec {
            name: "tether",
            doc: "Long-range attachments (Kim et al. 2012): each dynamic particle may be no \
                  farther from its nearest pins than the shortest path along the cloth at rest \
                  (unilateral, C = |x - pin| - geodesic <= 0). Keeps hanging cloth from \
                  stretching at the pins at any resolution; never resists folding.",
            default_order: 1,
            default_importance: 1,
            residual_unit: "relative overshoot",
            params: tether::TetherParams::specs(),
            factory: tether::build,
        },
        KindSpec {
            name: "stretch_hierarchy",
            doc: "Hierarchical position-based dynamics (Mueller 2008): coarser and coarser \
                  levels of each object's edge graph, each with unilateral edges no longer \
                  than the rest path between their ends, projected coarsest first with the \
                  dropped particles interpolated, before `stretch`. Carries a correction \
                  across the whole cloth in one pass; never resists bending or folding.",
            default_order: -1,
            default_importance: 1,
            residual_unit: "relative overshoot",
            params: hierarchy::HierarchyParams::specs(),
            factory: hierarchy::build,
        },
        KindSpec {
            name: "stretch_newton",
            doc: "Every edge of the target objects as a stiff spring (compliance > 0), solved \
                  globally: each pass is one Newton step on the substep's implicit-Euler \
                  problem, its linear system solved by a few conjugate-gradient iterations \
                  preconditioned by a geometric multigrid V-cycle. Use it instead of `stretch` \
                  for cloth that must hardly stretch; keep the passes and CG converged \
                  (the defaults), or the cloth's motion goes wrong before its strain shows it.",
            default_order: 0,
            default_importance: 1,
            residual_unit: "strain",
            params: newton::NewtonParams::specs(),
            factory: newton::build,
        },
    ]
}

nucleus_sdk::export_plugin!(nucleus_sdk::PluginDef {
    name: "stretch",
    version: env!("CARGO_PKG_VERSION"),
    kinds,
});
