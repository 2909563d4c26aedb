//! The search over the parameter domain shared by both queries: the cells of each query
//! (point–triangle: `t` and a sub-triangle of barycentrics; edge–edge: `t` and the two edge
//! parameters), how they are examined and split, and the depth-first then best-first order
//! in which they are visited.

use glam::DVec3;

use super::inclusion::Bounds;
use super::CcdResult;

/// Halvings of `t` and of each edge parameter (and 2× for the barycentric triangle, whose
/// bisection halves its legs every two levels): every midpoint stays an exact dyadic
/// rational with at most 50 bits.
const MAX_LEVEL: u8 = 50;

/// Once the search goes by time, `t` is halved unless the spatial spread of the corner
/// values exceeds the temporal one by more than this factor's inverse: no preference costs
/// many more cells on grazing contacts, time always first wastes the work bound on long
/// contacts (`docs/decisions/collision_ccd_tolerance.md`).
const TIME_BIAS: f64 = 1.0 / 32.0;

/// What examining a cell tells.
pub(super) struct Examined {
    /// The computed corner values (the first `n`; the first `n / 2` at the start time).
    pub(super) corners: [DVec3; 8],
    pub(super) n: usize,
    pub(super) lo: DVec3,
    pub(super) hi: DVec3,
    /// How far the corner values spread along `t` (max-norm), or `None` when `t` is at its
    /// finest level.
    pub(super) spread_t: Option<f64>,
    /// The spatial parameter whose halving helps most and its spread, or `None` when every
    /// spatial parameter is at its finest level.
    pub(super) space: Option<(u8, f64)>,
}

/// A cell of the parameter domain (`t` and the spatial parameters).
pub(super) trait Cell: Copy {
    type Query;
    /// Start time of the cell.
    fn t0(&self) -> f64;
    /// End time of the cell.
    fn t1(&self) -> f64;
    /// Number of halvings that made the cell.
    fn level(&self) -> u32;
    /// Corner-value bounds and the most useful split.
    fn examine(&self, query: &Self::Query) -> Examined;
    /// The two halves along parameter `dim`, the one to explore first (earlier `t`) first.
    fn split(&self, dim: u8) -> (Self, Self);
}

/// The search shared by both queries, in two phases.
///
/// 1. Depth first, earlier half in time first, until a first cell is accepted: a quick
///    upper bound `best` on the time of impact (or, if none, the proof that there is none:
///    every cell discarded).
/// 2. Best first: the pending cells in order of start time (deeper first among equal
///    starts), so the first cell accepted is the earliest; cells starting at or after
///    `best` are dropped, and a cell reaching past `best` is cut in time first (its later
///    half is then dropped for free).
///
/// Depth first alone can chase a contact that starts early and persists (coplanar edges
/// sweeping across each other: each spatial sub-cell gives a slightly earlier contact);
/// best first alone spreads over every cell along a contact that happens everywhere at once
/// (parallel edges landing flat: all those cells start at the same time). Together they do
/// well on both.
pub(super) fn search<C: Cell>(
    root: C,
    query: &C::Query,
    bounds: &Bounds,
    max_boxes: u32,
) -> CcdResult {
    // The root alone decides most queries: spare them the queue.
    let first = root.examine(query);
    let mut hint = DVec3::ZERO;
    if bounds.excludes(&first, &mut hint) {
        return CcdResult {
            toi: None,
            margin: bounds.margin,
            boxes: 1,
            certified: true,
        };
    }
    // A small queue suffices for nearly every query; the rare one that outgrows it is run
    // again with a large one (the search is deterministic, so only time is lost).
    match search_in::<C, SMALL_QUEUE>(root, query, bounds, max_boxes) {
        (result, false) => result,
        (_, true) => search_in::<C, LARGE_QUEUE>(root, query, bounds, max_boxes).0,
    }
}

