//! Zero-copy glam views of the boundary's slices.
//!
//! `[f64; 3]` and `glam::DVec3` have the same layout (three `f64`, `repr(C)`), and both are
//! `bytemuck::Pod`, so a slice of one is reinterpreted as a slice of the other without copying.

use abi_stable::std_types::RSlice;
use glam::DVec3;

use crate::abi::{Attribute, ObjectView, PluginError, SceneView, SolveContext};

/// `[[f64; 3]]` as `[DVec3]`.
pub fn as_dvec3(s: &[[f64; 3]]) -> &[DVec3] {
    bytemuck::cast_slice(s)
}

/// `[[f64; 3]]` as `[DVec3]`, mutably.
pub fn as_dvec3_mut(s: &mut [[f64; 3]]) -> &mut [DVec3] {
    bytemuck::cast_slice_mut(s)
}

/// The particle state split into its slices, positions and velocities mutable.
pub struct Particles<'c> {
    /// Positions being solved (m).
    pub x: &'c mut [DVec3],
    /// Velocities (m/s).
    pub v: &'c mut [DVec3],
    /// Positions at the start of the substep (m).
    pub x0: &'c [DVec3],
    /// Inverse masses (1/kg).
    pub inv_mass: &'c [f64],
    /// Object index per particle.
    pub object: &'c [u32],
    /// Flags per particle.
    pub flags: &'c [u32],
    /// Displacements by constraints against kinematic colliders (m), or empty
    /// ([`SolveContext::pushes`]).
    pub pushes: &'c mut [DVec3],
    /// Velocity changes by the same (m/s), or empty ([`SolveContext::kicks`]).
    pub kicks: &'c mut [DVec3],
}

fn find_attribute<'s>(attrs: RSlice<'s, Attribute<'s>>, name: &str) -> Option<(u32, &'s [f64])> {
    attrs
        .as_slice()
        .iter()
        .find(|a| a.name.as_str() == name)
        .map(|a| (a.width, a.data.as_slice()))
}

impl<'a> SolveContext<'a> {
    /// The substep length `h` (s), or an error if it is not a positive finite number: the
    /// check a group's `project` makes before dividing by it.
    pub fn substep_length(&self) -> Result<f64, PluginError> {
        let h = self.h;
        if h.is_finite() && h > 0.0 {
            Ok(h)
        } else {
            Err(PluginError::failed(format!(
                "the substep length must be positive, got {h}"
            )))
        }
    }

    /// An error unless every particle slice holds index `max_index` (`None`: a group with no
    /// particle, always fine): the check a group makes before indexing the state with the
    /// indices it was built with.
    pub fn check_holds(&self, max_index: Option<u32>) -> Result<(), PluginError> {
        let len = self
            .x
            .len()
            .min(self.v.len())
            .min(self.x0.len())
            .min(self.inv_mass.len());
        match max_index {
            Some(m) if m as usize >= len => Err(PluginError::failed(format!(
                "the group refers to particle {m} but the state has {len} particles"
            ))),
            _ => Ok(()),
        }
    }

    /// A context over particle arrays of one length for a substep of `h` seconds, as a
    /// plugin's own tests and benchmarks need it (the core builds its contexts itself): no
    /// attributes, no gravity, time 0, frame 0, the first of one substep and of one pass.
    /// Change any of these with struct update syntax:
    ///
    /// ```
    /// # use nucleus_sdk::SolveContext;
    /// let (mut x, mut v) = (vec![[0.0; 3]; 2], vec![[0.0; 3]; 2]);
    /// let (x0, inv_mass, object, flags) = (x.clone(), vec![1.0; 2], vec![0; 2], vec![0; 2]);
    /// let ctx = SolveContext {
    ///     gravity: [0.0, -9.81, 0.0],
    ///     substeps: 10,
    ///     ..SolveContext::new(&mut x, &mut v, &x0, &inv_mass, &object, &flags, 1.0 / 600.0)
    /// };
    /// assert_eq!(ctx.positions().len(), 2);
    /// ```
    pub fn new(
        x: &'a mut [[f64; 3]],
        v: &'a mut [[f64; 3]],
        x0: &'a [[f64; 3]],
        inv_mass: &'a [f64],
        object: &'a [u32],
        flags: &'a [u32],
        h: f64,
    ) -> Self {
        SolveContext {
            x: abi_stable::std_types::RSliceMut::from_mut_slice(x),
            v: abi_stable::std_types::RSliceMut::from_mut_slice(v),
            x0: RSlice::from_slice(x0),
            inv_mass: RSlice::from_slice(inv_mass),
            object: RSlice::from_slice(object),
            flags: RSlice::from_slice(flags),
            attributes: RSlice::EMPTY,
            h,
            time: 0.0,
            gravity: [0.0; 3],
            frame: 0,
            substep: 0,
            substeps: 1,
            pass: 0,
            passes: 1,
            team: crate::team::TeamRef::serial(),
            pushes: abi_stable::std_types::RSliceMut::from_mut_slice(&mut []),
            kicks: abi_stable::std_types::RSliceMut::from_mut_slice(&mut []),
        }
    }

