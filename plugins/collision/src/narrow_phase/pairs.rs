//! From a pair of primitives moving linearly over a substep to a [`Contact`]: the
//! continuous narrow phase ([`crate::narrow_phase::ccd`]) gives the earliest time of impact `t` at which the
//! pair comes within the distance `d`; the closest points at `t` ([`crate::narrow_phase::distance`]) give
//! the weights and the normal, which then stay fixed for the substep (the contact plane of
//! the impact).
//!
//! Before the continuous test, cheap discrete checks settle most pairs (all exact
//! consequences of linear motion):
//!
//! * a pair already within `d` at the start (to within [`AT_START_SLACK`]) has its time of
//!   impact at `t = 0`;
//! * the separation `F(t, ·)` (the difference of the two closest points' parametrisations)
//!   moves by `t · ΔF` with `|ΔF| ≤ M`, `M` the largest relative displacement of a vertex of
//!   one side against a vertex of the other over the substep (`F` is a convex combination
//!   of those differences). So the distance `δ(t) ≥ max(δ(0) − tM, δ(1) − (1 − t)M) ≥
//!   (δ(0) + δ(1) − M)/2`, and a pair with `(δ(0) + δ(1) − M)/2 > d` never comes within `d`
//!   (with a relative guard of 1e-9 against rounding);
//! * a pair with `M < δ(0)` **cannot cross** within the substep (`δ(t) ≥ δ(0) − tM > 0`): no
//!   time of impact is needed to keep it on its side. If it ends within `d` it gets its
//!   contact at `t = 0` — the start's separating direction and closest points, a
//!   conservative time of impact taken from the last state known to be valid — and if it
//!   ends outside `d` it needs no correction (see `contact_time`). The continuous test runs
//!   only for the pairs that move farther than they are apart, the only ones that can
//!   tunnel.
//!
//! Resting and slowly sliding neighbours — most candidates of a draped or folded cloth —
//! end there instead of in the bisection of the continuous test (grazing contacts with
//! thickness are its slowest queries: hundreds of cells each).
//!
//! The normal is the direction between the closest points at `t`. When they coincide (zero
//! thickness, or a start already touching), it falls back, in turn, to the geometric normal
//! (the triangle's, or the cross product of the two edges) oriented by the pair's separation at
//! the start of the substep, to that separation itself, and to the reverse of the relative
//! motion — a direction that undoes the approach.

use glam::DVec3;

use crate::colliders::shapes::Shape;
use crate::narrow_phase::ccd;
use crate::narrow_phase::distance;
use crate::response::contact::{Contact, PairKind};

/// The continuous test's tuning: the default relative tolerance (1e-6 of the configuration's
/// size). For fast bodies the size includes the whole substep's sweep, so a looser tolerance
/// takes contact normals and weights off the true time of impact and lets a fast shard end
/// inside a sheet's thickness (`docs/decisions/collision_ccd_tolerance.md`).
pub const CCD_OPTIONS: ccd::CcdOptions = ccd::CcdOptions {
    tolerance: ccd::DEFAULT_TOLERANCE,
    max_boxes: ccd::DEFAULT_MAX_BOXES,
};

/// A pair this close to its target distance at the start of the substep (relative to it)
/// is taken as in contact at `t = 0`: a false positive of at most 0.1 % of the thickness,
/// which spares the continuous test the resting and sliding contacts, its slowest queries.
pub const AT_START_SLACK: f64 = 1e-3;

/// Below this length (m) a separation vector has no usable direction.
const MIN_DIRECTION: f64 = 1e-12;

fn unit(v: DVec3) -> Option<DVec3> {
    let l = v.length();
    (l > MIN_DIRECTION && l.is_finite()).then(|| v / l)
}

/// Positions of a particle at the start and the end of the substep.
#[derive(Clone, Copy, Debug)]
pub struct Track {
    /// Start (m).
    pub x0: DVec3,
    /// End (m).
    pub x1: DVec3,
}

impl Track {
    #[inline]
    fn at(&self, t: f64) -> DVec3 {
        self.x0 + (self.x1 - self.x0) * t
    }
}

