//! Plugin discovery and loading.
//!
//! Plugin directories are searched in this order: the directories given on the command line,
//! those in `NUCLEUS_PLUGIN_PATH` (separated like `PATH`), then `plugins/` next to the
//! `nucleus` executable. Every file with the platform's library extension is opened on its own
//! with `lib_header_from_path(..)?.init_root_module()` (abi_stable's `RootModule::load_from_*`
//! caches one library per root-module type, and all plugins share that type) and asked for its
//! description; a group is instantiated only for the kinds a scene uses. Libraries stay mapped
//! for the life of the process.
//!
//! Failures never abort discovery: a file that is not a library, or not a Nucleus plugin, is
//! skipped with a warning; a plugin built against an incompatible SDK is *refused*, and the
//! refusal is reported with its path and a summarised cause wherever it matters (listing
//! plugins, or a scene asking for a kind that is not available). Two plugins providing the same
//! kind is an error naming both files.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use abi_stable::library::{lib_header_from_path, LibraryError};
use abi_stable::std_types::{RResult, RStr};
use nucleus_sdk::{
    GroupBox, PluginDef, PluginError, PluginInfo, PluginModRef, SceneView, SDK_ABI_VERSION,
};

use crate::error::PluginLoadError;

/// A library that was refused, with the summarised cause.
#[derive(Debug, Clone)]
pub struct Refused {
    /// The file.
    pub path: PathBuf,
    /// Why, in one or a few lines.
    pub cause: String,
}

/// Where a plugin's code lives.
#[derive(Clone, Copy)]
enum Source {
    /// A dynamically loaded library.
    Library(PluginModRef),
    /// Linked into this process (plugin unit tests; see [`Registry::add_in_process`]).
    InProcess(&'static PluginDef),
}

/// A loaded plugin.
#[derive(Clone)]
pub struct LoadedPlugin {
    /// The file (`<in-process>` for a plugin linked into the process).
    pub path: PathBuf,
    /// Its description.
    pub info: PluginInfo,
    source: Source,
}

impl std::fmt::Debug for LoadedPlugin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadedPlugin")
            .field("path", &self.path)
            .field("name", &self.info.name)
            .finish()
    }
}

impl LoadedPlugin {
    /// Builds a group of `kind` through the plugin's factory.
    pub fn create_group(
        &self,
        kind: &str,
        params_json: &str,
        scene: &SceneView<'_>,
    ) -> Result<GroupBox, PluginError> {
        let result = match self.source {
            Source::Library(module) => {
                (module.create_group())(RStr::from(kind), RStr::from(params_json), scene)
            }
            Source::InProcess(def) => nucleus_sdk::group::create_entry(
                def,
                RStr::from(kind),
                RStr::from(params_json),
                scene,
            ),
        };
        match result {
            RResult::ROk(g) => Ok(g),
            RResult::RErr(e) => Err(e),
        }
    }
}

/// Every plugin found in a set of directories.
#[derive(Debug, Default, Clone)]
pub struct Registry {
    /// Directories searched, in order.
    pub dirs: Vec<PathBuf>,
    /// Loaded plugins, in discovery order.
    pub plugins: Vec<LoadedPlugin>,
    /// Refused plugin libraries.
    pub refused: Vec<Refused>,
    /// Files skipped (not libraries, or not Nucleus plugins), with the reason.
    pub warnings: Vec<String>,
    /// Kind name → index into `plugins`.
    kinds: BTreeMap<String, usize>,
    /// Kinds provided twice.
    duplicates: Vec<PluginLoadError>,
}

/// The platform's dynamic library extension.
pub const LIB_EXTENSION: &str = std::env::consts::DLL_EXTENSION;

/// The default search path: `dirs`, then `NUCLEUS_PLUGIN_PATH`, then `plugins/` next to the
/// running executable.
pub fn search_path(dirs: &[PathBuf], include_default: bool) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = dirs.to_vec();
    if let Some(p) = std::env::var_os("NUCLEUS_PLUGIN_PATH") {
        out.extend(std::env::split_paths(&p).filter(|p| !p.as_os_str().is_empty()));
    }
    if include_default {
        if let Some(dir) = std::env::current_exe()
            .ok()
            .and_then(|e| e.parent().map(Path::to_path_buf))
        {
            out.push(dir.join("plugins"));
        }
    }
    out
}

/// Summarises abi_stable's layout report (which can run to a thousand lines) to the lines
/// that say what differs.
pub fn summarize_library_error(e: &LibraryError) -> String {
    match e {
        LibraryError::AbiInstability(_) => format!(
            "incompatible plugin ABI (built against a different Nucleus SDK layout; rebuild it against this SDK): {}",
            summarize_layout_report(&e.to_string())
        ),
        LibraryError::IncompatibleVersionNumber {
            expected_version,
            actual_version,
            ..
        } => format!(
            "incompatible plugin ABI: root module version {actual_version}, this host needs {expected_version} (rebuild the plugin against this SDK)"
        ),
        other => {
            let s = other.to_string();
            s.lines().take(3).collect::<Vec<_>>().join(" ")
        }
    }
}

