//! `nucleus new-plugin NAME [--path DIR] [--kind KIND] [--sdk DIR]`: writes a new, standalone
//! constraint-plugin crate from the SDK's template crate (`plugin-sdk/template/`).
//!
//! The template's files are embedded in this binary (`include_str!`), so the command needs
//! nothing but this binary and, to build the result, cargo. The generated crate:
//!
//! * is its own workspace (an empty `[workspace]` table), so it builds anywhere, outside any
//!   other workspace;
//! * depends on the SDK **by path** (the absolute path of `plugin-sdk/` in the Nucleus checkout
//!   this binary was built from, or `--sdk`); once the SDK is published, replace the path by
//!   the version (`nucleus-sdk = "0.1"`);
//! * spells out every other dependency with the version and features the Nucleus workspace
//!   uses (read from the workspace manifest embedded here), and carries the workspace's
//!   `Cargo.lock`, so it resolves to exactly the versions Nucleus was tested with (abi_stable
//!   included) and builds without touching the network when they are in cargo's cache;
//! * copies the workspace's `[profile.*]` tables, so the plugin is compiled exactly like the
//!   built-in ones — same code, same speed;
//! * names the crate NAME, and the kind KIND (default: NAME with `-` as `_`, lower case).
//!
//! It refuses to write into an existing non-empty directory, a NAME that is not a valid crate
//! name, a KIND that is not a valid kind name, and a KIND that a plugin already installed
//! beside this binary (or on `NUCLEUS_PLUGIN_PATH`) provides: a scene could not tell the two
//! apart.

use std::path::{Path, PathBuf};

use clap::Args;
use nucleus_core::plugins::{search_path, Registry};

/// The arguments of `nucleus new-plugin`.
#[derive(Args, Debug, Clone)]
pub struct NewPluginArgs {
    /// Crate name of the new plugin: ASCII letters, digits, `-` and `_`, starting with a
    /// letter (e.g. `my-attractor`).
    pub name: String,
    /// Directory to create [default: ./NAME]. It must not exist, or be empty.
    #[arg(long, value_name = "DIR")]
    pub path: Option<PathBuf>,
    /// Kind name scenes use (`kind = "..."`) [default: NAME in lower case, `-` as `_`].
    #[arg(long)]
    pub kind: Option<String>,
    /// The Nucleus SDK to depend on: the `plugin-sdk/` directory of a Nucleus checkout
    /// [default: the one this binary was built from].
    #[arg(long, value_name = "DIR")]
    pub sdk: Option<PathBuf>,
}

/// The template crate's files, as `(path in the crate, contents)`.
const TEMPLATE_FILES: &[(&str, &str)] = &[
    (
        "README.md",
        include_str!("../../plugin-sdk/template/README.md"),
    ),
    (
        "scene.toml",
        include_str!("../../plugin-sdk/template/scene.toml"),
    ),
    (
        "src/lib.rs",
        include_str!("../../plugin-sdk/template/src/lib.rs"),
    ),
    (
        "src/constraint.rs",
        include_str!("../../plugin-sdk/template/src/constraint.rs"),
    ),
    (
        "src/group.rs",
        include_str!("../../plugin-sdk/template/src/group.rs"),
    ),
    (
        "src/tests.rs",
        include_str!("../../plugin-sdk/template/src/tests.rs"),
    ),
    (
        "tests/load.rs",
        include_str!("../../plugin-sdk/template/tests/load.rs"),
    ),
    (
        "benches/project.rs",
        include_str!("../../plugin-sdk/template/benches/project.rs"),
    ),
];

/// The template crate's manifest (it inherits from the workspace; see [`manifest`]).
const TEMPLATE_MANIFEST: &str = include_str!("../../plugin-sdk/template/Cargo.toml");
/// The Nucleus workspace manifest: dependency versions and build profiles.
const WORKSPACE_MANIFEST: &str = include_str!("../../Cargo.toml");
/// The Nucleus workspace lockfile: the exact versions Nucleus is built and tested with.
const WORKSPACE_LOCK: &str = include_str!("../../Cargo.lock");

