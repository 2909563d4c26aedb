//! How a primitive that starts a substep inside an analytic collider leaves it
//! (`Leaves`): normally (back out the way it came, as a contact and the fail-safe allow),
//! through a box's feature, or along a capsule's axis.
//!
//! A box's corners and edges are its surface, so an edge or face can start a substep partly
//! inside the box with its vertices outside. A feature pair whose edge or face starts in the
//! box's interior, or whose closest point to the feature is inside it, has no contact and no
//! fail-safe test — both would hold it inside: the final projection pushes it out *through*
//! the feature (`Geometry::feature_side`).
//!
//! A capsule's axis can pass through a face whose vertices are all outside it: the face has
//! no direction out, and the way off is along the axis and over an end. For the substep, a
//! cloth whose face the axis pierces is *impaled* on that capsule (`find_impaled`), and
//! every one of its vertices, edges and faces that starts inside the capsule moves along the
//! axis instead of radially, towards the end nearer to where the axis meets it
//! (`push_off_axis`, `slide_off_axis`). Pushed radially, the vertices around the axis
//! would open a hole whose edges the cloth would have to stretch over.

use glam::DVec3;

use super::push_out::push_out_reach;
use crate::candidates::starts::{Leaves, StartOf};
use crate::candidates::{Candidate, Candidates};
use crate::colliders::shapes::{segment_enters_box, triangle_enters_box, Shape};
use crate::colliders::Colliders;
use crate::narrow_phase::distance;
use crate::primitives::{Geometry, Primitives, NO_FACE};
use crate::response::contact::PairKind;

/// Candidate `cand`'s primitive at the substep's start, with contact distance `reach`: for a
/// vertex–collider pair, the vertex's signed distance from the collider, and off the axis if
/// its object is impaled on it and it starts within its contact distance; for a feature pair,
/// its primitive's distance from the feature ([`Geometry::feature_distance`]) and how it
/// leaves ([`leaves_through_feature`]). `None` for the other kinds.
pub(crate) fn take_start(
    geo: Geometry<'_>,
    cand: Candidate,
    reach: f64,
    x0: &[DVec3],
) -> Option<StartOf> {
    let colliders = geo.colliders;
    if cand.kind == PairKind::Collider {
        let (c, v) = (cand.pair[0] as usize, cand.pair[1] as usize);
        let q0 = colliders.pose0[c].inverse_apply(x0[geo.prims.verts[v] as usize]);
        let distance = colliders.list[c].shape.signed_distance(q0).0;
        let leaves = if impaled_vertex(geo, c, v) && distance < reach {
            Leaves::OffAxis
        } else {
            Leaves::Normally
        };
        Some(StartOf { distance, leaves })
    } else if cand.kind.is_feature() {
        let c = colliders.feature_collider(cand) as usize;
        let distance = geo.feature_distance(cand, x0, colliders.pose0[c]);
        Some(StartOf {
            distance,
            leaves: leaves_through_feature(geo, cand, distance, reach, x0),
        })
    } else {
        None
    }
}

/// How a feature candidate, `start` (m, signed: [`Geometry::feature_side`]) from its feature
/// at the substep's start, leaves its collider: across the feature, so that a contact or
/// the fail-safe, which forbid that crossing, must leave it to the final projections
/// ([`crate::narrow_phase::Pass::project_features_out`]), when it is on the wrong side of a
/// box's corner or edge, or in the box ([`starts_in_box`]), or impaled on a capsule's axis
/// ([`starts_impaled`]) or sliding off it with an impaled object ([`slides_off_axis`]).
fn leaves_through_feature(
    geo: Geometry<'_>,
    cand: Candidate,
    start: f64,
    reach: f64,
    x0: &[DVec3],
) -> Leaves {
    if starts_impaled(geo, cand, x0) || slides_off_axis(geo, cand, start, reach) {
        Leaves::OffAxis
    } else if start < 0.0 || starts_in_box(geo, cand, x0) {
        Leaves::ThroughBox
    } else {
        Leaves::Normally
    }
}