    /// All slices at once, positions and velocities mutable.
    pub fn particles(&mut self) -> Particles<'_> {
        Particles {
            x: as_dvec3_mut(self.x.as_mut_slice()),
            v: as_dvec3_mut(self.v.as_mut_slice()),
            x0: as_dvec3(self.x0.as_slice()),
            inv_mass: self.inv_mass.as_slice(),
            object: self.object.as_slice(),
            flags: self.flags.as_slice(),
            pushes: as_dvec3_mut(self.pushes.as_mut_slice()),
            kicks: as_dvec3_mut(self.kicks.as_mut_slice()),
        }
    }
    /// Positions (m).
    pub fn positions(&self) -> &[DVec3] {
        as_dvec3(self.x.as_slice())
    }
    /// Velocities (m/s).
    pub fn velocities(&self) -> &[DVec3] {
        as_dvec3(self.v.as_slice())
    }
    /// Positions at the start of the substep (m).
    pub fn start_positions(&self) -> &[DVec3] {
        as_dvec3(self.x0.as_slice())
    }
    /// Gravity as a vector.
    pub fn gravity(&self) -> DVec3 {
        DVec3::from_array(self.gravity)
    }
    /// A named per-particle attribute: `(width, data)`.
    pub fn attribute(&self, name: &str) -> Option<(u32, &[f64])> {
        find_attribute(self.attributes, name)
    }
}

impl<'a> SceneView<'a> {
    /// The scene view a factory receives, from its parts: no attributes, no gravity, frame
    /// length 1/60 s, one substep (other fields by struct update syntax). For a plugin's tests
    /// and benchmarks; the host builds its own.
    pub fn new(
        objects: &'a [ObjectView<'a>],
        targets: &'a [u32],
        rest: &'a [[f64; 3]],
        inv_mass: &'a [f64],
    ) -> Self {
        SceneView {
            objects: RSlice::from_slice(objects),
            targets: RSlice::from_slice(targets),
            rest: RSlice::from_slice(rest),
            inv_mass: RSlice::from_slice(inv_mass),
            attributes: RSlice::EMPTY,
            gravity: [0.0; 3],
            frame_dt: 1.0 / 60.0,
            substeps: 1,
        }
    }

    /// Rest positions of all particles.
    pub fn rest_positions(&self) -> &'a [DVec3] {
        as_dvec3(self.rest.as_slice())
    }
    /// The objects this group applies to.
    pub fn targets(&self) -> impl Iterator<Item = &'a ObjectView<'a>> + 'a {
        let objects = self.objects.as_slice();
        self.targets
            .as_slice()
            .iter()
            .filter_map(move |&i| objects.get(i as usize))
    }
    /// A named per-particle attribute: `(width, data)`.
    pub fn attribute(&self, name: &str) -> Option<(u32, &'a [f64])> {
        find_attribute(self.attributes, name)
    }

    /// The objects this group applies to, each once, in the order first listed, with its
    /// index in [`objects`](Self::objects): what a factory builds its constraints from.
    ///
    /// Errors: a target index outside the scene's objects; an object whose particles
    /// `first..first + count` are not all particles of the scene (fewer rest positions or
    /// inverse masses than that), naming the object.
    pub fn unique_targets(&self) -> Result<Vec<(u32, &'a ObjectView<'a>)>, PluginError> {
        let objects = self.objects.as_slice();
        let particles = self.rest.len().min(self.inv_mass.len());
        let mut out: Vec<(u32, &'a ObjectView<'a>)> = Vec::with_capacity(self.targets.len());
        for &t in self.targets.as_slice() {
            let object = objects.get(t as usize).ok_or_else(|| {
                PluginError::failed(format!(
                    "target {t} is not an object of the scene ({} objects)",
                    objects.len()
                ))
            })?;
            // In u64: `first + count` may not fit the u32 of a corrupt view.
            let end = u64::from(object.first) + u64::from(object.count);
            if end > particles as u64 {
                return Err(PluginError::bad_object(
                    object.name.as_str(),
                    format!(
                        "its particles {}..{end} are outside the scene's {particles}",
                        object.first
                    ),
                ));
            }
            if !out.iter().any(|&(u, _)| u == t) {
                out.push((t, object));
            }
        }
        Ok(out)
    }
}

