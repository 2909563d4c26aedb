//! The refresh: a partial broad phase for the primitives that left their boxes.
//!
//! Before every pass, and at the start of the next substep, each primitive's tight swept box
//! is checked against the box its candidates were found with. Only the primitives that left
//! their boxes get new boxes and look for new pairs (a query per vertex, face or edge that
//! left, then a merge into the sorted list, `merge_kept`); every other candidate is kept.
//! More than an eighth of the primitives out (`REFRESH_MAX_SHARE`), unconnected particles
//! (their hash grid is not updated in part), a collider out of its box, or a changed mass (a
//! pin released) takes a full broad phase instead (`FoundWith::hold`).
//!
//! The list then holds every pair whose boxes overlap, so no pair that can touch is ever
//! skipped (a property test checks it against full broad phases over rounds of random
//! crumpling: `a_refresh_keeps_every_pair_a_full_broad_phase_finds`). A full broad phase would also list the pairs within a fresh margin of a primitive
//! that stayed in its older box; such a pair can only come within reach by leaving the
//! boxes, and is then tested from the next pass.

use glam::DVec3;
use nucleus_sdk::team::{span, SharedArray, TeamRef};

use super::bvh::Aabb;
use super::swept::margin;
use super::{split_queries, BroadPhase, Finder};
use crate::candidates::{Candidate, Candidates};
use crate::parallel::PARALLEL_MIN_ITEMS;
use crate::primitives::{Geometry, Primitives};
use crate::response::contact::PairKind;

/// A refresh ([`BroadPhase::refresh`]) when at most one primitive in this many left its box,
/// else a full broad phase, whose queries arrive sorted
/// (`docs/decisions/collision_broad_phase.md`).
const REFRESH_MAX_SHARE: usize = 8;

/// What a [`BroadPhase::refresh`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Refreshed {
    /// Nothing left its box: the candidates stand.
    Nothing,
    /// A full broad phase found the candidates again.
    Full,
    /// The escaped primitives found their pairs, merged with the candidates kept.
    Partial,
}

/// Which primitives left their boxes, and the pairs they found.
#[derive(Default)]
pub(crate) struct Escaped {
    /// Per vertex, edge and face: whether it left its box.
    pub verts: Vec<bool>,
    pub edges: Vec<bool>,
    pub faces: Vec<bool>,
    /// The escaped vertices, faces and edges (in that order), listed for
    /// [`Finder::escaped_pairs`].
    list: [Vec<u32>; 3],
    /// The new pairs, sorted.
    fresh: Vec<(Candidate, f64)>,
}

impl Escaped {
    /// No primitive of `prims` escaped yet.
    pub fn new(prims: &Primitives) -> Self {
        Self {
            verts: vec![false; prims.verts.len()],
            edges: vec![false; prims.edges.len()],
            faces: vec![false; prims.faces.len()],
            ..Self::default()
        }
    }

    /// The escape marks of the vertices (`kind` 0), edges (1) or faces (2).
    fn of_kind(&mut self, kind: usize) -> &mut Vec<bool> {
        match kind {
            0 => &mut self.verts,
            1 => &mut self.edges,
            _ => &mut self.faces,
        }
    }

    /// Whether candidate `c` has a primitive marked escaped.
    fn involves(&self, c: Candidate) -> bool {
        let [a, b] = c.pair.map(|k| k as usize);
        match c.kind {
            PairKind::Collider => self.verts[b],
            PairKind::VertexFace => self.verts[a] || self.faces[b],
            PairKind::EdgeEdge => self.edges[a] || self.edges[b],
            PairKind::FeatureFace => self.faces[b],
            PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => self.edges[b],
            // Only with unconnected particles, which take a full broad phase.
            PairKind::VertexVertex | PairKind::VertexEdge => true,
        }
    }
}

/// What the candidates were last found with, beyond the primitives' boxes: the colliders'
/// boxes, the features' boxes and the vertices' inverse masses (empty before the first broad
/// phase).
#[derive(Default)]
pub(crate) struct FoundWith {
    collider_boxes: Vec<Aabb>,
    feat_boxes: Vec<Aabb>,
    inv_mass: Vec<f64>,
}

