//! The fail-safe, the last step of a substep: the continuous test is run once more with zero
//! thickness on every candidate (for a collider's feature: reaching the collider's core — a
//! face crossing a box corner or a capsule's axis); while a pair still crosses, its dynamic
//! particles are *frozen*: put back at their start-of-substep position (a state free of
//! crossings), carried by the rigid motion of a fully kinematic object or an analytic
//! collider they hit (a moving collider pushes them along).
//!
//! Each round freezes at least one more particle or ends, so it terminates, and no simplex
//! ends the substep crossing another. A frozen particle's velocity becomes, through the
//! core's `v = (x − x0)/h`, zero or its carrier's: a local, perfectly inelastic "impact
//! zone". What the fail-safe cannot fix (a particle squeezed between two differently moving
//! colliders, or a deforming kinematic mesh sweeping into a frozen one) is counted as
//! `unresolved`. With importance 1 and a stack of contacts one pass cannot separate, the
//! fail-safe is what keeps the cloth whole
//! (`the_fail_safe_leaves_no_crossing_when_one_pass_per_substep_cannot_resolve_a_stack`).

use glam::DVec3;

use crate::colliders::Colliders;
use crate::narrow_phase::Pass;
use crate::primitives::{frame, Primitives};
use crate::response::contact::PairKind;

/// No carrier: the particle is not frozen.
const NOT_FROZEN: u32 = u32::MAX;
/// Carrier of a frozen vertex that stays where it started the substep.
const CARRY_STILL: u32 = u32::MAX - 1;
/// Carriers from this value on (below [`CARRY_STILL`]) are analytic colliders: `CARRY_COLLIDER
/// + c` carries a frozen vertex with collider `c`'s rigid motion. Below it: local objects.
const CARRY_COLLIDER: u32 = 1 << 30;

/// The particles the fail-safe froze this substep, and what carries each.
pub(crate) struct FailSafe {
    /// Fail-safe carrier of each particle ([`NOT_FROZEN`] if none).
    carrier: Vec<u32>,
    /// The particles frozen.
    frozen: Vec<u32>,
}

impl FailSafe {
    /// Nothing frozen, for a group of `n` particles.
    pub fn new(n: usize) -> Self {
        Self {
            carrier: vec![NOT_FROZEN; n],
            frozen: Vec::new(),
        }
    }

    /// Unfreezes every particle, for a new substep.
    pub fn begin(&mut self) {
        for &i in &self.frozen {
            self.carrier[i as usize] = NOT_FROZEN;
        }
        self.frozen.clear();
    }

    /// One round of the fail-safe over the candidates of `pass` (whose broad phase was just
    /// refreshed): every pair that crosses over `[x0, x]` freezes its dynamic particles not
    /// yet frozen. Returns the pairs found crossing and the particles frozen.
    pub fn round(
        &mut self,
        pass: &mut Pass<'_>,
        x0: &[DVec3],
        x: &mut [DVec3],
        inv_mass: &[f64],
    ) -> (usize, usize) {
        let (prims, colliders) = (pass.geo.prims, pass.geo.colliders);
        let (mut crossing, mut froze) = (0, 0);
        pass.cands.certs.update_moved(x);
        for k in 0..pass.cands.list.len() {
            let cand = pass.cands.list[k];
            if cand.kind == PairKind::Collider
                || pass.cands.skip(k, 0.0)
                || !pass.boxes.overlap(pass.geo, cand, x0, x)
            {
                continue;
            }
            let Some(c) = pass.detect(k, x0, x, 0.0, None) else {
                continue;
            };
            crossing += 1;
            let carrier = if cand.kind.is_feature() {
                CARRY_COLLIDER + colliders.feature_collider(cand)
            } else {
                c.ids
                    .iter()
                    .zip(&c.w)
                    .find(|(&i, &w)| w != 0.0 && inv_mass[i as usize] == 0.0)
                    .map(|(&i, _)| carrier_object(prims, i))
                    .unwrap_or(CARRY_STILL)
            };
            // Every particle of the two primitives is frozen (a vertex of a face with a zero
            // barycentric weight included); only the unused slots of the particle pairs
            // (weight 0) are skipped.
            let whole =
                matches!(c.kind, PairKind::VertexFace | PairKind::EdgeEdge) || c.kind.is_feature();
            for (&i, &w) in c.ids.iter().zip(&c.w) {
                let i = i as usize;
                if w == 0.0 && !whole {
                    continue;
                }
                if inv_mass[i] > 0.0 && self.carrier[i] == NOT_FROZEN {
                    self.carrier[i] = carrier;
                    self.frozen.push(i as u32);
                    x[i] = carried(prims, colliders, carrier, i, x0, x);
                    pass.cands.certs.note_moved(i, x);
                    froze += 1;
                }
            }
        }
        (crossing, froze)
    }
}

/// Where the fail-safe puts a frozen particle `p`: its start, carried by the rigid motion of
/// its carrier (a fully kinematic object, or an analytic collider) over the substep.
fn carried(
    prims: &Primitives,
    colliders: &Colliders,
    carrier: u32,
    p: usize,
    x0: &[DVec3],
    x: &[DVec3],
) -> DVec3 {
    if carrier == CARRY_STILL {
        return x0[p];
    }
    if carrier >= CARRY_COLLIDER {
        let c = (carrier - CARRY_COLLIDER) as usize;
        return colliders.pose1[c].apply(colliders.pose0[c].inverse_apply(x0[p]));
    }
    let Some([a, b, c]) = prims.rigid_frame[carrier as usize] else {
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

/// The local object of kinematic particle `p`, as a carrier ([`CARRY_STILL`] if the object
/// does not move rigidly).
fn carrier_object(prims: &Primitives, p: u32) -> u32 {
    // Primitives are grouped by object; vertices are sorted within each object.
    match prims.verts.iter().position(|&v| v == p) {
        Some(i) => {
            let o = prims.vert_obj[i];
            if prims.rigid_frame[o as usize].is_some() {
                o
            } else {
                CARRY_STILL
            }
        }
        None => CARRY_STILL,
    }
}
