//! Which pairs of primitives may be candidates, and at what contact distance.
//!
//! Never paired: pairs sharing a vertex (neighbours); pairs of one object whose
//! `self_collision` is off; two objects, or an object and a collider, whose collision
//! `layers` share no bit; excluded object pairs; pairs whose particles are all kinematic;
//! primitives whose flag is off (they are not listed at all). A pair of two objects is kept
//! at the sum of their thicknesses; a pair of one object at twice its thickness, or at a
//! fraction of its rest distance if it is closer at rest ([`super::rest_pairs`]).

use crate::broad_phase::bvh::Window;
use crate::colliders::shapes::Collider;
use crate::primitives::Primitives;

/// Whether a candidate involves only kinematic particles.
#[inline]
pub(crate) fn all_kinematic(ids: &[u32], inv_mass: &[f64]) -> bool {
    ids.iter().all(|&i| inv_mass[i as usize] == 0.0)
}

impl Primitives {
    /// What a query of object `obj`'s primitive wants from the tree of `tree` (0 vertices,
    /// 1 edges, 2 faces): nothing if the object meets no object, not its own primitives
    /// if it does not collide with itself, and only indices past `above` if given. Every
    /// primitive refused would give a pair [`Self::objects_may_collide`] drops.
    #[inline]
    pub fn window(&self, tree: usize, obj: u32, above: Option<u32>) -> Window {
        let o = obj as usize;
        Window {
            above,
            skip: if self.settings[o].self_collision {
                (0, 0)
            } else {
                self.object_ranges[o][tree]
            },
            none: !self.meets_objects[o],
        }
    }

    /// Whether an object (local) and a collider share a layer.
    #[inline]
    pub fn collides_with_collider(&self, object: u32, collider: &Collider) -> bool {
        self.settings[object as usize].layers & collider.layers != 0
    }

    /// The contact distance of vertex `i` against face `f` if they form a candidate (their
    /// boxes are assumed to overlap): not a vertex of the face, objects that collide, not all
    /// kinematic, and for one object, the rest shape's verdict
    /// ([`super::rest_pairs::CloseAtRest::vertex_face`]).
    #[inline]
    pub fn vertex_face_reach(&self, i: usize, f: u32, inv_mass: &[f64]) -> Option<f64> {
        let (p, po) = (self.verts[i], self.vert_obj[i]);
        let tri = self.faces[f as usize];
        let fo = self.face_obj[f as usize];
        if tri.contains(&p) || !self.objects_may_collide(po, fo) {
            return None;
        }
        if all_kinematic(&[p, tri[0], tri[1], tri[2]], inv_mass) {
            return None;
        }
        let d = self.radius(po) + self.radius(fo);
        if po == fo {
            if let Some(reach) = self.at_rest.vertex_face.reach(i, f) {
                return reach;
            }
        }
        Some(d)
    }

    /// The contact distance of edges `i < j` if they form a candidate (their boxes are
    /// assumed to overlap), as [`Self::vertex_face_reach`].
    #[inline]
    pub fn edge_edge_reach(&self, i: usize, j: u32, inv_mass: &[f64]) -> Option<f64> {
        let (e, eo) = (self.edges[i], self.edge_obj[i]);
        let f = self.edges[j as usize];
        let fo = self.edge_obj[j as usize];
        if f.contains(&e[0]) || f.contains(&e[1]) || !self.objects_may_collide(eo, fo) {
            return None;
        }
        if all_kinematic(&[e[0], e[1], f[0], f[1]], inv_mass) {
            return None;
        }
        let d = self.radius(eo) + self.radius(fo);
        if eo == fo {
            if let Some(reach) = self.at_rest.edge_edge.reach(i, j) {
                return reach;
            }
        }
        Some(d)
    }
}