/// The template's crate name, library name and kind, replaced in every file.
const TEMPLATE_CRATE: &str = "nucleus-template-attract";
const TEMPLATE_LIB: &str = "nucleus_template_attract";
const TEMPLATE_KIND: &str = "attract";

/// Rust keywords and crate names that cannot name a library crate, separated by spaces.
const RESERVED: &str = "as async await break const continue crate dyn else enum extern false fn \
    for if impl in let loop match mod move mut pub ref return self static struct super trait \
    true type unsafe use where while abstract become box do final gen macro override priv try \
    typeof unsized virtual yield test std core alloc proc_macro nucleus_sdk nucleus_core serde \
    criterion";

/// What to generate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PluginSpec {
    /// Crate name.
    pub name: String,
    /// Kind name.
    pub kind: String,
    /// Root of the Nucleus checkout whose SDK (and core, for the tests) the crate uses.
    pub nucleus_root: PathBuf,
}

impl PluginSpec {
    /// The library (and Rust crate) name: the crate name with `-` as `_`.
    pub fn lib_name(&self) -> String {
        self.name.replace('-', "_")
    }

    /// The platform file name of the plugin library cargo builds.
    pub fn lib_file(&self) -> String {
        format!(
            "{}{}{}",
            std::env::consts::DLL_PREFIX,
            self.lib_name(),
            std::env::consts::DLL_SUFFIX
        )
    }
}

/// Checks a crate name; the error says what is wrong with it.
pub fn check_crate_name(name: &str) -> Result<(), String> {
    let bad = |why: &str| Err(format!("`{name}` is not a valid plugin crate name: {why}"));
    if name.is_empty() {
        return bad("it is empty");
    }
    if name.len() > 64 {
        return bad("it is longer than 64 characters");
    }
    if !name.starts_with(|c: char| c.is_ascii_alphabetic()) {
        return bad("it must start with an ASCII letter");
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || *c == '-' || *c == '_'))
    {
        return bad(&format!(
            "{c:?} is not allowed (use ASCII letters, digits, `-` and `_`)"
        ));
    }
    let lib = name.replace('-', "_").to_ascii_lowercase();
    if RESERVED.split_whitespace().any(|r| r == lib) {
        return bad("it is a Rust keyword or the name of a crate the plugin depends on");
    }
    Ok(())
}

/// Checks a kind name: lower-case ASCII letters, digits and `_`, starting with a letter.
pub fn check_kind_name(kind: &str) -> Result<(), String> {
    let ok = kind.len() <= 64
        && kind.starts_with(|c: char| c.is_ascii_lowercase())
        && kind
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "`{kind}` is not a valid kind name: use lower-case ASCII letters, digits and `_`, \
             starting with a letter, at most 64 characters"
        ))
    }
}

/// The default kind of a crate name: lower case, `-` as `_`.
pub fn default_kind(name: &str) -> String {
    name.replace('-', "_").to_ascii_lowercase()
}

/// The `[section]` of a TOML manifest as its lines (without the header), up to the next header.
fn section<'a>(manifest: &'a str, header: &str) -> Vec<&'a str> {
    manifest
        .lines()
        .skip_while(|l| l.trim() != header)
        .skip(1)
        .take_while(|l| !l.trim_start().starts_with('['))
        .collect()
}

/// The value of `key = value` in a list of manifest lines.
fn value_of<'a>(lines: &[&'a str], key: &str) -> Option<&'a str> {
    lines.iter().find_map(|l| {
        let (k, v) = l.split_once('=')?;
        (k.trim() == key).then(|| v.trim())
    })
}

