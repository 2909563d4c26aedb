//! `nucleus bench`: run time against error.
//!
//! Runs a scene at every combination of substeps × iterations and measures, per combination:
//!
//! * `wall_s_per_frame` — step time per frame (the median over `--repeats` runs; output,
//!   residuals and errors are computed outside the timed region);
//! * each group's residual in its own unit (for stretch: strain): `<group>.max_end`,
//!   `<group>.rms_end` at the last frame, and `<group>.max_mean`, `<group>.rms_mean` averaged
//!   over all frames;
//! * the position error against a converged reference run of the same scene (the finest
//!   setting of the grid, or `--reference S,I`): `pos_rms_end`, `pos_max_end` (m, over
//!   particles at the last frame), `pos_rms_mean` (mean over frames of the per-frame RMS) and
//!   `pos_max_peak` (largest over frames and particles);
//! * `energy_drift_j` — total energy (kinetic + gravitational + energy stored in soft
//!   constraints) at the end minus at the start (J), and `energy_drift_rel`, the same divided
//!   by the largest kinetic energy the run reached (meaningful for scenes without
//!   dissipation; hard constraints themselves dissipate).
//!
//! Writes `DIR/bench.csv` and `DIR/bench.svg` (log-log time per frame against the position
//! error, one curve per substep count, the Pareto front marked) and `DIR/bench_residual.svg`
//! (the same against the first group's RMS residual).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nucleus_core::output::write_atomic;
use nucleus_core::{Registry, Scene, Simulation};
use plotters::prelude::*;

/// What to run.
pub struct BenchArgs {
    /// The scene.
    pub scene: PathBuf,
    /// `--set` overrides.
    pub set: Vec<String>,
    /// Substep counts.
    pub substeps: Vec<u32>,
    /// Iteration counts.
    pub iterations: Vec<u32>,
    /// Frames per run (default: the scene's).
    pub frames: Option<u32>,
    /// Timed repeats per combination.
    pub repeats: u32,
    /// Reference setting (substeps, iterations).
    pub reference: Option<(u32, u32)>,
    /// Output directory.
    pub out: PathBuf,
    /// Threads of the step's team (default: the simulation's, from `RAYON_NUM_THREADS`).
    pub threads: Option<usize>,
    /// Print progress.
    pub quiet: bool,
}

/// The measurements of one combination.
#[derive(Debug, Clone)]
pub struct Row {
    /// Substeps.
    pub substeps: u32,
    /// Iterations.
    pub iterations: u32,
    /// Median step time per frame (s).
    pub wall_s_per_frame: f64,
    /// Per group: (max at end, rms at end, mean of max, mean of rms).
    pub residuals: Vec<[f64; 4]>,
    /// Position error: rms at end, max at end, mean rms, peak max (m).
    pub position: [f64; 4],
    /// Energy drift (J) and relative drift.
    pub energy: [f64; 2],
    /// An error that stopped the run, if any.
    pub failure: Option<String>,
}

/// Parses `1,2,4`.
pub fn parse_list(s: &str) -> Result<Vec<u32>, String> {
    let v: Result<Vec<u32>, _> = s.split(',').map(|p| p.trim().parse::<u32>()).collect();
    match v {
        Ok(v) if !v.is_empty() && v.iter().all(|&x| x > 0) => Ok(v),
        _ => Err(format!(
            "`{s}`: expected a comma-separated list of positive integers"
        )),
    }
}

fn build(
    scene: &Scene,
    registry: &Registry,
    (s, i): (u32, u32),
    threads: Option<usize>,
) -> Result<Simulation, String> {
    let mut scene = scene.clone();
    scene.file.solver.substeps = s;
    scene.file.solver.iterations = i;
    let mut sim = Simulation::build(&scene, registry).map_err(|e| e.to_string())?;
    if let Some(t) = threads {
        sim.threads = t;
    }
    Ok(sim)
}

fn total_energy(sim: &mut Simulation) -> Result<f64, String> {
    let elastic: f64 = sim
        .residuals()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|r| r.energy)
        .sum();
    Ok(sim.kinetic_energy() + sim.gravity_energy() + elastic)
}

/// Runs the reference and returns its positions at every frame (1..=frames).
fn reference_positions(
    scene: &Scene,
    registry: &Registry,
    (s, i): (u32, u32),
    frames: u32,
    threads: Option<usize>,
) -> Result<Vec<Vec<[f64; 3]>>, String> {
    let mut sim = build(scene, registry, (s, i), threads)?;
    let mut out = Vec::with_capacity(frames as usize);
    for _ in 0..frames {
        sim.step_frame()
            .map_err(|e| format!("reference run {s}x{i}: {e}"))?;
        out.push(sim.particles.x.clone());
    }
    Ok(out)
}

