//! `cargo xtask scene-hashes [--frames N] [--threads N] [--out FILE]`: runs every scene of
//! `scenes/` (release build) for its first N frames (default 40) and prints one line per scene,
//! `NAME HASH`, the FNV-1a hash of the bytes of every `frame_NNNN.obj` it wrote, in order.
//!
//! A refactor that must not change behaviour runs it before and after and compares the two
//! outputs: `diff before.txt after.txt` is empty when every frame of every scene is
//! byte-identical. Wall times are not hashed (`stats.csv` is skipped).

use std::path::Path;
use std::process::Command;

/// FNV-1a, 64 bits: enough to tell two byte streams apart, no dependency.
fn fnv1a(hash: &mut u64, bytes: &[u8]) {
    for b in bytes {
        *hash ^= u64::from(*b);
        *hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
}

/// Hash of every `frame_*.obj` in `dir`, in name order.
fn frames_hash(dir: &Path) -> Result<(u64, usize), String> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("frame_") && n.ends_with(".obj"))
        })
        .collect();
    files.sort();
    let mut hash = 0xcbf2_9ce4_8422_2325;
    for f in &files {
        let bytes = std::fs::read(f).map_err(|e| format!("{}: {e}", f.display()))?;
        fnv1a(&mut hash, &bytes);
    }
    Ok((hash, files.len()))
}

pub fn run(profile: &Path, root: &Path, args: &[String]) -> Result<(), String> {
    let mut frames = "40".to_string();
    let mut threads = "2".to_string();
    let mut out = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let value = || -> Result<String, String> { Err(format!("{a} needs a value")) };
        match a.as_str() {
            "--frames" => frames = it.next().cloned().map_or_else(value, Ok)?,
            "--threads" => threads = it.next().cloned().map_or_else(value, Ok)?,
            "--out" => out = Some(it.next().cloned().map_or_else(value, Ok)?),
            _ => return Err(format!("scene-hashes: unknown argument {a}")),
        }
    }
    let mut scenes: Vec<_> = std::fs::read_dir(root.join("scenes"))
        .map_err(|e| format!("scenes: {e}"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    scenes.sort();
    let work = profile.join("scene-hashes");
    let mut lines = String::new();
    for scene in scenes {
        let name = scene.file_stem().unwrap().to_string_lossy().to_string();
        let dir = work.join(&name);
        let _ = std::fs::remove_dir_all(&dir);
        let status = Command::new(profile.join("nucleus"))
            .current_dir(root)
            .args(["run", "--quiet", "--frames", &frames, "--threads", &threads])
            .arg(&scene)
            .arg("--out")
            .arg(&dir)
            .status()
            .map_err(|e| format!("nucleus: {e}"))?;
        let line = if status.success() {
            let (hash, n) = frames_hash(&dir)?;
            format!("{name} {hash:016x} ({n} frames)")
        } else {
            format!("{name} FAILED ({status})")
        };
        println!("{line}");
        lines.push_str(&line);
        lines.push('\n');
    }
    if let Some(out) = out {
        std::fs::write(&out, lines).map_err(|e| format!("{out}: {e}"))?;
    }
    Ok(())
}
