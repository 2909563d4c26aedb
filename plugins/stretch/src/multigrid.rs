//! The linear algebra of the `stretch_newton` kind: a symmetric 3 × 3-block sparse matrix, a
//! multigrid hierarchy over it with Galerkin coarse operators, and conjugate gradients
//! preconditioned by one V-cycle.
//!
//! * [`BlockMatrix`] — compressed sparse rows of 3 × 3 blocks, both triangles stored, the
//!   pattern fixed at construction; a product costs one pass over the blocks.
//! * [`Prolongation`] — an interpolation from a coarse level's particles to a fine level's (a
//!   kept particle copies its coarse self, a dropped one takes a weighted mean of its coarse
//!   neighbours): applied to x, y and z alike (`P = P_s ⊗ I₃`), or rigid — each coarse
//!   particle a translation node and a rotation node, a dropped particle moved by its parents'
//!   rigid motions about their current positions. Every level stays a matrix of 3 × 3 blocks
//!   (a rigid level has two block rows per particle), so the products, sweeps and factor are
//!   the same code.
//! * [`Hierarchy`] — the levels. Its pattern, the prolongations and the symbolic Galerkin
//!   product are built once; [`Hierarchy::update`] recomputes every coarse operator
//!   `A_{l+1} = Pᵀ A_l P`, the diagonal blocks' inverses and the coarsest level's dense
//!   Cholesky factor for a new fine matrix, allocating nothing ([`Hierarchy::update_to`]: the
//!   first levels only, the deeper ones kept). The factor and its solves sum their dot
//!   products in four lanes in a fixed order ([`dot_in_fours`]).
//! * [`Hierarchy::v_cycle`] — one forward block Gauss-Seidel sweep, the coarse correction,
//!   one backward sweep: a symmetric positive definite preconditioner for a symmetric
//!   positive definite matrix, also with the sweeps relaxed by one weight `ω` in (0, 2)
//!   ([`Hierarchy::set_relaxation`]). The residual restricted after the forward sweep is taken from
//!   the blocks whose columns the sweep visits after each row (each row's own sweep zeroed
//!   the rest, up to a `(1 − ω)/ω` share of the diagonal block's term; `sweep_slots`): fewer
//!   than half a product's blocks. It equals `b − A x` to
//!   rounding (1e-16 of `|b|` in `the_residual_from_the_forward_sweep_is_b_minus_a_x`); part
//!   6's drape took 0.90 of the time on one thread and 0.91–0.97 on two (alternating runs,
//!   2026-11-27). The forward sweep itself starts from zero, so each row reads only the blocks
//!   of the columns swept before it (`sweep_slots`' earlier runs; `forward_from_zero`): the
//!   same bits as zeroing and sweeping, and in process 0.82 of the fine level's forward sweep
//!   and 0.62–0.65 of the coarser levels' (one thread, 2026-11-28; the fine level's waits for
//!   memory, its whole rows prefetched either way).
//!   Without pre-smoothing ([`Hierarchy::set_pre_smoothing`]) each level skips the forward
//!   sweep and its residual: it restricts its right-hand side as it is, sets `x` to the
//!   prolonged coarse correction and sweeps backward (a V(0,1) cycle, not symmetric), reading
//!   its matrix about once a cycle instead of twice.
//! * [`Pcg`] — conjugate gradients from zero with that preconditioner, at most a given number
//!   of iterations; with a V(0,1) cycle, `β` in the flexible (Polak–Ribière) form.
//!
//! **Threads.** The products, the Gauss-Seidel sweeps, the restrictions ([`Restriction`]:
//! `Pᵀ` by coarse rows), CG's vector updates, the Galerkin update and the diagonal inverses
//! of levels with at least [`PARALLEL_MIN_ROWS`] block rows are split over the host's
//! thread team. Each value is computed by one part, in an order that does not depend on the
//! number of parts (the sweeps go colour by colour, the rows of a colour being independent;
//! the Galerkin terms of a coarse block are summed by one part in a fixed order), and the dot
//! products are sequential, so results are bit-identical whatever the thread count.

use glam::{DMat3, DVec3};

use crate::block_lanes::{
    later_residuals, turning_sum, update_rows, update_rows_from_zero, weighted_sum,
};
use nucleus_sdk::team::{span, SharedArray, TeamRef};

/// A range of rows (or of blocks of rows).
pub type Rows = std::ops::Range<usize>;

/// Levels with fewer block rows than this run on the calling thread.
pub const PARALLEL_MIN_ROWS: usize = 2048;

/// Relative regularisation of a rigid level's diagonal blocks
/// ([`BlockMatrix::regularize_diagonal`]).
pub const ROTATION_REGULARIZATION: f64 = 1e-10;

/// Rows per block of the Gauss-Seidel sweeps' colouring ([`BlockMatrix::block_colours`]).
pub const GAUSS_SEIDEL_BLOCK: usize = 256;

/// [`TeamRef::for_ranges`] from [`PARALLEL_MIN_ROWS`] items on.
pub fn for_parts(team: TeamRef<'_>, n: usize, f: &(dyn Fn(Rows) + Sync)) {
    team.for_ranges(n, PARALLEL_MIN_ROWS, f);
}

/// A square matrix of 3 × 3 blocks in compressed sparse rows, both triangles stored, columns
/// sorted within a row and the diagonal block always present.
#[derive(Clone, Debug, Default)]
pub struct BlockMatrix {
    /// `start[i]..start[i + 1]`: the slots of row `i`.
    pub start: Vec<u32>,
    /// Block column of each slot.
    pub col: Vec<u32>,
    /// Block value of each slot.
    pub val: Vec<DMat3>,
    /// Slot of the diagonal block of each row.
    pub diag: Vec<u32>,
}

impl BlockMatrix {
    /// A zero matrix of `n` block rows with the diagonal and, for every pair `(i, j)`, the
    /// blocks `(i, j)` and `(j, i)`.
    pub fn with_pattern(n: usize, pairs: impl IntoIterator<Item = (u32, u32)>) -> BlockMatrix {
        let mut rows: Vec<Vec<u32>> = (0..n as u32).map(|i| vec![i]).collect();
        for (i, j) in pairs {
            rows[i as usize].push(j);
            rows[j as usize].push(i);
        }
        let mut m = BlockMatrix {
            start: Vec::with_capacity(n + 1),
            ..BlockMatrix::default()
        };
        m.start.push(0);
        for (i, row) in rows.iter_mut().enumerate() {
            row.sort_unstable();
            row.dedup();
            let d = row.binary_search(&(i as u32)).unwrap_or(0);
            m.diag.push((m.col.len() + d) as u32);
            m.col.extend_from_slice(row);
            m.start.push(m.col.len() as u32);
        }
        m.val = vec![DMat3::ZERO; m.col.len()];
        m
    }

    /// Number of block rows.
    pub fn n(&self) -> usize {
        self.diag.len()
    }

    /// The slot of block `(i, j)`, if it is in the pattern.
    pub fn slot(&self, i: u32, j: u32) -> Option<usize> {
        let range = self.start[i as usize] as usize..self.start[i as usize + 1] as usize;
        self.col[range.clone()]
            .binary_search(&j)
            .ok()
            .map(|k| range.start + k)
    }

