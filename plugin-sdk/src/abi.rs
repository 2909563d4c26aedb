//! The types that cross the plugin boundary.
//!
//! Everything here is `#[repr(C)]` + `StableAbi`: abi_stable checks the whole type graph of
//! the root module when a library is loaded, so a plugin built against an incompatible SDK is
//! refused with a layout error instead of crashing. Read [the versioning rule](crate#versioning)
//! before changing anything in this file: most changes here make every built plugin unloadable.
//!
//! Plugin authors never implement these types directly: they implement
//! [`ConstraintGroup`](crate::ConstraintGroup) and export with
//! [`export_plugin!`](crate::export_plugin), and the SDK's adapter does the rest.

// abi_stable 0.11's `sabi_trait` expands to impls inside a const block.
#![allow(non_local_definitions)]

use abi_stable::{
    declare_root_module_statics,
    library::RootModule,
    sabi_trait,
    sabi_types::VersionStrings,
    std_types::{RBox, RResult, RSlice, RSliceMut, RStr, RString, RVec},
    StableAbi,
};

/// Version of the plugin ABI's *semantics* (the handshake the host checks on top of
/// abi_stable's layout check). Bump it when the meaning of a field or a call changes while the
/// layout stays the same; the host refuses plugins whose version it does not support.
pub const SDK_ABI_VERSION: u32 = 3;

/// The abi_stable version string of the root module. Its major number is the frozen
/// layout generation of [`PluginMod`]: it changes only with a breaking layout change, which
/// also bumps [`SDK_ABI_VERSION`].
pub const ROOT_MODULE_VERSION: &str = "3.0.0";

// ---------------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------------

/// What went wrong inside a plugin. A struct with an open-ended `code` (not an enum), so new
/// codes can be added without changing the layout.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, PartialEq)]
pub struct PluginError {
    /// One of the `PluginError::*` code constants; unknown codes are reported as "failed".
    pub code: u32,
    /// What the error is about: a parameter name, an object name, or empty.
    pub subject: RString,
    /// A human-readable, one-line cause.
    pub message: RString,
}

impl PluginError {
    /// A parameter given to a factory is invalid; `subject` is the parameter name.
    pub const BAD_PARAMETER: u32 = 1;
    /// An object the group is applied to cannot be used; `subject` is the object name.
    pub const BAD_OBJECT: u32 = 2;
    /// The plugin panicked; the group is poisoned and refuses further calls.
    pub const PANICKED: u32 = 3;
    /// The kind asked for is not provided by this plugin; `subject` is the kind name.
    pub const UNKNOWN_KIND: u32 = 4;
    /// Any other failure.
    pub const FAILED: u32 = 5;

    /// A new error.
    pub fn new(code: u32, subject: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            code,
            subject: RString::from(subject.into()),
            message: RString::from(message.into()),
        }
    }
    /// A parameter error naming the parameter.
    pub fn bad_parameter(name: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(Self::BAD_PARAMETER, name, message)
    }
    /// An object error naming the object.
    pub fn bad_object(name: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(Self::BAD_OBJECT, name, message)
    }
    /// Any other failure.
    pub fn failed(message: impl Into<String>) -> Self {
        Self::new(Self::FAILED, "", message)
    }
}

impl std::fmt::Display for PluginError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match self.code {
            Self::BAD_PARAMETER => "parameter",
            Self::BAD_OBJECT => "object",
            Self::PANICKED => "panicked",
            Self::UNKNOWN_KIND => "unknown kind",
            _ => "failed",
        };
        if self.subject.is_empty() {
            write!(f, "{what}: {}", self.message)
        } else {
            write!(f, "{what} `{}`: {}", self.subject, self.message)
        }
    }
}

impl std::error::Error for PluginError {}

// ---------------------------------------------------------------------------------------------
// Description of a plugin and its kinds
// ---------------------------------------------------------------------------------------------

/// The type of a constraint kind's parameter, for validation and documentation.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamType(pub u32);

impl ParamType {
    /// A real number (JSON number).
    pub const NUMBER: Self = Self(1);
    /// An integer (JSON integer).
    pub const INTEGER: Self = Self(2);
    /// A boolean.
    pub const BOOL: Self = Self(3);
    /// A 3-vector `[x, y, z]`.
    pub const VEC3: Self = Self(4);
    /// A string.
    pub const TEXT: Self = Self(5);
    /// Anything else (a table, a list); the plugin validates it.
    pub const ANY: Self = Self(6);

    /// A short name for tables and messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::NUMBER => "number",
            Self::INTEGER => "integer",
            Self::BOOL => "bool",
            Self::VEC3 => "vec3",
            Self::TEXT => "text",
            _ => "any",
        }
    }
}

