//! The broad phase: the candidate pairs, every pair of primitives whose swept boxes overlap.
//!
//! Axis-aligned bounding box trees over the swept edges, faces and vertices ([`bvh`]), built
//! once over the rest shape and **refit** every substep, and a spatial hash grid over the
//! unconnected particles. Each box covers its primitive's particles at `x0` and `x − shift`,
//! grown by its thickness and a margin ([`swept`]). The candidates are collected once per
//! substep in sorted order (`BroadPhase::find_all`): the vertex–face and edge–edge queries
//! (one per vertex, one per edge) are split over the host's thread team in contiguous
//! ranges whose hits are joined in order, so the list is the same on any number of threads.
//!
//! The solve moves positions; before every pass, and at the start of the next substep, each
//! primitive's tight swept box is checked against the box its candidates were found with,
//! and only the primitives that left their boxes look for new pairs ([`refresh`]).
//!
//! A group holds at most a budget of candidates (`candidate_budget`); beyond it the
//! substep fails with an error naming the object that moved farthest, instead of holding
//! tens of millions of pairs for minutes.

pub mod bvh;
pub mod refresh;
pub mod swept;

use glam::DVec3;
use nucleus_sdk::prelude::*;
use nucleus_sdk::team::{span, SharedArray, TeamRef};

use crate::candidates::rest_pairs::{rest_reach, same_object_reach};
use crate::candidates::{filter::all_kinematic, Candidate, Candidates};
use crate::narrow_phase::distance;
use crate::parallel::{claim_chunks, CHUNKS_PER_PART, PARALLEL_MIN_ITEMS, PARALLEL_MIN_QUERIES};
use crate::primitives::{Geometry, Primitives};
use crate::response::contact::{Contact, PairKind};
use bvh::{Aabb, Bvh, HashGrid};
use refresh::{Escaped, FoundWith};
use swept::{margin, SweptBoxes};

/// The least [`candidate_budget`]: about 100 MB of candidate state.
const MIN_CANDIDATE_BUDGET: usize = 1 << 20;

/// The most candidate pairs a group may hold at once: 64 per primitive, or 8 per same-object
/// pair closer than its contact distance at rest (a thick cloth has hundreds of those per
/// vertex), at least [`MIN_CANDIDATE_BUDGET`]. The shipped scenes peak at about 8 per
/// primitive; a dense crumple stacks a few layers within reach, and fast relative motion a
/// few times more. Beyond the budget the substep fails with an error naming the fastest
/// object ([`BroadPhase::over_budget_error`]) instead of holding every pair
/// (`docs/decisions/collision_candidate_budget.md`).
fn candidate_budget(primitives: usize, rest_pairs: usize) -> usize {
    (64 * primitives)
        .max(8 * rest_pairs)
        .max(MIN_CANDIDATE_BUDGET)
}

/// The trees over the primitives' swept boxes, built over the rest shape.
struct Trees {
    edges: Bvh,
    faces: Bvh,
    /// Over the vertices' boxes, for the faces that left their boxes ([`refresh`]).
    verts: Bvh,
}

impl Trees {
    /// Refits the trees to the boxes.
    fn refit(&mut self, boxes: &SweptBoxes) {
        self.edges.refit(&boxes.edges);
        self.faces.refit(&boxes.faces);
        self.verts.refit(&boxes.verts);
    }
}

/// The buffers of a broad phase, their capacity kept from step to step.
#[derive(Default)]
struct Scratch {
    /// The candidates found, with their contact distance, before they are handed over.
    pending: Vec<(Candidate, f64)>,
    /// The query stack of the calling thread.
    stack: Vec<u32>,
    /// The buffers of the queries split over the thread team.
    parts: PartScratch,
    /// The candidates each part of the team keeps in a refresh ([`refresh::merge_kept`]).
    kept: Vec<usize>,
}

/// Over the thread team: each chunk's hits ([`claim_chunks`]) and each part's query stack.
#[derive(Default)]
struct PartScratch {
    hits: Vec<Vec<(Candidate, f64)>>,
    stacks: Vec<Vec<u32>>,
}

