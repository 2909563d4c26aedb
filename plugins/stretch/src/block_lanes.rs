//! The multigrid's two block kernels — a row of a 3 × 3-block matrix times a vector, and a
//! Gauss-Seidel update of a row — with each block's product in one 256-bit register (AVX2)
//! where the processor has it: the three columns of the block in three registers, multiplied
//! by the three coordinates broadcast. The arithmetic is [`DMat3::mul_vec3`]'s, operation for
//! operation (`(c₀ vₓ + c₁ v_y) + c₂ v_z`, each product and sum rounded on its own, no fused
//! multiply-add), and the row's sum is taken in the same order, so every result has the bits
//! of the scalar code, which is the fallback without AVX2.
//!
//! Why: the V-cycle's block Gauss-Seidel sweeps and the products of conjugate gradients are
//! most of a `stretch_newton` step. A block's product is fifteen scalar multiplies and adds;
//! in the lanes it is three multiplies and two adds. Measured on the 128 × 128 drape (1 × 3 × 4
//! CG, compliance 1e-6, `plain_levels = 1`, 10 start passes), runs of the old and new plugin
//! alternating: about 7 % less time a frame on 2 threads (e.g. 32.9 → 30.7 ms) and 10–15 % on
//! one, every frame's positions the same to the bit.
//!
//! **Asking for the blocks ahead.** A Gauss-Seidel row waits for the row before it (its last
//! term), so the processor cannot run far ahead of the sweep to load the blocks it will need:
//! the sweep waited on memory, not on arithmetic. Timed level by level (the same drape, 2
//! threads), the forward sweep of a coarse level whose blocks had just been read in order took
//! a quarter of its usual time (level 3: 33 against 124 ms over the run, the reading 22 ms),
//! and the backward sweep of the fine level, 6.9 ms a frame, was slower than the forward one
//! (4.9 ms). So each row asks for the blocks of the row [`PREFETCH_ROWS`] ahead in the sweep's
//! order ([`prefetch`], a hint that changes no value): the fine level's two sweeps went from
//! 4.9 + 6.9 to 1.8 + 2.1 ms a frame, and the whole frame from 32.4–37.2 to 26.4–29.2 ms on 2
//! threads and from 78–85 to 53 ms on one (alternating runs). 2, 4, 8 and 16 rows ahead gave
//! 30.7, 29.7, 28.3 (25.5 in a quieter run) and 25.3 ms. The matrix products, whose rows are
//! independent, did not gain (slower with it: 1.4 against 1.1 ms a frame on the fine level),
//! nor did the Galerkin products' gather of fine blocks.
//!
//! **The Galerkin sums of a copying level** ([`weighted_sum`]). Where the prolongation only
//! copies (the plain levels), each term of a coarse block is a fine block times a product of
//! two weights that never changes: the products are kept per term, and the run of a coarse
//! block is summed in the lanes, eight entries at a time, with the scalar bits. Whole frames,
//! 5 alternating runs on 2 threads: min 23.9 against 24.8 ms, mean 27.8 against 29.7 ms.
//!
//! Tried and not kept: the smoother's blocks in single precision (half the bytes: slower in
//! scalar code, 42 against 33 ms a frame, and looser, the last frame's max strain 0.56 %
//! against 0.39 %); every Galerkin term's sum in the lanes through a closure returning the
//! term, turning ones included (slower: the sums took 23 % of the samples against 12.6 %);
//! sweeping two independent blocks of a colour interleaved, a row of each in turn, to overlap
//! the row-to-row chains (no measurable change, before the prefetch and again after it: min
//! of 6 alternating runs 28.9 against 28.3 ms); two rows of a product interleaved (no
//! change); the hint in the products; the fine and copying levels' blocks, which are exactly
//! symmetric, packed as six doubles for the sweeps and products (two thirds of the bytes, the
//! same bits, packed at each update: min of 5 alternating runs 26.0 against 25.5 ms on 2
//! threads, 48.9 against 47.7 on one); CG's product `A p` taken from the V-cycle's backward
//! sweep, `A z = r + E (z_old − z_new)` over the blocks of the columns the sweep changed
//! after each row, with `p`'s recurrence applied to it (exact to 1e-15 of `|A z|`, half a
//! product's blocks, but 1.00–1.08 times the time in round-robins of 14–16 runs, whether the
//! sweep wrote each row's change or a copy kept the old values; 2026-11-27).
//!
//! [`later_residuals`] (the V-cycle's residual after its forward sweep) reads its slots through
//! an index list: per block it costs about 1.65 times a product's (the perf samples of one run:
//! 6.7 % for 0.71 fine products' blocks a V-cycle against 5.7 % for CG's one product).
//!
//! Left unexplained: timed alone on a 128 × 128 cloth Hessian, a fine-level product takes
//! 0.19 ms, and 0.53 ms right after 8 MB of other data were touched (0.69 ms after 16 MB, 0.89
//! ms after 32 MB: this VM's share of the 32 MB cache is small); inside the V-cycle it takes
//! 0.6–0.7 ms, a forward sweep 0.35–0.4 ms. So the fine level's passes read their blocks from
//! memory, yet a third fewer bytes bought nothing measurable. Nor did less than half
//! (2026-11-28): the fine level's springs as four doubles `[u, c]` a block, `−(u uᵀ + c I)`,
//! read by every fine pass with the product `u (u·x) + c x` in the lanes, made the forward
//! sweep and its residual 1.15–1.5 times slower and CG 1.07–1.15 times (a microbenchmark
//! had given 0.55–0.85): once in cache, these passes wait on their arithmetic and the
//! row-to-row chain (`bench/README.md`, "The stop after").