/// The "Error:" blocks of abi_stable's layout report, each on one line:
/// `mismatched type: expected PluginMod, found OldPluginMod`.
fn summarize_layout_report(report: &str) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut lines = report.lines().map(str::trim).peekable();
    while let Some(line) = lines.next() {
        let Some(what) = line.strip_prefix("Error:") else {
            continue;
        };
        let mut item = what.trim().to_string();
        while let Some(next) = lines.peek() {
            if next.is_empty() || next.starts_with("Error:") {
                break;
            }
            let next = lines.next().unwrap_or_default();
            match next {
                "Expected:" => item.push_str(": expected"),
                "Found:" => item.push_str(", found"),
                other => {
                    item.push(' ');
                    item.push_str(other);
                }
            }
        }
        if !out.contains(&item) {
            out.push(item);
        }
        if out.len() == 3 {
            break;
        }
    }
    if out.is_empty() {
        "the layout check failed".to_string()
    } else {
        out.join("; ")
    }
}

impl Registry {
    /// Searches the directories (in order; missing directories are skipped).
    pub fn discover(dirs: &[PathBuf]) -> Registry {
        let mut reg = Registry {
            dirs: dirs.to_vec(),
            ..Registry::default()
        };
        let mut seen: Vec<PathBuf> = Vec::new();
        for dir in dirs {
            let Ok(entries) = std::fs::read_dir(dir) else {
                continue;
            };
            let mut files: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect();
            files.sort();
            for path in files {
                let canonical = path.canonicalize().unwrap_or_else(|_| path.clone());
                if seen.contains(&canonical) {
                    continue;
                }
                seen.push(canonical);
                reg.load_file(&path);
            }
        }
        reg
    }

    /// Tries one file.
    pub fn load_file(&mut self, path: &Path) {
        if path.extension().and_then(|e| e.to_str()) != Some(LIB_EXTENSION) {
            self.warnings.push(format!(
                "{}: skipped: not a plugin library (*.{LIB_EXTENSION})",
                path.display()
            ));
            return;
        }
        let header = match lib_header_from_path(path) {
            Ok(h) => h,
            Err(e) => {
                let why = match &e {
                    LibraryError::OpenError { .. } => "not a loadable library".to_string(),
                    LibraryError::GetSymbolError { .. } => {
                        "not a Nucleus plugin (no root module)".to_string()
                    }
                    other => summarize_library_error(other),
                };
                self.warnings
                    .push(format!("{}: skipped: {why}", path.display()));
                return;
            }
        };
        let module = match header.init_root_module::<PluginModRef>() {
            Ok(m) => m,
            Err(e) => {
                self.refused.push(Refused {
                    path: path.to_path_buf(),
                    cause: summarize_library_error(&e),
                });
                return;
            }
        };
        if module.sdk_abi_version() != SDK_ABI_VERSION {
            self.refused.push(Refused {
                path: path.to_path_buf(),
                cause: format!(
                    "built against Nucleus SDK ABI version {}, this host speaks version {SDK_ABI_VERSION}; rebuild the plugin",
                    module.sdk_abi_version()
                ),
            });
            return;
        }
        let info = match (module.describe())() {
            RResult::ROk(i) => i,
            RResult::RErr(e) => {
                self.refused.push(Refused {
                    path: path.to_path_buf(),
                    cause: format!("describing itself failed: {e}"),
                });
                return;
            }
        };
        self.register(path, info, Source::Library(module));
    }

    /// Registers a plugin linked into this process, exactly as if it had been loaded from a
    /// library: for a plugin's own tests of whole scenes (`nucleus-core` as a dev-dependency).
    pub fn add_in_process(&mut self, def: &'static PluginDef) {
        let path = PathBuf::from(format!("<in-process {}>", def.name));
        self.register(&path, def.info(), Source::InProcess(def));
    }

    fn register(&mut self, path: &Path, info: PluginInfo, source: Source) {
        let index = self.plugins.len();
        for k in info.kinds.iter() {
            let name = k.name.to_string();
            if let Some(&other) = self.kinds.get(&name) {
                self.duplicates.push(PluginLoadError::DuplicateKind {
                    kind: name,
                    first: self.plugins[other].path.clone(),
                    second: path.to_path_buf(),
                });
            } else {
                self.kinds.insert(name, index);
            }
        }
        self.plugins.push(LoadedPlugin {
            path: path.to_path_buf(),
            info,
            source,
        });
    }

    /// Kinds provided twice (each an error).
    pub fn duplicate_kinds(&self) -> &[PluginLoadError] {
        &self.duplicates
    }

    /// The plugin providing `kind`, and the kind's description.
    pub fn find(
        &self,
        kind: &str,
    ) -> Result<(&LoadedPlugin, &nucleus_sdk::KindInfo), PluginLoadError> {
        if let Some(e) = self
            .duplicates
            .iter()
            .find(|e| matches!(e, PluginLoadError::DuplicateKind { kind: k, .. } if k == kind))
        {
            return Err(e.clone());
        }
        let Some(&i) = self.kinds.get(kind) else {
            let refused = if self.refused.is_empty() {
                String::new()
            } else {
                let list: Vec<String> = self
                    .refused
                    .iter()
                    .map(|r| format!("{}: {}", r.path.display(), r.cause))
                    .collect();
                format!("; refused plugins: {}", list.join("; "))
            };
            return Err(PluginLoadError::UnknownKind {
                kind: kind.to_string(),
                searched: self
                    .dirs
                    .iter()
                    .map(|d| d.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                refused,
            });
        };
        let p = &self.plugins[i];
        let k = p
            .info
            .kinds
            .iter()
            .find(|k| k.name.as_str() == kind)
            .expect("kind index points at a plugin that provides it");
        Ok((p, k))
    }
}
