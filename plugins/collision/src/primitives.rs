//! What the group collides: the vertices, edges and faces of its target objects (only the
//! surface of tetrahedral solids), each object's settings, and which objects may meet.
//!
//! An object's primitives are listed together, so each object owns a contiguous range of
//! each list (`Primitives::object_ranges`); the objects are the group's *local* objects,
//! numbered in the order of its targets.

use glam::DVec3;
use nucleus_sdk::prelude::*;

use crate::candidates::rest_pairs::CloseAtRest;
use crate::colliders::Colliders;
use crate::params::ObjectSettings;

/// No face on that side of an edge ([`Primitives::edge_faces`]).
pub(crate) const NO_FACE: u32 = u32::MAX;

/// Most thickness of a self-colliding object, in multiples of its mean rest edge length
/// (`Primitives::build` refuses more). At 4 a vertex of a regular triangle mesh keeps
/// about a hundred pairs with its own surface in the rest shape (pairs within
/// `2 × thickness`, about 8 edge lengths); much thicker, millions
/// (`docs/decisions/collision_candidate_budget.md`).
pub const MAX_THICKNESS_PER_EDGE: f64 = 4.0;

/// The primitives of the target objects and their settings.
pub(crate) struct Primitives {
    /// Settings of each target object (local object index).
    pub settings: Vec<ObjectSettings>,
    /// Name of each target object, for errors.
    pub names: Vec<String>,
    /// Excluded pairs of local objects (sorted).
    pub excluded: Vec<[u32; 2]>,
    /// Whether each target object may collide with any target object, itself included
    /// ([`Self::objects_may_collide`]): the mesh queries of an object that meets none are not
    /// made, since every pair they would find is dropped.
    pub meets_objects: Vec<bool>,
    /// Each target object's vertices', edges' and faces' index ranges.
    pub object_ranges: Vec<[(u32, u32); 3]>,
    /// Rest positions (m), for the rest-distance filter of self-collision.
    pub rest: Vec<DVec3>,
    /// Particles of every vertex primitive, and their object.
    pub verts: Vec<u32>,
    pub vert_obj: Vec<u32>,
    /// Vertex primitives that are unconnected particles (indices into `verts`).
    pub isolated: Vec<u32>,
    pub edges: Vec<[u32; 2]>,
    pub edge_obj: Vec<u32>,
    /// Whether each edge is a curve edge (in no triangle).
    pub edge_curve: Vec<bool>,
    /// Whether each edge is tested against the colliders' feature points: a curve edge, or
    /// an edge of an object whose faces do not collide (else its faces cover it).
    pub edge_point_tests: Vec<bool>,
    pub faces: Vec<[u32; 3]>,
    pub face_obj: Vec<u32>,
    /// The (at most two) faces on each edge ([`NO_FACE`] for none).
    pub edge_faces: Vec<[u32; 2]>,
    /// For each local object whose every vertex is kinematic, three vertices spanning a
    /// frame (its rigid motion carries vertices frozen by the fail-safe).
    pub rigid_frame: Vec<Option<[u32; 3]>>,
    /// The local objects with a dynamic vertex.
    pub dynamic_objects: Vec<usize>,
    /// The largest thickness of the group's objects (m).
    pub max_thickness: f64,
    /// The same-object pairs closer than their thickness in the rest shape.
    pub at_rest: CloseAtRest,
}

