//! `nucleus`: loads plugin directories and runs scenes.

mod bench;
mod new_plugin;
mod plugin_docs;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use nucleus_core::output::RunOutput;
use nucleus_core::plugins::{search_path, Registry};
use nucleus_core::schedule::{describe, Slot};
use nucleus_core::{Scene, Simulation};

#[derive(Parser)]
#[command(
    name = "nucleus",
    version,
    about = "Nucleus: a unified dynamics solver with constraint plugins"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Args, Clone)]
struct PluginArgs {
    /// Plugin directory to search (repeatable); searched before NUCLEUS_PLUGIN_PATH and the
    /// default `plugins/` next to the executable.
    #[arg(long = "plugins", value_name = "DIR")]
    plugins: Vec<PathBuf>,
    /// Do not search the default `plugins/` directory next to the executable.
    #[arg(long)]
    no_default_plugins: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene: writes DIR/frame_NNNN.obj per frame, DIR/stats.csv and DIR/run.json.
    Run {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Output directory [default: out/STEM, STEM the scene file name without .toml].
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Override the number of frames.
        #[arg(long)]
        frames: Option<u32>,
        /// Override the substeps per frame.
        #[arg(long)]
        substeps: Option<u32>,
        /// Override the iterations (importance multiplier).
        #[arg(long)]
        iterations: Option<u32>,
        /// Override any scene value: `--set objects.0.grid.resolution=[128,128]` (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Threads of the step's team [default: RAYON_NUM_THREADS, else the machine's cores].
        /// The output is bit-identical for every count.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
        threads: Option<u32>,
        /// Print plugins, groups and the schedule.
        #[arg(long, short)]
        verbose: bool,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
        #[command(flatten)]
        plugin_args: PluginArgs,
    },
    /// Run time against error: run SCENE at every substeps x iterations combination and write
    /// DIR/bench.csv, DIR/bench.svg (time per frame vs position error) and
    /// DIR/bench_residual.svg.
    Bench {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Substep counts, comma-separated.
        #[arg(long, default_value = "1,2,4,8,16")]
        substeps: String,
        /// Iteration counts, comma-separated.
        #[arg(long, default_value = "1,2,4,8,16")]
        iterations: String,
        /// Frames per run [default: the scene's].
        #[arg(long)]
        frames: Option<u32>,
        /// Timed runs per combination (the median is reported).
        #[arg(long, default_value_t = 3)]
        repeats: u32,
        /// The converged reference as SUBSTEPS,ITERATIONS [default: the finest combination].
        #[arg(long, value_name = "S,I")]
        reference: Option<String>,
        /// Output directory [default: out/bench-STEM, STEM the scene file name without .toml].
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Override any scene value (repeatable), as for `run`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Threads of the step's team, as for `run`.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
        threads: Option<u32>,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
        #[command(flatten)]
        plugin_args: PluginArgs,
    },
    /// List every plugin found, its kinds, their default order/importance and parameters.
    Plugins {
        /// Print the kinds and parameters as the Markdown reference of docs/scene-format.md.
        #[arg(long)]
        markdown: bool,
        #[command(flatten)]
        plugin_args: PluginArgs,
    },
    /// Create a new constraint-plugin crate from the SDK template: a workspace of its own,
    /// the SDK by path, ready to `cargo build --release`; prints the next three commands.
    NewPlugin(new_plugin::NewPluginArgs),
}

/// An error with the exit code it maps to.
struct Failure {
    code: u8,
    message: String,
}

impl From<String> for Failure {
    fn from(message: String) -> Self {
        Failure::input(message)
    }
}

