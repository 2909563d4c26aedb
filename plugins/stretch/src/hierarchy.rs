//! The `stretch_hierarchy` kind: hierarchical position-based dynamics (after Müller 2008,
//! "Hierarchical Position Based Dynamics"), a multigrid-like accelerator for hard stretch.
//!
//! Gauss-Seidel on the edges of an `N × N` cloth carries a correction one edge per pass, so
//! the smooth, long-range part of the error (the whole cloth's weight hanging from its pins)
//! needs O(N²) passes to settle. This kind builds coarser and coarser versions of each target
//! object's edge graph and projects them **coarsest first** before the edges themselves (its
//! default order, −1, runs it before `stretch` in every column of the schedule):
//!
//! * **Coarsening.** Level `l + 1`'s particles are a maximal independent set of level `l`'s
//!   graph (pins first, then by index: deterministic), so every particle dropped at level `l`
//!   has a neighbour kept. Two kept particles are joined at level `l + 1` when a path of at
//!   most three level-`l` edges through dropped particles links them; the coarse edge's
//!   length is the shortest such path at rest. Coarsening stops at `levels` levels or when a
//!   level has fewer than `coarsest` particles.
//! * **Unilateral coarse edges.** A coarse edge only resists stretching, `C = |xb − xa| − L
//!   ≤ 0`, projected (hard) only when violated. By default its length is a path length along
//!   the rest mesh, never shorter than the geodesic distance, so no isometric motion —
//!   bending, folding, unfolding a pre-folded shape — ever violates it: the hierarchy only
//!   fights stretch, like `tether`, but between every pair of neighbouring coarse particles
//!   rather than only to the pins. A path along grid edges is up to ~8 % longer than the
//!   straight line, and the slack adds up over the levels; `straight_lengths = true` uses the
//!   straight rest distance instead, exact for a flat rest shape (bending only brings two
//!   points of a flat sheet closer) and about twice as effective on the drape, but it would
//!   hold a pre-folded shape folded.
//! * **Interpolation.** A particle dropped at level `l` follows its kept neighbours: after
//!   level `l + 1` is projected it moves by `Σₖ wₖ Δxₖ`, the weighted total displacement of
//!   its neighbours in this pass (`wₖ ∝ 1/rest length`, `Σ wₖ = 1`), before level `l` is
//!   projected. So a coarse correction drags the whole region around it down to the finest
//!   particles in the same pass.
//! * **Momentum.** Each coarse particle is projected with the mass of everything that moves
//!   with it — its own plus the weighted masses of the particles interpolated from it,
//!   recursively — so a coarse correction and the interpolation it causes conserve linear
//!   momentum exactly (pins are infinitely heavy and never move; particles around them follow
//!   their free neighbours only in part). Angular momentum is not conserved exactly: a region
//!   moves by the translation of its coarse particle.
//!
//! The residual is the largest and RMS relative overshoot `C/L` of the coarse edges
//! (dimensionless); it stores no energy (hard constraints).
//!
//! **When it pays** (measured on the peers' drape, hard stretch, one pass per substep, one
//! thread; `bench/peers.sh`, `docs/peers.md`): at few substeps, where Gauss-Seidel cannot
//! carry the cloth's weight to the pins, it cuts the RMS strain 5–12× for 5–25 % more time per
//! frame (N = 64 at 10 substeps: 2.0 % against 13.7 % plain and 6.6 % with `tether`; N = 128:
//! 2.7 % against 33 % and 17 %). With many substeps the error left is local — every edge
//! turning within a substep — and the coarse levels no longer help: at 40 substeps it matches
//! `tether`, and beyond about 80 its deepest levels, whose corrections drag whole regions of
//! the cloth, leave a floor of about 0.4 % RMS strain that plain substeps go below (N = 64 at
//! 160 substeps: 0.41 % with 8 levels, 0.17 % with `levels = 1`, 0.16 % without the kind).
//! Use it, with a few levels, to make coarse time steps hold; use substeps and `tether` for
//! tight strain. **Not at many substeps**: there it makes energy and holds or throws the cloth
//! up (the 2-thread peer sweep of 2026-11-27, its motion columns: on the 128 × 128 drape 320 × 1
//! ends the first half second 11 cm above the other solvers with a rise of 4.2 J, 640 × 1 above
//! its start with 27 J; at 20–40 substeps the rise is 0.2–0.35 J and the fall right) — its
//! coarse corrections move each region by a translation, which conserves linear momentum but
//! not angular momentum, and more substeps apply more of them a second. Give the edges more passes than the hierarchy: the coarse levels carry the
//! load across the cloth in one pass, and what they leave is local, for the fine edges to
//! settle. With the `stretch` group at importance 3 and this kind at 1, the 128 × 128 drape
//! reaches RMS 0.93 % at 20 substeps in 21–24 ms a frame on 2 threads, against 1.57 % with one
//! edge pass (`bench/README.md`, "Importance per kind").