impl FoundWith {
    /// Records the colliders' and features' boxes and the vertices' inverse masses of a full
    /// broad phase.
    pub fn record(&mut self, geo: Geometry<'_>, inv_mass: &[f64]) {
        let colliders = geo.colliders;
        self.collider_boxes.clone_from(&colliders.boxes);
        self.feat_boxes.clear();
        self.feat_boxes
            .extend_from_slice(&colliders.feat_point_boxes);
        self.feat_boxes
            .extend_from_slice(&colliders.feat_edge_boxes);
        self.inv_mass.clear();
        self.inv_mass
            .extend(geo.prims.verts.iter().map(|&p| inv_mass[p as usize]));
    }

    /// Whether the candidates last found still hold every pair that can touch in the substep
    /// as far as the colliders and masses go: every collider box and feature box lies within
    /// the box it was found with, and no vertex changed its inverse mass (a pinned pair may
    /// have been left out). Then only the primitives that left their own boxes need new pairs
    /// ([`BroadPhase::refresh`]): a fresh broad phase would find a subset of the list, and
    /// the passes, which test every candidate exactly and keep their order, reach the same
    /// contacts in the same order.
    pub fn hold(&self, geo: Geometry<'_>, inv_mass: &[f64]) -> bool {
        let (prims, colliders) = (geo.prims, geo.colliders);
        let feat_boxes = (colliders.feat_point_boxes.iter()).chain(&colliders.feat_edge_boxes);
        self.inv_mass.len() == prims.verts.len()
            && self.feat_boxes.len()
                == colliders.feat_point_boxes.len() + colliders.feat_edge_boxes.len()
            && (prims.verts.iter().zip(&self.inv_mass))
                .all(|(&p, &w)| inv_mass[p as usize].to_bits() == w.to_bits())
            && (self.collider_boxes.iter().zip(&colliders.boxes))
                .all(|(found, now)| found.contains(now))
            && (self.feat_boxes.iter().zip(feat_boxes)).all(|(found, now)| found.contains(now))
    }
}

impl BroadPhase {
    /// Whether the candidates last found still hold as far as the colliders and masses go
    /// ([`FoundWith::hold`]).
    pub fn colliders_and_masses_hold(&self, geo: Geometry<'_>, inv_mass: &[f64]) -> bool {
        self.found.hold(geo, inv_mass)
    }

