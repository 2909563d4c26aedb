//! Developer tasks, run as `cargo xtask <task>` (an alias in `.cargo/config.toml`).
//!
//! `cargo build`/`cargo test` alone do not put the plugins' `cdylib`s where the host finds
//! them (the plugins are not dependencies of the host). These tasks build the workspace, stage
//! every plugin under `plugins/` into `target/<profile>/plugins/` (the default plugin
//! directory of `target/<profile>/nucleus`), and then run what was asked:
//!
//! * `cargo xtask demo [SCENE]` — release build, then `nucleus run` on the default scene;
//! * `cargo xtask test [ARGS]`  — debug build, then `cargo test --workspace [ARGS]`;
//! * `cargo xtask plugins [--release]` — build and stage only.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (task, rest) = match args.split_first() {
        Some((t, r)) => (t.as_str(), r.to_vec()),
        None => ("help", Vec::new()),
    };
    let result = match task {
        "demo" => demo(&rest),
        "test" => test(&rest),
        "plugins" => stage(rest.iter().any(|a| a == "--release")).map(|_| ()),
        _ => {
            eprintln!(
                "usage: cargo xtask demo [SCENE] | test [CARGO TEST ARGS] | plugins [--release]"
            );
            Err("unknown task".into())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {e}");
            ExitCode::FAILURE
        }
    }
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

fn cargo() -> Command {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.current_dir(root());
    c
}

fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .map(|p| if p.is_absolute() { p } else { root().join(p) })
        .unwrap_or_else(|| root().join("target"))
}

fn run(mut cmd: Command) -> Result<(), String> {
    let status = cmd.status().map_err(|e| format!("{cmd:?}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{cmd:?} failed with {status}"))
    }
}

/// The package names of the plugins under `plugins/` (one directory each).
fn plugin_packages() -> Result<Vec<String>, String> {
    let mut names = Vec::new();
    let dir = root().join("plugins");
    let mut entries: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path().join("Cargo.toml")))
        .filter(|p| p.is_file())
        .collect();
    entries.sort();
    for manifest in entries {
        let text = std::fs::read_to_string(&manifest)
            .map_err(|e| format!("{}: {e}", manifest.display()))?;
        let name = text
            .lines()
            .find_map(|l| {
                let l = l.trim();
                l.strip_prefix("name")
                    .map(|r| r.trim_start())
                    .and_then(|r| r.strip_prefix('='))
                    .map(|r| r.trim().trim_matches('"').to_string())
            })
            .ok_or_else(|| format!("{}: no package name", manifest.display()))?;
        names.push(name);
    }
    Ok(names)
}

fn lib_file(package: &str) -> String {
    let stem = package.replace('-', "_");
    format!(
        "{}{stem}{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    )
}

/// Builds the workspace (host, plugins, test fixtures) and copies the plugins into
/// `target/<profile>/plugins/`. Returns the profile directory.
fn stage(release: bool) -> Result<PathBuf, String> {
    let mut build = cargo();
    build.arg("build").arg("--workspace");
    if release {
        build.arg("--release");
    }
    run(build)?;
    let profile = target_dir().join(if release { "release" } else { "debug" });
    let plugins = profile.join("plugins");
    std::fs::create_dir_all(&plugins).map_err(|e| format!("{}: {e}", plugins.display()))?;
    for package in plugin_packages()? {
        let file = lib_file(&package);
        let from = profile.join(&file);
        let to = plugins.join(&file);
        // Copy to a temporary name and rename, so a running host never sees half a file.
        let tmp = plugins.join(format!(".{file}.tmp"));
        std::fs::copy(&from, &tmp).map_err(|e| format!("{}: {e}", from.display()))?;
        std::fs::rename(&tmp, &to).map_err(|e| format!("{}: {e}", to.display()))?;
    }
    Ok(profile)
}

fn demo(args: &[String]) -> Result<(), String> {
    let profile = stage(true)?;
    let scene = args
        .first()
        .cloned()
        .unwrap_or_else(|| "scenes/hanging_cloth.toml".into());
    let stem = Path::new(&scene)
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().to_string());
    let mut cmd = Command::new(profile.join("nucleus"));
    cmd.current_dir(root())
        .args(["run", &scene, "--out"])
        .arg(root().join("out").join(stem))
        .args(args.iter().skip(1));
    run(cmd)
}

fn test(args: &[String]) -> Result<(), String> {
    stage(false)?;
    let mut cmd = cargo();
    cmd.args(["test", "--workspace"]).args(args);
    run(cmd)
}
