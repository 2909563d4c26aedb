//! The final projections out of the analytic colliders, and the push-out of what started
//! inside them.
//!
//! In the last pass of a substep, every face and edge near a collider's feature is pushed out
//! to its contact distance along the current separating direction
//! (`Pass::project_features_out`), then every vertex is projected out of the colliders by
//! their exact signed distance (`Pass::project_out_of_colliders`): no vertex ends inside
//! one. A primitive that *started* the substep deeper than its contact distance (a cloth
//! placed through a collider) is moved out by at most `push_out_speed · h` instead, here and
//! in the contacts (`push_out_reach`): it leaves over several substeps, its neighbours
//! carried along by the stretch constraints, instead of being thrown out in one jump that
//! tears the cloth. Once out, the outward speed the pushes gave it is taken off its velocity
//! (`without_push_velocity`): the push moves it and does not launch it.

use glam::DVec3;

use super::leaving::{axis_exit, axis_parameter, push_off_axis, slide_off_axis};
use super::Response;
use crate::candidates::starts::Leaves;
use crate::candidates::Candidate;
use crate::narrow_phase::Pass;
use crate::primitives::Geometry;
use crate::response::contact::PairKind;

/// Most sweeps of the final projection of faces and edges out of the colliders' features.
const FEATURE_SWEEPS: usize = 8;

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

/// The push-out a particle carries: the outward speed pushes gave it while it was inside an
/// analytic collider, taken off when it gets out ([`Response::drop_push_out_velocity`]).
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
    /// Whether the particle is in the list of pushed particles.
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

/// The push-out of every particle, and the particles that got one.
pub(crate) struct PushOuts {
    push: Vec<PushOut>,
    pushed: Vec<u32>,
}

impl PushOuts {
    /// None yet, for a group of `n` particles.
    pub fn new(n: usize) -> Self {
        Self {
            push: vec![PushOut::NONE; n],
            pushed: Vec::with_capacity(n),
        }
    }

    /// Notes that a primitive of particle `i` started the substep inside a collider, was
    /// given `speed` (m/s) by its push along `normal` (unit) there, and was still held back
    /// (`inside`).
    fn note(&mut self, i: usize, normal: DVec3, collider_speed: f64, speed: f64, inside: bool) {
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
}

impl Geometry<'_> {
    /// A vertex–collider candidate's collider, particle and contact distance (m), if it is one
    /// and its particle is dynamic.
    #[inline]
    fn dynamic_collider_pair(
        &self,
        cand: Candidate,
        inv_mass: &[f64],
    ) -> Option<(usize, usize, f64)> {
        if cand.kind != PairKind::Collider {
            return None;
        }
        let (c, v) = (cand.pair[0] as usize, cand.pair[1] as usize);
        let p = self.prims.verts[v] as usize;
        (inv_mass[p] != 0.0).then(|| {
            (
                c,
                p,
                self.prims.radius(self.prims.vert_obj[v]) + self.colliders.list[c].thickness,
            )
        })
    }
}

impl Pass<'_> {
    /// Pushes every vertex out of the analytic colliders (exact signed-distance projection at
    /// the end of the substep), its displacement recorded in `pushes`.
    pub fn project_out_of_colliders(
        &mut self,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
        pushes: &mut [DVec3],
    ) {
        let geo = self.geo;
        self.cands.certs.update_moved(x);
        for k in 0..self.cands.list.len() {
            let Some((c, p, r)) = geo.dynamic_collider_pair(self.cands.list[k], inv_mass) else {
                continue;
            };
            let start = self.cands.start_of(k, geo, x0);
            if start.leaves == Leaves::OffAxis {
                if let Some(exit) =
                    axis_exit(geo.colliders, c, axis_parameter(geo.colliders, c, x0[p]))
                {
                    slide_off_axis(exit, p, r, self.push, x0, x, pushes);
                    self.cands.certs.note_moved(p, x);
                }
                continue;
            }
            if self.cands.certainly_beyond_reach(k, geo) {
                continue;
            }
            let col = &geo.colliders.list[c];
            let pose = geo.colliders.pose1[c];
            let q = pose.inverse_apply(x[p]);
            let (phi, n) = col.shape.signed_distance(q);
            if phi >= r {
                continue;
            }
            let r = push_out_reach(r, start.distance, self.push);
            if phi < r {
                let to = pose.apply(q + (r - phi) * n);
                if !pushes.is_empty() {
                    pushes[p] += to - x[p];
                }
                x[p] = to;
                self.cands.certs.note_moved(p, x);
            }
        }
    }

    /// Pushes the faces and edges out of the analytic colliders to their contact distance at
    /// the end of the substep — the counterpart, for the colliders' features, of
    /// [`Self::project_out_of_colliders`]: a primitive closer than its reach to a feature
    /// (at the collider's end pose) moves along the *current* separating direction (through
    /// the feature, for a primitive on the wrong side of a box's corner or edge:
    /// [`Geometry::feature_side`]), each particle by its weight in the closest point and its
    /// inverse mass, so that the closest point moves out by exactly the deficit. A contact
    /// keeps the plane of its time of impact, which drifts when the cloth slides around a
    /// curved core; this does not. A pair whose closest points coincide (no direction) is
    /// left to the fail-safe. Pushes that share particles undo each other a little, so the
    /// sweep is repeated (Gauss-Seidel, at most [`FEATURE_SWEEPS`] times) until no primitive
    /// is deeper than 1e-9 of its reach.
    pub fn project_features_out(
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
        let geo = self.geo;
        let mut worst: f64 = 0.0;
        self.cands.certs.update_moved(x);
        for k in 0..self.cands.list.len() {
            let cand = self.cands.list[k];
            if !cand.kind.is_feature() {
                continue;
            }
            let c = geo.colliders.feature_collider(cand) as usize;
            let start = self.cands.start_of(k, geo, x0);
            let reach = self.cands.reach[k];
            if start.leaves == Leaves::OffAxis {
                let left = push_off_axis(geo, cand, reach, self.push, x0, x, inv_mass, pushes);
                worst = worst.max(left);
                let ids = self.cands.ids[k];
                self.cands.certs.update_moved_of(&ids, x);
                continue;
            }
            if self.cands.certainly_beyond_reach(k, geo) {
                continue;
            }
            let side = geo.feature_side(cand, x, geo.colliders.pose1[c]);
            let (ids, w, out) = (side.ids, side.w, side.out());
            let dist = out.length();
            let signed = if side.inside { -dist } else { dist };
            if signed >= reach || dist < 1e-12 || !dist.is_finite() {
                continue;
            }
            let target = push_out_reach(reach, start.distance, self.push);
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
                    self.cands.certs.note_moved(i, x);
                }
            }
        }
        worst
    }
}