/// The normal of a contact with weights `w` over `tracks` at time `t`; `geometric` is the
/// optional geometric normal at `t` (unoriented).
fn contact_normal(tracks: &[Track; 4], w: &[f64; 4], t: f64, geometric: Option<DVec3>) -> DVec3 {
    let sep = |f: &dyn Fn(&Track) -> DVec3| -> DVec3 { (0..4).map(|k| w[k] * f(&tracks[k])).sum() };
    let st = sep(&|tr| tr.at(t));
    if let Some(n) = unit(st) {
        return n;
    }
    let s0 = sep(&|tr| tr.x0);
    if let Some(g) = geometric.and_then(unit) {
        let side = g.dot(s0);
        if side != 0.0 {
            return if side > 0.0 { g } else { -g };
        }
    }
    if let Some(n) = unit(s0) {
        return n;
    }
    let motion = sep(&|tr| tr.x1) - s0;
    if let Some(n) = unit(-motion) {
        return n;
    }
    geometric.and_then(unit).unwrap_or(DVec3::Y)
}

fn make(kind: PairKind, pair: [u32; 2], ids: [u32; 4], w: [f64; 4], n: DVec3, d: f64) -> Contact {
    Contact {
        kind,
        pair,
        ids,
        w,
        n,
        offset: d,
        collider_disp: DVec3::ZERO,
        dn: 0.0,
    }
}

/// What the discrete checks say about a pair (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prefilter {
    /// Within `d` at the start: the time of impact is 0.
    AtStart,
    /// Provably never within `d` over the substep.
    Apart,
    /// Cannot come to distance 0 within the substep (`M < δ(0)`): the end state decides.
    CannotCross,
    /// Undecided: run the continuous test.
    Undecided,
}

/// The discrete checks from the start and end distances `d0`, `d1`, the bound `m` on the
/// motion of the separation, and the target distance `d`.
#[inline]
pub fn prefilter(d0: f64, d1: f64, m: f64, d: f64) -> Prefilter {
    if !(d0.is_finite() && d1.is_finite() && m.is_finite()) {
        return Prefilter::Undecided;
    }
    if d0 <= d * (1.0 + AT_START_SLACK) {
        return Prefilter::AtStart;
    }
    let guard = 1e-9 * (d + d0 + d1 + m);
    if 0.5 * (d0 + d1 - m) > d + guard {
        Prefilter::Apart
    } else if m + guard < d0 {
        Prefilter::CannotCross
    } else {
        Prefilter::Undecided
    }
}

/// What the prefilter of a pair reads: the distances `d0` at the start and `d1` at the end of
/// the substep, and the bound `m` on the motion of the separation (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Separation {
    /// Distance at the start (m).
    pub d0: f64,
    /// Distance at the end (m).
    pub d1: f64,
    /// Largest relative displacement of a particle of one primitive against one of the other.
    pub m: f64,
}

impl Separation {
    /// No certificate: [`certainly_apart`](Self::certainly_apart) is never true.
    pub const UNKNOWN: Self = Self {
        d0: f64::NAN,
        d1: f64::NAN,
        m: f64::NAN,
    };

    /// Whether the pair is certainly [`Prefilter::Apart`] for the contact distance `d` (so its
    /// test finds no contact), given that since the end positions this separation was taken
    /// at, no particle of the pair has moved more than `delta` (the start positions are the
    /// substep's and do not move). Each primitive then moves at most `delta`, so `d1` falls by
    /// at most `2 delta` and `m` grows by at most `2 delta`; the margin of `1e-6` of the
    /// values in play covers the rounding of the distances recomputed at the new positions.
    ///
    /// Lets a Gauss-Seidel pass skip, with the same result, the many pairs the broad phase
    /// finds that stay well apart (a flat 64 × 64 cloth has 27,000 edge pairs whose boxes
    /// overlap, none in contact), at the cost of one distance per particle instead of two
    /// exact distances per pair.
    #[inline]
    pub fn certainly_apart(&self, delta: f64, d: f64) -> bool {
        let Self { d0, d1, m } = *self;
        let tol = 1e-6 * (d + d0 + d1 + m + 4.0 * delta);
        // NaN fails every comparison: no certificate, no skip.
        d0 > d * (1.0 + AT_START_SLACK) + tol && 0.5 * (d0 + d1 - m) - 2.0 * delta > d + tol
    }
}