    /// Adds `ε tr(D)/3 · I` to every diagonal block `D`, and makes a zero diagonal block the
    /// identity: a rigid level's rotation about a line through collinear particles (a curve's
    /// tangent) moves nothing, so its row of `Pᵀ A P` is singular; so is the rotation of a
    /// particle without edges. Their restricted residual is zero too, so any positive value
    /// serves; `ε` keeps the others' change below the rounding of the Galerkin sums.
    pub fn regularize_diagonal(&mut self, epsilon: f64) {
        for &d in &self.diag {
            let block = &mut self.val[d as usize];
            let trace = block.x_axis.x + block.y_axis.y + block.z_axis.z;
            *block += if trace > 0.0 {
                DMat3::IDENTITY * (epsilon * trace / 3.0)
            } else if *block == DMat3::ZERO {
                DMat3::IDENTITY
            } else {
                DMat3::ZERO
            };
        }
    }

    /// Sets every block to zero, keeping the pattern.
    pub fn zero(&mut self) {
        self.val.iter_mut().for_each(|b| *b = DMat3::ZERO);
    }

    /// `y = A x` (`y` holds [`n`](Self::n) rows), rows split over the team.
    pub fn mul(&self, team: TeamRef<'_>, x: &[DVec3], y: &mut [DVec3]) {
        assert!(y.len() >= self.n() && x.len() >= self.n());
        team.for_ranges_mut(&mut y[..self.n()], PARALLEL_MIN_ROWS, &|rows, ys| {
            crate::block_lanes::row_products(self, x, rows, ys)
        });
    }

    /// The rows cut into consecutive blocks of `size` rows, the blocks coloured so that no row
    /// of a block has a column in another block of its colour. Returns the blocks colour by
    /// colour (each in increasing order) and each colour's range in that list, flagged
    /// `false` for the last one if some block found all 64 colours taken by its neighbours
    /// (such blocks are not independent: swept on one thread). On a grid numbered row by row,
    /// blocks of two or more grid rows need two colours: a Gauss-Seidel sweep in this order
    /// visits the rows almost in their own order (memory order), unlike a colouring of single
    /// rows, which on one thread was 1.4× slower and smoothed worse on the drape.
    pub fn block_colours(&self, size: usize) -> (Vec<Rows>, Vec<(Rows, bool)>) {
        const OVERFLOW: usize = 64;
        let size = size.max(1);
        let count = self.n().div_ceil(size);
        let mut colour = vec![usize::MAX; count];
        for k in 0..count {
            let mut taken = 0u64;
            for i in k * size..((k + 1) * size).min(self.n()) {
                for s in self.start[i] as usize..self.start[i + 1] as usize {
                    let other = self.col[s] as usize / size;
                    // Blocks before this one are coloured already; later ones are not yet.
                    if other < k && colour[other] < OVERFLOW {
                        taken |= 1 << colour[other];
                    }
                }
            }
            colour[k] = if taken == u64::MAX {
                OVERFLOW
            } else {
                (!taken).trailing_zeros() as usize
            };
        }
        let mut blocks = Vec::with_capacity(count);
        let mut ranges = Vec::new();
        for c in 0..=OVERFLOW {
            let start = blocks.len();
            blocks.extend(
                (0..count)
                    .filter(|&k| colour[k] == c)
                    .map(|k| k * size..((k + 1) * size).min(self.n())),
            );
            if blocks.len() > start {
                ranges.push((start..blocks.len(), c < OVERFLOW));
            }
        }
        (blocks, ranges)
    }
}

/// An interpolation from a coarse level's nodes (3-vectors) to a fine level's, one row per
/// fine node: `(fine)ᵢ = Σₖ Bₖ (coarse)_{col k}` over the row's entries, each block `Bₖ` either
/// a copy `wₖ I` (a node moved by its coarse parent's translation, or a rotation copied from
/// the parent's rotation) or a turn `wₖ S(rₖ)`, `S(r) θ = θ × r`: a fine particle at lever arm
/// `rₖ` from its coarse parent carried round by the parent's rotation `θ`.
///
/// [`from_coarsening`](Self::from_coarsening) gives the plain interpolation (copies only,
/// `P = P_s ⊗ I₃`); [`rigid`](Self::rigid) one whose coarse particles each carry a
/// translation and a rotation (two nodes), so that the rigid motions of the *current* shape,
/// whole or local, are interpolated exactly: the lever arms are refitted to the positions by
/// [`refit`](Self::refit).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Prolongation {
    /// Number of coarse nodes.
    pub coarse: usize,
    /// `start[i]..start[i + 1]`: the entries of fine row `i`.
    pub start: Vec<u32>,
    /// Coarse node of each entry.
    pub col: Vec<u32>,
    /// Weight of each entry.
    pub weight: Vec<f64>,
    /// Whether each entry is a turn (else a copy).
    pub turn: Vec<bool>,
    /// Lever arm of each turn entry (m; zero for a copy).
    pub arm: Vec<DVec3>,
    /// Per turn entry, the positions' indices (fine particle, coarse particle) its lever arm
    /// is the difference of (`[u32::MAX; 2]` for a copy).
    pub origin: Vec<[u32; 2]>,
}

/// The prolongations of a [`crate::hierarchy::Coarsening`] of the fine particles, finest
/// first: plain ([`Prolongation::from_coarsening`]) or, if `rigid`, carrying rotations
/// ([`Prolongation::rigid`]) onto every coarse level past the first `plain_levels`, whose
/// particles only translate (0: every coarse level turns). `position[f]` is where fine particle `f`'s position is found in
/// the slice later given to [`Hierarchy::refit`] (the identity, or the group's particle
/// indices, so the simulation's positions serve directly).
pub fn prolongations(
    position: &[u32],
    coarsening: &crate::hierarchy::Coarsening,
    rigid: bool,
    plain_levels: usize,
) -> Vec<Prolongation> {
    let mut fine_n = position.len();
    let mut out = Vec::new();
    // Where each level's particles' positions are (those of the fine particles they stand for).
    let mut origin = position.to_vec();
    for (level, (kept, dropped)) in coarsening.kept.iter().zip(&coarsening.dropped).enumerate() {
        out.push(if rigid && level >= plain_levels {
            Prolongation::rigid(fine_n, level > plain_levels, kept, dropped, &origin)
        } else {
            Prolongation::from_coarsening(fine_n, kept, dropped)
        });
        origin = kept.iter().map(|&k| origin[k as usize]).collect();
        fine_n = kept.len();
    }
    out
}

/// `S(r)ᵀ m` with `S(r) θ = θ × r`: `r ×` each column of `m`.
#[inline]
fn turn_left(r: DVec3, m: DMat3) -> DMat3 {
    DMat3::from_cols(r.cross(m.x_axis), r.cross(m.y_axis), r.cross(m.z_axis))
}

/// `m S(r)`: column `k` is `m (eₖ × r)`.
#[inline]
fn turn_right(m: DMat3, r: DVec3) -> DMat3 {
    DMat3::from_cols(
        m * DVec3::new(0.0, -r.z, r.y),
        m * DVec3::new(r.z, 0.0, -r.x),
        m * DVec3::new(-r.y, r.x, 0.0),
    )
}