/// The hash grid over the unconnected particles: their boxes and the pairs it finds.
#[derive(Default)]
struct Grid {
    grid: HashGrid,
    boxes: Vec<Aabb>,
    pairs: Vec<[u32; 2]>,
}

/// The broad phase's state.
pub(crate) struct BroadPhase {
    /// The swept boxes of the primitives.
    pub boxes: SweptBoxes,
    trees: Trees,
    /// Over the unconnected particles.
    grid: Grid,
    /// Which primitives left their boxes, and their new pairs ([`refresh`]).
    escaped: Escaped,
    /// What the candidates were last found with, beyond the primitives' boxes.
    found: FoundWith,
    scratch: Scratch,
    /// The most candidate pairs the group holds ([`candidate_budget`]; the parameter
    /// `max_candidates`); more is an error.
    budget: usize,
    /// The largest candidate list refused since the last check (0: none).
    over_budget: usize,
}

/// A query of the broad phase over a range of primitives: `(range, stack, hits)`.
type QueryFn<'q> =
    dyn Fn(std::ops::Range<usize>, &mut Vec<u32>, &mut Vec<(Candidate, f64)>) + Sync + 'q;

impl BroadPhase {
    /// The broad phase of `prims` for a group of `n` particles, its trees built over the rest
    /// shape; at most `max_candidates` candidates (0: [`candidate_budget`]).
    pub fn new(prims: &Primitives, n: usize, max_candidates: u64) -> Self {
        let boxes = SweptBoxes::at_rest(prims, n);
        let trees = Trees {
            edges: Bvh::build(&boxes.edges),
            faces: Bvh::build(&boxes.faces),
            verts: Bvh::build(&boxes.verts),
        };
        let budget = match max_candidates {
            0 => candidate_budget(
                prims.len(),
                prims.at_rest.vertex_face.len() + prims.at_rest.edge_edge.len(),
            ),
            n => usize::try_from(n).unwrap_or(usize::MAX),
        };
        let mut scratch = Scratch {
            stack: Vec::with_capacity(128),
            ..Scratch::default()
        };
        scratch.pending.reserve(4 * prims.len());
        Self {
            escaped: Escaped::new(prims),
            boxes,
            trees,
            grid: Grid {
                boxes: vec![Aabb::EMPTY; prims.isolated.len()],
                ..Grid::default()
            },
            found: FoundWith::default(),
            scratch,
            budget,
            over_budget: 0,
        }
    }

    /// The full broad phase: refits the trees to the swept boxes over `[x0, x]` (grown by a
    /// margin) and collects the candidate pairs with their contact distances, sorted, ready
    /// for [`Self::hand_over`]. The pairs are generated in their sorted order — kinds in
    /// [`PairKind`] order, the first primitive ascending, and each query's hits sorted by the
    /// second — so no global sort is needed (checked in debug builds).
    pub fn find_all(
        &mut self,
        geo: Geometry<'_>,
        x0: &[DVec3],
        x: &[DVec3],
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) {
        self.boxes.fill_particle_boxes(x0, x);
        self.find_all_from_particle_boxes(geo, inv_mass, team);
    }

