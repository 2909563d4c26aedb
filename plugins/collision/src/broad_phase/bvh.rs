//! Broad phase: an axis-aligned bounding box hierarchy over swept primitives, built once
//! and **refit** (never rebuilt) every substep, and a spatial hash grid for unconnected
//! particles.
//!
//! The tree is built top-down at build time over the rest pose, splitting the primitives at
//! the median of their centroids along the longest axis, so neighbouring simplices of a mesh
//! share subtrees. A mesh's connectivity keeps those subtrees compact while it deforms, so
//! refitting (recomputing every node's box bottom-up from the primitives' swept boxes) keeps
//! the queries fast without the cost of a rebuild. Nodes are stored parents-first, so a refit
//! is one reverse sweep. Queries use a caller-owned stack: nothing allocates after the first
//! substep.

use glam::DVec3;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner (m).
    pub min: DVec3,
    /// Upper corner (m).
    pub max: DVec3,
}

impl Aabb {
    /// The empty box (contains nothing; the identity of [`union`](Self::union)).
    pub const EMPTY: Self = Self {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The box of a set of points, grown by `margin` on every side.
    #[inline]
    pub fn of_points(points: &[DVec3], margin: f64) -> Self {
        let mut b = Self::EMPTY;
        for &p in points {
            b.min = b.min.min(p);
            b.max = b.max.max(p);
        }
        b.grow(margin)
    }

    /// Grown by `m` on every side.
    #[inline]
    pub fn grow(self, m: f64) -> Self {
        Self {
            min: self.min - DVec3::splat(m),
            max: self.max + DVec3::splat(m),
        }
    }

    /// The smallest box containing both.
    #[inline]
    pub fn union(self, o: Self) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// Whether the boxes share a point.
    #[inline]
    pub fn overlaps(&self, o: &Self) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }

    /// The squared Euclidean distance between the boxes (0 if they overlap).
    #[inline]
    pub fn distance_squared(&self, o: &Self) -> f64 {
        let gap = (self.min - o.max).max(o.min - self.max).max(DVec3::ZERO);
        gap.length_squared()
    }

    /// Whether `o` lies inside `self`.
    #[inline]
    pub fn contains(&self, o: &Self) -> bool {
        self.min.cmple(o.min).all() && o.max.cmple(self.max).all()
    }

    /// Centre.
    #[inline]
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }
}

/// Leaves hold at most this many primitives.
const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    aabb: Aabb,
    /// Leaf: first index into `order`; inner: index of the left child (the right is
    /// `left + 1`... not necessarily; see `right`).
    first: u32,
    /// Leaf: number of primitives; inner: 0.
    count: u32,
    /// Inner: index of the right child.
    right: u32,
    /// The smallest and the largest primitive index under the node (for [`Window`]).
    min_index: u32,
    max_index: u32,
}

/// A bounding volume hierarchy over a fixed set of primitives.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    /// Primitive indices, leaf by leaf.
    order: Vec<u32>,
}

impl Bvh {
    /// Builds the tree over the boxes (their topology is kept for every later refit).
    pub fn build(boxes: &[Aabb]) -> Self {
        let mut bvh = Self {
            nodes: Vec::with_capacity(2 * boxes.len() / LEAF_SIZE + 1),
            order: (0..boxes.len() as u32).collect(),
        };
        if boxes.is_empty() {
            return bvh;
        }
        let centers: Vec<DVec3> = boxes.iter().map(Aabb::center).collect();
        bvh.split(&centers, 0, boxes.len());
        bvh.refit(boxes);
        bvh
    }

    fn split(&mut self, centers: &[DVec3], lo: usize, hi: usize) -> u32 {
        let index = self.nodes.len() as u32;
        self.nodes.push(Node {
            aabb: Aabb::EMPTY,
            first: lo as u32,
            count: (hi - lo) as u32,
            right: 0,
            min_index: self.order[lo..hi].iter().copied().min().unwrap_or(0),
            max_index: self.order[lo..hi].iter().copied().max().unwrap_or(0),
        });
        if hi - lo <= LEAF_SIZE {
            return index;
        }
        let mut cb = Aabb::EMPTY;
        for &i in &self.order[lo..hi] {
            let c = centers[i as usize];
            cb.min = cb.min.min(c);
            cb.max = cb.max.max(c);
        }
        let ext = cb.max - cb.min;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = (lo + hi) / 2;
        self.order[lo..hi].select_nth_unstable_by(mid - lo, |&a, &b| {
            centers[a as usize][axis]
                .total_cmp(&centers[b as usize][axis])
                .then(a.cmp(&b))
        });
        let left = self.split(centers, lo, mid);
        let right = self.split(centers, mid, hi);
        debug_assert_eq!(left, index + 1);
        let node = &mut self.nodes[index as usize];
        node.first = left;
        node.count = 0;
        node.right = right;
        index
    }