impl Prolongation {
    /// From a level of [`crate::hierarchy::coarsen`]: `kept` (fine indices of the coarse
    /// particles) and the dropped fine particles with their coarse parents and weights.
    pub fn from_coarsening(
        fine: usize,
        kept: &[u32],
        dropped: &[crate::hierarchy::Dropped],
    ) -> Prolongation {
        let mut rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); fine];
        for (k, &f) in kept.iter().enumerate() {
            rows[f as usize].push((k as u32, 1.0));
        }
        for (f, parents) in dropped {
            rows[*f as usize].extend_from_slice(parents);
        }
        let mut p = Prolongation {
            coarse: kept.len(),
            start: vec![0],
            ..Prolongation::default()
        };
        for row in rows {
            for (c, w) in row {
                p.push(c, w, None);
            }
            p.start.push(p.col.len() as u32);
        }
        p
    }

    /// The rigid interpolation of a level of [`crate::hierarchy::coarsen`] (`kept`, `dropped`
    /// as for [`from_coarsening`](Self::from_coarsening)) over `fine` particles: coarse
    /// particle `c` has nodes `2c` (translation) and `2c + 1` (rotation about its position).
    /// A fine particle's translation — its node `f`, or `2f` when `fine_rotates` (the fine
    /// level is itself rigid) — copies its coarse self's translation if kept, else is
    /// `Σ w (t_c + θ_c × (x_f − x_c))` over its parents; its rotation (node `2f + 1`, when
    /// `fine_rotates`) is `Σ w θ_c`. `origin[f]` indexes the fine particle's position for
    /// [`refit`](Self::refit); the coarse particles' are `origin[kept[c]]`.
    pub fn rigid(
        fine: usize,
        fine_rotates: bool,
        kept: &[u32],
        dropped: &[crate::hierarchy::Dropped],
        origin: &[u32],
    ) -> Prolongation {
        let mut parents: Vec<Vec<(u32, f64)>> = vec![Vec::new(); fine];
        let mut is_kept = vec![false; fine];
        for (k, &f) in kept.iter().enumerate() {
            parents[f as usize].push((k as u32, 1.0));
            is_kept[f as usize] = true;
        }
        for (f, list) in dropped {
            parents[*f as usize].extend_from_slice(list);
        }
        let mut p = Prolongation {
            coarse: 2 * kept.len(),
            start: vec![0],
            ..Prolongation::default()
        };
        for (f, list) in parents.iter().enumerate() {
            for &(c, w) in list {
                p.push(2 * c, w, None);
                if !is_kept[f] {
                    let pair = [origin[f], origin[kept[c as usize] as usize]];
                    p.push(2 * c + 1, w, Some(pair));
                }
            }
            p.start.push(p.col.len() as u32);
            if fine_rotates {
                for &(c, w) in list {
                    p.push(2 * c + 1, w, None);
                }
                p.start.push(p.col.len() as u32);
            }
        }
        p
    }

    fn push(&mut self, col: u32, weight: f64, turn: Option<[u32; 2]>) {
        self.col.push(col);
        self.weight.push(weight);
        self.turn.push(turn.is_some());
        self.arm.push(DVec3::ZERO);
        self.origin.push(turn.unwrap_or([u32::MAX; 2]));
    }

    /// Number of fine nodes.
    pub fn fine(&self) -> usize {
        self.start.len() - 1
    }

    /// Whether some entry is a turn.
    pub fn rotates(&self) -> bool {
        self.turn.contains(&true)
    }

    /// Sets each turn's lever arm to the difference of its two positions in `x`.
    pub fn refit(&mut self, x: &[DVec3]) {
        for ((arm, &turn), &[f, c]) in self.arm.iter_mut().zip(&self.turn).zip(&self.origin) {
            if turn {
                *arm = x[f as usize] - x[c as usize];
            }
        }
    }

    /// `B v` for entry `k`.
    #[inline]
    fn apply(&self, k: usize, v: DVec3) -> DVec3 {
        let w = self.weight[k];
        if self.turn[k] {
            v.cross(self.arm[k]) * w
        } else {
            v * w
        }
    }

    /// `Bᵀ v` for entry `k`.
    #[inline]
    fn apply_transposed(&self, k: usize, v: DVec3) -> DVec3 {
        let w = self.weight[k];
        if self.turn[k] {
            self.arm[k].cross(v) * w
        } else {
            v * w
        }
    }

    /// `Bᵢᵀ a Bⱼ` for entries `i` and `j`: a fine block's Galerkin term.
    #[inline]
    fn galerkin_term(&self, i: usize, a: DMat3, j: usize) -> DMat3 {
        let mut m = a * (self.weight[i] * self.weight[j]);
        if self.turn[j] {
            m = turn_right(m, self.arm[j]);
        }
        if self.turn[i] {
            m = turn_left(self.arm[i], m);
        }
        m
    }

    /// The entries of fine row `i`: (entry index, coarse node).
    fn row(&self, i: usize) -> impl Iterator<Item = (usize, u32)> + '_ {
        let range = self.start[i] as usize..self.start[i + 1] as usize;
        range.clone().zip(self.col[range].iter().copied())
    }

    /// `fine += P coarse`, fine rows split over the team.
    pub fn add_to_fine(&self, team: TeamRef<'_>, coarse: &[DVec3], fine: &mut [DVec3]) {
        self.to_fine(team, coarse, fine, true);
    }

    /// `fine = P coarse` (the rows of `fine` past `P`'s are left as they are), fine rows split
    /// over the team.
    pub fn set_fine(&self, team: TeamRef<'_>, coarse: &[DVec3], fine: &mut [DVec3]) {
        self.to_fine(team, coarse, fine, false);
    }

    /// `fine += P coarse` when `add`, else `fine = P coarse`.
    fn to_fine(&self, team: TeamRef<'_>, coarse: &[DVec3], fine: &mut [DVec3], add: bool) {
        assert!(fine.len() >= self.fine());
        let out = SharedArray::new(fine);
        for_parts(team, self.fine(), &|rows| {
            for i in rows {
                let mut sum = DVec3::ZERO;
                for (k, c) in self.row(i) {
                    sum += self.apply(k, coarse[c as usize]);
                }
                // SAFETY: `i < fine.len()` (asserted); each part writes its own rows.
                unsafe {
                    let out = out.at(i);
                    *out = if add { *out + sum } else { sum };
                }
            }
        });
    }

    /// `coarse = Pᵀ fine`.
    pub fn restrict(&self, fine: &[DVec3], coarse: &mut [DVec3]) {
        coarse.iter_mut().for_each(|c| *c = DVec3::ZERO);
        for (i, f) in fine.iter().enumerate().take(self.fine()) {
            for (k, c) in self.row(i) {
                coarse[c as usize] += self.apply_transposed(k, *f);
            }
        }
    }
}