impl Response {
    /// Follows the push-out of every particle of a primitive that started the substep closer
    /// to an analytic collider (or its feature) than its contact distance, for
    /// [`Self::drop_push_out_velocity`]: the outward speed a push gave it this substep
    /// ([`push_speed`], shared among a face's or an edge's particles as the projection shares
    /// it) adds to what it carries, up to the push-out speed; the direction out and the
    /// collider's speed along it are those at the end of the substep. A particle is out once
    /// none of its primitives was held back by the push-out speed ([`push_out_reach`] gave
    /// its full contact distance); one none of whose primitives started inside is dropped.
    pub fn record_push_outs(
        &mut self,
        pass: &mut Pass<'_>,
        x0: &[DVec3],
        x: &[DVec3],
        inv_mass: &[f64],
    ) {
        let (push, h) = (self.push_out(), self.h);
        if h.is_nan() || h <= 0.0 {
            return;
        }
        let state = &mut self.push_outs;
        for &i in &state.pushed {
            let p = &mut state.push[i as usize];
            (p.given, p.seen, p.inside) = (0.0, false, false);
        }
        let geo = pass.geo;
        let colliders = geo.colliders;
        for k in 0..pass.cands.list.len() {
            let cand = pass.cands.list[k];
            if cand.kind == PairKind::Collider {
                let Some((c, p, r)) = geo.dynamic_collider_pair(cand, inv_mass) else {
                    continue;
                };
                let start = pass.cands.start_of(k, geo, x0);
                if start.leaves == Leaves::OffAxis || !short_of(start.distance, r) {
                    continue;
                }
                let start = start.distance;
                let col = &colliders.list[c];
                let (pose0, pose1) = (colliders.pose0[c], colliders.pose1[c]);
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
                state.note(
                    p,
                    normal,
                    collider_speed,
                    speed,
                    still_inside(end, target, r),
                );
            } else if cand.kind.is_feature() {
                let c = colliders.feature_collider(cand) as usize;
                let (pose0, pose1) = (colliders.pose0[c], colliders.pose1[c]);
                let start = pass.cands.start_of(k, geo, x0).distance;
                let reach = pass.cands.reach[k];
                if !short_of(start, reach) {
                    continue;
                }
                let side = geo.feature_side(cand, x, pose1);
                let (ids, w, q) = (side.ids, side.w, side.q);
                let dist = side.distance();
                if dist.is_nan() || dist.abs() <= 1e-12 || !dist.is_finite() {
                    continue;
                }
                let normal = side.out() / dist.abs();
                let collider_speed = normal.dot(q - pose0.apply(pose1.inverse_apply(q))) / h;
                let predicted = geo.feature_distance(cand, &self.x_pred, pose1);
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
                        state.note(
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
        let PushOuts { push, pushed } = state;
        pushed.retain(|&i| {
            let p = &mut push[i as usize];
            if !p.seen {
                *p = PushOut::NONE;
                return false;
            }
            p.speed = (p.speed + p.given).min(limit);
            true
        });
    }

    /// Takes the speed the push-out gave off the velocity of every particle that got out this
    /// substep ([`without_push_velocity`]): a cloth placed through a collider leaves it at
    /// `push_out_speed` and stops at its surface, instead of flying on at that speed.
    pub fn drop_push_out_velocity(&mut self, v: &mut [DVec3]) {
        let PushOuts { push, pushed } = &mut self.push_outs;
        pushed.retain(|&i| {
            let i = i as usize;
            if push[i].inside {
                return true;
            }
            v[i] = without_push_velocity(v[i], &push[i]);
            push[i] = PushOut::NONE;
            false
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
