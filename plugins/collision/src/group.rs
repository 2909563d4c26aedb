//! The `collision` group: the primitives of the target objects, the broad phase, the contact
//! set of the current substep, and the stages that detect and resolve them. See the
//! [crate docs](crate) for the algorithm.

use glam::DVec3;
use nucleus_sdk::prelude::*;
use nucleus_sdk::team::{span, SharedArray, TeamRef};

use crate::broad_phase::bvh::{Aabb, Bvh, HashGrid, Window};
use crate::colliders::motion::Pose;
use crate::colliders::shapes::{
    first_contact, segment_enters_box, triangle_enters_box, Collider, Shape,
};
use crate::narrow_phase::distance;
use crate::narrow_phase::pairs::{self, Separation, Track};
use crate::params::{CollisionParams, ObjectSettings};
use crate::response::contact::{Contact, PairKind};

/// A pair of primitives whose swept boxes overlap this substep.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Candidate {
    /// What the two primitives are.
    pub kind: PairKind,
    /// The primitives (indices into the group's lists; see [`PairKind`]).
    pub pair: [u32; 2],
}

/// No contact for this candidate.
const NONE: u32 = u32::MAX;
/// Carrier of a frozen vertex that stays where it started the substep.
const CARRY_STILL: u32 = u32::MAX - 1;
/// Carriers from this value on (below [`CARRY_STILL`]) are analytic colliders: `CARRY_COLLIDER
/// + c` carries a frozen vertex with collider `c`'s rigid motion. Below it: local objects.
const CARRY_COLLIDER: u32 = 1 << 30;

/// Most thickness of a self-colliding object, in multiples of its mean rest edge length
/// ([`CollisionGroup`]'s build refuses more). At 4 a vertex of a regular triangle mesh keeps
/// about a hundred pairs with its own surface in the rest shape (pairs within `2 × thickness`,
/// about 8 edge lengths).
pub const MAX_THICKNESS_PER_EDGE: f64 = 4.0;

/// A pair of one object that is closer than its thickness `d` in the rest shape, without
/// sharing a vertex, is kept `REST_FRACTION ×` its rest distance apart instead of `d` (see
/// [`rest_reach`]).
pub const REST_FRACTION: f64 = 0.5;

/// The contact distance of a same-object pair of thickness `d` whose squared distance in the
/// rest shape is `rest_d2`: `d` if the rest shape keeps them that far apart, else
/// [`REST_FRACTION`] × the rest distance (they start closer than `d`: pushing them to `d`
/// would fight the object's own shape, and dropping them, as if they were neighbours, would
/// let them pass through each other however the object deforms), and `None` for a pair that
/// touches in the rest shape (coincident vertices of an unwelded seam: glued, like
/// neighbours).
pub fn rest_reach(d: f64, rest_d2: f64) -> Option<f64> {
    if rest_d2 >= d * d {
        Some(d)
    } else if rest_d2 > 0.0 {
        Some(REST_FRACTION * rest_d2.sqrt())
    } else {
        None
    }
}

/// Counters of one frame, for the stats.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Frame they belong to.
    pub frame: u64,
    /// Largest number of contacts in a substep.
    pub contacts: usize,
    /// Largest number of candidate pairs in a substep.
    pub candidates: usize,
    /// Full broad phases run: when a collider left its box or a mass changed, and when more
    /// than an eighth of the primitives left their boxes (at a substep's start or during
    /// the passes).
    pub broad_phases: usize,
    /// Partial broad phases: only the primitives that left their boxes looked for new pairs.
    pub refreshes: usize,
    /// Vertices frozen by the fail-safe.
    pub frozen: usize,
    /// Crossing pairs the fail-safe could not resolve (0 unless two colliders squeeze a
    /// vertex, or a deforming kinematic mesh sweeps through a frozen one).
    pub unresolved: usize,
    /// Deepest violation of the thickness at the end of a substep (m).
    pub max_penetration: f64,
}

/// All the collisions of one group.
pub struct CollisionGroup {
    restitution: f64,
    mu_static: f64,
    mu_dynamic: f64,
    /// Depenetration speed limit (m/s): see [`push_out_reach`].
    push_out_speed: f64,
    /// Settings of each target object (group-local object index).
    settings: Vec<ObjectSettings>,
    /// Whether each target object may collide with any target object, itself included
    /// ([`Self::objects_may_collide`]): the mesh queries of an object that meets none are not
    /// made, since every pair they would find is dropped.
    meets_objects: Vec<bool>,
    /// Each target object's primitives (group-local object index): its vertices', edges' and
    /// faces' index ranges, which are contiguous (an object's primitives are listed together).
    object_ranges: Vec<[(u32, u32); 3]>,
    /// Every particle of a vertex, an edge or a face (sorted), and the tight swept box of each
    /// (indexed by particle, radius 0): a primitive's tight box is the union of its
    /// particles' ([`Self::fill_particle_boxes`]).
    box_particles: Vec<u32>,
    particle_boxes: Vec<Aabb>,
    /// Name of each target object, for errors.
    names: Vec<String>,
    /// The most candidate pairs the group holds ([`candidate_budget`]); more is an error.
    candidate_budget: usize,
    /// The largest candidate list refused since the last check (0: none).
    over_budget: usize,
    /// Excluded pairs of group-local objects (sorted).
    excluded: Vec<[u32; 2]>,
    /// Rest positions (m), for the rest-distance filter of self-collision.
    rest: Vec<DVec3>,
    /// Particles of every vertex primitive, their object (local) and radius.
    verts: Vec<u32>,
    vert_obj: Vec<u32>,
    /// Vertex primitives that are unconnected particles (indices into `verts`).
    isolated: Vec<u32>,
    edges: Vec<[u32; 2]>,
    edge_obj: Vec<u32>,
    /// Whether each edge is a curve edge (in no triangle).
    edge_curve: Vec<bool>,
    /// Whether each edge is tested against the colliders' feature points: a curve edge, or
    /// an edge of an object whose faces do not collide (else its faces cover it).
    edge_point_tests: Vec<bool>,
    faces: Vec<[u32; 3]>,
    face_obj: Vec<u32>,
    /// Boxes of the edges and faces in the rest shape (not grown): a same-object pair whose
    /// boxes are `d` apart needs no exact rest distance.
    edge_rest_boxes: Vec<Aabb>,
    face_rest_boxes: Vec<Aabb>,
    /// The same-object vertex–face and edge–edge (`j > i`) pairs whose rest boxes are closer
    /// than their thickness, with the contact distance [`rest_reach`] gives them: every
    /// other same-object pair keeps its thickness. Found once; the broad phase looks a pair
    /// up instead of taking its exact rest distance every time it finds it.
    near_vertex_face: RestPairs,
    near_edge_edge: RestPairs,
    colliders: Vec<Collider>,
    /// Distance from each collider's core to its surface, plus its thickness (m).
    collider_radius: Vec<f64>,
    /// Sharp features of the colliders' cores ([`crate::colliders::shapes::Features`]): points and
    /// edges in their collider's rest frame, with the collider's index.
    feat_points: Vec<(u32, DVec3)>,
    feat_edges: Vec<(u32, [DVec3; 2])>,
    /// The feature edges that end at each feature point (a capsule's axis at its ends).
    point_edges: Vec<Vec<u32>>,
    /// The (at most two) faces on each edge (`NONE` for none).
    edge_faces: Vec<[u32; 2]>,
    /// (collider, local object) pairs impaled this substep ([`Self::find_impaled`]);
    /// capacity for every pair, set at build.
    impaled: Vec<(u32, u32)>,
    /// For each local object whose every vertex is kinematic, three vertices spanning a
    /// frame (its rigid motion carries vertices frozen by the fail-safe).
    rigid_frame: Vec<Option<[u32; 3]>>,
    /// Whether any pair can ever collide (else the group is empty and never scheduled).
    active: bool,

    // Broad phase (capacity kept between substeps).
    vert_boxes: Vec<Aabb>,
    edge_boxes: Vec<Aabb>,
    face_boxes: Vec<Aabb>,
    iso_boxes: Vec<Aabb>,
    edge_bvh: Bvh,
    face_bvh: Bvh,
    /// A tree over the vertices' boxes, for the faces that left their boxes
    /// ([`Self::refresh_escaped`]).
    vert_bvh: Bvh,
    /// Scratch of [`Self::refresh_escaped`]: which primitives left their boxes, and the new
    /// pairs.
    escaped_verts: Vec<bool>,
    escaped_edges: Vec<bool>,
    escaped_faces: Vec<bool>,
    /// The escaped vertices, faces and edges, listed for [`Self::escaped_pairs`].
    escaped_list: [Vec<u32>; 3],
    fresh: Vec<(Candidate, f64)>,
    grid: HashGrid,
    iso_pairs: Vec<[u32; 2]>,
    stack: Vec<u32>,
    collider_boxes: Vec<Aabb>,
    /// What the candidates were last found with, beyond the primitives' boxes: the colliders'
    /// boxes, the features' boxes and the vertices' inverse masses (empty before the first
    /// broad phase). A substep whose colliders and features lie within these, and whose masses
    /// are the same, keeps the candidates of the primitives that stayed in their boxes
    /// ([`Self::colliders_and_masses_hold`]).
    found_collider_boxes: Vec<Aabb>,
    found_feat_boxes: Vec<Aabb>,
    found_inv_mass: Vec<f64>,
    pose0: Vec<Pose>,
    pose1: Vec<Pose>,
    /// World positions of the feature points at the start and the end of the substep, and of
    /// the feature edges' ends (`[a0, b0, a1, b1]`); their swept boxes (not grown).
    feat_point_tracks: Vec<[DVec3; 2]>,
    feat_edge_tracks: Vec<[DVec3; 4]>,
    feat_point_boxes: Vec<Aabb>,
    feat_edge_boxes: Vec<Aabb>,
    /// Broad-phase scratch: candidates with their contact distance, before sorting.
    pending: Vec<(Candidate, f64)>,
    /// Broad-phase scratch over the thread team: each chunk's hits ([`claim_chunks`]) and each
    /// part's query stack.
    part_pending: Vec<Vec<(Candidate, f64)>>,
    /// The candidates each part of the team keeps in a refresh ([`merge_kept`]).
    part_kept: Vec<usize>,
    part_stacks: Vec<Vec<u32>>,
    /// Candidate pairs, sorted.
    candidates: Vec<Candidate>,
    /// Contact distance of each candidate (m): the sum of the two radii, or less for a pair
    /// of one object that is close in the rest shape ([`rest_reach`]).
    reach: Vec<f64>,
    /// Contact of each candidate (`NONE` if none).
    contact_of: Vec<u32>,
    /// The particles of each candidate (unused slots repeat one of them).
    cand_ids: Vec<[u32; 4]>,
    /// The separation of each candidate, taken the first time a pass tests it
    /// ([`Separation::UNKNOWN`] before that, and always for the kinds without one:
    /// particle pairs, and vertices against a box or a capsule; [`Self::separation_at`]), and
    /// the most any of its particles had then moved from `x_ref`.
    separation: Vec<Separation>,
    separation_moved: Vec<f64>,
    /// Each collider or feature candidate's primitive at the substep's start, once taken
    /// ([`Self::start_of`]; [`StartOf::UNKNOWN`] before). Only those kinds have one: the
    /// sorted list holds the vertex–collider pairs first and the feature pairs last, so
    /// `start` holds the first `start_split[0]` candidates' and then those from
    /// `start_split[1]` on ([`start_slot`]), not a slot for every self pair.
    start: Vec<StartOf>,
    start_split: [usize; 2],
    /// Whether each candidate's separation was taken ahead of its visit, over the team
    /// ([`Self::take_separations_ahead`]): positions may have moved since, so a pass that
    /// finds it no proof takes it again before testing the pair.
    taken_ahead: Vec<bool>,
    /// Set when the candidates were found again or a substep started
    /// ([`Self::restart_passes`]): the next pass takes the separations they lack ahead, over
    /// the team.
    separations_unknown: bool,
    /// During the pass that took the separations ahead: the particles its contacts have moved
    /// so far. A candidate none of whose particles moved still has exactly the separation
    /// taken ahead.
    touched: Vec<bool>,
    ahead_exact: bool,
    /// Whether the candidates' separations are over this substep's tracks: set once the
    /// substep's first broad phase, refresh or restart is done. A refresh within the substep
    /// then carries the separations of the candidates it keeps ([`Self::carry_separations`]).
    within_substep: bool,
    /// Scratch of [`Self::adopt`]: the candidates before a refresh, their separations and
    /// motions, and how far each particle has moved from the old `x_ref`.
    old_candidates: Vec<Candidate>,
    old_separation: Vec<Separation>,
    old_separation_moved: Vec<f64>,
    old_start: Vec<StartOf>,
    old_start_split: [usize; 2],
    carry_moved: Vec<f64>,
    /// The end positions the last broad phase saw, and how far each particle has moved from
    /// them since (m), kept current through a pass: a pair certainly apart at `x_ref` that has
    /// not moved enough to close the gap is skipped ([`Separation::certainly_apart`]).
    x_ref: Vec<DVec3>,
    moved: Vec<f64>,
    /// Contacts of the substep.
    contacts: Vec<Contact>,
    /// Positions after prediction, before the solve.
    x_pred: Vec<DVec3>,
    /// Velocities before the solve (end_substep scratch).
    v_pre: Vec<DVec3>,
    /// The push-out each particle got this substep ([`Self::record_push_outs`]), and the
    /// particles that got one.
    push: Vec<PushOut>,
    pushed: Vec<u32>,
    /// Fail-safe carrier of each particle.
    carrier: Vec<u32>,
    frozen_list: Vec<u32>,
    /// A displacement (m) taken off every swept box's end: every box of a substep is taken
    /// over `[x0, x − shift]` (the colliders' and features' too), so the boxes follow the
    /// motion the primitives share and the broad phase sees only their relative motion
    /// ([`Self::vert_box`]). It is the mean displacement of the group's dynamic vertices over
    /// the substep (from the prediction), updated only when that departs from it by more than
    /// the largest thickness plus its margin: a steady shift keeps the colliders' boxes where they were
    /// found, so the candidates can be kept, and a group that moves less than that a substep
    /// keeps a zero shift (the boxes of before the shift, bit for bit).
    shift: DVec3,
    /// The largest thickness of the group's objects (m).
    max_thickness: f64,
    h: f64,
    stats: FrameStats,
}

/// Most sweeps of the final projection of faces and edges out of the colliders' features.
const FEATURE_SWEEPS: usize = 8;

/// The margin (m) added to every swept box, beyond the thickness, so that the positions can
/// move a little during the solve without a new broad phase: 0.3 of the thickness plus a fixed
/// 0.1 mm. A tenth of the thickness (before 2026-11-23) sent a draping cloth back to the broad
/// phase at almost every pass (40 times a frame at 10 × 1 with the collision's 4 passes);
/// at 0.3 the 40 frames of `cloth_on_sphere` take 542 instead of 633 ms a frame on 2 threads,
/// `cloth_heap` 883 instead of 1041; a larger margin finds too many pairs (at 1.0, 450,000
/// on the 64 × 64 cloth, and slower again).
fn margin(radius: f64) -> f64 {
    0.3 * radius + 1e-4
}

/// A refresh ([`CollisionGroup::refresh_escaped`]) when at most one primitive in this many
/// left its box, else a full broad phase, whose queries arrive sorted. Measured on 2 threads,
/// the first 40 frames (ms per frame, `cloth_on_sphere` / `cloth_heap`): one in 4, 537 / 751;
/// one in 8, 498 / 752; one in 16, 495 / 781; never (always full), 527 / 953.
const REFRESH_MAX_SHARE: usize = 8;

/// From this many vertices (or edges) up, the broad phase's queries are split over the thread
/// team. Chosen, not tuned: a query costs about a microsecond, the team's hand-off about as
/// much as one.
const PARALLEL_MIN_QUERIES: usize = 512;

/// From this many items up, the per-candidate and per-primitive maps (the candidates' particles,
/// the carried separations, the primitives' boxes) are split over the thread team. Each item
/// costs a few nanoseconds, the team's hand-off about a microsecond.
const PARALLEL_MIN_ITEMS: usize = 16384;

/// `out[i] = f(i)` for every `i`, the indices split over the team in contiguous ranges from
/// [`PARALLEL_MIN_ITEMS`] on: each value is computed alone, so the array is the same on any
/// number of threads.
fn fill_over_team<T: Send>(team: TeamRef<'_>, out: &mut [T], f: impl Fn(usize) -> T + Sync) {
    team.for_ranges_mut(out, PARALLEL_MIN_ITEMS, &|r, out| {
        for (o, i) in out.iter_mut().zip(r) {
            *o = f(i);
        }
    });
}

/// How many chunks a job split over the team claims per part ([`claim_chunks`]): enough that
/// a part whose chunks cost more (the edge–edge pairs sort after the vertex–face ones, and
/// their exact distances cost more) is helped by the others, few enough that a chunk's
/// hand-off stays small against its work.
const CHUNKS_PER_PART: usize = 8;

/// Runs `f(part, chunk)` for every chunk `0..chunks` on the team, each chunk once, claimed by
/// the parts in turn as they come free (a part that finds its chunks cheap takes more), with
/// the claiming part's index. Whoever runs a chunk, it must write only what the chunk owns:
/// the results are then the same on any number of threads.
fn claim_chunks(team: TeamRef<'_>, chunks: usize, f: &(dyn Fn(usize, usize) + Sync)) {
    let next = std::sync::atomic::AtomicUsize::new(0);
    team.run(&|part| loop {
        // Relaxed: the counter only hands out chunk numbers; what the chunks write is published
        // by the end of the team's job.
        let c = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if c >= chunks {
            break;
        }
        f(part, c);
    });
}

/// The candidates of `old` (sorted, with their reaches) that `keep` keeps, merged with `fresh`
/// (sorted, none of them in `old`), into `out`: the sorted union. From [`PARALLEL_MIN_ITEMS`]
/// candidates on, `old` is split over the team in contiguous ranges: each part counts what it
/// keeps (`kept`, one count per part), and then writes its kept candidates merged with the
/// fresh ones that sort between its first candidate and the next part's, at the place the
/// counts before it give. The list is the same on any number of threads.
fn merge_kept(
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

/// A range of the broad phase's queries: `(group, range, stack, hits)`.
type QueryFn<'q> = dyn Fn(&CollisionGroup, std::ops::Range<usize>, &mut Vec<u32>, &mut Vec<(Candidate, f64)>)
    + Sync
    + 'q;

/// Particle `i`'s track over the substep: from `x0` to `x`.
#[inline]
fn track(x0: &[DVec3], x: &[DVec3], i: u32) -> Track {
    Track {
        x0: x0[i as usize],
        x1: x[i as usize],
    }
}

/// The index range of the primitives `owners` lists as object `k`'s, which are contiguous
/// (`(0, 0)` for none).
fn object_range(owners: &[u32], k: u32) -> (u32, u32) {
    let start = owners.partition_point(|&o| o < k);
    let end = owners.partition_point(|&o| o <= k);
    debug_assert!(
        owners.windows(2).all(|w| w[0] <= w[1]),
        "primitives out of object order"
    );
    if start == end {
        (0, 0)
    } else {
        (start as u32, end as u32)
    }
}

/// The distance a primitive is kept from an analytic collider (or its feature) at the end of
/// a substep: its contact distance `reach`, unless it started the substep deeper, at
/// `start` (m; the signed distance from the collider's surface for a vertex, the distance
/// from the feature otherwise): then `start + push` with `push = push_out_speed · h`, the
/// most it may leave by in one substep. Pushing a cloth placed through a sphere out in one
/// substep moves its inner vertices by up to the sphere's radius while their neighbours
/// stay, which tears the cloth and sends every jump through the rest of it; at a bounded
/// speed the stretch constraints carry the neighbours along. A primitive that starts
/// outside (`start ≥ reach − push`, every resting contact) keeps `reach`. A NaN start
/// keeps `reach` too.
#[inline]
pub(crate) fn push_out_reach(reach: f64, start: f64, push: f64) -> f64 {
    reach.min(start + push)
}

/// The faces on each edge (at most two kept; `NONE` for none).
fn edge_faces(edges: &[[u32; 2]], faces: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let index: std::collections::HashMap<[u32; 2], usize> =
        edges.iter().enumerate().map(|(i, &e)| (e, i)).collect();
    let mut out = vec![[NONE; 2]; edges.len()];
    for (f, t) in faces.iter().enumerate() {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if let Some(&e) = index.get(&[a.min(b), a.max(b)]) {
                match out[e] {
                    [NONE, _] => out[e][0] = f as u32,
                    [_, NONE] => out[e][1] = f as u32,
                    _ => {}
                }
            }
        }
    }
    out
}