/// The separation of vertex `0` against triangle `(1, 2, 3)`.
pub fn vertex_face_separation(tr: &[Track; 4]) -> Separation {
    let d0 = distance::point_triangle_distance_squared(tr[0].x0, tr[1].x0, tr[2].x0, tr[3].x0);
    let d1 = distance::point_triangle_distance_squared(tr[0].x1, tr[1].x1, tr[2].x1, tr[3].x1);
    Separation {
        d0: d0.sqrt(),
        d1: d1.sqrt(),
        m: relative_motion(tr, &[0], &[1, 2, 3]),
    }
}

/// The separation of edge `(0, 1)` against edge `(2, 3)`.
pub fn edge_edge_separation(tr: &[Track; 4]) -> Separation {
    let d0 = distance::segment_segment_distance_squared(tr[0].x0, tr[1].x0, tr[2].x0, tr[3].x0);
    let d1 = distance::segment_segment_distance_squared(tr[0].x1, tr[1].x1, tr[2].x1, tr[3].x1);
    Separation {
        d0: d0.sqrt(),
        d1: d1.sqrt(),
        m: relative_motion(tr, &[0, 1], &[2, 3]),
    }
}

/// The separation of vertex `0` against the curve edge `(2, 3)`.
pub fn vertex_edge_separation(tr: &[Track; 4]) -> Separation {
    let (_, d0) = distance::point_segment_closest(tr[0].x0, tr[2].x0, tr[3].x0);
    let (_, d1) = distance::point_segment_closest(tr[0].x1, tr[2].x1, tr[3].x1);
    Separation {
        d0: d0.sqrt(),
        d1: d1.sqrt(),
        m: relative_motion(tr, &[0], &[2, 3]),
    }
}

/// The separation of a pair of a kind with a prefilter (vertex–face, edge–edge,
/// vertex–edge; tracks in the slots of [`vertex_face`], [`edge_edge`], [`vertex_edge`]), or
/// `None` for the other kinds.
pub fn separation(kind: PairKind, tr: &[Track; 4]) -> Option<Separation> {
    match kind {
        PairKind::VertexFace => Some(vertex_face_separation(tr)),
        PairKind::EdgeEdge => Some(edge_edge_separation(tr)),
        PairKind::VertexEdge => Some(vertex_edge_separation(tr)),
        _ => None,
    }
}

/// The separation of a vertex whose track runs from `q0` to `q1` in an analytic collider's
/// frame, against a plane or a sphere: `d0` and `d1` the signed distances at the ends and `m`
/// the track's length. The signed distance is 1-Lipschitz, so the track stays
/// `½ (d0 + d1 − m)` away, and the contact test of these two shapes is closed-form
/// ([`first_contact`](crate::colliders::shapes::first_contact)): a certificate proves what it finds.
/// `None` for the others, whose test advances conservatively and may report a grazing track
/// that stays apart as a hit, so that a pass tests them every time.
pub fn collider_separation(shape: &Shape, q0: DVec3, q1: DVec3) -> Option<Separation> {
    matches!(shape, Shape::Plane { .. } | Shape::Sphere { .. }).then(|| Separation {
        d0: shape.signed_distance(q0).0,
        d1: shape.signed_distance(q1).0,
        m: (q1 - q0).length(),
    })
}

/// The contact of a pair of a kind with a prefilter, from its separation `s` over the same
/// tracks (as [`separation`] gives it): what [`vertex_face`], [`edge_edge`] or
/// [`vertex_edge`] return, without taking the distances again. `None` for the other kinds.
pub fn separated_contact(
    kind: PairKind,
    s: Separation,
    pair: [u32; 2],
    ids: [u32; 4],
    tr: &[Track; 4],
    d: f64,
) -> Option<Contact> {
    match kind {
        PairKind::VertexFace => vertex_face_separated(s, pair, ids, tr, d),
        PairKind::EdgeEdge => edge_edge_separated(s, pair, ids, tr, d),
        PairKind::VertexEdge => vertex_edge_separated(s, pair, ids, tr, d),
        _ => None,
    }
}

/// The largest `|Δxᵢ − Δxⱼ|` over `i` in `first`, `j` in `second` (the tracks' displacements).
#[inline]
fn relative_motion(tr: &[Track; 4], first: &[usize], second: &[usize]) -> f64 {
    let mut m: f64 = 0.0;
    for &i in first {
        for &j in second {
            let u = (tr[i].x1 - tr[i].x0) - (tr[j].x1 - tr[j].x0);
            m = m.max(u.length());
        }
    }
    m
}

