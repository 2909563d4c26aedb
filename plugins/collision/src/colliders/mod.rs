//! The analytic colliders: their shapes ([`shapes`]), how they move ([`motion`]), the sharp
//! features of their cores ([`features`]), and the group's colliders posed over the current
//! substep (`Colliders`).

pub mod features;
pub mod motion;
pub mod shapes;

use glam::DVec3;

use crate::broad_phase::bvh::Aabb;
use crate::candidates::Candidate;
use crate::response::contact::PairKind;
use motion::Pose;
use shapes::Collider;

/// The group's analytic colliders, their features, and where they are over the substep.
pub(crate) struct Colliders {
    pub list: Vec<Collider>,
    /// Distance from each collider's core to its surface, plus its thickness (m).
    pub radius: Vec<f64>,
    /// Sharp features of the colliders' cores ([`shapes::Shape::features`]): points and
    /// edges in their collider's rest frame, with the collider's index.
    pub feat_points: Vec<(u32, DVec3)>,
    pub feat_edges: Vec<(u32, [DVec3; 2])>,
    /// The feature edges that end at each feature point (a capsule's axis at its ends).
    pub point_edges: Vec<Vec<u32>>,
    /// Each collider's pose at the start and the end of the substep.
    pub pose0: Vec<Pose>,
    pub pose1: Vec<Pose>,
    /// World positions of the feature points at the start and the end of the substep, and of
    /// the feature edges' ends (`[a0, b0, a1, b1]`); their swept boxes (not grown).
    pub feat_point_tracks: Vec<[DVec3; 2]>,
    pub feat_edge_tracks: Vec<[DVec3; 4]>,
    pub feat_point_boxes: Vec<Aabb>,
    pub feat_edge_boxes: Vec<Aabb>,
    /// World boxes of the colliders over the substep ([`Self::pose`]).
    pub boxes: Vec<Aabb>,
    /// (collider, local object) pairs impaled this substep
    /// ([`crate::response::leaving::find_impaled`]); capacity for every pair, set at build.
    pub impaled: Vec<(u32, u32)>,
}

impl Colliders {
    /// The colliders `list` of a group of `objects` local objects, with their features.
    pub fn new(list: Vec<Collider>, objects: usize) -> Self {
        let mut radius = Vec::with_capacity(list.len());
        let (mut feat_points, mut feat_edges) = (Vec::new(), Vec::new());
        for (c, col) in list.iter().enumerate() {
            let f = col.shape.features();
            radius.push(f.radius + col.thickness);
            feat_points.extend(f.points.into_iter().map(|p| (c as u32, p)));
            feat_edges.extend(f.edges.into_iter().map(|e| (c as u32, e)));
        }
        let point_edges = (feat_points.iter())
            .map(|&(c, p)| {
                (0..feat_edges.len() as u32)
                    .filter(|&e| {
                        let (ec, [a, b]) = feat_edges[e as usize];
                        ec == c && (a == p || b == p)
                    })
                    .collect()
            })
            .collect();
        let n = list.len();
        Self {
            radius,
            feat_point_tracks: vec![[DVec3::ZERO; 2]; feat_points.len()],
            feat_edge_tracks: vec![[DVec3::ZERO; 4]; feat_edges.len()],
            feat_point_boxes: vec![Aabb::EMPTY; feat_points.len()],
            feat_edge_boxes: vec![Aabb::EMPTY; feat_edges.len()],
            point_edges,
            feat_points,
            feat_edges,
            pose0: vec![Pose::IDENTITY; n],
            pose1: vec![Pose::IDENTITY; n],
            boxes: vec![Aabb::EMPTY; n],
            impaled: Vec::with_capacity(n * objects),
            list,
        }
    }

    /// Poses the colliders at both ends of the substep `[time, time + h]`: their poses, the
    /// features' tracks and swept boxes, and the colliders' boxes, all with the broad
    /// phase's `shift` (its [`crate::broad_phase::swept::SweptBoxes::shift`]) taken off their
    /// ends and grown by the largest thickness of the group's objects, `max_thickness`.
    pub fn pose(&mut self, time: f64, h: f64, shift: DVec3, max_thickness: f64) {
        for (c, col) in self.list.iter().enumerate() {
            self.pose0[c] = col.motion.pose(time);
            self.pose1[c] = col.motion.pose(time + h);
        }
        for (f, &(c, q)) in self.feat_points.iter().enumerate() {
            let ends = [
                self.pose0[c as usize].apply(q),
                self.pose1[c as usize].apply(q),
            ];
            self.feat_point_tracks[f] = ends;
            self.feat_point_boxes[f] = Aabb::of_points(&[ends[0], ends[1] - shift], 0.0);
        }
        for (f, &(c, [a, b])) in self.feat_edges.iter().enumerate() {
            let (p0, p1) = (self.pose0[c as usize], self.pose1[c as usize]);
            let ends = [p0.apply(a), p0.apply(b), p1.apply(a), p1.apply(b)];
            self.feat_edge_tracks[f] = ends;
            let s = shift;
            self.feat_edge_boxes[f] =
                Aabb::of_points(&[ends[0], ends[1], ends[2] - s, ends[3] - s], 0.0);
        }
        self.bound(shift, max_thickness);
    }

    /// World boxes of the colliders over the substep (their rest-frame bounds, grown by
    /// every thickness in play, at both poses; a rotating shape is bounded by its bounding
    /// sphere about its pivot-independent centre).
    fn bound(&mut self, shift: DVec3, max_thickness: f64) {
        for (c, col) in self.list.iter().enumerate() {
            let (lo, hi) = col.shape.bounds(col.thickness + max_thickness);
            if !lo.is_finite() || !hi.is_finite() {
                self.boxes[c] = Aabb {
                    min: DVec3::splat(f64::NEG_INFINITY),
                    max: DVec3::splat(f64::INFINITY),
                };
                continue;
            }
            let center = 0.5 * (lo + hi);
            let r = 0.5 * (hi - lo).length();
            let ends = [
                self.pose0[c].apply(center),
                self.pose1[c].apply(center) - shift,
            ];
            self.boxes[c] = Aabb::of_points(&ends, r);
        }
    }

    /// The collider of a feature candidate.
    #[inline]
    pub fn feature_collider(&self, cand: Candidate) -> u32 {
        match cand.kind {
            PairKind::FeatureEdgeEdge => self.feat_edges[cand.pair[0] as usize].0,
            _ => self.feat_points[cand.pair[0] as usize].0,
        }
    }
}
