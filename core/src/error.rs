//! Every error the core returns, by where it happens: reading a scene ([`SceneError`]),
//! loading plugins ([`PluginLoadError`]), building a simulation ([`BuildError`]), stepping it
//! ([`StepError`]), writing its output ([`OutputError`]). Each names its file, object, group or
//! stage, so a message alone says where to look.

use std::path::{Path, PathBuf};

use nucleus_sdk::{PluginError, Stage};

/// A scene error, located in its file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read scene: {source}")]
    Io {
        /// The scene file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a valid scene (syntax, unknown field, wrong type).
    #[error("{path}:{line}:{col}: {message}")]
    Parse {
        /// The scene file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        col: usize,
        /// What is wrong.
        message: String,
    },
    /// A value is syntactically fine but invalid (a pin out of range, a negative mass...).
    #[error("{}", located(path, *line, *col, message))]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        col: usize,
        /// What is wrong.
        message: String,
    },
}

fn located(path: &Path, line: usize, col: usize, message: &str) -> String {
    if line == 0 {
        format!("{}: {message}", path.display())
    } else {
        format!("{}:{line}:{col}: {message}", path.display())
    }
}

/// An error while loading plugins or finding a kind's plugin.
#[derive(Debug, thiserror::Error, Clone)]
pub enum PluginLoadError {
    /// Two libraries provide the same kind.
    #[error("kind `{kind}` is provided by two plugins: {} and {}", first.display(), second.display())]
    DuplicateKind {
        /// The kind.
        kind: String,
        /// One library.
        first: PathBuf,
        /// The other.
        second: PathBuf,
    },
    /// A scene asks for a kind no plugin provides.
    #[error("no plugin provides kind `{kind}` (searched: {searched}){refused}")]
    UnknownKind {
        /// The kind.
        kind: String,
        /// The directories searched.
        searched: String,
        /// Refused plugins that might have provided it, summarised.
        refused: String,
    },
    /// A plugin's factory failed.
    #[error("plugin `{plugin}` ({}): group `{group}`: {error}", path.display())]
    Factory {
        /// Plugin name.
        plugin: String,
        /// Library path.
        path: PathBuf,
        /// Group name.
        group: String,
        /// The plugin's error.
        error: Box<PluginError>,
    },
}

/// An error while building a simulation from a scene.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A plugin could not be found or failed to build its group.
    #[error("{location}: {error}")]
    Plugin {
        /// `file:line:col` of the constraint in the scene.
        location: String,
        /// The cause.
        error: Box<PluginLoadError>,
    },
}

/// An error during a step. The state is left as it was when the error happened.
#[derive(Debug, thiserror::Error)]
pub enum StepError {
    /// A plugin returned an error (or panicked, which the SDK turns into an error).
    #[error("plugin `{plugin}` ({}), group `{group}`, {stage} at frame {frame} substep {substep}: {error}", path.display())]
    Plugin {
        /// Plugin name.
        plugin: String,
        /// Library path.
        path: PathBuf,
        /// Group name.
        group: String,
        /// Stage.
        stage: Stage,
        /// Frame.
        frame: u64,
        /// Substep.
        substep: u32,
        /// The plugin's error.
        error: Box<PluginError>,
    },
    /// A group's call left a NaN or infinity in the state.
    #[error("plugin `{plugin}` ({}), group `{group}`, {stage} at frame {frame} substep {substep}: wrote a non-finite {what} (NaN or infinity); stopping", path.display())]
    NonFinite {
        /// Plugin name.
        plugin: String,
        /// Library path.
        path: PathBuf,
        /// Group name.
        group: String,
        /// Stage.
        stage: Stage,
        /// Frame.
        frame: u64,
        /// Substep.
        substep: u32,
        /// "position" or "velocity".
        what: &'static str,
    },
}

/// An output error, naming the file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", path.display())]
pub struct OutputError {
    /// The file.
    pub path: PathBuf,
    /// The cause.
    pub source: std::io::Error,
}