use glam::{DMat3, DVec3};
use nucleus_sdk::lanes::avx2_available;
use nucleus_sdk::team::SharedArray;

use crate::multigrid::{BlockMatrix, Rows};

/// `Σ A[i, j] x[j]` over the slots of row `i`, in slot order, from zero.
#[inline]
fn row_product_scalar(a: &BlockMatrix, x: &[DVec3], i: usize) -> DVec3 {
    let mut sum = DVec3::ZERO;
    for s in a.start[i] as usize..a.start[i + 1] as usize {
        sum += a.val[s] * x[a.col[s] as usize];
    }
    sum
}

/// `y[k] = Σ A[i, j] x[j]` for the rows `i` of `rows` (`y[k]` for the `k`-th of them), each
/// sum in slot order from zero: [`BlockMatrix::mul`]'s rows.
pub(crate) fn row_products(a: &BlockMatrix, x: &[DVec3], rows: Rows, y: &mut [DVec3]) {
    assert!(x.len() >= a.n() && rows.end <= a.n() && y.len() >= rows.len());
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: AVX2 is present; the lengths are checked above.
        unsafe { avx2::row_products(a, x, rows, y) };
        return;
    }
    for (i, y) in rows.zip(y) {
        *y = row_product_scalar(a, x, i);
    }
}

/// Panics unless `runs[start[i]..start[i + 1]]` is in bounds for each row `i` of `rows` and
/// every such run `[s, e)` is a range of slots of `a`: the rows of one call only, since a sweep
/// calls block by block (a check of the whole level at each call made a sweep 3 times slower).
/// Debug builds only ([`debug_check_runs`]): it guards no memory access (every slot the kernels
/// read is indexed with a bounds check) and the runs come from `sweep_slots`, tested; in
/// release builds its pass over the runs was 1.5 % of a drape's samples (one thread).
fn check_runs(a: &BlockMatrix, start: &[u32], runs: &[[u32; 2]], rows: &Rows) {
    assert!(rows.start <= rows.end && rows.end < start.len());
    assert!(start[rows.start..=rows.end].is_sorted());
    let (first, last) = (start[rows.start] as usize, start[rows.end] as usize);
    assert!(last <= runs.len());
    assert!(runs[first..last]
        .iter()
        .all(|&[s, e]| s <= e && e as usize <= a.val.len()));
}

/// [`check_runs`] in debug builds (the test suite's), nothing in release builds.
#[inline(always)]
fn debug_check_runs(a: &BlockMatrix, start: &[u32], runs: &[[u32; 2]], rows: &Rows) {
    if cfg!(debug_assertions) {
        check_runs(a, start, runs, rows);
    }
}

/// `y[k] = c A[i, i] x[i] − Σ A[i, j] x[j]` over the slots
/// `later[later_start[i]..later_start[i + 1]]` of each row `i` of `rows` (`y[k]` for the `k`-th
/// of them), subtracted in order from the first term (`c = diagonal`; zero when it is). After
/// a forward Gauss-Seidel sweep from `x = 0` with relaxation weight `ω`, the residual `b − A x`
/// of each row, when `later` lists the slots whose columns the sweep visits after the row
/// ([`crate::multigrid`]'s `sweep_slots`) and `c = (1 − ω)/ω`: the row's sweep left
/// `A[i, i] x[i] = ω (b[i] − Σ_{earlier} A[i, j] x[j])`.
pub(crate) fn later_residuals(
    a: &BlockMatrix,
    later_start: &[u32],
    later: &[[u32; 2]],
    x: &[DVec3],
    rows: Rows,
    y: &mut [DVec3],
    diagonal: f64,
) {
    assert!(x.len() >= a.n() && y.len() >= rows.len());
    debug_check_runs(a, later_start, later, &rows);
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: AVX2 is present (the slots are indexed with bounds checks).
        unsafe { avx2::later_residuals(a, later_start, later, x, rows, y, diagonal) };
        return;
    }
    for (i, y) in rows.zip(y) {
        *y = later_residual_scalar(a, later_start, later, x, i, diagonal);
    }
}