/// Whether a feature candidate's primitive (its edge or face) starts the substep in the
/// interior of its collider, a box (at `x0` and the collider's start pose): a cloth
/// started through a box, whose way out crosses the box's edges and corners.
fn starts_in_box(geo: Geometry<'_>, cand: Candidate, x0: &[DVec3]) -> bool {
    let colliders = geo.colliders;
    let c = colliders.feature_collider(cand) as usize;
    let Shape::Box {
        center,
        half_extents,
        rotation,
    } = colliders.list[c].shape
    else {
        return false;
    };
    let pose0 = colliders.pose0[c];
    let local = |i: u32| rotation.inverse() * (pose0.inverse_apply(x0[i as usize]) - center);
    let b = cand.pair[1] as usize;
    match cand.kind {
        PairKind::FeatureFace => triangle_enters_box(geo.prims.faces[b].map(local), half_extents),
        _ => {
            let [p, q] = geo.prims.edges[b].map(local);
            segment_enters_box(p, q, half_extents)
        }
    }
}

/// Whether a feature candidate of a capsule starts the substep *impaled*: for its axis
/// and an edge, the axis through a face on the edge; for an end and a face, the axis
/// through the face (at `x0` and the collider's start pose). The way off is along the axis
/// ([`push_off_axis`]), across the axis and over the end, which a contact or the fail-safe
/// would forbid.
fn starts_impaled(geo: Geometry<'_>, cand: Candidate, x0: &[DVec3]) -> bool {
    let (prims, colliders) = (geo.prims, geo.colliders);
    let c = colliders.feature_collider(cand) as usize;
    if !matches!(colliders.list[c].shape, Shape::Capsule { .. }) {
        return false;
    }
    let (a, b) = (cand.pair[0] as usize, cand.pair[1] as usize);
    let pierces = |e: usize, f: u32| {
        // The axis at the start pose ([`Colliders::pose`]).
        let [p, q, _, _] = colliders.feat_edge_tracks[e];
        let t = prims.faces[f as usize].map(|i| x0[i as usize]);
        // Boxes apart (closed), no meeting: the exact test only where it can say yes.
        let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        p.min(q).cmple(hi).all()
            && lo.cmple(p.max(q)).all()
            && distance::segment_triangle_intersect(p, q, t)
    };
    match cand.kind {
        PairKind::FeatureEdgeEdge => prims.edge_faces[b]
            .iter()
            .any(|&f| f != NO_FACE && pierces(a, f)),
        PairKind::FeatureFace => colliders.point_edges[a]
            .iter()
            .any(|&e| pierces(e as usize, b as u32)),
        _ => false,
    }
}

/// Lists in `colliders.impaled` the (collider, local object) pairs with an object's face
/// impaled on a capsule's axis at the substep's start ([`starts_impaled`]), from the feature
/// pairs among the candidates: the vertices of that object inside the capsule slide off along
/// the axis with the impaled faces ([`impaled_vertex`]) instead of leaving it radially, which
/// would open a hole around the axis and stretch the cloth around it.
pub(crate) fn find_impaled(
    colliders: &mut Colliders,
    prims: &Primitives,
    cands: &Candidates,
    x0: &[DVec3],
) {
    let mut impaled = std::mem::take(&mut colliders.impaled);
    impaled.clear();
    let geo = Geometry {
        prims,
        colliders: &*colliders,
    };
    // The feature pairs come last.
    for k in cands.starts.first_feature()..cands.list.len() {
        let cand = cands.list[k];
        if cand.kind != PairKind::FeatureEdgeEdge || !starts_impaled(geo, cand, x0) {
            continue;
        }
        let pair = (
            colliders.feature_collider(cand),
            prims.edge_obj[cand.pair[1] as usize],
        );
        if !impaled.contains(&pair) && impaled.len() < impaled.capacity() {
            impaled.push(pair);
        }
    }
    colliders.impaled = impaled;
}

/// Whether a capsule feature candidate's primitive belongs to an object impaled on that
/// capsule this substep and starts inside it (its distance from the feature at the
/// substep's start, `start`, short of `reach`): it slides off along the axis
/// ([`push_off_axis`]) instead of leaving it radially.
fn slides_off_axis(geo: Geometry<'_>, cand: Candidate, start: f64, reach: f64) -> bool {
    let colliders = geo.colliders;
    if colliders.impaled.is_empty() || start.is_nan() || start >= reach {
        return false;
    }
    let b = cand.pair[1] as usize;
    let object = match cand.kind {
        PairKind::FeatureFace => geo.prims.face_obj[b],
        _ => geo.prims.edge_obj[b],
    };
    colliders
        .impaled
        .contains(&(colliders.feature_collider(cand), object))
}