impl Primitives {
    /// Collects the primitives of the scene's target objects with their `settings` (in the
    /// targets' order) and `excluded` object pairs; refuses a vertex outside its object and a
    /// self-colliding object much thicker than its edges ([`MAX_THICKNESS_PER_EDGE`]).
    pub fn build(
        scene: &SceneView<'_>,
        names: Vec<String>,
        settings: Vec<ObjectSettings>,
        excluded: Vec<[u32; 2]>,
    ) -> Result<Self, PluginError> {
        let rest = scene.rest_positions().to_vec();
        let inv_mass = scene.inv_mass.as_slice();
        let targets = scene.unique_targets()?;
        let mut g = Self {
            settings,
            names,
            excluded,
            meets_objects: Vec::new(),
            object_ranges: Vec::new(),
            rest,
            verts: Vec::new(),
            vert_obj: Vec::new(),
            isolated: Vec::new(),
            edges: Vec::new(),
            edge_obj: Vec::new(),
            edge_curve: Vec::new(),
            edge_point_tests: Vec::new(),
            faces: Vec::new(),
            face_obj: Vec::new(),
            edge_faces: Vec::new(),
            rigid_frame: Vec::new(),
            dynamic_objects: Vec::new(),
            max_thickness: 0.0,
            at_rest: CloseAtRest::default(),
        };
        let objects = g.settings.len() as u32;
        g.meets_objects = (0..objects)
            .map(|a| (0..objects).any(|b| g.objects_may_collide(a, b)))
            .collect();
        for (k, &(_, o)) in targets.iter().enumerate() {
            let s = g.settings[k];
            let range = o.particles();
            let bad = |m: String| PluginError::bad_object(o.name.as_str(), m);
            let check = |i: u32| -> Result<(), PluginError> {
                if range.contains(&(i as usize)) {
                    Ok(())
                } else {
                    Err(bad(format!(
                        "vertex {i} is outside the object's particles {}..{}",
                        range.start, range.end
                    )))
                }
            };
            let tet_count = o.triangle_tet_count.as_slice();
            let mut surface: Vec<[u32; 3]> = Vec::new();
            for (i, tri) in o.triangles.as_slice().iter().enumerate() {
                if tet_count.get(i).copied().unwrap_or(0) < 2 {
                    for &v in tri {
                        check(v)?;
                    }
                    surface.push(*tri);
                }
            }
            let mut edges: Vec<([u32; 2], bool)> = surface
                .iter()
                .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
                .map(|[a, b]| ([a.min(b), a.max(b)], false))
                .collect();
            let counts = o.edge_triangle_count.as_slice();
            for (i, e) in o.edges.as_slice().iter().enumerate() {
                if counts.get(i).copied() == Some(0) {
                    check(e[0])?;
                    check(e[1])?;
                    edges.push(([e[0].min(e[1]), e[0].max(e[1])], true));
                }
            }
            edges.sort_unstable();
            edges.dedup_by(|a, b| a.0 == b.0);
            edges.retain(|(e, _)| e[0] != e[1]);
            let mut verts: Vec<u32> = surface
                .iter()
                .flatten()
                .copied()
                .chain(edges.iter().flat_map(|(e, _)| *e))
                .collect();
            let mut points = o.points.as_slice().to_vec();
            for &p in &points {
                check(p)?;
            }
            points.sort_unstable();
            verts.extend_from_slice(&points);
            verts.sort_unstable();
            verts.dedup();

            let all_kinematic = range.clone().all(|i| inv_mass[i] == 0.0);
            g.rigid_frame.push(if all_kinematic {
                frame_vertices(&g.rest, &verts)
            } else {
                None
            });
            if !all_kinematic {
                g.dynamic_objects.push(k);
            }
            if s.vertex {
                for &v in &verts {
                    if points.binary_search(&v).is_ok() {
                        g.isolated.push(g.verts.len() as u32);
                    }
                    g.verts.push(v);
                    g.vert_obj.push(k as u32);
                }
            }
            if s.edge {
                for (e, curve) in edges {
                    g.edges.push(e);
                    g.edge_obj.push(k as u32);
                    g.edge_curve.push(curve);
                    g.edge_point_tests.push(curve || !s.face);
                }
            }
            if s.face {
                for t in surface {
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        g.faces.push(t);
                        g.face_obj.push(k as u32);
                    }
                }
            }
        }
        g.max_thickness = g.settings.iter().map(|s| s.thickness).fold(0.0, f64::max);
        g.edge_faces = edge_faces(&g.edges, &g.faces);
        g.object_ranges = (0..objects)
            .map(|k| [&g.vert_obj, &g.edge_obj, &g.face_obj].map(|owners| object_range(owners, k)))
            .collect();
        for &k in &g.dynamic_objects {
            let o = targets[k].1;
            g.check_self_thickness(k as u32)
                .map_err(|m| PluginError::bad_object(o.name.as_str(), m))?;
        }
        g.at_rest = CloseAtRest::find(&g);
        Ok(g)
    }

    /// Number of vertex, edge and face primitives.
    pub fn counts(&self) -> [usize; 3] {
        [self.verts.len(), self.edges.len(), self.faces.len()]
    }

    /// Number of primitives of every kind.
    pub fn len(&self) -> usize {
        self.verts.len() + self.edges.len() + self.faces.len()
    }

    /// Whether any pair can ever collide: a dynamic object with a collider on a common layer
    /// (through its vertices, or its edges and faces against a collider with sharp features),
    /// with itself, or with another object on a common layer that is not excluded.
    pub fn any_pair(&self, colliders: &Colliders) -> bool {
        let k_count = self.settings.len();
        let has = |list: &[u32], k: usize| list.contains(&(k as u32));
        let any_prims =
            |k: usize| has(&self.vert_obj, k) || has(&self.edge_obj, k) || has(&self.face_obj, k);
        let mut active = false;
        for &k in &self.dynamic_objects {
            if !any_prims(k) {
                continue;
            }
            let mask = self.settings[k].layers;
            let edges_or_faces = has(&self.edge_obj, k) || has(&self.face_obj, k);
            for (c, col) in colliders.list.iter().enumerate() {
                let features = colliders.feat_points.iter().any(|f| f.0 == c as u32);
                if col.layers & mask != 0 && (has(&self.vert_obj, k) || edges_or_faces && features)
                {
                    active = true;
                }
            }
            if self.settings[k].self_collision && self.may_self_collide(k as u32) {
                active = true;
            }
            for other in 0..k_count {
                if other != k
                    && any_prims(other)
                    && self.objects_may_collide(k as u32, other as u32)
                {
                    active = true;
                }
            }
        }
        active
    }

    /// Whether object `k` (local) has two primitives that could form a pair: a vertex and a
    /// face, two edges, two unconnected particles, or one and a curve edge.
    fn may_self_collide(&self, k: u32) -> bool {
        let count = |list: &[u32]| list.iter().filter(|&&o| o == k).count();
        let (verts, edges, faces) = (
            count(&self.vert_obj),
            count(&self.edge_obj),
            count(&self.face_obj),
        );
        let isolated = self
            .isolated
            .iter()
            .filter(|&&i| self.vert_obj[i as usize] == k)
            .count();
        (faces > 0 && verts > 3) || edges > 1 || isolated > 1 || (isolated > 0 && edges > 0)
    }

    /// Refuses a self-colliding dynamic object whose thickness is more than
    /// [`MAX_THICKNESS_PER_EDGE`] times its mean rest edge length: every vertex would keep
    /// hundreds to millions of pairs with its own surface in the rest shape, and the cloth
    /// could not fold anyway. The message gives the limit and the two ways out.
    fn check_self_thickness(&self, k: u32) -> Result<(), String> {
        let s = self.settings[k as usize];
        if !s.self_collision || !self.may_self_collide(k) {
            return Ok(());
        }
        let (mut sum, mut count) = (0.0, 0usize);
        for (e, _) in self.edges.iter().zip(&self.edge_obj).filter(|p| *p.1 == k) {
            sum += self.rest[e[0] as usize].distance(self.rest[e[1] as usize]);
            count += 1;
        }
        // No edges, or a rest shape without length (or not finite): nothing to compare with.
        let mean = if count > 0 { sum / count as f64 } else { 0.0 };
        if mean.is_nan() || mean <= 0.0 || s.thickness <= MAX_THICKNESS_PER_EDGE * mean {
            return Ok(());
        }
        Err(format!(
            "thickness {} m is {:.1} times the object's mean edge length ({:.3e} m); with \
             self-collision at most {MAX_THICKNESS_PER_EDGE} times it ({:.3e} m) is accepted, since \
             every vertex would be in contact with its own surface at rest: use a smaller \
             thickness, or turn self_collision off for this object (objects_settings)",
            s.thickness,
            s.thickness / mean,
            mean,
            MAX_THICKNESS_PER_EDGE * mean
        ))
    }

    /// The thickness of a local object (m).
    #[inline]
    pub fn radius(&self, local_object: u32) -> f64 {
        self.settings[local_object as usize].thickness
    }

    fn is_excluded(&self, a: u32, b: u32) -> bool {
        self.excluded.binary_search(&[a.min(b), a.max(b)]).is_ok()
    }

    /// Whether a pair of objects (local) may collide at all: one object with itself if its
    /// `self_collision` is on; two objects if they share a layer and are not excluded.
    #[inline]
    pub fn objects_may_collide(&self, a: u32, b: u32) -> bool {
        if a == b {
            self.settings[a as usize].self_collision
        } else {
            self.settings[a as usize].layers & self.settings[b as usize].layers != 0
                && !self.is_excluded(a, b)
        }
    }
}