/// Row `i` of [`later_residuals`], in scalar code.
#[inline]
fn later_residual_scalar(
    a: &BlockMatrix,
    later_start: &[u32],
    later: &[[u32; 2]],
    x: &[DVec3],
    i: usize,
    diagonal: f64,
) -> DVec3 {
    let mut sum = if diagonal == 0.0 {
        DVec3::ZERO
    } else {
        a.val[a.diag[i] as usize] * x[i] * diagonal
    };
    for &[start, end] in &later[later_start[i] as usize..later_start[i + 1] as usize] {
        for s in start as usize..end as usize {
            sum -= a.val[s] * x[a.col[s] as usize];
        }
    }
    sum
}

/// A forward Gauss-Seidel sweep's rows from `x = 0` ([`update_rows`] with every `x` zeroed
/// first, `backward == false`): row `i` sums only its slots in `earlier[earlier_start[i]..
/// earlier_start[i + 1]]` (runs `[start, end)` of the slots whose columns the sweep visits
/// before the row; [`crate::multigrid`]'s `sweep_slots`), in decreasing slot order, since the
/// others still hold zero, and its old value is that zero: the same bits (up to the sign of an
/// exact zero) for about half the blocks, and nothing to zero first.
///
/// # Safety
/// `x` holds at least `a.n()` vectors; the runs are slots of their rows; no other thread writes
/// a row of `rows` or any column those rows read, nor reads a row of `rows`, meanwhile.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn update_rows_from_zero(
    a: &BlockMatrix,
    inv_diag: &[DMat3],
    b: &[DVec3],
    x: SharedArray<DVec3>,
    earlier_start: &[u32],
    earlier: &[[u32; 2]],
    rows: Rows,
    omega: f64,
) {
    assert!(rows.end <= a.n() && inv_diag.len() >= a.n() && b.len() >= a.n());
    debug_check_runs(a, earlier_start, earlier, &rows);
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: AVX2 is present; the caller's contract, the lengths checked above.
        unsafe {
            avx2::update_rows_from_zero(a, inv_diag, b, x, earlier_start, earlier, rows, omega)
        };
        return;
    }
    for i in rows {
        prefetch_ahead(a, i, false);
        // SAFETY: the caller's contract.
        unsafe {
            update_row_from_zero_scalar(a, inv_diag[i], b[i], x, earlier_start, earlier, i, omega)
        }
    }
}

/// Row `i` of [`update_rows_from_zero`], in scalar code.
///
/// # Safety
/// The contract of [`update_rows_from_zero`] for row `i`.
#[inline]
#[allow(clippy::too_many_arguments)]
unsafe fn update_row_from_zero_scalar(
    a: &BlockMatrix,
    inv: DMat3,
    b: DVec3,
    x: SharedArray<DVec3>,
    earlier_start: &[u32],
    earlier: &[[u32; 2]],
    i: usize,
    omega: f64,
) {
    let mut sum = b;
    for &[start, end] in earlier[earlier_start[i] as usize..earlier_start[i + 1] as usize]
        .iter()
        .rev()
    {
        for s in (start as usize..end as usize).rev() {
            // SAFETY: the caller's contract.
            sum -= a.val[s] * unsafe { *x.at(a.col[s] as usize) };
        }
    }
    let update = inv * sum;
    // SAFETY: the caller's contract.
    unsafe {
        *x.at(i) = if omega == 1.0 {
            update
        } else {
            DVec3::ZERO + (update - DVec3::ZERO) * omega
        };
    }
}

/// One Gauss-Seidel update of row `i`: `x[i] = D⁻¹ (b[i] − Σ_{j ≠ i} A[i, j] x[j])`, the
/// slots taken in decreasing column order (`backward == false`) or increasing; with a
/// relaxation weight `omega ≠ 1`, `x[i]` moves by `omega` times that update (successive
/// over- or under-relaxation: `x + (update − x) ω`).
///
/// # Safety
/// `x` holds at least `a.n()` vectors; no other thread writes `x[i]` or any `x[j]` of the row
/// meanwhile.
#[inline]
unsafe fn update_row_scalar(
    a: &BlockMatrix,
    inv: DMat3,
    b: DVec3,
    x: SharedArray<DVec3>,
    i: usize,
    backward: bool,
    omega: f64,
) {
    let mut sum = b;
    let mut term = |s: usize| {
        let j = a.col[s] as usize;
        if j != i {
            // SAFETY: the caller's contract.
            sum -= a.val[s] * unsafe { *x.at(j) };
        }
    };
    let slots = a.start[i] as usize..a.start[i + 1] as usize;
    if backward {
        slots.for_each(&mut term);
    } else {
        slots.rev().for_each(&mut term);
    }
    // SAFETY: the caller's contract.
    unsafe {
        let update = inv * sum;
        *x.at(i) = if omega == 1.0 {
            update
        } else {
            *x.at(i) + (update - *x.at(i)) * omega
        };
    }
}