    /// Number of primitives.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether the tree holds no primitive.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Recomputes every node's box from the primitives' new boxes (children before parents).
    pub fn refit(&mut self, boxes: &[Aabb]) {
        for k in (0..self.nodes.len()).rev() {
            let n = self.nodes[k];
            let aabb = if n.count > 0 {
                let (a, b) = (n.first as usize, (n.first + n.count) as usize);
                self.order[a..b]
                    .iter()
                    .fold(Aabb::EMPTY, |acc, &i| acc.union(boxes[i as usize]))
            } else {
                self.nodes[n.first as usize]
                    .aabb
                    .union(self.nodes[n.right as usize].aabb)
            };
            self.nodes[k].aabb = aabb;
        }
    }

    /// Calls `hit(i)` for every primitive `i` whose box (as of the last refit) overlaps
    /// `query`, in a fixed order. `stack` is scratch space.
    #[inline]
    pub fn query(&self, query: &Aabb, boxes: &[Aabb], stack: &mut Vec<u32>, hit: impl FnMut(u32)) {
        self.query_in(query, Window::ALL, boxes, stack, hit);
    }

    /// As [`query`](Self::query), for the primitives `window` admits only: the same hits in
    /// the same order as `query` filtered by the window, but a subtree whose primitives it
    /// all refuses is not entered. A self query (edge against edge) that finds each pair
    /// from its lower index skips about half the nodes whose boxes the query meets; an
    /// object that does not collide with itself skips its own subtrees.
    #[inline]
    pub fn query_in(
        &self,
        query: &Aabb,
        window: Window,
        boxes: &[Aabb],
        stack: &mut Vec<u32>,
        mut hit: impl FnMut(u32),
    ) {
        if self.nodes.is_empty() || window.none {
            return;
        }
        stack.clear();
        stack.push(0);
        while let Some(k) = stack.pop() {
            let n = &self.nodes[k as usize];
            if window.refuses_all(n.min_index, n.max_index) || !n.aabb.overlaps(query) {
                continue;
            }
            if n.count > 0 {
                for &i in &self.order[n.first as usize..(n.first + n.count) as usize] {
                    if window.admits(i) && boxes[i as usize].overlaps(query) {
                        hit(i);
                    }
                }
            } else {
                stack.push(n.right);
                stack.push(n.first);
            }
        }
    }
}

/// Which primitive indices a [`Bvh::query_in`] wants: those past `above`, outside the
/// range `skip` (half open), and none at all when `none`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// Only indices greater than this (`None`: any).
    pub above: Option<u32>,
    /// Not the indices in `skip.0 .. skip.1` (an empty range skips nothing).
    pub skip: (u32, u32),
    /// No index at all (a query every hit of which would be dropped).
    pub none: bool,
}

impl Window {
    /// Every index.
    pub const ALL: Self = Self {
        above: None,
        skip: (0, 0),
        none: false,
    };

    /// Whether index `i` is wanted.
    #[inline]
    pub fn admits(&self, i: u32) -> bool {
        self.above.is_none_or(|a| i > a) && !(self.skip.0 <= i && i < self.skip.1)
    }

    /// Whether every index in `lo ..= hi` is refused.
    #[inline]
    fn refuses_all(&self, lo: u32, hi: u32) -> bool {
        self.above.is_some_and(|a| hi <= a) || (self.skip.0 <= lo && hi < self.skip.1)
    }
}

