//! What a collider or feature candidate's primitive was at the substep's start, taken once:
//! whether it started inside, how far, and how it leaves (`StartOf`). It depends only on
//! the substep's start, so each pair's answer is kept for the substep (and carried over a
//! refresh with the separations) instead of being taken again on every pass, in each sweep
//! of the final projections and for the push-out's record.
//!
//! Only the vertex–collider and feature pairs, the first and last runs of the sorted list,
//! have a slot (`start_slot`).

use glam::DVec3;

use super::{Candidate, Candidates};
use crate::primitives::Geometry;
use crate::response::contact::PairKind;
use crate::response::leaving;

/// How a collider or feature candidate's primitive leaves its collider in this substep, if
/// it started inside ([`Candidates::start_of`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Leaves {
    /// As a contact and the fail-safe allow: out of the collider the way it came, or not
    /// inside at all.
    Normally,
    /// Through a box's corner or edge, or out of the box's interior.
    ThroughBox,
    /// Off a capsule's axis, over its end, with an object impaled on it
    /// ([`leaving::push_off_axis`], [`leaving::slide_off_axis`]).
    OffAxis,
}

/// A collider or feature candidate's primitive at the substep's start, taken the first time
/// the substep needs it and kept until the next ([`Candidates::start_of`]): everything
/// in it depends only on `x0`, the collider's start pose, the candidate's reach and the
/// objects impaled this substep, so a pass, the final projections and the push-out's record
/// read it instead of taking it again.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StartOf {
    /// Its signed distance (m) from the collider or feature
    /// ([`crate::colliders::features::FeatureSide`], `Shape::signed_distance`); NaN until
    /// taken.
    pub distance: f64,
    /// How it leaves.
    pub leaves: Leaves,
}

impl StartOf {
    pub const UNKNOWN: StartOf = StartOf {
        distance: f64::NAN,
        leaves: Leaves::Normally,
    };
}

/// Where candidate `k`'s [`StartOf`] is kept, with the candidates split at
/// `[colliders, features]` (the vertex–collider pairs before the first, the feature pairs
/// from the second on: the order of [`PairKind`]); `None` for the pairs between, which have
/// none.
#[inline]
pub(crate) fn start_slot([colliders, features]: [usize; 2], k: usize) -> Option<usize> {
    if k < colliders {
        Some(k)
    } else if k >= features {
        Some(colliders + (k - features))
    } else {
        None
    }
}

/// The starts of the collider and feature candidates of the substep.
#[derive(Default)]
pub(crate) struct Starts {
    /// The starts ([`StartOf::UNKNOWN`] until taken), at their [`start_slot`].
    pub slots: Vec<StartOf>,
    /// Where the vertex–collider pairs end and the feature pairs begin in the list.
    pub split: [usize; 2],
}

impl Starts {
    /// No start taken for any of the candidates `list`.
    pub fn restart(&mut self, list: &[Candidate]) {
        let colliders = list.partition_point(|c| c.kind == PairKind::Collider);
        let features = list.partition_point(|c| !c.kind.is_feature());
        self.split = [colliders, features];
        self.slots.clear();
        self.slots
            .resize(colliders + (list.len() - features), StartOf::UNKNOWN);
    }

    /// Index of the first feature candidate.
    pub fn first_feature(&self) -> usize {
        self.split[1]
    }
}

impl Candidates {
    /// Candidate `k`'s primitive at the substep's start ([`StartOf`]), taken now if the
    /// substep has not yet ([`leaving::take_start`]); [`StartOf::UNKNOWN`] for the kinds
    /// without one. It must not be asked before the substep's impaled objects are found
    /// ([`leaving::find_impaled`]).
    #[inline]
    pub fn start_of(&mut self, k: usize, geo: Geometry<'_>, x0: &[DVec3]) -> StartOf {
        let Some(slot) = start_slot(self.starts.split, k) else {
            return StartOf::UNKNOWN;
        };
        let known = self.starts.slots[slot];
        if !known.distance.is_nan() {
            return known;
        }
        let Some(taken) = leaving::take_start(geo, self.list[k], self.reach[k], x0) else {
            return StartOf::UNKNOWN;
        };
        self.starts.slots[slot] = taken;
        taken
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kept starts ([`Candidates::start_of`]) live in the sorted list's first and last
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
}