/// The time at which a pair gets its contact, from its separation `s` (the prefilter's verdict
/// and the distance at the end), the contact distance `d` and the continuous test `ccd()` (the
/// earliest time within `d`, or `None`).
///
/// Only a pair that can cross needs a time of impact. A pair that cannot (it moves less than
/// it is apart) and ends within `d` gets its contact at `t = 0`: the start's separating
/// direction and closest points — a conservative time of impact, and the last state known to
/// be valid (the end may be corrupted by another pair's crossing: a particle that went
/// through one triangle ends below its neighbours too, and a normal taken there points
/// sideways). A pair that cannot cross and ends outside `d` needs no correction.
fn contact_time(s: Separation, d: f64, ccd: impl FnOnce() -> Option<f64>) -> Option<f64> {
    match prefilter(s.d0, s.d1, s.m, d) {
        Prefilter::AtStart => Some(0.0),
        Prefilter::Apart => None,
        Prefilter::CannotCross => (s.d1 <= d).then_some(0.0),
        Prefilter::Undecided => ccd(),
    }
}

/// Vertex `p` against triangle `(a, b, c)`, kept `d` apart.
pub fn vertex_face(pair: [u32; 2], ids: [u32; 4], tr: &[Track; 4], d: f64) -> Option<Contact> {
    vertex_face_separated(vertex_face_separation(tr), pair, ids, tr, d)
}

/// [`vertex_face`] from the pair's separation `s` over the same tracks.
fn vertex_face_separated(
    s: Separation,
    pair: [u32; 2],
    ids: [u32; 4],
    tr: &[Track; 4],
    d: f64,
) -> Option<Contact> {
    let t = contact_time(s, d, || {
        ccd::point_triangle_ccd(
            [tr[0].x0, tr[1].x0, tr[2].x0, tr[3].x0],
            [tr[0].x1, tr[1].x1, tr[2].x1, tr[3].x1],
            d,
            &CCD_OPTIONS,
        )
        .toi
    })?;
    let (p, a, b, c) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
    let (bary, _) = distance::point_triangle_closest(p, a, b, c);
    let w = [1.0, -bary[0], -bary[1], -bary[2]];
    let n = contact_normal(tr, &w, t, Some((b - a).cross(c - a)));
    Some(make(PairKind::VertexFace, pair, ids, w, n, d))
}

/// Edge `(a, b)` against edge `(c, d)`, kept `dist` apart.
pub fn edge_edge(pair: [u32; 2], ids: [u32; 4], tr: &[Track; 4], dist: f64) -> Option<Contact> {
    edge_edge_separated(edge_edge_separation(tr), pair, ids, tr, dist)
}

/// [`edge_edge`] from the pair's separation `s` over the same tracks.
fn edge_edge_separated(
    s: Separation,
    pair: [u32; 2],
    ids: [u32; 4],
    tr: &[Track; 4],
    dist: f64,
) -> Option<Contact> {
    let t = contact_time(s, dist, || {
        ccd::edge_edge_ccd(
            [tr[0].x0, tr[1].x0, tr[2].x0, tr[3].x0],
            [tr[0].x1, tr[1].x1, tr[2].x1, tr[3].x1],
            dist,
            &CCD_OPTIONS,
        )
        .toi
    })?;
    let (a, b, c, d) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
    let (s, u, _) = distance::segment_segment_closest(a, b, c, d);
    let w = [1.0 - s, s, -(1.0 - u), -u];
    let n = contact_normal(tr, &w, t, Some((b - a).cross(d - c)));
    Some(make(PairKind::EdgeEdge, pair, ids, w, n, dist))
}

/// Particle `p` against the curve edge `(c, d)`, kept `dist` apart (an edge–edge test whose
/// first edge is a point).
pub fn vertex_edge(pair: [u32; 2], ids: [u32; 4], tr: &[Track; 4], dist: f64) -> Option<Contact> {
    vertex_edge_separated(vertex_edge_separation(tr), pair, ids, tr, dist)
}

/// [`vertex_edge`] from the pair's separation `s` over the same tracks.
fn vertex_edge_separated(
    s: Separation,
    pair: [u32; 2],
    ids: [u32; 4],
    tr: &[Track; 4],
    dist: f64,
) -> Option<Contact> {
    let t = contact_time(s, dist, || {
        ccd::edge_edge_ccd(
            [tr[0].x0, tr[0].x0, tr[2].x0, tr[3].x0],
            [tr[0].x1, tr[0].x1, tr[2].x1, tr[3].x1],
            dist,
            &CCD_OPTIONS,
        )
        .toi
    })?;
    let (p, c, d) = (tr[0].at(t), tr[2].at(t), tr[3].at(t));
    let u = closest_on_segment(p, c, d);
    let w = [1.0, 0.0, -(1.0 - u), -u];
    let n = contact_normal(tr, &w, t, None);
    Some(make(PairKind::VertexEdge, pair, ids, w, n, dist))
}

