//! The narrow phase: whether and when a candidate pair comes within its contact distance over
//! the substep, and the contact it then gets (`Pass::detect`).
//!
//! Vertex–face and edge–edge (and the colliders' features, on their rigid tracks): the
//! conservative continuous tests of [`ccd`] (no false negative), giving the earliest
//! `t ∈ [0, 1]` at which the pair comes within `d` — for every pair that moves farther over
//! the substep than it is apart, the only pairs that can pass through each other. A pair that
//! moves less than its start distance cannot cross: its end state decides, which spares the
//! bisection the grazing and resting contacts ([`pairs`], the prefilter). Particle–particle:
//! a quadratic in closed form ([`pairs::point_point_toi`]). Vertex–collider: the same question
//! against the collider's exact signed distance, in the collider's frame
//! ([`crate::colliders::shapes::first_contact`]). The closest points at `t` ([`distance`]) fix
//! the contact's weights and normal for the rest of the substep; a collider's feature is
//! folded into the contact's offset and its motion into the contact's collider displacement
//! ([`pairs::fold_kinematic`]), so friction and restitution see the motion relative to the
//! collider.
//!
//! A pass ([`pass`]) runs the test on every candidate and projects each new contact at once.

pub mod ccd;
pub mod distance;
pub mod pairs;
pub mod pass;

use glam::DVec3;

use crate::broad_phase::swept::SweptBoxes;
use crate::candidates::starts::Leaves;
use crate::candidates::{Candidate, Candidates};
use crate::colliders::shapes::first_contact;
use crate::colliders::Colliders;
use crate::primitives::Geometry;
use crate::response::contact::{Contact, PairKind};
use crate::response::push_out::push_out_reach;
use pairs::{Separation, Track};

/// Particle `i`'s track over the substep: from `x0` to `x`.
#[inline]
fn track(x0: &[DVec3], x: &[DVec3], i: u32) -> Track {
    Track {
        x0: x0[i as usize],
        x1: x[i as usize],
    }
}

/// The tracks over `[x0, x]` of a candidate's particles `ids`, written out (an array `map`
/// stayed an out-of-line call).
#[inline(always)]
pub(crate) fn tracks(ids: &[u32; 4], x0: &[DVec3], x: &[DVec3]) -> [Track; 4] {
    let [a, b, c, d] = *ids;
    [
        track(x0, x, a),
        track(x0, x, b),
        track(x0, x, c),
        track(x0, x, d),
    ]
}

/// A feature candidate's tracks over `[x0, x]` with the feature's in its slots (`ids` its
/// [`crate::candidates::candidate_ids`]), and the mesh kind whose test it takes.
#[inline]
pub(crate) fn feature_tracks(
    colliders: &Colliders,
    cand: Candidate,
    ids: &[u32; 4],
    x0: &[DVec3],
    x: &[DVec3],
) -> (PairKind, [Track; 4]) {
    let a = cand.pair[0] as usize;
    let mut tr = tracks(ids, x0, x);
    let kind = match cand.kind {
        PairKind::FeatureFace => {
            let [p0, p1] = colliders.feat_point_tracks[a];
            tr[0] = Track { x0: p0, x1: p1 };
            PairKind::VertexFace
        }
        PairKind::FeaturePointEdge => {
            let [p0, p1] = colliders.feat_point_tracks[a];
            tr[0] = Track { x0: p0, x1: p1 };
            tr[1] = tr[0];
            PairKind::VertexEdge
        }
        _ => {
            let [a0, b0, a1, b1] = colliders.feat_edge_tracks[a];
            tr[0] = Track { x0: a0, x1: a1 };
            tr[1] = Track { x0: b0, x1: b1 };
            PairKind::EdgeEdge
        }
    };
    (kind, tr)
}

/// What a pass over the candidates works with: the geometry, the swept boxes, the candidates
/// and the contacts of the substep.
pub(crate) struct Pass<'a> {
    pub geo: Geometry<'a>,
    pub boxes: &'a SweptBoxes,
    pub cands: &'a mut Candidates,
    pub contacts: &'a mut Vec<Contact>,
    /// How far (m) a primitive that starts the substep inside a collider may leave it by in
    /// this substep ([`push_out_reach`]).
    pub push: f64,
}

impl Pass<'_> {
    /// The contact of candidate `k` if the pair comes within `thickness_scale × reach` (its
    /// contact distance) over `[x0, x]` (`thickness_scale = 0`: the pair crosses; for a
    /// collider's feature, it crosses the collider's core). `known`: the pair's separation
    /// over these very positions, if just taken ([`Candidates::take_separation`]), so it is
    /// not taken twice.
    pub fn detect(
        &mut self,
        k: usize,
        x0: &[DVec3],
        x: &[DVec3],
        thickness_scale: f64,
        known: Option<Separation>,
    ) -> Option<Contact> {
        let (prims, colliders) = (self.geo.prims, self.geo.colliders);
        let (cand, reach) = (self.cands.list[k], self.cands.reach[k]);
        let track = |i: u32| track(x0, x, i);
        let mut d = thickness_scale * reach;
        let start = self.cands.start_of(k, self.geo, x0);
        if start.leaves != Leaves::Normally {
            // The final projections take it out across the feature or along the axis.
            return None;
        }
        if cand.kind.is_feature() && thickness_scale > 0.0 {
            d = push_out_reach(d, start.distance, self.push);
        }
        let [a, b] = cand.pair;
        match cand.kind {
            PairKind::VertexFace | PairKind::EdgeEdge | PairKind::VertexEdge => {
                let ids = self.cands.ids[k];
                let tr = tracks(&ids, x0, x);
                let s = known.or_else(|| pairs::separation(cand.kind, &tr))?;
                pairs::separated_contact(cand.kind, s, cand.pair, ids, &tr, d)
            }
            PairKind::VertexVertex => {
                let (p, q) = (prims.verts[a as usize], prims.verts[b as usize]);
                let ids = [p, q, p, p];
                pairs::vertex_vertex(cand.pair, ids, &ids.map(track), d)
            }
            PairKind::Collider => {
                let (c, v) = (a as usize, b as usize);
                let p = prims.verts[v] as usize;
                let col = &colliders.list[c];
                let (pose0, pose1) = (colliders.pose0[c], colliders.pose1[c]);
                let q0 = pose0.inverse_apply(x0[p]);
                let q1 = pose1.inverse_apply(x[p]);
                let d = if thickness_scale > 0.0 {
                    push_out_reach(d, start.distance, self.push)
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
                let ids = self.cands.ids[k];
                let (kind, tr) = feature_tracks(colliders, cand, &ids, x0, x);
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
}
