//! Output files: one OBJ per frame and a stats CSV, written so an interrupted or failed run
//! never leaves a truncated file that looks complete.
//!
//! * Each `frame_NNNN.obj` is written to a temporary name and renamed when complete, so a
//!   frame file either is whole or does not exist.
//! * Rows go to `stats.csv.partial` as frames finish; only a run that completes renames it to
//!   `stats.csv` and writes `run.json` with `"status": "complete"`. A failed run leaves
//!   `stats.csv.partial` and a `run.json` with `"status": "failed"` and the error.
//! * Before a run starts, `stats.csv` and `run.json` of an earlier run in the same directory
//!   are removed, so stale files never vouch for new frames.

use std::fmt::Write as _;
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::OutputError;
use crate::simulation::Simulation;

fn io<T>(path: &Path, r: std::io::Result<T>) -> Result<T, OutputError> {
    r.map_err(|source| OutputError {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `contents` to `path` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, contents: &[u8]) -> Result<(), OutputError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    {
        let mut f = io(&tmp, File::create(&tmp))?;
        io(&tmp, f.write_all(contents))?;
        io(&tmp, f.sync_data())?;
    }
    io(path, fs::rename(&tmp, path))
}

/// Formats the current state as an OBJ: one `o` per object, `v` lines for every particle,
/// `f` for surface triangles, `l` for curve edges and `p` for isolated points (1-based).
pub fn obj_text(sim: &Simulation, out: &mut String) {
    out.clear();
    let _ = writeln!(out, "# Nucleus frame {} t={}", sim.frame, sim.time);
    for p in &sim.particles.x {
        let _ = writeln!(out, "v {} {} {}", p[0], p[1], p[2]);
    }
    for o in &sim.objects {
        let _ = writeln!(out, "o {}", o.name);
        for t in &o.surface_triangles {
            let _ = writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        for e in &o.curve_edges {
            let _ = writeln!(out, "l {} {}", e[0] + 1, e[1] + 1);
        }
        for p in &o.points {
            let _ = writeln!(out, "p {}", p + 1);
        }
    }
}

/// The output of one run.
pub struct RunOutput {
    dir: PathBuf,
    stats: BufWriter<File>,
    stats_path: PathBuf,
    columns: Vec<String>,
    text: String,
    report_columns: Vec<String>,
}

impl RunOutput {
    /// Creates the directory, removes an earlier run's completion markers, and opens the
    /// partial stats file with its header.
    pub fn create(
        dir: &Path,
        sim: &mut Simulation,
    ) -> Result<RunOutput, Box<dyn std::error::Error + Send + Sync>> {
        io(dir, fs::create_dir_all(dir))?;
        for stale in ["stats.csv", "run.json"] {
            let p = dir.join(stale);
            if p.exists() {
                io(&p, fs::remove_file(&p))?;
            }
        }
        let stats_path = dir.join("stats.csv.partial");
        let file = io(&stats_path, File::create(&stats_path))?;
        let mut columns: Vec<String> = ["frame", "time_s", "wall_s", "kinetic_j", "potential_j"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        for g in &sim.groups {
            columns.push(format!("{}.max", g.name));
            columns.push(format!("{}.rms", g.name));
        }
        let report_columns: Vec<String> = sim.reports()?.into_iter().map(|(n, _)| n).collect();
        columns.extend(report_columns.iter().cloned());
        let mut out = RunOutput {
            dir: dir.to_path_buf(),
            stats: BufWriter::new(file),
            stats_path,
            columns,
            text: String::new(),
            report_columns,
        };
        let header = out.columns.join(",");
        io(&out.stats_path, writeln!(out.stats, "{header}"))?;
        Ok(out)
    }

    /// Writes the OBJ of the current frame.
    pub fn write_frame(&mut self, sim: &Simulation) -> Result<PathBuf, OutputError> {
        obj_text(sim, &mut self.text);
        let path = self.dir.join(format!("frame_{:04}.obj", sim.frame));
        write_atomic(&path, self.text.as_bytes())?;
        Ok(path)
    }

    /// Appends the stats row of the current frame.
    pub fn write_stats(
        &mut self,
        sim: &mut Simulation,
        wall_s: f64,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let residuals = sim.residuals()?;
        let elastic: f64 = residuals.iter().map(|r| r.energy).sum();
        let mut row = format!(
            "{},{},{},{},{}",
            sim.frame,
            sim.time,
            wall_s,
            sim.kinetic_energy(),
            sim.gravity_energy() + elastic
        );
        for r in &residuals {
            let _ = write!(row, ",{},{}", r.max, r.rms);
        }
        let reports = sim.reports()?;
        for name in &self.report_columns {
            let v = reports
                .iter()
                .find(|(n, _)| n == name)
                .map_or(f64::NAN, |(_, v)| *v);
            let _ = write!(row, ",{v}");
        }
        io(&self.stats_path, writeln!(self.stats, "{row}"))?;
        io(&self.stats_path, self.stats.flush())?;
        Ok(())
    }

    /// Marks the run complete: `stats.csv.partial` becomes `stats.csv`, `run.json` says so.
    pub fn finish(mut self, frames: u64, summary: &str) -> Result<(), OutputError> {
        io(&self.stats_path, self.stats.flush())?;
        let final_path = self.dir.join("stats.csv");
        io(&final_path, fs::rename(&self.stats_path, &final_path))?;
        let json = format!(
            "{{\"status\":\"complete\",\"frames\":{frames},\"summary\":{}}}\n",
            serde_json::Value::from(summary)
        );
        write_atomic(&self.dir.join("run.json"), json.as_bytes())
    }

    /// Marks the run failed: `run.json` records the error; the partial stats stay partial.
    pub fn fail(mut self, frames: u64, error: &str) -> Result<(), OutputError> {
        let _ = self.stats.flush();
        let json = format!(
            "{{\"status\":\"failed\",\"frames\":{frames},\"error\":{}}}\n",
            serde_json::Value::from(error)
        );
        write_atomic(&self.dir.join("run.json"), json.as_bytes())
    }

    /// The column names of the stats.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }
}
