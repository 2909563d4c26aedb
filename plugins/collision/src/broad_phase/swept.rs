//! The swept boxes of the primitives over the substep: each covers the primitive's particles
//! at `x0` and `x − shift`, grown by its thickness (the *tight* box) and by a margin (the box
//! the candidates are found with), so that the positions can move a little during the solve
//! without a new broad phase.
//!
//! Why a shift keeps every pair: two points that come within `d` at some time `t` of the
//! substep, on their linear tracks `x0 + t (x − x0)`, are still within `d` once both are
//! moved by the same `−t·shift`, and the moved track `x0 + t (x − shift − x0)` lies in the box
//! of `x0` and `x − shift`. So the boxes of any pair that can touch overlap, whatever the
//! shift, as long as every box of the substep (the colliders' and features' included) takes
//! the same one. A cloth carried fast then has boxes the size of its relative motion instead
//! of its travel; a motion that is not shared is not helped
//! (`docs/decisions/collision_broad_phase.md`).

use glam::DVec3;

use super::bvh::Aabb;
use crate::candidates::Candidate;
use crate::primitives::{Geometry, Primitives};
use crate::response::contact::PairKind;

/// The margin (m) added to every swept box, beyond the thickness: 0.3 of the thickness plus a
/// fixed 0.1 mm (`docs/decisions/collision_broad_phase.md`). A smaller margin sends a draping
/// cloth back to the broad phase at almost every pass; a larger one finds too many pairs.
pub(crate) fn margin(radius: f64) -> f64 {
    0.3 * radius + 1e-4
}

/// The boxes of the primitives and of their particles.
pub(crate) struct SweptBoxes {
    /// Every particle of a vertex, an edge or a face (sorted), and the tight swept box of
    /// each (indexed by particle, radius 0): a primitive's tight box is the union of its
    /// particles' ([`Self::fill_particle_boxes`]).
    pub box_particles: Vec<u32>,
    pub particle_boxes: Vec<Aabb>,
    /// The boxes the candidates were found with (tight boxes grown by the [`margin`]), of the
    /// vertices, edges and faces.
    pub verts: Vec<Aabb>,
    pub edges: Vec<Aabb>,
    pub faces: Vec<Aabb>,
    /// A displacement (m) taken off every swept box's end: every box of a substep is taken
    /// over `[x0, x − shift]` (the colliders' and features' too), so the boxes follow the
    /// motion the primitives share and the broad phase sees only their relative motion
    /// (see the module docs). It is the mean displacement of the group's dynamic vertices
    /// over the substep (from the prediction), updated only when that departs from it by more
    /// than the largest thickness plus its margin ([`Self::follow`]): a steady shift keeps
    /// the colliders' boxes where they were found, so the candidates can be kept, and a group
    /// that moves less than that a substep keeps a zero shift.
    pub shift: DVec3,
}

impl SweptBoxes {
    /// The boxes of `prims` over their rest shape (grown by their thickness) for a group of
    /// `n` particles.
    pub fn at_rest(prims: &Primitives, n: usize) -> Self {
        let rest = &prims.rest;
        let mut box_particles: Vec<u32> = (prims.verts.iter().copied())
            .chain(prims.edges.iter().flatten().copied())
            .chain(prims.faces.iter().flatten().copied())
            .collect();
        box_particles.sort_unstable();
        box_particles.dedup();
        let radius_v = |i: usize| prims.radius(prims.vert_obj[i]);
        Self {
            box_particles,
            particle_boxes: vec![Aabb::EMPTY; n],
            verts: (0..prims.verts.len())
                .map(|i| Aabb::of_points(&[rest[prims.verts[i] as usize]], radius_v(i)))
                .collect(),
            edges: (prims.edges.iter().zip(&prims.edge_obj))
                .map(|(e, &o)| {
                    Aabb::of_points(&[rest[e[0] as usize], rest[e[1] as usize]], prims.radius(o))
                })
                .collect(),
            faces: (prims.faces.iter().zip(&prims.face_obj))
                .map(|(f, &o)| {
                    Aabb::of_points(
                        &[
                            rest[f[0] as usize],
                            rest[f[1] as usize],
                            rest[f[2] as usize],
                        ],
                        prims.radius(o),
                    )
                })
                .collect(),
            shift: DVec3::ZERO,
        }
    }