/// What the group collides, read-only during a substep: its primitives and its colliders.
#[derive(Clone, Copy)]
pub(crate) struct Geometry<'a> {
    pub prims: &'a Primitives,
    pub colliders: &'a Colliders,
}

/// The index range of the primitives `owners` lists as object `k`'s, which are contiguous
/// (`(0, 0)` for none).
fn object_range(owners: &[u32], k: u32) -> (u32, u32) {
    let start = owners.partition_point(|&o| o < k);
    let end = owners.partition_point(|&o| o <= k);
    debug_assert!(
        owners.windows(2).all(|w| w[0] <= w[1]),
        "primitives out of object order"
    );
    if start == end {
        (0, 0)
    } else {
        (start as u32, end as u32)
    }
}

/// The faces on each edge (at most two kept; [`NO_FACE`] for none).
fn edge_faces(edges: &[[u32; 2]], faces: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let index: std::collections::HashMap<[u32; 2], usize> =
        edges.iter().enumerate().map(|(i, &e)| (e, i)).collect();
    let mut out = vec![[NO_FACE; 2]; edges.len()];
    for (f, t) in faces.iter().enumerate() {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if let Some(&e) = index.get(&[a.min(b), a.max(b)]) {
                match out[e] {
                    [NO_FACE, _] => out[e][0] = f as u32,
                    [_, NO_FACE] => out[e][1] = f as u32,
                    _ => {}
                }
            }
        }
    }
    out
}

