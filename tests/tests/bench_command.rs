//! `nucleus bench`, end to end through the host binary: one CSV row per substeps × iterations
//! combination with the documented columns, the reference row exactly at zero position error,
//! errors that fall with more substeps, the Small Steps result (`docs/decisions/small-steps.md`: n substeps of
//! one pass beat one substep of n passes), no energy made by hard constraints, both plots
//! written; bad input — zero frames, a bad scene, an output directory that cannot be made — is
//! refused as such (exit 2) before any combination runs.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Output;

use nucleus_tests::*;

const STRETCH: &str = "[[constraints]]\nkind = \"stretch\"\nobjects = [\"cloth\"]\n";

/// Runs `nucleus bench` on a 12 × 12 drape (10 frames) with `args`, writing to `out`.
fn bench(tag: &str, args: &[&str]) -> (Output, std::path::PathBuf) {
    let dir = temp_dir(tag);
    let scene = dir.join("drape.toml");
    std::fs::write(&scene, drape_text(12, 10, 2, 1, STRETCH)).unwrap();
    let out = dir.join("out");
    let output = host_command("bench", &scene, &out)
        .args(args)
        .output()
        .unwrap();
    (output, out)
}

/// The rows of `bench.csv`, keyed by (substeps, iterations), each a map from column to value.
fn rows(path: &Path) -> BTreeMap<(u32, u32), BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    lines
        .map(|l| {
            let cells: BTreeMap<String, String> = header
                .iter()
                .zip(l.split(','))
                .map(|(h, c)| (h.to_string(), c.to_string()))
                .collect();
            let key = (
                cells["substeps"].parse().unwrap(),
                cells["iterations"].parse().unwrap(),
            );
            (key, cells)
        })
        .collect()
}

#[test]
fn bench_writes_a_row_per_combination_and_its_errors_follow_the_substeps() {
    let (output, out) = bench(
        "bench-grid",
        &[
            "--substeps",
            "1,4,16",
            "--iterations",
            "1,4",
            "--frames",
            "10",
            "--repeats",
            "1",
        ],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let rows = rows(&out.join("bench.csv"));
    let keys: Vec<(u32, u32)> = rows.keys().copied().collect();
    assert_eq!(keys, [(1, 1), (1, 4), (4, 1), (4, 4), (16, 1), (16, 4)]);
    let value = |k: (u32, u32), column: &str| -> f64 {
        rows[&k][column]
            .parse()
            .unwrap_or_else(|e| panic!("{k:?} {column}: {e}"))
    };
    for (&k, row) in &rows {
        assert_eq!(row["failure"], "", "{k:?}");
        let wall = value(k, "wall_s_per_frame");
        assert!(wall > 0.0 && wall.is_finite(), "{k:?}: {wall}");
        for column in ["stretch.max_end", "stretch.rms_mean", "pos_rms_mean"] {
            let v = value(k, column);
            assert!(v.is_finite() && v >= 0.0, "{k:?} {column}: {v}");
        }
        // Hard constraints only take energy out of an undamped drape.
        let drift = value(k, "energy_drift_rel");
        assert!(
            drift <= 0.0,
            "{k:?}: energy made, {drift} of the peak kinetic"
        );
    }
    // The reference is the finest combination, run again: the same bits, zero error.
    for column in ["pos_rms_end", "pos_max_end", "pos_rms_mean", "pos_max_peak"] {
        assert_eq!(value((16, 4), column), 0.0, "{column}");
    }
    // More substeps of one pass: less strain and closer to the reference, by a wide margin.
    for column in ["stretch.rms_mean", "pos_rms_mean"] {
        let (a, b, c) = (
            value((1, 1), column),
            value((4, 1), column),
            value((16, 1), column),
        );
        assert!(b < 0.8 * a && c < 0.5 * b, "{column}: {a} {b} {c}");
    }
    // Small Steps (Macklin et al. 2019; docs/decisions/small-steps.md): at equal passes a
    // frame, n substeps of one pass beat one substep of n passes (about 1.7× and 2.2× in strain
    // here).
    for column in ["stretch.rms_mean", "pos_rms_mean"] {
        assert!(
            value((4, 1), column) < 0.8 * value((1, 4), column),
            "{column}: 4 × 1 against 1 × 4"
        );
        assert!(
            value((16, 1), column) < 0.8 * value((4, 4), column),
            "{column}: 16 × 1 against 4 × 4"
        );
    }
    for plot in ["bench.svg", "bench_residual.svg"] {
        let svg = std::fs::read_to_string(out.join(plot)).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
            "{plot}"
        );
    }
}

#[test]
fn a_benchmark_of_zero_frames_is_refused() {
    let (output, out) = bench(
        "bench-zero-frames",
        &["--substeps", "1", "--iterations", "1", "--frames", "0"],
    );
    assert_eq!(output.status.code(), Some(2), "bad input");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("needs at least 1 frame"), "{stderr}");
    assert!(!out.join("bench.csv").exists());
}

/// A bad scene and an output directory that cannot be made are bad input (exit 2), found
/// before any combination runs: neither the reference run nor a row is measured.
#[test]
fn a_bad_scene_or_output_directory_is_refused_before_the_sweep_runs() {
    let (output, out) = bench(
        "bench-bad-scene",
        &[
            "--substeps",
            "1",
            "--iterations",
            "1",
            "--set",
            "constraints.0.kind=\"strech\"",
        ],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no plugin provides kind `strech`"),
        "{stderr}"
    );
    assert!(!stderr.contains("reference:") && !out.exists(), "{stderr}");

    let dir = temp_dir("bench-bad-out");
    let scene = dir.join("drape.toml");
    std::fs::write(&scene, drape_text(12, 10, 2, 1, STRETCH)).unwrap();
    let blocker = dir.join("a_file");
    std::fs::write(&blocker, "keep me").unwrap();
    let out = blocker.join("out");
    let output = host_command("bench", &scene, &out)
        .args(["--substeps", "1", "--iterations", "1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("cannot create the output directory"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("substeps x"),
        "a combination ran: {stderr}"
    );
    assert_eq!(std::fs::read_to_string(&blocker).unwrap(), "keep me");
}
