//! Pairs of one object that are closer than their thickness in the rest shape, without
//! sharing a vertex (a fine mesh whose non-adjacent vertices are closer than twice its
//! thickness, a garment's front and back modelled close together): they are kept at a
//! fraction of their rest distance instead of the thickness ([`rest_reach`]). Found once, at
//! build; the broad phase looks a pair up instead of taking its exact rest distance every
//! time it finds it.

use crate::broad_phase::bvh::{Aabb, Bvh};
use crate::narrow_phase::distance;
use crate::primitives::Primitives;

/// A pair of one object that is closer than its thickness `d` in the rest shape, without
/// sharing a vertex, is kept `REST_FRACTION ×` its rest distance apart instead of `d` (see
/// [`rest_reach`]).
pub const REST_FRACTION: f64 = 0.5;

/// The contact distance of a same-object pair of thickness `d` whose squared distance in the
/// rest shape is `rest_d2`: `d` if the rest shape keeps them that far apart, else
/// [`REST_FRACTION`] × the rest distance (they start closer than `d`: pushing them to `d`
/// would fight the object's own shape, and dropping them, as if they were neighbours, would
/// let them pass through each other however the object deforms), and `None` for a pair that
/// touches in the rest shape (coincident vertices of an unwelded seam: glued, like
/// neighbours).
pub fn rest_reach(d: f64, rest_d2: f64) -> Option<f64> {
    if rest_d2 >= d * d {
        Some(d)
    } else if rest_d2 > 0.0 {
        Some(REST_FRACTION * rest_d2.sqrt())
    } else {
        None
    }
}

/// The contact distance of a same-object pair whose rest boxes are `gap2` (squared) apart,
/// from its exact rest distance `exact()` only when the boxes are closer than `d`.
pub(crate) fn same_object_reach(d: f64, gap2: f64, exact: &dyn Fn() -> f64) -> Option<f64> {
    if gap2 >= d * d {
        Some(d)
    } else {
        rest_reach(d, exact())
    }
}

/// Pairs of primitives found once from the rest shape, per first primitive (compressed rows):
/// the second primitives in increasing order, each with its contact distance (`None`:
/// glued, never a pair).
#[derive(Clone, Debug, Default)]
pub(crate) struct RestPairs {
    /// Row `i` is `first[i]..first[i + 1]`.
    first: Vec<u32>,
    other: Vec<u32>,
    reach: Vec<Option<f64>>,
}

impl RestPairs {
    /// The rows of `n` first primitives, each filled by `row(i, out)` in any order.
    fn collect(n: usize, mut row: impl FnMut(usize, &mut Vec<(u32, Option<f64>)>)) -> RestPairs {
        let mut pairs = RestPairs {
            first: Vec::with_capacity(n + 1),
            ..RestPairs::default()
        };
        pairs.first.push(0);
        let mut out = Vec::new();
        for i in 0..n {
            out.clear();
            row(i, &mut out);
            out.sort_unstable_by_key(|&(j, _)| j);
            pairs.other.extend(out.iter().map(|&(j, _)| j));
            pairs.reach.extend(out.iter().map(|&(_, r)| r));
            pairs.first.push(pairs.other.len() as u32);
        }
        pairs
    }

    /// The contact distance of pair `(i, j)` if it is listed (`Some(None)`: glued).
    #[inline]
    pub fn reach(&self, i: usize, j: u32) -> Option<Option<f64>> {
        let row = self.first[i] as usize..self.first[i + 1] as usize;
        let k = self.other[row.clone()].binary_search(&j).ok()?;
        Some(self.reach[row.start + k])
    }

    /// Number of pairs listed.
    pub fn len(&self) -> usize {
        self.other.len()
    }
}