/// Gauss-Seidel updates ([`update_row_scalar`], relaxation weight `omega`) of the rows of
/// `rows` in increasing order, or in decreasing order with the slots reversed when
/// `backward`.
///
/// # Safety
/// `x` holds at least `a.n()` vectors; no other thread writes a row of `rows` or any column
/// those rows read, nor reads a row of `rows`, meanwhile.
pub(crate) unsafe fn update_rows(
    a: &BlockMatrix,
    inv_diag: &[DMat3],
    b: &[DVec3],
    x: SharedArray<DVec3>,
    rows: Rows,
    backward: bool,
    omega: f64,
) {
    assert!(rows.end <= a.n() && inv_diag.len() >= a.n() && b.len() >= a.n());
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: AVX2 is present; the caller's contract, the lengths checked above.
        unsafe { avx2::update_rows(a, inv_diag, b, x, rows, backward, omega) };
        return;
    }
    let row = |i: usize| {
        prefetch_ahead(a, i, backward);
        // SAFETY: the caller's contract.
        unsafe { update_row_scalar(a, inv_diag[i], b[i], x, i, backward, omega) }
    };
    if backward {
        rows.rev().for_each(row);
    } else {
        rows.for_each(row);
    }
}

/// `Σₖ val[terms[k].0] · weights[k]`, in order from zero: a coarse block of a Galerkin product
/// whose prolongation only copies (each term a fine block times the product of two weights).
/// In the lanes each entry's product and sum is rounded as the scalar `sum += a * w` rounds it.
pub(crate) fn weighted_sum(
    val: &[DMat3],
    terms: &[(u32, u32, u32, u32)],
    weights: &[f64],
) -> DMat3 {
    assert!(terms.len() == weights.len());
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: AVX2 is present.
        return unsafe { avx2::weighted_sum(val, terms, weights) };
    }
    let mut sum = DMat3::ZERO;
    for (t, &w) in terms.iter().zip(weights) {
        sum += val[t.0 as usize] * w;
    }
    sum
}

/// `Σₖ Bᵢᵀ val[s] Bⱼ` over the terms `(s, _, i, j)` of a coarse block of a Galerkin product
/// whose prolongation turns: `B` a copy `w I` or a turn `w S(r)` (`weight`, `turn`, `arm` per
/// prolongation entry, as in [`crate::multigrid::Prolongation`]), in the lanes — each block
/// three column registers — with the bits of the scalar terms (`a * (wᵢ wⱼ)`, then
/// `m S(rⱼ)` column by column as `m * (eₖ × rⱼ)`, then `rᵢ ×` each column, summed in order).
/// `None` without AVX2: the caller sums the scalar terms.
pub(crate) fn turning_sum(
    val: &[DMat3],
    terms: &[(u32, u32, u32, u32)],
    weight: &[f64],
    turn: &[bool],
    arm: &[DVec3],
) -> Option<DMat3> {
    assert!(weight.len() == turn.len() && arm.len() == turn.len());
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: AVX2 is present.
        return Some(unsafe { avx2::turning_sum(val, terms, weight, turn, arm) });
    }
    None
}