/// A spatial hash grid over boxes (unconnected particles): each box is entered in every cell
/// it overlaps; a box spanning more than [`HashGrid::MAX_CELLS_PER_AXIS`] cells along an
/// axis (a very fast particle) goes to an overflow list tested against every box instead.
/// Entries are kept sorted by cell hash in one vector: no hash map, deterministic.
#[derive(Clone, Debug, Default)]
pub struct HashGrid {
    cell: f64,
    /// (bucket, box index), sorted.
    entries: Vec<(u32, u32)>,
    /// Start of each bucket in `entries` (`buckets + 1` values).
    starts: Vec<u32>,
    /// Boxes too large for the grid.
    overflow: Vec<u32>,
}

impl HashGrid {
    /// A box spanning more cells than this along an axis goes to the overflow list.
    pub const MAX_CELLS_PER_AXIS: i64 = 4;

    fn cell_range(&self, b: &Aabb) -> Option<([i64; 3], [i64; 3])> {
        let lo = (b.min / self.cell).floor();
        let hi = (b.max / self.cell).floor();
        let ext = hi - lo;
        // NaN extents fail the comparison and go to the overflow list too.
        let spans_few_cells = ext.max_element() < Self::MAX_CELLS_PER_AXIS as f64;
        if !spans_few_cells || !lo.is_finite() {
            return None;
        }
        Some((
            [lo.x as i64, lo.y as i64, lo.z as i64],
            [hi.x as i64, hi.y as i64, hi.z as i64],
        ))
    }

    fn bucket(&self, c: [i64; 3]) -> u32 {
        let h = (c[0].wrapping_mul(73_856_093))
            ^ (c[1].wrapping_mul(19_349_663))
            ^ (c[2].wrapping_mul(83_492_791));
        (h.rem_euclid(self.starts.len().max(2) as i64 - 1)) as u32
    }