/// `Pᵀ` of a [`Prolongation`] by coarse rows: each coarse node's entries, `(fine row, entry)`
/// in increasing order, so that [`apply`](Self::apply) sums each coarse node's terms in the
/// order [`Prolongation::restrict`] adds them — the same bits — with the coarse nodes split
/// over the team (the scatter of `restrict` runs on one thread).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Restriction {
    /// `start[c]..start[c + 1]`: the entries of coarse node `c`.
    start: Vec<u32>,
    /// `(fine row, entry of the prolongation)`.
    entries: Vec<(u32, u32)>,
}

impl Restriction {
    /// The transpose of `p`'s pattern.
    pub fn new(p: &Prolongation) -> Restriction {
        let mut count = vec![0u32; p.coarse + 1];
        for &c in &p.col {
            count[c as usize + 1] += 1;
        }
        for c in 0..p.coarse {
            count[c + 1] += count[c];
        }
        let start = count.clone();
        let mut entries = vec![(0, 0); p.col.len()];
        for i in 0..p.fine() {
            for (k, c) in p.row(i) {
                let at = &mut count[c as usize];
                entries[*at as usize] = (i as u32, k as u32);
                *at += 1;
            }
        }
        Restriction { start, entries }
    }

    /// `coarse = Pᵀ fine` for the prolongation this was built from, coarse nodes split over
    /// the team.
    pub fn apply(&self, p: &Prolongation, team: TeamRef<'_>, fine: &[DVec3], coarse: &mut [DVec3]) {
        assert!(coarse.len() >= p.coarse && self.start.len() == p.coarse + 1);
        assert!(fine.len() >= p.fine());
        team.for_ranges_mut(&mut coarse[..p.coarse], PARALLEL_MIN_ROWS, &|nodes, out| {
            for (c, out) in nodes.zip(out) {
                let mut sum = DVec3::ZERO;
                let range = self.start[c] as usize..self.start[c + 1] as usize;
                for &(i, k) in &self.entries[range] {
                    sum += p.apply_transposed(k as usize, fine[i as usize]);
                }
                *out = sum;
            }
        });
    }
}

/// One level of the hierarchy: its operator, its diagonal blocks' inverses, the
/// interpolation from the next coarser level and the Galerkin map onto that level.
#[derive(Clone, Debug, Default)]
struct Level {
    a: BlockMatrix,
    inv_diag: Vec<DMat3>,
    /// Interpolation from the next coarser level (none on the coarsest), and its transpose.
    p: Option<Prolongation>,
    restriction: Restriction,
    /// Whether `p` has turns (rotations): its lever arms are refitted and the next level's
    /// diagonal regularised.
    rigid: bool,
    /// `(fine slot, coarse slot, entry i, entry j)`: the coarse operator is
    /// `Σ Bᵢᵀ A[fine slot] Bⱼ` (the prolongation's entries) accumulated into each coarse slot
    /// of the upper triangle and the diagonal.
    galerkin: Vec<(u32, u32, u32, u32)>,
    /// Where each coarse block's run of terms ends in `galerkin` (its terms are consecutive,
    /// sorted by coarse slot): the runs found once, not scanned for at every update.
    runs: Vec<u32>,
    /// Per Galerkin term, the product of its two weights, when the prolongation only copies
    /// (empty when it turns): the term is then the fine block times it.
    copy_weights: Vec<f64>,
    /// `(lower slot, upper slot)` of the next coarser level: the lower triangle is the upper
    /// one transposed (the operator is symmetric), copied instead of summed — half the work.
    mirror: Vec<(u32, u32)>,
    /// Blocks of consecutive rows colour by colour, and each colour's range of blocks (see
    /// [`BlockMatrix::block_colours`]).
    blocks: Vec<std::ops::Range<usize>>,
    colours: Vec<(std::ops::Range<usize>, bool)>,
    /// Per row `i`, `later[later_start[i]..later_start[i + 1]]`: the runs of consecutive slots
    /// (`start..end`) of the row whose columns the forward sweep visits after row `i`
    /// ([`sweep_slots`]).
    later_start: Vec<u32>,
    later: Vec<[u32; 2]>,
    /// The same for the slots whose columns the forward sweep visits before row `i` (the
    /// diagonal in neither): all the forward sweep from zero reads.
    earlier_start: Vec<u32>,
    earlier: Vec<[u32; 2]>,
    /// Right-hand side, solution and residual of this level within a V-cycle.
    b: Vec<DVec3>,
    x: Vec<DVec3>,
    r: Vec<DVec3>,
}

impl Level {
    /// Inverts the diagonal blocks of this level's operator; `false` if one is not positive
    /// definite (numerically; its inverse is then left zero).
    fn invert_diagonal(&mut self, team: TeamRef<'_>) -> bool {
        let a = &self.a;
        let n = a.n();
        let inv = SharedArray::new(&mut self.inv_diag);
        let bad = std::sync::atomic::AtomicBool::new(false);
        for_parts(team, n, &|rows| {
            for i in rows {
                let block = a.val[a.diag[i] as usize];
                let det = block.determinant();
                let good = det > 0.0 && det.is_finite() && block.x_axis.x > 0.0;
                if !good {
                    bad.store(true, std::sync::atomic::Ordering::Relaxed);
                }
                // SAFETY: `i < n`, the length of `inv_diag`; each part writes its own rows.
                unsafe { *inv.at(i) = if good { block.inverse() } else { DMat3::ZERO } };
            }
        });
        !bad.into_inner()
    }

    /// The next coarser level's operator, `Pᵀ A P` of this one's (the upper triangle summed
    /// term by term, the lower one mirrored).
    fn galerkin_into(&self, team: TeamRef<'_>, next: &mut Level) {
        let a = &self.a;
        let (g, copy_weights) = (&self.galerkin, &self.copy_weights);
        let p = self
            .p
            .as_ref()
            .expect("a prolongation on every level but the last");
        let vals = SharedArray::new(&mut next.a.val);
        let coarse_len = next.a.val.len();
        let runs = &self.runs;
        assert!(runs.last().is_none_or(|&end| end as usize == g.len()));
        // Each coarse block is the sum of its run of terms, stored once; the runs (whole
        // coarse blocks) are split over the team.
        for_parts(team, runs.len(), &|range| {
            let mut at = if range.start == 0 {
                0
            } else {
                runs[range.start - 1] as usize
            };
            for &end in &runs[range] {
                let run = &g[at..end as usize];
                let t = run[0].1 as usize;
                assert!(t < coarse_len);
                let sum = if self.rigid {
                    turning_sum(&a.val, run, &p.weight, &p.turn, &p.arm).unwrap_or_else(|| {
                        let mut sum = DMat3::ZERO;
                        for &(s, _, ki, kj) in run {
                            let block = a.val[s as usize];
                            sum += p.galerkin_term(ki as usize, block, kj as usize);
                        }
                        sum
                    })
                } else {
                    weighted_sum(&a.val, run, &copy_weights[at..end as usize])
                };
                at = end as usize;
                // SAFETY: in bounds (asserted); each coarse block is one run's, and each run
                // is one part's.
                unsafe { *vals.at(t) = sum };
            }
        });
        let mirror = &self.mirror;
        assert!(mirror
            .iter()
            .all(|&(l, u)| (l.max(u) as usize) < coarse_len));
        for_parts(team, mirror.len(), &|range| {
            for &(lower, upper) in &mirror[range] {
                // SAFETY: in bounds (asserted); each lower slot is written by one part
                // and the upper slots are only read (written before, by the join above).
                unsafe { *vals.at(lower as usize) = (*vals.at(upper as usize)).transpose() };
            }
        });
        if self.rigid {
            next.a.regularize_diagonal(ROTATION_REGULARIZATION);
        }
    }
}