/// How a collider or feature candidate's primitive leaves its collider in this substep, if
/// it started inside ([`CollisionGroup::start_of`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Leaves {
    /// As a contact and the fail-safe allow: out of the collider the way it came, or not
    /// inside at all.
    Normally,
    /// Through a box's corner or edge, or out of the box's interior.
    ThroughBox,
    /// Off a capsule's axis, over its end, with an object impaled on it
    /// ([`CollisionGroup::push_off_axis`], [`CollisionGroup::slide_off_axis`]).
    OffAxis,
}

/// A collider or feature candidate's primitive at the substep's start, taken the first time
/// the substep needs it and kept until the next ([`CollisionGroup::start_of`]): everything
/// in it depends only on `x0`, the collider's start pose, the candidate's reach and the
/// objects impaled this substep, so a pass, the final projections and the push-out's record
/// read it instead of taking it again.
#[derive(Clone, Copy, Debug)]
struct StartOf {
    /// Its signed distance (m) from the collider or feature ([`CollisionGroup::feature_side`],
    /// `Shape::signed_distance`); NaN until taken.
    distance: f64,
    /// How it leaves.
    leaves: Leaves,
}

impl StartOf {
    const UNKNOWN: StartOf = StartOf {
        distance: f64::NAN,
        leaves: Leaves::Normally,
    };
}

/// Where candidate `k`'s [`StartOf`] is kept, with the candidates split at
/// `[colliders, features]` (the vertex–collider pairs before the first, the feature pairs
/// from the second on: the order of [`PairKind`]); `None` for the pairs between, which have
/// none.
#[inline]
fn start_slot([colliders, features]: [usize; 2], k: usize) -> Option<usize> {
    if k < colliders {
        Some(k)
    } else if k >= features {
        Some(colliders + (k - features))
    } else {
        None
    }
}

/// A feature candidate's primitive against its feature ([`CollisionGroup::feature_side`]).
struct FeatureSide {
    /// The primitive's particles and their weights in its closest point `p`.
    ids: [u32; 3],
    w: [f64; 3],
    p: DVec3,
    /// The feature's closest point and the squared distance to it, as the query gives it.
    q: DVec3,
    d2: f64,
    /// Whether `p` is inside the collider (only a box's features can have it so).
    inside: bool,
}

impl FeatureSide {
    /// The signed distance (m): negative on the wrong side of a box's feature.
    fn distance(&self) -> f64 {
        if self.inside {
            -self.d2.sqrt()
        } else {
            self.d2.sqrt()
        }
    }

    /// The direction out (from the feature to the primitive, reversed on the wrong side),
    /// not normalised: `p − q` or `q − p`.
    fn out(&self) -> DVec3 {
        if self.inside {
            self.q - self.p
        } else {
            self.p - self.q
        }
    }
}

/// The push-out a particle carries: the outward speed pushes gave it while it was inside an
/// analytic collider, taken off when it gets out ([`CollisionGroup::drop_push_out_velocity`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PushOut {
    /// The direction out of the collider at the end of the last substep (unit).
    pub normal: DVec3,
    /// The collider's own speed along `normal` there (m/s): the particle keeps it.
    pub collider_speed: f64,
    /// The outward speed the pushes gave the particle so far (m/s), at most the push-out
    /// speed (0: none).
    pub speed: f64,
    /// The most a push gave it in this substep (m/s).
    given: f64,
    /// Whether a primitive of the particle started this substep inside (it is listed), and
    /// whether one still had to be held back by the push-out speed (it is not out yet).
    seen: bool,
    inside: bool,
    /// Whether the particle is in the group's list of pushed particles.
    listed: bool,
}

impl PushOut {
    pub const NONE: Self = Self {
        normal: DVec3::ZERO,
        collider_speed: 0.0,
        speed: 0.0,
        given: 0.0,
        seen: false,
        inside: false,
        listed: false,
    };
}

/// The velocity a particle keeps once out of a collider whose pushes gave it `push.speed`
/// along `push.normal` (unit), the collider's own speed along it being `push.collider_speed`
/// (m/s): its outward speed relative to the collider loses up to `push.speed` and never goes
/// below zero by it. The push moves the particle out without launching it (as a split impulse
/// does), while the part of its motion the push did not cause — a throw faster than the push,
/// the collider's own motion, any tangential motion — is kept.
pub(crate) fn without_push_velocity(v: DVec3, push: &PushOut) -> DVec3 {
    let outward = v.dot(push.normal) - push.collider_speed;
    if outward > 0.0 && push.speed > 0.0 {
        v - push.normal * outward.min(push.speed)
    } else {
        v
    }
}

/// The outward speed (m/s) a push-out gave a primitive in a substep of length `h`: how far it
/// ended out (`end`, capped at the `target` [`push_out_reach`] allowed) beyond where it started
/// (`start`) or where the prediction alone put it (`predicted`), whichever is further out — all
/// three its distance from the collider's surface or feature (m). A primitive carried out by
/// its own velocity (`predicted` at or beyond `end`) got none; one at rest inside got
/// `end − start`. Negative: none (a NaN start is never pushed: see [`push_out_reach`]).
pub(crate) fn push_speed(start: f64, predicted: f64, end: f64, target: f64, h: f64) -> f64 {
    (end.min(target) - start.max(predicted)) / h
}

/// Whether a distance from a collider's surface or feature (m) is short of a contact distance
/// `reach` by more than the rounding of a projection onto it (a relative 1e-9): a primitive
/// that starts a substep so is inside, one that starts a resting contact is not.
pub(crate) fn short_of(distance: f64, reach: f64) -> bool {
    distance < reach * (1.0 - 1e-9)
}

/// Whether a primitive pushed out of a collider is still inside at the end of a substep: the
/// push-out speed held it back (its `target` [`push_out_reach`] is short of its contact
/// distance `reach`) and it ended [`short_of`] `reach` (`end`). All three distances (m) from
/// the collider's surface or feature.
pub(crate) fn still_inside(end: f64, target: f64, reach: f64) -> bool {
    target < reach && short_of(end, reach)
}

/// The least [`candidate_budget`]: about 100 MB of candidate state.
const MIN_CANDIDATE_BUDGET: usize = 1 << 20;

/// The most candidate pairs a group may hold at once: 64 per primitive, or 8 per same-object
/// pair closer than its contact distance at rest (a thick cloth has hundreds of those per
/// vertex), at least [`MIN_CANDIDATE_BUDGET`]. The shipped scenes peak at about 8 per
/// primitive (`cloth_heap`, 203,962 for 24,067 primitives); a dense crumple stacks a few layers
/// within reach, and fast relative motion a few times more. Beyond the budget the substep
/// fails with an error naming the fastest object ([`CollisionGroup::over_budget_error`]) instead
/// of holding every pair: a gravity of −2e9 m/s² on `cloth_on_sphere` (6 km a substep except
/// where the sphere stops the cloth) made 54 million candidates, several gigabytes, and 76 s
/// a substep.
fn candidate_budget(primitives: usize, rest_pairs: usize) -> usize {
    (64 * primitives)
        .max(8 * rest_pairs)
        .max(MIN_CANDIDATE_BUDGET)
}

/// Sorts the hits of one query (those from `from` on) by their second primitive.
fn sort_by_second(pending: &mut [(Candidate, f64)], from: usize) {
    pending[from..].sort_unstable_by_key(|c| c.0.pair[1]);
}

/// Pairs of primitives found once from the rest shape, per first primitive (compressed rows):
/// the second primitives in increasing order, each with its contact distance (`None`:
/// glued, never a pair).
#[derive(Clone, Debug, Default)]
struct RestPairs {
    /// Row `i` is `first[i]..first[i + 1]`.
    first: Vec<u32>,
    other: Vec<u32>,
    reach: Vec<Option<f64>>,
}

impl RestPairs {
    /// The rows of `n` first primitives, each filled by `row(i, out)` in any order.
    fn collect(n: usize, mut row: impl FnMut(usize, &mut Vec<(u32, Option<f64>)>)) -> RestPairs {
        let mut pairs = RestPairs {
            first: Vec::with_capacity(n + 1),
            ..RestPairs::default()
        };
        pairs.first.push(0);
        let mut out = Vec::new();
        for i in 0..n {
            out.clear();
            row(i, &mut out);
            out.sort_unstable_by_key(|&(j, _)| j);
            pairs.other.extend(out.iter().map(|&(j, _)| j));
            pairs.reach.extend(out.iter().map(|&(_, r)| r));
            pairs.first.push(pairs.other.len() as u32);
        }
        pairs
    }

    /// The contact distance of pair `(i, j)` if it is listed (`Some(None)`: glued).
    #[inline]
    fn reach(&self, i: usize, j: u32) -> Option<Option<f64>> {
        let row = self.first[i] as usize..self.first[i + 1] as usize;
        let k = self.other[row.clone()].binary_search(&j).ok()?;
        Some(self.reach[row.start + k])
    }
}

/// The contact distance of a same-object pair whose rest boxes are `gap2` (squared) apart,
/// from its exact rest distance `exact()` only when the boxes are closer than `d`.
fn same_object_reach(d: f64, gap2: f64, exact: &dyn Fn() -> f64) -> Option<f64> {
    if gap2 >= d * d {
        Some(d)
    } else {
        rest_reach(d, exact())
    }
}

impl CollisionGroup {
    /// Builds the group: collects the vertices, edges and faces of the target objects (only
    /// the surface of tetrahedral solids), their settings and the colliders.
    pub fn new(params: &CollisionParams, scene: &SceneView<'_>) -> Result<Self, PluginError> {
        params.validate_numbers()?;
        let rest = scene.rest_positions().to_vec();
        let inv_mass = scene.inv_mass.as_slice();
        let n = rest.len().min(inv_mass.len());

        let targets = scene.unique_targets()?;
        let names: Vec<&str> = targets.iter().map(|(_, o)| o.name.as_str()).collect();
        let settings = params.object_settings(&names)?;
        let excluded = params.excluded_pairs(&names)?;
        let colliders = params.colliders()?;

        let mut collider_radius = Vec::with_capacity(colliders.len());
        let (mut feat_points, mut feat_edges) = (Vec::new(), Vec::new());
        for (c, col) in colliders.iter().enumerate() {
            let f = col.shape.features();
            collider_radius.push(f.radius + col.thickness);
            feat_points.extend(f.points.into_iter().map(|p| (c as u32, p)));
            feat_edges.extend(f.edges.into_iter().map(|e| (c as u32, e)));
        }

        let mut g = Self {
            restitution: params.restitution,
            mu_static: params.friction_static,
            mu_dynamic: params.friction_dynamic,
            push_out_speed: params.push_out_speed,
            settings,
            meets_objects: Vec::new(),
            object_ranges: Vec::new(),
            box_particles: Vec::new(),
            particle_boxes: vec![Aabb::EMPTY; n],
            names: names.iter().map(|n| n.to_string()).collect(),
            candidate_budget: usize::MAX,
            over_budget: 0,
            excluded,
            rest,
            verts: Vec::new(),
            vert_obj: Vec::new(),
            isolated: Vec::new(),
            edges: Vec::new(),
            edge_obj: Vec::new(),
            edge_curve: Vec::new(),
            edge_point_tests: Vec::new(),
            faces: Vec::new(),
            face_obj: Vec::new(),
            edge_rest_boxes: Vec::new(),
            face_rest_boxes: Vec::new(),
            near_vertex_face: RestPairs::default(),
            near_edge_edge: RestPairs::default(),
            colliders,
            collider_radius,
            feat_point_tracks: vec![[DVec3::ZERO; 2]; feat_points.len()],
            feat_edge_tracks: vec![[DVec3::ZERO; 4]; feat_edges.len()],
            feat_point_boxes: vec![Aabb::EMPTY; feat_points.len()],
            feat_edge_boxes: vec![Aabb::EMPTY; feat_edges.len()],
            point_edges: Vec::new(),
            edge_faces: Vec::new(),
            impaled: Vec::new(),
            feat_points,
            feat_edges,
            rigid_frame: Vec::new(),
            active: false,
            vert_boxes: Vec::new(),
            edge_boxes: Vec::new(),
            face_boxes: Vec::new(),
            iso_boxes: Vec::new(),
            edge_bvh: Bvh::default(),
            face_bvh: Bvh::default(),
            vert_bvh: Bvh::default(),
            escaped_verts: Vec::new(),
            escaped_edges: Vec::new(),
            escaped_faces: Vec::new(),
            escaped_list: Default::default(),
            fresh: Vec::new(),
            grid: HashGrid::default(),
            iso_pairs: Vec::new(),
            stack: Vec::with_capacity(128),
            collider_boxes: Vec::new(),
            found_collider_boxes: Vec::new(),
            found_feat_boxes: Vec::new(),
            found_inv_mass: Vec::new(),
            pose0: Vec::new(),
            pose1: Vec::new(),
            pending: Vec::new(),
            part_pending: Vec::new(),
            part_kept: Vec::new(),
            part_stacks: Vec::new(),
            candidates: Vec::new(),
            reach: Vec::new(),
            contact_of: Vec::new(),
            cand_ids: Vec::new(),
            separation: Vec::new(),
            separation_moved: Vec::new(),
            start: Vec::new(),
            start_split: [0, 0],
            taken_ahead: Vec::new(),
            separations_unknown: false,
            touched: Vec::new(),
            ahead_exact: false,
            within_substep: false,
            old_candidates: Vec::new(),
            old_separation: Vec::new(),
            old_separation_moved: Vec::new(),
            old_start: Vec::new(),
            old_start_split: [0, 0],
            carry_moved: Vec::new(),
            x_ref: vec![DVec3::ZERO; n],
            moved: vec![0.0; n],
            contacts: Vec::new(),
            x_pred: vec![DVec3::ZERO; n],
            v_pre: vec![DVec3::ZERO; n],
            push: vec![PushOut::NONE; n],
            pushed: Vec::with_capacity(n),
            carrier: vec![NONE; n],
            frozen_list: Vec::new(),
            shift: DVec3::ZERO,
            max_thickness: 0.0,
            h: 0.0,
            stats: FrameStats::default(),
        };

        let objects = g.settings.len() as u32;
        g.meets_objects = (0..objects)
            .map(|a| (0..objects).any(|b| g.objects_may_collide(a, b)))
            .collect();
        let mut dynamic_objects = Vec::new();
        for (k, &(_, o)) in targets.iter().enumerate() {
            let s = g.settings[k];
            let range = o.particles();
            let bad = |m: String| PluginError::bad_object(o.name.as_str(), m);
            let check = |i: u32| -> Result<(), PluginError> {
                if range.contains(&(i as usize)) {
                    Ok(())
                } else {
                    Err(bad(format!(
                        "vertex {i} is outside the object's particles {}..{}",
                        range.start, range.end
                    )))
                }
            };
            let tet_count = o.triangle_tet_count.as_slice();
            let mut surface: Vec<[u32; 3]> = Vec::new();
            for (i, tri) in o.triangles.as_slice().iter().enumerate() {
                if tet_count.get(i).copied().unwrap_or(0) < 2 {
                    for &v in tri {
                        check(v)?;
                    }
                    surface.push(*tri);
                }
            }
            let mut edges: Vec<([u32; 2], bool)> = surface
                .iter()
                .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
                .map(|[a, b]| ([a.min(b), a.max(b)], false))
                .collect();
            let counts = o.edge_triangle_count.as_slice();
            for (i, e) in o.edges.as_slice().iter().enumerate() {
                if counts.get(i).copied() == Some(0) {
                    check(e[0])?;
                    check(e[1])?;
                    edges.push(([e[0].min(e[1]), e[0].max(e[1])], true));
                }
            }
            edges.sort_unstable();
            edges.dedup_by(|a, b| a.0 == b.0);
            edges.retain(|(e, _)| e[0] != e[1]);
            let mut verts: Vec<u32> = surface
                .iter()
                .flatten()
                .copied()
                .chain(edges.iter().flat_map(|(e, _)| *e))
                .collect();
            let mut points = o.points.as_slice().to_vec();
            for &p in &points {
                check(p)?;
            }
            points.sort_unstable();
            verts.extend_from_slice(&points);
            verts.sort_unstable();
            verts.dedup();

            let all_kinematic = range.clone().all(|i| inv_mass[i] == 0.0);
            g.rigid_frame.push(if all_kinematic {
                frame_vertices(&g.rest, &verts)
            } else {
                None
            });
            if !all_kinematic {
                dynamic_objects.push(k);
            }
            if s.vertex {
                for &v in &verts {
                    if points.binary_search(&v).is_ok() {
                        g.isolated.push(g.verts.len() as u32);
                    }
                    g.verts.push(v);
                    g.vert_obj.push(k as u32);
                }
            }
            if s.edge {
                for (e, curve) in edges {
                    g.edges.push(e);
                    g.edge_obj.push(k as u32);
                    g.edge_curve.push(curve);
                    g.edge_point_tests.push(curve || !s.face);
                }
            }
            if s.face {
                for t in surface {
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        g.faces.push(t);
                        g.face_obj.push(k as u32);
                    }
                }
            }
        }

        // Can anything collide? A dynamic object with a collider on a common layer (through
        // its vertices, or its edges and faces against a collider with sharp features), with
        // itself, or with another object on a common layer that is not excluded.
        let k_count = targets.len();
        let has = |list: &[u32], k: usize| list.contains(&(k as u32));
        let any_prims =
            |k: usize| has(&g.vert_obj, k) || has(&g.edge_obj, k) || has(&g.face_obj, k);
        for &k in &dynamic_objects {
            if !any_prims(k) {
                continue;
            }
            let mask = g.settings[k].layers;
            let edges_or_faces = has(&g.edge_obj, k) || has(&g.face_obj, k);
            for (c, col) in g.colliders.iter().enumerate() {
                let features = g.feat_points.iter().any(|f| f.0 == c as u32);
                if col.layers & mask != 0 && (has(&g.vert_obj, k) || edges_or_faces && features) {
                    g.active = true;
                }
            }
            if g.settings[k].self_collision && g.may_self_collide(k as u32) {
                g.active = true;
            }
            for other in 0..k_count {
                if other != k && any_prims(other) && g.objects_may_collide(k as u32, other as u32) {
                    g.active = true;
                }
            }
        }

        g.max_thickness = g.settings.iter().map(|s| s.thickness).fold(0.0, f64::max);
        g.point_edges = g
            .feat_points
            .iter()
            .map(|&(c, p)| {
                (0..g.feat_edges.len() as u32)
                    .filter(|&e| {
                        let (ec, [a, b]) = g.feat_edges[e as usize];
                        ec == c && (a == p || b == p)
                    })
                    .collect()
            })
            .collect();
        g.edge_faces = edge_faces(&g.edges, &g.faces);
        g.box_particles = (g.verts.iter().copied())
            .chain(g.edges.iter().flatten().copied())
            .chain(g.faces.iter().flatten().copied())
            .collect();
        g.box_particles.sort_unstable();
        g.box_particles.dedup();
        g.object_ranges = (0..targets.len() as u32)
            .map(|k| [&g.vert_obj, &g.edge_obj, &g.face_obj].map(|owners| object_range(owners, k)))
            .collect();
        g.impaled = Vec::with_capacity(g.colliders.len() * g.settings.len());