/// [`search`] with a queue of `N` cells, and whether that queue overflowed (the answer is
/// then the conservative one: the earliest start of any cell not yet discarded).
// Never inlined: its frame holds the queue (up to 150 kB for the large one), which would
// otherwise be reserved, and probed page by page, even by queries that end before any search.
#[inline(never)]
fn search_in<C: Cell, const N: usize>(
    root: C,
    query: &C::Query,
    bounds: &Bounds,
    max_boxes: u32,
) -> (CcdResult, bool) {
    let mut result = CcdResult {
        toi: None,
        margin: bounds.margin,
        boxes: 0,
        certified: true,
    };
    let mut queue = Queue::<C, N>::new(root);
    queue.push(root);
    let mut best = f64::INFINITY;
    let mut hint = DVec3::ZERO;
    // Give up, conservatively: no contact before the earliest start of the cells not yet
    // discarded (`cell` and the queue).
    let give_up = |cell: &C, queue: &Queue<C, N>, best: f64, mut result: CcdResult| {
        let pending = queue.earliest().unwrap_or(f64::INFINITY);
        result.toi = Some(best.min(pending).min(cell.t0()));
        result.certified = false;
        result
    };
    while let Some(cell) = queue.pop() {
        let t0 = cell.t0();
        if t0 >= best {
            if queue.by_time {
                break;
            }
            continue;
        }
        if result.boxes >= max_boxes {
            return (give_up(&cell, &queue, best, result), false);
        }
        result.boxes += 1;
        let ex = cell.examine(query);
        if bounds.excludes(&ex, &mut hint) {
            continue;
        }
        let split = if bounds.accepts(&ex) {
            None
        } else if cell.t1() > best && ex.spread_t.is_some() {
            Some(0)
        } else {
            // Halve the parameter that spreads the values most; once the search goes by time,
            // prefer `t` (a later half waits, and is dropped if a contact comes first).
            let bias = if queue.by_time { TIME_BIAS } else { 1.0 };
            match (ex.spread_t, ex.space) {
                (Some(wt), Some((dim, ws))) => Some(if wt >= bias * ws { 0 } else { dim }),
                (Some(_), None) => Some(0),
                (None, Some((dim, _))) => Some(dim),
                (None, None) => {
                    // At the finest parameter resolution: a contact as far as floating
                    // point can tell, and still no later than the true one.
                    result.certified = false;
                    None
                }
            }
        };
        let Some(dim) = split else {
            // Accepted.
            best = t0;
            if queue.by_time {
                break;
            }
            queue.order_by_time();
            continue;
        };
        if queue.len + 2 > N {
            return (give_up(&cell, &queue, best, result), true);
        }
        let (head, tail) = cell.split(dim);
        if tail.t0() < best {
            queue.push(tail);
        }
        queue.push(head);
    }
    if best.is_finite() {
        result.toi = Some(best);
    }
    (result, false)
}

/// Capacity of the search queue (cells waiting to be examined) of the first attempt.
const SMALL_QUEUE: usize = 64;
/// Capacity of the queue of the second attempt, when the first overflowed.
const LARGE_QUEUE: usize = 2048;

/// The pending cells: a stack (depth first) until [`Queue::order_by_time`], then a binary
/// min-heap by start time, deeper first among equal starts. A fixed array: no allocation.
struct Queue<C: Cell, const N: usize> {
    cells: [C; N],
    len: usize,
    by_time: bool,
    peak: usize,
}

impl<C: Cell, const N: usize> Queue<C, N> {
    fn new(fill: C) -> Self {
        Self {
            cells: [fill; N],
            len: 0,
            by_time: false,
            peak: 0,
        }
    }

    #[inline]
    fn before(a: &C, b: &C) -> bool {
        a.t0() < b.t0() || (a.t0() == b.t0() && a.level() > b.level())
    }

    /// The earliest start among the pending cells.
    fn earliest(&self) -> Option<f64> {
        self.cells[..self.len].iter().map(Cell::t0).reduce(f64::min)
    }

    /// Switch to best first: heapify the pending cells.
    fn order_by_time(&mut self) {
        self.by_time = true;
        for i in (0..self.len / 2).rev() {
            self.sift_down(i);
        }
    }

