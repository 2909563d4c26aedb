//! Third-party plugins have equal rank: the SDK's template crate (`plugin-sdk/template`, kind
//! `attract`) is found, listed, scheduled and run exactly like the built-in plugins, and
//! `nucleus new-plugin` writes a standalone crate from it. (Building a generated crate out of
//! the workspace, loading it and checking its scene is `cargo xtask template-check`, run by
//! `cargo xtask test`: it takes a cold cargo build, too slow for a test.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use nucleus_core::Simulation;
use nucleus_sdk::SDK_ABI_VERSION;
use nucleus_tests::*;

/// The template plugin, built by the workspace build.
fn template_lib() -> PathBuf {
    let path = profile_dir().join(lib_name("nucleus_template_attract"));
    assert!(
        path.is_file(),
        "{} is missing: run the test suite with `cargo xtask test`",
        path.display()
    );
    path
}

/// The template crate's directory.
fn template_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../plugin-sdk/template")
        .canonicalize()
        .expect("plugin-sdk/template")
}

fn host(args: &[&str]) -> Output {
    Command::new(host_bin())
        .args(args)
        .output()
        .expect("run the host")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).to_string()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// What a line of `nucleus plugins` is.
#[derive(Debug, PartialEq, Eq, Clone, Copy)]
enum Line {
    Header,
    Kind,
    Doc,
    Param { unit: bool, range: bool },
}

/// The lines of the plugin block whose header starts with `name `, classified.
fn block(listing: &str, name: &str) -> Vec<(Line, String)> {
    let mut lines = listing
        .lines()
        .skip_while(|l| !l.starts_with(&format!("{name} ")))
        .take_while(|l| !l.is_empty());
    let mut out = Vec::new();
    if let Some(header) = lines.next() {
        out.push((Line::Header, header.to_string()));
    }
    for l in lines {
        let class = if l.starts_with("  kind `") {
            Line::Kind
        } else if l.starts_with("    - ") {
            let head = l.split(')').next().unwrap_or_default();
            Line::Param {
                unit: head.contains(" ["),
                range: l.contains(", range ["),
            }
        } else {
            Line::Doc
        };
        out.push((class, l.to_string()));
    }
    out
}

