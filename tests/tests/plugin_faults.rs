//! Faults at the plugin boundary are reported, never suffered: an incompatible plugin is
//! refused with a summarised layout error naming its file; a panicking plugin comes back as an
//! error naming the plugin and the group and the run stops cleanly; a plugin that writes NaN
//! is named; a non-library file is skipped with a warning; two plugins with the same kind are
//! an error naming both files; a factory that rejects a parameter names it; plugins are found
//! through `NUCLEUS_PLUGIN_PATH`.

use std::process::Command;

use nucleus_core::error::{BuildError, PluginLoadError, StepError};
use nucleus_core::Simulation;
use nucleus_tests::*;

const CLOTH: &str = r#"
[solver]
frames = 5
substeps = 2
[[objects]]
name = "cloth"
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [4, 4]
[[constraints]]
kind = "stretch"
objects = ["cloth"]
"#;

fn with_kind(kind: &str, params: &str) -> String {
    format!("{CLOTH}\n[[constraints]]\nkind = \"{kind}\"\nname = \"my_{kind}\"\nobjects = [\"cloth\"]\nparams = {params}\n")
}

#[test]
fn incompatible_sdk_layout_is_refused_with_a_summary() {
    let dir = plugin_dir_with("old-abi", &[stretch_lib(), fixture("old_abi")]);
    let reg = registry(std::slice::from_ref(&dir));
    assert_eq!(reg.plugins.len(), 1, "only the stretch plugin loads");
    assert_eq!(reg.refused.len(), 1, "{:?}", reg.refused);
    let cause = &reg.refused[0].cause;
    assert!(cause.contains("incompatible plugin ABI"), "{cause}");
    assert!(
        cause.contains("expected PluginMod, found OldPluginMod"),
        "{cause}"
    );
    assert!(
        cause.lines().count() <= 3,
        "the layout report must be summarised: {cause}"
    );
    assert!(
        cause.len() < 2000,
        "summary too long: {} chars",
        cause.len()
    );
    // A scene asking for its kind fails and names the refused file.
    let scene = scene(&with_kind("old_kind", "{}"));
    let err = Simulation::build(&scene, &reg).err().expect("must fail");
    let msg = err.to_string();
    assert!(msg.contains("old_kind") && msg.contains("old_abi"), "{msg}");
    assert!(msg.starts_with("inline.toml:"), "location first: {msg}");
}

#[test]
fn non_library_file_is_skipped_with_a_warning() {
    let dir = plugin_dir_with("junk", &[stretch_lib()]);
    std::fs::write(dir.join("notes.txt"), "not a plugin").unwrap();
    std::fs::write(dir.join(lib_name("fake")), "not a library either").unwrap();
    let reg = registry(&[dir]);
    assert_eq!(reg.plugins.len(), 1);
    assert_eq!(reg.warnings.len(), 2, "{:?}", reg.warnings);
    assert!(reg.warnings.iter().any(|w| w.contains("notes.txt")));
    assert!(reg
        .warnings
        .iter()
        .any(|w| w.contains("fake") && w.contains("not a loadable library")));
}

#[test]
fn duplicate_kind_names_both_files() {
    let a = plugin_dir_with("dup-a", &[stretch_lib()]);
    let b = plugin_dir_with("dup-b", &[stretch_lib()]);
    let reg = registry(&[a.clone(), b.clone()]);
    // Every kind of the stretch plugin (stretch, tether) is provided twice; each error names
    // the kind and both files.
    let dups = reg.duplicate_kinds();
    assert_eq!(dups.len(), reg.plugins[0].info.kinds.len(), "{dups:?}");
    for kind in ["stretch", "tether"] {
        let msg = dups
            .iter()
            .map(ToString::to_string)
            .find(|m| m.contains(&format!("kind `{kind}`")))
            .unwrap_or_else(|| panic!("no duplicate error for {kind}: {dups:?}"));
        assert!(
            msg.contains(a.to_str().unwrap()) && msg.contains(b.to_str().unwrap()),
            "{msg}"
        );
    }
    let err = Simulation::build(&scene(CLOTH), &reg)
        .err()
        .expect("ambiguous kind");
    assert!(
        matches!(err, BuildError::Plugin { ref error, .. } if matches!(**error, PluginLoadError::DuplicateKind { .. }))
    );
}

#[test]
fn panic_in_project_names_plugin_and_group_and_stops() {
    let mut sim = simulation(
        &with_kind("panic_in_project", "{ at = 0.02 }"),
        &[fixture("faulty")],
    );
    let mut frames_ok = 0;
    let err = loop {
        match sim.step_frame() {
            Ok(()) => frames_ok += 1,
            Err(e) => break e,
        }
        assert!(frames_ok < 5, "the fault never fired");
    };
    assert_eq!(frames_ok, 1, "fault at t = 0.02 s fires in frame 2");
    let msg = err.to_string();
    assert!(matches!(err, StepError::Plugin { .. }), "{msg}");
    assert!(
        msg.contains("fixture-faulty") && msg.contains("my_panic_in_project"),
        "{msg}"
    );
    assert!(msg.contains("deliberate panic in project"), "{msg}");
    // The group is poisoned: calling it again gives an error, never undefined behaviour.
    let again = sim.step_frame().unwrap_err().to_string();
    assert!(again.contains("poisoned"), "{again}");
}