/// Whether vertex primitive `v`'s object is impaled on collider `c` this substep.
fn impaled_vertex(geo: Geometry<'_>, c: usize, v: usize) -> bool {
    let impaled = &geo.colliders.impaled;
    !impaled.is_empty() && impaled.contains(&(c as u32, geo.prims.vert_obj[v]))
}

/// The way off capsule `c`'s axis for a point at parameter `s` along it (0 at its first
/// end, 1 at its second): the unit direction along the axis towards the nearer end, and
/// that end, at the collider's start and end poses (`None` if the collider is not a
/// capsule or its axis has no length).
pub(crate) fn axis_exit(colliders: &Colliders, c: usize, s: f64) -> Option<[DVec3; 4]> {
    let Shape::Capsule { a, b, .. } = colliders.list[c].shape else {
        return None;
    };
    let (from, to) = if s >= 0.5 { (a, b) } else { (b, a) };
    let dir = (to - from).normalize_or_zero();
    if dir == DVec3::ZERO {
        return None;
    }
    let (pose0, pose1) = (colliders.pose0[c], colliders.pose1[c]);
    Some([
        pose0.rotate(dir),
        pose0.apply(to),
        pose1.rotate(dir),
        pose1.apply(to),
    ])
}

/// The parameter along capsule `c`'s axis (0 at its first end, 1 at its second) of the
/// point of it nearest to `p`, at the collider's start pose (0 for a point, or not a
/// capsule).
pub(crate) fn axis_parameter(colliders: &Colliders, c: usize, p: DVec3) -> f64 {
    let Shape::Capsule { a, b, .. } = colliders.list[c].shape else {
        return 0.0;
    };
    let (a0, b0) = (colliders.pose0[c].apply(a), colliders.pose0[c].apply(b));
    distance::point_segment_closest(p, a0, b0).0
}

/// Moves particle `i` along an [`axis_exit`] until it is `reach` (m) beyond the end, by at
/// most the push-out distance `push` beyond where it started, the move recorded in `pushes`;
/// returns the move left before this one, relative to `reach`.
pub(crate) fn slide_off_axis(
    exit: [DVec3; 4],
    i: usize,
    reach: f64,
    push: f64,
    x0: &[DVec3],
    x: &mut [DVec3],
    pushes: &mut [DVec3],
) -> f64 {
    let [dir0, end0, dir1, end1] = exit;
    let start = dir0.dot(x0[i] - end0);
    let target = push_out_reach(reach, start, push);
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

/// Moves the particles of a cloth edge or face impaled on a capsule's axis (its face pierced
/// at the substep's start, [`starts_impaled`]) along the axis towards the end nearer to where
/// the axis meets it ([`slide_off_axis`]): the cloth slides off the capsule over its end.
/// Returns the largest move left, relative to `reach`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn push_off_axis(
    geo: Geometry<'_>,
    cand: Candidate,
    reach: f64,
    push: f64,
    x0: &[DVec3],
    x: &mut [DVec3],
    inv_mass: &[f64],
    pushes: &mut [DVec3],
) -> f64 {
    let colliders = geo.colliders;
    let c = colliders.feature_collider(cand) as usize;
    let b = cand.pair[1] as usize;
    let ids = match cand.kind {
        PairKind::FeatureFace => geo.prims.faces[b],
        _ => {
            let [p, q] = geo.prims.edges[b];
            [p, q, q]
        }
    };
    let centre = (x0[ids[0] as usize] + x0[ids[1] as usize] + x0[ids[2] as usize]) / 3.0;
    let Some(exit) = axis_exit(colliders, c, axis_parameter(colliders, c, centre)) else {
        return 0.0;
    };
    let mut worst: f64 = 0.0;
    for i in ids.map(|i| i as usize) {
        if inv_mass[i] > 0.0 {
            worst = worst.max(slide_off_axis(exit, i, reach, push, x0, x, pushes));
        }
    }
    worst
}
