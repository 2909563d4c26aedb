//! `docs/scene-format.md` holds every kind's parameters as the plugins declare them: its
//! generated block equals what `nucleus plugins --markdown` prints over the staged plugins, so
//! a parameter added, renamed or re-documented in a plugin cannot leave the reference stale.

use nucleus_tests::*;

const BEGIN: &str = "<!-- BEGIN GENERATED: nucleus plugins --markdown -->";
const END: &str = "<!-- END GENERATED -->";

#[test]
fn scene_format_parameter_block_matches_the_plugins_declarations() {
    let output = std::process::Command::new(host_bin())
        .args(["plugins", "--markdown", "--no-default-plugins", "--plugins"])
        .arg(plugin_dir())
        .env_remove("NUCLEUS_PLUGIN_PATH")
        .output()
        .expect("run nucleus plugins --markdown");
    assert!(
        output.status.success(),
        "nucleus plugins --markdown failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let live = String::from_utf8(output.stdout).expect("UTF-8 output");
    for kind in ["stretch", "bend", "air", "pressure", "rigid", "collision"] {
        assert!(
            live.contains(&format!("\n### `{kind}`\n")),
            "no section for the `{kind}` kind in:\n{live}"
        );
    }
    let page = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/scene-format.md");
    let text = std::fs::read_to_string(&page).expect("docs/scene-format.md");
    let begin = text.find(BEGIN).expect("the BEGIN GENERATED marker") + BEGIN.len() + 1;
    let end = text.find(END).expect("the END GENERATED marker");
    let checked_in = &text[begin..end];
    if checked_in != live {
        let line = checked_in
            .lines()
            .zip(live.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(checked_in.lines().count().min(live.lines().count()));
        panic!(
            "docs/scene-format.md's generated parameter reference differs from the plugins' \
             declarations (first difference at line {} of the block: {:?} against {:?}): \
             regenerate it with `cargo xtask docs`",
            line + 1,
            checked_in.lines().nth(line).unwrap_or("<end>"),
            live.lines().nth(line).unwrap_or("<end>"),
        );
    }
}