/// Two particles kept `d` apart.
pub fn vertex_vertex(pair: [u32; 2], ids: [u32; 4], tr: &[Track; 4], d: f64) -> Option<Contact> {
    let t = point_point_toi(tr[0].x0, tr[1].x0, tr[0].x1, tr[1].x1, d)?;
    let w = [1.0, -1.0, 0.0, 0.0];
    let n = contact_normal(tr, &w, t, None);
    Some(make(PairKind::VertexVertex, pair, ids, w, n, d))
}

/// Turns the slots `slots` of a contact found on `tracks` into a moving *kinematic point* that
/// is not a particle (a sharp feature of an analytic collider): their share of the separation
/// at the end of the substep goes into the offset, their displacement into
/// [`Contact::collider_disp`] (so friction and restitution see the motion relative to the
/// collider), and their weights become 0, so the projection moves only the particles. With
/// `s = Σ_real wₖ xₖ` and the folded part `k = Σ_slots wₖ pₖ(end)`, `n·(s + k) − d ≥ 0` is
/// `n·s − (d − n·k) ≥ 0`.
pub fn fold_kinematic(c: &mut Contact, slots: &[usize], tracks: &[Track; 4]) {
    let (mut start, mut end) = (DVec3::ZERO, DVec3::ZERO);
    for &k in slots {
        start += c.w[k] * tracks[k].x0;
        end += c.w[k] * tracks[k].x1;
        c.w[k] = 0.0;
    }
    c.offset -= c.n.dot(end);
    c.collider_disp = start - end;
}