/// A geometric multigrid hierarchy with Galerkin coarse operators; see the module docs.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    levels: Vec<Level>,
    /// The coarsest operator as a dense `3n × 3n` matrix, overwritten by its Cholesky factor
    /// (lower triangle, row-major) and that factor's transpose (upper triangle, for the
    /// backward substitution; [`mirror_factor`]).
    dense: Vec<f64>,
    /// The coarsest level's right-hand side and solution as `3n` numbers.
    dense_x: Vec<f64>,
    /// The sweeps' relaxation weight `ω` ([`set_relaxation`](Self::set_relaxation)).
    relaxation: f64,
    /// Whether each level sweeps before its coarse correction as well as after it
    /// ([`set_pre_smoothing`](Self::set_pre_smoothing)).
    pre_smoothing: bool,
}

impl Hierarchy {
    /// The hierarchy over the fine matrix `fine` (its pattern; values are set by
    /// [`fine_mut`](Self::fine_mut) and [`update`](Self::update)), with one prolongation per
    /// coarser level, finest first: `prolongations[l]` maps level `l + 1` onto level `l`.
    pub fn new(fine: BlockMatrix, prolongations: Vec<Prolongation>) -> Hierarchy {
        let mut levels = Vec::new();
        let mut a = fine;
        for p in prolongations {
            debug_assert_eq!(p.fine(), a.n());
            // The coarse pattern: every pair of coarse parents of a fine block's row and column.
            let mut pairs = Vec::new();
            for i in 0..a.n() {
                for s in a.start[i] as usize..a.start[i + 1] as usize {
                    for (_, ci) in p.row(i) {
                        for (_, cj) in p.row(a.col[s] as usize) {
                            if ci < cj {
                                pairs.push((ci, cj));
                            }
                        }
                    }
                }
            }
            let coarse = BlockMatrix::with_pattern(p.coarse, pairs);
            let mut galerkin = Vec::new();
            for i in 0..a.n() {
                for s in a.start[i] as usize..a.start[i + 1] as usize {
                    for (ki, ci) in p.row(i) {
                        for (kj, cj) in p.row(a.col[s] as usize).filter(|&(_, cj)| ci <= cj) {
                            let t = coarse
                                .slot(ci, cj)
                                .expect("coarse pattern holds every pair");
                            galerkin.push((s as u32, t as u32, ki as u32, kj as u32));
                        }
                    }
                }
            }
            // Accumulate coarse slots in order: better locality for the numeric product.
            galerkin.sort_unstable_by_key(|&(s, t, ki, kj)| (t, s, ki, kj));
            let runs: Vec<u32> = (1..=galerkin.len())
                .filter(|&k| k == galerkin.len() || galerkin[k].1 != galerkin[k - 1].1)
                .map(|k| k as u32)
                .collect();
            let mut mirror = Vec::new();
            for i in 0..coarse.n() {
                for t in coarse.start[i] as usize..coarse.diag[i] as usize {
                    let j = coarse.col[t];
                    let upper = coarse.slot(j, i as u32).expect("the pattern is symmetric");
                    mirror.push((t as u32, upper as u32));
                }
            }
            let copy_weights = if p.rotates() {
                Vec::new()
            } else {
                galerkin
                    .iter()
                    .map(|&(_, _, ki, kj)| p.weight[ki as usize] * p.weight[kj as usize])
                    .collect()
            };
            let n = a.n();
            let (blocks, colours) = a.block_colours(GAUSS_SEIDEL_BLOCK);
            let [(later_start, later), (earlier_start, earlier)] =
                sweep_slots(&a, &blocks, &colours);
            levels.push(Level {
                a,
                inv_diag: vec![DMat3::ZERO; n],
                rigid: p.rotates(),
                restriction: Restriction::new(&p),
                p: Some(p),
                galerkin,
                runs,
                copy_weights,
                mirror,
                blocks,
                colours,
                later_start,
                later,
                earlier_start,
                earlier,
                b: vec![DVec3::ZERO; n],
                x: vec![DVec3::ZERO; n],
                r: vec![DVec3::ZERO; n],
            });
            a = coarse;
        }
        let n = a.n();
        levels.push(Level {
            a,
            inv_diag: vec![DMat3::ZERO; n],
            b: vec![DVec3::ZERO; n],
            x: vec![DVec3::ZERO; n],
            r: vec![DVec3::ZERO; n],
            ..Level::default()
        });
        Hierarchy {
            levels,
            dense: vec![0.0; 9 * n * n],
            dense_x: vec![0.0; 3 * n],
            relaxation: 1.0,
            pre_smoothing: true,
        }
    }

    /// Sets the relaxation weight `ω` of every Gauss-Seidel sweep (1 when built): each row
    /// moves by `ω` times its Gauss-Seidel update. Forward then backward with one `ω` in
    /// `(0, 2)` stays a symmetric positive definite preconditioner. Below 1 the sweeps damp
    /// rather than overshoot; on the stiff 128 × 128 drape 0.7 let three CG iterations a
    /// Newton step hold what four held at 1, more often (`stretch_newton`'s `relaxation`).
    pub fn set_relaxation(&mut self, omega: f64) {
        assert!(
            omega > 0.0 && omega < 2.0,
            "relaxation {omega} outside (0, 2)"
        );
        self.relaxation = omega;
    }

    /// Whether each level of a V-cycle sweeps forward before its coarse correction (`true`
    /// when built: a V(1,1) cycle, symmetric) or only backward after it (`false`: a V(0,1)
    /// cycle). Without the first sweep the level restricts its right-hand side itself (the
    /// sweep would have started from zero, so the residual is `b`), sets `x` to the
    /// prolonged coarse correction and sweeps backward from there: a level's passes over its
    /// matrix go from about two (the forward sweep over the blocks before each row, the
    /// residual over those after it, the backward sweep over all) to one. The cycle is then
    /// no longer symmetric, so [`Pcg::solve`] takes its `β` in the flexible (Polak–Ribière)
    /// form, which a symmetric cycle does not need. Run to a tight tolerance it needs about
    /// twice the iterations (a folded 33 × 33 cloth's Hessian to 1e-11: 69 against 31), but
    /// its first few take off nearly as much (0.19 against 0.15 of the residual after three),
    /// and those are what a truncated Newton step uses: on the stiff 128 × 128 drape (3 CG
    /// iterations a Newton step) a frame took 0.83 of the time within the same strain bounds
    /// (`stretch_newton`'s `pre_smoothing`).
    pub fn set_pre_smoothing(&mut self, on: bool) {
        self.pre_smoothing = on;
    }

    /// See [`set_pre_smoothing`](Self::set_pre_smoothing).
    pub fn pre_smoothing(&self) -> bool {
        self.pre_smoothing
    }