    /// [`Self::find_all`] with the particle boxes already filled at `[x0, x]`
    /// ([`SweptBoxes::fill_particle_boxes`]), as a refresh that falls back to it has them.
    fn find_all_from_particle_boxes(
        &mut self,
        geo: Geometry<'_>,
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) {
        let (prims, colliders) = (geo.prims, geo.colliders);
        for kind in 0..3 {
            let mut boxes = std::mem::take(self.boxes.of_kind(kind));
            let this = &self.boxes;
            team.for_ranges_mut(&mut boxes, PARALLEL_MIN_ITEMS, &|r, boxes| {
                this.each_tight_box(prims, kind, r, |j, tight, radius| {
                    boxes[j] = tight.grow(margin(radius));
                });
            });
            *self.boxes.of_kind(kind) = boxes;
        }
        self.trees.refit(&self.boxes);
        let (find, scratch, grid) = self.split(geo, inv_mass);
        let Scratch {
            pending,
            stack,
            parts,
            ..
        } = scratch;
        pending.clear();
        // Vertex–collider.
        for c in 0..colliders.list.len() {
            for i in 0..prims.verts.len() {
                if inv_mass[prims.verts[i] as usize] > 0.0 {
                    pending.extend(find.collider_pair(c, i));
                }
            }
        }
        // Particle–particle, through the hash grid (its pairs come sorted).
        if prims.isolated.len() > 1 {
            find.particle_pairs(grid, pending);
        }
        // Particle–curve edge.
        for &k in &prims.isolated {
            let from = pending.len();
            find.vertex_curve_pairs(k, stack, pending);
            sort_by_second(pending, from);
        }
        // Vertex–face, then edge–edge: one query per vertex or edge, split over the thread
        // team in contiguous ranges whose hits are joined in order (the same list whatever
        // the number of parts).
        if !prims.faces.is_empty() {
            split_queries(
                prims.verts.len(),
                team,
                parts,
                stack,
                pending,
                &|r, stack, out| find.vertex_face_pairs(r, stack, out),
            );
        }
        split_queries(
            prims.edges.len(),
            team,
            parts,
            stack,
            pending,
            &|r, stack, out| find.edge_edge_pairs(r, stack, out),
        );
        // The colliders' feature points against faces, then against edges, and feature edges
        // against edges.
        for (kind, points, boxes, faces) in [
            (
                PairKind::FeatureFace,
                true,
                &colliders.feat_point_boxes,
                true,
            ),
            (
                PairKind::FeaturePointEdge,
                true,
                &colliders.feat_point_boxes,
                false,
            ),
            (
                PairKind::FeatureEdgeEdge,
                false,
                &colliders.feat_edge_boxes,
                false,
            ),
        ] {
            for (f, tight) in boxes.iter().enumerate() {
                let c = if points {
                    colliders.feat_points[f].0
                } else {
                    colliders.feat_edges[f].0
                };
                let from = pending.len();
                find.feature_candidates(kind, [f as u32, c], *tight, faces, pending, stack);
                sort_by_second(pending, from);
            }
        }
        self.found.record(geo, inv_mass);
    }

    /// The queries' view of the boxes and trees, with the buffers they fill, borrowed apart.
    fn split<'a>(
        &'a mut self,
        geo: Geometry<'a>,
        inv_mass: &'a [f64],
    ) -> (Finder<'a>, &'a mut Scratch, &'a mut Grid) {
        let find = Finder {
            geo,
            boxes: &self.boxes,
            trees: &self.trees,
            escaped: &self.escaped,
            inv_mass,
        };
        (find, &mut self.scratch, &mut self.grid)
    }

    /// Hands the candidates just found to `cands` ([`Candidates::adopt`]), unless there are
    /// more than the budget: then the substep fails ([`Self::over_budget_error`]), and the
    /// list and its memory are dropped.
    pub fn hand_over(
        &mut self,
        cands: &mut Candidates,
        prims: &Primitives,
        contacts: &[Contact],
        x: &[DVec3],
        team: TeamRef<'_>,
    ) {
        let pending = &mut self.scratch.pending;
        if pending.len() > self.budget {
            self.over_budget = self.over_budget.max(pending.len());
            *pending = Vec::new();
        }
        cands.adopt(pending, x, prims, contacts, team);
    }

    /// The error of a substep of length `h` whose candidates went over the budget, if one did
    /// (and clears it): it names the object of the vertex that moved farthest over the
    /// substep, and how far.
    pub fn over_budget_error(
        &mut self,
        prims: &Primitives,
        x0: &[DVec3],
        x: &[DVec3],
        h: f64,
    ) -> Result<(), PluginError> {
        let found = std::mem::take(&mut self.over_budget);
        if found == 0 {
            return Ok(());
        }
        let (mut far, mut who) = (0.0f64, 0usize);
        for (i, &p) in prims.verts.iter().enumerate() {
            let d = x[p as usize].distance(x0[p as usize]);
            if d > far || d.is_nan() {
                (far, who) = (d, i);
            }
        }
        let name = prims
            .names
            .get(prims.vert_obj.get(who).copied().unwrap_or(0) as usize);
        let message = format!(
            "{found} candidate pairs in one substep, over the group's budget of {} (parameter \
             max_candidates; automatic: 64 per primitive, 8 per pair in contact at rest, at \
             least {MIN_CANDIDATE_BUDGET}): its primitives move too far against each other in a \
             substep (a vertex of this object moved {far:.3e} m in {h:.3e} s); use more \
             substeps, or check the gravity, the velocities and the colliders' motion",
            self.budget
        );
        Err(match name {
            Some(n) => PluginError::bad_object(n.as_str(), message),
            None => PluginError::failed(message),
        })
    }
}