use std::collections::BTreeMap;

use nucleus_sdk::params::{self, ParamSpec};
use nucleus_sdk::prelude::*;
use nucleus_sdk::team::SharedArray;
use serde::Deserialize;

/// The parameters of the `stretch_hierarchy` kind.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HierarchyParams {
    /// Most coarse levels built per object.
    pub levels: i64,
    /// Coarsening stops once a level would have fewer particles than this.
    pub coarsest: i64,
    /// Coarse edges as long as the straight line between their ends at rest (exact for a
    /// flat rest shape, where bending only brings points closer) instead of the shortest rest
    /// path (safe for any rest shape, but up to ~8 % slack per level on a grid).
    pub straight_lengths: bool,
}

impl HierarchyParams {
    /// The parameter descriptions.
    pub fn specs() -> Vec<ParamSpec> {
        vec![
            ParamSpec::integer("levels", 8)
                .doc("most coarse levels built per object")
                .range(1.0, 32.0),
            ParamSpec::integer("coarsest", 8)
                .doc("coarsening stops once a level would have fewer particles than this")
                .range(2.0, 1e9),
            ParamSpec::boolean("straight_lengths", false)
                .doc("coarse edges as long as the straight line at rest (stronger; only for flat rest shapes, it would resist unfolding a pre-folded one) instead of the shortest rest path along the mesh"),
        ]
    }
}

/// An edge graph over some particles, by local index: `adjacency[a]` lists `(b, length)`.
type Graph = Vec<Vec<(u32, f64)>>;

/// A particle dropped from a level (its index there) and its interpolation parents (indices
/// into the next coarser level) with weights summing to 1.
pub type Dropped = (u32, Vec<(u32, f64)>);

/// The coarse levels of one object, built from its edge graph (local indices).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coarsening {
    /// Per level (finest coarse level first): the kept particles, as indices into the
    /// previous level's particles.
    pub kept: Vec<Vec<u32>>,
    /// Per level: its edges (indices into its own particles) and their rest lengths.
    pub edges: Vec<Vec<([u32; 2], f64)>>,
    /// Per level: for each particle of the previous level that was dropped, its index there
    /// and its parents (indices into this level's particles) with weights summing to 1.
    pub dropped: Vec<Vec<Dropped>>,
}

/// A maximal independent set of `graph`, chosen greedily: `first` (pins) in order, then every
/// other node by index. Returns the kept nodes in increasing index.
pub fn independent_set(graph: &Graph, first: &[u32]) -> Vec<u32> {
    let n = graph.len();
    let mut state = vec![0u8; n]; // 0 free, 1 kept, 2 blocked
    let candidates = first.iter().copied().chain(0..n as u32);
    for v in candidates {
        if state[v as usize] != 0 {
            continue;
        }
        state[v as usize] = 1;
        for &(u, _) in &graph[v as usize] {
            if state[u as usize] == 0 {
                state[u as usize] = 2;
            }
        }
    }
    (0..n as u32).filter(|&v| state[v as usize] == 1).collect()
}

/// The coarse graph over `kept` (indices into `graph`): kept nodes linked by a path of at
/// most three edges whose inner nodes were dropped, with the shortest such path's length.
pub fn coarse_graph(graph: &Graph, kept: &[u32]) -> Graph {
    let mut coarse_index = vec![u32::MAX; graph.len()];
    for (k, &v) in kept.iter().enumerate() {
        coarse_index[v as usize] = k as u32;
    }
    let mut out: Graph = vec![Vec::new(); kept.len()];
    for (ka, &a) in kept.iter().enumerate() {
        // Shortest lengths to kept nodes within three edges through dropped nodes.
        let mut best: BTreeMap<u32, f64> = BTreeMap::new();
        let mut reach = |b: u32, len: f64| {
            let kb = coarse_index[b as usize];
            if kb != u32::MAX && kb != ka as u32 {
                let e = best.entry(kb).or_insert(f64::INFINITY);
                *e = e.min(len);
            }
        };
        for &(f, l1) in &graph[a as usize] {
            if coarse_index[f as usize] != u32::MAX {
                reach(f, l1);
                continue;
            }
            for &(g, l2) in &graph[f as usize] {
                if coarse_index[g as usize] != u32::MAX {
                    reach(g, l1 + l2);
                    continue;
                }
                for &(b, l3) in &graph[g as usize] {
                    if b != f {
                        reach(b, l1 + l2 + l3);
                    }
                }
            }
        }
        out[ka] = best.into_iter().collect();
    }
    // Symmetric by construction (paths reverse); keep both directions.
    out
}