/// A TOML basic string.
fn toml_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The generated crate's manifest: the template's, with its name, and every
/// `X.workspace = true` replaced by what the Nucleus workspace says — package fields from
/// `[workspace.package]`, dependencies from `[workspace.dependencies]` with path dependencies
/// made absolute — then an empty `[workspace]` table and the workspace's build profiles.
pub fn manifest(spec: &PluginSpec) -> Result<String, String> {
    let package = section(WORKSPACE_MANIFEST, "[workspace.package]");
    let deps = section(WORKSPACE_MANIFEST, "[workspace.dependencies]");
    let mut out = String::new();
    for line in TEMPLATE_MANIFEST.lines() {
        let trimmed = line.trim();
        if trimmed.starts_with("##") {
            continue; // the template's notes about itself
        }
        if let Some(key) = trimmed.strip_suffix(".workspace = true") {
            match key {
                "license" => continue, // the author's choice, not ours
                "version" => out.push_str("version = \"0.1.0\"\n"),
                _ => {
                    if let Some(v) = value_of(&package, key) {
                        out.push_str(&format!("{key} = {v}\n"));
                    } else if let Some(v) = value_of(&deps, key) {
                        out.push_str(&dependency(key, v, &spec.nucleus_root)?);
                    } else {
                        return Err(format!(
                            "the template's `{key}.workspace = true` is not in the workspace manifest"
                        ));
                    }
                }
            }
            continue;
        }
        if let Some(v) = trimmed.strip_prefix("name = ") {
            if v == toml_string(TEMPLATE_CRATE) {
                out.push_str(&format!("name = {}\n", toml_string(&spec.name)));
                continue;
            }
        }
        if trimmed.starts_with("description = ") {
            out.push_str(&format!(
                "description = {}\n",
                toml_string(&format!("Nucleus constraint plugin: kind `{}`", spec.kind))
            ));
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    while out.contains("\n\n\n") {
        out = out.replace("\n\n\n", "\n\n");
    }
    out.push_str(
        "\n# A workspace of its own: this crate builds anywhere, outside any other workspace.\n\
         [workspace]\n",
    );
    // The profiles Nucleus builds its own plugins with, so this one is compiled the same way.
    let mut in_profile = false;
    for line in WORKSPACE_MANIFEST.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            in_profile = t.starts_with("[profile.");
            if in_profile {
                out.push('\n');
            }
        }
        if in_profile && !line.trim().is_empty() {
            out.push_str(line);
            out.push('\n');
        }
    }
    Ok(out)
}

/// One dependency line: the workspace's spec, with a path made absolute.
fn dependency(key: &str, spec: &str, root: &Path) -> Result<String, String> {
    let Some(rest) = spec.split_once("path = \"").map(|(_, r)| r) else {
        return Ok(format!("{key} = {spec}\n"));
    };
    let rel = rest
        .split_once('"')
        .map(|(p, _)| p)
        .ok_or_else(|| format!("cannot read the path of `{key}` in the workspace manifest"))?;
    let abs = root.join(rel);
    let abs = abs.to_str().ok_or_else(|| {
        format!(
            "the path {} is not valid UTF-8, which a manifest cannot hold",
            abs.display()
        )
    })?;
    Ok(format!(
        "# By path to the Nucleus checkout this crate was generated from; once the SDK is\n\
         # published, depend on it by version instead: {key} = \"0.1\"\n\
         {key} = {{ path = {} }}\n",
        toml_string(abs)
    ))
}

/// Every file of the generated crate, as `(path in the crate, contents)`.
pub fn files(spec: &PluginSpec) -> Result<Vec<(String, String)>, String> {
    let mut out = vec![
        ("Cargo.toml".to_string(), manifest(spec)?),
        ("Cargo.lock".to_string(), WORKSPACE_LOCK.to_string()),
        (".gitignore".to_string(), "/target\n/out\n".to_string()),
    ];
    let kind = &spec.kind;
    let replacements = [
        (TEMPLATE_CRATE.to_string(), spec.name.clone()),
        (TEMPLATE_LIB.to_string(), spec.lib_name()),
        (format!("\"{TEMPLATE_KIND}\""), format!("\"{kind}\"")),
        (format!("`{TEMPLATE_KIND}`"), format!("`{kind}`")),
        (
            format!("{TEMPLATE_KIND}.mean_distance"),
            format!("{kind}.mean_distance"),
        ),
    ];
    for (path, text) in TEMPLATE_FILES {
        let mut text = text.to_string();
        for (from, to) in &replacements {
            text = text.replace(from.as_str(), to);
        }
        out.push((path.to_string(), text));
    }
    Ok(out)
}