impl<'a> ObjectView<'a> {
    /// An object named `name` owning particles `first..first + count`, with no simplices, open
    /// and manifold: for a plugin's tests and benchmarks, which set the simplices they need by
    /// struct update syntax.
    ///
    /// ```
    /// use nucleus_sdk::abi_stable::std_types::RSlice;
    /// use nucleus_sdk::ObjectView;
    /// let edges = [[0, 1], [1, 2]];
    /// let rope = ObjectView {
    ///     edges: RSlice::from_slice(&edges),
    ///     ..ObjectView::new("rope", 0, 3)
    /// };
    /// assert_eq!(rope.particles(), 0..3);
    /// ```
    pub fn new(name: &'a str, first: u32, count: u32) -> Self {
        ObjectView {
            name: name.into(),
            first,
            count,
            points: RSlice::EMPTY,
            edges: RSlice::EMPTY,
            edge_triangle_count: RSlice::EMPTY,
            triangles: RSlice::EMPTY,
            triangle_tet_count: RSlice::EMPTY,
            tets: RSlice::EMPTY,
            triangle_pairs: RSlice::EMPTY,
            edge_pairs: RSlice::EMPTY,
            boundary_edges: RSlice::EMPTY,
            closed: 0,
            manifold: 1,
        }
    }

    /// Whether the object's surface is closed.
    pub fn is_closed(&self) -> bool {
        self.closed != 0
    }
    /// Whether every edge is in at most two triangles.
    pub fn is_manifold(&self) -> bool {
        self.manifold != 0
    }
    /// The global particle indices of the object (summed in `usize`, so a corrupt view whose
    /// `first + count` overflows a `u32` gives a range past the scene rather than a panic).
    pub fn particles(&self) -> std::ops::Range<usize> {
        self.first as usize..self.first as usize + self.count as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unique_targets_lists_each_object_once_in_the_order_first_listed() {
        let objects = [
            ObjectView::new("a", 0, 2),
            ObjectView::new("b", 2, 3),
            ObjectView::new("c", 5, 1),
        ];
        let (rest, w) = ([[0.0; 3]; 6], [1.0; 6]);
        let targets = [2, 0, 2, 0, 1];
        let s = SceneView::new(&objects, &targets, &rest, &w);
        let got: Vec<(u32, &str)> = s
            .unique_targets()
            .unwrap()
            .iter()
            .map(|(t, o)| (*t, o.name.as_str()))
            .collect();
        assert_eq!(got, [(2, "c"), (0, "a"), (1, "b")]);
    }

    #[test]
    fn unique_targets_refuses_a_target_outside_the_scene() {
        let objects = [ObjectView::new("a", 0, 2)];
        let (rest, w) = ([[0.0; 3]; 2], [1.0; 2]);
        let e = SceneView::new(&objects, &[0, 3], &rest, &w)
            .unique_targets()
            .unwrap_err();
        assert_eq!(e.code, PluginError::FAILED);
        assert!(
            e.message
                .contains("target 3 is not an object of the scene (1 objects)"),
            "{}",
            e.message
        );
    }

    #[test]
    fn unique_targets_refuses_an_object_beyond_the_particles_naming_it() {
        // Three rest positions but two inverse masses: the scene has two particles.
        let objects = [ObjectView::new("a", 0, 1), ObjectView::new("sheet", 1, 2)];
        let (rest, w) = ([[0.0; 3]; 3], [1.0; 2]);
        let e = SceneView::new(&objects, &[0, 1], &rest, &w)
            .unique_targets()
            .unwrap_err();
        assert_eq!(e.code, PluginError::BAD_OBJECT);
        assert_eq!(e.subject.as_str(), "sheet");
        assert!(e.message.contains("1..3"), "{}", e.message);
        // A count whose end does not fit a u32 is refused, not wrapped.
        let objects = [ObjectView::new("huge", u32::MAX, 2)];
        let e = SceneView::new(&objects, &[0], &rest, &w)
            .unique_targets()
            .unwrap_err();
        assert_eq!(e.subject.as_str(), "huge");
    }

    #[test]
    fn the_substep_length_must_be_a_positive_finite_number() {
        let (mut x, mut v) = ([[0.0; 3]; 2], [[0.0; 3]; 2]);
        let (x0, w, o, f) = ([[0.0; 3]; 2], [1.0; 2], [0u32; 2], [0u32; 2]);
        for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let ctx = SolveContext::new(&mut x, &mut v, &x0, &w, &o, &f, h);
            let e = ctx.substep_length().unwrap_err();
            assert!(e.message.contains("substep length"), "{h}: {}", e.message);
        }
        let ctx = SolveContext::new(&mut x, &mut v, &x0, &w, &o, &f, 1e-3);
        assert_eq!(ctx.substep_length().unwrap(), 1e-3);
    }

    #[test]
    fn check_holds_refuses_an_index_past_the_shortest_particle_slice() {
        let (mut x, mut v) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
        let (x0, w, o, f) = ([[0.0; 3]; 3], [1.0; 2], [0u32; 3], [0u32; 3]);
        let ctx = SolveContext::new(&mut x, &mut v, &x0, &w, &o, &f, 1e-3);
        assert!(ctx.check_holds(None).is_ok());
        assert!(ctx.check_holds(Some(1)).is_ok());
        // Two inverse masses: index 2 is past them although x holds it.
        let e = ctx.check_holds(Some(2)).unwrap_err();
        assert!(
            e.message
                .contains("refers to particle 2 but the state has 2 particles"),
            "{}",
            e.message
        );
    }
}