    /// Refits every rigid prolongation's lever arms to the positions `x` (see
    /// [`Prolongation::refit`]); call before [`update`](Self::update).
    pub fn refit(&mut self, x: &[DVec3]) {
        for level in self.levels.iter_mut().filter(|l| l.rigid) {
            if let Some(p) = level.p.as_mut() {
                p.refit(x);
            }
        }
    }

    /// The fine matrix, to assemble into before [`update`](Self::update).
    pub fn fine_mut(&mut self) -> &mut BlockMatrix {
        &mut self.levels[0].a
    }

    /// The fine matrix.
    pub fn fine(&self) -> &BlockMatrix {
        &self.levels[0].a
    }

    /// Number of levels, the finest included.
    pub fn depth(&self) -> usize {
        self.levels.len()
    }

    /// Block rows of each level, finest first.
    pub fn sizes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.a.n()).collect()
    }

    /// Blocks stored over all levels divided by those of the finest level.
    pub fn operator_complexity(&self) -> f64 {
        let total: usize = self.levels.iter().map(|l| l.a.val.len()).sum();
        total as f64 / self.levels[0].a.val.len().max(1) as f64
    }

    /// Recomputes the coarse operators, the diagonal inverses and the coarsest factor from
    /// the fine matrix, which must be symmetric (block `(j, i)` the transpose of `(i, j)`: the
    /// coarse operators' lower triangles are copied from their upper ones). Returns `false`
    /// if a diagonal block or the coarsest operator is not positive definite (numerically), in
    /// which case the V-cycle must not be used.
    pub fn update(&mut self, team: TeamRef<'_>) -> bool {
        self.update_to(team, usize::MAX)
    }

    /// [`update`](Self::update) of the first levels only: the coarse operators of levels
    /// `1..=depth` and the diagonal inverses of levels `0..=depth` are recomputed, the coarsest
    /// factor if the coarsest level is among them; the levels beyond keep the operators of an
    /// earlier update (of an earlier fine matrix). The V-cycle stays a symmetric positive
    /// definite preconditioner, its deep coarse corrections those of the older matrix.
    /// `depth = 0` refreshes the fine level's inverses alone; `usize::MAX`, everything.
    pub fn update_to(&mut self, team: TeamRef<'_>, depth: usize) -> bool {
        let mut ok = true;
        for l in 0..self.levels.len().min(depth.saturating_add(1)) {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let level = &mut fine[l];
            ok &= level.invert_diagonal(team);
            if l < depth {
                if let Some(next) = coarse.first_mut() {
                    level.galerkin_into(team, next);
                }
            }
        }
        if depth >= self.levels.len() - 1 {
            ok &= self.factor_coarsest();
        }
        ok
    }

    /// Copies the coarsest operator into `dense` and factors it in place (Cholesky).
    fn factor_coarsest(&mut self) -> bool {
        let a = &self.levels.last().expect("at least one level").a;
        let m = 3 * a.n();
        let d = &mut self.dense;
        d.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..a.n() {
            for s in a.start[i] as usize..a.start[i + 1] as usize {
                let j = a.col[s] as usize;
                let b = a.val[s];
                for r in 0..3 {
                    for c in 0..3 {
                        d[(3 * i + r) * m + 3 * j + c] = b.col(c)[r];
                    }
                }
            }
        }
        let ok = cholesky_in_place(d, m);
        mirror_factor(d, m);
        ok
    }

    /// `z ≈ A⁻¹ r` by one V-cycle from zero.
    pub fn v_cycle(&mut self, team: TeamRef<'_>, r: &[DVec3], z: &mut [DVec3]) {
        self.levels[0].b.copy_from_slice(r);
        self.cycle(team, 0);
        z.copy_from_slice(&self.levels[0].x);
    }

    /// [`v_cycle`](Self::v_cycle) without copying: `r` is lent to the finest level as its
    /// right-hand side and given back unchanged, and `z` is swapped with the level's solution
    /// (both must have the finest level's length).
    pub fn v_cycle_in_place(&mut self, team: TeamRef<'_>, r: &mut Vec<DVec3>, z: &mut Vec<DVec3>) {
        let fine = &mut self.levels[0];
        assert!(r.len() == fine.b.len() && z.len() == fine.x.len());
        std::mem::swap(&mut fine.b, r);
        self.cycle(team, 0);
        let fine = &mut self.levels[0];
        std::mem::swap(&mut fine.b, r);
        std::mem::swap(&mut fine.x, z);
    }

    fn cycle(&mut self, team: TeamRef<'_>, l: usize) {
        let omega = self.relaxation;
        if l + 1 == self.levels.len() {
            let level = &mut self.levels[l];
            let x = &mut self.dense_x;
            for (k, b) in level.b.iter().enumerate() {
                x[3 * k..3 * k + 3].copy_from_slice(&b.to_array());
            }
            cholesky_solve_in_place(&self.dense, x);
            for (k, out) in level.x.iter_mut().enumerate() {
                *out = DVec3::from_slice(&x[3 * k..3 * k + 3]);
            }
            return;
        }
        let pre = self.pre_smoothing;
        if pre {
            let level = &mut self.levels[l];
            // From zero: each row reads only the rows swept before it (nothing to zero first).
            forward_from_zero(team, level, omega);
            // The residual `b − A x`: each row's sweep left `A[i, i] x[i] = ω (b[i] − Σ A[i, j]
            // x[j])` over the columns swept before it (zero for the others then), so what
            // remains is `(1 − ω)/ω A[i, i] x[i]` and the later columns' terms — fewer than half
            // the row's blocks.
            let (a, x) = (&level.a, &level.x);
            let (later_start, later) = (&level.later_start, &level.later);
            let diagonal = (1.0 - omega) / omega;
            team.for_ranges_mut(&mut level.r, PARALLEL_MIN_ROWS, &|rows, rs| {
                later_residuals(a, later_start, later, x, rows, rs, diagonal)
            });
        }
        {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let p = fine[l]
                .p
                .as_ref()
                .expect("a prolongation on every level but the last");
            // Without the forward sweep, `x` would be zero and the residual `b` itself.
            let residual = if pre { &fine[l].r } else { &fine[l].b };
            fine[l]
                .restriction
                .apply(p, team, residual, &mut coarse[0].b);
        }
        self.cycle(team, l + 1);
        let (fine, coarse) = self.levels.split_at_mut(l + 1);
        let level = &mut fine[l];
        let p = level
            .p
            .as_ref()
            .expect("a prolongation on every level but the last");
        if pre {
            p.add_to_fine(team, &coarse[0].x, &mut level.x);
        } else {
            p.set_fine(team, &coarse[0].x, &mut level.x);
        }
        gauss_seidel(team, level, true, omega);
    }
}