impl Failure {
    fn input(message: impl std::fmt::Display) -> Self {
        Self {
            code: 2,
            message: message.to_string(),
        }
    }
    fn run(message: impl std::fmt::Display) -> Self {
        Self {
            code: 1,
            message: message.to_string(),
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run {
            scene,
            out,
            frames,
            substeps,
            iterations,
            set,
            threads,
            verbose,
            quiet,
            plugin_args,
        } => run(RunArgs {
            scene,
            out,
            frames,
            substeps,
            iterations,
            set,
            threads,
            verbose,
            quiet,
            plugin_args,
        }),
        Command::NewPlugin(args) => new_plugin::run(&args).map_err(Failure::input),
        Command::Plugins {
            markdown: true,
            plugin_args,
        } => discover(&plugin_args, false).map(|r| print!("{}", plugin_docs::markdown(&r))),
        Command::Plugins { plugin_args, .. } => list_plugins(&plugin_args),
        Command::Bench {
            scene,
            substeps,
            iterations,
            frames,
            repeats,
            reference,
            out,
            set,
            threads,
            quiet,
            plugin_args,
        } => (|| {
            let reference = match reference {
                Some(r) => match bench::parse_list(&r)?.as_slice() {
                    [s, i] => Some((*s, *i)),
                    _ => return Err(Failure::input("--reference takes SUBSTEPS,ITERATIONS")),
                },
                None => None,
            };
            let out = out.unwrap_or_else(|| {
                let stem = default_out(&scene);
                let name = stem.file_name().map(|n| n.to_string_lossy().to_string());
                PathBuf::from("out").join(format!("bench-{}", name.unwrap_or_default()))
            });
            let args = bench::BenchArgs {
                substeps: bench::parse_list(&substeps)?,
                iterations: bench::parse_list(&iterations)?,
                scene,
                set,
                frames,
                repeats,
                reference,
                out,
                threads: threads.map(|t| t as usize),
                quiet,
            };
            let registry = discover(&plugin_args, quiet)?;
            bench::run(&args, &registry).map_err(|e| match e {
                bench::BenchError::Input(m) => Failure::input(m),
                bench::BenchError::Run(m) => Failure::run(m),
            })?;
            if !quiet {
                println!("wrote {}", args.out.join("bench.csv").display());
            }
            Ok(())
        })(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            // One line, whatever the cause's formatting.
            let one_line: Vec<&str> = f.message.lines().map(str::trim).collect();
            eprintln!("error: {}", one_line.join(" "));
            ExitCode::from(f.code)
        }
    }
}

fn discover(args: &PluginArgs, quiet: bool) -> Result<Registry, Failure> {
    let dirs = search_path(&args.plugins, !args.no_default_plugins);
    let registry = Registry::discover(&dirs);
    if !quiet {
        for w in &registry.warnings {
            eprintln!("warning: {w}");
        }
        for r in &registry.refused {
            eprintln!("warning: {}: refused: {}", r.path.display(), r.cause);
        }
    }
    if let Some(e) = registry.duplicate_kinds().first() {
        return Err(Failure::input(e));
    }
    Ok(registry)
}

fn list_plugins(args: &PluginArgs) -> Result<(), Failure> {
    let registry = discover(args, false)?;
    println!(
        "searched: {}",
        registry
            .dirs
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    if registry.plugins.is_empty() {
        println!("no plugins found");
    }
    for p in &registry.plugins {
        println!(
            "\n{} {} (SDK ABI {}) — {}",
            p.info.name,
            p.info.version,
            p.info.sdk_abi_version,
            p.path.display()
        );
        for k in p.info.kinds.iter() {
            println!(
                "  kind `{}`: order {}, importance {}, residual in {}",
                k.name, k.default_order, k.default_importance, k.residual_unit
            );
            for line in k.doc.as_str().lines() {
                println!("    {line}");
            }
            for prm in k.params.iter() {
                let unit = if prm.unit.is_empty() {
                    String::new()
                } else {
                    format!(" [{}]", prm.unit)
                };
                let range = if prm.min.is_finite() || prm.max.is_finite() {
                    format!(", range [{}, {}]", prm.min, prm.max)
                } else {
                    String::new()
                };
                println!(
                    "    - {} ({}{unit}) = {}{range}: {}",
                    prm.name,
                    prm.ty.name(),
                    prm.default,
                    prm.doc
                );
            }
        }
    }
    Ok(())
}

struct RunArgs {
    scene: PathBuf,
    out: Option<PathBuf>,
    frames: Option<u32>,
    substeps: Option<u32>,
    iterations: Option<u32>,
    set: Vec<String>,
    threads: Option<u32>,
    verbose: bool,
    quiet: bool,
    plugin_args: PluginArgs,
}

fn default_out(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().to_string());
    PathBuf::from("out").join(stem)
}

/// Makes the output directory before anything is run or written: one that cannot be made is
/// the user's argument (bad input), not a failure of the run.
pub(crate) fn create_output_dir(dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{}: cannot create the output directory: {e}", dir.display()))
}

fn run(args: RunArgs) -> Result<(), Failure> {
    let mut scene = Scene::load_with_overrides(&args.scene, &args.set).map_err(Failure::input)?;
    if let Some(f) = args.frames {
        scene.file.solver.frames = f;
    }
    if let Some(s) = args.substeps {
        if s == 0 {
            return Err(Failure::input("--substeps must be at least 1"));
        }
        scene.file.solver.substeps = s;
    }
    if let Some(i) = args.iterations {
        if i == 0 {
            return Err(Failure::input("--iterations must be at least 1"));
        }
        scene.file.solver.iterations = i;
    }
    let registry = discover(&args.plugin_args, args.quiet)?;
    let mut sim = Simulation::build(&scene, &registry).map_err(Failure::input)?;
    if sim.particles.is_empty() {
        // Valid (every field has a default), but most likely not what was meant.
        eprintln!(
            "warning: {}: the scene has no objects; its frames will be empty",
            args.scene.display()
        );
    }
    if let Some(t) = args.threads {
        sim.threads = t as usize;
    }
    if args.verbose {
        let mut used: Vec<String> = sim
            .groups
            .iter()
            .map(|g| format!("{} ({})", g.plugin, g.path.display()))
            .collect();
        used.dedup();
        eprintln!("plugins used: {}", used.join(", "));
        for g in &sim.groups {
            eprintln!(
                "group `{}`: kind `{}`, {} constraints, order {}, importance {}",
                g.name, g.kind, g.len, g.order, g.importance
            );
        }
        let names: Vec<&str> = sim.groups.iter().map(|g| g.name.as_str()).collect();
        let slots: Vec<Slot> = sim
            .groups
            .iter()
            .map(|g| Slot {
                order: g.order,
                importance: if g.len > 0 {
                    g.importance * sim.settings.iterations
                } else {
                    0
                },
            })
            .collect();
        eprintln!(
            "schedule per substep:\n{}",
            describe(&names, &slots, sim.settings.schedule)
        );
    }
    let out_dir = args.out.unwrap_or_else(|| default_out(&args.scene));
    let frames = sim.settings.frames as u64;
    create_output_dir(&out_dir).map_err(Failure::input)?;
    let mut out = RunOutput::create(&out_dir, &mut sim).map_err(Failure::run)?;
    out.write_frame(&sim).map_err(Failure::run)?;

    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(frames);
        b.set_style(
            ProgressStyle::with_template(
                "{spinner} frame {pos}/{len} {wide_bar} {elapsed}/{duration} {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };
    let started = Instant::now();
    let mut step_time = 0.0;
    for _ in 0..frames {
        let t = Instant::now();
        let stepped = sim.step_frame();
        let wall = t.elapsed().as_secs_f64();
        step_time += wall;
        if let Err(e) = stepped {
            bar.abandon();
            let msg = e.to_string();
            let _ = out.fail(sim.frame, &msg);
            return Err(Failure::run(format!(
                "{msg} (frames written so far are intact in {}; run.json says failed)",
                out_dir.display()
            )));
        }
        out.write_frame(&sim).map_err(Failure::run)?;
        if let Err(e) = out.write_stats(&mut sim, wall) {
            let msg = e.to_string();
            let _ = out.fail(sim.frame, &msg);
            return Err(Failure::run(msg));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let residuals = sim.residuals().map_err(Failure::run)?;
    // The team runs at most `MAX_PARTS` parts, whatever was asked.
    let threads = nucleus_sdk::team::parts_for(sim.threads);
    let mut summary = format!(
        "{} frames, {} particles, {} groups; step {:.3} ms/frame on {} thread{}; total {:.2} s",
        frames,
        sim.particles.len(),
        sim.groups.len(),
        1e3 * step_time / frames.max(1) as f64,
        threads,
        if threads == 1 { "" } else { "s" },
        started.elapsed().as_secs_f64()
    );
    for (g, r) in sim.groups.iter().zip(&residuals) {
        summary.push_str(&format!(
            "; {} residual max {:.3e} rms {:.3e} {}",
            g.name, r.max, r.rms, g.residual_unit
        ));
    }
    out.finish(frames, &summary).map_err(Failure::run)?;
    if !args.quiet {
        println!("{summary}");
        println!("wrote {}", out_dir.display());
    }
    Ok(())
}