fn measure(
    scene: &Scene,
    registry: &Registry,
    (s, i): (u32, u32),
    frames: u32,
    repeats: u32,
    reference: &[Vec<[f64; 3]>],
    threads: Option<usize>,
) -> Result<Row, String> {
    let mut times = Vec::new();
    let mut row = Row {
        substeps: s,
        iterations: i,
        wall_s_per_frame: f64::NAN,
        residuals: Vec::new(),
        position: [0.0; 4],
        energy: [0.0; 2],
        failure: None,
    };
    for r in 0..repeats {
        let mut sim = build(scene, registry, (s, i), threads)?;
        let measure_errors = r == 0;
        let groups = sim.groups.len();
        let mut sums = vec![[0.0f64; 4]; groups];
        let e0 = if measure_errors {
            total_energy(&mut sim)?
        } else {
            0.0
        };
        let mut max_ke: f64 = 0.0;
        let mut step = 0.0;
        for refx in reference.iter().take(frames as usize) {
            let t = Instant::now();
            let stepped = sim.step_frame();
            step += t.elapsed().as_secs_f64();
            if let Err(e) = stepped {
                row.failure = Some(e.to_string());
                return Ok(row);
            }
            if !measure_errors {
                continue;
            }
            let res = sim.residuals().map_err(|e| e.to_string())?;
            for (acc, r) in sums.iter_mut().zip(&res) {
                acc[0] = r.max;
                acc[1] = r.rms;
                acc[2] += r.max / frames as f64;
                acc[3] += r.rms / frames as f64;
            }
            max_ke = max_ke.max(sim.kinetic_energy());
            let (mut sq, mut mx) = (0.0f64, 0.0f64);
            for (a, b) in sim.particles.x.iter().zip(refx) {
                let d2 = (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2);
                sq += d2;
                mx = mx.max(d2);
            }
            let rms = (sq / refx.len().max(1) as f64).sqrt();
            let mx = mx.sqrt();
            row.position[0] = rms;
            row.position[1] = mx;
            row.position[2] += rms / frames as f64;
            row.position[3] = row.position[3].max(mx);
        }
        if measure_errors {
            row.residuals = sums;
            let e1 = total_energy(&mut sim)?;
            row.energy = [e1 - e0, (e1 - e0) / max_ke.max(f64::MIN_POSITIVE)];
        }
        times.push(step / frames.max(1) as f64);
    }
    times.sort_by(f64::total_cmp);
    row.wall_s_per_frame = times[times.len() / 2];
    Ok(row)
}

/// Indices of the rows on the Pareto front of (time, error): no other row is at least as
/// fast and at least as accurate, and strictly better in one.
pub fn pareto(points: &[(f64, f64)]) -> Vec<usize> {
    (0..points.len())
        .filter(|&i| {
            let (t, e) = points[i];
            t.is_finite()
                && e.is_finite()
                && !points
                    .iter()
                    .enumerate()
                    .any(|(j, &(tj, ej))| j != i && tj <= t && ej <= e && (tj < t || ej < e))
        })
        .collect()
}

fn csv(rows: &[Row], names: &[String]) -> String {
    let mut s = String::from("substeps,iterations,wall_s_per_frame");
    for n in names {
        let _ = write!(s, ",{n}.max_end,{n}.rms_end,{n}.max_mean,{n}.rms_mean");
    }
    s.push_str(",pos_rms_end,pos_max_end,pos_rms_mean,pos_max_peak,energy_drift_j,energy_drift_rel,failure\n");
    for r in rows {
        let _ = write!(s, "{},{},{}", r.substeps, r.iterations, r.wall_s_per_frame);
        for k in 0..names.len() {
            let v = r.residuals.get(k).copied().unwrap_or([f64::NAN; 4]);
            let _ = write!(s, ",{},{},{},{}", v[0], v[1], v[2], v[3]);
        }
        let p = r.position;
        let _ = writeln!(
            s,
            ",{},{},{},{},{},{},{}",
            p[0],
            p[1],
            p[2],
            p[3],
            r.energy[0],
            r.energy[1],
            r.failure.as_deref().unwrap_or("").replace(',', ";")
        );
    }
    s
}

