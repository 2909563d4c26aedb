//! Scene files: what to simulate, in TOML.
//!
//! A scene has `[solver]` settings, `[[objects]]` (each with exactly one shape table: `grid`,
//! `rope`, `particles`, `tet_box`, `sphere` or `mesh`), and `[[constraints]]` groups (a kind,
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
//!
//! Here: [`Scene`] — reading, parsing, validating the settings and names, and locating errors
//! in the file. Beside it: `file` (the tables' types, re-exported here), `overrides` (`--set`)
//! and `geometry` (each object's shape, pins and masses).

mod file;
mod geometry;
mod overrides;

use std::ops::Range;
use std::path::{Path, PathBuf};

pub use file::*;
pub use geometry::Geometry;
use overrides::{apply_override, one_line, place, Origin, Place};

use crate::error::SceneError;

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
}
