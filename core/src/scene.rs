//! Scene files: what to simulate, in TOML.
//!
//! A scene has `[solver]` settings, `[[objects]]` (each with exactly one shape table:
//! `grid`, `rope`, `particles`, `tet_box` or `mesh`), and `[[constraints]]` groups (a kind,
//! the objects it applies to, its parameters, and optional order/importance overrides).
//! Every table denies unknown fields, so a misspelt key fails loudly with its line and column.
//!
//! ```toml
//! [solver]
//! frame_rate = 60.0
//! frames = 120
//! substeps = 10
//!
//! [[objects]]
//! name = "cloth"
//! mass = 1.0
//! pins = ["corners:row0"]
//! [objects.grid]
//! size = [1.0, 1.0]
//! resolution = [32, 32]
//!
//! [[constraints]]
//! kind = "stretch"
//! objects = ["cloth"]
//! params = { compliance = 0.0 }
//! ```

use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::error::SceneError;
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

/// The simplices and rest positions of one built object (local vertex indices).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Geometry {
    /// Rest positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Isolated points.
    pub points: Vec<u32>,
    /// Curve edges.
    pub edges: Vec<[u32; 2]>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Tetrahedra.
    pub tets: Vec<[u32; 4]>,
    /// Grid resolution, for grid selectors.
    pub grid: Option<[u32; 2]>,
    /// Positions per frame of an animated mesh (frame 0 first); empty if not animated.
    pub sequence: Vec<Vec<[f64; 3]>>,
}

/// A scene read from a file, with its source kept for error locations.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The parsed file.
    pub file: SceneFile,
    /// Where it came from.
    pub path: PathBuf,
    source: String,
    /// With `--set` overrides: where each line of `source` came from.
    origin: Option<Origin>,
}

/// Where the lines of a scene text with `--set` overrides came from: the overrides are made in
/// place ([`apply_override`]), so every line of the file is kept verbatim except those holding
/// an overridden value, and inserted keys add lines. `lines[k]` is the file's line (1-based)
/// that line `k + 1` of the text is, or `None` for a line an override wrote.
#[derive(Clone, Debug)]
struct Origin {
    overrides: Vec<String>,
    lines: Vec<Option<usize>>,
}

/// Where an offset of a scene's text is, for error messages.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Place {
    /// 1-based line and column in the file.
    At(usize, usize),
    /// On a line written by an override (the `--set` argument, or all of them when the line
    /// cannot be told apart).
    Override(String),
}

impl Origin {
    /// Aligns the lines of `text` (the file with the overrides made in place) with those of
    /// `file`: equal lines in order are the file's (a longest common subsequence, or a greedy
    /// match for very long texts), the rest the overrides'.
    fn new(file: &str, text: &str, overrides: &[String]) -> Origin {
        let a: Vec<&str> = text.lines().collect();
        let b: Vec<&str> = file.lines().collect();
        let mut lines = vec![None; a.len()];
        if a.len().saturating_mul(b.len()) <= 4_000_000 {
            // lcs[i][j]: the longest common subsequence of a[i..] and b[j..].
            let w = b.len() + 1;
            let mut lcs = vec![0u32; (a.len() + 1) * w];
            for i in (0..a.len()).rev() {
                for j in (0..b.len()).rev() {
                    lcs[i * w + j] = if a[i] == b[j] {
                        lcs[(i + 1) * w + j + 1] + 1
                    } else {
                        lcs[(i + 1) * w + j].max(lcs[i * w + j + 1])
                    };
                }
            }
            let (mut i, mut j) = (0, 0);
            while i < a.len() && j < b.len() {
                if a[i] == b[j] {
                    lines[i] = Some(j + 1);
                    i += 1;
                    j += 1;
                } else if lcs[(i + 1) * w + j] >= lcs[i * w + j + 1] {
                    i += 1;
                } else {
                    j += 1;
                }
            }
        } else {
            let mut j = 0;
            for (i, line) in a.iter().enumerate() {
                if let Some(k) = b[j..].iter().position(|l| l == line) {
                    j += k;
                    lines[i] = Some(j + 1);
                    j += 1;
                }
            }
        }
        Origin {
            overrides: overrides.to_vec(),
            lines,
        }
    }