#[test]
fn the_template_is_listed_exactly_like_a_builtin_plugin() {
    let dir = plugin_dir_with("listing", &[template_lib()]);
    let out = host(&["plugins", "--plugins", s(&dir)]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let listing = text(&out.stdout);
    let ours = block(&listing, "stretch");
    let theirs = block(&listing, "nucleus-template-attract");
    let lib = dir.join(lib_name("nucleus_template_attract"));
    assert_eq!(
        theirs[0].1,
        format!(
            "nucleus-template-attract 0.1.0 (SDK ABI {SDK_ABI_VERSION}) — {}",
            lib.display()
        )
    );
    assert!(ours[0].1.ends_with(&format!(
        "(SDK ABI {SDK_ABI_VERSION}) — {}",
        stretch_lib().display()
    )));
    assert_eq!(
        theirs[1].1,
        "  kind `attract`: order -10, importance 1, residual in m"
    );
    // The same grammar: header, kind, its doc, then one line per parameter with its type,
    // unit, default, range and doc.
    let shape = |b: &[(Line, String)]| -> Vec<Line> {
        let mut v: Vec<Line> = b.iter().map(|(c, _)| *c).collect();
        v.dedup_by(|a, b| *a == Line::Doc && *b == Line::Doc);
        v
    };
    let param = Line::Param {
        unit: true,
        range: true,
    };
    assert_eq!(
        shape(&theirs),
        [
            Line::Header,
            Line::Kind,
            Line::Doc,
            Line::Param {
                unit: true,
                range: false
            },
            param,
            param,
            param
        ],
        "{listing}"
    );
    // Ours follow the same grammar: a header, then per kind its line, its doc, its parameters.
    let grammatical = |shape: &[Line]| {
        shape.first() == Some(&Line::Header)
            && shape.get(1) == Some(&Line::Kind)
            && shape[1..].split(|l| *l == Line::Kind).skip(1).all(|kind| {
                kind.first() == Some(&Line::Doc)
                    && kind[1..].iter().all(|l| matches!(l, Line::Param { .. }))
            })
    };
    assert!(grammatical(&shape(&ours)), "{listing}");
    assert!(grammatical(&shape(&theirs)), "{listing}");
    assert!(
        theirs.iter().any(|(_, l)| l
            == "    - period (number [s]) = 0.5, range [0, inf]: natural period of the pull, \
                the same for every mass; 0 is a hard pull"),
        "{listing}"
    );
}

#[test]
fn the_template_scene_runs_through_the_host_and_gathers_the_cloud() {
    let dir = plugin_dir_with("scene", &[template_lib()]);
    let out_dir = temp_dir("template-scene");
    let out = host(&[
        "run",
        s(&template_dir().join("scene.toml")),
        "--frames",
        "60",
        "--verbose",
        "--out",
        s(&out_dir),
        "--no-default-plugins",
        "--plugins",
        s(&dir),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(
        err.contains(&format!(
            "plugins used: nucleus-template-attract ({})",
            dir.join(lib_name("nucleus_template_attract")).display()
        )),
        "{err}"
    );
    assert!(
        err.contains("group `attract`: kind `attract`, 1000 constraints, order -10, importance 1"),
        "{err}"
    );
    let stats = std::fs::read_to_string(out_dir.join("stats.csv")).expect("a complete run");
    let mut rows = stats.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = header
        .iter()
        .position(|c| *c == "attract.mean_distance")
        .unwrap_or_else(|| panic!("{header:?}"));
    assert!(header.contains(&"attract.max") && header.contains(&"attract.rms"));
    let mean: Vec<f64> = rows
        .map(|r| r.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    assert_eq!(mean.len(), 60, "one row per frame simulated");
    assert!(
        mean[59] < 0.5 * mean[0],
        "the cloud gathers: {} m -> {} m",
        mean[0],
        mean[59]
    );
}

#[test]
fn figure_13_a_kind_inserted_right_after_collisions_with_the_same_importance() {
    // The guide's worked example: read the collision kind's order and importance, give ours
    // order + 1 and the same importance, and every collision pass is followed by ours.
    let reg = registry(&[plugin_dir(), plugin_dir_with("fig13", &[template_lib()])]);
    let (_, collision) = reg
        .find("collision")
        .expect("the collision plugin is staged");
    let (order, importance) = (collision.default_order, collision.default_importance);
    assert!(
        importance > 1,
        "the example needs collisions solved more than once"
    );
    let scene_text = format!(
        "[solver]\nframes = 1\nsubsteps = 2\n[[objects]]\nname = \"cloth\"\n\
         pins = [\"corners:row0\"]\n[objects.grid]\nsize = [1.0, 1.0]\nresolution = [4, 4]\n\
         [[constraints]]\nkind = \"stretch\"\n[[constraints]]\nkind = \"collision\"\n\
         [[constraints]]\nkind = \"attract\"\norder = {}\nimportance = {importance}\n\
         params = {{ center = [0.0, -1.0, 0.0], radius = 0.1 }}\n",
        order + 1
    );
    let mut sim = Simulation::build(&scene(&scene_text), &reg).unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<&str> = sim.groups.iter().map(|g| g.name.as_str()).collect();
    let calls: Vec<&str> = sim.calls.iter().map(|c| names[c.group as usize]).collect();
    let after_collision: Vec<&str> = calls
        .windows(2)
        .filter(|w| w[0] == "collision")
        .map(|w| w[1])
        .collect();
    assert_eq!(after_collision.len(), importance as usize, "{calls:?}");
    assert!(after_collision.iter().all(|&n| n == "attract"), "{calls:?}");
    assert_eq!(
        calls.last(),
        Some(&"attract"),
        "ours has the last word: {calls:?}"
    );
    assert_eq!(
        calls.iter().filter(|&&n| n == "attract").count(),
        importance as usize
    );
    sim.step_frame().unwrap_or_else(|e| panic!("{e}"));

    // The same, as `nucleus run --verbose` shows it: one row per group in order, one column
    // per pass; ours right below collision with the same marks.
    let tmp = temp_dir("fig13");
    let scene_path = tmp.join("scene.toml");
    std::fs::write(&scene_path, &scene_text).unwrap();
    let extra = plugin_dir_with("fig13-host", &[template_lib()]);
    let out = host(&[
        "run",
        s(&scene_path),
        "--verbose",
        "--out",
        s(&tmp.join("out")),
        "--plugins",
        s(&extra),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    let rows: Vec<&str> = err
        .lines()
        .skip_while(|l| !l.starts_with("schedule per substep:"))
        .skip(1)
        .take(3)
        .collect();
    let marks = |row: &str| {
        row.split_whitespace()
            .nth(1)
            .unwrap_or_default()
            .to_string()
    };
    assert!(
        rows[0].starts_with("stretch") && rows[1].starts_with("collision"),
        "{err}"
    );
    assert!(rows[2].starts_with("attract"), "{err}");
    assert_eq!(marks(rows[2]), marks(rows[1]), "{err}");
    assert_eq!(marks(rows[1]), "x".repeat(importance as usize), "{err}");
}

#[test]
fn new_plugin_writes_a_standalone_crate_and_prints_the_next_commands() {
    let tmp = temp_dir("new-plugin");
    let dir = tmp.join("my-attractor");
    let out = host(&["new-plugin", "my-attractor", "--path", s(&dir)]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    let dir = dir.canonicalize().unwrap();
    let d = dir.display();
    for line in [
        format!("created plugin crate `my-attractor` with kind `my_attractor` in {d}"),
        format!("  cd {d} && cargo build --release"),
        format!("plugins --plugins {d}/target/release"),
        format!("run {d}/scene.toml --plugins {d}/target/release"),
    ] {
        assert!(stdout.contains(&line), "{line:?} not in {stdout}");
    }
    let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    assert!(manifest.contains("name = \"my-attractor\"") && manifest.contains("\n[workspace]\n"));
    let sdk = manifest
        .lines()
        .find_map(|l| l.strip_prefix("nucleus-sdk = { path = \""))
        .and_then(|l| l.strip_suffix("\" }"))
        .unwrap_or_else(|| panic!("{manifest}"));
    assert!(Path::new(sdk).is_absolute() && Path::new(sdk).join("src/abi.rs").is_file());
    let scene = std::fs::read_to_string(dir.join("scene.toml")).unwrap();
    assert!(scene.contains("kind = \"my_attractor\""), "{scene}");
    let lib = std::fs::read_to_string(dir.join("src/lib.rs")).unwrap();
    assert!(lib.contains("pub const KIND: &str = \"my_attractor\";"));
    for f in [
        "Cargo.lock",
        "README.md",
        "src/constraint.rs",
        "tests/load.rs",
    ] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    // Running it again refuses to touch the crate.
    std::fs::write(dir.join("src/lib.rs"), "// my work").unwrap();
    let again = host(&["new-plugin", "my-attractor", "--path", s(&dir)]);
    assert_eq!(again.status.code(), Some(2));
    assert!(
        text(&again.stderr).contains("not empty"),
        "{}",
        text(&again.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("src/lib.rs")).unwrap(),
        "// my work"
    );
}

#[test]
fn new_plugin_refuses_bad_names_and_a_missing_sdk_saying_why() {
    let tmp = temp_dir("new-plugin-bad");
    let target = tmp.join("x");
    for (args, why) in [
        (
            vec!["new-plugin", "9lives"],
            "not a valid plugin crate name",
        ),
        (
            vec!["new-plugin", "ok", "--kind", "Bad-Kind"],
            "not a valid kind name",
        ),
        (
            vec!["new-plugin", "ok", "--sdk", "/nonexistent/plugin-sdk"],
            "pass --sdk",
        ),
    ] {
        let mut args = args.clone();
        args.extend(["--path", s(&target)]);
        let out = host(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = text(&out.stderr);
        assert!(err.contains(why), "{args:?}: {err}");
        assert!(!target.exists(), "{args:?} wrote something");
    }
}
