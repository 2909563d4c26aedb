//! `cargo xtask docs`: regenerates the generated block of `docs/scene-format.md` (every kind
//! and parameter, from `nucleus plugins --markdown` over the staged plugins).
//! `tests/tests/scene_format_doc.rs` fails when the checked-in block differs from it.

use std::path::Path;
use std::process::Command;

/// The markers around the generated block; `tests/tests/scene_format_doc.rs` uses the same.
pub const BEGIN: &str = "<!-- BEGIN GENERATED: nucleus plugins --markdown -->";
/// See [`BEGIN`].
pub const END: &str = "<!-- END GENERATED -->";

/// Writes the block into `root/docs/scene-format.md`; `profile` holds the host and its staged
/// plugins.
pub fn run(profile: &Path, root: &Path) -> Result<(), String> {
    let output = Command::new(profile.join(format!("nucleus{}", std::env::consts::EXE_SUFFIX)))
        .args(["plugins", "--markdown", "--no-default-plugins", "--plugins"])
        .arg(profile.join("plugins"))
        .env_remove("NUCLEUS_PLUGIN_PATH")
        .output()
        .map_err(|e| format!("nucleus plugins --markdown: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "nucleus plugins --markdown failed: {}",
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let block = String::from_utf8(output.stdout).map_err(|e| e.to_string())?;
    let page = root.join("docs").join("scene-format.md");
    let text = std::fs::read_to_string(&page).map_err(|e| format!("{}: {e}", page.display()))?;
    let (Some(b), Some(e)) = (text.find(BEGIN), text.find(END)) else {
        return Err(format!("{}: no generated-block markers", page.display()));
    };
    let new = format!(
        "{}{BEGIN}\n{block}{END}{}",
        &text[..b],
        &text[e + END.len()..]
    );
    std::fs::write(&page, new).map_err(|e| format!("{}: {e}", page.display()))?;
    eprintln!("wrote {}", page.display());
    Ok(())
}
