//! The objects of a simulation: each one's topology in global particle indices, as plugins
//! see it ([`ObjectData`], exported from its simplicial complex), and where its pinned or
//! animated particles go (`MovingPins`, the kinematic stage's state).

use std::ops::Range;

use abi_stable::std_types::{RSlice, RStr};
use glam::{DQuat, DVec3};
use nucleus_sdk::{EdgePair, ObjectView, TrianglePair, FLAG_KINEMATIC};

use crate::complex::Complex;
use crate::particles::Particles;
use crate::scene::PinMotion;

/// An object's topology in global particle indices, as plugins see it.
#[derive(Debug, Clone, Default)]
pub struct ObjectData {
    /// Name.
    pub name: String,
    /// First particle.
    pub first: u32,
    /// Number of particles.
    pub count: u32,
    /// Isolated points.
    pub points: Vec<u32>,
    /// All edges.
    pub edges: Vec<[u32; 2]>,
    /// Triangles per edge.
    pub edge_triangle_count: Vec<u32>,
    /// All triangles, oriented.
    pub triangles: Vec<[u32; 3]>,
    /// Tets per triangle.
    pub triangle_tet_count: Vec<u32>,
    /// Triangles on the surface (not shared by two tets), for output and collisions.
    pub surface_triangles: Vec<[u32; 3]>,
    /// Curve edges (in no triangle), for output.
    pub curve_edges: Vec<[u32; 2]>,
    /// Tets.
    pub tets: Vec<[u32; 4]>,
    /// Triangle pairs.
    pub triangle_pairs: Vec<TrianglePair>,
    /// Curve edge pairs.
    pub edge_pairs: Vec<EdgePair>,
    /// Boundary edges.
    pub boundary_edges: Vec<[u32; 2]>,
    /// Closed surface.
    pub closed: bool,
    /// Manifold.
    pub manifold: bool,
    /// Motion of the pinned vertices.
    pub pin_motion: PinMotion,
    /// Positions per frame of an animated mesh (local vertex order); empty if not animated.
    pub sequence: Vec<Vec<[f64; 3]>>,
}

impl ObjectData {
    /// The object's topology from its complex, its vertices numbered from `first`.
    pub(crate) fn from_complex(name: &str, first: u32, complex: &Complex) -> ObjectData {
        let g = |i: u32| i + first;
        let edges: Vec<[u32; 2]> = complex.edges().iter().map(|e| [g(e[0]), g(e[1])]).collect();
        let edge_triangle_count = complex.edge_triangle_count();
        let triangles: Vec<[u32; 3]> = complex
            .triangles_oriented()
            .iter()
            .map(|t| [g(t[0]), g(t[1]), g(t[2])])
            .collect();
        let triangle_tet_count: Vec<u32> = (0..triangles.len())
            .map(|i| complex.valence(2, i) as u32)
            .collect();
        let surface_triangles = triangles
            .iter()
            .enumerate()
            .filter(|(i, _)| complex.valence(2, *i) < 2)
            .map(|(_, t)| *t)
            .collect();
        let curve_edges = edges
            .iter()
            .zip(&edge_triangle_count)
            .filter(|(_, &c)| c == 0)
            .map(|(e, _)| *e)
            .collect();
        ObjectData {
            name: name.to_string(),
            first,
            count: complex.n_vertices() as u32,
            points: complex.isolated_points().iter().map(|&p| g(p)).collect(),
            edges,
            edge_triangle_count,
            triangles,
            triangle_tet_count,
            surface_triangles,
            curve_edges,
            tets: complex
                .tets()
                .iter()
                .map(|t| [g(t[0]), g(t[1]), g(t[2]), g(t[3])])
                .collect(),
            triangle_pairs: complex
                .triangle_pairs()
                .iter()
                .map(|p| TrianglePair {
                    triangles: p.triangles,
                    edge: [g(p.edge[0]), g(p.edge[1])],
                    opposite: [g(p.opposite[0]), g(p.opposite[1])],
                })
                .collect(),
            edge_pairs: complex
                .edge_pairs()
                .iter()
                .map(|p| EdgePair {
                    vertices: [g(p[0]), g(p[1]), g(p[2])],
                })
                .collect(),
            boundary_edges: complex
                .boundary_edges()
                .iter()
                .map(|e| [g(e[0]), g(e[1])])
                .collect(),
            closed: complex.is_closed(),
            manifold: complex.is_manifold(),
            pin_motion: PinMotion::default(),
            sequence: Vec::new(),
        }
    }

