//! From a pair of primitives moving linearly over a substep to a [`Contact`]: the
//! continuous narrow phase ([`crate::ccd`]) gives the earliest time of impact `t` at which the
//! pair comes within the distance `d`; the closest points at `t` ([`crate::distance`]) give
//! the weights and the normal, which then stay fixed for the substep (the contact plane of
//! the impact).
//!
//! The normal is the direction between the closest points at `t`. When they coincide (zero
//! thickness, or a start already touching), it falls back, in turn, to the geometric normal
//! (the triangle's, or the cross product of the two edges) oriented by the pair's separation at
//! the start of the substep, to that separation itself, and to the reverse of the relative
//! motion — a direction that undoes the approach.

use glam::DVec3;

use crate::ccd;
use crate::contact::{Contact, PairKind};
use crate::distance;

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
    let sep = |f: &dyn Fn(&Track) -> DVec3| -> DVec3 {
        (0..4).map(|k| w[k] * f(&tracks[k])).sum()
    };
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

/// Vertex `p` against triangle `(a, b, c)`, kept `d` apart.
pub fn vertex_face(
    pair: [u32; 2],
    ids: [u32; 4],
    tr: &[Track; 4],
    d: f64,
) -> Option<Contact> {
    let t = ccd::point_triangle_toi(
        tr[0].x0, tr[1].x0, tr[2].x0, tr[3].x0, tr[0].x1, tr[1].x1, tr[2].x1, tr[3].x1, d,
    )?;
    let (p, a, b, c) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
    let (bary, _) = distance::point_triangle_closest(p, a, b, c);
    let w = [1.0, -bary[0], -bary[1], -bary[2]];
    let n = contact_normal(tr, &w, t, Some((b - a).cross(c - a)));
    Some(make(PairKind::VertexFace, pair, ids, w, n, d))
}

/// Edge `(a, b)` against edge `(c, d)`, kept `dist` apart.
pub fn edge_edge(pair: [u32; 2], ids: [u32; 4], tr: &[Track; 4], dist: f64) -> Option<Contact> {
    let t = ccd::edge_edge_toi(
        tr[0].x0, tr[1].x0, tr[2].x0, tr[3].x0, tr[0].x1, tr[1].x1, tr[2].x1, tr[3].x1, dist,
    )?;
    let (a, b, c, d) = (tr[0].at(t), tr[1].at(t), tr[2].at(t), tr[3].at(t));
    let (s, u, _) = distance::segment_segment_closest(a, b, c, d);
    let w = [1.0 - s, s, -(1.0 - u), -u];
    let n = contact_normal(tr, &w, t, Some((b - a).cross(d - c)));
    Some(make(PairKind::EdgeEdge, pair, ids, w, n, dist))
}

/// Particle `p` against the curve edge `(c, d)`, kept `dist` apart (an edge–edge test whose
/// first edge is a point).
pub fn vertex_edge(pair: [u32; 2], ids: [u32; 4], tr: &[Track; 4], dist: f64) -> Option<Contact> {
    let t = ccd::edge_edge_toi(
        tr[0].x0, tr[0].x0, tr[2].x0, tr[3].x0, tr[0].x1, tr[0].x1, tr[2].x1, tr[3].x1, dist,
    )?;
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

    #[test]
    fn point_point_toi_is_the_first_time_at_distance_d() {
        // Head-on at relative speed 2, 1 m apart, d = 0.2: contact after 0.8 m, t = 0.4.
        let t = point_point_toi(
            DVec3::ZERO,
            DVec3::X,
            DVec3::X,
            DVec3::ZERO,
            0.2,
        )
        .unwrap();
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
            point_point_toi(DVec3::ZERO, DVec3::X * 0.1, DVec3::ZERO, DVec3::X * 0.1, 0.2),
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
