//! Certificates: what proves a candidate pair apart, so that a pass skips it with the verdict
//! its full test would give.
//!
//! Most candidates of a cloth never touch. A pass tests a pair the first time in full,
//! keeping its start and end distances and relative motion ([`Separation`]); until the next
//! broad phase it skips the pair while that separation, less twice the most any of its
//! particles has moved since, still proves it apart ([`Separation::certainly_apart`]). The
//! motion is counted from the end positions the candidates were found at (`x_ref`), one
//! distance per particle, kept current through a pass.
//!
//! A collider's feature against a face or an edge keeps the separation of the mesh test it
//! runs on the feature's track, and a vertex against a plane or a sphere its signed distances
//! at the ends of its track and the track's length ([`pairs::collider_separation`]); the
//! final projections and the penetration statistic skip on them too
//! (`Candidates::certainly_beyond_reach`). The separations' distances are taken by
//! [`crate::narrow_phase::distance::segment_segment_distance_squared`] and
//! [`crate::narrow_phase::distance::point_triangle_distance_squared`], the robust ones' to
//! rounding.
//!
//! The first pass after the candidates were found takes the separations they lack ahead of
//! its visits, over the thread team (`Candidates::take_separations_ahead`); a refresh
//! within the substep carries the separations of the pairs it keeps
//! (`Candidates::adopt`).

use glam::DVec3;
use nucleus_sdk::team::{span, SharedArray, TeamRef};

use super::Candidates;
use crate::colliders::shapes::Shape;
use crate::narrow_phase::pairs::{self, Separation};
use crate::narrow_phase::{feature_tracks, tracks};
use crate::parallel::{claim_chunks, CHUNKS_PER_PART};
use crate::primitives::Geometry;
use crate::response::contact::PairKind;

/// The separation of each candidate and the motion since it was taken.
#[derive(Default)]
pub(crate) struct Certificates {
    /// The separation of each candidate, taken the first time a pass tests it
    /// ([`Separation::UNKNOWN`] before that, and always for the kinds without one:
    /// particle pairs, and vertices against a box or a capsule;
    /// [`Candidates::separation_at`]), and the most any of its particles had then moved from
    /// `x_ref`.
    pub separation: Vec<Separation>,
    pub separation_moved: Vec<f64>,
    /// Whether each candidate's separation was taken ahead of its visit, over the team
    /// ([`Candidates::take_separations_ahead`]): positions may have moved since, so a pass
    /// that finds it no proof takes it again before testing the pair.
    pub taken_ahead: Vec<bool>,
    /// Set when the candidates were found again or a substep started
    /// ([`Candidates::restart`]): the next pass takes the separations they lack ahead, over
    /// the team.
    pub unknown: bool,
    /// During the pass that took the separations ahead (`ahead_exact`): the particles its
    /// contacts have moved so far. A candidate none of whose particles moved still has
    /// exactly the separation taken ahead.
    pub touched: Vec<bool>,
    pub ahead_exact: bool,
    /// The end positions the last broad phase saw, and how far each particle has moved from
    /// them since (m), kept current through a pass.
    pub x_ref: Vec<DVec3>,
    pub moved: Vec<f64>,
}

impl Certificates {
    /// The certificates of a group of `n` particles.
    pub fn new(n: usize) -> Self {
        Self {
            x_ref: vec![DVec3::ZERO; n],
            moved: vec![0.0; n],
            ..Self::default()
        }
    }

    /// No separation known for any of `candidates` pairs; motion counted from `x`.
    pub fn restart(&mut self, x: &[DVec3], candidates: usize) {
        let n = self.x_ref.len();
        self.x_ref.copy_from_slice(&x[..n]);
        self.moved.fill(0.0);
        self.separation.clear();
        self.separation.resize(candidates, Separation::UNKNOWN);
        self.separation_moved.clear();
        self.separation_moved.resize(candidates, 0.0);
        self.taken_ahead.clear();
        self.taken_ahead.resize(candidates, false);
        self.unknown = true;
    }

    /// Starts the pass that takes the separations ahead: no particle touched yet.
    pub fn begin_ahead(&mut self) {
        self.touched.clear();
        self.touched.resize(self.x_ref.len(), false);
        self.ahead_exact = true;
    }

    /// `moved` for particle `i`, just moved outside a pass (the final projections).
    #[inline]
    pub fn note_moved(&mut self, i: usize, x: &[DVec3]) {
        self.moved[i] = (x[i] - self.x_ref[i]).length();
    }

    /// `moved` for every particle, from the current positions.
    pub fn update_moved(&mut self, x: &[DVec3]) {
        for ((m, &r), &p) in self.moved.iter_mut().zip(&self.x_ref).zip(x) {
            *m = (p - r).length();
        }
    }