    fn push(&mut self, cell: C) {
        let mut i = self.len;
        self.cells[i] = cell;
        self.len += 1;
        self.peak = self.peak.max(self.len);
        if !self.by_time {
            return;
        }
        while i > 0 {
            let parent = (i - 1) / 2;
            if !Self::before(&self.cells[i], &self.cells[parent]) {
                break;
            }
            self.cells.swap(i, parent);
            i = parent;
        }
    }

    fn pop(&mut self) -> Option<C> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        if !self.by_time {
            return Some(self.cells[self.len]);
        }
        let top = self.cells[0];
        self.cells[0] = self.cells[self.len];
        self.sift_down(0);
        Some(top)
    }

    fn sift_down(&mut self, mut i: usize) {
        loop {
            let (l, r) = (2 * i + 1, 2 * i + 2);
            let mut m = i;
            if l < self.len && Self::before(&self.cells[l], &self.cells[m]) {
                m = l;
            }
            if r < self.len && Self::before(&self.cells[r], &self.cells[m]) {
                m = r;
            }
            if m == i {
                break;
            }
            self.cells.swap(i, m);
            i = m;
        }
    }
}

/// `(1 − t) x + t y` with the weights formed exactly (`t` dyadic), as the error bound assumes.
#[inline]
fn lerp(x: DVec3, y: DVec3, t: f64) -> DVec3 {
    (1.0 - t) * x + t * y
}

/// Point–triangle differences `eᵢᵏ = pᵏ − xᵢᵏ`, `i = a, b, c`.
pub(super) struct PtQuery {
    pub(super) e0: [DVec3; 3],
    pub(super) e1: [DVec3; 3],
}

/// `[t₀, t₁]` × a right isosceles sub-triangle of the barycentric triangle, given by the
/// `(u, v)` = `(β_b, β_c)` of its vertices, the right angle first.
#[derive(Clone, Copy)]
pub(super) struct PtCell {
    pub(super) t: [f64; 2],
    pub(super) uv: [[f64; 2]; 3],
    pub(super) level_t: u8,
    pub(super) level_uv: u8,
}

impl Cell for PtCell {
    type Query = PtQuery;

    #[inline]
    fn t0(&self) -> f64 {
        self.t[0]
    }

    #[inline]
    fn t1(&self) -> f64 {
        self.t[1]
    }

    #[inline]
    fn level(&self) -> u32 {
        self.level_t as u32 + self.level_uv as u32
    }

    fn examine(&self, q: &PtQuery) -> Examined {
        let mut f = [DVec3::ZERO; 6];
        for k in 0..2 {
            let t = self.t[k];
            // Written out: `[0, 1, 2].map(…)` stayed a call here (`try_map`, ~9 % of a
            // self-colliding cloth's step).
            let g = [
                lerp(q.e0[0], q.e1[0], t),
                lerp(q.e0[1], q.e1[1], t),
                lerp(q.e0[2], q.e1[2], t),
            ];
            for j in 0..3 {
                let [u, v] = self.uv[j];
                let w = 1.0 - u - v;
                f[3 * k + j] = w * g[0] + u * g[1] + v * g[2];
            }
        }
        let (mut lo, mut hi) = (f[0], f[0]);
        for x in &f[1..] {
            lo = lo.min(*x);
            hi = hi.max(*x);
        }
        let mut spread_t = 0.0f64;
        let mut spread_uv = 0.0f64;
        for j in 0..3 {
            spread_t = spread_t.max((f[3 + j] - f[j]).abs().max_element());
            for k in 0..2 {
                let (x, y) = (f[3 * k + j], f[3 * k + (j + 1) % 3]);
                spread_uv = spread_uv.max((x - y).abs().max_element());
            }
        }
        let spread_t = (self.level_t < MAX_LEVEL).then_some(spread_t);
        let space = (self.level_uv < 2 * MAX_LEVEL).then_some((1, spread_uv));
        let mut corners = [DVec3::ZERO; 8];
        corners[..6].copy_from_slice(&f);
        Examined {
            corners,
            n: 6,
            lo,
            hi,
            spread_t,
            space,
        }
    }

