//! The faults a third-party plugin author will hit, each with the message they will read.
//!
//! * SDK versions, both directions. A plugin built against a **newer, compatible** SDK (its
//!   root module has grown a field after `create_group`) loads and runs. A plugin built
//!   against an **older** SDK whose root module has since grown is refused by abi_stable's
//!   layout check; one whose boundary types have another layout is refused the same way, and so
//!   is one built against the next semver-incompatible release of the `nucleus-sdk` crate even
//!   with an unchanged boundary; one reporting another SDK ABI version (the semantic
//!   handshake) is refused naming both versions. Every refusal is one short line naming the file, and a scene asking for the
//!   refused plugin's kind names the refusal.
//! * A kind that collides with an installed plugin: an error naming both files.
//! * A factory that rejects its parameters: the message names the parameter, located in the
//!   scene file.
//! * A plugin that writes NaN: the host names the plugin and the group, exits 1, and leaves
//!   the output honest (frames before the fault whole, no `stats.csv`, `run.json` failed).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use nucleus_core::Simulation;
use nucleus_sdk::SDK_ABI_VERSION;
use nucleus_tests::*;

/// The template plugin (`plugin-sdk/template`, kind `attract`), built by the workspace build.
fn template_lib() -> PathBuf {
    let path = profile_dir().join(lib_name("nucleus_template_attract"));
    assert!(
        path.is_file(),
        "{} is missing: run the test suite with `cargo xtask test`",
        path.display()
    );
    path
}

/// Runs the host binary.
fn host(args: &[&str]) -> Output {
    Command::new(host_bin())
        .args(args)
        .output()
        .expect("run the host")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).to_string()
}

/// The last line of stderr: the one-line cause the host promises.
fn last_line(out: &Output) -> String {
    stderr(out).lines().last().unwrap_or_default().to_string()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

const FALLING_CLOTH: &str = r#"
[solver]
frames = 20
substeps = 4
[[objects]]
name = "cloth"
[objects.grid]
size = [1.0, 1.0]
resolution = [4, 4]
origin = [0.0, 0.5, 0.0]
[[constraints]]
kind = "stretch"
objects = ["cloth"]
"#;

#[test]
fn a_plugin_built_against_a_newer_compatible_sdk_loads_and_runs() {
    let dir = plugin_dir_with("newer-sdk", &[fixture("newer_sdk")]);
    let reg = registry(&[plugin_dir(), dir]);
    assert!(reg.refused.is_empty(), "{:?}", reg.refused);
    let p = reg
        .plugins
        .iter()
        .find(|p| p.info.name.as_str() == "fixture-newer-sdk")
        .expect("the newer plugin is loaded");
    assert_eq!(p.info.sdk_abi_version, SDK_ABI_VERSION);
    // Its group runs: the falling cloth stops on its floor at y = 0.
    let text =
        format!("{FALLING_CLOTH}[[constraints]]\nkind = \"floor\"\nparams = {{ y = 0.0 }}\n");
    let mut sim = Simulation::build(&scene(&text), &reg).unwrap_or_else(|e| panic!("{e}"));
    for _ in 0..20 {
        sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
    }
    let lowest = sim
        .positions()
        .iter()
        .map(|x| x.y)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest.abs() < 1e-12, "the floor holds: lowest y = {lowest}");
    let residual = sim.residuals().unwrap()[1];
    assert_eq!((residual.count, residual.max), (16, 0.0));
}

#[test]
fn a_plugin_built_against_an_older_sdk_whose_root_module_has_grown_is_refused() {
    let dir = plugin_dir_with("older-sdk", &[fixture("older_sdk")]);
    let reg = registry(&[dir]);
    assert!(reg.plugins.is_empty());
    assert_eq!(reg.refused.len(), 1, "{:?}", reg.refused);
    let cause = &reg.refused[0].cause;
    assert!(
        cause.starts_with("incompatible plugin ABI") && cause.contains("rebuild it"),
        "{cause}"
    );
    // Refused for the missing field, not for anything else about it.
    assert!(
        cause.contains("prefix") && cause.contains("expected 3, found 2"),
        "{cause}"
    );
    assert!(
        cause.lines().count() == 1 && cause.len() < 600,
        "one short line: {cause}"
    );
}