    /// The object as plugins see it.
    pub(crate) fn view(&self) -> ObjectView<'_> {
        ObjectView {
            name: RStr::from(self.name.as_str()),
            first: self.first,
            count: self.count,
            points: RSlice::from_slice(&self.points),
            edges: RSlice::from_slice(&self.edges),
            edge_triangle_count: RSlice::from_slice(&self.edge_triangle_count),
            triangles: RSlice::from_slice(&self.triangles),
            triangle_tet_count: RSlice::from_slice(&self.triangle_tet_count),
            tets: RSlice::from_slice(&self.tets),
            triangle_pairs: RSlice::from_slice(&self.triangle_pairs),
            edge_pairs: RSlice::from_slice(&self.edge_pairs),
            boundary_edges: RSlice::from_slice(&self.boundary_edges),
            closed: self.closed as u8,
            manifold: self.manifold as u8,
        }
    }

    /// Where moving pin `i` of this object goes at `frame_pos` (time in frames): its rest
    /// position under the object's pin transform `(rotation, translation)` about the pivot, or
    /// the object's animated mesh sequence, interpolated between the two frames around
    /// `frame_pos`.
    fn pin_target(
        &self,
        (rot, trans): (DQuat, DVec3),
        rest: [f64; 3],
        i: usize,
        frame_pos: f64,
    ) -> DVec3 {
        if self.sequence.is_empty() {
            let pivot = DVec3::from_array(self.pin_motion.pivot);
            pivot + rot * (DVec3::from_array(rest) - pivot) + trans
        } else {
            let last = self.sequence.len() - 1;
            let f = (frame_pos.floor().max(0.0) as usize).min(last);
            let g = (f + 1).min(last);
            let s = (frame_pos - f as f64).clamp(0.0, 1.0);
            let local = i - self.first as usize;
            DVec3::from_array(self.sequence[f][local])
                .lerp(DVec3::from_array(self.sequence[g][local]), s)
        }
    }
}

/// The kinematic stage's state: which particles are moving pins, and the pin transform of each
/// object at the substep's end, where the prediction sends them.
#[derive(Debug, Clone, Default)]
pub(crate) struct MovingPins {
    /// Kinematic particles whose object has a pin motion or an animated mesh, in particle
    /// order.
    particles: Vec<u32>,
    /// Each object's pin transform at the target time.
    transforms: Vec<(DQuat, DVec3)>,
    /// The target time in frames.
    frame_pos: f64,
}

impl MovingPins {
    /// The moving pins of particles `p` of `objects`, their transforms the identity.
    pub(crate) fn new(objects: &[ObjectData], p: &Particles) -> MovingPins {
        let particles = (0..p.len() as u32)
            .filter(|&i| {
                let o = &objects[p.object[i as usize] as usize];
                p.flags[i as usize] & FLAG_KINEMATIC != 0
                    && (o.pin_motion.is_moving() || !o.sequence.is_empty())
            })
            .collect();
        MovingPins {
            particles,
            transforms: vec![(DQuat::IDENTITY, DVec3::ZERO); objects.len()],
            frame_pos: 0.0,
        }
    }

    /// Sets the target time to `t` (s): each object's pin transform at `t`, and `t` in frames.
    pub(crate) fn update(&mut self, objects: &[ObjectData], t: f64, frame_rate: f64) {
        self.frame_pos = t * frame_rate;
        if self.particles.is_empty() {
            return;
        }
        for (o, tr) in objects.iter().zip(&mut self.transforms) {
            *tr = o.pin_motion.transform(t);
        }
    }

    /// The moving pins among the particles `range`: a run of the list, which is in particle
    /// order.
    pub(crate) fn within(&self, range: Range<usize>) -> &[u32] {
        let first = self
            .particles
            .partition_point(|&i| (i as usize) < range.start);
        let end = self
            .particles
            .partition_point(|&i| (i as usize) < range.end);
        &self.particles[first..end]
    }

    /// Where moving pin `i`, of object `object` and at rest at `rest`, goes at the target time.
    pub(crate) fn target(
        &self,
        objects: &[ObjectData],
        i: usize,
        object: u32,
        rest: [f64; 3],
    ) -> DVec3 {
        let o = object as usize;
        objects[o].pin_target(self.transforms[o], rest, i, self.frame_pos)
    }
}