/// The description of one parameter of a constraint kind.
#[repr(C)]
#[derive(StableAbi, Debug, Clone)]
pub struct ParamInfo {
    /// Name as written in a scene file.
    pub name: RString,
    /// One line saying what it does.
    pub doc: RString,
    /// Unit (SI), or empty for dimensionless.
    pub unit: RString,
    /// Value type.
    pub ty: ParamType,
    /// Default value, as JSON text.
    pub default: RString,
    /// Smallest valid value for numbers (inclusive); `-inf` if unbounded.
    pub min: f64,
    /// Largest valid value for numbers (inclusive); `+inf` if unbounded.
    pub max: f64,
}

/// The description of one constraint kind a plugin provides.
#[repr(C)]
#[derive(StableAbi, Debug, Clone)]
pub struct KindInfo {
    /// Kind name as written in a scene file (`kind = "stretch"`); unique across plugins.
    pub name: RString,
    /// One paragraph saying what the kind does.
    pub doc: RString,
    /// Default order O: groups are called in increasing order within a column.
    pub default_order: i32,
    /// Default importance I: how many times per substep the group is solved.
    pub default_importance: u32,
    /// Unit of the residual this kind reports (e.g. "strain", "rad", "m").
    pub residual_unit: RString,
    /// Its parameters.
    pub params: RVec<ParamInfo>,
}

/// What a plugin library says about itself.
#[repr(C)]
#[derive(StableAbi, Debug, Clone)]
pub struct PluginInfo {
    /// Plugin name.
    pub name: RString,
    /// Plugin version (its crate version).
    pub version: RString,
    /// The [`SDK_ABI_VERSION`] the plugin was built with.
    pub sdk_abi_version: u32,
    /// The kinds it provides.
    pub kinds: RVec<KindInfo>,
}

// ---------------------------------------------------------------------------------------------
// The scene as a factory sees it
// ---------------------------------------------------------------------------------------------

/// Two triangles sharing an edge. The shared edge `(i, j)` is oriented as it is traversed by
/// the first triangle's winding, whose third vertex is `opposite[0]`; `opposite[1]` is the
/// third vertex of the second triangle. All indices are global particle indices, except
/// `triangles`, which index [`ObjectView::triangles`].
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrianglePair {
    /// The two triangles (indices into the object's triangle list).
    pub triangles: [u32; 2],
    /// The shared edge `(i, j)`.
    pub edge: [u32; 2],
    /// The vertex of each triangle opposite the shared edge, `(k, l)`.
    pub opposite: [u32; 2],
}

/// Two edges sharing a vertex: `(i, j)` and `(j, k)`, with `j` the shared vertex (global
/// particle indices). Listed for edges that are not a face of any triangle (curves); a
/// surface's corner angles come from its triangles.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgePair {
    /// `[i, j, k]`, `j` shared.
    pub vertices: [u32; 3],
}

/// A named per-particle attribute: `data.len() == particle_count * width`.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy)]
pub struct Attribute<'a> {
    /// Attribute name (e.g. `"thickness"`).
    pub name: RStr<'a>,
    /// Values per particle.
    pub width: u32,
    /// The values, particle-major.
    pub data: RSlice<'a, f64>,
}

/// One object of the scene: a simplicial complex over a contiguous range of particles.
/// All vertex indices are global particle indices (`first..first + count`).
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy)]
pub struct ObjectView<'a> {
    /// Object name from the scene.
    pub name: RStr<'a>,
    /// First particle of the object.
    pub first: u32,
    /// Number of particles.
    pub count: u32,
    /// Isolated points: vertices that are not a face of any edge, triangle or tet.
    pub points: RSlice<'a, u32>,
    /// Every 1-simplex, given or derived as a face of a triangle or tet, sorted `[lo, hi]`.
    pub edges: RSlice<'a, [u32; 2]>,
    /// For each edge, how many triangles contain it (0: a curve edge, 1: boundary, 2: interior).
    pub edge_triangle_count: RSlice<'a, u32>,
    /// Every 2-simplex, given or derived as a face of a tet, in its given winding (tet faces
    /// are wound outward from their first tet).
    pub triangles: RSlice<'a, [u32; 3]>,
    /// For each triangle, how many tets contain it (0: a surface of its own, 1: on a solid's
    /// boundary, 2: inside a solid).
    pub triangle_tet_count: RSlice<'a, u32>,
    /// Every 3-simplex as given.
    pub tets: RSlice<'a, [u32; 4]>,
    /// Triangle pairs sharing an edge, with opposite vertices.
    pub triangle_pairs: RSlice<'a, TrianglePair>,
    /// Curve edge pairs sharing a vertex.
    pub edge_pairs: RSlice<'a, EdgePair>,
    /// Edges on the boundary of the surface (in exactly one triangle).
    pub boundary_edges: RSlice<'a, [u32; 2]>,
    /// 1 if the surface is closed (it has triangles and no boundary edge), else 0.
    pub closed: u8,
    /// 1 if every triangle is in at most two tets and every edge in at most two *surface*
    /// triangles (those not shared by two tets), else 0.
    pub manifold: u8,
}