    fn split(&self, dim: u8) -> (Self, Self) {
        let mut a = *self;
        let mut b = *self;
        if dim == 0 {
            let mid = 0.5 * (self.t[0] + self.t[1]);
            a.t[1] = mid;
            b.t[0] = mid;
            a.level_t += 1;
            b.level_t += 1;
        } else {
            // Halve the hypotenuse (v1, v2) at m: (m; v0, v1) and (m; v2, v0).
            let [v0, v1, v2] = self.uv;
            let m = [0.5 * (v1[0] + v2[0]), 0.5 * (v1[1] + v2[1])];
            a.uv = [m, v0, v1];
            b.uv = [m, v2, v0];
            a.level_uv += 1;
            b.level_uv += 1;
        }
        (a, b)
    }
}

/// Edge–edge differences `eᵢⱼᵏ` for `(i, j)` = `(a, c), (a, d), (b, c), (b, d)`.
pub(super) struct EeQuery {
    pub(super) e0: [DVec3; 4],
    pub(super) e1: [DVec3; 4],
}

/// `[t₀, t₁] × [s₀, s₁] × [r₀, r₁]`.
#[derive(Clone, Copy)]
pub(super) struct EeCell {
    pub(super) t: [f64; 2],
    pub(super) s: [f64; 2],
    pub(super) r: [f64; 2],
    pub(super) level: [u8; 3],
}

impl Cell for EeCell {
    type Query = EeQuery;

    #[inline]
    fn t0(&self) -> f64 {
        self.t[0]
    }

    #[inline]
    fn t1(&self) -> f64 {
        self.t[1]
    }

    #[inline]
    fn level(&self) -> u32 {
        self.level.iter().map(|&l| l as u32).sum()
    }

    fn examine(&self, q: &EeQuery) -> Examined {
        // Corner (k, i, j) of (t, s, r) at index 4k + 2i + j.
        let mut f = [DVec3::ZERO; 8];
        for k in 0..2 {
            let t = self.t[k];
            // Written out, as in the point–triangle query.
            let g = [
                lerp(q.e0[0], q.e1[0], t),
                lerp(q.e0[1], q.e1[1], t),
                lerp(q.e0[2], q.e1[2], t),
                lerp(q.e0[3], q.e1[3], t),
            ];
            for j in 0..2 {
                let r = self.r[j];
                let at_a = lerp(g[0], g[1], r);
                let at_b = lerp(g[2], g[3], r);
                for i in 0..2 {
                    f[4 * k + 2 * i + j] = lerp(at_a, at_b, self.s[i]);
                }
            }
        }
        let (mut lo, mut hi) = (f[0], f[0]);
        for x in &f[1..] {
            lo = lo.min(*x);
            hi = hi.max(*x);
        }
        let mut spread = [0.0f64; 3];
        for (dim, stride) in [(0, 4), (1, 2), (2, 1)] {
            for n in 0..8 {
                if n & stride == 0 {
                    let w = (f[n + stride] - f[n]).abs().max_element();
                    spread[dim] = spread[dim].max(w);
                }
            }
        }
        let mut space = None;
        for (dim, (&level, &w)) in self.level.iter().zip(&spread).enumerate().skip(1) {
            if level < MAX_LEVEL && space.is_none_or(|(_, widest)| w > widest) {
                space = Some((dim as u8, w));
            }
        }
        Examined {
            corners: f,
            n: 8,
            lo,
            hi,
            spread_t: (self.level[0] < MAX_LEVEL).then_some(spread[0]),
            space,
        }
    }

    fn split(&self, dim: u8) -> (Self, Self) {
        let mut a = *self;
        let mut b = *self;
        let (x, y) = match dim {
            0 => (&mut a.t, &mut b.t),
            1 => (&mut a.s, &mut b.s),
            _ => (&mut a.r, &mut b.r),
        };
        let mid = 0.5 * (x[0] + x[1]);
        x[1] = mid;
        y[0] = mid;
        a.level[dim as usize] += 1;
        b.level[dim as usize] += 1;
        (a, b)
    }
}