    /// After some primitives left their boxes (during the passes, or since the last substep):
    /// gives only those new boxes and finds only their pairs, keeping every other candidate
    /// of `cands` (found with the boxes the rest still lie in), ready for
    /// [`BroadPhase::hand_over`]. A full broad phase instead when more than an eighth of the
    /// primitives left ([`REFRESH_MAX_SHARE`]), or the group has unconnected particles.
    pub fn refresh(
        &mut self,
        geo: Geometry<'_>,
        cands: &Candidates,
        x0: &[DVec3],
        x: &[DVec3],
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) -> Refreshed {
        let prims = geo.prims;
        let mut count = 0;
        self.boxes.fill_particle_boxes(x0, x);
        for kind in 0..3 {
            let mut boxes = std::mem::take(self.boxes.of_kind(kind));
            let mut flags = std::mem::take(self.escaped.of_kind(kind));
            let n = flags.len();
            debug_assert_eq!(boxes.len(), n, "one escape mark per primitive");
            {
                let this = &self.boxes;
                let (shared_boxes, shared_flags) =
                    (SharedArray::new(&mut boxes), SharedArray::new(&mut flags));
                team.for_ranges(n, PARALLEL_MIN_ITEMS, &|r| {
                    // SAFETY: the ranges of `for_ranges` are disjoint and inside the two
                    // arrays (one box and one flag per primitive), exclusively borrowed here.
                    let (boxes, flags) = unsafe {
                        (
                            shared_boxes.slice(r.start, r.len()),
                            shared_flags.slice(r.start, r.len()),
                        )
                    };
                    this.each_tight_box(prims, kind, r, |j, tight, radius| {
                        let out = !boxes[j].contains(&tight);
                        flags[j] = out;
                        if out {
                            boxes[j] = tight.grow(margin(radius));
                        }
                    });
                });
            }
            count += flags.iter().filter(|&&out| out).count();
            *self.boxes.of_kind(kind) = boxes;
            *self.escaped.of_kind(kind) = flags;
        }
        if count == 0 {
            return Refreshed::Nothing;
        }
        if !prims.isolated.is_empty() || REFRESH_MAX_SHARE * count > prims.len() {
            self.find_all_from_particle_boxes(geo, inv_mass, team);
            return Refreshed::Full;
        }
        self.trees.refit(&self.boxes);

        // The pairs of the escaped primitives, found once each: the vertices', faces' and
        // edges' queries split over the thread team as in the full broad phase (the hits
        // are sorted below, so the list is the same on any number of threads).
        let escaped = &mut self.escaped;
        let mut fresh = std::mem::take(&mut escaped.fresh);
        fresh.clear();
        for (kind, flags) in [&escaped.verts, &escaped.faces, &escaped.edges]
            .into_iter()
            .enumerate()
        {
            let list = &mut escaped.list[kind];
            list.clear();
            list.extend((0..flags.len() as u32).filter(|&k| flags[k as usize]));
        }
        let (find, scratch, _) = self.split(geo, inv_mass);
        for &i in &find.escaped.list[0] {
            let i = i as usize;
            if inv_mass[prims.verts[i] as usize] > 0.0 {
                for c in 0..geo.colliders.list.len() {
                    fresh.extend(find.collider_pair(c, i));
                }
            }
        }
        let super::Scratch {
            pending,
            stack,
            parts,
            kept,
        } = scratch;
        for kind in 0..3 {
            let n = find.escaped.list[kind].len();
            split_queries(n, team, parts, stack, &mut fresh, &|r, stack, out| {
                find.escaped_pairs(kind, r, stack, out)
            });
        }
        fresh.sort_unstable_by_key(|&(c, _)| c);

        // Merge them with the candidates that involve no escaped primitive (both sorted,
        // disjoint).
        merge_kept(
            team,
            (&cands.list, &cands.reach),
            &|c| !find.escaped.involves(c),
            &fresh,
            kept,
            pending,
        );
        self.escaped.fresh = fresh;
        Refreshed::Partial
    }
}

impl Finder<'_> {
    /// The new pairs of the escaped vertices (`kind` 0: against the faces), faces (1: against
    /// the vertices that stayed and the colliders' feature points) or edges (2: against the
    /// edges, each pair of two escaped edges once, and the features) listed at `range` of
    /// the escaped primitives.
    fn escaped_pairs(
        &self,
        kind: usize,
        range: std::ops::Range<usize>,
        stack: &mut Vec<u32>,
        fresh: &mut Vec<(Candidate, f64)>,
    ) {
        let (prims, colliders) = (self.geo.prims, self.geo.colliders);
        let inv_mass = self.inv_mass;
        for &k in &self.escaped.list[kind][range] {
            match kind {
                0 => {
                    let i = k as usize;
                    let window = prims.window(2, prims.vert_obj[i], None);
                    self.trees.faces.query_in(
                        &self.boxes.verts[i],
                        window,
                        &self.boxes.faces,
                        stack,
                        |f| {
                            if let Some(d) = prims.vertex_face_reach(i, f, inv_mass) {
                                let kind = PairKind::VertexFace;
                                fresh.push((Candidate { kind, pair: [k, f] }, d));
                            }
                        },
                    );
                }
                1 => {
                    let f = k;
                    let window = prims.window(0, prims.face_obj[f as usize], None);
                    self.trees.verts.query_in(
                        &self.boxes.faces[f as usize],
                        window,
                        &self.boxes.verts,
                        stack,
                        |i| {
                            if self.escaped.verts[i as usize] {
                                return; // found from the vertex
                            }
                            if let Some(d) = prims.vertex_face_reach(i as usize, f, inv_mass) {
                                let kind = PairKind::VertexFace;
                                fresh.push((Candidate { kind, pair: [i, f] }, d));
                            }
                        },
                    );
                    for (p, &(c, _)) in colliders.feat_points.iter().enumerate() {
                        let kind = PairKind::FeatureFace;
                        let tight = colliders.feat_point_boxes[p];
                        if let Some(d) = self.feature_reach(kind, c, tight, true, f) {
                            fresh.push((
                                Candidate {
                                    kind,
                                    pair: [p as u32, f],
                                },
                                d,
                            ));
                        }
                    }
                }
                _ => {
                    let i = k as usize;
                    let window = prims.window(1, prims.edge_obj[i], None);
                    self.trees.edges.query_in(
                        &self.boxes.edges[i],
                        window,
                        &self.boxes.edges,
                        stack,
                        |j| {
                            let ju = j as usize;
                            if ju == i || (self.escaped.edges[ju] && ju < i) {
                                return; // itself, or found from the other escaped edge
                            }
                            let (a, b) = (i.min(ju), i.max(ju) as u32);
                            if let Some(d) = prims.edge_edge_reach(a, b, inv_mass) {
                                let kind = PairKind::EdgeEdge;
                                fresh.push((
                                    Candidate {
                                        kind,
                                        pair: [a as u32, b],
                                    },
                                    d,
                                ));
                            }
                        },
                    );
                    let features = (colliders.feat_points.iter().map(|f| f.0))
                        .zip(&colliders.feat_point_boxes)
                        .map(|(c, &b)| (PairKind::FeaturePointEdge, c, b))
                        .chain(
                            (colliders.feat_edges.iter().map(|f| f.0))
                                .zip(&colliders.feat_edge_boxes)
                                .map(|(c, &b)| (PairKind::FeatureEdgeEdge, c, b)),
                        );
                    let points = colliders.feat_points.len();
                    for (n, (kind, c, tight)) in features.enumerate() {
                        let p = if n < points { n } else { n - points };
                        if let Some(d) = self.feature_reach(kind, c, tight, false, k) {
                            fresh.push((
                                Candidate {
                                    kind,
                                    pair: [p as u32, k],
                                },
                                d,
                            ));
                        }
                    }
                }
            }
        }
    }
}