    /// Follows the motion the group's dynamic vertices share over `[x0, x]`
    /// ([`Self::shift`]): moves the shift to their mean displacement when it departs from
    /// the shift by more than the largest thickness plus its margin.
    pub fn follow(&mut self, prims: &Primitives, x0: &[DVec3], x: &[DVec3], inv_mass: &[f64]) {
        let mean = shared_displacement(prims, x0, x, inv_mass);
        let r = prims.max_thickness;
        if (mean - self.shift).length() > r + margin(r) {
            self.shift = mean;
        }
    }

    /// The tight swept box of vertex `i`: its particle over `[x0, x − shift]`, grown by its
    /// radius.
    #[inline]
    pub fn vert_box(&self, prims: &Primitives, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        let p = prims.verts[i] as usize;
        let s = self.shift;
        Aabb::of_points(&[x0[p], x[p] - s], prims.radius(prims.vert_obj[i]))
    }

    /// The tight swept box of edge `i`.
    #[inline]
    pub fn edge_box(&self, prims: &Primitives, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        let [a, b] = prims.edges[i];
        let (a, b) = (a as usize, b as usize);
        let s = self.shift;
        Aabb::of_points(
            &[x0[a], x0[b], x[a] - s, x[b] - s],
            prims.radius(prims.edge_obj[i]),
        )
    }

    /// The tight swept box of face `i`.
    #[inline]
    pub fn face_box(&self, prims: &Primitives, i: usize, x0: &[DVec3], x: &[DVec3]) -> Aabb {
        let [a, b, c] = prims.faces[i];
        let (a, b, c) = (a as usize, b as usize, c as usize);
        let s = self.shift;
        Aabb::of_points(
            &[x0[a], x0[b], x0[c], x[a] - s, x[b] - s, x[c] - s],
            prims.radius(prims.face_obj[i]),
        )
    }

    /// The tight swept box of every particle of a primitive over the substep so far,
    /// `[x0, x − shift]` ([`Self::tight_box_of`]).
    pub fn fill_particle_boxes(&mut self, x0: &[DVec3], x: &[DVec3]) {
        let s = self.shift;
        for &p in &self.box_particles {
            let p = p as usize;
            self.particle_boxes[p] = Aabb::of_points(&[x0[p], x[p] - s], 0.0);
        }
    }

    /// [`Self::tight_box_of`] for a kind chosen at run time (the tests').
    #[cfg(test)]
    pub fn tight_box(&self, prims: &Primitives, kind: usize, i: usize) -> (Aabb, f64) {
        match kind {
            0 => self.tight_box_of::<0>(prims, i),
            1 => self.tight_box_of::<1>(prims, i),
            _ => self.tight_box_of::<2>(prims, i),
        }
    }

    /// The tight swept box of vertex, edge or face `i` (`KIND` 0, 1, 2) and its radius, from
    /// the particle boxes just filled: the union of its particles' grown by its radius, which
    /// is [`Self::vert_box`], [`Self::edge_box`] or [`Self::face_box`] (the same minima and
    /// maxima of the same coordinates, then the same growth). The kind is a constant so that
    /// the loops over every primitive of a kind ([`Self::each_tight_box`]) pay no call and no
    /// branch per primitive for it.
    #[inline(always)]
    fn tight_box_of<const KIND: usize>(&self, prims: &Primitives, i: usize) -> (Aabb, f64) {
        let pb = |p: u32| self.particle_boxes[p as usize];
        let (b, obj) = match KIND {
            0 => (pb(prims.verts[i]), prims.vert_obj[i]),
            1 => {
                let [a, b] = prims.edges[i];
                (pb(a).union(pb(b)), prims.edge_obj[i])
            }
            _ => {
                let [a, b, c] = prims.faces[i];
                (pb(a).union(pb(b)).union(pb(c)), prims.face_obj[i])
            }
        };
        let radius = prims.radius(obj);
        (b.grow(radius), radius)
    }