/// The read-only view of the scene a factory receives.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy)]
pub struct SceneView<'a> {
    /// Every object of the scene.
    pub objects: RSlice<'a, ObjectView<'a>>,
    /// The objects this group applies to (indices into `objects`).
    pub targets: RSlice<'a, u32>,
    /// Rest positions of all particles (m).
    pub rest: RSlice<'a, [f64; 3]>,
    /// Inverse masses of all particles (1/kg); 0 for kinematic particles.
    pub inv_mass: RSlice<'a, f64>,
    /// Named per-particle attributes.
    pub attributes: RSlice<'a, Attribute<'a>>,
    /// Gravity (m/s²).
    pub gravity: [f64; 3],
    /// Frame length (s).
    pub frame_dt: f64,
    /// Substeps per frame.
    pub substeps: u32,
}

// ---------------------------------------------------------------------------------------------
// The solve context a group receives at every call
// ---------------------------------------------------------------------------------------------

/// Particle flag: the particle is kinematic (pinned or animated); its inverse mass is 0.
pub const FLAG_KINEMATIC: u32 = 1;

/// Everything a group sees during a step. Positions and velocities are mutable; the rest is
/// read-only. State is `f64`: a 1 m cloth at 0.1 mm accuracy under hard constraints
/// accumulates millions of tiny corrections per second, and `f32`'s 7 digits turn them into
/// drift and jitter; `f64` costs little on CPUs and makes conservation tests meaningful.
#[repr(C)]
#[derive(StableAbi, Debug)]
pub struct SolveContext<'a> {
    /// Positions being solved (m).
    pub x: RSliceMut<'a, [f64; 3]>,
    /// Velocities (m/s).
    pub v: RSliceMut<'a, [f64; 3]>,
    /// Positions at the start of the substep (m).
    pub x0: RSlice<'a, [f64; 3]>,
    /// Inverse masses (1/kg); 0 for kinematic particles.
    pub inv_mass: RSlice<'a, f64>,
    /// Object index of each particle.
    pub object: RSlice<'a, u32>,
    /// Flags of each particle (`FLAG_*`).
    pub flags: RSlice<'a, u32>,
    /// Named per-particle attributes.
    pub attributes: RSlice<'a, Attribute<'a>>,
    /// Substep length (s).
    pub h: f64,
    /// Simulated time at the start of this substep (s).
    pub time: f64,
    /// Gravity (m/s²).
    pub gravity: [f64; 3],
    /// Frame index (0-based).
    pub frame: u64,
    /// Substep index within the frame.
    pub substep: u32,
    /// Substeps per frame.
    pub substeps: u32,
    /// Which of this group's passes this is within the substep (0-based).
    pub pass: u32,
    /// How many passes this group gets in this substep (its importance).
    pub passes: u32,
    /// The host's thread team, for a group to split a pass over (see [`crate::team`]).
    pub team: crate::team::TeamRef<'a>,
    /// What constraints against immovable things (kinematic colliders) moved each particle by
    /// (m), summed since the substep's prediction or since a reader last cleared it; empty
    /// unless a group of the scene has [`Stages::TAKES_PUSHES`] and one has
    /// [`Stages::GIVES_PUSHES`]. A group that moves
    /// particles against something that cannot move back adds each displacement here when
    /// the slice is not empty; a group that moves particles as parts of a larger body (a rigid
    /// body) reads them as pushes on the body, answers them with the body's own mass, and
    /// sets the entries it read back to 0. The core zeroes them after the prediction.
    pub pushes: RSliceMut<'a, [f64; 3]>,
    /// The same for velocity changes (m/s) made at the velocity level, after the velocity
    /// update (restitution against a collider): written in `end_substep`, so a reader finds
    /// them in the next substep, where they moved the particle by `h Δv` in the prediction;
    /// zeroed by the core before the next `end_substep` stage.
    pub kicks: RSliceMut<'a, [f64; 3]>,
}