    /// `moved` for the particles of one contact just projected.
    pub fn update_moved_of(&mut self, ids: &[u32; 4], x: &[DVec3]) {
        for &i in ids {
            let i = i as usize;
            self.note_moved(i, x);
            if self.ahead_exact {
                self.touched[i] = true;
            }
        }
    }
}

impl Candidates {
    /// The most any particle of candidate `k` has moved from `x_ref`.
    #[inline]
    pub fn candidate_moved(&self, k: usize) -> f64 {
        self.ids[k]
            .iter()
            .fold(0.0f64, |m, &i| m.max(self.certs.moved[i as usize]))
    }

    /// Whether candidate `k` is certainly apart at contact distance `d` now. Its separation
    /// was taken when its particles had moved at most `m0` from `x_ref`, and they have moved
    /// at most `m1` from it now, so at most `m0 + m1` since.
    #[inline]
    pub fn skip(&self, k: usize, d: f64) -> bool {
        let s = &self.certs.separation[k];
        !s.d0.is_nan()
            && s.certainly_apart(self.certs.separation_moved[k] + self.candidate_moved(k), d)
    }

    /// Whether vertex–collider or feature candidate `k` is certainly farther than its reach
    /// from the collider at the substep's end pose, now: its certificate ([`Self::skip`],
    /// with `moved` current), which bounds the signed distance for any collider but a box's
    /// features — a primitive inside a box is far from its corners and edges, so those are
    /// never skipped. What the final projections and the penetration statistic would find
    /// nothing to do for.
    #[inline]
    pub fn certainly_beyond_reach(&self, k: usize, geo: Geometry<'_>) -> bool {
        let cand = self.list[k];
        let colliders = geo.colliders;
        let boxed = cand.kind.is_feature()
            && matches!(
                colliders.list[colliders.feature_collider(cand) as usize].shape,
                Shape::Box { .. }
            );
        !boxed && self.skip(k, self.reach[k])
    }

    /// Candidate `k`'s separation over `[x0, x]`, for the kinds whose test it decides
    /// exactly: the mesh pairs with a prefilter ([`pairs::separation`]), a collider's feature
    /// against a face or an edge (the same tests on the feature's track over the substep),
    /// and a vertex against a plane or a sphere ([`pairs::collider_separation`]). `None` for
    /// the kinds without one.
    pub fn separation_at(
        &self,
        k: usize,
        geo: Geometry<'_>,
        x0: &[DVec3],
        x: &[DVec3],
    ) -> Option<Separation> {
        let cand = self.list[k];
        let a = cand.pair[0] as usize;
        let colliders = geo.colliders;
        match cand.kind {
            PairKind::VertexFace | PairKind::EdgeEdge | PairKind::VertexEdge => {
                pairs::separation(cand.kind, &tracks(&self.ids[k], x0, x))
            }
            PairKind::VertexVertex => None,
            PairKind::Collider => {
                let p = self.ids[k][0] as usize;
                let q0 = colliders.pose0[a].inverse_apply(x0[p]);
                let q1 = colliders.pose1[a].inverse_apply(x[p]);
                pairs::collider_separation(&colliders.list[a].shape, q0, q1)
            }
            PairKind::FeatureFace | PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
                let (kind, tr) = feature_tracks(colliders, cand, &self.ids[k], x0, x);
                pairs::separation(kind, &tr)
            }
        }
    }

    /// Takes and keeps candidate `k`'s separation over `[x0, x]` ([`Self::separation_at`];
    /// `None` for the kinds without one), the first time a pass tests it.
    #[inline]
    pub fn take_separation(
        &mut self,
        k: usize,
        geo: Geometry<'_>,
        x0: &[DVec3],
        x: &[DVec3],
    ) -> Option<Separation> {
        let s = self.separation_at(k, geo, x0, x)?;
        self.certs.separation[k] = s;
        self.certs.separation_moved[k] = self.candidate_moved(k);
        Some(s)
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
    pub fn take_separations_ahead(
        &mut self,
        geo: Geometry<'_>,
        x0: &[DVec3],
        x: &[DVec3],
        team: TeamRef<'_>,
    ) {
        let n = self.list.len();
        let parts = team.parts();
        let mut separation = std::mem::take(&mut self.certs.separation);
        let mut moved = std::mem::take(&mut self.certs.separation_moved);
        let mut ahead = std::mem::take(&mut self.certs.taken_ahead);
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
                    if let Some(s) = this.separation_at(k, geo, x0, x) {
                        sep[i] = s;
                        mov[i] = this.candidate_moved(k);
                        ahd[i] = true;
                    }
                }
            });
        }
        self.certs.separation = separation;
        self.certs.separation_moved = moved;
        self.certs.taken_ahead = ahead;
    }
}
