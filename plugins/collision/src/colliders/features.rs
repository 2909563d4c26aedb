//! A collider's sharp feature against a face or an edge (a *feature pair*): their closest
//! points, and on which side of the feature the primitive is. The features are the vertices
//! and edges of a collider's convex core ([`super::shapes::Shape::features`]); they move
//! rigidly with their collider.

use glam::DVec3;

use super::motion::Pose;
use super::shapes::Shape;
use crate::candidates::Candidate;
use crate::narrow_phase::distance;
use crate::primitives::Geometry;
use crate::response::contact::PairKind;

/// A feature candidate's primitive against its feature ([`Geometry::feature_side`]).
pub(crate) struct FeatureSide {
    /// The primitive's particles and their weights in its closest point `p`.
    pub ids: [u32; 3],
    pub w: [f64; 3],
    pub p: DVec3,
    /// The feature's closest point and the squared distance to it, as the query gives it.
    pub q: DVec3,
    pub d2: f64,
    /// Whether `p` is inside the collider (only a box's features can have it so).
    pub inside: bool,
}

impl FeatureSide {
    /// The signed distance (m): negative on the wrong side of a box's feature.
    pub fn distance(&self) -> f64 {
        if self.inside {
            -self.d2.sqrt()
        } else {
            self.d2.sqrt()
        }
    }

    /// The direction out (from the feature to the primitive, reversed on the wrong side),
    /// not normalised: `p − q` or `q − p`.
    pub fn out(&self) -> DVec3 {
        if self.inside {
            self.q - self.p
        } else {
            self.p - self.q
        }
    }
}

impl Geometry<'_> {
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
        let (prims, colliders) = (self.prims, self.colliders);
        let (a, b) = (cand.pair[0] as usize, cand.pair[1] as usize);
        match cand.kind {
            PairKind::FeatureFace => {
                let t = prims.faces[b];
                let p = pose.apply(colliders.feat_points[a].1);
                let at = |i: u32| x[i as usize];
                let (bary, d2) = distance::point_triangle_closest(p, at(t[0]), at(t[1]), at(t[2]));
                (t, bary, p, d2)
            }
            PairKind::FeaturePointEdge => {
                let e = prims.edges[b];
                let p = pose.apply(colliders.feat_points[a].1);
                let (u, d2) =
                    distance::point_segment_closest(p, x[e[0] as usize], x[e[1] as usize]);
                ([e[0], e[1], e[1]], [1.0 - u, u, 0.0], p, d2)
            }
            _ => {
                let e = prims.edges[b];
                let [f0, f1] = colliders.feat_edges[a].1.map(|v| pose.apply(v));
                let (s, u, d2) =
                    distance::segment_segment_closest(f0, f1, x[e[0] as usize], x[e[1] as usize]);
                ([e[0], e[1], e[1]], [1.0 - u, u, 0.0], f0.lerp(f1, s), d2)
            }
        }
    }

    /// A feature candidate's closest points ([`Self::feature_closest`]), and on which side of
    /// its feature the primitive is. A box's corners and edges are its surface: a primitive
    /// whose closest point lies inside the box (a cloth edge cutting a corner, a face a box
    /// edge pokes through) is on the wrong side, and its way out is through the feature. A
    /// sphere's centre and a capsule's axis are inside their shapes: every primitive is on
    /// the outer side of them.
    pub fn feature_side(&self, cand: Candidate, x: &[DVec3], pose: Pose) -> FeatureSide {
        let (ids, w, q, d2) = self.feature_closest(cand, x, pose);
        let p: DVec3 = (0..3).map(|j| w[j] * x[ids[j] as usize]).sum();
        let c = self.colliders.feature_collider(cand) as usize;
        let shape = &self.colliders.list[c].shape;
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

    /// The distance (m) between a feature candidate's feature, with the collider at `pose`,
    /// and its primitive at `x`.
    pub fn feature_distance(&self, cand: Candidate, x: &[DVec3], pose: Pose) -> f64 {
        self.feature_side(cand, x, pose).distance()
    }
}
