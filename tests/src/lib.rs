//! Helpers for the workspace tests: they go through the real, dynamically loaded plugins that
//! `cargo xtask test` builds and stages into `target/<profile>/plugins/`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use nucleus_core::{Registry, Scene, Simulation};

/// `target/<profile>`, found from the running test executable (`target/<profile>/deps/..`).
pub fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .and_then(Path::parent)
        .expect("test executables live in target/<profile>/deps")
        .to_path_buf()
}

/// The staged plugin directory, with a clear message if the plugins were not built.
pub fn plugin_dir() -> PathBuf {
    let dir = profile_dir().join("plugins");
    let stretch = dir.join(lib_name("nucleus_stretch"));
    assert!(
        stretch.is_file(),
        "{} is missing: run the test suite with `cargo xtask test`, which builds and stages the plugin libraries",
        stretch.display()
    );
    dir
}

/// The platform file name of a cdylib.
pub fn lib_name(stem: &str) -> String {
    format!(
        "{}{stem}{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    )
}

/// A test fixture library (`tests/fixtures/<name>`), built by `cargo build --workspace`.
pub fn fixture(name: &str) -> PathBuf {
    let path = profile_dir().join(lib_name(&format!("nucleus_fixture_{name}")));
    assert!(
        path.is_file(),
        "{} is missing: run the test suite with `cargo xtask test`",
        path.display()
    );
    path
}

/// The `nucleus` binary.
pub fn host_bin() -> PathBuf {
    let path = profile_dir().join(format!("nucleus{}", std::env::consts::EXE_SUFFIX));
    assert!(
        path.is_file(),
        "{} is missing: run `cargo xtask test`",
        path.display()
    );
    path
}

/// `nucleus COMMAND SCENE --quiet --no-default-plugins --plugins <staged> --out OUT`: the host
/// binary on a scene with only the staged plugins ([`plugin_dir`]), quietly, writing to `out`.
/// Add arguments or environment, then run it.
pub fn host_command(command: &str, scene: &Path, out: &Path) -> std::process::Command {
    let mut host = std::process::Command::new(host_bin());
    host.arg(command)
        .arg(scene)
        .args(["--quiet", "--no-default-plugins", "--plugins"])
        .arg(plugin_dir())
        .arg("--out")
        .arg(out);
    host
}

/// The exit code and the last line of standard error of a finished host run.
pub fn exit_and_last_error(output: &std::process::Output) -> (Option<i32>, String) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    let last = stderr.lines().last().unwrap_or_default().to_string();
    (output.status.code(), last)
}

/// A fresh, empty directory under `target/<profile>/test-tmp/`.
pub fn temp_dir(tag: &str) -> PathBuf {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let n = COUNTER.fetch_add(1, Ordering::SeqCst);
    let dir = profile_dir()
        .join("test-tmp")
        .join(format!("{tag}-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// A temporary plugin directory holding copies of `libs`.
pub fn plugin_dir_with(tag: &str, libs: &[PathBuf]) -> PathBuf {
    let dir = temp_dir(tag);
    for lib in libs {
        std::fs::copy(lib, dir.join(lib.file_name().expect("file name"))).expect("copy plugin");
    }
    dir
}

/// The shipped scene `scenes/<name>`.
pub fn shipped_scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name)
}

/// Every shipped scene (`scenes/*.toml`), sorted.
pub fn shipped_scenes() -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(shipped_scene(""))
        .expect("scenes/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    paths
}

/// The staged stretch plugin library.
pub fn stretch_lib() -> PathBuf {
    plugin_dir().join(lib_name("nucleus_stretch"))
}

/// Discovers the plugins of `dirs` (no default directory, no environment).
pub fn registry(dirs: &[PathBuf]) -> Registry {
    Registry::discover(dirs)
}

/// Parses a scene from text (as if read from `inline.toml`).
pub fn scene(text: &str) -> Scene {
    Scene::parse(text, Path::new("inline.toml")).unwrap_or_else(|e| panic!("scene: {e}"))
}

/// Builds a simulation from scene text with the staged plugins plus `extra` libraries.
pub fn simulation(text: &str, extra: &[PathBuf]) -> Simulation {
    let mut dirs = vec![plugin_dir()];
    if !extra.is_empty() {
        dirs.push(plugin_dir_with("extra", extra));
    }
    let reg = registry(&dirs);
    Simulation::build(&scene(text), &reg).unwrap_or_else(|e| panic!("build: {e}"))
}

/// The particle range of object `name`.
pub fn particles_of(sim: &Simulation, name: &str) -> std::ops::Range<usize> {
    let o = sim.object(name).expect("object");
    o.first as usize..(o.first + o.count) as usize
}

/// The triangles of object `name` at the current positions.
pub fn triangles(sim: &Simulation, name: &str) -> Vec<[glam::DVec3; 3]> {
    let x = sim.positions();
    sim.object(name)
        .expect("object")
        .triangles
        .iter()
        .map(|t| t.map(|i| x[i as usize]))
        .collect()
}

/// Runs `frames` frames substep by substep, calling `check(sim)` after every substep.
pub fn run(sim: &mut Simulation, frames: u32, mut check: impl FnMut(&Simulation)) {
    for _ in 0..frames {
        for s in 0..sim.settings.substeps {
            sim.substep(s).unwrap_or_else(|e| panic!("step: {e}"));
            check(sim);
        }
        sim.frame += 1;
    }
}

/// Steps every frame of `sim` (its `settings.frames`), calling `check(sim, frame)` after each,
/// and returns the mean over the last half of the frames of group `group`'s RMS residual.
pub fn mean_rms_residual(
    sim: &mut Simulation,
    group: usize,
    mut check: impl FnMut(&Simulation, u32),
) -> f64 {
    let frames = sim.settings.frames;
    let mut sum = 0.0;
    for f in 0..frames {
        sim.step_frame().unwrap_or_else(|e| panic!("step: {e}"));
        check(sim, f);
        if f >= frames / 2 {
            sum += sim.residuals().unwrap_or_else(|e| panic!("residuals: {e}"))[group].rms;
        }
    }
    sum / (frames - frames / 2) as f64
}

/// The peers' drape (`scenes/drape.toml`) as scene text: a 1 m cloth of `n × n` vertices in
/// the plane y = 0, 1 kg, the two corners of row 0 pinned, gravity −9.81 m/s² along y, no
/// damping, `frames` frames of `substeps` substeps × `iterations` passes, and `constraints`
/// (TOML tables, written as given) acting on it.
pub fn drape_text(
    n: u32,
    frames: u32,
    substeps: u32,
    iterations: u32,
    constraints: &str,
) -> String {
    format!(
        r#"
[solver]
frames = {frames}
substeps = {substeps}
iterations = {iterations}
gravity = [0.0, -9.81, 0.0]
[[objects]]
name = "cloth"
mass = 1.0
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [{n}, {n}]
plane = "xz"
{constraints}"#
    )
}
