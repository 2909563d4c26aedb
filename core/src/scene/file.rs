//! What a scene file may hold: the serde types of its tables, each denying unknown fields.

use std::path::PathBuf;

use serde::Deserialize;
use toml::Spanned;

use crate::schedule::ScheduleMode;

/// Solver settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// Frames per second of the output (Hz). Default 60.
    pub frame_rate: f64,
    /// Frames to simulate. Default 120.
    pub frames: u32,
    /// Substeps per frame (each a full predict/solve/update). Default 10.
    pub substeps: u32,
    /// Multiplier on every group's importance (passes per substep). Default 1.
    pub iterations: u32,
    /// Interleaved (paper, Fig. 13) or sequential schedule. Default interleaved.
    pub schedule: ScheduleMode,
    /// Gravity (m/s²). Default `[0, -9.81, 0]`.
    pub gravity: [f64; 3],
    /// Linear velocity damping (1/s): `v *= exp(-damping h)` each substep. Default 0.
    pub damping: f64,
    /// Check positions/velocities for NaN/Inf after every plugin call. Default true.
    pub check_finite: bool,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            frame_rate: 60.0,
            frames: 120,
            substeps: 10,
            iterations: 1,
            schedule: ScheduleMode::Interleaved,
            gravity: [0.0, -9.81, 0.0],
            damping: 0.0,
            check_finite: true,
        }
    }
}

/// The plane a grid lies in: vertex `(i, j)` sits at `origin + j·du·U + i·dv·V`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum Plane {
    /// U = x, V = z (horizontal; the default).
    #[default]
    Xz,
    /// U = x, V = y (vertical).
    Xy,
    /// U = y, V = z.
    Yz,
}

/// A rectangular cloth: `resolution = [nu, nv]` vertices, split into two triangles per quad
/// along the same diagonal. Rows `i` run along V, columns `j` along U.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Side lengths `[along U, along V]` (m).
    pub size: [f64; 2],
    /// Vertices per side `[along U, along V]`, each >= 2.
    pub resolution: Spanned<[u32; 2]>,
    /// Plane of the grid. Default `xz`.
    #[serde(default)]
    pub plane: Plane,
    /// Position of vertex (0, 0) (m). Default origin.
    #[serde(default)]
    pub origin: [f64; 3],
}

/// A polyline (rope, hair, chain) from `start` to `end` with `segments` edges.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RopeSpec {
    /// First vertex (m).
    pub start: [f64; 3],
    /// Last vertex (m).
    pub end: [f64; 3],
    /// Number of edges, >= 1.
    pub segments: Spanned<u32>,
    /// Rope length (m); if longer than the distance between the ends, the rope starts as a
    /// V hanging between them. Default: the distance between the ends.
    pub length: Option<f64>,
}

/// Unconnected particles on a regular lattice filling a box.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticlesSpec {
    /// Box corner (m).
    pub min: [f64; 3],
    /// Opposite corner (m).
    pub max: [f64; 3],
    /// Particles per axis, each >= 1.
    pub count: Spanned<[u32; 3]>,
}

/// A box of tetrahedra: `resolution` cells per axis, six tets per cell.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TetBoxSpec {
    /// Box corner (m).
    pub min: [f64; 3],
    /// Opposite corner (m).
    pub max: [f64; 3],
    /// Cells per axis, each >= 1.
    pub resolution: Spanned<[u32; 3]>,
}

/// A closed sphere surface (icosphere), normals pointing out.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSpec {
    /// Centre (m).
    pub center: [f64; 3],
    /// Radius (m).
    pub radius: f64,
    /// Subdivisions of the icosahedron (0: 20 triangles; each level ×4). Default 2.
    #[serde(default = "two")]
    pub subdivisions: Spanned<u32>,
}

fn two() -> Spanned<u32> {
    Spanned::new(0..0, 2)
}

/// A triangle (and polyline) mesh from an OBJ file, relative to the scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// Path of the OBJ file, relative to the scene file.
    pub path: Spanned<PathBuf>,
    /// Uniform scale. Default 1.
    #[serde(default = "one")]
    pub scale: f64,
    /// Translation after scaling (m). Default 0.
    #[serde(default)]
    pub translate: [f64; 3],
    /// An animated mesh: a file pattern with `{frame}` (or `{frame:04}` for zero padding),
    /// relative to the scene file, read for frames 0..=frames (the last file found is held).
    /// Every file must have the same vertices and faces as `path`; pinned vertices follow
    /// it, interpolated linearly within each frame.
    pub sequence: Option<Spanned<String>>,
}

fn one() -> f64 {
    1.0
}

/// Motion of an object's pinned (kinematic) vertices: a rigid motion about `pivot`, either
/// at constant velocity or through keyframes. A vertex at rest position `r` is at
/// `pivot + R(t) (r − pivot) + T(t)` at time `t`.
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PinMotion {
    /// Linear velocity (m/s): `T(t) = velocity · t`.
    pub velocity: [f64; 3],
    /// Angular velocity (rad/s), about `pivot`: `R(t) = exp(angular_velocity · t)`.
    pub angular_velocity: [f64; 3],
    /// Centre of rotation (m).
    pub pivot: [f64; 3],
    /// Keyframes (instead of the velocities): translation interpolated linearly, rotation by
    /// slerp, held constant before the first and after the last key.
    pub keys: Vec<Keyframe>,
}