/// Interpolation parents of every dropped node of `graph`: its kept neighbours, weighted by
/// inverse rest length and normalised. A dropped node always has one (the set is maximal).
fn parents(graph: &Graph, kept: &[u32]) -> Vec<Dropped> {
    let mut coarse_index = vec![u32::MAX; graph.len()];
    for (k, &v) in kept.iter().enumerate() {
        coarse_index[v as usize] = k as u32;
    }
    let mut out = Vec::new();
    for (v, neighbours) in graph.iter().enumerate() {
        if coarse_index[v] != u32::MAX {
            continue;
        }
        let mut list: Vec<(u32, f64)> = neighbours
            .iter()
            .filter(|(u, _)| coarse_index[*u as usize] != u32::MAX)
            .map(|&(u, len)| (coarse_index[u as usize], 1.0 / len.max(1e-12)))
            .collect();
        let sum: f64 = list.iter().map(|p| p.1).sum();
        if list.is_empty() || !(sum > 0.0 && sum.is_finite()) {
            continue;
        }
        list.iter_mut().for_each(|p| p.1 /= sum);
        out.push((v as u32, list));
    }
    out
}

/// Builds the levels of an object from its edge graph, keeping `pins` at every level.
pub fn coarsen(graph: &Graph, pins: &[u32], levels: usize, coarsest: usize) -> Coarsening {
    let mut out = Coarsening::default();
    let mut graph = graph.clone();
    let mut pins: Vec<u32> = pins.to_vec();
    for _ in 0..levels {
        let kept = independent_set(&graph, &pins);
        if kept.len() < coarsest || kept.len() == graph.len() {
            break;
        }
        let coarse = coarse_graph(&graph, &kept);
        let mut index = vec![u32::MAX; graph.len()];
        for (k, &v) in kept.iter().enumerate() {
            index[v as usize] = k as u32;
        }
        out.dropped.push(parents(&graph, &kept));
        out.edges.push(
            coarse
                .iter()
                .enumerate()
                .flat_map(|(a, list)| {
                    list.iter()
                        .filter(move |&&(b, _)| (a as u32) < b)
                        .map(move |&(b, len)| ([a as u32, b], len))
                })
                .collect(),
        );
        pins = pins.iter().map(|&p| index[p as usize]).collect();
        out.kept.push(kept);
        graph = coarse;
    }
    out
}

/// From this many dropped particles a level's prolongation is shared by the host's thread
/// team: the finest level of a 128 × 128 cloth drops about 12,000 (tens of microseconds of
/// work), its coarser levels a few hundred. Chosen, as the stretch group's 256 edges, not tuned.
pub const PARALLEL_MIN_DROPPED: usize = 2048;

/// One unilateral, hard coarse-edge projection between `xa`, `xb` with inverse masses
/// `wa`, `wb` and length `len`: the displacements of `a` and `b`, or `None` if the edge is
/// not stretched or cannot move.
#[inline]
pub fn project_coarse_edge(
    xa: DVec3,
    xb: DVec3,
    wa: f64,
    wb: f64,
    len: f64,
) -> Option<(DVec3, DVec3)> {
    let d = xb - xa;
    let dist = d.length();
    let c = dist - len;
    let w = wa + wb;
    if !(c > 0.0 && w > 0.0 && dist.is_finite()) {
        return None;
    }
    let n = d * (c / (dist * w));
    Some((n * wa, -n * wb))
}