    /// Every pair `[i, j]`, `i < j`, of boxes that overlap, sorted and without duplicates,
    /// appended to `out` (which is cleared first). The cell size is twice the mean box
    /// extent.
    pub fn pairs(&mut self, boxes: &[Aabb], out: &mut Vec<[u32; 2]>) {
        out.clear();
        self.entries.clear();
        self.overflow.clear();
        if boxes.len() < 2 {
            return;
        }
        let mean: f64 = boxes
            .iter()
            .map(|b| (b.max - b.min).max_element())
            .filter(|e| e.is_finite())
            .sum::<f64>()
            / boxes.len() as f64;
        self.cell = (2.0 * mean).max(1e-9);
        let buckets = (2 * boxes.len()).next_power_of_two();
        self.starts.clear();
        self.starts.resize(buckets + 1, 0);
        for (i, b) in boxes.iter().enumerate() {
            match self.cell_range(b) {
                None => self.overflow.push(i as u32),
                Some((lo, hi)) => {
                    for x in lo[0]..=hi[0] {
                        for y in lo[1]..=hi[1] {
                            for z in lo[2]..=hi[2] {
                                let k = self.bucket([x, y, z]);
                                self.entries.push((k, i as u32));
                            }
                        }
                    }
                }
            }
        }
        self.entries.sort_unstable();
        self.entries.dedup();
        for &(k, _) in &self.entries {
            self.starts[k as usize + 1] += 1;
        }
        for k in 0..buckets {
            self.starts[k + 1] += self.starts[k];
        }
        for (i, b) in boxes.iter().enumerate() {
            let Some((lo, hi)) = self.cell_range(b) else {
                continue;
            };
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        let k = self.bucket([x, y, z]) as usize;
                        let (s, e) = (self.starts[k] as usize, self.starts[k + 1] as usize);
                        for &(_, j) in &self.entries[s..e] {
                            if j as usize > i && b.overlaps(&boxes[j as usize]) {
                                out.push([i as u32, j]);
                            }
                        }
                    }
                }
            }
        }
        for &i in &self.overflow {
            for (j, b) in boxes.iter().enumerate() {
                if j as u32 != i && b.overlaps(&boxes[i as usize]) {
                    let (a, c) = (i.min(j as u32), i.max(j as u32));
                    out.push([a, c]);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_boxes(n: usize, seed: &mut u64, size: f64) -> Vec<Aabb> {
        let mut r = || {
            *seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (*seed >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let c = DVec3::new(r(), r(), r());
                let e = DVec3::new(r(), r(), r()) * size;
                Aabb {
                    min: c - e,
                    max: c + e,
                }
            })
            .collect()
    }

    fn brute_pairs(boxes: &[Aabb]) -> Vec<[u32; 2]> {
        let mut out = Vec::new();
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                if boxes[i].overlaps(&boxes[j]) {
                    out.push([i as u32, j as u32]);
                }
            }
        }
        out
    }

    #[test]
    fn bvh_query_finds_exactly_the_overlapping_boxes_after_refits() {
        let mut seed = 5;
        let boxes = random_boxes(300, &mut seed, 0.03);
        let mut bvh = Bvh::build(&boxes);
        let mut stack = Vec::new();
        // Refit to boxes that moved far from the ones the tree was built on.
        for round in 0..3 {
            let moved = random_boxes(300, &mut seed, 0.05 * (round + 1) as f64);
            bvh.refit(&moved);
            for q in random_boxes(50, &mut seed, 0.1) {
                let mut got = Vec::new();
                bvh.query(&q, &moved, &mut stack, |i| got.push(i));
                got.sort_unstable();
                let want: Vec<u32> = (0..moved.len() as u32)
                    .filter(|&i| moved[i as usize].overlaps(&q))
                    .collect();
                assert_eq!(got, want);
            }
        }
    }

    #[test]
    fn a_query_in_a_window_gives_the_hits_of_a_query_it_admits_in_the_same_order() {
        let mut seed = 11;
        // Boxes built in index order along x, as a mesh's primitives come object by object:
        // whole subtrees then fall inside a skipped range or below `above`.
        let mut boxes = random_boxes(300, &mut seed, 0.04);
        boxes.sort_by(|a, b| a.min.x.total_cmp(&b.min.x));
        let mut bvh = Bvh::build(&boxes);
        let mut stack = Vec::new();
        for round in 0..3 {
            let moved: Vec<Aabb> = boxes
                .iter()
                .map(|b| {
                    let d = 0.02 * (round as f64) * DVec3::new(1.0, -0.5, 0.3);
                    Aabb {
                        min: b.min + d,
                        max: b.max + d,
                    }
                })
                .collect();
            bvh.refit(&moved);
            for (k, q) in random_boxes(60, &mut seed, 0.3).iter().enumerate() {
                let k = k as u32;
                let windows = [
                    Window::ALL,
                    Window {
                        above: Some(k * 5), // 0 … 295
                        ..Window::ALL
                    },
                    Window {
                        skip: (k * 3, k * 3 + 90),
                        ..Window::ALL
                    },
                    Window {
                        above: Some(k * 2),
                        skip: (100, 200),
                        none: false,
                    },
                    Window {
                        none: true,
                        ..Window::ALL
                    },
                ];
                for w in windows {
                    let mut all = Vec::new();
                    bvh.query(q, &moved, &mut stack, |i| all.push(i));
                    all.retain(|&i| !w.none && w.admits(i));
                    let mut got = Vec::new();
                    bvh.query_in(q, w, &moved, &mut stack, |i| got.push(i));
                    assert_eq!(got, all, "query {k}, {w:?}");
                }
            }
        }
    }

    #[test]
    fn hash_grid_finds_exactly_the_overlapping_pairs_including_huge_boxes() {
        let mut seed = 9;
        let mut boxes = random_boxes(400, &mut seed, 0.02);
        // A "bullet": one box spanning the whole scene.
        boxes[17] = Aabb {
            min: DVec3::splat(-1.0),
            max: DVec3::splat(2.0),
        };
        let mut grid = HashGrid::default();
        let mut out = Vec::new();
        grid.pairs(&boxes, &mut out);
        assert_eq!(out, brute_pairs(&boxes));
        // Reuse: a second call gives the answer for the new boxes.
        let boxes = random_boxes(50, &mut seed, 0.1);
        grid.pairs(&boxes, &mut out);
        assert_eq!(out, brute_pairs(&boxes));
    }

    #[test]
    fn empty_inputs_are_fine() {
        let bvh = Bvh::build(&[]);
        let mut stack = Vec::new();
        bvh.query(
            &Aabb::of_points(&[DVec3::ZERO], 1.0),
            &[],
            &mut stack,
            |_| panic!("no primitive"),
        );
        let mut out = vec![[0, 1]];
        HashGrid::default().pairs(&[], &mut out);
        assert!(out.is_empty());
    }
}