/// Draws time per frame (ms) against `error(row)` on log-log axes, one curve per substep
/// count, with the Pareto front marked.
fn plot(
    path: &Path,
    title: &str,
    y_label: &str,
    rows: &[Row],
    error: impl Fn(&Row) -> f64,
) -> Result<(), String> {
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.wall_s_per_frame * 1e3, error(r)))
        .collect();
    let usable: Vec<(f64, f64)> = pts
        .iter()
        .copied()
        .filter(|&(t, e)| t > 0.0 && e > 0.0 && t.is_finite() && e.is_finite())
        .collect();
    if usable.is_empty() {
        return Ok(());
    }
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, 0.0f64, f64::MAX, 0.0f64);
    for &(t, e) in &usable {
        t0 = t0.min(t);
        t1 = t1.max(t);
        e0 = e0.min(e);
        e1 = e1.max(e);
    }
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let root = SVGBackend::new(path, (900, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(75)
        .build_cartesian_2d(
            (t0 / 1.5..t1 * 1.5).log_scale(),
            (e0 / 2.0..e1 * 2.0).log_scale(),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("step time per frame (ms)")
        .y_desc(y_label)
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| err(&e))?;
    let mut substeps: Vec<u32> = rows.iter().map(|r| r.substeps).collect();
    substeps.sort_unstable();
    substeps.dedup();
    for (k, s) in substeps.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        let mut line: Vec<(f64, f64)> = rows
            .iter()
            .zip(&pts)
            .filter(|(r, &(t, e))| r.substeps == *s && t > 0.0 && e > 0.0 && e.is_finite())
            .map(|(_, &p)| p)
            .collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(line.clone(), color.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(format!("{s} substeps"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        chart
            .draw_series(line.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(|e| err(&e))?;
    }
    let mut front: Vec<(f64, f64)> = pareto(&pts)
        .into_iter()
        .map(|i| pts[i])
        .filter(|&(t, e)| t > 0.0 && e > 0.0)
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart
        .draw_series(LineSeries::new(front.clone(), BLACK.stroke_width(1)))
        .map_err(|e| err(&e))?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    chart
        .draw_series(
            front
                .iter()
                .map(|&p| Circle::new(p, 7, BLACK.stroke_width(2))),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Runs the benchmark and writes its files; returns the rows.
pub fn run(args: &BenchArgs, registry: &Registry) -> Result<Vec<Row>, BenchError> {
    // Bad input first, before any combination runs: the scene, its frames, a simulation built
    // from it, and the output directory.
    let input = BenchError::Input;
    let mut scene =
        Scene::load_with_overrides(&args.scene, &args.set).map_err(|e| input(e.to_string()))?;
    if let Some(f) = args.frames {
        scene.file.solver.frames = f;
    }
    // Every figure is a mean or a peak over the frames run: none without a frame.
    let frames = scene.file.solver.frames;
    if frames == 0 {
        return Err(input(format!(
            "{}: the benchmark needs at least 1 frame (--frames or the scene's frames)",
            args.scene.display()
        )));
    }
    let names: Vec<String> = build(&scene, registry, (1, 1), args.threads)
        .map_err(input)?
        .groups
        .iter()
        .map(|g| g.name.clone())
        .collect();
    crate::create_output_dir(&args.out).map_err(input)?;
    let reference = args.reference.unwrap_or((
        *args.substeps.iter().max().unwrap_or(&1),
        *args.iterations.iter().max().unwrap_or(&1),
    ));
    if !args.quiet {
        eprintln!(
            "reference: {} substeps x {} iterations, {frames} frames",
            reference.0, reference.1
        );
    }
    measure_all(args, registry, &scene, frames, reference, &names).map_err(BenchError::Run)
}

/// Why a benchmark stopped: bad input (the scene, the output directory), found before any
/// combination runs, or a failure while running or writing.
#[derive(Debug)]
pub enum BenchError {
    /// Bad input.
    Input(String),
    /// A failure of a run or of the output.
    Run(String),
}

/// The reference run, every combination, then `bench.csv` and the plots.
fn measure_all(
    args: &BenchArgs,
    registry: &Registry,
    scene: &Scene,
    frames: u32,
    reference: (u32, u32),
    names: &[String],
) -> Result<Vec<Row>, String> {
    let ref_x = reference_positions(scene, registry, reference, frames, args.threads)?;
    let mut rows = Vec::new();
    for &s in &args.substeps {
        for &i in &args.iterations {
            let row = measure(
                scene,
                registry,
                (s, i),
                frames,
                args.repeats.max(1),
                &ref_x,
                args.threads,
            )?;
            if !args.quiet {
                eprintln!(
                    "{s:>4} substeps x {i:>3} iterations: {:>9.3} ms/frame, position rms {:.3e} m{}",
                    row.wall_s_per_frame * 1e3,
                    row.position[0],
                    row.residuals
                        .first()
                        .map(|r| format!(", {} rms {:.3e} max {:.3e}", names[0], r[1], r[0]))
                        .unwrap_or_default()
                );
            }
            rows.push(row);
        }
    }
    write_atomic(&args.out.join("bench.csv"), csv(&rows, names).as_bytes())
        .map_err(|e| e.to_string())?;
    let title = format!(
        "{}: time per frame vs position error (reference {}x{})",
        args.scene.display(),
        reference.0,
        reference.1
    );
    plot(
        &args.out.join("bench.svg"),
        &title,
        "RMS position error at the end (m)",
        &rows,
        |r| r.position[0],
    )?;
    if let Some(first) = names.first() {
        plot(
            &args.out.join("bench_residual.svg"),
            &format!(
                "{}: time per frame vs {first} residual",
                args.scene.display()
            ),
            &format!("{first} RMS residual, mean over frames"),
            &rows,
            |r| r.residuals.first().map_or(f64::NAN, |v| v[3]),
        )?;
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let pts = [
            (1.0, 10.0),
            (2.0, 5.0),
            (3.0, 6.0),
            (4.0, 1.0),
            (4.0, 2.0),
            (0.5, f64::NAN),
        ];
        assert_eq!(pareto(&pts), vec![0, 1, 3]);
    }

    #[test]
    fn lists_parse_and_reject_zero() {
        assert_eq!(parse_list("1,2, 4").unwrap(), vec![1, 2, 4]);
        assert!(parse_list("1,0").is_err());
        assert!(parse_list("a").is_err());
    }
}