/// The candidates of `old` (sorted, with their reaches) that `keep` keeps, merged with `fresh`
/// (sorted, none of them in `old`), into `out`: the sorted union. From [`PARALLEL_MIN_ITEMS`]
/// candidates on, `old` is split over the team in contiguous ranges: each part counts what it
/// keeps (`kept`, one count per part), and then writes its kept candidates merged with the
/// fresh ones that sort between its first candidate and the next part's, at the place the
/// counts before it give. The list is the same on any number of threads.
pub(crate) fn merge_kept(
    team: TeamRef<'_>,
    (old, reach): (&[Candidate], &[f64]),
    keep: &(dyn Fn(Candidate) -> bool + Sync),
    fresh: &[(Candidate, f64)],
    kept: &mut Vec<usize>,
    out: &mut Vec<(Candidate, f64)>,
) {
    /// Appends `old`'s kept candidates merged with `fresh` to `out`.
    fn merge_into(
        (old, reach): (&[Candidate], &[f64]),
        keep: &(dyn Fn(Candidate) -> bool + Sync),
        fresh: &[(Candidate, f64)],
        mut out: impl FnMut((Candidate, f64)),
    ) {
        let mut next = fresh.iter().peekable();
        for (&c, &d) in old.iter().zip(reach) {
            if !keep(c) {
                continue;
            }
            while let Some(&&f) = next.peek() {
                if f.0 >= c {
                    break;
                }
                out(f);
                next.next();
            }
            out((c, d));
        }
        next.for_each(|&f| out(f));
    }
    out.clear();
    let (n, parts) = (old.len(), team.parts());
    if parts < 2 || n < PARALLEL_MIN_ITEMS {
        merge_into((old, reach), keep, fresh, |f| out.push(f));
        return;
    }
    kept.clear();
    kept.resize(parts, 0);
    let counts = SharedArray::new(kept);
    team.run(&|part| {
        let r = span(part, parts, n);
        let count = old[r].iter().filter(|&&c| keep(c)).count();
        // SAFETY: each part writes only its own count; `kept` holds `parts` of them and is
        // exclusively borrowed until the writes below.
        unsafe { *counts.at(part) = count };
    });
    // Where each part's fresh candidates start: those before its first candidate belong to the
    // parts before (all of them to part 0 when they sort before every candidate).
    let fresh_from = |part: usize| match part {
        0 => 0,
        p if p >= parts => fresh.len(),
        p => fresh.partition_point(|f| f.0 < old[span(p, parts, n).start]),
    };
    let total = kept.iter().sum::<usize>() + fresh.len();
    let placeholder = (
        Candidate {
            kind: PairKind::Collider,
            pair: [0; 2],
        },
        f64::NAN,
    );
    out.resize(total, placeholder);
    let (kept, slots) = (&*kept, SharedArray::new(out));
    team.run(&|part| {
        let r = span(part, parts, n);
        let (f0, f1) = (fresh_from(part), fresh_from(part + 1));
        let at = kept[..part].iter().sum::<usize>() + f0;
        let len = kept[part] + (f1 - f0);
        // SAFETY: part `part` writes `at..at + len`: its kept candidates and the fresh ones
        // between its first candidate and the next part's, after everything the parts before
        // write. The ranges are disjoint, cover `0..total` and lie inside `out`, which is
        // exclusively borrowed for this call.
        let mine = unsafe { slots.slice(at, len) };
        let mut i = 0;
        merge_into((&old[r.clone()], &reach[r]), keep, &fresh[f0..f1], |f| {
            mine[i] = f;
            i += 1;
        });
        debug_assert_eq!(i, len, "a part's merge filled its place");
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use nucleus_sdk::testing::Rng;

    /// The sorted candidates `[kind, a, b]` of a random list: distinct, `n` of them.
    fn random_candidates(rng: &mut Rng, n: usize) -> Vec<Candidate> {
        let kinds = [
            PairKind::Collider,
            PairKind::VertexFace,
            PairKind::EdgeEdge,
            PairKind::FeatureFace,
        ];
        let mut list: Vec<Candidate> = (0..n)
            .map(|_| Candidate {
                kind: kinds[rng.pick(kinds.len())],
                pair: [rng.pick(300) as u32, rng.pick(300) as u32],
            })
            .collect();
        list.sort_unstable();
        list.dedup();
        list
    }

    #[test]
    fn a_refresh_merges_the_same_list_on_any_team() {
        let teams = [0, 1, 2, 4].map(nucleus_sdk::team::Team::new);
        let mut rng = Rng(23);
        for round in 0..40 {
            // Sizes on both sides of the split: from a few candidates to several times
            // `PARALLEL_MIN_ITEMS`, fresh lists from none to a third of them.
            let n = [
                10,
                PARALLEL_MIN_ITEMS - 1,
                PARALLEL_MIN_ITEMS,
                3 * PARALLEL_MIN_ITEMS,
            ][round % 4];
            let all = random_candidates(&mut rng, n + n / 3 + 1);
            let (mut old, mut fresh) = (Vec::new(), Vec::new());
            for &c in &all {
                if rng.pick(4) == 0 {
                    fresh.push((c, rng.range(0.0, 1.0)));
                } else {
                    old.push(c);
                }
            }
            if round % 5 == 0 {
                fresh.clear();
            }
            let reach: Vec<f64> = old.iter().map(|_| rng.range(0.0, 1.0)).collect();
            let dropped: Vec<u32> = (0..40).map(|_| rng.pick(300) as u32).collect();
            let keep = |c: Candidate| !dropped.contains(&c.pair[0]);
            // The expected list: the kept candidates and the fresh ones, sorted.
            let mut expected: Vec<(Candidate, f64)> = (old.iter().zip(&reach))
                .filter(|(&c, _)| keep(c))
                .map(|(&c, &d)| (c, d))
                .chain(fresh.iter().copied())
                .collect();
            expected.sort_by_key(|e| e.0);
            for team in &teams {
                let (mut kept, mut out) = (Vec::new(), vec![(all[0], 7.0)]);
                merge_kept(
                    TeamRef::new(team),
                    (&old, &reach),
                    &keep,
                    &fresh,
                    &mut kept,
                    &mut out,
                );
                let bits = |l: &[(Candidate, f64)]| -> Vec<(Candidate, u64)> {
                    l.iter().map(|&(c, d)| (c, d.to_bits())).collect()
                };
                assert_eq!(
                    bits(&out),
                    bits(&expected),
                    "round {round}: {} candidates, {} fresh, a team of {} parts",
                    old.len(),
                    fresh.len(),
                    TeamRef::new(team).parts()
                );
            }
        }
    }
}