/// The Nucleus checkout this binary was built from.
fn built_from() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// Finds the Nucleus checkout from the SDK directory (`--sdk`, or the one this binary was built
/// from), checking that it holds the SDK and the core the generated crate depends on.
pub fn nucleus_root(sdk: Option<&Path>) -> Result<PathBuf, String> {
    let sdk_dir = sdk.map_or_else(|| built_from().join("plugin-sdk"), Path::to_path_buf);
    let hint = if sdk.is_some() {
        "pass --sdk the `plugin-sdk` directory of a Nucleus checkout".to_string()
    } else {
        format!(
            "this binary was built from {}, which has moved or is gone; pass --sdk the \
             `plugin-sdk` directory of a Nucleus checkout",
            built_from().display()
        )
    };
    let sdk_dir = sdk_dir
        .canonicalize()
        .map_err(|e| format!("the Nucleus SDK {}: {e}; {hint}", sdk_dir.display()))?;
    let root = sdk_dir
        .parent()
        .ok_or_else(|| format!("{} has no parent directory; {hint}", sdk_dir.display()))?
        .to_path_buf();
    for (dir, package) in [("plugin-sdk", "nucleus-sdk"), ("core", "nucleus-core")] {
        let manifest = root.join(dir).join("Cargo.toml");
        let text = std::fs::read_to_string(&manifest).unwrap_or_default();
        if !text.contains(&format!("name = \"{package}\"")) {
            return Err(format!(
                "{} is not the manifest of `{package}`; {hint}",
                manifest.display()
            ));
        }
    }
    Ok(root)
}