/// How far a group's constraints are from satisfied, in the kind's own unit, plus the
/// potential energy they store.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, Default, PartialEq)]
pub struct Residual {
    /// Number of constraints measured.
    pub count: u64,
    /// Largest absolute violation.
    pub max: f64,
    /// Root mean square violation.
    pub rms: f64,
    /// Potential energy stored in the group's soft constraints (J); 0 if not applicable.
    pub energy: f64,
}

/// A named value a group reports once per frame (written to the stats).
#[repr(C)]
#[derive(StableAbi, Debug, Clone)]
pub struct Stat {
    /// Column name; the host prefixes it with the group name.
    pub name: RString,
    /// The value.
    pub value: f64,
}

/// Which optional stages a group implements; the core never calls the others.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stages(pub u32);

impl Stages {
    /// No optional stage.
    pub const NONE: Self = Self(0);
    /// `force`: velocity level, before prediction.
    pub const FORCE: Self = Self(1);
    /// `begin_substep`: after prediction, before the first projection.
    pub const BEGIN_SUBSTEP: Self = Self(2);
    /// `project`: scheduled `importance` times per substep.
    pub const PROJECT: Self = Self(4);
    /// `end_substep`: velocity level, after the velocity update.
    pub const END_SUBSTEP: Self = Self(8);
    /// `report`: named values once per frame.
    pub const REPORT: Self = Self(16);
    /// Not a stage: the group reads [`SolveContext::pushes`] and [`SolveContext::kicks`].
    /// The core keeps them only for a scene with a group that takes them and one that gives
    /// them ([`Stages::GIVES_PUSHES`]); otherwise they are empty and writers skip them.
    pub const TAKES_PUSHES: Self = Self(32);
    /// Not a stage: the group writes [`SolveContext::pushes`] or [`SolveContext::kicks`]
    /// when they are not empty.
    pub const GIVES_PUSHES: Self = Self(64);

    /// Whether every stage of `other` is in `self`.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
}

impl std::ops::BitOr for Stages {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        Self(self.0 | rhs.0)
    }
}

/// The constraint group as it crosses the boundary. Plugin authors implement
/// [`ConstraintGroup`](crate::ConstraintGroup) instead; the SDK adapts it.
///
/// Every call is per group, never per constraint.
#[sabi_trait]
pub trait GroupAbi: Send {
    /// The optional stages implemented.
    fn stages(&self) -> Stages;
    /// Number of constraints the group owns.
    fn constraint_count(&self) -> u64;
    /// Velocity-level forces, before prediction.
    fn force(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError>;
    /// Start of a substep, after prediction.
    fn begin_substep(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError>;
    /// One Gauss-Seidel pass over every constraint.
    fn project(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError>;
    /// End of a substep, after the velocity update.
    fn end_substep(&mut self, ctx: &mut SolveContext<'_>) -> RResult<(), PluginError>;
    /// The group's residual at the current positions.
    fn residual(&self, ctx: &SolveContext<'_>) -> RResult<Residual, PluginError>;
    /// Named values for the stats, once per frame.
    #[sabi(last_prefix_field)]
    fn report(&self, ctx: &SolveContext<'_>) -> RResult<RVec<Stat>, PluginError>;
}

/// A boxed constraint group crossing the boundary.
pub type GroupBox = GroupAbi_TO<'static, RBox<()>>;

// ---------------------------------------------------------------------------------------------
// The root module
// ---------------------------------------------------------------------------------------------

/// The root module every plugin library exports. Small and frozen: see
/// [the versioning rule](crate#versioning).
#[repr(C)]
#[derive(StableAbi)]
#[sabi(kind(Prefix(prefix_ref = PluginModRef)))]
#[sabi(missing_field(panic))]
pub struct PluginMod {
    /// The [`SDK_ABI_VERSION`] the plugin was built with.
    pub sdk_abi_version: u32,
    /// The plugin's name, version and kinds.
    pub describe: extern "C" fn() -> RResult<PluginInfo, PluginError>,
    /// Builds the group of `kind` for a scene from the kind's parameters (JSON text).
    #[sabi(last_prefix_field)]
    pub create_group: extern "C" fn(
        kind: RStr<'_>,
        params_json: RStr<'_>,
        scene: &SceneView<'_>,
    ) -> RResult<GroupBox, PluginError>,
}

impl RootModule for PluginModRef {
    declare_root_module_statics! {PluginModRef}
    const BASE_NAME: &'static str = "nucleus_plugin";
    const NAME: &'static str = "nucleus_plugin";
    const VERSION_STRINGS: VersionStrings = VersionStrings::new(ROOT_MODULE_VERSION);
}