/// One level of the batch, in global particle indices.
#[derive(Clone, Debug, Default)]
struct Level {
    /// The level's particles (global indices).
    members: Vec<u32>,
    /// Effective inverse mass of each member: its own mass plus the weighted masses that
    /// move with it (0 for pins).
    inv_mass: Vec<f64>,
    /// Edges, as indices into `members`, and their lengths.
    edges: Vec<[u32; 2]>,
    length: Vec<f64>,
    /// Particles of the next finer level dropped here (global), with ranges into
    /// `parent`/`weight` (indices into `members`).
    dropped: Vec<u32>,
    parent_start: Vec<u32>,
    parent: Vec<u32>,
    weight: Vec<f64>,
}

/// The `stretch_hierarchy` group: the coarse levels of every target object.
pub struct HierarchyGroup {
    /// Per object, its levels finest first.
    objects: Vec<Vec<Level>>,
    /// Every particle of a coarse level (global), and its position at the start of the pass.
    tracked: Vec<u32>,
    start: Vec<DVec3>,
    /// Global index → slot in `tracked` (u32::MAX if not tracked).
    slot: Vec<u32>,
    max_index: Option<u32>,
    count: usize,
}

impl HierarchyGroup {
    /// Builds the hierarchy of every target object from its edges and rest positions.
    pub fn new(p: &HierarchyParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        let rest = scene.rest_positions();
        let w = scene.inv_mass.as_slice();
        let particles = rest.len().min(w.len());
        let mut g = HierarchyGroup {
            objects: Vec::new(),
            tracked: Vec::new(),
            start: Vec::new(),
            slot: vec![u32::MAX; particles],
            max_index: None,
            count: 0,
        };
        for (_, object) in scene.unique_targets()? {
            let range = object.particles();
            let first = object.first;
            let mut graph: Graph = vec![Vec::new(); range.len()];
            for &[i, j] in object.edges.as_slice() {
                if !range.contains(&(i as usize)) || !range.contains(&(j as usize)) || i == j {
                    return Err(PluginError::bad_object(
                        object.name.as_str(),
                        format!(
                            "edge ({i}, {j}) is outside the object or joins a particle to itself"
                        ),
                    ));
                }
                let len = (rest[j as usize] - rest[i as usize]).length();
                if !len.is_finite() {
                    return Err(PluginError::bad_object(
                        object.name.as_str(),
                        format!("edge ({i}, {j}) has a non-finite rest length"),
                    ));
                }
                graph[(i - first) as usize].push((j - first, len));
                graph[(j - first) as usize].push((i - first, len));
            }
            let pins: Vec<u32> = range
                .clone()
                .filter(|&i| w[i] == 0.0)
                .map(|i| i as u32 - first)
                .collect();
            let c = coarsen(
                &graph,
                &pins,
                p.levels.max(0) as usize,
                p.coarsest.max(2) as usize,
            );
            if c.kept.is_empty() {
                continue;
            }
            // Global indices and masses level by level. `mass` of the previous level's
            // particles: the mass that moves with each (infinite for pins).
            let mut globals: Vec<u32> = (first..first + range.len() as u32).collect();
            let mut mass: Vec<f64> = globals
                .iter()
                .map(|&i| {
                    let wi = w[i as usize];
                    if wi > 0.0 {
                        1.0 / wi
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            let mut levels = Vec::new();
            for l in 0..c.kept.len() {
                let kept = &c.kept[l];
                let mut level_mass: Vec<f64> = kept.iter().map(|&k| mass[k as usize]).collect();
                let mut level = Level {
                    members: kept.iter().map(|&k| globals[k as usize]).collect(),
                    ..Level::default()
                };
                for (f, list) in &c.dropped[l] {
                    let mf = mass[*f as usize];
                    level.dropped.push(globals[*f as usize]);
                    level.parent_start.push(level.parent.len() as u32);
                    for &(k, wk) in list {
                        level.parent.push(k);
                        level.weight.push(wk);
                        // A pin is not dragged along: its mass stays its own.
                        if mf.is_finite() {
                            level_mass[k as usize] += wk * mf;
                        }
                    }
                }
                level.parent_start.push(level.parent.len() as u32);
                level.inv_mass = level_mass
                    .iter()
                    .map(|&m| if m.is_finite() { 1.0 / m } else { 0.0 })
                    .collect();
                for &(e, len) in &c.edges[l] {
                    let (ga, gb) = (level.members[e[0] as usize], level.members[e[1] as usize]);
                    let straight = (rest[gb as usize] - rest[ga as usize]).length();
                    level.edges.push(e);
                    level
                        .length
                        .push(if p.straight_lengths { straight } else { len });
                }
                g.count += level.edges.len();
                globals = level.members.clone();
                mass = level_mass;
                levels.push(level);
            }
            for level in &levels {
                for &m in &level.members {
                    if g.slot[m as usize] == u32::MAX {
                        g.slot[m as usize] = g.tracked.len() as u32;
                        g.tracked.push(m);
                    }
                }
            }
            g.max_index = g.max_index.max(Some(first + range.len() as u32 - 1));
            g.objects.push(levels);
        }
        g.start = vec![DVec3::ZERO; g.tracked.len()];
        Ok(g)
    }

    /// The number of coarse edges on each level of each object (finest first).
    pub fn level_sizes(&self) -> Vec<Vec<usize>> {
        self.objects
            .iter()
            .map(|levels| levels.iter().map(|l| l.edges.len()).collect())
            .collect()
    }
}

impl ConstraintGroup for HierarchyGroup {
    fn stages(&self) -> Stages {
        Stages::PROJECT
    }

    fn len(&self) -> usize {
        self.count
    }

    /// Coarsest level first: projects the level's stretched edges once (Gauss-Seidel, on this
    /// thread), then moves the particles dropped below it by the weighted displacement of their
    /// parents since the start of the pass. A dropped particle reads only its parents, which
    /// are the level's members and never dropped there, and writes only itself: from
    /// [`PARALLEL_MIN_DROPPED`] on, the dropped particles of a level are split over the host's
    /// thread team, with the same bits on any number of threads. No allocation.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        ctx.check_holds(self.max_index)?;
        let team = ctx.team;
        let p = ctx.particles();
        let (x, inv_mass) = (p.x, p.inv_mass);
        for (s, &i) in self.start.iter_mut().zip(&self.tracked) {
            *s = x[i as usize];
        }
        let (start, slot) = (&self.start, &self.slot);
        for levels in &self.objects {
            for level in levels.iter().rev() {
                for (e, &len) in level.edges.iter().zip(&level.length) {
                    let (a, b) = (e[0] as usize, e[1] as usize);
                    let (ga, gb) = (level.members[a] as usize, level.members[b] as usize);
                    if let Some((da, db)) =
                        project_coarse_edge(x[ga], x[gb], level.inv_mass[a], level.inv_mass[b], len)
                    {
                        x[ga] += da;
                        x[gb] += db;
                    }
                }
                let shared = SharedArray::new(&mut *x);
                team.for_ranges(level.dropped.len(), PARALLEL_MIN_DROPPED, &|range| {
                    for k in range {
                        let f = level.dropped[k] as usize;
                        if inv_mass[f] == 0.0 {
                            continue;
                        }
                        let parents =
                            level.parent_start[k] as usize..level.parent_start[k + 1] as usize;
                        let mut dx = DVec3::ZERO;
                        for (&parent, &wk) in level.parent[parents.clone()]
                            .iter()
                            .zip(&level.weight[parents])
                        {
                            let g = level.members[parent as usize] as usize;
                            // SAFETY: `g` is a member of this level, which no part writes in
                            // this loop (the dropped particles are not members); every index
                            // is below `max_index`, checked against the state above.
                            dx += (unsafe { *shared.at(g) } - start[slot[g] as usize]) * wk;
                        }
                        // SAFETY: each dropped particle appears once in the level's list, and
                        // its index `k` belongs to this part's range alone.
                        unsafe { *shared.at(f) += dx };
                    }
                });
            }
        }
        Ok(())
    }

    /// Relative overshoot `max(C, 0)/L` of the coarse edges (dimensionless).
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        let (mut max, mut sq, mut n) = (0.0f64, 0.0, 0u64);
        for levels in &self.objects {
            for level in levels {
                for (e, &len) in level.edges.iter().zip(&level.length) {
                    let (Some(a), Some(b)) = (
                        x.get(level.members[e[0] as usize] as usize),
                        x.get(level.members[e[1] as usize] as usize),
                    ) else {
                        continue;
                    };
                    let r = (((*b - *a).length() - len) / len).max(0.0);
                    max = max.max(r);
                    sq += r * r;
                    n += 1;
                }
            }
        }
        Residual {
            count: n,
            max,
            rms: if n > 0 { (sq / n as f64).sqrt() } else { 0.0 },
            energy: 0.0,
        }
    }
}

/// The factory of the `stretch_hierarchy` kind.
pub fn build(json: &str, scene: &SceneView<'_>) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let p: HierarchyParams = params::parse(json)?;
    Ok(Box::new(HierarchyGroup::new(&p, scene)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The graph of an `n × n` grid with one diagonal per quad, unit spacing.
    fn grid(n: u32) -> Graph {
        let mut g: Graph = vec![Vec::new(); (n * n) as usize];
        let mut add = |a: u32, b: u32, len: f64| {
            g[a as usize].push((b, len));
            g[b as usize].push((a, len));
        };
        for r in 0..n {
            for c in 0..n {
                let a = r * n + c;
                if c + 1 < n {
                    add(a, a + 1, 1.0);
                }
                if r + 1 < n {
                    add(a, a + n, 1.0);
                }
                if c + 1 < n && r + 1 < n {
                    add(a, a + n + 1, 2f64.sqrt());
                }
            }
        }
        g
    }

    #[test]
    fn the_independent_set_is_maximal_and_keeps_the_pins() {
        let g = grid(9);
        let kept = independent_set(&g, &[8, 40]);
        assert!(kept.contains(&8) && kept.contains(&40));
        let is_kept = |v: u32| kept.binary_search(&v).is_ok();
        for (v, list) in g.iter().enumerate() {
            let v = v as u32;
            if is_kept(v) {
                assert!(
                    list.iter().all(|&(u, _)| !is_kept(u)),
                    "{v} has a kept neighbour"
                );
            } else {
                assert!(list.iter().any(|&(u, _)| is_kept(u)), "{v} could be added");
            }
        }
    }

    #[test]
    fn coarse_lengths_are_shortest_paths_never_shorter_than_the_straight_line() {
        let n = 9;
        let g = grid(n);
        let kept = independent_set(&g, &[]);
        let coarse = coarse_graph(&g, &kept);
        let pos = |v: u32| DVec3::new((v % n) as f64, (v / n) as f64, 0.0);
        let mut edges = 0;
        for (a, list) in coarse.iter().enumerate() {
            for &(b, len) in list {
                let straight = pos(kept[a]).distance(pos(kept[b as usize]));
                assert!(len >= straight - 1e-12, "{len} < {straight}");
                assert!(len <= 3.0 * 2f64.sqrt() + 1e-12);
                // Symmetric.
                assert!(coarse[b as usize]
                    .iter()
                    .any(|&(c, l)| c as usize == a && l == len));
                edges += 1;
            }
        }
        assert!(edges > 0);
        // The coarse graph is connected: a breadth-first search reaches every kept node.
        let mut seen = vec![false; kept.len()];
        let mut queue = vec![0usize];
        seen[0] = true;
        while let Some(a) = queue.pop() {
            for &(b, _) in &coarse[a] {
                if !std::mem::replace(&mut seen[b as usize], true) {
                    queue.push(b as usize);
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn levels_shrink_until_the_coarsest_and_parents_weigh_one() {
        let g = grid(33);
        let c = coarsen(&g, &[0, 32], 20, 8);
        assert!(c.kept.len() >= 3, "{} levels", c.kept.len());
        let mut previous = g.len();
        for (l, kept) in c.kept.iter().enumerate() {
            assert!(kept.len() < previous && kept.len() >= 8);
            // Every dropped node of the previous level has parents weighing 1 in total.
            assert_eq!(c.dropped[l].len(), previous - kept.len());
            for (_, list) in &c.dropped[l] {
                let sum: f64 = list.iter().map(|p| p.1).sum();
                assert!((sum - 1.0).abs() < 1e-12);
            }
            previous = kept.len();
        }
    }

    #[test]
    fn a_coarse_edge_only_pulls_and_conserves_momentum() {
        let (xa, xb) = (DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0));
        assert!(
            project_coarse_edge(xa, xb, 1.0, 1.0, 2.5).is_none(),
            "slack"
        );
        let (da, db) = project_coarse_edge(xa, xb, 1.0, 3.0, 1.0).unwrap();
        assert!((((xb + db) - (xa + da)).length() - 1.0).abs() < 1e-15);
        // m_a Δa + m_b Δb = 0 with m = 1/w.
        assert!((da / 1.0 + db / 3.0).length() < 1e-15);
        assert!(
            project_coarse_edge(xa, xb, 0.0, 0.0, 1.0).is_none(),
            "two pins"
        );
        assert!(
            project_coarse_edge(xa, xa, 1.0, 1.0, 0.0).is_none(),
            "no length, no NaN"
        );
    }
}