/// What the queries of a broad phase read.
#[derive(Clone, Copy)]
struct Finder<'a> {
    geo: Geometry<'a>,
    boxes: &'a SweptBoxes,
    trees: &'a Trees,
    escaped: &'a Escaped,
    inv_mass: &'a [f64],
}

impl Finder<'_> {
    /// Vertex `i` against collider `c`, if its box overlaps the collider's and they share a
    /// layer (its particle assumed dynamic).
    #[inline]
    fn collider_pair(&self, c: usize, i: usize) -> Option<(Candidate, f64)> {
        let (prims, colliders) = (self.geo.prims, self.geo.colliders);
        let col = &colliders.list[c];
        let vo = prims.vert_obj[i];
        (self.boxes.verts[i].overlaps(&colliders.boxes[c]) && prims.collides_with_collider(vo, col))
            .then(|| {
                let pair = [c as u32, i as u32];
                let kind = PairKind::Collider;
                (Candidate { kind, pair }, prims.radius(vo) + col.thickness)
            })
    }

    /// The particle–particle candidates, from the hash grid over the unconnected particles'
    /// boxes (its pairs come sorted).
    fn particle_pairs(&self, grid: &mut Grid, out: &mut Vec<(Candidate, f64)>) {
        let prims = self.geo.prims;
        let rest = &prims.rest;
        for (b, &k) in grid.boxes.iter_mut().zip(&prims.isolated) {
            *b = self.boxes.verts[k as usize];
        }
        grid.grid.pairs(&grid.boxes, &mut grid.pairs);
        for &[a, b] in &grid.pairs {
            let (i, j) = (prims.isolated[a as usize], prims.isolated[b as usize]);
            let (p, q) = (prims.verts[i as usize], prims.verts[j as usize]);
            let (po, qo) = (prims.vert_obj[i as usize], prims.vert_obj[j as usize]);
            if !prims.objects_may_collide(po, qo) || all_kinematic(&[p, q], self.inv_mass) {
                continue;
            }
            let mut d = prims.radius(po) + prims.radius(qo);
            if po == qo {
                let d2 = rest[p as usize].distance_squared(rest[q as usize]);
                match rest_reach(d, d2) {
                    Some(r) => d = r,
                    None => continue,
                }
            }
            let pair = [i, j];
            out.push((
                Candidate {
                    kind: PairKind::VertexVertex,
                    pair,
                },
                d,
            ));
        }
    }

    /// The particle–curve edge candidates of unconnected particle `k` (an index into the
    /// vertices), in the tree's order.
    fn vertex_curve_pairs(&self, k: u32, stack: &mut Vec<u32>, out: &mut Vec<(Candidate, f64)>) {
        let prims = self.geo.prims;
        let rest = &prims.rest;
        let i = k as usize;
        let p = prims.verts[i];
        let po = prims.vert_obj[i];
        let at_rest = Aabb::of_points(&[rest[p as usize]], 0.0);
        self.trees
            .edges
            .query(&self.boxes.verts[i], &self.boxes.edges, stack, |j| {
                let f = prims.edges[j as usize];
                let fo = prims.edge_obj[j as usize];
                if !prims.edge_curve[j as usize]
                    || f.contains(&p)
                    || !prims.objects_may_collide(po, fo)
                    || all_kinematic(&[p, f[0], f[1]], self.inv_mass)
                {
                    return;
                }
                let mut d = prims.radius(po) + prims.radius(fo);
                if po == fo {
                    let gap2 = at_rest.distance_squared(&prims.at_rest.edge_boxes[j as usize]);
                    let exact = || {
                        let [a, b] = f.map(|v| rest[v as usize]);
                        distance::point_segment_closest(rest[p as usize], a, b).1
                    };
                    match same_object_reach(d, gap2, &exact) {
                        Some(r) => d = r,
                        None => return,
                    }
                }
                let pair = [k, j];
                out.push((
                    Candidate {
                        kind: PairKind::VertexEdge,
                        pair,
                    },
                    d,
                ));
            });
    }

    /// The vertex–face candidates of the vertices `verts`, in order, each query's hits sorted
    /// by face.
    fn vertex_face_pairs(
        &self,
        verts: std::ops::Range<usize>,
        stack: &mut Vec<u32>,
        out: &mut Vec<(Candidate, f64)>,
    ) {
        let prims = self.geo.prims;
        for i in verts {
            let window = prims.window(2, prims.vert_obj[i], None);
            let from = out.len();
            self.trees.faces.query_in(
                &self.boxes.verts[i],
                window,
                &self.boxes.faces,
                stack,
                |f| {
                    if let Some(d) = prims.vertex_face_reach(i, f, self.inv_mass) {
                        let pair = [i as u32, f];
                        out.push((
                            Candidate {
                                kind: PairKind::VertexFace,
                                pair,
                            },
                            d,
                        ));
                    }
                },
            );
            sort_by_second(out, from);
        }
    }

    /// The edge–edge candidates `(i, j)`, `j > i`, of the edges `i` in `edges`, in order, each
    /// query's hits sorted by `j`.
    fn edge_edge_pairs(
        &self,
        edges: std::ops::Range<usize>,
        stack: &mut Vec<u32>,
        out: &mut Vec<(Candidate, f64)>,
    ) {
        let prims = self.geo.prims;
        for i in edges {
            let window = prims.window(1, prims.edge_obj[i], Some(i as u32));
            let from = out.len();
            self.trees.edges.query_in(
                &self.boxes.edges[i],
                window,
                &self.boxes.edges,
                stack,
                |j| {
                    if let Some(d) = prims.edge_edge_reach(i, j, self.inv_mass) {
                        let pair = [i as u32, j];
                        out.push((
                            Candidate {
                                kind: PairKind::EdgeEdge,
                                pair,
                            },
                            d,
                        ));
                    }
                },
            );
            sort_by_second(out, from);
        }
    }

    /// The candidates of one collider feature `[feature, collider]` (with bounding box
    /// `tight`) against the faces (`faces`) or the edges: the trees' boxes are grown by each
    /// primitive's radius and margin, the query box by the collider's; then the Euclidean gap
    /// between the boxes must be within the collider's radius and margin (a sphere's centre
    /// meets only the faces near its surface, not every face in its bounding cube). Point
    /// features skip edges whose vertex tests are off.
    fn feature_candidates(
        &self,
        kind: PairKind,
        [f, c]: [u32; 2],
        tight: Aabb,
        faces: bool,
        pending: &mut Vec<(Candidate, f64)>,
        stack: &mut Vec<u32>,
    ) {
        let rc = self.geo.colliders.radius[c as usize];
        let reach = rc + margin(rc);
        let (bvh, boxes) = if faces {
            (&self.trees.faces, &self.boxes.faces)
        } else {
            (&self.trees.edges, &self.boxes.edges)
        };
        bvh.query(&tight.grow(reach), boxes, stack, |j| {
            if let Some(d) = self.feature_reach(kind, c, tight, faces, j) {
                pending.push((Candidate { kind, pair: [f, j] }, d));
            }
        });
    }

    /// The contact distance of collider `c`'s feature with box `tight` against face (`faces`)
    /// or edge `j`, if they form a candidate: not all kinematic, layers that collide, and the
    /// boxes' Euclidean gap within the collider's radius and margin.
    #[inline]
    fn feature_reach(
        &self,
        kind: PairKind,
        c: u32,
        tight: Aabb,
        faces: bool,
        j: u32,
    ) -> Option<f64> {
        let (prims, colliders) = (self.geo.prims, self.geo.colliders);
        let rc = colliders.radius[c as usize];
        let reach = rc + margin(rc);
        let (object, kinematic, b) = if faces {
            let tri = prims.faces[j as usize];
            (
                prims.face_obj[j as usize],
                all_kinematic(&tri, self.inv_mass),
                self.boxes.faces[j as usize],
            )
        } else {
            let points_only_where_tested =
                kind == PairKind::FeaturePointEdge && !prims.edge_point_tests[j as usize];
            let edge = prims.edges[j as usize];
            (
                prims.edge_obj[j as usize],
                points_only_where_tested || all_kinematic(&edge, self.inv_mass),
                self.boxes.edges[j as usize],
            )
        };
        if kinematic
            || !prims.collides_with_collider(object, &colliders.list[c as usize])
            || tight.distance_squared(&b) > reach * reach
        {
            return None;
        }
        Some(rc + prims.radius(object))
    }
}