/// Runs of consecutive slots per row: the slots whose columns a forward sweep
/// ([`gauss_seidel`]) visits after the row, then those it visits before it (the diagonal in
/// neither), each as `(start, runs)`, row `i`'s runs `runs[start[i]..start[i + 1]]`, each
/// `[start, end)`, in slot order. The sweep visits the colours in order, each colour's blocks in
/// order, each block's rows in order; two blocks of one independent colour share no block of
/// the matrix, so their relative order does not matter and the lists are the same whatever the
/// thread count. On a grid the later columns of a row are its own block's past it and whole
/// neighbouring blocks: one or two runs, as are the earlier ones, read without an index per
/// slot.
fn sweep_slots(
    a: &BlockMatrix,
    blocks: &[std::ops::Range<usize>],
    colours: &[(std::ops::Range<usize>, bool)],
) -> [(Vec<u32>, Vec<[u32; 2]>); 2] {
    let mut visit = vec![usize::MAX; a.n()];
    let mut order = 0;
    for (range, _) in colours {
        for rows in &blocks[range.clone()] {
            for i in rows.clone() {
                visit[i] = order;
                order += 1;
            }
        }
    }
    debug_assert!(
        visit.iter().all(|&v| v != usize::MAX),
        "the blocks cover every row"
    );
    let runs = |later: bool| {
        let mut start = vec![0u32];
        let mut runs: Vec<[u32; 2]> = Vec::new();
        for i in 0..a.n() {
            let first_run = runs.len();
            for s in a.start[i] as usize..a.start[i + 1] as usize {
                let v = visit[a.col[s] as usize];
                if v == visit[i] || (v > visit[i]) != later {
                    continue;
                }
                let s = s as u32;
                let grows = runs.len() > first_run;
                match runs.last_mut() {
                    Some(run) if grows && run[1] == s => run[1] = s + 1,
                    _ => runs.push([s, s + 1]),
                }
            }
            start.push(runs.len() as u32);
        }
        (start, runs)
    };
    [runs(true), runs(false)]
}

/// The forward sweep of a V-cycle from `x = 0` on the level's `A x = b`: [`gauss_seidel`]'s
/// order and split over the team, each row reading only the columns swept before it
/// ([`update_rows_from_zero`]); the same bits as zeroing `x` and sweeping (up to the sign of
/// an exact zero).
fn forward_from_zero(team: TeamRef<'_>, level: &mut Level, omega: f64) {
    let (a, inv_diag, b) = (&level.a, &level.inv_diag, &level.b);
    let (start, earlier) = (&level.earlier_start, &level.earlier);
    assert!(level.x.len() >= a.n() && b.len() >= a.n() && inv_diag.len() >= a.n());
    let x = SharedArray::new(&mut level.x);
    in_sweep_order(team, a.n(), &level.blocks, &level.colours, false, &|rows| {
        // SAFETY: `x` has `a.n()` vectors (asserted); the rows of this block are swept by this
        // part alone, and the rows they read were swept before them: in this block, or in
        // blocks of an earlier colour (joined), never in another block of this one.
        unsafe { update_rows_from_zero(a, inv_diag, b, x, start, earlier, rows.clone(), omega) }
    });
}

/// One block Gauss-Seidel sweep on the level's `A x = b`: colour by colour, each block of
/// rows in order (or everything reversed: the transposed sweep, so that forward then backward
/// is symmetric). The blocks of one colour are independent, so they are split over the team;
/// each block is swept by one part in a fixed order, so the result does not depend on the
/// number of parts.
fn gauss_seidel(team: TeamRef<'_>, level: &mut Level, backward: bool, omega: f64) {
    let (a, inv_diag, b) = (&level.a, &level.inv_diag, &level.b);
    assert!(level.x.len() >= a.n() && b.len() >= a.n() && inv_diag.len() >= a.n());
    let x = SharedArray::new(&mut level.x);
    // The row just swept (i − 1 forward, i + 1 backward) is the one term that waits for the
    // previous row's result: the slots are summed so that it comes last (columns in
    // decreasing order forward, increasing backward), which keeps the chain of dependent
    // operations from one row to the next short (`block_lanes::update_rows`).
    in_sweep_order(
        team,
        a.n(),
        &level.blocks,
        &level.colours,
        backward,
        &|rows| {
            // SAFETY: `x` has `a.n()` vectors (asserted); the rows of this block are swept by this
            // part alone, and the rows they read are in this block or in blocks of another
            // colour, which no part writes meanwhile.
            unsafe { update_rows(a, inv_diag, b, x, rows.clone(), backward, omega) }
        },
    );
}

/// Calls `sweep_block` on each block of rows of a level of `n` rows in a sweep's order:
/// colour by colour, each colour's blocks in order, or everything reversed when `backward`
/// (the exact transpose of the forward order, even where a colour's blocks are not
/// independent: the overflow colour). The blocks of an independent colour are split over the
/// team (from [`PARALLEL_MIN_ROWS`] rows on), each part taking a contiguous span of them in
/// the same order, so each block is swept whole by one part whatever the number of parts.
fn in_sweep_order(
    team: TeamRef<'_>,
    n: usize,
    blocks: &[Rows],
    colours: &[(Rows, bool)],
    backward: bool,
    sweep_block: &(dyn Fn(&Rows) + Sync),
) {
    let sweep = |blocks: &[Rows]| {
        if backward {
            blocks.iter().rev().for_each(sweep_block);
        } else {
            blocks.iter().for_each(sweep_block);
        }
    };
    let parts = team.parts();
    let run = |(range, independent): &(Rows, bool)| {
        let colour = &blocks[range.clone()];
        if *independent && parts > 1 && n >= PARALLEL_MIN_ROWS && colour.len() > 1 {
            team.run(&|part| sweep(&colour[span(part, parts, colour.len())]));
        } else {
            sweep(colour);
        }
    };
    if backward {
        colours.iter().rev().for_each(run);
    } else {
        colours.iter().for_each(run);
    }
}