/// A keyframe of a rigid pin motion.
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Keyframe {
    /// Time (s).
    pub time: f64,
    /// Translation (m).
    pub translate: [f64; 3],
    /// Rotation as an axis-angle vector (rad), about the motion's pivot.
    pub rotate: [f64; 3],
}

impl PinMotion {
    /// Whether the pins move at all.
    pub fn is_moving(&self) -> bool {
        self.velocity != [0.0; 3] || self.angular_velocity != [0.0; 3] || !self.keys.is_empty()
    }

    /// The rigid transform `(R, T)` at time `t`.
    pub fn transform(&self, t: f64) -> (glam::DQuat, glam::DVec3) {
        use glam::{DQuat, DVec3};
        if self.keys.is_empty() {
            return (
                DQuat::from_scaled_axis(DVec3::from_array(self.angular_velocity) * t),
                DVec3::from_array(self.velocity) * t,
            );
        }
        let key = |k: &Keyframe| {
            (
                DQuat::from_scaled_axis(DVec3::from_array(k.rotate)),
                DVec3::from_array(k.translate),
            )
        };
        let keys = &self.keys;
        let after = keys.partition_point(|k| k.time <= t);
        if after == 0 {
            return key(&keys[0]);
        }
        if after == keys.len() {
            return key(&keys[keys.len() - 1]);
        }
        let (k0, k1) = (&keys[after - 1], &keys[after]);
        let s = ((t - k0.time) / (k1.time - k0.time)).clamp(0.0, 1.0);
        let (r0, t0) = key(k0);
        let (r1, t1) = key(k1);
        (r0.slerp(r1, s), t0.lerp(t1, s))
    }
}

/// A pin selector: a vertex index, a named selector, or a box in the rest pose.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum PinSelector {
    /// A vertex index (0-based, within the object).
    Index(i64),
    /// A named selector: `corners:row0` / `corners:rowN` / `corners:col0` / `corners:colN`
    /// (the two corners of that edge of a grid), `edge:row0` ... (all vertices of that grid
    /// edge), `start` / `end` / `ends` (of a rope), `all`.
    Named(String),
    /// Every vertex inside the axis-aligned box (rest pose).
    Box {
        /// Box corner (m).
        min: [f64; 3],
        /// Opposite corner (m).
        max: [f64; 3],
    },
}

/// A mass map: the selected vertices' mass is multiplied by `scale`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MassMap {
    /// The vertices, chosen as pins are (indices, named selectors, boxes).
    pub vertices: Spanned<Vec<PinSelector>>,
    /// Factor on their mass (dimensionless, positive and finite).
    pub scale: Spanned<f64>,
}

/// An object of the scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Unique name, used by constraint groups and in the output.
    pub name: Spanned<String>,
    /// Total mass (kg), spread evenly over the vertices. Default 1 kg if no mass is given.
    pub mass: Option<Spanned<f64>>,
    /// Density, lumped to the vertices by the measure of the highest simplices
    /// (kg/m for curves, kg/m² for surfaces, kg/m³ for solids).
    pub density: Option<Spanned<f64>>,
    /// Mass of every vertex (kg).
    pub vertex_mass: Option<Spanned<f64>>,
    /// Density of the solid a closed surface (or tetrahedral mesh) encloses (kg/m³): the
    /// object's mass is `solid_density × enclosed volume`, lumped to the vertices by surface
    /// area (or by tet volume). A rigid ball made of a surface gets a ball's mass this way.
    pub solid_density: Option<Spanned<f64>>,
    /// Mass maps, applied in order after `mass` / `density` / `vertex_mass`: the mass of the
    /// selected vertices is multiplied by `scale` (a heavy hem, a light fringe).
    #[serde(default)]
    pub mass_maps: Vec<MassMap>,
    /// Initial velocity (m/s).
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Vertices that are kinematic (pinned; inverse mass 0).
    pub pins: Option<Spanned<Vec<PinSelector>>>,
    /// How pinned vertices move. Default: they stay put.
    #[serde(default)]
    pub pin_motion: PinMotion,
    /// A grid cloth.
    pub grid: Option<GridSpec>,
    /// A rope.
    pub rope: Option<RopeSpec>,
    /// A particle block.
    pub particles: Option<ParticlesSpec>,
    /// A tetrahedral box.
    pub tet_box: Option<TetBoxSpec>,
    /// An OBJ mesh.
    pub mesh: Option<MeshSpec>,
    /// A sphere surface.
    pub sphere: Option<SphereSpec>,
}

/// A constraint group: one kind over some objects.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConstraintSpec {
    /// The kind (as listed by `nucleus plugins`).
    pub kind: Spanned<String>,
    /// Group name in stats and errors. Default `<kind>` (or `<kind>#<n>` if repeated).
    pub name: Option<String>,
    /// Objects the group applies to. Default: every object.
    pub objects: Option<Vec<Spanned<String>>>,
    /// Order override.
    pub order: Option<i32>,
    /// Importance override.
    pub importance: Option<u32>,
    /// The kind's parameters.
    pub params: Option<Spanned<toml::Table>>,
}

/// Output settings.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSpec {
    /// Write an OBJ every `obj_every` frames (0: never). Default 1.
    pub obj_every: Option<u32>,
}

/// A whole scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Solver settings.
    #[serde(default)]
    pub solver: SolverSettings,
    /// Objects.
    #[serde(default)]
    pub objects: Vec<ObjectSpec>,
    /// Constraint groups.
    #[serde(default)]
    pub constraints: Vec<ConstraintSpec>,
    /// Output settings.
    #[serde(default)]
    pub output: OutputSpec,
}