        // Broad-phase structures over the rest pose; refit from the first substep on.
        let radius_v = |i: usize| g.settings[g.vert_obj[i] as usize].thickness;
        g.vert_boxes = (0..g.verts.len())
            .map(|i| Aabb::of_points(&[g.rest[g.verts[i] as usize]], radius_v(i)))
            .collect();
        g.edge_boxes = g
            .edges
            .iter()
            .zip(&g.edge_obj)
            .map(|(e, &o)| {
                Aabb::of_points(
                    &[g.rest[e[0] as usize], g.rest[e[1] as usize]],
                    g.settings[o as usize].thickness,
                )
            })
            .collect();
        g.face_boxes = g
            .faces
            .iter()
            .zip(&g.face_obj)
            .map(|(f, &o)| {
                Aabb::of_points(
                    &[
                        g.rest[f[0] as usize],
                        g.rest[f[1] as usize],
                        g.rest[f[2] as usize],
                    ],
                    g.settings[o as usize].thickness,
                )
            })
            .collect();
        g.edge_bvh = Bvh::build(&g.edge_boxes);
        g.face_bvh = Bvh::build(&g.face_boxes);
        g.vert_bvh = Bvh::build(&g.vert_boxes);
        g.escaped_verts = vec![false; g.verts.len()];
        g.escaped_edges = vec![false; g.edges.len()];
        g.escaped_faces = vec![false; g.faces.len()];
        let rest = &g.rest;
        g.edge_rest_boxes = g
            .edges
            .iter()
            .map(|e| Aabb::of_points(&e.map(|i| rest[i as usize]), 0.0))
            .collect();
        g.face_rest_boxes = g
            .faces
            .iter()
            .map(|f| Aabb::of_points(&f.map(|i| rest[i as usize]), 0.0))
            .collect();
        for &k in &dynamic_objects {
            let o = targets[k].1;
            g.check_self_thickness(k as u32)
                .map_err(|m| PluginError::bad_object(o.name.as_str(), m))?;
        }
        g.near_vertex_face = g.near_vertex_face_pairs();
        g.near_edge_edge = g.near_edge_edge_pairs();
        g.candidate_budget = match params.max_candidates {
            0 => candidate_budget(
                g.verts.len() + g.edges.len() + g.faces.len(),
                g.near_vertex_face.other.len() + g.near_edge_edge.other.len(),
            ),
            n => usize::try_from(n).unwrap_or(usize::MAX),
        };
        g.iso_boxes = vec![Aabb::EMPTY; g.isolated.len()];
        g.collider_boxes = vec![Aabb::EMPTY; g.colliders.len()];
        g.pose0 = vec![Pose::IDENTITY; g.colliders.len()];
        g.pose1 = vec![Pose::IDENTITY; g.colliders.len()];
        let prims = g.verts.len() + g.edges.len() + g.faces.len();
        g.pending.reserve(4 * prims);
        g.candidates.reserve(4 * prims);
        g.reach.reserve(4 * prims);
        g.contact_of.reserve(4 * prims);
        g.contacts.reserve(prims);
        Ok(g)
    }

    /// Whether object `k` (local) has two primitives that could form a pair: a vertex and a
    /// face, two edges, two unconnected particles, or one and a curve edge.
    fn may_self_collide(&self, k: u32) -> bool {
        let count = |list: &[u32]| list.iter().filter(|&&o| o == k).count();
        let (verts, edges, faces) = (
            count(&self.vert_obj),
            count(&self.edge_obj),
            count(&self.face_obj),
        );
        let isolated = self
            .isolated
            .iter()
            .filter(|&&i| self.vert_obj[i as usize] == k)
            .count();
        (faces > 0 && verts > 3) || edges > 1 || isolated > 1 || (isolated > 0 && edges > 0)
    }

    /// Refuses a self-colliding dynamic object whose thickness is more than
    /// [`MAX_THICKNESS_PER_EDGE`] times its mean rest edge length: every vertex would keep
    /// hundreds to millions of pairs with its own surface in the rest shape (a 0.5 m thickness
    /// on a 64 × 64, 1 m cloth: 30 s to build, minutes a substep), and the cloth could not
    /// fold anyway. The message gives the limit and the two ways out.
    fn check_self_thickness(&self, k: u32) -> Result<(), String> {
        let s = self.settings[k as usize];
        if !s.self_collision || !self.may_self_collide(k) {
            return Ok(());
        }
        let (mut sum, mut count) = (0.0, 0usize);
        for (e, _) in self.edges.iter().zip(&self.edge_obj).filter(|p| *p.1 == k) {
            sum += self.rest[e[0] as usize].distance(self.rest[e[1] as usize]);
            count += 1;
        }
        // No edges, or a rest shape without length (or not finite): nothing to compare with.
        let mean = if count > 0 { sum / count as f64 } else { 0.0 };
        if mean.is_nan() || mean <= 0.0 || s.thickness <= MAX_THICKNESS_PER_EDGE * mean {
            return Ok(());
        }
        Err(format!(
            "thickness {} m is {:.1} times the object's mean edge length ({:.3e} m); with \
             self-collision at most {MAX_THICKNESS_PER_EDGE} times it ({:.3e} m) is accepted, since \
             every vertex would be in contact with its own surface at rest: use a smaller \
             thickness, or turn self_collision off for this object (objects_settings)",
            s.thickness,
            s.thickness / mean,
            mean,
            MAX_THICKNESS_PER_EDGE * mean
        ))
    }

    /// The same-object vertex–face pairs of [`Self::near_vertex_face`], found with a
    /// bounding-volume tree over the faces' rest boxes.
    fn near_vertex_face_pairs(&self) -> RestPairs {
        let grown: Vec<Aabb> = (self.face_rest_boxes.iter().zip(&self.face_obj))
            .map(|(b, &o)| b.grow(2.0 * self.radius(o)))
            .collect();
        let bvh = Bvh::build(&grown);
        let mut stack = Vec::new();
        RestPairs::collect(self.verts.len(), |i, out| {
            let (p, po) = (self.verts[i], self.vert_obj[i]);
            let at_rest = Aabb::of_points(&[self.rest[p as usize]], 0.0);
            let d = 2.0 * self.radius(po);
            bvh.query(&at_rest, &grown, &mut stack, |f| {
                let tri = self.faces[f as usize];
                if self.face_obj[f as usize] != po || tri.contains(&p) {
                    return;
                }
                if at_rest.distance_squared(&self.face_rest_boxes[f as usize]) < d * d {
                    let [a, b, c] = tri.map(|k| self.rest[k as usize]);
                    let exact = distance::point_triangle_closest(self.rest[p as usize], a, b, c).1;
                    out.push((f, rest_reach(d, exact)));
                }
            });
        })
    }

    /// The same-object edge–edge pairs `(i, j)`, `j > i`, of [`Self::near_edge_edge`].
    fn near_edge_edge_pairs(&self) -> RestPairs {
        let grown: Vec<Aabb> = (self.edge_rest_boxes.iter().zip(&self.edge_obj))
            .map(|(b, &o)| b.grow(2.0 * self.radius(o)))
            .collect();
        let bvh = Bvh::build(&grown);
        let mut stack = Vec::new();
        RestPairs::collect(self.edges.len(), |i, out| {
            let (e, eo) = (self.edges[i], self.edge_obj[i]);
            let d = 2.0 * self.radius(eo);
            bvh.query(&self.edge_rest_boxes[i], &grown, &mut stack, |j| {
                let f = self.edges[j as usize];
                if j as usize <= i
                    || self.edge_obj[j as usize] != eo
                    || f.contains(&e[0])
                    || f.contains(&e[1])
                {
                    return;
                }
                let gap2 =
                    self.edge_rest_boxes[i].distance_squared(&self.edge_rest_boxes[j as usize]);
                if gap2 < d * d {
                    let [a, b] = e.map(|v| self.rest[v as usize]);
                    let [c, g] = f.map(|v| self.rest[v as usize]);
                    let exact = distance::segment_segment_closest(a, b, c, g).2;
                    out.push((j, rest_reach(d, exact)));
                }
            });
        })
    }

    fn is_excluded(&self, a: u32, b: u32) -> bool {
        self.excluded.binary_search(&[a.min(b), a.max(b)]).is_ok()
    }

    /// The contacts of the current substep.
    pub fn contacts(&self) -> &[Contact] {
        &self.contacts
    }

    /// The candidate pairs of the current substep.
    pub fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }

    /// The counters of the last frame.
    pub fn frame_stats(&self) -> FrameStats {
        self.stats
    }

    /// Number of vertex, edge and face primitives.
    pub fn primitive_counts(&self) -> [usize; 3] {
        [self.verts.len(), self.edges.len(), self.faces.len()]
    }

    fn radius(&self, local_object: u32) -> f64 {
        self.settings[local_object as usize].thickness
    }

    // ------------------------------------------------------------------------------------
    // Broad phase
    // ------------------------------------------------------------------------------------

    /// The tight swept box of a primitive: its particles over `[x0, x − shift]`, grown by its
    /// radius.
    ///
    /// Why the shift ([`Self::shift`]) keeps every pair: two points that come within `d` at
    /// some time `t` of the substep, on their linear tracks `x0 + t (x − x0)`, are still within
    /// `d` once both are moved by the same `−t·shift`, and the moved track
    /// `x0 + t (x − shift − x0)` lies in the box of `x0` and `x − shift`. So the boxes of any
    /// pair that can touch overlap, whatever the shift, as long as every box of the substep
    /// (the colliders' and features' included) takes the same one. A cloth carried fast then
    /// has boxes the size of its relative motion instead of its travel: `cloth_on_sphere`'s
    /// 64 × 64 cloth thrown at 20 m/s has 35,218 candidates a substep instead of 258,446, and
    /// steps 3.6 times faster with the same bits. A motion that is not shared is not helped:
    /// under a gravity of −2e9 m/s² the cloth falls 6 km in a substep except where the sphere
    /// stops it, and one substep still takes over a minute.
    #[inline]
    fn vert_box(&self, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        let p = self.verts[i] as usize;
        let s = self.shift;
        Aabb::of_points(&[x0[p], x[p] - s], self.radius(self.vert_obj[i]))
    }

    #[inline]
    fn edge_box(&self, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        let [a, b] = self.edges[i];
        let (a, b) = (a as usize, b as usize);
        let s = self.shift;
        Aabb::of_points(
            &[x0[a], x0[b], x[a] - s, x[b] - s],
            self.radius(self.edge_obj[i]),
        )
    }

    #[inline]
    fn face_box(&self, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        let [a, b, c] = self.faces[i];
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let s = self.shift;
        Aabb::of_points(
            &[x0[a], x0[b], x0[c], x[a] - s, x[b] - s, x[c] - s],
            self.radius(self.face_obj[i]),
        )
    }

    /// The mean displacement of the group's dynamic vertices from `x0` to `x` (zero if none
    /// moves or it is not finite): the substep's [`Self::shift`].
    fn shared_displacement(&self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64]) -> DVec3 {
        let (mut sum, mut n) = (DVec3::ZERO, 0usize);
        for &p in &self.verts {
            let p = p as usize;
            if inv_mass[p] > 0.0 {
                sum += x[p] - x0[p];
                n += 1;
            }
        }
        let mean = sum / n.max(1) as f64;
        if mean.is_finite() {
            mean
        } else {
            DVec3::ZERO
        }
    }

    /// Whether a pair of objects (local) may collide at all: one object with itself if its
    /// `self_collision` is on; two objects if they share a layer and are not excluded.
    #[inline]
    fn objects_may_collide(&self, a: u32, b: u32) -> bool {
        if a == b {
            self.settings[a as usize].self_collision
        } else {
            self.settings[a as usize].layers & self.settings[b as usize].layers != 0
                && !self.is_excluded(a, b)
        }
    }

    /// What a query of object `obj`'s primitive wants from the tree of `tree` (0 vertices,
    /// 1 edges, 2 faces): nothing if the object meets no object, not its own primitives
    /// if it does not collide with itself, and only indices past `above` if given. Every
    /// primitive refused would give a pair [`Self::objects_may_collide`] drops.
    #[inline]
    fn window(&self, tree: usize, obj: u32, above: Option<u32>) -> Window {
        let o = obj as usize;
        Window {
            above,
            skip: if self.settings[o].self_collision {
                (0, 0)
            } else {
                self.object_ranges[o][tree]
            },
            none: !self.meets_objects[o],
        }
    }

    /// Whether an object (local) and a collider share a layer.
    #[inline]
    fn collides_with_collider(&self, object: u32, collider: u32) -> bool {
        self.settings[object as usize].layers & self.colliders[collider as usize].layers != 0
    }

    /// Whether a candidate involves only kinematic particles.
    fn all_kinematic(ids: &[u32], inv_mass: &[f64]) -> bool {
        ids.iter().all(|&i| inv_mass[i as usize] == 0.0)
    }

    /// The candidates of one collider feature `[feature, collider]` (with bounding box
    /// `tight`) against the faces (`faces`) or the edges: the trees' boxes are grown by each
    /// primitive's radius and margin, the query box by the collider's; then the Euclidean gap
    /// between the boxes must be within the collider's radius and margin (a sphere's centre
    /// meets only the faces near its surface, not every face in its bounding cube). Point
    /// features skip edges whose vertex tests are off.
    #[allow(clippy::too_many_arguments)]
    fn feature_candidates(
        &self,
        kind: PairKind,
        [f, c]: [u32; 2],
        tight: Aabb,
        faces: bool,
        inv_mass: &[f64],
        pending: &mut Vec<(Candidate, f64)>,
        stack: &mut Vec<u32>,
    ) {
        let rc = self.collider_radius[c as usize];
        let reach = rc + margin(rc);
        let (bvh, boxes) = if faces {
            (&self.face_bvh, &self.face_boxes)
        } else {
            (&self.edge_bvh, &self.edge_boxes)
        };
        bvh.query(&tight.grow(reach), boxes, stack, |j| {
            if let Some(d) = self.feature_reach(kind, c, tight, faces, j, inv_mass) {
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
        inv_mass: &[f64],
    ) -> Option<f64> {
        let rc = self.collider_radius[c as usize];
        let reach = rc + margin(rc);
        let (object, kinematic, b) = if faces {
            let tri = self.faces[j as usize];
            (
                self.face_obj[j as usize],
                Self::all_kinematic(&tri, inv_mass),
                self.face_boxes[j as usize],
            )
        } else {
            let points_only_where_tested =
                kind == PairKind::FeaturePointEdge && !self.edge_point_tests[j as usize];
            let edge = self.edges[j as usize];
            (
                self.edge_obj[j as usize],
                points_only_where_tested || Self::all_kinematic(&edge, inv_mass),
                self.edge_boxes[j as usize],
            )
        };
        if kinematic
            || !self.collides_with_collider(object, c)
            || tight.distance_squared(&b) > reach * reach
        {
            return None;
        }
        Some(rc + self.radius(object))
    }

    /// Refits the trees to the swept boxes over `[x0, x]` (grown by a margin) and collects the
    /// candidate pairs with their contact distances, sorted; remaps the existing contacts onto
    /// them. The pairs are generated in their sorted order — kinds in [`PairKind`] order, the
    /// first primitive ascending, and each query's hits sorted by the second — so no global
    /// sort is needed (checked in debug builds).
    fn broad_phase(&mut self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64], team: TeamRef<'_>) {
        self.fill_particle_boxes(x0, x);
        self.broad_phase_from_particle_boxes(x, inv_mass, team);
    }

    /// [`Self::broad_phase`] with the particle boxes already filled at `[x0, x]`
    /// ([`Self::fill_particle_boxes`]), as a refresh that falls back to it has them.
    fn broad_phase_from_particle_boxes(
        &mut self,
        x: &[DVec3],
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) {
        self.stats.broad_phases += 1;
        for kind in 0..3 {
            let mut boxes = std::mem::take(self.boxes_and_flags(kind).0);
            let this = &*self;
            team.for_ranges_mut(&mut boxes, PARALLEL_MIN_ITEMS, &|r, boxes| {
                this.each_tight_box(kind, r, |j, tight, radius| {
                    boxes[j] = tight.grow(margin(radius));
                });
            });
            *self.boxes_and_flags(kind).0 = boxes;
        }
        self.edge_bvh.refit(&self.edge_boxes);
        self.face_bvh.refit(&self.face_boxes);
        self.vert_bvh.refit(&self.vert_boxes);
        let mut stack = std::mem::take(&mut self.stack);
        let mut pending = std::mem::take(&mut self.pending);
        pending.clear();
        let rest = &self.rest;

        // Vertex–collider.
        for c in 0..self.colliders.len() {
            let cb = self.collider_boxes[c];
            let rc = self.colliders[c].thickness;
            for i in 0..self.verts.len() {
                let vo = self.vert_obj[i];
                if inv_mass[self.verts[i] as usize] > 0.0
                    && self.vert_boxes[i].overlaps(&cb)
                    && self.collides_with_collider(vo, c as u32)
                {
                    let pair = [c as u32, i as u32];
                    let d = self.radius(vo) + rc;
                    pending.push((
                        Candidate {
                            kind: PairKind::Collider,
                            pair,
                        },
                        d,
                    ));
                }
            }
        }
        // Particle–particle, through the hash grid (its pairs come sorted).
        if self.isolated.len() > 1 {
            for (b, &k) in self.iso_boxes.iter_mut().zip(&self.isolated) {
                *b = self.vert_boxes[k as usize];
            }
            let mut iso_pairs = std::mem::take(&mut self.iso_pairs);
            self.grid.pairs(&self.iso_boxes, &mut iso_pairs);
            for &[a, b] in &iso_pairs {
                let (i, j) = (self.isolated[a as usize], self.isolated[b as usize]);
                let (p, q) = (self.verts[i as usize], self.verts[j as usize]);
                let (po, qo) = (self.vert_obj[i as usize], self.vert_obj[j as usize]);
                if !self.objects_may_collide(po, qo) || Self::all_kinematic(&[p, q], inv_mass) {
                    continue;
                }
                let mut d = self.radius(po) + self.radius(qo);
                if po == qo {
                    let d2 = rest[p as usize].distance_squared(rest[q as usize]);
                    match rest_reach(d, d2) {
                        Some(r) => d = r,
                        None => continue,
                    }
                }
                let pair = [i, j];
                pending.push((
                    Candidate {
                        kind: PairKind::VertexVertex,
                        pair,
                    },
                    d,
                ));
            }
            self.iso_pairs = iso_pairs;
        }
        // Particle–curve edge.
        for &k in &self.isolated {
            let i = k as usize;
            let p = self.verts[i];
            let po = self.vert_obj[i];
            let from = pending.len();
            let at_rest = Aabb::of_points(&[rest[p as usize]], 0.0);
            self.edge_bvh
                .query(&self.vert_boxes[i], &self.edge_boxes, &mut stack, |j| {
                    let f = self.edges[j as usize];
                    let fo = self.edge_obj[j as usize];
                    if !self.edge_curve[j as usize]
                        || f.contains(&p)
                        || !self.objects_may_collide(po, fo)
                        || Self::all_kinematic(&[p, f[0], f[1]], inv_mass)
                    {
                        return;
                    }
                    let mut d = self.radius(po) + self.radius(fo);
                    if po == fo {
                        let gap2 = at_rest.distance_squared(&self.edge_rest_boxes[j as usize]);
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
                    pending.push((
                        Candidate {
                            kind: PairKind::VertexEdge,
                            pair,
                        },
                        d,
                    ));
                });
            sort_by_second(&mut pending, from);
        }
        // Vertex–face, then edge–edge: one query per vertex or edge, split over the thread
        // team in contiguous ranges whose hits are joined in order (the same list whatever
        // the number of parts).
        if !self.faces.is_empty() {
            self.split_queries(
                self.verts.len(),
                team,
                &mut stack,
                &mut pending,
                &|this, r, stack, out| this.vertex_face_pairs(r, inv_mass, stack, out),
            );
        }
        self.split_queries(
            self.edges.len(),
            team,
            &mut stack,
            &mut pending,
            &|this, r, stack, out| this.edge_edge_pairs(r, inv_mass, stack, out),
        );
        // The colliders' feature points against faces, then against edges, and feature edges
        // against edges.
        for (kind, points, boxes, faces) in [
            (PairKind::FeatureFace, true, &self.feat_point_boxes, true),
            (
                PairKind::FeaturePointEdge,
                true,
                &self.feat_point_boxes,
                false,
            ),
            (
                PairKind::FeatureEdgeEdge,
                false,
                &self.feat_edge_boxes,
                false,
            ),
        ] {
            for (f, tight) in boxes.iter().enumerate() {
                let c = if points {
                    self.feat_points[f].0
                } else {
                    self.feat_edges[f].0
                };
                let from = pending.len();
                self.feature_candidates(
                    kind,
                    [f as u32, c],
                    *tight,
                    faces,
                    inv_mass,
                    &mut pending,
                    &mut stack,
                );
                sort_by_second(&mut pending, from);
            }
        }
        self.found_collider_boxes.clone_from(&self.collider_boxes);
        self.found_feat_boxes.clear();
        self.found_feat_boxes
            .extend_from_slice(&self.feat_point_boxes);
        self.found_feat_boxes
            .extend_from_slice(&self.feat_edge_boxes);
        self.found_inv_mass.clear();
        self.found_inv_mass
            .extend(self.verts.iter().map(|&p| inv_mass[p as usize]));
        self.adopt(pending, stack, x, team);
    }

    /// Makes `pending` (sorted) the candidates, with their particles, and restarts the passes'
    /// state; keeps both buffers for the next broad phase. Within a substep, the candidates
    /// found again keep their separations ([`Self::carry_separations`]).
    fn adopt(
        &mut self,
        mut pending: Vec<(Candidate, f64)>,
        stack: Vec<u32>,
        x: &[DVec3],
        team: TeamRef<'_>,
    ) {
        if pending.len() > self.candidate_budget {
            // The substep fails (`over_budget_error`); the list and its memory are dropped.
            self.over_budget = self.over_budget.max(pending.len());
            pending = Vec::new();
        }
        debug_assert!(
            pending.windows(2).all(|w| w[0].0 < w[1].0),
            "candidates out of order"
        );
        let carry = self.within_substep;
        if carry {
            std::mem::swap(&mut self.candidates, &mut self.old_candidates);
            std::mem::swap(&mut self.separation, &mut self.old_separation);
            std::mem::swap(&mut self.separation_moved, &mut self.old_separation_moved);
            std::mem::swap(&mut self.start, &mut self.old_start);
            std::mem::swap(&mut self.start_split, &mut self.old_start_split);
            self.carry_moved.clear();
            self.carry_moved
                .extend(self.x_ref.iter().zip(x).map(|(&r, &p)| (p - r).length()));
        }
        self.candidates.clear();
        self.candidates.extend(pending.iter().map(|&(c, _)| c));
        self.reach.clear();
        self.reach.extend(pending.iter().map(|&(_, d)| d));
        self.pending = pending;
        self.stack = stack;
        self.stats.candidates = self.stats.candidates.max(self.candidates.len());
        let mut cand_ids = std::mem::take(&mut self.cand_ids);
        cand_ids.clear();
        cand_ids.resize(self.candidates.len(), [0; 4]);
        let this = &*self;
        fill_over_team(team, &mut cand_ids, |k| {
            this.candidate_ids(this.candidates[k])
        });
        self.cand_ids = cand_ids;
        self.restart_passes(x);
        if carry {
            self.carry_separations(team);
        }
    }

    /// Gives every candidate that was a candidate before the last [`Self::adopt`] its start
    /// ([`Self::start_of`], the same substep's), and its separation from then, as a
    /// certificate only: taken when its particles had moved at
    /// most `m0` from the old `x_ref`, which they have now left by at most `m1`
    /// (`carry_moved`), so they have moved at most `m0 + m1` since, and the new `x_ref` is
    /// where they are now. A refresh after a few primitives left their boxes then costs the
    /// exact distances of the new pairs only, not those of every pair again; the skips stay
    /// the verdicts of the full tests ([`Self::skip`]), so the same contacts and bits.
    ///
    /// The new list is split over the team in contiguous ranges, each merged with the part of
    /// the old list from its first candidate on (both lists are sorted): every candidate's
    /// values come from its own old twin alone, so the same on any number of threads.
    fn carry_separations(&mut self, team: TeamRef<'_>) {
        let mut start = std::mem::take(&mut self.start);
        let mut separation = std::mem::take(&mut self.separation);
        let mut moved = std::mem::take(&mut self.separation_moved);
        let n = self.candidates.len();
        {
            let this = &*self;
            let (start_n, split) = (start.len(), self.start_split);
            let (st, sep, mov) = (
                SharedArray::new(&mut start),
                SharedArray::new(&mut separation),
                SharedArray::new(&mut moved),
            );
            team.for_ranges(n, PARALLEL_MIN_ITEMS, &|r| {
                // SAFETY: the ranges of `for_ranges` are disjoint and inside `0..n`, the length
                // of the two separation arrays; a candidate's start slot is a strictly
                // increasing function of its index within `0..start_n` ([`start_slot`]), so
                // the ranges' slots are disjoint too. The three arrays are exclusively
                // borrowed for this block.
                let (sep, mov) =
                    unsafe { (sep.slice(r.start, r.len()), mov.slice(r.start, r.len())) };
                let (old, new) = (&this.old_candidates, &this.candidates[r.clone()]);
                let Some(first) = new.first() else {
                    return;
                };
                let mut i = old.partition_point(|c| c < first);
                let mut j = 0;
                while i < old.len() && j < new.len() {
                    match old[i].cmp(&new[j]) {
                        std::cmp::Ordering::Less => i += 1,
                        std::cmp::Ordering::Greater => j += 1,
                        std::cmp::Ordering::Equal => {
                            let k = r.start + j;
                            let (from, to) =
                                (start_slot(this.old_start_split, i), start_slot(split, k));
                            if let (Some(from), Some(to)) = (from, to) {
                                debug_assert!(to < start_n);
                                // SAFETY: `to` is this candidate's own slot (above).
                                unsafe { *st.at(to) = this.old_start[from] };
                            }
                            let s = this.old_separation[i];
                            if !s.d0.is_nan() {
                                let m1 = this.cand_ids[k]
                                    .iter()
                                    .fold(0.0f64, |m, &p| m.max(this.carry_moved[p as usize]));
                                sep[j] = s;
                                mov[j] = this.old_separation_moved[i] + m1;
                            }
                            i += 1;
                            j += 1;
                        }
                    }
                }
            });
        }
        self.start = start;
        self.separation = separation;
        self.separation_moved = moved;
    }

    /// After some primitives left their boxes (during the passes, or since the last substep):
    /// gives only those new boxes and finds only their pairs, keeping every other candidate
    /// (found with the boxes the rest still lie in). The list then holds every pair whose
    /// boxes overlap, so every pair that can touch before a primitive leaves its box again. A
    /// full broad phase instead when more than an eighth of the primitives left
    /// ([`REFRESH_MAX_SHARE`]), or the group has unconnected particles (their hash grid is not
    /// updated in part).
    ///
    /// Returns whether the candidates were found again (the passes' state then restarted).
    fn refresh_escaped(
        &mut self,
        x0: &[DVec3],
        x: &[DVec3],
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) -> bool {
        let mut count = 0;
        self.fill_particle_boxes(x0, x);
        for kind in 0..3 {
            let (b, f) = self.boxes_and_flags(kind);
            let (mut boxes, mut flags) = (std::mem::take(b), std::mem::take(f));
            let n = flags.len();
            debug_assert_eq!(boxes.len(), n, "one escape mark per primitive");
            {
                let this = &*self;
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
                    this.each_tight_box(kind, r, |j, tight, radius| {
                        let out = !boxes[j].contains(&tight);
                        flags[j] = out;
                        if out {
                            boxes[j] = tight.grow(margin(radius));
                        }
                    });
                });
            }
            count += flags.iter().filter(|&&out| out).count();
            let (b, f) = self.boxes_and_flags(kind);
            (*b, *f) = (boxes, flags);
        }
        let total = self.verts.len() + self.edges.len() + self.faces.len();
        if count == 0 {
            return false;
        }
        if !self.isolated.is_empty() || REFRESH_MAX_SHARE * count > total {
            self.broad_phase_from_particle_boxes(x, inv_mass, team);
            return true;
        }
        self.stats.refreshes += 1;
        self.edge_bvh.refit(&self.edge_boxes);
        self.face_bvh.refit(&self.face_boxes);
        self.vert_bvh.refit(&self.vert_boxes);

        // The pairs of the escaped primitives, found once each: the vertices', faces' and
        // edges' queries split over the thread team as in the full broad phase (the hits
        // are sorted below, so the list is the same on any number of threads).
        let mut fresh = std::mem::take(&mut self.fresh);
        let mut stack = std::mem::take(&mut self.stack);
        fresh.clear();
        for kind in 0..3 {
            let list = match kind {
                0 => &mut self.escaped_list[0],
                1 => &mut self.escaped_list[1],
                _ => &mut self.escaped_list[2],
            };
            list.clear();
            let flags = [
                &self.escaped_verts,
                &self.escaped_faces,
                &self.escaped_edges,
            ][kind];
            list.extend((0..flags.len() as u32).filter(|&k| flags[k as usize]));
        }
        for &i in &self.escaped_list[0] {
            let i = i as usize;
            let vo = self.vert_obj[i];
            if inv_mass[self.verts[i] as usize] > 0.0 {
                for c in 0..self.colliders.len() {
                    if self.vert_boxes[i].overlaps(&self.collider_boxes[c])
                        && self.collides_with_collider(vo, c as u32)
                    {
                        let kind = PairKind::Collider;
                        let d = self.radius(vo) + self.colliders[c].thickness;
                        fresh.push((
                            Candidate {
                                kind,
                                pair: [c as u32, i as u32],
                            },
                            d,
                        ));
                    }
                }
            }
        }
        for kind in 0..3 {
            let n = self.escaped_list[kind].len();
            self.split_queries(n, team, &mut stack, &mut fresh, &|this, r, stack, out| {
                this.escaped_pairs(kind, r, inv_mass, stack, out)
            });
        }
        fresh.sort_unstable_by_key(|&(c, _)| c);

        // Merge them with the candidates that involve no escaped primitive (both sorted,
        // disjoint).
        let mut pending = std::mem::take(&mut self.pending);
        let mut part_kept = std::mem::take(&mut self.part_kept);
        merge_kept(
            team,
            (&self.candidates, &self.reach),
            &|c| !self.involves_escaped(c),
            &fresh,
            &mut part_kept,
            &mut pending,
        );
        self.part_kept = part_kept;
        self.fresh = fresh;
        self.adopt(pending, stack, x, team);
        true
    }

    /// The new pairs of the escaped vertices (`kind` 0: against the faces), faces (1: against
    /// the vertices that stayed and the colliders' feature points) or edges (2: against the
    /// edges, each pair of two escaped edges once, and the features) listed at `range` of
    /// [`Self::escaped_list`].
    fn escaped_pairs(
        &self,
        kind: usize,
        range: std::ops::Range<usize>,
        inv_mass: &[f64],
        stack: &mut Vec<u32>,
        fresh: &mut Vec<(Candidate, f64)>,
    ) {
        for &k in &self.escaped_list[kind][range] {
            match kind {
                0 => {
                    let i = k as usize;
                    let window = self.window(2, self.vert_obj[i], None);
                    self.face_bvh.query_in(
                        &self.vert_boxes[i],
                        window,
                        &self.face_boxes,
                        stack,
                        |f| {
                            if let Some(d) = self.vertex_face_reach(i, f, inv_mass) {
                                let kind = PairKind::VertexFace;
                                fresh.push((Candidate { kind, pair: [k, f] }, d));
                            }
                        },
                    );
                }
                1 => {
                    let f = k;
                    let window = self.window(0, self.face_obj[f as usize], None);
                    self.vert_bvh.query_in(
                        &self.face_boxes[f as usize],
                        window,
                        &self.vert_boxes,
                        stack,
                        |i| {
                            if self.escaped_verts[i as usize] {
                                return; // found from the vertex
                            }
                            if let Some(d) = self.vertex_face_reach(i as usize, f, inv_mass) {
                                let kind = PairKind::VertexFace;
                                fresh.push((Candidate { kind, pair: [i, f] }, d));
                            }
                        },
                    );
                    for (p, &(c, _)) in self.feat_points.iter().enumerate() {
                        let kind = PairKind::FeatureFace;
                        let tight = self.feat_point_boxes[p];
                        if let Some(d) = self.feature_reach(kind, c, tight, true, f, inv_mass) {
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
                    let window = self.window(1, self.edge_obj[i], None);
                    self.edge_bvh.query_in(
                        &self.edge_boxes[i],
                        window,
                        &self.edge_boxes,
                        stack,
                        |j| {
                            let ju = j as usize;
                            if ju == i || (self.escaped_edges[ju] && ju < i) {
                                return; // itself, or found from the other escaped edge
                            }
                            let (a, b) = (i.min(ju), i.max(ju) as u32);
                            if let Some(d) = self.edge_edge_reach(a, b, inv_mass) {
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
                    let features = (self.feat_points.iter().map(|f| f.0))
                        .zip(&self.feat_point_boxes)
                        .map(|(c, &b)| (PairKind::FeaturePointEdge, c, b))
                        .chain(
                            (self.feat_edges.iter().map(|f| f.0))
                                .zip(&self.feat_edge_boxes)
                                .map(|(c, &b)| (PairKind::FeatureEdgeEdge, c, b)),
                        );
                    let points = self.feat_points.len();
                    for (n, (kind, c, tight)) in features.enumerate() {
                        let p = if n < points { n } else { n - points };
                        if let Some(d) = self.feature_reach(kind, c, tight, false, k, inv_mass) {
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

    /// The stored boxes and escape marks of the vertices (`kind` 0), edges (1) or faces (2).
    fn boxes_and_flags(&mut self, kind: usize) -> (&mut Vec<Aabb>, &mut Vec<bool>) {
        match kind {
            0 => (&mut self.vert_boxes, &mut self.escaped_verts),
            1 => (&mut self.edge_boxes, &mut self.escaped_edges),
            _ => (&mut self.face_boxes, &mut self.escaped_faces),
        }
    }

    /// The tight swept box of every particle of a primitive over the substep so far,
    /// `[x0, x − shift]` ([`Self::tight_box_of`]).
    fn fill_particle_boxes(&mut self, x0: &[DVec3], x: &[DVec3]) {
        let s = self.shift;
        for &p in &self.box_particles {
            let p = p as usize;
            self.particle_boxes[p] = Aabb::of_points(&[x0[p], x[p] - s], 0.0);
        }
    }

    /// [`Self::tight_box_of`] for a kind chosen at run time (the tests').
    #[cfg(test)]
    fn tight_box(&self, kind: usize, i: usize) -> (Aabb, f64) {
        match kind {
            0 => self.tight_box_of::<0>(i),
            1 => self.tight_box_of::<1>(i),
            _ => self.tight_box_of::<2>(i),
        }
    }

    /// The tight swept box of vertex, edge or face `i` (`KIND` 0, 1, 2) and its radius, from
    /// the particle boxes just filled: the union of its particles' grown by its radius, which
    /// is [`Self::vert_box`], [`Self::edge_box`] or [`Self::face_box`] (the same minima and
    /// maxima of the same coordinates, then the same growth). The kind is a constant so that
    /// the loops over every primitive of a kind ([`Self::each_tight_box`]) pay no call and no
    /// branch per primitive for it (a run-time kind made those loops 1.1x dearer).
    #[inline(always)]
    fn tight_box_of<const KIND: usize>(&self, i: usize) -> (Aabb, f64) {
        let pb = |p: u32| self.particle_boxes[p as usize];
        let (b, obj) = match KIND {
            0 => (pb(self.verts[i]), self.vert_obj[i]),
            1 => {
                let [a, b] = self.edges[i];
                (pb(a).union(pb(b)), self.edge_obj[i])
            }
            _ => {
                let [a, b, c] = self.faces[i];
                (pb(a).union(pb(b)).union(pb(c)), self.face_obj[i])
            }
        };
        let radius = self.radius(obj);
        (b.grow(radius), radius)
    }

    /// `f(j, tight box, radius)` for every primitive `i = range.start + j` of `kind` in `range`
    /// ([`Self::tight_box_of`]), the kind chosen once for the whole range.
    #[inline]
    fn each_tight_box(
        &self,
        kind: usize,
        range: std::ops::Range<usize>,
        mut f: impl FnMut(usize, Aabb, f64),
    ) {
        let start = range.start;
        match kind {
            0 => range.for_each(|i| {
                let (b, r) = self.tight_box_of::<0>(i);
                f(i - start, b, r)
            }),
            1 => range.for_each(|i| {
                let (b, r) = self.tight_box_of::<1>(i);
                f(i - start, b, r)
            }),
            _ => range.for_each(|i| {
                let (b, r) = self.tight_box_of::<2>(i);
                f(i - start, b, r)
            }),
        }
    }

    /// Whether candidate `c` has a primitive marked escaped by [`Self::refresh_escaped`].
    fn involves_escaped(&self, c: Candidate) -> bool {
        let [a, b] = c.pair.map(|k| k as usize);
        match c.kind {
            PairKind::Collider => self.escaped_verts[b],
            PairKind::VertexFace => self.escaped_verts[a] || self.escaped_faces[b],
            PairKind::EdgeEdge => self.escaped_edges[a] || self.escaped_edges[b],
            PairKind::FeatureFace => self.escaped_faces[b],
            PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => self.escaped_edges[b],
            // Only with unconnected particles, which take a full broad phase.
            PairKind::VertexVertex | PairKind::VertexEdge => true,
        }
    }

    /// Whether the candidates last found still hold every pair that can touch in the substep
    /// as far as the colliders and masses go: every collider box and feature box lies within
    /// the box it was found with, and no vertex changed its inverse mass (a pinned pair may
    /// have been left out). Then only the primitives that left their own boxes need new pairs
    /// ([`Self::refresh_escaped`]): a fresh broad phase would find a subset of the list, and
    /// the passes, which test every candidate exactly and keep their order, reach the same
    /// contacts in the same order.
    fn colliders_and_masses_hold(&self, inv_mass: &[f64]) -> bool {
        let feat_boxes = self.feat_point_boxes.iter().chain(&self.feat_edge_boxes);
        self.found_inv_mass.len() == self.verts.len()
            && self.found_feat_boxes.len()
                == self.feat_point_boxes.len() + self.feat_edge_boxes.len()
            && (self.verts.iter().zip(&self.found_inv_mass))
                .all(|(&p, &w)| inv_mass[p as usize].to_bits() == w.to_bits())
            && (self.found_collider_boxes.iter().zip(&self.collider_boxes))
                .all(|(found, now)| found.contains(now))
            && (self.found_feat_boxes.iter().zip(feat_boxes))
                .all(|(found, now)| found.contains(now))
    }

    /// Sets the passes' state up for the current candidates: no separation known yet, no
    /// start taken ([`Self::start_of`]), no contact.
    fn restart_passes(&mut self, x: &[DVec3]) {
        let n = self.x_ref.len();
        self.x_ref.copy_from_slice(&x[..n]);
        self.moved.fill(0.0);
        self.separation.clear();
        self.separation
            .resize(self.candidates.len(), Separation::UNKNOWN);
        self.separation_moved.clear();
        self.separation_moved.resize(self.candidates.len(), 0.0);
        let colliders = (self.candidates).partition_point(|c| c.kind == PairKind::Collider);
        let features = (self.candidates).partition_point(|c| !c.kind.is_feature());
        self.start_split = [colliders, features];
        self.start.clear();
        self.start.resize(
            colliders + (self.candidates.len() - features),
            StartOf::UNKNOWN,
        );
        self.taken_ahead.clear();
        self.taken_ahead.resize(self.candidates.len(), false);
        self.separations_unknown = true;

        // Existing contacts keep their slot.
        self.contact_of.clear();
        self.contact_of.resize(self.candidates.len(), NONE);
        for (k, c) in self.contacts.iter().enumerate() {
            let key = Candidate {
                kind: c.kind,
                pair: c.pair,
            };
            if let Ok(at) = self.candidates.binary_search(&key) {
                self.contact_of[at] = k as u32;
            }
        }
    }

    /// Runs `query` over `0..n` (vertices or edges), appending its hits to `pending`. Below
    /// [`PARALLEL_MIN_QUERIES`] queries, or on one thread, the whole range runs here, straight
    /// into `pending` with `stack`; else the range is cut into contiguous chunks, eight per
    /// part, which the parts claim as they come free ([`claim_chunks`]; the queries of some
    /// chunks find many more pairs than others'), each with its own hit list and its part's
    /// stack, and the chunks' hits are appended in chunk order: the same list whoever ran
    /// them. The buffers keep their capacity from step to step.
    fn split_queries(
        &mut self,
        n: usize,
        team: TeamRef<'_>,
        stack: &mut Vec<u32>,
        pending: &mut Vec<(Candidate, f64)>,
        query: &QueryFn<'_>,
    ) {
        let parts = team.parts();
        if n < PARALLEL_MIN_QUERIES || parts < 2 {
            query(self, 0..n, stack, pending);
            return;
        }
        let chunks = (parts * CHUNKS_PER_PART).min(n);
        let mut outs = std::mem::take(&mut self.part_pending);
        let mut stacks = std::mem::take(&mut self.part_stacks);
        if outs.len() < chunks {
            outs.resize_with(chunks, Vec::new);
        }
        if stacks.len() < parts {
            stacks.resize_with(parts, || Vec::with_capacity(128));
        }
        {
            let this = &*self;
            let (o, st) = (SharedArray::new(&mut outs), SharedArray::new(&mut stacks));
            claim_chunks(team, chunks, &|part, c| {
                // SAFETY: a chunk takes only its own hit list, and a part only its own stack
                // (a part runs its chunks one after another); the arrays are exclusively
                // borrowed for this block and hold at least `chunks` and `parts` elements.
                let (out, stack) = unsafe { (&mut *o.at(c), &mut *st.at(part)) };
                // Worked on as locals: the vector headers share cache lines, and a push writes
                // its length (sharing them made two threads 1.2x slower than one).
                let (mut hits, mut local) = (std::mem::take(out), std::mem::take(stack));
                hits.clear();
                query(this, span(c, chunks, n), &mut local, &mut hits);
                (*out, *stack) = (hits, local);
            });
        }
        for out in &outs[..chunks] {
            pending.extend_from_slice(out);
        }
        self.part_pending = outs;
        self.part_stacks = stacks;
    }

    /// The contact distance of vertex `i` against face `f` if they form a candidate (their
    /// boxes are assumed to overlap): not a vertex of the face, objects that collide, not all
    /// kinematic, and for one object, the rest shape's verdict ([`Self::near_vertex_face`]).
    #[inline]
    fn vertex_face_reach(&self, i: usize, f: u32, inv_mass: &[f64]) -> Option<f64> {
        let (p, po) = (self.verts[i], self.vert_obj[i]);
        let tri = self.faces[f as usize];
        let fo = self.face_obj[f as usize];
        if tri.contains(&p) || !self.objects_may_collide(po, fo) {
            return None;
        }
        if Self::all_kinematic(&[p, tri[0], tri[1], tri[2]], inv_mass) {
            return None;
        }
        let d = self.radius(po) + self.radius(fo);
        if po == fo {
            if let Some(reach) = self.near_vertex_face.reach(i, f) {
                return reach;
            }
        }
        Some(d)
    }

    /// The contact distance of edges `i < j` if they form a candidate (their boxes are
    /// assumed to overlap), as [`Self::vertex_face_reach`].
    #[inline]
    fn edge_edge_reach(&self, i: usize, j: u32, inv_mass: &[f64]) -> Option<f64> {
        let (e, eo) = (self.edges[i], self.edge_obj[i]);
        let f = self.edges[j as usize];
        let fo = self.edge_obj[j as usize];
        if f.contains(&e[0]) || f.contains(&e[1]) || !self.objects_may_collide(eo, fo) {
            return None;
        }
        if Self::all_kinematic(&[e[0], e[1], f[0], f[1]], inv_mass) {
            return None;
        }
        let d = self.radius(eo) + self.radius(fo);
        if eo == fo {
            if let Some(reach) = self.near_edge_edge.reach(i, j) {
                return reach;
            }
        }
        Some(d)
    }

    /// The vertex–face candidates of the vertices `verts`, in order, each query's hits sorted
    /// by face.
    fn vertex_face_pairs(
        &self,
        verts: std::ops::Range<usize>,
        inv_mass: &[f64],
        stack: &mut Vec<u32>,
        out: &mut Vec<(Candidate, f64)>,
    ) {
        for i in verts {
            let window = self.window(2, self.vert_obj[i], None);
            let from = out.len();
            self.face_bvh
                .query_in(&self.vert_boxes[i], window, &self.face_boxes, stack, |f| {
                    if let Some(d) = self.vertex_face_reach(i, f, inv_mass) {
                        let pair = [i as u32, f];
                        out.push((
                            Candidate {
                                kind: PairKind::VertexFace,
                                pair,
                            },
                            d,
                        ));
                    }
                });
            sort_by_second(out, from);
        }
    }

    /// The edge–edge candidates `(i, j)`, `j > i`, of the edges `i` in `edges`, in order, each
    /// query's hits sorted by `j`.
    fn edge_edge_pairs(
        &self,
        edges: std::ops::Range<usize>,
        inv_mass: &[f64],
        stack: &mut Vec<u32>,
        out: &mut Vec<(Candidate, f64)>,
    ) {
        for i in edges {
            let window = self.window(1, self.edge_obj[i], Some(i as u32));
            let from = out.len();
            self.edge_bvh
                .query_in(&self.edge_boxes[i], window, &self.edge_boxes, stack, |j| {
                    if let Some(d) = self.edge_edge_reach(i, j, inv_mass) {
                        let pair = [i as u32, j];
                        out.push((
                            Candidate {
                                kind: PairKind::EdgeEdge,
                                pair,
                            },
                            d,
                        ));
                    }
                });
            sort_by_second(out, from);
        }
    }

    /// Poses the colliders at both ends of the substep `[time, time + h]`: their poses, the
    /// features' tracks and swept boxes, and the colliders' boxes (all with the substep's
    /// [`Self::shift`]).
    fn pose_colliders(&mut self, time: f64, h: f64) {
        for (c, col) in self.colliders.iter().enumerate() {
            self.pose0[c] = col.motion.pose(time);
            self.pose1[c] = col.motion.pose(time + h);
        }
        for (f, &(c, q)) in self.feat_points.iter().enumerate() {
            let ends = [
                self.pose0[c as usize].apply(q),
                self.pose1[c as usize].apply(q),
            ];
            self.feat_point_tracks[f] = ends;
            self.feat_point_boxes[f] = Aabb::of_points(&[ends[0], ends[1] - self.shift], 0.0);
        }
        for (f, &(c, [a, b])) in self.feat_edges.iter().enumerate() {
            let (p0, p1) = (self.pose0[c as usize], self.pose1[c as usize]);
            let ends = [p0.apply(a), p0.apply(b), p1.apply(a), p1.apply(b)];
            self.feat_edge_tracks[f] = ends;
            let s = self.shift;
            self.feat_edge_boxes[f] =
                Aabb::of_points(&[ends[0], ends[1], ends[2] - s, ends[3] - s], 0.0);
        }
        self.collider_bounds();
    }

    /// World boxes of the colliders over the substep (their rest-frame bounds, grown by
    /// every thickness in play, at both poses; a rotating shape is bounded by its bounding
    /// sphere about its pivot-independent centre).
    fn collider_bounds(&mut self) {
        for (c, col) in self.colliders.iter().enumerate() {
            let (lo, hi) = col.shape.bounds(col.thickness + self.max_thickness);
            if !lo.is_finite() || !hi.is_finite() {
                self.collider_boxes[c] = Aabb {
                    min: DVec3::splat(f64::NEG_INFINITY),
                    max: DVec3::splat(f64::INFINITY),
                };
                continue;
            }
            let center = 0.5 * (lo + hi);
            let r = 0.5 * (hi - lo).length();
            let ends = [
                self.pose0[c].apply(center),
                self.pose1[c].apply(center) - self.shift,
            ];
            self.collider_boxes[c] = Aabb::of_points(&ends, r);
        }
    }

    // ------------------------------------------------------------------------------------
    // Narrow phase
    // ------------------------------------------------------------------------------------

    /// The particles of a candidate of a kind with a prefilter (vertex–face, edge–edge,
    /// vertex–edge), in the slots its test uses; zeros for the other kinds.
    fn candidate_ids(&self, cand: Candidate) -> [u32; 4] {
        let [a, b] = cand.pair;
        let (a, b) = (a as usize, b as usize);
        match cand.kind {
            PairKind::VertexFace => {
                let (p, t) = (self.verts[a], self.faces[b]);
                [p, t[0], t[1], t[2]]
            }
            PairKind::EdgeEdge => {
                let (e, f) = (self.edges[a], self.edges[b]);
                [e[0], e[1], f[0], f[1]]
            }
            PairKind::VertexEdge => {
                let (p, f) = (self.verts[a], self.edges[b]);
                [p, p, f[0], f[1]]
            }
            PairKind::VertexVertex => [0; 4],
            PairKind::Collider => [self.verts[b]; 4],
            // The feature's slots hold no particle: the primitive's first stands in.
            PairKind::FeatureFace => {
                let t = self.faces[b];
                [t[0], t[0], t[1], t[2]]
            }
            PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
                let e = self.edges[b];
                [e[0], e[0], e[0], e[1]]
            }
        }
    }

    /// The most any particle of candidate `k` has moved from `x_ref`.
    #[inline]
    fn candidate_moved(&self, k: usize) -> f64 {
        self.cand_ids[k]
            .iter()
            .fold(0.0f64, |m, &i| m.max(self.moved[i as usize]))
    }

    /// Whether candidate `k` is certainly apart at contact distance `d` now. Its separation
    /// was taken when its particles had moved at most `m0` from `x_ref`, and they have moved
    /// at most `m1` from it now, so at most `m0 + m1` since.
    #[inline]
    fn skip(&self, k: usize, d: f64) -> bool {
        let s = &self.separation[k];
        !s.d0.is_nan() && s.certainly_apart(self.separation_moved[k] + self.candidate_moved(k), d)
    }

    /// Whether vertex–collider or feature candidate `k` is certainly farther than its reach
    /// from the collider at the substep's end pose, now: its certificate ([`Self::skip`], with
    /// `moved` current), which bounds the signed distance for any collider but a box's
    /// features — a primitive inside a box is far from its corners and edges, so those are
    /// never skipped. What the final projections and the penetration statistic would find
    /// nothing to do for.
    #[inline]
    fn certainly_beyond_reach(&self, k: usize) -> bool {
        let cand = self.candidates[k];
        let boxed = cand.kind.is_feature()
            && matches!(
                self.colliders[self.feature_collider(cand) as usize].shape,
                Shape::Box { .. }
            );
        !boxed && self.skip(k, self.reach[k])
    }

    /// The tracks of candidate `k`'s particles over `[x0, x]`, written out (an array `map`
    /// stayed an out-of-line call).
    #[inline(always)]
    fn candidate_tracks(&self, k: usize, x0: &[DVec3], x: &[DVec3]) -> [Track; 4] {
        let [a, b, c, d] = self.cand_ids[k];
        [
            track(x0, x, a),
            track(x0, x, b),
            track(x0, x, c),
            track(x0, x, d),
        ]
    }

    /// Candidate `k`'s separation over `[x0, x]`, for the kinds whose test it decides
    /// exactly: the mesh pairs with a prefilter ([`pairs::separation`]), a collider's feature
    /// against a face or an edge (the same tests on the feature's track over the substep), and
    /// a vertex against a plane or a sphere ([`pairs::collider_separation`]). `None` for the
    /// kinds without one.
    fn separation_at(&self, k: usize, x0: &[DVec3], x: &[DVec3]) -> Option<Separation> {
        let cand = self.candidates[k];
        let a = cand.pair[0] as usize;
        match cand.kind {
            PairKind::VertexFace | PairKind::EdgeEdge | PairKind::VertexEdge => {
                pairs::separation(cand.kind, &self.candidate_tracks(k, x0, x))
            }
            PairKind::VertexVertex => None,
            PairKind::Collider => {
                let p = self.cand_ids[k][0] as usize;
                let q0 = self.pose0[a].inverse_apply(x0[p]);
                let q1 = self.pose1[a].inverse_apply(x[p]);
                pairs::collider_separation(&self.colliders[a].shape, q0, q1)
            }
            PairKind::FeatureFace | PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
                let (kind, tr) = self.feature_tracks(cand, &self.cand_ids[k], x0, x);
                pairs::separation(kind, &tr)
            }
        }
    }

    /// A feature candidate's tracks over `[x0, x]` with the feature's in its slots (`ids` its
    /// [`Self::candidate_ids`]), and the mesh kind whose test it takes.
    #[inline]
    fn feature_tracks(
        &self,
        cand: Candidate,
        ids: &[u32; 4],
        x0: &[DVec3],
        x: &[DVec3],
    ) -> (PairKind, [Track; 4]) {
        let a = cand.pair[0] as usize;
        let [p, q, r, t] = *ids;
        let mut tr = [
            track(x0, x, p),
            track(x0, x, q),
            track(x0, x, r),
            track(x0, x, t),
        ];
        let kind = match cand.kind {
            PairKind::FeatureFace => {
                let [p0, p1] = self.feat_point_tracks[a];
                tr[0] = Track { x0: p0, x1: p1 };
                PairKind::VertexFace
            }
            PairKind::FeaturePointEdge => {
                let [p0, p1] = self.feat_point_tracks[a];
                tr[0] = Track { x0: p0, x1: p1 };
                tr[1] = tr[0];
                PairKind::VertexEdge
            }
            _ => {
                let [a0, b0, a1, b1] = self.feat_edge_tracks[a];
                tr[0] = Track { x0: a0, x1: a1 };
                tr[1] = Track { x0: b0, x1: b1 };
                PairKind::EdgeEdge
            }
        };
        (kind, tr)
    }

    /// Takes and keeps candidate `k`'s separation over `[x0, x]` ([`Self::separation_at`];
    /// `None` for the kinds without one), the first time a pass tests it.
    fn take_separation(&mut self, k: usize, x0: &[DVec3], x: &[DVec3]) -> Option<Separation> {
        let s = self.separation_at(k, x0, x)?;
        self.separation[k] = s;
        self.separation_moved[k] = self.candidate_moved(k);
        Some(s)
    }

    /// `moved` for every particle, from the current positions.
    fn update_moved(&mut self, x: &[DVec3]) {
        for ((m, &r), &p) in self.moved.iter_mut().zip(&self.x_ref).zip(x) {
            *m = (p - r).length();
        }
    }

    /// `moved` for the particles of one contact just projected.
    fn update_moved_of(&mut self, ids: &[u32; 4], x: &[DVec3]) {
        for &i in ids {
            let i = i as usize;
            self.note_moved(i, x);
            if self.ahead_exact {
                self.touched[i] = true;
            }
        }
    }

    /// `moved` for particle `i`, just moved outside a pass (the final projections).
    #[inline]
    fn note_moved(&mut self, i: usize, x: &[DVec3]) {
        self.moved[i] = (x[i] - self.x_ref[i]).length();
    }

    /// The contact of candidate `k` if the pair comes within `thickness_scale × reach` (its
    /// contact distance) over `[x0, x]` (`thickness_scale = 0`: the pair crosses; for a
    /// collider's feature, it crosses the collider's core). `known`: the pair's separation over
    /// these very positions, if just taken ([`Self::take_separation`]), so it is not taken
    /// twice.
    fn detect(
        &mut self,
        k: usize,
        x0: &[DVec3],
        x: &[DVec3],
        thickness_scale: f64,
        known: Option<Separation>,
    ) -> Option<Contact> {
        let (cand, reach) = (self.candidates[k], self.reach[k]);
        let track = |i: u32| track(x0, x, i);
        let mut d = thickness_scale * reach;
        let start = self.start_of(k, x0);
        if start.leaves != Leaves::Normally {
            // The final projections take it out across the feature or along the axis.
            return None;
        }
        if cand.kind.is_feature() && thickness_scale > 0.0 {
            d = push_out_reach(d, start.distance, self.push_out());
        }
        let [a, b] = cand.pair;
        match cand.kind {
            PairKind::VertexFace | PairKind::EdgeEdge | PairKind::VertexEdge => {
                let ids = self.cand_ids[k];
                let tr = self.candidate_tracks(k, x0, x);
                let s = known.or_else(|| pairs::separation(cand.kind, &tr))?;
                pairs::separated_contact(cand.kind, s, cand.pair, ids, &tr, d)
            }
            PairKind::VertexVertex => {
                let (p, q) = (self.verts[a as usize], self.verts[b as usize]);
                let ids = [p, q, p, p];
                pairs::vertex_vertex(cand.pair, ids, &ids.map(track), d)
            }
            PairKind::Collider => {
                let (c, v) = (a as usize, b as usize);
                let p = self.verts[v] as usize;
                let col = &self.colliders[c];
                let (pose0, pose1) = (self.pose0[c], self.pose1[c]);
                let q0 = pose0.inverse_apply(x0[p]);
                let q1 = pose1.inverse_apply(x[p]);
                let d = if thickness_scale > 0.0 {
                    push_out_reach(d, start.distance, self.push_out())
                } else {
                    d
                };
                let t = first_contact(&col.shape, q0, q1, d)?;
                let qt = q0.lerp(q1, t);
                let (phi, n_local) = col.shape.signed_distance(qt);
                let surface = qt - phi * n_local;
                let n = pose1.rotate(n_local);
                let s1 = pose1.apply(surface);
                Some(Contact {
                    kind: PairKind::Collider,
                    pair: cand.pair,
                    ids: [p as u32; 4],
                    w: [1.0, 0.0, 0.0, 0.0],
                    n,
                    offset: n.dot(s1) + d,
                    collider_disp: s1 - pose0.apply(surface),
                    dn: 0.0,
                })
            }
            // A collider's feature is a kinematic point or segment that is no particle: the
            // query runs on its world track over the substep like a mesh collider's vertex,
            // then its slots are folded into the contact's offset.
            PairKind::FeatureFace | PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
                let ids = self.cand_ids[k];
                let (kind, tr) = self.feature_tracks(cand, &ids, x0, x);
                let s = known.or_else(|| pairs::separation(kind, &tr))?;
                let mut c = pairs::separated_contact(kind, s, cand.pair, ids, &tr, d)?;
                let kinematic: &[usize] = if cand.kind == PairKind::FeatureFace {
                    &[0]
                } else {
                    &[0, 1]
                };
                c.kind = cand.kind;
                pairs::fold_kinematic(&mut c, kinematic, &tr);
                Some(c)
            }
        }
    }

    /// The collider of a feature candidate.
    #[inline]
    fn feature_collider(&self, cand: Candidate) -> u32 {
        match cand.kind {
            PairKind::FeatureEdgeEdge => self.feat_edges[cand.pair[0] as usize].0,
            _ => self.feat_points[cand.pair[0] as usize].0,
        }
    }

    /// Whether the tight swept boxes of a candidate's primitives overlap.
    fn boxes_overlap(&self, cand: Candidate, x0: &[DVec3], x: &[DVec3]) -> bool {
        let [a, b] = cand.pair;
        let (a, b) = (a as usize, b as usize);
        match cand.kind {
            PairKind::VertexFace => self.vert_box(a, x0, x).overlaps(&self.face_box(b, x0, x)),
            PairKind::EdgeEdge => self.edge_box(a, x0, x).overlaps(&self.edge_box(b, x0, x)),
            PairKind::VertexEdge => self.vert_box(a, x0, x).overlaps(&self.edge_box(b, x0, x)),
            PairKind::VertexVertex => self.vert_box(a, x0, x).overlaps(&self.vert_box(b, x0, x)),
            PairKind::Collider => true,
            PairKind::FeatureFace | PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
                let r = self.collider_radius[self.feature_collider(cand) as usize];
                let (feature, other) = match cand.kind {
                    PairKind::FeatureFace => (self.feat_point_boxes[a], self.face_box(b, x0, x)),
                    PairKind::FeaturePointEdge => {
                        (self.feat_point_boxes[a], self.edge_box(b, x0, x))
                    }
                    _ => (self.feat_edge_boxes[a], self.edge_box(b, x0, x)),
                };
                feature.distance_squared(&other) <= r * r
            }
        }
    }

    /// Takes, split over the team, the separation of every candidate with a prefilter that has
    /// none (what the pass would take at the candidate's first visit; a refresh within the
    /// substep carries the others over), with how far its particles have moved from `x_ref`.
    /// The pass's contacts move particles before it reaches a candidate, so a separation taken
    /// ahead proves the pair apart only with that motion added ([`Self::skip`], the
    /// certificate every later pass uses too); where it proves nothing, the pass takes it
    /// again over the positions of the visit. The verdicts, hence the contacts and positions,
    /// are those of a pass that takes each separation at its visit: the same bits on any
    /// number of threads.
    fn take_separations_ahead(&mut self, x0: &[DVec3], x: &[DVec3], team: TeamRef<'_>) {
        let n = self.candidates.len();
        let parts = team.parts();
        let mut separation = std::mem::take(&mut self.separation);
        let mut moved = std::mem::take(&mut self.separation_moved);
        let mut ahead = std::mem::take(&mut self.taken_ahead);
        {
            let this = &*self;
            let (sep, mov, ahd) = (
                SharedArray::new(&mut separation),
                SharedArray::new(&mut moved),
                SharedArray::new(&mut ahead),
            );
            let chunks = (parts * CHUNKS_PER_PART).min(n);
            claim_chunks(team, chunks, &|_, c| {
                let r = span(c, chunks, n);
                // SAFETY: each chunk writes only its own range `r` of the three arrays, which
                // are exclusively borrowed for this block and hold `n` elements each.
                let (sep, mov, ahd) = unsafe {
                    (
                        sep.slice(r.start, r.len()),
                        mov.slice(r.start, r.len()),
                        ahd.slice(r.start, r.len()),
                    )
                };
                for (i, k) in r.enumerate() {
                    if !sep[i].d0.is_nan() {
                        continue;
                    }
                    if let Some(s) = this.separation_at(k, x0, x) {
                        sep[i] = s;
                        mov[i] = this.candidate_moved(k);
                        ahd[i] = true;
                    }
                }
            });
        }
        self.separation = separation;
        self.separation_moved = moved;
        self.taken_ahead = ahead;
    }

    /// One Gauss-Seidel pass: re-project the contacts found so far, then run the continuous
    /// test on every candidate and project each new contact at once. The pass after the
    /// candidates were found takes their separations ahead over the team, where it has more
    /// than one thread and enough candidates ([`Self::take_separations_ahead`]).
    fn resolve_pass(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
        team: TeamRef<'_>,
    ) {
        for c in &mut self.contacts {
            recorded(c, x, inv_mass, pushes, |c, x| {
                c.project(x, inv_mass);
            });
        }
        self.update_moved(x);
        if std::mem::take(&mut self.separations_unknown)
            && team.parts() > 1
            && self.candidates.len() >= PARALLEL_MIN_QUERIES
        {
            self.take_separations_ahead(x0, x, team);
            self.touched.clear();
            self.touched.resize(self.x_ref.len(), false);
            self.ahead_exact = true;
        }
        for k in 0..self.candidates.len() {
            let cand = self.candidates[k];
            let d = self.reach[k];
            if self.skip(k, d) || !self.boxes_overlap(cand, x0, x) {
                continue;
            }
            // A pair tested for the first time since the broad phase: its separation, kept for
            // the next passes, may settle it here (the verdict its test's prefilter would give)
            // and otherwise serves the test. One taken ahead that proves nothing is taken
            // again: the positions may have moved since.
            let mut known = None;
            let exact = self.ahead_exact
                && self.taken_ahead[k]
                && !self.cand_ids[k].iter().any(|&i| self.touched[i as usize]);
            if exact || self.separation[k].d0.is_nan() || self.taken_ahead[k] {
                self.taken_ahead[k] = false;
                known = if exact {
                    Some(self.separation[k])
                } else {
                    self.take_separation(k, x0, x)
                };
                if known.is_some_and(|s| s.certainly_apart(0.0, d)) {
                    continue;
                }
            }
            let Some(mut contact) = self.detect(k, x0, x, 1.0, known) else {
                continue;
            };
            let ids = contact.ids;
            let slot = self.contact_of[k];
            if slot != NONE {
                contact.dn = self.contacts[slot as usize].dn;
            }
            recorded(&mut contact, x, inv_mass, pushes, |c, x| {
                c.project(x, inv_mass);
            });
            if slot == NONE {
                self.contact_of[k] = self.contacts.len() as u32;
                self.contacts.push(contact);
            } else {
                self.contacts[slot as usize] = contact;
            }
            self.update_moved_of(&ids, x);
        }
        self.ahead_exact = false;
    }

    /// A vertex–collider candidate's collider, particle and contact distance (m), if it is one
    /// and its particle is dynamic.
    fn dynamic_collider_pair(
        &self,
        cand: Candidate,
        inv_mass: &[f64],
    ) -> Option<(usize, usize, f64)> {
        if cand.kind != PairKind::Collider {
            return None;
        }
        let (c, v) = (cand.pair[0] as usize, cand.pair[1] as usize);
        let p = self.verts[v] as usize;
        (inv_mass[p] != 0.0).then(|| {
            (
                c,
                p,
                self.radius(self.vert_obj[v]) + self.colliders[c].thickness,
            )
        })
    }

    /// Pushes every vertex out of the analytic colliders (exact signed-distance projection at
    /// the end of the substep).
    fn project_out_of_colliders(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) {
        self.update_moved(x);
        for k in 0..self.candidates.len() {
            let Some((c, p, r)) = self.dynamic_collider_pair(self.candidates[k], inv_mass) else {
                continue;
            };
            let start = self.start_of(k, x0);
            if start.leaves == Leaves::OffAxis {
                if let Some(exit) = self.axis_exit(c, self.axis_parameter(c, x0[p])) {
                    self.slide_off_axis(exit, p, r, x0, x, pushes);
                    self.note_moved(p, x);
                }
                continue;
            }
            if self.certainly_beyond_reach(k) {
                continue;
            }
            let col = &self.colliders[c];
            let pose = self.pose1[c];
            let q = pose.inverse_apply(x[p]);
            let (phi, n) = col.shape.signed_distance(q);
            if phi >= r {
                continue;
            }
            let r = push_out_reach(r, start.distance, self.push_out());
            if phi < r {
                let to = pose.apply(q + (r - phi) * n);
                if !pushes.is_empty() {
                    pushes[p] += to - x[p];
                }
                x[p] = to;
                self.note_moved(p, x);
            }
        }
    }

    /// Pushes the faces and edges out of the analytic colliders to their contact distance at
    /// the end of the substep — the counterpart, for the colliders' features, of
    /// [`Self::project_out_of_colliders`]: a primitive closer than its reach to a feature
    /// (at the collider's end pose) moves along the *current* separating direction (through
    /// the feature, for a primitive on the wrong side of a box's corner or edge:
    /// [`Self::feature_side`]), each
    /// particle by its weight in the closest point and its inverse mass, so that the closest
    /// point moves out by exactly the deficit. A contact keeps the plane of its time of
    /// impact, which drifts when the cloth slides around a curved core; this does not. A pair
    /// whose closest points coincide (no direction) is left to the fail-safe. Pushes that
    /// share particles undo each other a little, so the sweep is repeated (Gauss-Seidel, at
    /// most [`FEATURE_SWEEPS`] times) until no primitive is deeper than 1e-9 of its reach.
    fn project_features_out(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) {
        for _ in 0..FEATURE_SWEEPS {
            if self.project_features_out_once(x0, x, inv_mass, pushes) <= 1e-9 {
                return;
            }
        }
    }

    /// One sweep of [`Self::project_features_out`]; returns the largest deficit it found,
    /// relative to the pair's reach.
    fn project_features_out_once(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) -> f64 {
        let mut worst: f64 = 0.0;
        self.update_moved(x);
        for k in 0..self.candidates.len() {
            let cand = self.candidates[k];
            if !cand.kind.is_feature() {
                continue;
            }
            let c = self.feature_collider(cand) as usize;
            let start = self.start_of(k, x0);
            if start.leaves == Leaves::OffAxis {
                let left = self.push_off_axis(cand, self.reach[k], x0, x, inv_mass, pushes);
                worst = worst.max(left);
                let ids = self.cand_ids[k];
                self.update_moved_of(&ids, x);
                continue;
            }
            if self.certainly_beyond_reach(k) {
                continue;
            }
            let side = self.feature_side(cand, x, self.pose1[c]);
            let (ids, w, out) = (side.ids, side.w, side.out());
            let dist = out.length();
            let signed = if side.inside { -dist } else { dist };
            if signed >= self.reach[k] || dist < 1e-12 || !dist.is_finite() {
                continue;
            }
            let target = push_out_reach(self.reach[k], start.distance, self.push_out());
            let deficit = target - signed;
            if deficit <= 0.0 {
                continue;
            }
            // Relative to the distance it is pushed to (its reach, unless a push-out limits it).
            worst = worst.max(deficit / target.abs().max(f64::MIN_POSITIVE));
            let w_total: f64 = (0..3)
                .map(|j| inv_mass[ids[j] as usize] * w[j] * w[j])
                .sum();
            if w_total <= 0.0 || !w_total.is_finite() {
                continue;
            }
            let step = out * (deficit / (dist * w_total));
            for j in 0..3 {
                let i = ids[j] as usize;
                if w[j] != 0.0 && inv_mass[i] > 0.0 {
                    x[i] += inv_mass[i] * w[j] * step;
                    if !pushes.is_empty() {
                        pushes[i] += inv_mass[i] * w[j] * step;
                    }
                    self.note_moved(i, x);
                }
            }
        }
        worst
    }

    /// A feature candidate's closest points, with the collider at `pose` and the particles at
    /// `x`: the primitive's particles, their weights in its closest point, the feature's
    /// closest point, and the squared distance between the two (as the distance query gives
    /// it).
    fn feature_closest(
        &self,
        cand: Candidate,
        x: &[DVec3],
        pose: Pose,
    ) -> ([u32; 3], [f64; 3], DVec3, f64) {
        let (a, b) = (cand.pair[0] as usize, cand.pair[1] as usize);
        match cand.kind {
            PairKind::FeatureFace => {
                let t = self.faces[b];
                let p = pose.apply(self.feat_points[a].1);
                let at = |i: u32| x[i as usize];
                let (bary, d2) = distance::point_triangle_closest(p, at(t[0]), at(t[1]), at(t[2]));
                (t, bary, p, d2)
            }
            PairKind::FeaturePointEdge => {
                let e = self.edges[b];
                let p = pose.apply(self.feat_points[a].1);
                let (u, d2) =
                    distance::point_segment_closest(p, x[e[0] as usize], x[e[1] as usize]);
                ([e[0], e[1], e[1]], [1.0 - u, u, 0.0], p, d2)
            }
            _ => {
                let e = self.edges[b];
                let [f0, f1] = self.feat_edges[a].1.map(|v| pose.apply(v));
                let (s, u, d2) =
                    distance::segment_segment_closest(f0, f1, x[e[0] as usize], x[e[1] as usize]);
                ([e[0], e[1], e[1]], [1.0 - u, u, 0.0], f0.lerp(f1, s), d2)
            }
        }
    }

    /// The distance (m) between a feature candidate's feature, with the collider at `pose`,
    /// and its primitive at `x`.
    fn feature_distance(&self, cand: Candidate, x: &[DVec3], pose: Pose) -> f64 {
        self.feature_side(cand, x, pose).distance()
    }

    /// Whether a feature candidate's primitive (its edge or face) starts the substep in the
    /// interior of its collider, a box (at `x0` and the collider's start pose): a cloth
    /// started through a box, whose way out crosses the box's edges and corners.
    fn starts_in_box(&self, cand: Candidate, x0: &[DVec3]) -> bool {
        let c = self.feature_collider(cand) as usize;
        let Shape::Box {
            center,
            half_extents,
            rotation,
        } = self.colliders[c].shape
        else {
            return false;
        };
        let pose0 = self.pose0[c];
        let local = |i: u32| rotation.inverse() * (pose0.inverse_apply(x0[i as usize]) - center);
        let b = cand.pair[1] as usize;
        match cand.kind {
            PairKind::FeatureFace => triangle_enters_box(self.faces[b].map(local), half_extents),
            _ => {
                let [p, q] = self.edges[b].map(local);
                segment_enters_box(p, q, half_extents)
            }
        }
    }

    /// Whether a feature candidate of a capsule starts the substep *impaled*: for its axis
    /// and an edge, the axis through a face on the edge; for an end and a face, the axis
    /// through the face (at `x0` and the collider's start pose). The way off is along the axis
    /// ([`Self::push_off_axis`]), across the axis and over the end, which a contact or the
    /// fail-safe would forbid.
    fn starts_impaled(&self, cand: Candidate, x0: &[DVec3]) -> bool {
        let c = self.feature_collider(cand) as usize;
        if !matches!(self.colliders[c].shape, Shape::Capsule { .. }) {
            return false;
        }
        let (a, b) = (cand.pair[0] as usize, cand.pair[1] as usize);
        let pierces = |e: usize, f: u32| {
            // The axis at the start pose ([`Self::pose_colliders`]).
            let [p, q, _, _] = self.feat_edge_tracks[e];
            let t = self.faces[f as usize].map(|i| x0[i as usize]);
            // Boxes apart (closed), no meeting: the exact test only where it can say yes.
            let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            p.min(q).cmple(hi).all()
                && lo.cmple(p.max(q)).all()
                && distance::segment_triangle_intersect(p, q, t)
        };
        match cand.kind {
            PairKind::FeatureEdgeEdge => self.edge_faces[b]
                .iter()
                .any(|&f| f != NONE && pierces(a, f)),
            PairKind::FeatureFace => self.point_edges[a]
                .iter()
                .any(|&e| pierces(e as usize, b as u32)),
            _ => false,
        }
    }

    /// The way off a capsule's axis for a point at parameter `s` along it (0 at its first
    /// end, 1 at its second): the unit direction along the axis towards the nearer end, and
    /// that end, at the collider's start and end poses (`None` if the collider is not a
    /// capsule or its axis has no length).
    fn axis_exit(&self, c: usize, s: f64) -> Option<[DVec3; 4]> {
        let Shape::Capsule { a, b, .. } = self.colliders[c].shape else {
            return None;
        };
        let (from, to) = if s >= 0.5 { (a, b) } else { (b, a) };
        let dir = (to - from).normalize_or_zero();
        if dir == DVec3::ZERO {
            return None;
        }
        let (pose0, pose1) = (self.pose0[c], self.pose1[c]);
        Some([
            pose0.rotate(dir),
            pose0.apply(to),
            pose1.rotate(dir),
            pose1.apply(to),
        ])
    }

    /// Moves particle `i` along an [`Self::axis_exit`] until it is `reach` (m) beyond the
    /// end, by at most the push-out distance beyond where it started; returns the move left
    /// before this one, relative to `reach`.
    fn slide_off_axis(
        &self,
        exit: [DVec3; 4],
        i: usize,
        reach: f64,
        x0: &[DVec3],
        x: &mut [DVec3],
        pushes: &mut [DVec3],
    ) -> f64 {
        let [dir0, end0, dir1, end1] = exit;
        let start = dir0.dot(x0[i] - end0);
        let target = push_out_reach(reach, start, self.push_out());
        let deficit = target - dir1.dot(x[i] - end1);
        if deficit > 0.0 {
            x[i] += deficit * dir1;
            if !pushes.is_empty() {
                pushes[i] += deficit * dir1;
            }
            deficit / reach
        } else {
            0.0
        }
    }

    /// Moves the particles of a cloth edge impaled on a capsule's axis (its face pierced at the
    /// substep's start, [`Self::starts_impaled`]) along the axis towards the end nearer to where
    /// the axis meets it ([`Self::slide_off_axis`]): the cloth slides off the capsule over
    /// its end. Returns the largest move left, relative to `reach`.
    fn push_off_axis(
        &self,
        cand: Candidate,
        reach: f64,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) -> f64 {
        let c = self.feature_collider(cand) as usize;
        let b = cand.pair[1] as usize;
        let ids = match cand.kind {
            PairKind::FeatureFace => self.faces[b],
            _ => {
                let [p, q] = self.edges[b];
                [p, q, q]
            }
        };
        let centre = (x0[ids[0] as usize] + x0[ids[1] as usize] + x0[ids[2] as usize]) / 3.0;
        let Some(exit) = self.axis_exit(c, self.axis_parameter(c, centre)) else {
            return 0.0;
        };
        let mut worst: f64 = 0.0;
        for i in ids.map(|i| i as usize) {
            if inv_mass[i] > 0.0 {
                worst = worst.max(self.slide_off_axis(exit, i, reach, x0, x, pushes));
            }
        }
        worst
    }

    /// The parameter along capsule `c`'s axis (0 at its first end, 1 at its second) of the
    /// point of it nearest to `p`, at the collider's start pose (0 for a point, or not a
    /// capsule).
    fn axis_parameter(&self, c: usize, p: DVec3) -> f64 {
        let Shape::Capsule { a, b, .. } = self.colliders[c].shape else {
            return 0.0;
        };
        let (a0, b0) = (self.pose0[c].apply(a), self.pose0[c].apply(b));
        distance::point_segment_closest(p, a0, b0).0
    }

    /// Lists the (collider, local object) pairs with an object's face impaled on a capsule's
    /// axis at the substep's start ([`Self::starts_impaled`]): the vertices of that object
    /// inside the capsule slide off along the axis with the impaled faces
    /// ([`Self::impaled_vertex`]) instead of leaving it radially, which would open a hole
    /// around the axis and stretch the cloth around it.
    fn find_impaled(&mut self, x0: &[DVec3]) {
        self.impaled.clear();
        // The feature pairs come last ([`Self::start_split`]).
        for k in self.start_split[1]..self.candidates.len() {
            let cand = self.candidates[k];
            if cand.kind != PairKind::FeatureEdgeEdge || !self.starts_impaled(cand, x0) {
                continue;
            }
            let pair = (
                self.feature_collider(cand),
                self.edge_obj[cand.pair[1] as usize],
            );
            if !self.impaled.contains(&pair) && self.impaled.len() < self.impaled.capacity() {
                self.impaled.push(pair);
            }
        }
    }

    /// Whether a capsule feature candidate's primitive belongs to an object impaled on that
    /// capsule this substep and starts inside it (its distance from the feature at the
    /// substep's start, `start`, short of `reach`): it slides off along the axis
    /// ([`Self::push_off_axis`]) instead of leaving it radially.
    fn slides_off_axis(&self, cand: Candidate, start: f64, reach: f64) -> bool {
        if self.impaled.is_empty() || start.is_nan() || start >= reach {
            return false;
        }
        let b = cand.pair[1] as usize;
        let object = match cand.kind {
            PairKind::FeatureFace => self.face_obj[b],
            _ => self.edge_obj[b],
        };
        self.impaled
            .contains(&(self.feature_collider(cand), object))
    }

    /// How a feature candidate, `start` (m, signed: [`Self::feature_side`]) from its feature
    /// at the substep's start, leaves its collider: across the feature, so that a contact or
    /// the fail-safe, which forbid that crossing, must leave it to the final projections
    /// ([`Self::project_features_out`]), when it is on the wrong side of a box's corner or
    /// edge, or in the box ([`Self::starts_in_box`]), or impaled on a capsule's axis
    /// ([`Self::starts_impaled`]) or sliding off it with an impaled object
    /// ([`Self::slides_off_axis`]).
    fn leaves_through_feature(
        &self,
        cand: Candidate,
        start: f64,
        reach: f64,
        x0: &[DVec3],
    ) -> Leaves {
        if self.starts_impaled(cand, x0) || self.slides_off_axis(cand, start, reach) {
            Leaves::OffAxis
        } else if start < 0.0 || self.starts_in_box(cand, x0) {
            Leaves::ThroughBox
        } else {
            Leaves::Normally
        }
    }

    /// Candidate `k`'s primitive at the substep's start ([`StartOf`]), taken now if the
    /// substep has not yet: for a vertex–collider pair, the vertex's signed distance from the
    /// collider, and off the axis if its object is impaled on it and it starts within its
    /// contact distance ([`Self::impaled_vertex`]); for a feature pair, its primitive's
    /// distance from the feature ([`Self::feature_distance`]) and how it leaves
    /// ([`Self::leaves_through_feature`]).
    /// [`StartOf::UNKNOWN`] for the other kinds. It must not be asked before the substep's
    /// impaled objects are found ([`Self::find_impaled`]).
    fn start_of(&mut self, k: usize, x0: &[DVec3]) -> StartOf {
        let Some(slot) = start_slot(self.start_split, k) else {
            return StartOf::UNKNOWN;
        };
        let known = self.start[slot];
        if !known.distance.is_nan() {
            return known;
        }
        let cand = self.candidates[k];
        let taken = if cand.kind == PairKind::Collider {
            let (c, v) = (cand.pair[0] as usize, cand.pair[1] as usize);
            let q0 = self.pose0[c].inverse_apply(x0[self.verts[v] as usize]);
            let distance = self.colliders[c].shape.signed_distance(q0).0;
            let leaves = if self.impaled_vertex(c, v) && distance < self.reach[k] {
                Leaves::OffAxis
            } else {
                Leaves::Normally
            };
            StartOf { distance, leaves }
        } else if cand.kind.is_feature() {
            let c = self.feature_collider(cand) as usize;
            let distance = self.feature_distance(cand, x0, self.pose0[c]);
            StartOf {
                distance,
                leaves: self.leaves_through_feature(cand, distance, self.reach[k], x0),
            }
        } else {
            return StartOf::UNKNOWN;
        };
        self.start[slot] = taken;
        taken
    }

    /// Whether vertex primitive `v`'s object is impaled on collider `c` this substep.
    fn impaled_vertex(&self, c: usize, v: usize) -> bool {
        !self.impaled.is_empty() && self.impaled.contains(&(c as u32, self.vert_obj[v]))
    }

    /// A feature candidate's closest points ([`Self::feature_closest`]), and on which side of
    /// its feature the primitive is. A box's corners and edges are its surface: a primitive
    /// whose closest point lies inside the box (a cloth edge cutting a corner, a face a box
    /// edge pokes through) is on the wrong side, and its way out is through the feature. A
    /// sphere's centre and a capsule's axis are inside their shapes: every primitive is on
    /// the outer side of them.
    fn feature_side(&self, cand: Candidate, x: &[DVec3], pose: Pose) -> FeatureSide {
        let (ids, w, q, d2) = self.feature_closest(cand, x, pose);
        let p: DVec3 = (0..3).map(|j| w[j] * x[ids[j] as usize]).sum();
        let shape = &self.colliders[self.feature_collider(cand) as usize].shape;
        let inside = matches!(shape, Shape::Box { .. })
            && shape.signed_distance(pose.inverse_apply(p)).0 < 0.0;
        FeatureSide {
            ids,
            w,
            p,
            q,
            d2,
            inside,
        }
    }

    /// How far (m) a primitive that starts the substep inside a collider may leave it by in
    /// this substep: `push_out_speed · h` ([`push_out_reach`]).
    #[inline]
    fn push_out(&self) -> f64 {
        self.push_out_speed * self.h
    }

    /// Follows the push-out of every particle of a primitive that started the substep closer to
    /// an analytic collider (or its feature) than its contact distance, for
    /// [`Self::drop_push_out_velocity`]: the outward speed a push gave it this substep
    /// ([`push_speed`], shared among a face's or an edge's particles as the projection shares
    /// it) adds to what it carries, up to the push-out speed; the direction out and the
    /// collider's speed along it are those at the end of the substep. A particle is out once
    /// none of its primitives was held back by the push-out speed ([`push_out_reach`] gave its
    /// full contact distance); one none of whose primitives started inside is dropped.
    fn record_push_outs(&mut self, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64]) {
        let (push, h) = (self.push_out(), self.h);
        if h.is_nan() || h <= 0.0 {
            return;
        }
        for &i in &self.pushed {
            let p = &mut self.push[i as usize];
            (p.given, p.seen, p.inside) = (0.0, false, false);
        }
        for k in 0..self.candidates.len() {
            let cand = self.candidates[k];
            if cand.kind == PairKind::Collider {
                let Some((c, p, r)) = self.dynamic_collider_pair(cand, inv_mass) else {
                    continue;
                };
                let start = self.start_of(k, x0);
                if start.leaves == Leaves::OffAxis || !short_of(start.distance, r) {
                    continue;
                }
                let start = start.distance;
                let col = &self.colliders[c];
                let (pose0, pose1) = (self.pose0[c], self.pose1[c]);
                let q = pose1.inverse_apply(x[p]);
                let (end, n_local) = col.shape.signed_distance(q);
                let predicted = col
                    .shape
                    .signed_distance(pose1.inverse_apply(self.x_pred[p]))
                    .0;
                let normal = pose1.rotate(n_local);
                let collider_speed = normal.dot(x[p] - pose0.apply(q)) / h;
                let target = push_out_reach(r, start, push);
                let speed = push_speed(start, predicted, end, target, h);
                self.note_push(
                    p,
                    normal,
                    collider_speed,
                    speed,
                    still_inside(end, target, r),
                );
            } else if cand.kind.is_feature() {
                let c = self.feature_collider(cand) as usize;
                let (pose0, pose1) = (self.pose0[c], self.pose1[c]);
                let start = self.start_of(k, x0).distance;
                let reach = self.reach[k];
                if !short_of(start, reach) {
                    continue;
                }
                let side = self.feature_side(cand, x, pose1);
                let (ids, w, q) = (side.ids, side.w, side.q);
                let dist = side.distance();
                if dist.is_nan() || dist.abs() <= 1e-12 || !dist.is_finite() {
                    continue;
                }
                let normal = side.out() / dist.abs();
                let collider_speed = normal.dot(q - pose0.apply(pose1.inverse_apply(q))) / h;
                let predicted = self.feature_distance(cand, &self.x_pred, pose1);
                let target = push_out_reach(reach, start, push);
                let speed = push_speed(start, predicted, dist, target, h);
                // The projection moves particle j by inv_mass_j w_j / Σ inv_mass w² of the
                // closest point's move.
                let w_total: f64 = (0..3)
                    .map(|j| inv_mass[ids[j] as usize] * w[j] * w[j])
                    .sum();
                if w_total.is_nan() || w_total <= 0.0 || !w_total.is_finite() {
                    continue;
                }
                for j in 0..3 {
                    let i = ids[j] as usize;
                    if w[j] != 0.0 && inv_mass[i] > 0.0 && (j == 0 || ids[j] != ids[j - 1]) {
                        let share = inv_mass[i] * w[j] / w_total;
                        self.note_push(
                            i,
                            normal,
                            collider_speed,
                            speed * share,
                            still_inside(dist, target, reach),
                        );
                    }
                }
            }
        }
        let limit = self.push_out_speed;
        let push_state = &mut self.push;
        self.pushed.retain(|&i| {
            let p = &mut push_state[i as usize];
            if !p.seen {
                *p = PushOut::NONE;
                return false;
            }
            p.speed = (p.speed + p.given).min(limit);
            true
        });
    }

    /// Notes that a primitive of particle `i` started the substep inside a collider, was
    /// given `speed` (m/s) by its push along `normal` (unit) there, and was still held back
    /// (`inside`).
    fn note_push(
        &mut self,
        i: usize,
        normal: DVec3,
        collider_speed: f64,
        speed: f64,
        inside: bool,
    ) {
        if !normal.is_finite() || !collider_speed.is_finite() {
            return;
        }
        if !self.push[i].listed {
            self.push[i].listed = true;
            self.pushed.push(i as u32);
        }
        let p = &mut self.push[i];
        p.seen = true;
        p.inside |= inside;
        let speed = if speed.is_finite() {
            speed.max(0.0)
        } else {
            0.0
        };
        if speed >= p.given {
            (p.given, p.normal, p.collider_speed) = (speed, normal, collider_speed);
        }
    }

    /// Takes the speed the push-out gave off the velocity of every particle that got out this
    /// substep ([`without_push_velocity`]): a cloth placed through a collider leaves it at
    /// `push_out_speed` and stops at its surface, instead of flying on at that speed.
    fn drop_push_out_velocity(&mut self, v: &mut [DVec3]) {
        let push_state = &mut self.push;
        self.pushed.retain(|&i| {
            let i = i as usize;
            if push_state[i].inside {
                return true;
            }
            v[i] = without_push_velocity(v[i], &push_state[i]);
            push_state[i] = PushOut::NONE;
            false
        });
    }

    /// Where the fail-safe puts a frozen particle: its start, carried by the rigid motion of
    /// its carrier (a fully kinematic object, or an analytic collider) over the substep.
    fn carried(&self, carrier: u32, p: usize, x0: &[DVec3], x: &[DVec3]) -> DVec3 {
        if carrier == CARRY_STILL {
            return x0[p];
        }
        if carrier >= CARRY_COLLIDER {
            let c = (carrier - CARRY_COLLIDER) as usize;
            return self.pose1[c].apply(self.pose0[c].inverse_apply(x0[p]));
        }
        let Some([a, b, c]) = self.rigid_frame[carrier as usize] else {
            return x0[p];
        };
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let f0 = frame(x0[a], x0[b], x0[c]);
        let f1 = frame(x[a], x[b], x[c]);
        match (f0, f1) {
            (Some(f0), Some(f1)) => x[a] + f1 * (f0.transpose() * (x0[p] - x0[a])),
            _ => x0[p] + (x[a] - x0[a]),
        }
    }

    /// The fail-safe: while some pair still *crosses* over `[x0, x]` (a continuous test with
    /// zero thickness; for an analytic collider's feature, reaching the collider's core),
    /// freeze its dynamic particles — put them back where they started the substep, carried
    /// by the rigid motion of a kinematic object or analytic collider they hit. The start of
    /// the substep is crossing-free, so every round either resolves the remaining crossings or
    /// freezes a new particle: at most one round per particle. Returns the pairs left crossing.
    fn fail_safe(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        team: TeamRef<'_>,
    ) -> usize {
        loop {
            self.refresh_escaped(x0, x, inv_mass, team);
            let mut crossing = 0;
            let mut froze = false;
            self.update_moved(x);
            for k in 0..self.candidates.len() {
                let cand = self.candidates[k];
                if cand.kind == PairKind::Collider
                    || self.skip(k, 0.0)
                    || !self.boxes_overlap(cand, x0, x)
                {
                    continue;
                }
                let Some(c) = self.detect(k, x0, x, 0.0, None) else {
                    continue;
                };
                crossing += 1;
                let carrier = if cand.kind.is_feature() {
                    CARRY_COLLIDER + self.feature_collider(cand)
                } else {
                    c.ids
                        .iter()
                        .zip(&c.w)
                        .find(|(&i, &w)| w != 0.0 && inv_mass[i as usize] == 0.0)
                        .map(|(&i, _)| self.object_of_particle(i))
                        .unwrap_or(CARRY_STILL)
                };
                // Every particle of the two primitives is frozen (a vertex of a face with a zero
                // barycentric weight included); only the unused slots of the particle pairs
                // (weight 0) are skipped.
                let whole = matches!(c.kind, PairKind::VertexFace | PairKind::EdgeEdge)
                    || c.kind.is_feature();
                for (&i, &w) in c.ids.iter().zip(&c.w) {
                    let i = i as usize;
                    if w == 0.0 && !whole {
                        continue;
                    }
                    if inv_mass[i] > 0.0 && self.carrier[i] == NONE {
                        self.carrier[i] = carrier;
                        self.frozen_list.push(i as u32);
                        x[i] = self.carried(carrier, i, x0, x);
                        self.moved[i] = (x[i] - self.x_ref[i]).length();
                        froze = true;
                        self.stats.frozen += 1;
                    }
                }
            }
            if crossing == 0 || !froze {
                return crossing;
            }
        }
    }

    /// The local object of a kinematic particle, as a carrier (`CARRY_STILL` if the object
    /// does not move rigidly).
    fn object_of_particle(&self, p: u32) -> u32 {
        // Primitives are grouped by object; vertices are sorted within each object.
        match self.verts.iter().position(|&v| v == p) {
            Some(i) => {
                let o = self.vert_obj[i];
                if self.rigid_frame[o as usize].is_some() {
                    o
                } else {
                    CARRY_STILL
                }
            }
            None => CARRY_STILL,
        }
    }

    /// The error of a substep whose candidates went over [`Self::candidate_budget`], if one
    /// did (and clears it): it names the object of the vertex that moved farthest over the
    /// substep, and how far.
    fn over_budget_error(&mut self, x0: &[DVec3], x: &[DVec3]) -> Result<(), PluginError> {
        let found = std::mem::take(&mut self.over_budget);
        if found == 0 {
            return Ok(());
        }
        let (mut far, mut who) = (0.0f64, 0usize);
        for (i, &p) in self.verts.iter().enumerate() {
            let d = x[p as usize].distance(x0[p as usize]);
            if d > far || d.is_nan() {
                (far, who) = (d, i);
            }
        }
        let name = self
            .names
            .get(self.vert_obj.get(who).copied().unwrap_or(0) as usize);
        let message = format!(
            "{found} candidate pairs in one substep, over the group's budget of {} (parameter \
             max_candidates; automatic: 64 per primitive, 8 per pair in contact at rest, at \
             least {MIN_CANDIDATE_BUDGET}): its primitives move too far against each other in a \
             substep (a vertex of this object moved {far:.3e} m in {:.3e} s); use more \
             substeps, or check the gravity, the velocities and the colliders' motion",
            self.candidate_budget, self.h
        );
        Err(match name {
            Some(n) => PluginError::bad_object(n.as_str(), message),
            None => PluginError::failed(message),
        })
    }

    fn check_state(&self, len: usize) -> Result<(), PluginError> {
        if len < self.x_pred.len() {
            return Err(PluginError::failed(format!(
                "the group was built for {} particles but the state has {len}",
                self.x_pred.len()
            )));
        }
        Ok(())
    }

    /// Deepest thickness violation (m) at positions `x`, with the colliders at `poses`: over
    /// the contacts between particles, and over every candidate pair with a collider (its
    /// vertices by the exact signed distance, its features by their distance to the faces and
    /// edges near them). With `at_substep_end` (`x` the substep's end positions, `moved`
    /// current and `poses` its end poses) the pairs certainly beyond their reach, which add
    /// nothing, are skipped ([`Self::certainly_beyond_reach`]).
    fn penetration(&self, x: &[DVec3], poses: &[Pose], at_substep_end: bool) -> f64 {
        let mut worst: f64 = 0.0;
        for c in &self.contacts {
            if c.kind != PairKind::Collider && !c.kind.is_feature() {
                let (_, d2) = self.current_distance(c, x);
                worst = worst.max(c.offset - d2.sqrt());
            }
        }
        for (k, cand) in self.candidates.iter().enumerate() {
            let (a, b) = (cand.pair[0] as usize, cand.pair[1] as usize);
            if cand.kind != PairKind::Collider && !cand.kind.is_feature() {
                continue;
            }
            if at_substep_end && self.certainly_beyond_reach(k) {
                continue;
            }
            let dist = match cand.kind {
                PairKind::Collider => {
                    let p = self.verts[b] as usize;
                    let col = &self.colliders[a];
                    let (phi, _) = col.shape.signed_distance(poses[a].inverse_apply(x[p]));
                    phi
                }
                kind if kind.is_feature() => {
                    let c = self.feature_collider(*cand) as usize;
                    self.feature_distance(*cand, x, poses[c])
                }
                _ => continue,
            };
            worst = worst.max(self.reach[k] - dist);
        }
        worst
    }

    /// `(unused, squared distance)` between a mesh contact's two primitives at `x`.
    fn current_distance(&self, c: &Contact, x: &[DVec3]) -> ((), f64) {
        let g = |k: usize| x[c.ids[k] as usize];
        let d2 = match c.kind {
            PairKind::VertexFace => distance::point_triangle_closest(g(0), g(1), g(2), g(3)).1,
            PairKind::EdgeEdge => distance::segment_segment_closest(g(0), g(1), g(2), g(3)).2,
            PairKind::VertexEdge => distance::point_segment_closest(g(0), g(2), g(3)).1,
            PairKind::VertexVertex => g(0).distance_squared(g(1)),
            _ => f64::INFINITY,
        };
        ((), d2)
    }
}

/// An orthonormal frame (columns) from three points, `None` if they are (nearly) collinear.
/// Runs `act` on contact `c` and, when `out` is being recorded (not empty), adds to it what
/// `act` moved the contact's particles by if the contact is against something immovable
/// ([`Contact::moves_if`]): displacements with positions for `x`, velocity changes with
/// velocities.
#[inline]
fn recorded(
    c: &mut Contact,
    x: &mut [DVec3],
    inv_mass: &[f64],
    out: &mut [DVec3],
    act: impl FnOnce(&mut Contact, &mut [DVec3]),
) {
    let moves = c.moves_if(!out.is_empty(), x, inv_mass);
    act(c, x);
    if let Some(m) = moves {
        m.add_to(x, out);
    }
}

fn frame(a: DVec3, b: DVec3, c: DVec3) -> Option<glam::DMat3> {
    let e1 = (b - a).try_normalize()?;
    let u = c - a;
    let e2 = (u - e1 * e1.dot(u)).try_normalize()?;
    Some(glam::DMat3::from_cols(e1, e2, e1.cross(e2)))
}

/// Three vertices of `verts` spanning a well-shaped frame in the rest pose.
fn frame_vertices(rest: &[DVec3], verts: &[u32]) -> Option<[u32; 3]> {
    let &a = verts.first()?;
    let pa = rest[a as usize];
    let &b = verts.iter().max_by(|&&i, &&j| {
        pa.distance_squared(rest[i as usize])
            .total_cmp(&pa.distance_squared(rest[j as usize]))
    })?;
    let pb = rest[b as usize];
    let &c = verts.iter().max_by(|&&i, &&j| {
        let area = |k: u32| (pb - pa).cross(rest[k as usize] - pa).length_squared();
        area(i).total_cmp(&area(j))
    })?;
    let area = (pb - pa).cross(rest[c as usize] - pa).length();
    (area > 1e-12 && frame(pa, pb, rest[c as usize]).is_some()).then_some([a, b, c])
}

impl ConstraintGroup for CollisionGroup {
    fn stages(&self) -> Stages {
        Stages::BEGIN_SUBSTEP
            | Stages::PROJECT
            | Stages::END_SUBSTEP
            | Stages::REPORT
            | Stages::GIVES_PUSHES
    }

    /// The number of collision primitives (vertices, edges, faces and colliders), or 0 when
    /// no pair can ever collide: then the core never schedules the group.
    fn len(&self) -> usize {
        if self.active {
            self.verts.len() + self.edges.len() + self.faces.len() + self.colliders.len()
        } else {
            0
        }
    }

    /// Saves the predicted positions, poses the colliders at both ends of the substep, and
    /// runs the broad phase over the swept primitives.
    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        if ctx.frame != self.stats.frame {
            self.stats = FrameStats {
                frame: ctx.frame,
                ..FrameStats::default()
            };
        }
        let (h, time, team) = (ctx.substep_length()?, ctx.time, ctx.team);
        let p = ctx.particles();
        self.check_state(p.x.len().min(p.x0.len()).min(p.inv_mass.len()))?;
        let n = self.x_pred.len();
        self.x_pred.copy_from_slice(&p.x[..n]);
        self.h = h;
        let mean = self.shared_displacement(p.x0, p.x, p.inv_mass);
        let r = self.max_thickness;
        if (mean - self.shift).length() > r + margin(r) {
            self.shift = mean;
        }
        self.pose_colliders(time, h);
        for &i in &self.frozen_list {
            self.carrier[i as usize] = NONE;
        }
        self.frozen_list.clear();
        self.contacts.clear();
        // A new substep, new tracks: no separation carries over from the last one.
        self.within_substep = false;
        if !self.colliders_and_masses_hold(p.inv_mass) {
            self.broad_phase(p.x0, p.x, p.inv_mass, team);
        } else if !self.refresh_escaped(p.x0, p.x, p.inv_mass, team) {
            self.restart_passes(p.x);
        }
        self.within_substep = true;
        self.find_impaled(p.x0);
        self.over_budget_error(p.x0, p.x)
    }

    /// One pass of detection and resolution; the last pass of the substep also applies
    /// friction, projects out of the analytic colliders and runs the fail-safe.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let (last, team) = (ctx.pass + 1 >= ctx.passes, ctx.team);
        let p = ctx.particles();
        self.check_state(p.x.len().min(p.x0.len()).min(p.inv_mass.len()))?;
        let (x0, x, w, pushes) = (p.x0, p.x, p.inv_mass, p.pushes);
        self.refresh_escaped(x0, x, w, team);
        self.resolve_pass(x0, x, w, pushes, team);
        if last {
            let (mu_static, mu_dynamic) = (self.mu_static, self.mu_dynamic);
            for c in &mut self.contacts {
                recorded(c, x, w, pushes, |c, x| {
                    c.friction(x, x0, w, mu_static, mu_dynamic);
                });
            }
            // Friction moved particles tangentially: one more normal sweep.
            for c in &mut self.contacts {
                recorded(c, x, w, pushes, |c, x| {
                    c.project(x, w);
                });
            }
            // Friction and the sweeps moved particles: the final projections must see every
            // pair near a collider now, not only those of the pass's candidates.
            self.refresh_escaped(x0, x, w, team);
            self.project_features_out(x0, x, w, pushes);
            self.project_out_of_colliders(x0, x, w, pushes);
            let unresolved = self.fail_safe(x0, x, w, team);
            self.record_push_outs(x0, x, w);
            self.stats.unresolved += unresolved;
            self.stats.contacts = self.stats.contacts.max(self.contacts.len());
        }
        self.over_budget_error(x0, x)
    }

    /// Restitution: contacts that worked this substep and were approaching faster than
    /// `2|g|h` leave with `−e` times their approach speed.
    fn end_substep(&mut self, ctx: &mut SolveContext<'_>) -> Result<(), PluginError> {
        let h = ctx.h;
        let threshold = 2.0 * ctx.gravity().length() * h;
        let p = ctx.particles();
        self.check_state(p.x.len().min(p.x0.len()).min(p.inv_mass.len()))?;
        self.update_moved(p.x);
        let pen = self.penetration(p.x, &self.pose1, true);
        self.stats.max_penetration = self.stats.max_penetration.max(pen);
        self.drop_push_out_velocity(p.v);
        if self.restitution <= 0.0 || self.contacts.is_empty() || h <= 0.0 {
            return Ok(());
        }
        for (vp, (&xp, &x0)) in self.v_pre.iter_mut().zip(self.x_pred.iter().zip(p.x0)) {
            *vp = (xp - x0) / h;
        }
        for c in &mut self.contacts {
            let collider_v = c.collider_disp / h;
            recorded(c, p.v, p.inv_mass, p.kicks, |c, v| {
                c.restitution(
                    v,
                    &self.v_pre,
                    p.inv_mass,
                    self.restitution,
                    threshold,
                    collider_v,
                );
            });
        }
        Ok(())
    }

    /// The deepest violation of the thickness (m) over the contacts of the last substep and
    /// the vertices near colliders, at the current positions.
    fn residual(&self, ctx: &SolveContext<'_>) -> Residual {
        let x = ctx.positions();
        if x.len() < self.x_pred.len() {
            return Residual::default();
        }
        let poses: Vec<Pose> = self
            .colliders
            .iter()
            .map(|c| c.motion.pose(ctx.time))
            .collect();
        let max = self.penetration(x, &poses, false);
        Residual {
            count: self.contacts.len() as u64,
            max,
            rms: max,
            energy: 0.0,
        }
    }

    fn report(&self, _ctx: &SolveContext<'_>, out: &mut Vec<(String, f64)>) {
        let s = self.stats;
        out.push(("contacts".into(), s.contacts as f64));
        out.push(("candidates".into(), s.candidates as f64));
        out.push(("broad_phases".into(), s.broad_phases as f64));
        out.push(("refreshes".into(), s.refreshes as f64));
        out.push(("frozen".into(), s.frozen as f64));
        out.push(("unresolved".into(), s.unresolved as f64));
        out.push(("max_penetration".into(), s.max_penetration));
    }
}

/// The factory of the `collision` kind.
pub(crate) fn build(
    params_json: &str,
    scene: &SceneView<'_>,
) -> Result<Box<dyn ConstraintGroup>, PluginError> {
    let params = CollisionParams::parse(params_json)?;
    Ok(Box::new(CollisionGroup::new(&params, scene)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nucleus_sdk::abi_stable::std_types::RSlice;
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
    fn every_chunk_runs_once_whatever_the_team_and_the_chunks_cover_the_range() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let teams = [0, 1, 2, 4].map(nucleus_sdk::team::Team::new);
        for team in &teams {
            let team = TeamRef::new(team);
            for (n, chunks) in [(1, 1), (7, 7), (513, 16), (100_003, 32)] {
                let runs: Vec<AtomicUsize> = (0..chunks).map(|_| AtomicUsize::new(0)).collect();
                let covered: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
                let parts = team.parts();
                claim_chunks(team, chunks, &|part, c| {
                    assert!(part < parts, "a part index out of the team");
                    runs[c].fetch_add(1, Ordering::Relaxed);
                    for i in span(c, chunks, n) {
                        covered[i].fetch_add(1, Ordering::Relaxed);
                    }
                });
                let parts = team.parts();
                assert!(
                    runs.iter().all(|r| r.load(Ordering::Relaxed) == 1),
                    "{parts} parts, {chunks} chunks"
                );
                assert!(
                    covered.iter().all(|c| c.load(Ordering::Relaxed) == 1),
                    "{parts} parts, n = {n}"
                );
            }
        }
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

    /// Rest positions, edges and triangles of a mesh.
    type Mesh = (Vec<[f64; 3]>, Vec<[u32; 2]>, Vec<[u32; 3]>);

    /// A flat `n × n` cloth of side 0.5 m in the plane z = 0, two triangles per quad.
    fn cloth(n: u32) -> Mesh {
        let s = 0.5 / (n - 1) as f64;
        let rest = (0..n * n)
            .map(|k| [(k % n) as f64 * s, (k / n) as f64 * s, 0.0])
            .collect();
        let mut tris = Vec::new();
        for r in 0..n - 1 {
            for c in 0..n - 1 {
                let a = r * n + c;
                tris.push([a, a + 1, a + n + 1]);
                tris.push([a, a + n + 1, a + n]);
            }
        }
        let mut edges: Vec<[u32; 2]> = tris
            .iter()
            .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
            .map(|[a, b]| [a.min(b), a.max(b)])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        (rest, edges, tris)
    }

    /// Two identical groups over the cloth: self-collision, a sphere and a box (whose corners
    /// and edges are features).
    fn groups(rest: &[[f64; 3]], edges: &[[u32; 2]], tris: &[[u32; 3]]) -> [CollisionGroup; 2] {
        let inv_mass = vec![1.0; rest.len()];
        let objects = [ObjectView {
            edges: RSlice::from_slice(edges),
            triangles: RSlice::from_slice(tris),
            ..ObjectView::new("cloth", 0, rest.len() as u32)
        }];
        let scene = SceneView::new(&objects, &[0], rest, &inv_mass);
        let infos: Vec<_> = CollisionParams::specs().iter().map(|s| s.info()).collect();
        let json = nucleus_sdk::params::validate_json(
            r#"{"thickness": 0.01, "colliders": [
                {"type": "sphere", "center": [0.25, 0.25, -0.2], "radius": 0.15},
                {"type": "box", "center": [0.1, 0.1, 0.05], "half_extents": [0.05, 0.05, 0.05]}
            ]}"#,
            &infos,
        )
        .expect("valid parameters");
        let params = CollisionParams::parse(&json).expect("params");
        let make = || CollisionGroup::new(&params, &scene).expect("group");
        let mut pair = [make(), make()];
        for g in &mut pair {
            g.pose_colliders(0.0, 0.0);
            let features = (g.feat_points.len(), g.feat_edges.len());
            assert!(features.0 > 0 && features.1 > 0, "the box has features");
        }
        pair
    }

    /// Whether candidate `c`'s primitives can touch now: their tight boxes (swept over the
    /// substep and grown by their radii, no margin) overlap, or for a collider feature, lie
    /// within the collider's radius.
    fn touching(g: &CollisionGroup, c: Candidate, x0: &[DVec3], x: &[DVec3]) -> bool {
        let [a, b] = c.pair.map(|k| k as usize);
        let feature = |tight: Aabb, collider: u32, other: Aabb| {
            let rc = g.collider_radius[collider as usize];
            tight.distance_squared(&other) <= rc * rc
        };
        match c.kind {
            PairKind::Collider => g.vert_box(b, x0, x).overlaps(&g.collider_boxes[a]),
            PairKind::VertexFace => g.vert_box(a, x0, x).overlaps(&g.face_box(b, x0, x)),
            PairKind::EdgeEdge => g.edge_box(a, x0, x).overlaps(&g.edge_box(b, x0, x)),
            PairKind::FeatureFace => feature(
                g.feat_point_boxes[a],
                g.feat_points[a].0,
                g.face_box(b, x0, x),
            ),
            PairKind::FeaturePointEdge => feature(
                g.feat_point_boxes[a],
                g.feat_points[a].0,
                g.edge_box(b, x0, x),
            ),
            PairKind::FeatureEdgeEdge => feature(
                g.feat_edge_boxes[a],
                g.feat_edges[a].0,
                g.edge_box(b, x0, x),
            ),
            PairKind::VertexVertex | PairKind::VertexEdge => true,
        }
    }

    #[test]
    fn a_push_gives_only_the_speed_beyond_the_start_and_the_prediction() {
        let h = 0.25;
        // At rest inside: the push moves it 0.1 m out in the substep.
        assert!((push_speed(-0.3, -0.3, -0.2, -0.2, h) - 0.4).abs() < 1e-12);
        // Falling in (predicted deeper than the start): the contact takes the fall, the
        // push gives only what it moved beyond the start.
        assert!((push_speed(-0.3, -0.5, -0.2, -0.2, h) - 0.4).abs() < 1e-12);
        // Carried out by its own velocity beyond where the push would take it: none.
        assert!(push_speed(-0.3, -0.1, -0.1, -0.2, h) <= 0.0);
        // Ending beyond the target (other constraints pulled it out): capped at the target.
        assert!((push_speed(-0.3, -0.3, 0.5, -0.2, h) - 0.4).abs() < 1e-12);
        // Out once it ends at its reach, or once nothing holds it back.
        assert!(still_inside(-0.2, -0.2, 0.01));
        assert!(!still_inside(0.01 * (1.0 - 1e-12), -0.2, 0.01));
        assert!(!still_inside(0.0, 0.01, 0.01));
    }

    #[test]
    fn taking_a_push_off_keeps_the_tangential_motion_and_the_colliders() {
        let push = PushOut {
            normal: DVec3::Y,
            collider_speed: 0.5,
            speed: 1.0,
            ..PushOut::NONE
        };
        // 1.5 m/s out on a collider moving out at 0.5: the 1 m/s the push gave goes.
        let v = without_push_velocity(DVec3::new(2.0, 1.5, -1.0), &push);
        assert_eq!(v, DVec3::new(2.0, 0.5, -1.0));
        // Thrown out faster than the push: only the push's share goes.
        let v = without_push_velocity(DVec3::new(0.0, 4.0, 0.0), &push);
        assert_eq!(v, DVec3::new(0.0, 3.0, 0.0));
        // Moving in relative to the collider: nothing to take off.
        let v = without_push_velocity(DVec3::new(0.0, 0.2, 0.0), &push);
        assert_eq!(v, DVec3::new(0.0, 0.2, 0.0));
    }

    /// After primitives leave their boxes, the partial refresh keeps every pair a full broad
    /// phase finds that can touch now, with the same contact distance, in sorted order — over
    /// rounds of random crumpling in which a few or most vertices move. (A full broad phase
    /// also lists pairs within a fresh margin of each other; the refresh keeps the older
    /// boxes of the primitives that stayed in theirs, and lists the pairs within those.)
    #[test]
    fn a_refresh_keeps_every_pair_a_full_broad_phase_finds() {
        let (rest, edges, tris) = cloth(14);
        let [mut partial, mut full] = groups(&rest, &edges, &tris);
        let inv_mass = vec![1.0; rest.len()];
        let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
        let mut x = x0.clone();
        let mut rng = Rng(3);
        partial.broad_phase(&x0, &x, &inv_mass, TeamRef::serial());
        let (mut refreshed, mut fallbacks) = (0, 0);
        for round in 0..60 {
            // A few vertices (or, one round in ten, most) jump by up to 3 cm; the cloth folds.
            let share = if round % 10 == 9 { 0.6 } else { 0.05 };
            for p in x.iter_mut() {
                if rng.next_f64() < share {
                    *p += rng.vec3(0.03);
                }
            }
            let before = partial.stats;
            partial.refresh_escaped(&x0, &x, &inv_mass, TeamRef::serial());
            refreshed += partial.stats.refreshes - before.refreshes;
            fallbacks += partial.stats.broad_phases - before.broad_phases;
            full.broad_phase(&x0, &x, &inv_mass, TeamRef::serial());
            assert!(partial.candidates.windows(2).all(|w| w[0] < w[1]));
            let mut checked = 0;
            for (c, d) in full.candidates.iter().zip(&full.reach) {
                if !touching(&full, *c, &x0, &x) {
                    continue;
                }
                checked += 1;
                let at = partial.candidates.binary_search(c);
                let at = at.unwrap_or_else(|_| panic!("round {round}: {c:?} missing"));
                assert_eq!(
                    partial.reach[at].to_bits(),
                    d.to_bits(),
                    "round {round}: {c:?}"
                );
            }
            assert_eq!(partial.cand_ids.len(), partial.candidates.len());
            assert!(checked > 0, "round {round}: no pair can touch");
        }
        assert!(
            refreshed > 30 && fallbacks >= 3,
            "{refreshed} refreshes, {fallbacks} full"
        );
        let kinds: Vec<PairKind> = full.candidates.iter().map(|c| c.kind).collect();
        for kind in [PairKind::VertexFace, PairKind::EdgeEdge, PairKind::Collider] {
            assert!(
                kinds.contains(&kind),
                "no {kind:?} pair: the test would not test it"
            );
        }
    }

    /// The tight boxes a broad phase or a refresh takes from the particle boxes are, to the
    /// bit, the boxes of the primitives' own coordinates ([`CollisionGroup::vert_box`],
    /// [`CollisionGroup::edge_box`], [`CollisionGroup::face_box`]), with a shift and crumpled
    /// positions.
    #[test]
    fn tight_boxes_from_particle_boxes_are_the_primitives_own() {
        let (rest, edges, tris) = cloth(9);
        let [mut g, _] = groups(&rest, &edges, &tris);
        let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
        let mut rng = Rng(17);
        for round in 0..20 {
            let x: Vec<DVec3> = x0.iter().map(|&p| p + rng.vec3(0.05)).collect();
            g.shift = if round % 2 == 0 {
                DVec3::ZERO
            } else {
                rng.vec3(0.02)
            };
            g.fill_particle_boxes(&x0, &x);
            let bits = |b: Aabb| {
                (
                    b.min.to_array().map(f64::to_bits),
                    b.max.to_array().map(f64::to_bits),
                )
            };
            for i in 0..g.verts.len() {
                assert_eq!(bits(g.tight_box(0, i).0), bits(g.vert_box(i, &x0, &x)));
            }
            for i in 0..g.edges.len() {
                assert_eq!(bits(g.tight_box(1, i).0), bits(g.edge_box(i, &x0, &x)));
            }
            for i in 0..g.faces.len() {
                assert_eq!(bits(g.tight_box(2, i).0), bits(g.face_box(i, &x0, &x)));
            }
            assert!(!g.faces.is_empty() && !g.edges.is_empty());
        }
    }

    /// With every box of a substep shifted by the displacement its vertices share
    /// ([`CollisionGroup::shift`]), the broad phase still pairs every pair that comes within
    /// reach over the substep — every pair in which the narrow phase's continuous test finds
    /// a contact — over rounds of random crumpling carried by a common motion of up to 20 cm
    /// (ten times the contact distance), each a new substep with its own shift. The shifted
    /// lists are shorter than the unshifted ones (else the test would not test the shift).
    #[test]
    fn a_shifted_broad_phase_keeps_every_pair_that_comes_within_reach() {
        let (rest, edges, tris) = cloth(14);
        let [mut shifted, mut plain] = groups(&rest, &edges, &tris);
        let inv_mass = vec![1.0; rest.len()];
        let mut x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
        let mut rng = Rng(5);
        let team = TeamRef::serial();
        let (mut checked, mut fewer) = (0, 0);
        for round in 0..40 {
            let common = rng.vec3(0.2);
            let x: Vec<DVec3> = x0
                .iter()
                .map(|&p| {
                    let own = if rng.next_f64() < 0.3 {
                        rng.vec3(0.02)
                    } else {
                        DVec3::ZERO
                    };
                    p + common + own
                })
                .collect();
            // A substep long enough that no push-out limit applies.
            for g in [&mut shifted, &mut plain] {
                g.h = 1e3;
            }
            shifted.shift = shifted.shared_displacement(&x0, &x, &inv_mass);
            shifted.pose_colliders(0.0, 0.0);
            shifted.broad_phase(&x0, &x, &inv_mass, team);
            plain.broad_phase(&x0, &x, &inv_mass, team);
            for k in 0..plain.candidates.len() {
                if plain.detect(k, &x0, &x, 1.0, None).is_none() {
                    continue;
                }
                let (c, d) = (&plain.candidates[k], &plain.reach[k]);
                checked += 1;
                let at = shifted.candidates.binary_search(c);
                let at = at.unwrap_or_else(|_| panic!("round {round}: {c:?} missing"));
                assert_eq!(shifted.reach[at].to_bits(), d.to_bits());
            }
            fewer += usize::from(shifted.candidates.len() < plain.candidates.len());
            x0 = x;
        }
        assert!(checked > 100, "only {checked} pairs came within reach");
        assert!(fewer > 30, "the shift made {fewer} of 40 lists shorter");
    }

    /// A refresh within a substep keeps the separations of the pairs it keeps, with the motion
    /// since they were taken added ([`CollisionGroup::carry_separations`]): over rounds of
    /// random crumpling, each followed by a refresh and a pass, the contacts and positions are
    /// the bits of a group whose refreshes forget every separation, as before the carry. Fails
    /// if the motion since the old `x_ref` is left out of a carried certificate.
    #[test]
    fn separations_carried_over_a_refresh_give_the_contacts_of_forgotten_ones() {
        let (rest, edges, tris) = cloth(14);
        let [mut carried, mut forgotten] = groups(&rest, &edges, &tris);
        let inv_mass = vec![1.0; rest.len()];
        let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
        let (mut xa, mut xb) = (x0.clone(), x0.clone());
        let team = TeamRef::serial();
        for (g, x) in [(&mut carried, &xa), (&mut forgotten, &xb)] {
            g.broad_phase(&x0, x, &inv_mass, team);
        }
        carried.within_substep = true;
        let mut rng = Rng(11);
        let (mut carries, mut contacts) = (0, 0);
        for round in 0..80 {
            // A few vertices (one round in ten, most) move by up to 1.5 cm, as far as the
            // cloth's contact distance (2 cm): pairs come into contact after their separation
            // was taken.
            let share = if round % 10 == 9 { 0.6 } else { 0.08 };
            for k in 0..xa.len() {
                if rng.next_f64() < share {
                    let dx = rng.vec3(0.015);
                    xa[k] += dx;
                    xb[k] += dx;
                }
            }
            let kept = carried.separation.iter().filter(|s| !s.d0.is_nan()).count();
            let refreshed = carried.refresh_escaped(&x0, &xa, &inv_mass, team);
            forgotten.refresh_escaped(&x0, &xb, &inv_mass, team);
            if refreshed && kept > 0 {
                carries += carried.separation.iter().filter(|s| !s.d0.is_nan()).count();
            }
            carried.resolve_pass(&x0, &mut xa, &inv_mass, &mut [], team);
            forgotten.resolve_pass(&x0, &mut xb, &inv_mass, &mut [], team);
            assert_eq!(carried.candidates, forgotten.candidates, "round {round}");
            assert_eq!(
                carried.contacts.len(),
                forgotten.contacts.len(),
                "round {round}"
            );
            contacts += carried.contacts.len();
            for (k, (a, b)) in xa.iter().zip(&xb).enumerate() {
                assert_eq!(
                    a.to_array().map(f64::to_bits),
                    b.to_array().map(f64::to_bits),
                    "round {round}: particle {k}"
                );
            }
        }
        assert!(carries > 1000, "only {carries} separations carried over");
        assert!(
            contacts > 100,
            "only {contacts} contacts: nothing to get wrong"
        );
    }

    /// The kept starts ([`CollisionGroup::start_of`]) live in the sorted list's first and last
    /// runs: the vertex–collider pairs must sort before every other kind and the feature pairs
    /// after.
    #[test]
    fn collider_pairs_sort_first_and_feature_pairs_last() {
        use PairKind::*;
        let kinds = [
            Collider,
            VertexVertex,
            VertexEdge,
            VertexFace,
            EdgeEdge,
            FeatureFace,
            FeaturePointEdge,
            FeatureEdgeEdge,
        ];
        for a in kinds {
            for b in kinds {
                if a == Collider && b != Collider {
                    assert!(a < b, "{a:?} before {b:?}");
                }
                if a.is_feature() && !b.is_feature() {
                    assert!(a > b, "{a:?} after {b:?}");
                }
            }
        }
        let split = [2, 5];
        let slots: Vec<_> = (0..7).map(|k| start_slot(split, k)).collect();
        assert_eq!(
            slots,
            [Some(0), Some(1), None, None, None, Some(2), Some(3)]
        );
    }

    /// What the passes keep of a collider or feature pair's start (its distance from the
    /// collider or feature, and how it leaves) is what it would take afresh, after refreshes
    /// within the substep move the pairs to new places in the list: over rounds of random
    /// crumpling, every kept start is checked against one taken again, bit for bit.
    #[test]
    fn the_starts_kept_over_refreshes_are_those_taken_afresh() {
        let (rest, edges, tris) = cloth(14);
        let [mut g, _] = groups(&rest, &edges, &tris);
        let inv_mass = vec![1.0; rest.len()];
        let x0: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
        let mut x = x0.clone();
        let team = TeamRef::serial();
        g.h = 1e-2;
        g.broad_phase(&x0, &x, &inv_mass, team);
        g.within_substep = true;
        let mut rng = Rng(5);
        let (mut carried, mut checked) = (0, 0);
        for round in 0..40 {
            let share = if round % 10 == 9 { 0.6 } else { 0.08 };
            for p in x.iter_mut() {
                if rng.next_f64() < share {
                    *p += rng.vec3(0.015);
                }
            }
            if g.refresh_escaped(&x0, &x, &inv_mass, team) {
                carried += g.start.iter().filter(|s| !s.distance.is_nan()).count();
            }
            g.resolve_pass(&x0, &mut x, &inv_mass, &mut [], team);
            for k in 0..g.candidates.len() {
                let kind = g.candidates[k].kind;
                let Some(slot) = start_slot(g.start_split, k) else {
                    assert!(kind != PairKind::Collider && !kind.is_feature(), "{kind:?}");
                    continue;
                };
                assert!(kind == PairKind::Collider || kind.is_feature(), "{kind:?}");
                let kept = g.start[slot];
                if kept.distance.is_nan() {
                    continue;
                }
                g.start[slot] = StartOf::UNKNOWN;
                let fresh = g.start_of(k, &x0);
                assert_eq!(
                    (kept.distance.to_bits(), kept.leaves),
                    (fresh.distance.to_bits(), fresh.leaves),
                    "round {round}: candidate {k} ({kind:?})"
                );
                checked += 1;
            }
        }
        assert!(
            carried > 100,
            "only {carried} starts carried over a refresh"
        );
        assert!(checked > 1000, "only {checked} starts checked");
    }

    #[test]
    fn a_changed_mass_or_a_moved_collider_takes_a_full_broad_phase() {
        let (rest, edges, tris) = cloth(6);
        let [mut g, _] = groups(&rest, &edges, &tris);
        let mut inv_mass = vec![1.0; rest.len()];
        let x: Vec<DVec3> = rest.iter().map(|&p| DVec3::from(p)).collect();
        assert!(!g.colliders_and_masses_hold(&inv_mass), "nothing found yet");
        g.broad_phase(&x, &x, &inv_mass, TeamRef::serial());
        assert!(g.colliders_and_masses_hold(&inv_mass));
        inv_mass[3] = 0.0;
        assert!(!g.colliders_and_masses_hold(&inv_mass), "a pinned vertex");
        inv_mass[3] = 1.0;
        g.collider_boxes[0] = g.collider_boxes[0].grow(1e-3);
        assert!(
            !g.colliders_and_masses_hold(&inv_mass),
            "a collider left its box"
        );
    }
}