/// Writes `files` into `dir`, which must not exist or be empty. The files are written into a
/// temporary sibling directory first and moved into place at the end, so a failure leaves no
/// half-written crate behind.
pub fn write_crate(dir: &Path, files: &[(String, String)]) -> Result<(), String> {
    if dir.exists() {
        let mut entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        if entries.next().is_some() {
            return Err(format!(
                "{} already exists and is not empty: refusing to overwrite it (choose another --path)",
                dir.display()
            ));
        }
    }
    let name = dir
        .file_name()
        .ok_or_else(|| format!("{} does not name a directory", dir.display()))?;
    let parent = dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".new-plugin-{}", std::process::id()));
    let tmp = parent.join(tmp_name);
    let _ = std::fs::remove_dir_all(&tmp);
    let result = (|| {
        for (path, text) in files {
            let file = tmp.join(path);
            if let Some(d) = file.parent() {
                std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
            }
            std::fs::write(&file, text).map_err(|e| format!("{}: {e}", file.display()))?;
        }
        if dir.exists() {
            std::fs::remove_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        }
        std::fs::rename(&tmp, dir).map_err(|e| format!("{}: {e}", dir.display()))
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

/// Refuses a kind that an installed plugin (beside this binary, or on `NUCLEUS_PLUGIN_PATH`)
/// already provides.
fn check_kind_is_free(kind: &str) -> Result<(), String> {
    let registry = Registry::discover(&search_path(&[], true));
    if let Some(p) = registry
        .plugins
        .iter()
        .find(|p| p.info.kinds.iter().any(|k| k.name.as_str() == kind))
    {
        return Err(format!(
            "kind `{kind}` is already provided by plugin `{}` ({}); a scene could not tell \
             the two apart: choose another NAME or --kind",
            p.info.name,
            p.path.display()
        ));
    }
    Ok(())
}

/// Runs the command: validates, writes the crate, prints the next three commands.
pub fn run(args: &NewPluginArgs) -> Result<(), String> {
    check_crate_name(&args.name)?;
    let kind = args
        .kind
        .clone()
        .unwrap_or_else(|| default_kind(&args.name));
    check_kind_name(&kind)?;
    check_kind_is_free(&kind)?;
    let spec = PluginSpec {
        name: args.name.clone(),
        kind,
        nucleus_root: nucleus_root(args.sdk.as_deref())?,
    };
    let dir = args
        .path
        .clone()
        .unwrap_or_else(|| PathBuf::from(&args.name));
    write_crate(&dir, &files(&spec)?)?;
    let dir = dir.canonicalize().unwrap_or(dir);
    let exe = std::env::current_exe()
        .ok()
        .filter(|e| e.is_file())
        .map_or_else(|| "nucleus".to_string(), |e| e.display().to_string());
    let d = dir.display();
    println!(
        "created plugin crate `{}` with kind `{}` in {d}\n\
         SDK by path: {}\n\n\
         next:\n  \
         cd {d} && cargo build --release    # builds target/release/{}\n  \
         {exe} plugins --plugins {d}/target/release\n  \
         {exe} run {d}/scene.toml --plugins {d}/target/release --out {d}/out",
        spec.name,
        spec.kind,
        spec.nucleus_root.join("plugin-sdk").display(),
        spec.lib_file(),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(name: &str, kind: &str) -> PluginSpec {
        PluginSpec {
            name: name.to_string(),
            kind: kind.to_string(),
            nucleus_root: built_from(),
        }
    }

    fn file<'a>(files: &'a [(String, String)], path: &str) -> &'a str {
        &files
            .iter()
            .find(|(p, _)| p == path)
            .unwrap_or_else(|| panic!("no {path}"))
            .1
    }

    #[test]
    fn crate_names_are_checked() {
        for ok in ["probe", "my-attractor", "Goal_2", "a"] {
            assert!(check_crate_name(ok).is_ok(), "{ok}");
        }
        for (bad, why) in [
            ("", "empty"),
            ("9lives", "start with"),
            ("-x", "start with"),
            ("my plugin", "' ' is not allowed"),
            ("café", "not allowed"),
            ("self", "keyword"),
            ("test", "keyword"),
            ("nucleus-sdk", "depends on"),
        ] {
            let e = check_crate_name(bad).unwrap_err();
            assert!(
                e.contains(why) && e.contains(&format!("`{bad}`")),
                "{bad}: {e}"
            );
        }
        assert!(check_crate_name(&"x".repeat(65)).is_err());
    }

    #[test]
    fn kind_names_are_checked_and_derived_from_the_crate_name() {
        assert_eq!(default_kind("My-Goal"), "my_goal");
        assert!(check_kind_name("my_goal2").is_ok());
        for bad in ["", "2d", "My", "a-b", "a b"] {
            assert!(check_kind_name(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_manifest_is_standalone_with_the_workspace_versions_and_profiles() {
        let m = manifest(&spec("probe-plugin", "probe")).unwrap();
        assert!(m.contains("name = \"probe-plugin\""), "{m}");
        assert!(!m.contains(".workspace"), "{m}");
        assert!(m.contains("\n[workspace]\n"), "{m}");
        assert!(m.contains("crate-type = [\"cdylib\", \"rlib\"]"), "{m}");
        let root = built_from();
        for (dep, dir) in [("nucleus-sdk", "plugin-sdk"), ("nucleus-core", "core")] {
            let line = format!(
                "{dep} = {{ path = {} }}",
                toml_string(root.join(dir).to_str().unwrap())
            );
            assert!(m.contains(&line), "{line} not in {m}");
            assert!(root.join(dir).join("Cargo.toml").is_file());
        }
        // Every other dependency exactly as the workspace declares it.
        let deps = section(WORKSPACE_MANIFEST, "[workspace.dependencies]");
        for dep in ["serde", "criterion"] {
            let line = format!("{dep} = {}", value_of(&deps, dep).unwrap());
            assert!(m.contains(&line), "{line} not in {m}");
        }
        for profile in ["[profile.release]", "[profile.dev]"] {
            assert!(m.contains(profile), "{profile} not in {m}");
        }
    }

    #[test]
    fn every_template_name_is_replaced() {
        let files = files(&spec("probe-plugin", "probe_kind")).unwrap();
        for (path, text) in &files {
            if path == "Cargo.lock" {
                continue;
            }
            for stale in [
                TEMPLATE_CRATE.to_string(),
                TEMPLATE_LIB.to_string(),
                format!("\"{TEMPLATE_KIND}\""),
                format!("`{TEMPLATE_KIND}`"),
            ] {
                assert!(!text.contains(&stale), "{path} still holds {stale}");
            }
        }
        assert!(file(&files, "src/lib.rs").contains("pub const KIND: &str = \"probe_kind\";"));
        assert!(file(&files, "scene.toml").contains("kind = \"probe_kind\""));
        assert!(file(&files, "benches/project.rs").contains("probe_plugin::KIND"));
        assert!(file(&files, "README.md").contains("`probe_kind`"));
        let names: Vec<&str> = files.iter().map(|(p, _)| p.as_str()).collect();
        for needed in [
            "Cargo.toml",
            "Cargo.lock",
            ".gitignore",
            "src/lib.rs",
            "tests/load.rs",
        ] {
            assert!(names.contains(&needed), "{needed} missing: {names:?}");
        }
    }

    #[test]
    fn every_file_of_the_template_is_embedded() {
        // Every file of the template directory is embedded, and nothing else.
        let dir = built_from().join("plugin-sdk/template");
        let mut on_disk = Vec::new();
        let mut stack = vec![dir.clone()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    if p.file_name().is_some_and(|n| n != "target") {
                        stack.push(p);
                    }
                } else {
                    let rel = p.strip_prefix(&dir).unwrap().to_str().unwrap().to_string();
                    on_disk.push(rel.replace('\\', "/"));
                }
            }
        }
        on_disk.retain(|p| p != "Cargo.toml");
        on_disk.sort();
        let mut embedded: Vec<String> = TEMPLATE_FILES.iter().map(|(p, _)| p.to_string()).collect();
        embedded.sort();
        assert_eq!(
            on_disk, embedded,
            "update TEMPLATE_FILES in host/src/new_plugin.rs"
        );
    }

    #[test]
    fn an_existing_non_empty_directory_is_never_overwritten() {
        let base = std::env::temp_dir().join(format!("nucleus-new-plugin-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let dir = base.join("crate");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("keep.txt"), "mine").unwrap();
        let files = vec![("a/b.txt".to_string(), "x".to_string())];
        let e = write_crate(&dir, &files).unwrap_err();
        assert!(e.contains("not empty") && e.contains("crate"), "{e}");
        assert_eq!(
            std::fs::read_to_string(dir.join("keep.txt")).unwrap(),
            "mine"
        );
        assert!(!dir.join("a").exists());
        // An empty directory, or none, is fine.
        std::fs::remove_file(dir.join("keep.txt")).unwrap();
        write_crate(&dir, &files).unwrap();
        assert_eq!(std::fs::read_to_string(dir.join("a/b.txt")).unwrap(), "x");
        write_crate(&base.join("fresh/deeper"), &files).unwrap();
        assert!(base.join("fresh/deeper/a/b.txt").is_file());
        let leftovers: Vec<_> = std::fs::read_dir(&base)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n.to_string_lossy().starts_with('.'))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
        let _ = std::fs::remove_dir_all(&base);
    }

    #[test]
    fn a_missing_sdk_is_reported_with_what_to_do() {
        let e = nucleus_root(Some(Path::new("/nonexistent/plugin-sdk"))).unwrap_err();
        assert!(
            e.contains("/nonexistent/plugin-sdk") && e.contains("--sdk"),
            "{e}"
        );
        let root = nucleus_root(None).unwrap();
        assert!(root.join("plugin-sdk/src/lib.rs").is_file());
    }
}
