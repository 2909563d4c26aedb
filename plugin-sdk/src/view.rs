//! Zero-copy glam views of the boundary's slices.
//!
//! `[f64; 3]` and `glam::DVec3` have the same layout (three `f64`, `repr(C)`), and both are
//! `bytemuck::Pod`, so a slice of one is reinterpreted as a slice of the other without copying.

use abi_stable::std_types::RSlice;
use glam::DVec3;

use crate::abi::{Attribute, ObjectView, SceneView, SolveContext};

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
}

fn find_attribute<'s>(attrs: RSlice<'s, Attribute<'s>>, name: &str) -> Option<(u32, &'s [f64])> {
    attrs
        .as_slice()
        .iter()
        .find(|a| a.name.as_str() == name)
        .map(|a| (a.width, a.data.as_slice()))
}

impl<'a> SolveContext<'a> {
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
}

impl<'a> ObjectView<'a> {
    /// Whether the object's surface is closed.
    pub fn is_closed(&self) -> bool {
        self.closed != 0
    }
    /// Whether every edge is in at most two triangles.
    pub fn is_manifold(&self) -> bool {
        self.manifold != 0
    }
    /// The global particle indices of the object.
    pub fn particles(&self) -> std::ops::Range<usize> {
        self.first as usize..(self.first + self.count) as usize
    }
}