    /// Where `offset` of `text` is.
    fn place(&self, text: &str, offset: usize) -> Place {
        let (line, col) = line_col(text, offset);
        match self.lines.get(line - 1) {
            Some(Some(file_line)) => Place::At(*file_line, col),
            _ => {
                // The override whose key names the line's key (`key = …`), else all of them.
                let line_text = text.lines().nth(line - 1).unwrap_or("");
                let key = line_text
                    .split('=')
                    .next()
                    .unwrap_or("")
                    .trim()
                    .trim_matches(|c| c == '"' || c == '\'' || c == '[' || c == ']');
                let named = self.overrides.iter().rev().find(|o| {
                    let path = o.split('=').next().unwrap_or("");
                    !key.is_empty() && path.trim().split('.').any(|p| p == key)
                });
                Place::Override(named.cloned().unwrap_or_else(|| self.overrides.join(" ")))
            }
        }
    }
}

/// A place in a document being overridden: a key's item, a table of an array of tables, or
/// a value inside an inline table or an array.
enum Cursor<'d> {
    Item(&'d mut toml_edit::Item),
    Table(&'d mut toml_edit::Table),
    Value(&'d mut toml_edit::Value),
}

/// `part` as an index into a list of `n` entries.
fn index(part: &str, n: usize) -> Result<usize, String> {
    let i: usize = part
        .parse()
        .map_err(|_| format!("`{part}` is not an index"))?;
    if i < n {
        Ok(i)
    } else {
        Err(format!("index {i} out of range ({n} entries)"))
    }
}

/// Sets `a.b.0.c = value` in a TOML document (numbers index arrays and arrays of tables;
/// inline tables are entered as tables; missing tables are created) **in place**: the other
/// lines keep their text, and a replaced value its line, so that error locations can be
/// given in the file ([`Origin`]).
fn apply_override(doc: &mut toml_edit::DocumentMut, assignment: &str) -> Result<(), String> {
    use toml_edit::{Item, Value};
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE".to_string())?;
    let parsed: toml_edit::DocumentMut = format!("v = {}", value.trim())
        .parse()
        .map_err(|e: toml_edit::TomlError| format!("bad value: {}", one_line(e.message())))?;
    let mut value = parsed
        .get("v")
        .and_then(Item::as_value)
        .cloned()
        .ok_or_else(|| "bad value".to_string())?;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.trim().is_empty()) {
        return Err("empty key".to_string());
    }
    let (last, path) = parts.split_last().ok_or_else(|| "empty key".to_string())?;
    let mut cur = Cursor::Table(doc.as_table_mut());
    for part in path {
        cur = match cur {
            Cursor::Table(t) | Cursor::Item(Item::Table(t)) => {
                Cursor::Item(t.entry(part).or_insert_with(toml_edit::table))
            }
            Cursor::Item(Item::ArrayOfTables(a)) => {
                let i = index(part, a.len())?;
                Cursor::Table(a.get_mut(i).expect("an index in range"))
            }
            Cursor::Item(Item::Value(v)) | Cursor::Value(v) => match v {
                Value::InlineTable(t) => Cursor::Value(
                    t.entry(*part)
                        .or_insert_with(|| Value::InlineTable(Default::default())),
                ),
                Value::Array(a) => {
                    let i = index(part, a.len())?;
                    Cursor::Value(a.get_mut(i).expect("an index in range"))
                }
                _ => return Err(format!("`{part}`: not a table")),
            },
            Cursor::Item(Item::None) => return Err(format!("`{part}`: not a table")),
        };
    }
    // A replaced value keeps the spaces around it.
    let mut replace = |old: &mut Value| {
        *value.decor_mut() = old.decor().clone();
        *old = value.clone();
    };
    match cur {
        Cursor::Table(t) | Cursor::Item(Item::Table(t)) => match t.get_mut(last) {
            Some(Item::Value(old)) => replace(old),
            Some(old) => *old = Item::Value(value),
            None => {
                t.insert(last, Item::Value(value));
            }
        },
        Cursor::Item(Item::Value(v)) | Cursor::Value(v) => match v {
            Value::InlineTable(t) => match t.get_mut(last) {
                Some(old) => replace(old),
                None => {
                    t.insert(*last, value);
                }
            },
            Value::Array(a) => {
                let i = index(last, a.len())?;
                replace(a.get_mut(i).expect("an index in range"));
            }
            _ => return Err(format!("`{last}`: parent is not a table")),
        },
        Cursor::Item(Item::ArrayOfTables(a)) => {
            let i = index(last, a.len())?;
            return Err(format!("`{last}`: entry {i} is a table; set its keys"));
        }
        Cursor::Item(Item::None) => return Err(format!("`{last}`: parent is not a table")),
    }
    Ok(())
}

/// Where byte `offset` of a scene text is: in the file, through `origin` when overrides
/// wrote the text.
fn place(text: &str, origin: Option<&Origin>, offset: usize) -> Place {
    match origin {
        Some(origin) => origin.place(text, offset),
        None => {
            let (line, col) = line_col(text, offset);
            Place::At(line, col)
        }
    }
}

/// A parser's message on one line (the TOML parsers' span several).
fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// 1-based line and column of a byte offset.
pub fn line_col(source: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(source.len());
    let before = &source[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rfind('\n').map_or(offset, |p| offset - p - 1) + 1;
    (line, col)
}

impl Scene {
    /// Reads and parses a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let source = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&source, path)
    }

    /// Reads a scene file and applies `key=value` overrides (`solver.substeps=4`,
    /// `objects.0.grid.resolution=[128,128]`; values are TOML) before parsing. The overrides
    /// are made in the file's text, so an error is located in the file (`path:line:col`), or
    /// named by the `--set` argument when it is in a value an override wrote.
    pub fn load_with_overrides(path: &Path, overrides: &[String]) -> Result<Scene, SceneError> {
        if overrides.is_empty() {
            return Self::load(path);
        }
        let source = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut doc: toml_edit::DocumentMut =
            source.parse().map_err(|e: toml_edit::TomlError| {
                let (line, col) = e.span().map_or((1, 1), |s| line_col(&source, s.start));
                SceneError::Parse {
                    path: path.to_path_buf(),
                    line,
                    col,
                    message: one_line(e.message()),
                }
            })?;
        for o in overrides {
            apply_override(&mut doc, o).map_err(|message| SceneError::Invalid {
                path: path.to_path_buf(),
                line: 0,
                col: 0,
                message: format!("--set {o}: {message}"),
            })?;
        }
        let text = doc.to_string();
        let origin = Origin::new(&source, &text, overrides);
        Self::parse_from(&text, path, Some(origin))
    }

    /// Parses scene text; `path` is used for error messages and relative mesh paths.
    pub fn parse(source: &str, path: &Path) -> Result<Scene, SceneError> {
        Self::parse_from(source, path, None)
    }

    fn parse_from(source: &str, path: &Path, origin: Option<Origin>) -> Result<Scene, SceneError> {
        let file: SceneFile = toml::from_str(source).map_err(|e| {
            let message = one_line(e.message());
            match place(source, origin.as_ref(), e.span().map_or(0, |s| s.start)) {
                Place::Override(o) => SceneError::Invalid {
                    path: path.to_path_buf(),
                    line: 0,
                    col: 0,
                    message: format!("--set {o}: {message}"),
                },
                Place::At(line, col) => SceneError::Parse {
                    path: path.to_path_buf(),
                    line,
                    col,
                    message,
                },
            }
        })?;
        let scene = Scene {
            file,
            path: path.to_path_buf(),
            source: source.to_string(),
            origin,
        };
        scene.validate()?;
        Ok(scene)
    }

    /// Where byte `offset` of the scene text is.
    fn place(&self, offset: usize) -> Place {
        place(&self.source, self.origin.as_ref(), offset)
    }

    /// `path:line:col` of byte `offset` of the scene text in the file, or `path (--set …)`
    /// when an override wrote it: for messages about a value of the scene.
    pub fn location(&self, offset: usize) -> String {
        match self.place(offset) {
            Place::At(line, col) => format!("{}:{line}:{col}", self.path.display()),
            Place::Override(o) => format!("{} (--set {o})", self.path.display()),
        }
    }

    /// The scene text.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// An error at a span of the source (in the file, or naming the `--set` that wrote it).
    pub fn invalid(&self, span: Range<usize>, message: impl Into<String>) -> SceneError {
        let (line, col, message) = match self.place(span.start) {
            Place::At(line, col) => (line, col, message.into()),
            Place::Override(o) => (0, 0, format!("--set {o}: {}", message.into())),
        };
        SceneError::Invalid {
            path: self.path.clone(),
            line,
            col,
            message,
        }
    }

    /// An error located at the start of the first line matching `needle` (for values that
    /// carry no span), or at 1:1.
    pub fn invalid_near(&self, needle: &str, message: impl Into<String>) -> SceneError {
        let offset = self.source.find(needle).unwrap_or(0);
        self.invalid(offset..offset, message)
    }

    fn validate(&self) -> Result<(), SceneError> {
        let s = &self.file.solver;
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(s.frame_rate) {
            return Err(self.invalid_near("frame_rate", "frame_rate must be a positive number"));
        }
        if s.substeps == 0 {
            return Err(self.invalid_near("substeps", "substeps must be at least 1"));
        }
        let h = 1.0 / (s.frame_rate * f64::from(s.substeps));
        if !positive(h) {
            return Err(self.invalid_near(
                "frame_rate",
                format!(
                    "the substep length 1 / (frame_rate × substeps) = {h:e} s is not a \
                     positive finite number (frame_rate {:e}, substeps {})",
                    s.frame_rate, s.substeps
                ),
            ));
        }
        if s.iterations == 0 {
            return Err(self.invalid_near("iterations", "iterations must be at least 1"));
        }
        if !s.gravity.iter().all(|g| g.is_finite()) {
            return Err(self.invalid_near("gravity", "gravity must be finite"));
        }
        // The prediction x + h v + h² g: a displacement that overflows would be caught only
        // after the next plugin ran, and blamed on it.
        let fall = h * h * s.gravity.iter().map(|g| g * g).sum::<f64>().sqrt();
        if !fall.is_finite() {
            return Err(self.invalid_near(
                "frame_rate",
                format!(
                    "gravity's displacement over one substep, h²·|g| with h = {h:e} s, \
                     overflows (frame_rate {:e}, substeps {})",
                    s.frame_rate, s.substeps
                ),
            ));
        }
        if !(s.damping.is_finite() && s.damping >= 0.0) {
            return Err(self.invalid_near("damping", "damping must be finite and >= 0"));
        }
        let mut names: Vec<&str> = Vec::new();
        for o in &self.file.objects {
            let name = o.name.get_ref();
            if name.is_empty() {
                return Err(self.invalid(o.name.span(), "object name must not be empty"));
            }
            if names.contains(&name.as_str()) {
                return Err(self.invalid(o.name.span(), format!("duplicate object `{name}`")));
            }
            names.push(name);
            let given = [
                o.mass.as_ref(),
                o.density.as_ref(),
                o.vertex_mass.as_ref(),
                o.solid_density.as_ref(),
            ];
            let mut count = 0;
            for m in given.into_iter().flatten() {
                count += 1;
                if !(m.get_ref().is_finite() && *m.get_ref() > 0.0) {
                    return Err(self.invalid(
                        m.span(),
                        format!(
                            "object `{name}`: mass must be a positive finite number, found {}",
                            m.get_ref()
                        ),
                    ));
                }
            }
            if count > 1 {
                return Err(self.invalid(
                    o.name.span(),
                    format!(
                        "object `{name}`: give only one of mass, density, vertex_mass, solid_density"
                    ),
                ));
            }
            for map in &o.mass_maps {
                let f = *map.scale.get_ref();
                if !(f.is_finite() && f > 0.0) {
                    return Err(self.invalid(
                        map.scale.span(),
                        format!(
                            "object `{name}`: a mass map's scale must be a positive finite number, found {f}"
                        ),
                    ));
                }
            }
            let m = &o.pin_motion;
            let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
            let keys_ok = m
                .keys
                .iter()
                .all(|k| k.time.is_finite() && finite(&k.translate) && finite(&k.rotate))
                && m.keys.windows(2).all(|w| w[1].time > w[0].time);
            if !(finite(&m.velocity) && finite(&m.angular_velocity) && finite(&m.pivot) && keys_ok)
            {
                return Err(self.invalid(
                    o.name.span(),
                    format!(
                        "object `{name}`: pin_motion must be finite, with keys in increasing time"
                    ),
                ));
            }
            if !m.keys.is_empty() && (m.velocity != [0.0; 3] || m.angular_velocity != [0.0; 3]) {
                return Err(self.invalid(
                    o.name.span(),
                    format!(
                        "object `{name}`: pin_motion takes either keys or velocities, not both"
                    ),
                ));
            }
            if !o.velocity.iter().all(|v| v.is_finite()) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: velocity must be finite"),
                ));
            }
        }
        for c in &self.file.constraints {
            if let Some(objs) = &c.objects {
                for obj in objs {
                    if !names.contains(&obj.get_ref().as_str()) {
                        return Err(self.invalid(
                            obj.span(),
                            format!(
                                "constraint `{}`: no object named `{}`",
                                c.kind.get_ref(),
                                obj.get_ref()
                            ),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Builds the geometry of an object (reads mesh files).
    pub fn geometry(&self, o: &ObjectSpec) -> Result<Geometry, SceneError> {
        let name = o.name.get_ref();
        let shapes = [
            o.grid.is_some(),
            o.rope.is_some(),
            o.particles.is_some(),
            o.tet_box.is_some(),
            o.mesh.is_some(),
            o.sphere.is_some(),
        ];
        let n_shapes = shapes.iter().filter(|&&b| b).count();
        if n_shapes != 1 {
            return Err(self.invalid(
                o.name.span(),
                format!(
                    "object `{name}` needs exactly one shape table (grid, rope, particles, tet_box, mesh, sphere), found {n_shapes}"
                ),
            ));
        }
        let finite3 = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
        if let Some(g) = &o.grid {
            let [nu, nv] = *g.resolution.get_ref();
            if nu < 2 || nv < 2 || (nu as u64) * (nv as u64) > 50_000_000 {
                return Err(self.invalid(
                    g.resolution.span(),
                    format!("object `{name}`: grid resolution must be at least 2 per side (and sane), found [{nu}, {nv}]"),
                ));
            }
            if !(g.size.iter().all(|s| s.is_finite() && *s > 0.0) && finite3(&g.origin)) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: grid size must be positive and origin finite"),
                ));
            }
            return Ok(crate::shapes::grid(g.size, [nu, nv], g.plane, g.origin));
        }
        if let Some(r) = &o.rope {
            let n = *r.segments.get_ref();
            if n == 0 || n > 50_000_000 {
                return Err(self.invalid(
                    r.segments.span(),
                    format!("object `{name}`: a rope needs at least 1 segment"),
                ));
            }
            if !(finite3(&r.start) && finite3(&r.end)) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: rope ends must be finite"),
                ));
            }
            if r.length.is_some_and(|l| !(l.is_finite() && l > 0.0)) {
                return Err(self.invalid(
                    r.segments.span(),
                    format!("object `{name}`: rope length must be positive"),
                ));
            }
            return Ok(crate::shapes::rope(r.start, r.end, n, r.length));
        }
        if let Some(p) = &o.particles {
            let c = *p.count.get_ref();
            if c.contains(&0) || c.iter().map(|&x| x as u64).product::<u64>() > 50_000_000 {
                return Err(self.invalid(
                    p.count.span(),
                    format!("object `{name}`: particle count must be at least 1 per axis"),
                ));
            }
            if !(finite3(&p.min) && finite3(&p.max)) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: particle box must be finite"),
                ));
            }
            return Ok(crate::shapes::particle_block(p.min, p.max, c));
        }
        if let Some(t) = &o.tet_box {
            let r = *t.resolution.get_ref();
            if r.contains(&0) || r.iter().map(|&x| x as u64).product::<u64>() > 10_000_000 {
                return Err(self.invalid(
                    t.resolution.span(),
                    format!("object `{name}`: tet_box resolution must be at least 1 per axis"),
                ));
            }
            let ok =
                (0..3).all(|k| t.min[k].is_finite() && t.max[k].is_finite() && t.max[k] > t.min[k]);
            if !ok {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: tet_box needs finite min < max"),
                ));
            }
            return Ok(crate::shapes::tet_box(t.min, t.max, r));
        }
        if let Some(sp) = &o.sphere {
            let n = *sp.subdivisions.get_ref();
            if n > 7 {
                return Err(self.invalid(
                    sp.subdivisions.span(),
                    format!("object `{name}`: at most 7 subdivisions (327,682 vertices)"),
                ));
            }
            if !(finite3(&sp.center) && sp.radius.is_finite() && sp.radius > 0.0) {
                return Err(self.invalid(
                    o.name.span(),
                    format!("object `{name}`: sphere needs a finite center and a positive radius"),
                ));
            }
            return Ok(crate::shapes::icosphere(sp.center, sp.radius, n));
        }
        let m = o.mesh.as_ref().expect("exactly one shape is set");
        let rel = m.path.get_ref();
        let full = self
            .path
            .parent()
            .map_or_else(|| rel.clone(), |d| d.join(rel));
        if !(m.scale.is_finite() && m.scale > 0.0 && finite3(&m.translate)) {
            return Err(self.invalid(
                m.path.span(),
                format!("object `{name}`: mesh scale must be positive and translate finite"),
            ));
        }
        let mut geo = crate::shapes::load_obj(&full, m.scale, m.translate).map_err(|e| {
            self.invalid(
                m.path.span(),
                format!("object `{name}`: mesh {}: {e}", full.display()),
            )
        })?;
        if let Some(pattern) = &m.sequence {
            let dir = self
                .path
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default();
            for frame in 0..=self.file.solver.frames {
                let file = dir.join(
                    pattern
                        .get_ref()
                        .replace("{frame:04}", &format!("{frame:04}"))
                        .replace("{frame}", &frame.to_string()),
                );
                if !file.is_file() {
                    if frame == 0 {
                        geo.sequence.push(geo.positions.clone());
                        continue;
                    }
                    break;
                }
                let g = crate::shapes::load_obj(&file, m.scale, m.translate).map_err(|e| {
                    self.invalid(
                        pattern.span(),
                        format!("object `{name}`: mesh {}: {e}", file.display()),
                    )
                })?;
                if g.positions.len() != geo.positions.len() || g.triangles != geo.triangles {
                    return Err(self.invalid(
                        pattern.span(),
                        format!(
                            "object `{name}`: {} does not have the same vertices and faces as {}",
                            file.display(),
                            full.display()
                        ),
                    ));
                }
                geo.sequence.push(g.positions);
            }
            if geo.sequence.len() < 2 {
                return Err(self.invalid(
                    pattern.span(),
                    format!(
                        "object `{name}`: no files match the sequence `{}`",
                        pattern.get_ref()
                    ),
                ));
            }
        }
        Ok(geo)
    }

    /// Resolves the pins of an object to local vertex indices (sorted, unique).
    pub fn pins(&self, o: &ObjectSpec, geo: &Geometry) -> Result<Vec<u32>, SceneError> {
        match &o.pins {
            Some(pins) => self.select(o, pins, geo, "pin"),
            None => Ok(Vec::new()),
        }
    }

    /// The object's per-vertex masses: `mass`, `density` or `vertex_mass`, then its mass maps.
    pub fn masses(&self, o: &ObjectSpec, geo: &Geometry) -> Result<Vec<f64>, SceneError> {
        let mut masses = match &o.solid_density {
            Some(rho) => {
                let volume = crate::shapes::enclosed_volume(geo).map_err(|e| {
                    self.invalid(
                        rho.span(),
                        format!("object `{}`: solid_density: {e}", o.name.get_ref()),
                    )
                })?;
                let lumped = crate::shapes::vertex_masses(geo, None, Some(1.0), None);
                let sum: f64 = lumped.iter().sum();
                lumped
                    .iter()
                    .map(|m| m / sum * rho.get_ref() * volume)
                    .collect()
            }
            None => crate::shapes::vertex_masses(
                geo,
                o.mass.as_ref().map(|m| *m.get_ref()),
                o.density.as_ref().map(|m| *m.get_ref()),
                o.vertex_mass.as_ref().map(|m| *m.get_ref()),
            ),
        };
        for map in &o.mass_maps {
            for i in self.select(o, &map.vertices, geo, "mass map")? {
                masses[i as usize] *= *map.scale.get_ref();
            }
        }
        Ok(masses)
    }

    /// Resolves vertex selectors of an object to local vertex indices (sorted, unique);
    /// errors name the object and `what` selects.
    fn select(
        &self,
        o: &ObjectSpec,
        selectors: &Spanned<Vec<PinSelector>>,
        geo: &Geometry,
        what: &str,
    ) -> Result<Vec<u32>, SceneError> {
        let n = geo.positions.len();
        let name = o.name.get_ref();
        let mut out = Vec::new();
        let pins = selectors;
        for sel in pins.get_ref() {
            match sel {
                PinSelector::Index(i) => {
                    if *i < 0 || *i as usize >= n {
                        return Err(self.invalid(
                            pins.span(),
                            format!("object `{name}`: {what} index {i} is out of range (the object has {n} vertices)"),
                        ));
                    }
                    out.push(*i as u32);
                }
                PinSelector::Named(s) => {
                    let found = crate::shapes::select(s, geo).ok_or_else(|| {
                        self.invalid(
                            pins.span(),
                            format!("object `{name}`: unknown {what} selector `{s}` for this shape (grids: corners:row0|rowN|col0|colN, edge:...; ropes: start, end, ends; any: all)"),
                        )
                    })?;
                    out.extend(found);
                }
                PinSelector::Box { min, max } => {
                    out.extend(geo.positions.iter().enumerate().filter_map(|(i, p)| {
                        (0..3)
                            .all(|k| p[k] >= min[k] && p[k] <= max[k])
                            .then_some(i as u32)
                    }));
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }
}