/// Sorts the hits of one query (those from `from` on) by their second primitive.
fn sort_by_second(pending: &mut [(Candidate, f64)], from: usize) {
    pending[from..].sort_unstable_by_key(|c| c.0.pair[1]);
}

/// Runs `query` over `0..n` (vertices or edges), appending its hits to `pending`. Below
/// [`PARALLEL_MIN_QUERIES`] queries, or on one thread, the whole range runs here, straight
/// into `pending` with `stack`; else the range is cut into contiguous chunks, eight per
/// part, which the parts claim as they come free ([`claim_chunks`]; the queries of some
/// chunks find many more pairs than others'), each with its own hit list and its part's
/// stack (in `parts`), and the chunks' hits are appended in chunk order: the same list
/// whoever ran them. The buffers keep their capacity from step to step.
fn split_queries(
    n: usize,
    team: TeamRef<'_>,
    parts_scratch: &mut PartScratch,
    stack: &mut Vec<u32>,
    pending: &mut Vec<(Candidate, f64)>,
    query: &QueryFn<'_>,
) {
    let parts = team.parts();
    if n < PARALLEL_MIN_QUERIES || parts < 2 {
        query(0..n, stack, pending);
        return;
    }
    let chunks = (parts * CHUNKS_PER_PART).min(n);
    let PartScratch { hits: outs, stacks } = parts_scratch;
    if outs.len() < chunks {
        outs.resize_with(chunks, Vec::new);
    }
    if stacks.len() < parts {
        stacks.resize_with(parts, || Vec::with_capacity(128));
    }
    {
        let (o, st) = (SharedArray::new(outs), SharedArray::new(stacks));
        claim_chunks(team, chunks, &|part, c| {
            // SAFETY: a chunk takes only its own hit list, and a part only its own stack
            // (a part runs its chunks one after another); the arrays are exclusively
            // borrowed for this block and hold at least `chunks` and `parts` elements.
            let (out, stack) = unsafe { (&mut *o.at(c), &mut *st.at(part)) };
            // Worked on as locals: the vector headers share cache lines, and a push writes
            // its length (sharing them made two threads slower than one).
            let (mut hits, mut local) = (std::mem::take(out), std::mem::take(stack));
            hits.clear();
            query(span(c, chunks, n), &mut local, &mut hits);
            (*out, *stack) = (hits, local);
        });
    }
    for out in &outs[..chunks] {
        pending.extend_from_slice(out);
    }
}