    /// `f(j, tight box, radius)` for every primitive `i = range.start + j` of `kind` in `range`
    /// ([`Self::tight_box_of`]), the kind chosen once for the whole range.
    #[inline]
    pub fn each_tight_box(
        &self,
        prims: &Primitives,
        kind: usize,
        range: std::ops::Range<usize>,
        mut f: impl FnMut(usize, Aabb, f64),
    ) {
        let start = range.start;
        match kind {
            0 => range.for_each(|i| {
                let (b, r) = self.tight_box_of::<0>(prims, i);
                f(i - start, b, r)
            }),
            1 => range.for_each(|i| {
                let (b, r) = self.tight_box_of::<1>(prims, i);
                f(i - start, b, r)
            }),
            _ => range.for_each(|i| {
                let (b, r) = self.tight_box_of::<2>(prims, i);
                f(i - start, b, r)
            }),
        }
    }

    /// The stored boxes of the vertices (`kind` 0), edges (1) or faces (2).
    pub fn of_kind(&mut self, kind: usize) -> &mut Vec<Aabb> {
        match kind {
            0 => &mut self.verts,
            1 => &mut self.edges,
            _ => &mut self.faces,
        }
    }

    /// Whether the tight swept boxes of a candidate's primitives overlap (for a feature pair:
    /// lie within the collider's radius).
    pub fn overlap(&self, geo: Geometry<'_>, cand: Candidate, x0: &[DVec3], x: &[DVec3]) -> bool {
        let (prims, colliders) = (geo.prims, geo.colliders);
        let [a, b] = cand.pair;
        let (a, b) = (a as usize, b as usize);
        let vert = |i| self.vert_box(prims, i, x0, x);
        let edge = |i| self.edge_box(prims, i, x0, x);
        match cand.kind {
            PairKind::VertexFace => vert(a).overlaps(&self.face_box(prims, b, x0, x)),
            PairKind::EdgeEdge => edge(a).overlaps(&edge(b)),
            PairKind::VertexEdge => vert(a).overlaps(&edge(b)),
            PairKind::VertexVertex => vert(a).overlaps(&vert(b)),
            PairKind::Collider => true,
            PairKind::FeatureFace | PairKind::FeaturePointEdge | PairKind::FeatureEdgeEdge => {
                let r = colliders.radius[colliders.feature_collider(cand) as usize];
                let (feature, other) = match cand.kind {
                    PairKind::FeatureFace => (
                        colliders.feat_point_boxes[a],
                        self.face_box(prims, b, x0, x),
                    ),
                    PairKind::FeaturePointEdge => (colliders.feat_point_boxes[a], edge(b)),
                    _ => (colliders.feat_edge_boxes[a], edge(b)),
                };
                feature.distance_squared(&other) <= r * r
            }
        }
    }
}

/// The mean displacement of the group's dynamic vertices from `x0` to `x` (zero if none
/// moves or it is not finite).
pub(crate) fn shared_displacement(
    prims: &Primitives,
    x0: &[DVec3],
    x: &[DVec3],
    inv_mass: &[f64],
) -> DVec3 {
    let (mut sum, mut n) = (DVec3::ZERO, 0usize);
    for &p in &prims.verts {
        let p = p as usize;
        if inv_mass[p] > 0.0 {
            sum += x[p] - x0[p];
            n += 1;
        }
    }
    let mean = sum / n.max(1) as f64;
    if mean.is_finite() {
        mean
    } else {
        DVec3::ZERO
    }
}