/// The parameter `u ∈ [0, 1]` of the point of segment `c–d` closest to `p`.
pub fn closest_on_segment(p: DVec3, c: DVec3, d: DVec3) -> f64 {
    let cd = d - c;
    let l2 = cd.length_squared();
    if l2 > 0.0 {
        ((p - c).dot(cd) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The earliest `t ∈ [0, 1]` at which two linearly moving points come within `d`:
/// `|r0 + t (r1 − r0)| = d` with `r = p − q`, the smaller root of a quadratic (exact; `t = 0`
/// if they start within `d`).
pub fn point_point_toi(p0: DVec3, q0: DVec3, p1: DVec3, q1: DVec3, d: f64) -> Option<f64> {
    let r0 = p0 - q0;
    let dr = (p1 - q1) - r0;
    let c = r0.length_squared() - d * d;
    if c <= 0.0 {
        return Some(0.0);
    }
    let a = dr.length_squared();
    let b = r0.dot(dr);
    if a == 0.0 || b >= 0.0 {
        return None;
    }
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let t = c / (-b + disc.sqrt());
    (t <= 1.0).then_some(t.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    use nucleus_sdk::testing::Rng;

    type Test = fn([u32; 2], [u32; 4], &[Track; 4], f64) -> Option<Contact>;
    type Sep = fn(&[Track; 4]) -> Separation;

    #[test]
    fn a_pair_certainly_apart_finds_no_contact_after_moves_within_the_bound() {
        // Random pairs at random distances; the end positions then move by at most `delta`
        // each. Whenever the certificate says apart, the full test must find no contact; and
        // it must say apart often enough to be worth having.
        let kinds: [(&str, Test, Sep); 3] = [
            ("vertex-face", vertex_face, vertex_face_separation),
            ("edge-edge", edge_edge, edge_edge_separation),
            ("vertex-edge", vertex_edge, vertex_edge_separation),
        ];
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for (name, test, separation) in kinds {
            let (mut skipped, mut tried) = (0, 0);
            for _ in 0..20_000 {
                let d = 0.01 * (1.0 + rng.range(-1.0, 1.0));
                let start: [DVec3; 4] = std::array::from_fn(|_| rng.vec3(0.05));
                let end: [DVec3; 4] = std::array::from_fn(|k| start[k] + rng.vec3(0.01));
                let tracks = |e: &[DVec3; 4]| -> [Track; 4] {
                    std::array::from_fn(|k| Track {
                        x0: start[k],
                        x1: e[k],
                    })
                };
                let s = separation(&tracks(&end));
                let delta = 0.005 * (1.0 + rng.range(-1.0, 1.0));
                if !s.certainly_apart(delta, d) {
                    continue;
                }
                skipped += 1;
                for _ in 0..4 {
                    let moved: [DVec3; 4] = std::array::from_fn(|k| end[k] + rng.in_ball(delta));
                    tried += 1;
                    assert!(
                        test([0, 1], [0, 1, 2, 3], &tracks(&moved), d).is_none(),
                        "{name}: certainly apart ({s:?}, delta {delta}, d {d}) but in contact"
                    );
                }
            }
            assert!(
                skipped > 2_000,
                "{name}: only {skipped} of 20,000 pairs certified"
            );
            assert!(tried >= 4 * skipped);
        }
    }

    #[test]
    fn a_vertex_certainly_off_a_plane_or_a_sphere_meets_neither_after_moves_within_the_bound() {
        use crate::colliders::shapes::first_contact;
        let shapes = [
            Shape::Plane {
                point: DVec3::new(0.0, -0.02, 0.0),
                normal: DVec3::new(0.6, 0.8, 0.0),
            },
            Shape::Sphere {
                center: DVec3::new(0.01, 0.0, -0.01),
                radius: 0.03,
            },
        ];
        let mut rng = Rng(0x51_7cc1_b727_220a);
        for shape in &shapes {
            let (mut skipped, mut tried, mut hits) = (0, 0, 0);
            for _ in 0..20_000 {
                let d = 0.01 * (1.0 + rng.range(-1.0, 1.0));
                let q0 = rng.vec3(0.08);
                let q1 = q0 + rng.vec3(0.03);
                hits += usize::from(first_contact(shape, q0, q1, d).is_some());
                let s = collider_separation(shape, q0, q1).unwrap();
                let delta = 0.005 * (1.0 + rng.range(-1.0, 1.0));
                if !s.certainly_apart(delta, d) {
                    continue;
                }
                skipped += 1;
                for _ in 0..4 {
                    let moved = q1 + rng.in_ball(delta);
                    tried += 1;
                    assert!(
                        first_contact(shape, q0, moved, d).is_none(),
                        "{shape:?}: certainly apart ({s:?}, delta {delta}, d {d}) but in contact"
                    );
                }
            }
            // Not vacuous: many tracks certified, many others in contact.
            assert!(
                skipped > 2_000 && hits > 2_000,
                "{shape:?}: {skipped} / {hits}"
            );
            assert!(tried >= 4 * skipped);
        }
        // A box or a capsule gets none: its test may report a grazing track as a hit.
        let capsule = Shape::Capsule {
            a: DVec3::ZERO,
            b: DVec3::X,
            radius: 0.1,
        };
        assert!(collider_separation(&capsule, DVec3::Y, DVec3::Z).is_none());
    }

    #[test]
    fn no_certificate_for_a_pair_at_contact_distance_or_an_unknown_one() {
        // Within d(1 + slack) at the start: the test takes it as a contact at t = 0.
        let at_start = Separation {
            d0: 0.01,
            d1: 1.0,
            m: 0.0,
        };
        assert!(!at_start.certainly_apart(0.0, 0.01));
        // Far at both ends but moving more than the gap: no verdict from the bound.
        let crossing = Separation {
            d0: 0.1,
            d1: 0.1,
            m: 0.25,
        };
        assert!(!crossing.certainly_apart(0.0, 0.01));
        // Apart, until the particles may have moved half the gap.
        let apart = Separation {
            d0: 0.1,
            d1: 0.1,
            m: 0.0,
        };
        assert!(apart.certainly_apart(0.0, 0.01));
        assert!(apart.certainly_apart(0.04, 0.01));
        assert!(!apart.certainly_apart(0.046, 0.01));
        assert!(!Separation::UNKNOWN.certainly_apart(0.0, 0.0));
    }

    #[test]
    fn point_point_toi_is_the_first_time_at_distance_d() {
        // Head-on at relative speed 2, 1 m apart, d = 0.2: contact after 0.8 m, t = 0.4.
        let t = point_point_toi(DVec3::ZERO, DVec3::X, DVec3::X, DVec3::ZERO, 0.2).unwrap();
        assert!((t - 0.4).abs() < 1e-15);
        // Passing by at 0.3: never within 0.2.
        assert_eq!(
            point_point_toi(
                DVec3::new(-1.0, 0.3, 0.0),
                DVec3::ZERO,
                DVec3::new(1.0, 0.3, 0.0),
                DVec3::ZERO,
                0.2
            ),
            None
        );
        // Already within d.
        assert_eq!(
            point_point_toi(
                DVec3::ZERO,
                DVec3::X * 0.1,
                DVec3::ZERO,
                DVec3::X * 0.1,
                0.2
            ),
            Some(0.0)
        );
        // A bullet through the other point within one step is caught.
        assert!(point_point_toi(
            DVec3::new(-100.0, 0.0, 0.0),
            DVec3::ZERO,
            DVec3::new(100.0, 0.0, 0.0),
            DVec3::ZERO,
            0.01
        )
        .is_some());
    }

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    fn random_tracks(seed: &mut u64, motion: f64) -> [Track; 4] {
        std::array::from_fn(|_| {
            let x0 = DVec3::new(lcg(seed), lcg(seed), lcg(seed));
            let u = DVec3::new(lcg(seed), lcg(seed), lcg(seed)) * motion;
            Track { x0, x1: x0 + u }
        })
    }

    /// A pair's distance as a function of time, its relative motion bound, and its contact.
    type Case<'a> = (&'a dyn Fn(f64) -> f64, f64, Option<Contact>);

    /// Whether a dense sampling sees point `tr[0]` pass through the plane of triangle
    /// `tr[1..]` within it (a crossing, found independently of the continuous test).
    fn sampled_crossing(tr: &[Track; 4]) -> bool {
        // (side of the plane, whether the point's projection falls in the triangle)
        let side = |t: f64| {
            let (p, a, b, c) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
            let n = (b - a).cross(c - a);
            let h = n.dot(p - a);
            let foot = p - h / n.length_squared() * n;
            let (_, d2) = distance::point_triangle_closest(foot, a, b, c);
            (h > 0.0, d2 < 1e-24)
        };
        (0..400).any(|k| {
            let (s0, in0) = side(k as f64 / 400.0);
            let (s1, in1) = side((k + 1) as f64 / 400.0);
            s0 != s1 && in0 && in1
        })
    }

    /// Every pair that a dense sampling of the motion finds within `d` gets a contact if it
    /// can cross (it moves farther than it is apart, or starts in contact); one that cannot
    /// gets one exactly when it ends within `d`, taken at the start of the substep; and every
    /// crossing a sampling sees (a vertex through a face) gets a contact.
    #[test]
    fn prefilter_and_toi_never_miss_a_sampled_contact() {
        let mut seed = 21;
        let d = 0.05;
        let (mut contacts, mut continuous, mut at_start, mut crossings) = (0, 0, 0, 0);
        for k in 0..4500 {
            // Large motions, and small ones in a configuration of about the thickness's size
            // (most of those cannot cross).
            let mut tr = random_tracks(&mut seed, [0.3, 1.5, 0.3][k % 3]);
            if k % 3 == 2 {
                for t in &mut tr {
                    t.x0 *= 0.12;
                    t.x1 *= 0.12;
                }
            }
            let vf = vertex_face([0, 0], [0, 1, 2, 3], &tr, d);
            if sampled_crossing(&tr) {
                crossings += 1;
                assert!(vf.is_some(), "missed a crossing");
            }
            let vf_dist = |t: f64| {
                let (p, a, b, c) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
                distance::point_triangle_closest(p, a, b, c).1.sqrt()
            };
            let ee_dist = |t: f64| {
                let (a, b, c, e) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
                distance::segment_segment_closest(a, b, c, e).2.sqrt()
            };
            let cases: [Case; 2] = [
                (&vf_dist, relative_motion(&tr, &[0], &[1, 2, 3]), vf),
                (
                    &ee_dist,
                    relative_motion(&tr, &[0, 1], &[2, 3]),
                    edge_edge([0, 0], [0, 1, 2, 3], &tr, d),
                ),
            ];
            for (dist, m, contact) in cases {
                let first = (0..=400).map(|s| s as f64 / 400.0).find(|&t| dist(t) <= d);
                let Some(first) = first else { continue };
                contacts += 1;
                let starts_in = dist(0.0) <= d * (1.0 + AT_START_SLACK);
                if m < dist(0.0) && !starts_in {
                    // Cannot cross: a contact exactly when it ends within `d`, taken at the
                    // start (where its constraint holds).
                    assert_eq!(contact.is_some(), dist(1.0) <= d);
                    if let Some(c) = contact {
                        let x: Vec<DVec3> = tr.iter().map(|t| t.x0).collect();
                        assert!(c.value(&x) >= -1e-12);
                        at_start += 1;
                    }
                    continue;
                }
                let c = contact.unwrap_or_else(|| panic!("missed a contact at t = {first}"));
                assert!(c.n.is_finite() && (c.n.length() - 1.0).abs() < 1e-12);
                continuous += 1;
            }
        }
        assert!(
            contacts > 300 && continuous > 50 && at_start > 10 && crossings > 20,
            "too few cases: {contacts} contacts, {continuous} continuous, {at_start} taken at \
             the start, {crossings} crossings"
        );
    }

    /// A pair that cannot cross and ends within `d` gets its contact with the start's
    /// direction and closest points: projecting it at the end restores the distance exactly.
    #[test]
    fn a_pair_that_cannot_cross_gets_its_contact_from_the_start() {
        let still = |p: DVec3| Track { x0: p, x1: p };
        // A vertex 3 cm above a face, coming down 2.5 cm: it cannot cross, ends 5 mm above.
        let tr = [
            Track {
                x0: DVec3::new(0.2, 0.03, 0.2),
                x1: DVec3::new(0.2, 0.005, 0.2),
            },
            still(DVec3::ZERO),
            still(DVec3::new(1.0, 0.0, 0.0)),
            still(DVec3::new(0.0, 0.0, 1.0)),
        ];
        assert_eq!(prefilter(0.03, 0.005, 0.025, 0.01), Prefilter::CannotCross);
        let mut c = vertex_face([0, 0], [0, 1, 2, 3], &tr, 0.01).expect("a contact");
        assert!((c.n - DVec3::Y).length() < 1e-12, "{}", c.n);
        let mut x: Vec<DVec3> = tr.iter().map(|t| t.x1).collect();
        c.project(&mut x, &[1.0, 0.0, 0.0, 0.0]);
        assert!((x[0].y - 0.01).abs() < 1e-15, "{}", x[0]);
        // Ending 2 cm above: nothing to correct.
        let mut far = tr;
        far[0].x1.y = 0.02;
        assert!(vertex_face([0, 0], [0, 1, 2, 3], &far, 0.01).is_none());
        // Coming down at a slant past the face's edge: the contact has the start's
        // direction (straight up from the face below the start), not the end's (sideways).
        let mut slant = tr;
        slant[0] = Track {
            x0: DVec3::new(0.008, 0.032, 0.2),
            x1: DVec3::new(-0.004, 0.006, 0.2),
        };
        assert!(relative_motion(&slant, &[0], &[1, 2, 3]) < 0.032);
        let c = vertex_face([0, 0], [0, 1, 2, 3], &slant, 0.01).expect("a contact");
        assert!((c.n - DVec3::Y).length() < 1e-12, "{}", c.n);
    }

    #[test]
    fn prefilter_decides_only_what_it_can_prove() {
        assert_eq!(prefilter(0.01, 5.0, 9.0, 0.02), Prefilter::AtStart);
        // 1 m apart at both ends, moving 0.5 m relative: at least 0.75 m apart throughout.
        assert_eq!(prefilter(1.0, 1.0, 0.5, 0.7), Prefilter::Apart);
        assert_eq!(prefilter(1.0, 1.0, 0.5, 0.76), Prefilter::CannotCross);
        assert_eq!(prefilter(1.0, 0.1, 1.5, 0.2), Prefilter::Undecided);
        assert_eq!(prefilter(f64::NAN, 1.0, 0.5, 0.1), Prefilter::Undecided);
    }

    #[test]
    fn coincident_tracks_get_a_finite_unit_normal() {
        let tr = [Track {
            x0: DVec3::ONE,
            x1: DVec3::ONE,
        }; 4];
        let n = contact_normal(&tr, &[1.0, -1.0, 0.0, 0.0], 0.0, None);
        assert!((n.length() - 1.0).abs() < 1e-15);
        let c = vertex_vertex([0, 1], [0, 1, 0, 0], &tr, 0.01).unwrap();
        assert!(c.n.is_finite());
    }
}