/// The same-object pairs closer than their thickness at rest, and the rest boxes they were
/// found with.
#[derive(Clone, Debug, Default)]
pub(crate) struct CloseAtRest {
    /// Boxes of the edges and faces in the rest shape (not grown): a same-object pair whose
    /// boxes are `d` apart needs no exact rest distance.
    pub edge_boxes: Vec<Aabb>,
    pub face_boxes: Vec<Aabb>,
    /// The same-object vertex–face and edge–edge (`j > i`) pairs whose rest boxes are closer
    /// than their thickness, with the contact distance [`rest_reach`] gives them: every
    /// other same-object pair keeps its thickness.
    pub vertex_face: RestPairs,
    pub edge_edge: RestPairs,
}

impl CloseAtRest {
    /// Finds them among `prims`, with bounding-volume trees over the rest boxes.
    pub fn find(prims: &Primitives) -> Self {
        let rest = &prims.rest;
        let mut at_rest = CloseAtRest {
            edge_boxes: (prims.edges.iter())
                .map(|e| Aabb::of_points(&e.map(|i| rest[i as usize]), 0.0))
                .collect(),
            face_boxes: (prims.faces.iter())
                .map(|f| Aabb::of_points(&f.map(|i| rest[i as usize]), 0.0))
                .collect(),
            ..CloseAtRest::default()
        };
        at_rest.vertex_face = at_rest.vertex_face_pairs(prims);
        at_rest.edge_edge = at_rest.edge_edge_pairs(prims);
        at_rest
    }

    /// The same-object vertex–face pairs of [`Self::vertex_face`], found with a
    /// bounding-volume tree over the faces' rest boxes.
    fn vertex_face_pairs(&self, prims: &Primitives) -> RestPairs {
        let grown: Vec<Aabb> = (self.face_boxes.iter().zip(&prims.face_obj))
            .map(|(b, &o)| b.grow(2.0 * prims.radius(o)))
            .collect();
        let bvh = Bvh::build(&grown);
        let mut stack = Vec::new();
        RestPairs::collect(prims.verts.len(), |i, out| {
            let (p, po) = (prims.verts[i], prims.vert_obj[i]);
            let at_rest = Aabb::of_points(&[prims.rest[p as usize]], 0.0);
            let d = 2.0 * prims.radius(po);
            bvh.query(&at_rest, &grown, &mut stack, |f| {
                let tri = prims.faces[f as usize];
                if prims.face_obj[f as usize] != po || tri.contains(&p) {
                    return;
                }
                if at_rest.distance_squared(&self.face_boxes[f as usize]) < d * d {
                    let [a, b, c] = tri.map(|k| prims.rest[k as usize]);
                    let exact = distance::point_triangle_closest(prims.rest[p as usize], a, b, c).1;
                    out.push((f, rest_reach(d, exact)));
                }
            });
        })
    }

    /// The same-object edge–edge pairs `(i, j)`, `j > i`, of [`Self::edge_edge`].
    fn edge_edge_pairs(&self, prims: &Primitives) -> RestPairs {
        let grown: Vec<Aabb> = (self.edge_boxes.iter().zip(&prims.edge_obj))
            .map(|(b, &o)| b.grow(2.0 * prims.radius(o)))
            .collect();
        let bvh = Bvh::build(&grown);
        let mut stack = Vec::new();
        RestPairs::collect(prims.edges.len(), |i, out| {
            let (e, eo) = (prims.edges[i], prims.edge_obj[i]);
            let d = 2.0 * prims.radius(eo);
            bvh.query(&self.edge_boxes[i], &grown, &mut stack, |j| {
                let f = prims.edges[j as usize];
                if j as usize <= i
                    || prims.edge_obj[j as usize] != eo
                    || f.contains(&e[0])
                    || f.contains(&e[1])
                {
                    return;
                }
                let gap2 = self.edge_boxes[i].distance_squared(&self.edge_boxes[j as usize]);
                if gap2 < d * d {
                    let [a, b] = e.map(|v| prims.rest[v as usize]);
                    let [c, g] = f.map(|v| prims.rest[v as usize]);
                    let exact = distance::segment_segment_closest(a, b, c, g).2;
                    out.push((j, rest_reach(d, exact)));
                }
            });
        })
    }
}