#[test]
fn panic_in_factory_is_an_error_naming_the_group() {
    let reg = registry(&[
        plugin_dir(),
        plugin_dir_with("factory", &[fixture("faulty")]),
    ]);
    let err = Simulation::build(&scene(&with_kind("panic_in_factory", "{}")), &reg)
        .err()
        .expect("must fail");
    let msg = err.to_string();
    assert!(
        msg.contains("my_panic_in_factory") && msg.contains("deliberate panic in factory"),
        "{msg}"
    );
}

#[test]
fn nan_writer_is_named_and_state_check_stops_the_run() {
    let mut sim = simulation(
        &with_kind("write_nan", "{ at = 0.0 }"),
        &[fixture("faulty")],
    );
    let err = sim.step_frame().unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, StepError::NonFinite { .. }), "{msg}");
    assert!(
        msg.contains("fixture-faulty") && msg.contains("my_write_nan") && msg.contains("position"),
        "{msg}"
    );
}

/// The finite check after a substep's last call runs in the velocity update's loop; after
/// every other call, on its own. Both name the group that wrote the value, and what it was.
#[test]
fn a_nan_is_named_for_its_writer_whether_its_call_is_the_last_or_not() {
    // Written by the last call of the substep: a velocity.
    let mut sim = simulation(
        &with_kind("write_nan_velocity", "{ at = 0.0 }"),
        &[fixture("faulty")],
    );
    let err = sim.step_frame().unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("my_write_nan_velocity")
            && msg.contains("velocity")
            && msg.contains("substep 0"),
        "{msg}"
    );
    // Written by the first call, before `stretch` spreads it: named for the writer.
    let first = with_kind("write_nan", "{ at = 0.0 }").replace(
        "name = \"my_write_nan\"",
        "name = \"my_write_nan\"\norder = -1",
    );
    let mut sim = simulation(&first, &[fixture("faulty")]);
    assert_eq!(sim.groups[sim.calls[0].group as usize].name, "my_write_nan");
    let msg = sim.step_frame().unwrap_err().to_string();
    assert!(
        msg.contains("my_write_nan") && msg.contains("position") && msg.contains("substep 0"),
        "{msg}"
    );
}

#[test]
fn factory_rejecting_a_parameter_names_it() {
    let reg = registry(&[plugin_dir(), plugin_dir_with("picky", &[fixture("faulty")])]);
    let err = Simulation::build(&scene(&with_kind("picky", "{ level = 7 }")), &reg)
        .err()
        .expect("must fail");
    let msg = err.to_string();
    assert!(
        msg.contains("`level`") && msg.contains("at most 3"),
        "{msg}"
    );
    // The SDK's own validation names unknown and out-of-range parameters before the factory.
    let err = Simulation::build(&scene(&with_kind("picky", "{ levle = 1 }")), &reg)
        .err()
        .expect("must fail");
    assert!(err.to_string().contains("`levle`"), "{err}");
}

#[test]
fn host_run_with_panicking_plugin_exits_nonzero_and_marks_output_failed() {
    let dir = temp_dir("host-panic");
    let scene_path = dir.join("scene.toml");
    std::fs::write(&scene_path, with_kind("panic_in_project", "{ at = 0.04 }")).unwrap();
    let extra = plugin_dir_with("host-panic-plugins", &[fixture("faulty")]);
    let out = dir.join("out");
    let res = Command::new(host_bin())
        .args([
            "run",
            scene_path.to_str().unwrap(),
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ])
        .args([
            "--plugins",
            plugin_dir().to_str().unwrap(),
            "--plugins",
            extra.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&res.stderr);
    let last = stderr.lines().last().unwrap_or_default();
    assert!(
        last.starts_with("error: ") && last.contains("my_panic_in_project"),
        "{stderr}"
    );
    assert!(
        !out.join("stats.csv").exists(),
        "a failed run must not claim completeness"
    );
    let run_json = std::fs::read_to_string(out.join("run.json")).unwrap();
    assert!(run_json.contains("\"failed\""), "{run_json}");
    // Frames written before the fault are whole OBJ files.
    let frame = std::fs::read_to_string(out.join("frame_0001.obj")).unwrap();
    assert_eq!(frame.lines().filter(|l| l.starts_with("v ")).count(), 16);
}

#[test]
fn plugins_are_found_through_nucleus_plugin_path_in_order() {
    // Two directories on the variable (separated like PATH), no default directory: the stretch
    // plugin in the second one is found; an empty entry is ignored.
    let empty = plugin_dir_with("path-empty", &[]);
    let with_stretch = plugin_dir_with("path-stretch", &[stretch_lib()]);
    let joined = std::env::join_paths([empty.clone(), "".into(), with_stretch.clone()]).unwrap();
    let out = Command::new(host_bin())
        .args(["plugins", "--no-default-plugins"])
        .env("NUCLEUS_PLUGIN_PATH", &joined)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("kind `stretch`"), "{stdout}");
    assert!(stdout.contains(with_stretch.to_str().unwrap()), "{stdout}");
    // Without the variable and without defaults nothing is found.
    let none = Command::new(host_bin())
        .args(["plugins", "--no-default-plugins"])
        .env_remove("NUCLEUS_PLUGIN_PATH")
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&none.stdout).contains("kind `stretch`"));
}