#[test]
fn refusals_are_one_line_warnings_in_the_plugin_listing_and_errors_when_a_scene_needs_them() {
    let dir = plugin_dir_with(
        "refused",
        &[
            fixture("older_sdk"),
            fixture("old_abi"),
            fixture("next_abi"),
        ],
    );
    let listing = host(&["plugins", "--no-default-plugins", "--plugins", s(&dir)]);
    assert!(listing.status.success(), "{}", stderr(&listing));
    let err = stderr(&listing);
    let refused: Vec<&str> = err.lines().filter(|l| l.contains("refused")).collect();
    assert_eq!(refused.len(), 3, "{err}");
    for (lib, why) in [
        ("older_sdk", "incompatible plugin ABI"),
        ("old_abi", "expected PluginMod, found OldPluginMod"),
        ("next_abi", "Nucleus SDK ABI version"),
    ] {
        assert!(
            refused
                .iter()
                .any(|l| l.starts_with("warning: ") && l.contains(lib) && l.contains(why)),
            "{lib}: {err}"
        );
    }
    // A scene asking for the kind of a refused plugin: exit 2, naming the kind and the
    // refused file with its cause.
    let tmp = temp_dir("refused-scene");
    let scene = tmp.join("scene.toml");
    std::fs::write(
        &scene,
        format!("{FALLING_CLOTH}[[constraints]]\nkind = \"old_kind\"\n"),
    )
    .unwrap();
    let out = host(&[
        "run",
        s(&scene),
        "--quiet",
        "--out",
        s(&tmp.join("out")),
        "--plugins",
        s(&plugin_dir()),
        "--plugins",
        s(&dir),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let last = last_line(&out);
    assert!(
        last.contains("scene.toml:")
            && last.contains("`old_kind`")
            && last.contains("old_abi")
            && last.contains("incompatible plugin ABI"),
        "{last}"
    );
    assert!(
        !tmp.join("out").exists(),
        "nothing is written for bad input"
    );
}

#[test]
fn a_plugin_reporting_another_sdk_abi_version_is_refused_naming_both_versions() {
    let dir = plugin_dir_with("next-abi", &[fixture("next_abi")]);
    let reg = registry(&[dir]);
    assert!(reg.plugins.is_empty());
    assert_eq!(reg.refused.len(), 1, "{:?}", reg.refused);
    let cause = &reg.refused[0].cause;
    let theirs = format!("version {}", SDK_ABI_VERSION + 1);
    let ours = format!("version {SDK_ABI_VERSION}");
    assert!(
        cause.contains(&theirs) && cause.contains(&ours) && cause.contains("rebuild"),
        "{cause}"
    );
}

#[test]
fn a_plugin_built_against_the_next_minor_release_of_the_sdk_crate_is_refused() {
    // The boundary is unchanged; only the `nucleus-sdk` crate's version moved to the next
    // semver-incompatible one. abi_stable checks the declaring package's version of every type.
    let dir = plugin_dir_with("next-sdk-crate", &[fixture("next_sdk_crate")]);
    let reg = registry(&[dir]);
    assert!(reg.plugins.is_empty());
    assert_eq!(reg.refused.len(), 1, "{:?}", reg.refused);
    let cause = &reg.refused[0].cause;
    let ours = env!("CARGO_PKG_VERSION"); // the workspace's version, the SDK's too
    assert!(
        cause.starts_with("incompatible plugin ABI")
            && cause.contains("package versions")
            && cause.contains(&format!("expected {ours}, found ")),
        "{cause}"
    );
}

#[test]
fn a_third_party_kind_colliding_with_an_installed_one_names_both_files() {
    // The same library in two directories: the kind `attract` is provided twice.
    let a = plugin_dir_with("collide-a", &[template_lib()]);
    let b = plugin_dir_with("collide-b", &[template_lib()]);
    let tmp = temp_dir("collide");
    let scene = tmp.join("scene.toml");
    std::fs::write(
        &scene,
        format!("{FALLING_CLOTH}[[constraints]]\nkind = \"attract\"\n"),
    )
    .unwrap();
    for cmd in [
        vec!["plugins"],
        vec!["run", s(&scene), "--quiet", "--out", s(&tmp.join("out"))],
    ] {
        let mut args = cmd.clone();
        args.extend(["--plugins", s(&a), "--plugins", s(&b)]);
        let out = host(&args);
        assert_eq!(out.status.code(), Some(2), "{cmd:?}: {}", stderr(&out));
        let last = last_line(&out);
        assert!(
            last.contains("kind `attract`") && last.contains(s(&a)) && last.contains(s(&b)),
            "{cmd:?}: {last}"
        );
    }
    // `nucleus new-plugin` refuses up front a kind an installed plugin provides, naming it.
    let out = host(&["new-plugin", "stretch", "--path", s(&tmp.join("mine"))]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let last = last_line(&out);
    let stretch = plugin_dir().join(lib_name("nucleus_stretch"));
    assert!(
        last.contains("kind `stretch`") && last.contains(s(&stretch)),
        "{last}"
    );
    assert!(!tmp.join("mine").exists());
}

#[test]
fn a_factory_rejecting_its_parameters_names_the_parameter_in_the_scene() {
    let dir = plugin_dir_with("reject", &[template_lib()]);
    let tmp = temp_dir("reject");
    let scene = tmp.join("scene.toml");
    let text = format!(
        "{FALLING_CLOTH}[[constraints]]\nkind = \"attract\"\n\
         params = {{ radius = 0.5, max_distance = 0.2 }}\n"
    );
    let line = 1 + text
        .lines()
        .position(|l| l == "kind = \"attract\"")
        .unwrap();
    std::fs::write(&scene, text).unwrap();
    let out = host(&[
        "run",
        s(&scene),
        "--quiet",
        "--out",
        s(&tmp.join("out")),
        "--plugins",
        s(&dir),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let last = last_line(&out);
    // `file:line:col` of the constraint, the plugin and its file, the group, the parameter.
    assert!(
        last.starts_with(&format!("error: {}:{line}:", s(&scene))),
        "{last}"
    );
    assert!(
        last.contains("plugin `nucleus-template-attract`")
            && last.contains(s(&dir))
            && last.contains("group `attract`")
            && last.contains("parameter `max_distance`")
            && last.contains("larger than radius"),
        "{last}"
    );
    assert!(
        !tmp.join("out").exists(),
        "nothing is written for bad input"
    );
}

#[test]
fn a_plugin_writing_nan_is_named_and_the_output_stays_honest() {
    let tmp = temp_dir("nan");
    let scene = tmp.join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "{FALLING_CLOTH}[[constraints]]\nkind = \"write_nan\"\nname = \"my_write_nan\"\n\
             params = {{ at = 0.04 }}\n"
        ),
    )
    .unwrap();
    let extra = plugin_dir_with("nan-plugins", &[fixture("faulty")]);
    let out_dir = tmp.join("out");
    let out = host(&[
        "run",
        s(&scene),
        "--quiet",
        "--out",
        s(&out_dir),
        "--plugins",
        s(&plugin_dir()),
        "--plugins",
        s(&extra),
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let last = last_line(&out);
    assert!(
        last.starts_with("error: plugin `fixture-faulty`")
            && last.contains(s(&extra))
            && last.contains("group `my_write_nan`")
            && last.contains("non-finite position")
            && last.contains("frame 2"),
        "{last}"
    );
    // The frames written before the fault (0 to 2) are whole and finite; none after it; no
    // temporary file left; no stats.csv claiming a complete run.
    let mut names: Vec<String> = std::fs::read_dir(&out_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "frame_0000.obj",
            "frame_0001.obj",
            "frame_0002.obj",
            "run.json",
            "stats.csv.partial"
        ],
        "{names:?}"
    );
    for f in &names[..3] {
        let text = std::fs::read_to_string(out_dir.join(f)).unwrap();
        let coords: Vec<f64> = text
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .flat_map(|l| l.split_whitespace().map(|c| c.parse::<f64>().unwrap()))
            .collect();
        assert_eq!(coords.len(), 48, "{f}: 16 vertices");
        assert!(coords.iter().all(|c| c.is_finite()), "{f}");
    }
    let run_json = std::fs::read_to_string(out_dir.join("run.json")).unwrap();
    assert!(
        run_json.contains("\"failed\"") && run_json.contains("my_write_nan"),
        "{run_json}"
    );
}