/// An orthonormal frame (columns) from three points, `None` if they are (nearly) collinear.
pub(crate) fn frame(a: DVec3, b: DVec3, c: DVec3) -> Option<glam::DMat3> {
    let e1 = (b - a).try_normalize()?;
    let u = c - a;
    let e2 = (u - e1 * e1.dot(u)).try_normalize()?;
    Some(glam::DMat3::from_cols(e1, e2, e1.cross(e2)))
}

/// Three vertices of `verts` spanning a well-shaped frame in the rest pose.
fn frame_vertices(rest: &[DVec3], verts: &[u32]) -> Option<[u32; 3]> {
    let &a = verts.first()?;
    let pa = rest[a as usize];
    let &b = verts.iter().max_by(|&&i, &&j| {
        pa.distance_squared(rest[i as usize])
            .total_cmp(&pa.distance_squared(rest[j as usize]))
    })?;
    let pb = rest[b as usize];
    let &c = verts.iter().max_by(|&&i, &&j| {
        let area = |k: u32| (pb - pa).cross(rest[k as usize] - pa).length_squared();
        area(i).total_cmp(&area(j))
    })?;
    let area = (pb - pa).cross(rest[c as usize] - pa).length();
    (area > 1e-12 && frame(pa, pb, rest[c as usize]).is_some()).then_some([a, b, c])
}