/// `Σₖ a[k] b[k]` over the shorter length, in four running sums (`k mod 4`) added as
/// `(s₀ + s₁) + (s₂ + s₃)`: a fixed order, so the same bits on every machine and thread count,
/// and four independent chains instead of one, which the compiler puts in one register. The
/// dense coarsest level's factor and solves are these dot products: summed one term after
/// another they waited on each addition (0.18 ms a factor of the 128 × 128 drape's 102 × 102
/// coarsest matrix, serial, three a frame).
#[inline]
pub fn dot_in_fours(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut s = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    for (k, (x, y)) in ra.iter().zip(rb).enumerate() {
        s[k] += x * y;
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// Cholesky factorisation `A = L Lᵀ` of the dense symmetric `m × m` row-major `a`, in place
/// (lower triangle; the strict upper triangle is left as it was). Each entry's sum over the
/// columns before it is a [`dot_in_fours`] of two rows. Returns `false` if a pivot is not
/// positive (the factor is then unusable).
pub fn cholesky_in_place(a: &mut [f64], m: usize) -> bool {
    assert!(a.len() >= m * m);
    for j in 0..m {
        // Rows before j are finished; row j and the rows after it are `rest`.
        let rest = &mut a[j * m..m * m];
        let (row_j, after) = rest.split_at_mut(m);
        let d = row_j[j] - dot_in_fours(&row_j[..j], &row_j[..j]);
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        row_j[j] = d;
        for row_i in after.chunks_exact_mut(m) {
            row_i[j] = (row_i[j] - dot_in_fours(&row_i[..j], &row_j[..j])) / d;
        }
    }
    true
}

/// Copies the factor `L` of [`cholesky_in_place`] into the strict upper triangle of the same
/// matrix as `Lᵀ` (row `i` then holds column `i` of `L` past the diagonal), which the
/// factorisation leaves unused, so that the backward substitution reads rows too.
pub fn mirror_factor(a: &mut [f64], m: usize) {
    assert!(a.len() >= m * m);
    for i in 0..m {
        for k in i + 1..m {
            a[i * m + k] = a[k * m + i];
        }
    }
}

/// Solves `L Lᵀ x = b` in place (`x` holds `b` on entry) with the factor `l` of
/// [`cholesky_in_place`], its transpose in the upper triangle ([`mirror_factor`]): forward
/// then backward substitution, each entry's sum a [`dot_in_fours`] of a row and the solved
/// entries.
pub fn cholesky_solve_in_place(l: &[f64], x: &mut [f64]) {
    let m = x.len();
    assert!(l.len() >= m * m);
    for i in 0..m {
        let (solved, rest) = x.split_at_mut(i);
        rest[0] = (rest[0] - dot_in_fours(&l[i * m..i * m + i], solved)) / l[i * m + i];
    }
    for i in (0..m).rev() {
        let (head, solved) = x.split_at_mut(i + 1);
        head[i] = (head[i] - dot_in_fours(&l[i * m + i + 1..(i + 1) * m], solved)) / l[i * m + i];
    }
}

/// What one [`Pcg::solve`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CgStats {
    /// Iterations run.
    pub iterations: u32,
    /// Final residual norm over the initial one.
    pub reduction: f64,
}

/// Conjugate gradients preconditioned by a V-cycle; owns its work vectors.
#[derive(Clone, Debug, Default)]
pub struct Pcg {
    r: Vec<DVec3>,
    z: Vec<DVec3>,
    p: Vec<DVec3>,
    q: Vec<DVec3>,
    /// The dot products' chunk sums ([`dot`]).
    partial: Vec<f64>,
}

/// Rows of one chunk of CG's dot products.
pub const DOT_CHUNK: usize = 1024;

/// `a · b`, in chunks of [`DOT_CHUNK`] rows split over the team, each chunk summed in order,
/// then the chunks' sums in order: the same bits whatever the thread count (and, below one
/// chunk, the plain sum's). `partial` holds a sum per chunk.
fn dot(team: TeamRef<'_>, a: &[DVec3], b: &[DVec3], partial: &mut [f64]) -> f64 {
    assert!(a.len() == b.len());
    let chunks = a.len().div_ceil(DOT_CHUNK);
    let partial = &mut partial[..chunks];
    team.for_ranges_mut(
        partial,
        PARALLEL_MIN_ROWS.div_ceil(DOT_CHUNK),
        &|range, sums| {
            for (c, sum) in range.zip(sums) {
                let rows = c * DOT_CHUNK..((c + 1) * DOT_CHUNK).min(a.len());
                *sum = a[rows.clone()]
                    .iter()
                    .zip(&b[rows])
                    .map(|(x, y)| x.dot(*y))
                    .sum();
            }
        },
    );
    partial.iter().sum()
}

impl Pcg {
    /// Work vectors for `n` block rows.
    pub fn new(n: usize) -> Pcg {
        Pcg {
            r: vec![DVec3::ZERO; n],
            z: vec![DVec3::ZERO; n],
            p: vec![DVec3::ZERO; n],
            q: vec![DVec3::ZERO; n],
            partial: vec![0.0; n.div_ceil(DOT_CHUNK)],
        }
    }

    /// At most `max_iterations` of CG on `A x = b` from `x = 0` (A: the hierarchy's fine
    /// matrix, updated), preconditioned by one V-cycle, stopping early once the residual is
    /// `tolerance` times the initial one or its norm at most `floor` (before any iteration if
    /// `b`'s is: then `x = 0`, no iteration and a reduction of 1).
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        team: TeamRef<'_>,
        h: &mut Hierarchy,
        b: &[DVec3],
        x: &mut [DVec3],
        max_iterations: u32,
        tolerance: f64,
        floor: f64,
    ) -> CgStats {
        assert!(b.len() == self.r.len());
        team.for_ranges_mut(x, PARALLEL_MIN_ROWS, &|_, xs| xs.fill(DVec3::ZERO));
        team.for_ranges_mut(&mut self.r, PARALLEL_MIN_ROWS, &|rows, rs| {
            rs.copy_from_slice(&b[rows])
        });
        let r0 = dot(team, &self.r, &self.r, &mut self.partial).sqrt();
        let mut stats = CgStats {
            iterations: 0,
            reduction: 1.0,
        };
        if !(r0 > 0.0 && r0.is_finite()) {
            stats.reduction = if r0 == 0.0 { 0.0 } else { f64::NAN };
            return stats;
        }
        if r0 <= floor {
            return stats;
        }
        h.v_cycle_in_place(team, &mut self.r, &mut self.z);
        self.p.copy_from_slice(&self.z);
        let mut rz = dot(team, &self.r, &self.z, &mut self.partial);
        for _ in 0..max_iterations {
            h.fine().mul(team, &self.p, &mut self.q);
            let pq = dot(team, &self.p, &self.q, &mut self.partial);
            if !(pq > 0.0 && rz.is_finite()) {
                break;
            }
            let alpha = rz / pq;
            let (p, q) = (&self.p, &self.q);
            assert!(x.len() == p.len() && self.r.len() == p.len() && q.len() == p.len());
            let (xs, rs) = (SharedArray::new(x), SharedArray::new(&mut self.r));
            for_parts(team, p.len(), &|rows| {
                for i in rows {
                    // SAFETY: `i` is in bounds of all four (asserted); each part its own rows.
                    unsafe {
                        *xs.at(i) += p[i] * alpha;
                        *rs.at(i) -= q[i] * alpha;
                    }
                }
            });
            stats.iterations += 1;
            let rn = dot(team, &self.r, &self.r, &mut self.partial).sqrt();
            stats.reduction = rn / r0;
            if stats.reduction <= tolerance || rn <= floor || stats.iterations == max_iterations {
                break;
            }
            h.v_cycle_in_place(team, &mut self.r, &mut self.z);
            let rz_new = dot(team, &self.r, &self.z, &mut self.partial);
            let beta = if h.pre_smoothing() {
                rz_new / rz
            } else {
                // Flexible CG for a cycle that is not symmetric: β = z·(r_new − r)/(z·r)_old,
                // where r_new − r = −α A p (Polak–Ribière); the symmetric cycle's z·r_old is 0.
                -alpha * dot(team, &self.z, &self.q, &mut self.partial) / rz
            };
            rz = rz_new;
            let z = &self.z;
            team.for_ranges_mut(&mut self.p, PARALLEL_MIN_ROWS, &|rows, ps| {
                for (pi, zi) in ps.iter_mut().zip(&z[rows]) {
                    *pi = *zi + *pi * beta;
                }
            });
        }
        stats
    }
}
#[cfg(test)]
#[path = "multigrid_tests.rs"]
mod tests;