/// Asks the processor for the cache lines of `count` values from `p` on: a hint, which reads
/// nothing, cannot fault, and does nothing on processors other than x86_64.
#[inline(always)]
fn prefetch<T>(p: *const T, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let first = p as *const i8;
        for offset in (0..count * std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: SSE, which the intrinsic needs, is part of every x86_64 processor; a
            // prefetch reads nothing and cannot fault, whatever the address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(first.wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, count);
}

/// How many rows ahead a Gauss-Seidel sweep asks for a row's blocks.
const PREFETCH_ROWS: usize = 8;

/// Asks for the blocks of the row [`PREFETCH_ROWS`] after row `i` in a sweep's order (before
/// it when `backward`), if there is one.
#[inline(always)]
fn prefetch_ahead(a: &BlockMatrix, i: usize, backward: bool) {
    let ahead = if backward {
        i.checked_sub(PREFETCH_ROWS)
    } else {
        Some(i + PREFETCH_ROWS).filter(|&k| k < a.n())
    };
    if let Some(k) = ahead {
        let (from, to) = (a.start[k] as usize, a.start[k + 1] as usize);
        prefetch(a.val.as_ptr().wrapping_add(from), to - from);
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use glam::{DMat3, DVec3};
    use nucleus_sdk::team::SharedArray;

    use crate::multigrid::{BlockMatrix, Rows};

    /// The three columns of `m`, one a register (lanes 0..2; lane 3 is not meaningful).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn columns(m: &DMat3) -> [__m256d; 3] {
        // A `DMat3` is nine `f64`, column after column (`repr(C)`).
        let m = m as *const DMat3 as *const f64;
        // SAFETY: every load is within the nine doubles of `m` (the third column is loaded
        // from one double before it, then turned into place).
        unsafe {
            [
                _mm256_loadu_pd(m),
                _mm256_loadu_pd(m.add(3)),
                _mm256_permute4x64_pd::<0b00_11_10_01>(_mm256_loadu_pd(m.add(5))),
            ]
        }
    }

    /// `(c₀ b₀ + c₁ b₁) + c₂ b₂`, lane by lane: [`DMat3::mul_vec3`]'s operations for the
    /// columns `c` and a vector's coordinates broadcast in `b`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn combine(c: [__m256d; 3], b: [__m256d; 3]) -> __m256d {
        let t = _mm256_mul_pd(c[0], b[0]);
        let t = _mm256_add_pd(t, _mm256_mul_pd(c[1], b[1]));
        _mm256_add_pd(t, _mm256_mul_pd(c[2], b[2]))
    }

    /// `m v`, lanes 0..2 (lane 3 is not meaningful), with [`DMat3::mul_vec3`]'s operations.
    ///
    /// # Safety
    /// `v` is valid to read; AVX2 is present.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn block_times(m: &DMat3, v: *const DVec3) -> __m256d {
        // A `DVec3` is three `f64` (`repr(C)`).
        let v = v as *const f64;
        // SAFETY: the three doubles of `v`.
        let b = unsafe {
            [
                _mm256_broadcast_sd(&*v),
                _mm256_broadcast_sd(&*v.add(1)),
                _mm256_broadcast_sd(&*v.add(2)),
            ]
        };
        combine(columns(m), b)
    }

    /// `m s` for `s` in lanes 0..2 of a register, as [`block_times`].
    #[inline]
    #[target_feature(enable = "avx2")]
    fn block_times_lanes(m: &DMat3, s: __m256d) -> __m256d {
        let b = [
            _mm256_permute4x64_pd::<0b00_00_00_00>(s),
            _mm256_permute4x64_pd::<0b01_01_01_01>(s),
            _mm256_permute4x64_pd::<0b10_10_10_10>(s),
        ];
        combine(columns(m), b)
    }

    /// Lanes 0..2 of `v`, lane 3 zero.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn lanes_of(v: DVec3) -> __m256d {
        _mm256_setr_pd(v.x, v.y, v.z, 0.0)
    }

    /// Writes lanes 0..2 of `s` to `*p`.
    ///
    /// # Safety
    /// `p` is valid to write; AVX2 is present.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn store(p: *mut DVec3, s: __m256d) {
        let p = p as *mut f64;
        // SAFETY: the three doubles of `*p`.
        unsafe {
            _mm_storeu_pd(p, _mm256_castpd256_pd128(s));
            _mm_store_sd(p.add(2), _mm256_extractf128_pd::<1>(s));
        }
    }

    /// [`super::row_products`] in the lanes.
    ///
    /// # Safety
    /// AVX2 is present; `x` has `a.n()` vectors, `rows` are rows of `a`, `y` has a vector per
    /// row of `rows`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn row_products(a: &BlockMatrix, x: &[DVec3], rows: Rows, y: &mut [DVec3]) {
        for (i, y) in rows.zip(y) {
            let mut sum = _mm256_setzero_pd();
            for s in a.start[i] as usize..a.start[i + 1] as usize {
                let j = a.col[s] as usize;
                // SAFETY: `s` is a slot and `j < a.n() <= x.len()` a column of the matrix.
                sum = _mm256_add_pd(sum, unsafe { block_times(&a.val[s], &x[j]) });
            }
            // SAFETY: `y` is a valid vector.
            unsafe { store(y, sum) };
        }
    }

    /// [`super::later_residuals`] in the lanes.
    ///
    /// # Safety
    /// AVX2 is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn later_residuals(
        a: &BlockMatrix,
        later_start: &[u32],
        later: &[[u32; 2]],
        x: &[DVec3],
        rows: Rows,
        y: &mut [DVec3],
        diagonal: f64,
    ) {
        let weight = _mm256_set1_pd(diagonal);
        for (i, y) in rows.zip(y) {
            let mut sum = if diagonal == 0.0 {
                _mm256_setzero_pd()
            } else {
                // SAFETY: `&x[i]` is a valid vector (indexed with a bounds check).
                let d = unsafe { block_times(&a.val[a.diag[i] as usize], &x[i]) };
                _mm256_mul_pd(d, weight)
            };
            for &[start, end] in &later[later_start[i] as usize..later_start[i + 1] as usize] {
                let run = start as usize..end as usize;
                for (m, &j) in a.val[run.clone()].iter().zip(&a.col[run]) {
                    // SAFETY: `&x[j]` is a valid vector (indexed with a bounds check).
                    sum = _mm256_sub_pd(sum, unsafe { block_times(m, &x[j as usize]) });
                }
            }
            // SAFETY: `y` is a valid vector.
            unsafe { store(y, sum) };
        }
    }

    /// [`super::update_rows`] in the lanes.
    ///
    /// # Safety
    /// AVX2 is present; the contract of [`super::update_rows`].
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn update_rows(
        a: &BlockMatrix,
        inv_diag: &[DMat3],
        b: &[DVec3],
        x: SharedArray<DVec3>,
        rows: Rows,
        backward: bool,
        omega: f64,
    ) {
        let weight = _mm256_set1_pd(omega);
        let row = |i: usize| {
            super::prefetch_ahead(a, i, backward);
            let mut sum = lanes_of(b[i]);
            let mut term = |s: usize| {
                let j = a.col[s] as usize;
                if j != i {
                    // SAFETY: `j` is a column of the matrix, in `x`; the caller's contract.
                    sum = _mm256_sub_pd(sum, unsafe { block_times(&a.val[s], x.at(j)) });
                }
            };
            let slots = a.start[i] as usize..a.start[i + 1] as usize;
            if backward {
                slots.for_each(&mut term);
            } else {
                slots.rev().for_each(&mut term);
            }
            let mut update = block_times_lanes(&inv_diag[i], sum);
            if omega != 1.0 {
                // `x + (update − x) ω`, as the scalar rows round it.
                // SAFETY: `i` is a row of the matrix, in `x`; the caller's contract.
                let old = lanes_of(unsafe { *x.at(i) });
                update = _mm256_add_pd(old, _mm256_mul_pd(_mm256_sub_pd(update, old), weight));
            }
            // SAFETY: `i` is a row of the matrix, in `x`; the caller's contract.
            unsafe { store(x.at(i), update) };
        };
        if backward {
            rows.rev().for_each(row);
        } else {
            rows.for_each(row);
        }
    }

    /// [`super::update_rows_from_zero`] in the lanes.
    ///
    /// # Safety
    /// AVX2 is present; the contract of [`super::update_rows_from_zero`].
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn update_rows_from_zero(
        a: &BlockMatrix,
        inv_diag: &[DMat3],
        b: &[DVec3],
        x: SharedArray<DVec3>,
        earlier_start: &[u32],
        earlier: &[[u32; 2]],
        rows: Rows,
        omega: f64,
    ) {
        let (weight, zero) = (_mm256_set1_pd(omega), _mm256_setzero_pd());
        for i in rows {
            super::prefetch_ahead(a, i, false);
            let mut sum = lanes_of(b[i]);
            let runs = &earlier[earlier_start[i] as usize..earlier_start[i + 1] as usize];
            for &[start, end] in runs.iter().rev() {
                for s in (start as usize..end as usize).rev() {
                    let j = a.col[s] as usize;
                    // SAFETY: `j` is a column of the matrix, in `x`; the caller's contract.
                    sum = _mm256_sub_pd(sum, unsafe { block_times(&a.val[s], x.at(j)) });
                }
            }
            let mut update = block_times_lanes(&inv_diag[i], sum);
            if omega != 1.0 {
                // `0 + (update − 0) ω`: the scalar row's rounding from a zeroed `x`.
                update = _mm256_add_pd(zero, _mm256_mul_pd(_mm256_sub_pd(update, zero), weight));
            }
            // SAFETY: `i` is a row of the matrix, in `x`; the caller's contract.
            unsafe { store(x.at(i), update) };
        }
    }

    /// [`super::weighted_sum`] in the lanes: entries 0..3 and 4..7 of each block in two
    /// registers, entry 8 alone.
    ///
    /// # Safety
    /// AVX2 is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn weighted_sum(
        val: &[DMat3],
        terms: &[(u32, u32, u32, u32)],
        weights: &[f64],
    ) -> DMat3 {
        let (mut low, mut high, mut last) = (_mm256_setzero_pd(), _mm256_setzero_pd(), 0.0);
        for (t, &w) in terms.iter().zip(weights) {
            // A block is nine doubles, column after column (`repr(C)`).
            let e = &val[t.0 as usize] as *const DMat3 as *const f64;
            let w4 = _mm256_set1_pd(w);
            // SAFETY: entries 0..3, 4..7 and 8 of the block.
            unsafe {
                low = _mm256_add_pd(low, _mm256_mul_pd(_mm256_loadu_pd(e), w4));
                high = _mm256_add_pd(high, _mm256_mul_pd(_mm256_loadu_pd(e.add(4)), w4));
                last += *e.add(8) * w;
            }
        }
        let mut e = [0.0; 9];
        // SAFETY: `e` holds nine doubles: entries 0..3 and 4..7.
        unsafe {
            _mm256_storeu_pd(e.as_mut_ptr(), low);
            _mm256_storeu_pd(e.as_mut_ptr().add(4), high);
        }
        e[8] = last;
        DMat3::from_cols_array(&e)
    }

    /// [`super::turning_sum`] in the lanes.
    ///
    /// # Safety
    /// AVX2 is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn turning_sum(
        val: &[DMat3],
        terms: &[(u32, u32, u32, u32)],
        weight: &[f64],
        turn: &[bool],
        arm: &[DVec3],
    ) -> DMat3 {
        let mut sum = [_mm256_setzero_pd(); 3];
        for &(s, _, i, j) in terms {
            let (i, j) = (i as usize, j as usize);
            let w = _mm256_set1_pd(weight[i] * weight[j]);
            let [mut x, mut y, mut z] = columns(&val[s as usize]).map(|c| _mm256_mul_pd(c, w));
            if turn[j] {
                // Column k becomes m (eₖ × r), as glam's `m * v`: (x vₓ + y v_y) + z v_z.
                let r = arm[j];
                let column =
                    |v: DVec3| combine([x, y, z], [v.x, v.y, v.z].map(|c| _mm256_set1_pd(c)));
                [x, y, z] = [
                    column(DVec3::new(0.0, -r.z, r.y)),
                    column(DVec3::new(r.z, 0.0, -r.x)),
                    column(DVec3::new(-r.y, r.x, 0.0)),
                ];
            }
            if turn[i] {
                // Each column c becomes r × c, as glam's `cross`: (r_y c_z − c_y r_z, …).
                let r = arm[i];
                let r_yzx = _mm256_setr_pd(r.y, r.z, r.x, 0.0);
                let r_zxy = _mm256_setr_pd(r.z, r.x, r.y, 0.0);
                let cross = |c: __m256d| {
                    let c_zxy = _mm256_permute4x64_pd::<0b11_01_00_10>(c);
                    let c_yzx = _mm256_permute4x64_pd::<0b11_00_10_01>(c);
                    _mm256_sub_pd(_mm256_mul_pd(r_yzx, c_zxy), _mm256_mul_pd(c_yzx, r_zxy))
                };
                [x, y, z] = [cross(x), cross(y), cross(z)];
            }
            sum = [
                _mm256_add_pd(sum[0], x),
                _mm256_add_pd(sum[1], y),
                _mm256_add_pd(sum[2], z),
            ];
        }
        let mut e = [0.0; 12];
        // SAFETY: `e` holds twelve doubles; the stores write 0..4, 3..7 and 6..10, each column
        // after the one before (lane 3 of a column is overwritten by the next).
        unsafe {
            _mm256_storeu_pd(e.as_mut_ptr(), sum[0]);
            _mm256_storeu_pd(e.as_mut_ptr().add(3), sum[1]);
            _mm256_storeu_pd(e.as_mut_ptr().add(6), sum[2]);
        }
        DMat3::from_cols_slice(&e[..9])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random sparse block matrix (about `per_row` off-diagonal blocks a row, values of
    /// both signs and magnitudes from 1e-3 to 1e6) and a random vector.
    fn random(n: usize, per_row: usize, seed: u64) -> (BlockMatrix, Vec<DMat3>, Vec<DVec3>) {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut pairs = Vec::new();
        for i in 0..n {
            for _ in 0..per_row {
                let j = (next() * n as f64) as usize % n;
                if j != i {
                    pairs.push((i as u32, j as u32));
                }
            }
        }
        let mut a = BlockMatrix::with_pattern(n, pairs);
        let mut value = || (next() - 0.5) * 10f64.powf(next() * 9.0 - 3.0);
        for v in a.val.iter_mut() {
            *v = DMat3::from_cols_array(&std::array::from_fn(|_| value()));
        }
        let inv: Vec<DMat3> = (0..n)
            .map(|_| DMat3::from_cols_array(&std::array::from_fn(|_| value())))
            .collect();
        let x = (0..n)
            .map(|_| DVec3::new(value(), value(), value()))
            .collect();
        (a, inv, x)
    }

    fn bits(v: &[DVec3]) -> Vec<[u64; 3]> {
        v.iter()
            .map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect()
    }

    #[test]
    fn later_residuals_have_the_bits_of_the_scalar_sums() {
        // Runs of one and of two slots of each row as its "later" list (the first slot alone,
        // then every other pair), with and without the diagonal term.
        let (a, _, x) = random(300, 6, 3);
        let mut later_start = vec![0u32];
        let mut later = Vec::new();
        for i in 0..a.n() {
            let (start, end) = (a.start[i], a.start[i + 1]);
            later.push([start, start + 1]);
            later.extend((start + 1..end).step_by(4).map(|s| [s, (s + 2).min(end)]));
            later_start.push(later.len() as u32);
        }
        for diagonal in [0.0, 0.25, -0.3] {
            let mut y = vec![DVec3::ZERO; a.n()];
            later_residuals(&a, &later_start, &later, &x, 0..a.n(), &mut y, diagonal);
            let scalar: Vec<DVec3> = (0..a.n())
                .map(|i| later_residual_scalar(&a, &later_start, &later, &x, i, diagonal))
                .collect();
            assert_eq!(bits(&y), bits(&scalar), "diagonal {diagonal}");
            assert!(y.iter().any(|v| *v != DVec3::ZERO), "nothing summed");
            let mut part = vec![DVec3::ZERO; 7];
            later_residuals(&a, &later_start, &later, &x, 100..107, &mut part, diagonal);
            assert_eq!(bits(&part), bits(&scalar[100..107]), "diagonal {diagonal}");
        }
    }

    #[test]
    #[should_panic]
    fn a_run_past_the_slots_panics_in_every_build() {
        // Debug builds catch it in `check_runs`; release builds, which skip that pass, at the
        // slot's bounds-checked read: never a read out of bounds.
        let (a, _, x) = random(20, 3, 4);
        let slots = a.val.len() as u32;
        let later_start = [0u32, 1];
        let later = [[slots - 1, slots + 1]];
        let mut y = vec![DVec3::ZERO; 1];
        later_residuals(&a, &later_start, &later, &x, 0..1, &mut y, 0.0);
    }

    #[test]
    fn row_products_have_the_bits_of_the_scalar_block_products() {
        let (a, _, x) = random(300, 6, 1);
        let mut y = vec![DVec3::ZERO; a.n()];
        row_products(&a, &x, 0..a.n(), &mut y);
        let scalar: Vec<DVec3> = (0..a.n()).map(|i| row_product_scalar(&a, &x, i)).collect();
        assert_eq!(bits(&y), bits(&scalar));
        // And a sub-range lands at the start of `y`.
        let mut part = vec![DVec3::ZERO; 7];
        row_products(&a, &x, 100..107, &mut part);
        assert_eq!(bits(&part), bits(&scalar[100..107]));
        if !avx2_available() {
            eprintln!("no AVX2 here: the lanes were not exercised");
        }
    }

    #[test]
    fn weighted_sums_have_the_bits_of_the_scalar_sums() {
        let (a, inv, _) = random(60, 4, 5);
        let terms: Vec<(u32, u32, u32, u32)> = (0..50)
            .map(|k| ((k * 7 % a.val.len()) as u32, 0, 0, 0))
            .collect();
        let weights: Vec<f64> = (0..50).map(|k| inv[k].x_axis.y).collect();
        let lanes = weighted_sum(&a.val, &terms, &weights);
        let mut scalar = DMat3::ZERO;
        for (t, &w) in terms.iter().zip(&weights) {
            scalar += a.val[t.0 as usize] * w;
        }
        let bits = |m: DMat3| m.to_cols_array().map(f64::to_bits);
        assert_eq!(bits(lanes), bits(scalar));
        assert_ne!(scalar, DMat3::ZERO);
    }

    #[test]
    fn gauss_seidel_rows_from_zero_have_the_bits_of_the_scalar_updates() {
        // Runs of one and of two slots below the diagonal as the "earlier" lists (the rows swept
        // in order, so a row reads values the sweep already wrote), relaxed or not.
        let (a, inv, b) = random(300, 6, 4);
        let mut earlier_start = vec![0u32];
        let mut earlier = Vec::new();
        for i in 0..a.n() {
            let (start, diag) = (a.start[i], a.diag[i]);
            earlier.extend((start..diag).step_by(3).map(|s| [s, (s + 2).min(diag)]));
            earlier_start.push(earlier.len() as u32);
        }
        assert!(
            earlier.iter().any(|r| r[1] - r[0] == 2) && earlier.iter().any(|r| r[1] - r[0] == 1)
        );
        for omega in [1.0, 0.8, 1.3] {
            for rows in [0..a.n(), 37..211] {
                let (mut lanes, mut scalar) = (b.clone(), b.clone());
                let shared = SharedArray::new(&mut lanes);
                // SAFETY: one thread; `lanes` has a vector per row, the runs are the rows' slots.
                unsafe {
                    update_rows_from_zero(
                        &a,
                        &inv,
                        &b,
                        shared,
                        &earlier_start,
                        &earlier,
                        rows.clone(),
                        omega,
                    )
                };
                let shared = SharedArray::new(&mut scalar);
                for i in rows.clone() {
                    // SAFETY: as above.
                    unsafe {
                        update_row_from_zero_scalar(
                            &a,
                            inv[i],
                            b[i],
                            shared,
                            &earlier_start,
                            &earlier,
                            i,
                            omega,
                        )
                    };
                }
                let what = format!("omega {omega}, rows {rows:?}");
                assert_eq!(bits(&lanes), bits(&scalar), "{what}");
                assert!(lanes != b, "{what}: the sweep changed nothing");
            }
        }
    }

    #[test]
    fn gauss_seidel_rows_have_the_bits_of_the_scalar_updates() {
        // Plain Gauss-Seidel and under- and over-relaxed.
        let (a, inv, b) = random(300, 6, 2);
        for omega in [1.0, 0.8, 1.3] {
            for backward in [false, true] {
                for rows in [0..a.n(), 37..211] {
                    let (mut lanes, mut scalar) = (b.clone(), b.clone());
                    let shared = SharedArray::new(&mut lanes);
                    // SAFETY: one thread; `lanes` has a vector per row.
                    unsafe { update_rows(&a, &inv, &b, shared, rows.clone(), backward, omega) };
                    let shared = SharedArray::new(&mut scalar);
                    let order: Vec<usize> = if backward {
                        rows.clone().rev().collect()
                    } else {
                        rows.clone().collect()
                    };
                    for i in order {
                        // SAFETY: as above.
                        unsafe { update_row_scalar(&a, inv[i], b[i], shared, i, backward, omega) };
                    }
                    let what = format!("omega {omega}, backward {backward}, rows {rows:?}");
                    assert_eq!(bits(&lanes), bits(&scalar), "{what}");
                    assert!(lanes != b, "{what}: the sweep changed nothing");
                }
            }
        }
    }
}
