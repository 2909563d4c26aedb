//! The plugin as the host sees it: the `cdylib` cargo built for this test run is copied into a
//! plugin directory of its own and loaded through `nucleus-core`'s discovery — abi_stable's
//! layout check and the SDK handshake included — then listed and used by scenes, exactly as
//! `nucleus run --plugins DIR` does. Nothing here links the crate itself: every call goes
//! through the dynamically loaded library.

use std::path::{Path, PathBuf};

use nucleus_core::{Registry, Scene, Simulation};
use nucleus_sdk::glam::DVec3;

/// The platform file name of this crate's `cdylib`.
fn lib_file() -> String {
    format!(
        "{}{}{}",
        std::env::consts::DLL_PREFIX,
        env!("CARGO_PKG_NAME").replace('-', "_"),
        std::env::consts::DLL_SUFFIX
    )
}

/// A fresh plugin directory holding only this crate's library, as cargo built it for this
/// test run (in `target/<profile>/deps/`, beside the test executable).
fn plugin_dir(tag: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe
        .parent()
        .expect("the test executable is in target/<profile>/deps");
    let candidates = [
        deps.join(lib_file()),
        deps.parent().unwrap_or(deps).join(lib_file()),
    ];
    let lib = candidates
        .iter()
        .find(|p| p.is_file())
        .unwrap_or_else(|| panic!("{} was not built (looked in {candidates:?})", lib_file()));
    let dir = deps
        .parent()
        .unwrap_or(deps)
        .join("plugin-load-test")
        .join(format!("{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the plugin directory");
    std::fs::copy(lib, dir.join(lib_file())).expect("copy the library");
    dir
}

/// The loaded plugin's one kind.
fn kind(registry: &Registry) -> String {
    registry.plugins[0].info.kinds[0].name.to_string()
}

#[test]
fn the_library_loads_and_describes_itself_like_any_plugin() {
    let registry = Registry::discover(&[plugin_dir("describe")]);
    assert!(registry.refused.is_empty(), "{:?}", registry.refused);
    assert!(registry.warnings.is_empty(), "{:?}", registry.warnings);
    assert_eq!(registry.plugins.len(), 1);
    let info = &registry.plugins[0].info;
    assert_eq!(info.name.as_str(), env!("CARGO_PKG_NAME"));
    assert_eq!(info.version.as_str(), env!("CARGO_PKG_VERSION"));
    assert_eq!(info.sdk_abi_version, nucleus_sdk::SDK_ABI_VERSION);
    assert_eq!(info.kinds.len(), 1);
    let k = &info.kinds[0];
    assert_eq!((k.default_order, k.default_importance), (-10, 1));
    assert_eq!(k.residual_unit.as_str(), "m");
    let params: Vec<(&str, &str)> = k
        .params
        .iter()
        .map(|p| (p.name.as_str(), p.unit.as_str()))
        .collect();
    assert_eq!(
        params,
        [
            ("center", "m"),
            ("radius", "m"),
            ("period", "s"),
            ("max_distance", "m")
        ]
    );
    assert!(k.params.iter().all(|p| !p.doc.is_empty()));
}

#[test]
fn a_hanging_particle_settles_where_the_theory_says_through_the_library() {
    // The same analytic equilibrium as the in-process test: g τ² beyond the sphere.
    let registry = Registry::discover(&[plugin_dir("hang")]);
    let (g, r, period) = (9.81, 0.25, 0.4);
    let text = format!(
        "[solver]\nsubsteps = 10\ndamping = 5.0\n[[objects]]\nname = \"p\"\nvertex_mass = 0.2\n\
         [objects.particles]\nmin = [0.3, 0.0, 0.0]\nmax = [0.3, 0.0, 0.0]\ncount = [1, 1, 1]\n\
         [[constraints]]\nkind = \"{}\"\nparams = {{ center = [0.0, 1.0, 0.0], radius = {r:?}, \
         period = {period:?} }}\n",
        kind(&registry)
    );
    let mut sim = Simulation::from_toml(&text, &registry).unwrap_or_else(|e| panic!("{e}"));
    for _ in 0..600 {
        sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
    }
    let tau = period / std::f64::consts::TAU;
    let x = sim.positions()[0];
    let expected = DVec3::new(0.0, 1.0 - r - g * tau * tau, 0.0);
    assert!((x - expected).length() < 1e-9, "{x} vs {expected}");
}

#[test]
fn the_example_scene_gathers_the_cloud() {
    let registry = Registry::discover(&[plugin_dir("example")]);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scene.toml");
    let scene = Scene::load_with_overrides(&path, &["solver.frames=60".to_string()])
        .unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::build(&scene, &registry).unwrap_or_else(|e| panic!("{e}"));
    let mean_distance = |sim: &mut Simulation| {
        let reports = sim.reports().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(reports.len(), 1, "{reports:?}");
        reports[0].1
    };
    let before = mean_distance(&mut sim);
    for _ in 0..sim.settings.frames {
        sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
    }
    let after = mean_distance(&mut sim);
    assert!(
        after < 0.5 * before,
        "mean distance {before} m -> {after} m"
    );
}
