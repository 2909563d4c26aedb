//! Numerical stability under stress: every plugin, at the extremes the issue lists, through the
//! real, dynamically loaded libraries. Each case is a scene (plus files and a way to break the
//! start state) and the checks below, run after every substep; each test states one fact.
//!
//! * **Finite**: every position and velocity stays finite. The core also stops with an error
//!   naming the plugin and the group that wrote a NaN; that error fails the test verbatim.
//! * **Energy** (cases without an energy source): `E = kinetic + gravity + Σ energy stored in the
//!   groups' soft constraints` (`Simulation::kinetic_energy`, `gravity_energy`, `residuals()`),
//!   sampled at the start and after every frame. The *energy in play* at time `t` is
//!   `P(t) = max over s ≤ t of [K(s) + |U(s) − U(0)|]` (`U` = gravity + stored energy): what the
//!   run has actually moved around. `Ē(t)` is the mean of `E` over the samples in `(t − w, t]`,
//!   `w = max(min(1 s, T/4), 3 Δ)` for a run of duration `T` sampled every `Δ` (one frame):
//!   hard constraints snapping taut make the energy sampled at a frame boundary flicker for a
//!   frame or two (kinetic energy of the snap, potential energy of the strain it leaves), which
//!   is not growth, and a window must hold three samples to see past it (at `h = 1 s` a 1 s
//!   window holds one). A run too short for two windows fails: it cannot show either. For every two
//!   samples `s < t` at least `w` apart: `Ē(t) − Ē(s) ≤ 1 %/s · max(t − s, 1 s) · P(t)`. The
//!   figure is the largest `(Ē(t) − Ē(s)) / (max(t − s, 1 s) · P(t))`, in %/s.
//! * **Speed**: no dynamic particle is faster than the case's bound, either
//!   `k · (v₀ + |g| t + v_pin) + v_extra` — the initial top speed, what gravity can add, the
//!   speed of moving pins, and where the start violates hard constraints (collapsed or
//!   inverted shapes, pins pulled apart) the speed of undoing that within a substep or a frame
//!   (`v_extra`, stated per case); `k` = 2 unless stated, for the whip effect: constraints hand
//!   the momentum of heavy parts to light free ends (a hanging cloth's corner swings faster
//!   than free fall) — or, where light particles meet heavy ones (mass ratios of 1e6), the
//!   energy bound `½ mᵢ |vᵢ|² ≤ P(t)`: no particle holds more than the energy in play. The
//!   figure is the largest ratio of speed to bound.
//! * **No tunnelling** (collision cases): the clearance the case defines (signed distance to a
//!   sheet, a box, the ground) stays positive after every substep.
//!
//! The long cases are ignored in the default run: `cargo xtask plugins --release && cargo test
//! --release -p nucleus-tests --test stress -- --include-ignored --nocapture`. Every case prints
//! one `STRESS | case | passed | figures` line; docs/stress.md holds the table.

use std::time::Instant;

use glam::DVec3;
use nucleus_core::{Scene, Simulation};
use nucleus_tests::*;

// ---------------------------------------------------------------------------------------------
// The machinery

/// Whether a case has an energy source, and from which frame its energy is checked.
enum Energy {
    /// No source: checked from the state after `from_frame` frames on (0: the start).
    Conserved { from_frame: u32 },
    /// A source (the reason): not checked.
    Source(&'static str),
}

/// A speed bound.
#[derive(Clone, Copy)]
enum Speed {
    /// `factor · (v₀ + |g| t + pin) + extra` (m/s).
    Motion { factor: f64, pin: f64, extra: f64 },
    /// `½ mᵢ |vᵢ|² ≤ P(t)` for every dynamic particle (needs `Energy::Conserved`).
    Energy,
}

/// The default bound: twice what the start, gravity and the pins can give.
const WHIP: Speed = Speed::Motion {
    factor: 2.0,
    pin: 0.0,
    extra: 0.0,
};

/// `WHIP` with another factor, pin speed and extra speed.
const fn motion(factor: f64, pin: f64, extra: f64) -> Speed {
    Speed::Motion { factor, pin, extra }
}

/// A check on the final state.
type Final = fn(&mut Simulation) -> Result<String, String>;

struct Case {
    name: &'static str,
    /// The scene text, written to `scene.toml` in a fresh directory.
    scene: String,
    /// Other files beside the scene (meshes).
    files: Vec<(String, String)>,
    /// Breaks the start state (collapse, invert) before the first step.
    prepare: Option<fn(&mut Simulation)>,
    energy: Energy,
    speed: Speed,
    /// The clearance (m) that must stay positive: no tunnelling.
    clearance: Option<fn(&Simulation) -> f64>,
    /// A check on the final state, returning a figure.
    last: Option<Final>,
}

impl Case {
    fn new(name: &'static str, scene: String, energy: Energy, speed: Speed) -> Case {
        Case {
            name,
            scene,
            files: Vec::new(),
            prepare: None,
            energy,
            speed,
            clearance: None,
            last: None,
        }
    }
    fn file(mut self, name: &str, text: String) -> Case {
        self.files.push((name.to_string(), text));
        self
    }
    fn prepare(mut self, f: fn(&mut Simulation)) -> Case {
        self.prepare = Some(f);
        self
    }
    fn clearance(mut self, f: fn(&Simulation) -> f64) -> Case {
        self.clearance = Some(f);
        self
    }
    fn last(mut self, f: Final) -> Case {
        self.last = Some(f);
        self
    }
}

fn dynamic_speeds(sim: &Simulation) -> impl Iterator<Item = f64> + '_ {
    sim.velocities()
        .iter()
        .zip(&sim.particles.inv_mass)
        .filter(|(_, &w)| w > 0.0)
        .map(|(v, _)| v.length())
}

fn finite(sim: &Simulation) -> bool {
    let p = &sim.particles;
    p.x.iter().chain(&p.v).flatten().all(|c| c.is_finite())
}

/// `(K, U)`: kinetic energy, and gravity plus the energy stored in the groups.
fn energies(sim: &mut Simulation) -> Result<(f64, f64), String> {
    let stored: f64 = sim
        .residuals()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|r| r.energy)
        .sum();
    Ok((sim.kinetic_energy(), sim.gravity_energy() + stored))
}

/// The largest `(Ē(t) − Ē(s)) / (max(t − s, 1 s) · P(t))` over sample pairs at least `w` apart
/// (1/s; `−∞` if there are none), and the largest energy in play (J). Samples are `(t, K, U)`.
fn energy_growth(samples: &[(f64, f64, f64)]) -> (f64, f64) {
    let Some(&(t0, _, u0)) = samples.first() else {
        return (f64::NEG_INFINITY, 0.0);
    };
    let duration = samples.last().map_or(0.0, |s| s.0) - t0;
    // The sampling interval: the widest gap between consecutive samples (one frame).
    let interval = samples
        .windows(2)
        .map(|p| p[1].0 - p[0].0)
        .fold(0.0, f64::max);
    let w = (duration.min(4.0) / 4.0).max(3.0 * interval);
    // Slightly less than w, so that frames exactly w apart count despite rounding in t.
    let w_eps = w * (1.0 - 1e-9);
    let mut in_play = Vec::with_capacity(samples.len());
    let mut p = 1e-12_f64;
    for &(_, k, u) in samples {
        p = p.max(k + (u - u0).abs());
        in_play.push(p);
    }
    let mean: Vec<f64> = samples
        .iter()
        .map(|&(t, ..)| {
            let window = samples.iter().filter(|s| s.0 <= t && s.0 > t - w_eps);
            let (sum, n) = window.fold((0.0, 0), |(sum, n), s| (sum + s.1 + s.2, n + 1));
            sum / n.max(1) as f64
        })
        .collect();
    let mut worst = f64::NEG_INFINITY;
    for k in 0..samples.len() {
        let t = samples[k].0;
        for j in 0..k {
            let s = samples[j].0;
            if t - s >= w_eps {
                let rate = (mean[k] - mean[j]) / ((t - s).max(1.0) * in_play[k]);
                worst = worst.max(rate);
            }
        }
    }
    (worst, p)
}

struct Outcome {
    error: Option<String>,
    steps: u64,
    max_speed: f64,
    speed_ratio: f64,
    growth: Option<(f64, f64)>,
    clearance: Option<f64>,
    last: Option<Result<String, String>>,
    seconds: f64,
}

fn build(case: &Case) -> Simulation {
    let tag: String = case
        .name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .take(40)
        .collect();
    let dir = temp_dir(&format!("stress-{tag}"));
    for (name, text) in &case.files {
        std::fs::write(dir.join(name), text).expect("write case file");
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, &case.scene).expect("write scene");
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: scene: {e}", case.name));
    Simulation::build(&scene, &registry(&[plugin_dir()]))
        .unwrap_or_else(|e| panic!("{}: build: {e}", case.name))
}

fn simulate(case: &Case) -> Outcome {
    let started = Instant::now();
    let mut sim = build(case);
    if let Some(prepare) = case.prepare {
        prepare(&mut sim);
    }
    let g = DVec3::from_array(sim.settings.gravity).length();
    let v0 = dynamic_speeds(&sim).fold(0.0, f64::max);
    let from_frame = match case.energy {
        Energy::Conserved { from_frame } => Some(from_frame as u64),
        Energy::Source(_) => None,
    };
    // The largest ratio of a particle's speed to its bound; `in_play` is P so far.
    let speed_ratio = |sim: &Simulation, in_play: f64| -> f64 {
        match case.speed {
            Speed::Motion { factor, pin, extra } => {
                let bound = factor * (v0 + g * sim.time + pin) + extra;
                dynamic_speeds(sim).fold(0.0, f64::max) / bound
            }
            Speed::Energy => {
                let p = &sim.particles;
                let worst =
                    p.v.iter()
                        .zip(&p.inv_mass)
                        .filter(|(_, &w)| w > 0.0)
                        .map(|(v, &w)| 0.5 * DVec3::from_array(*v).length_squared() / w)
                        .fold(0.0, f64::max);
                (worst / in_play).sqrt()
            }
        }
    };
    let mut out = Outcome {
        error: None,
        steps: 0,
        max_speed: v0,
        speed_ratio: 0.0,
        growth: None,
        clearance: case.clearance.map(|f| f(&sim)),
        last: None,
        seconds: 0.0,
    };
    let mut samples: Vec<(f64, f64, f64)> = Vec::new();
    // P so far, from the energy at the start of the checked part (u0) and every observation.
    let mut u0: Option<f64> = None;
    let mut in_play = 1e-12_f64;
    let mut observe = |sim: &mut Simulation, record: bool, samples: &mut Vec<_>| {
        let (k, u) = energies(sim)?;
        let base = *u0.get_or_insert(u);
        in_play = in_play.max(k + (u - base).abs());
        if record {
            samples.push((sim.time, k, u));
        }
        Ok::<f64, String>(in_play)
    };
    let checked = |sim: &Simulation| from_frame.is_some_and(|f| sim.frame >= f);
    let energy_bound = matches!(case.speed, Speed::Energy);
    let mut failure = None;
    let mut p = 1e-12;
    if checked(&sim) {
        match observe(&mut sim, true, &mut samples) {
            Ok(v) => p = v,
            Err(e) => failure = Some(e),
        }
    }
    out.speed_ratio = speed_ratio(&sim, p);
    'run: for _ in 0..sim.settings.frames {
        if failure.is_some() {
            break;
        }
        for s in 0..sim.settings.substeps {
            if let Err(e) = sim.substep(s) {
                failure = Some(e.to_string());
                break 'run;
            }
            out.steps += 1;
            if !finite(&sim) {
                failure = Some(format!(
                    "non-finite state at frame {} substep {s}",
                    sim.frame
                ));
                break 'run;
            }
            if energy_bound && checked(&sim) {
                match observe(&mut sim, false, &mut samples) {
                    Ok(v) => p = v,
                    Err(e) => {
                        failure = Some(e);
                        break 'run;
                    }
                }
            }
            out.max_speed = out.max_speed.max(dynamic_speeds(&sim).fold(0.0, f64::max));
            out.speed_ratio = out.speed_ratio.max(speed_ratio(&sim, p));
            if let (Some(f), Some(c)) = (case.clearance, out.clearance.as_mut()) {
                *c = c.min(f(&sim));
            }
        }
        sim.frame += 1;
        if checked(&sim) {
            match observe(&mut sim, true, &mut samples) {
                Ok(v) => p = v,
                Err(e) => failure = Some(e),
            }
        }
    }
    out.error = failure;
    if from_frame.is_some() {
        out.growth = Some(energy_growth(&samples));
    }
    if out.error.is_none() {
        out.last = case.last.map(|f| f(&mut sim));
    }
    out.seconds = started.elapsed().as_secs_f64();
    out
}

/// `x` with 4 significant digits.
fn sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = x.abs().log10().floor() as i32;
    if (-3..5).contains(&digits) {
        format!("{:.*}", (3 - digits).max(0) as usize, x)
    } else {
        format!("{x:.3e}")
    }
}

/// Runs a case and asserts every check ([`check_all`] for one case).
fn check(case: Case) {
    check_all([case]);
}

/// Runs every case, printing each one's `STRESS |` line, then asserts every check of every
/// case: a failing case does not hide the rows of the cases after it.
fn check_all(cases: impl IntoIterator<Item = Case>) {
    let failures: Vec<String> = cases.into_iter().filter_map(run_case).collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Runs a case and prints its `STRESS |` line. Returns what failed, after the case's name.
fn run_case(case: Case) -> Option<String> {
    let o = simulate(&case);
    let mut failures = Vec::new();
    if let Some(e) = &o.error {
        failures.push(e.clone());
    }
    if o.speed_ratio > 1.0 {
        failures.push(format!(
            "a particle reached {} m/s, {:.3} times the speed bound",
            sig(o.max_speed),
            o.speed_ratio
        ));
    }
    let energy = match (&case.energy, o.growth) {
        (Energy::Conserved { .. }, Some((rate, in_play))) => {
            if rate == f64::NEG_INFINITY {
                failures.push(
                    "the run is too short to measure the energy's growth: no two samples a window apart"
                        .into(),
                );
            } else if rate > 0.01 {
                failures.push(format!(
                    "the energy grew by {:.3} %/s of the energy in play ({} J)",
                    rate * 100.0,
                    sig(in_play)
                ));
            }
            format!(
                "energy growth {:.2e} %/s of {} J in play",
                rate.max(0.0) * 100.0,
                sig(in_play)
            )
        }
        (Energy::Source(why), _) => format!("energy not checked ({why})"),
        _ => String::new(),
    };
    let clearance = match o.clearance {
        Some(c) => {
            if c.is_nan() || c <= 0.0 {
                failures.push(format!("tunnelling: the clearance reached {} m", sig(c)));
            }
            format!("; min clearance {c:.3e} m")
        }
        None => String::new(),
    };
    let last = match &o.last {
        Some(Ok(figure)) => format!("; {figure}"),
        Some(Err(e)) => {
            failures.push(e.clone());
            format!("; {e}")
        }
        None => String::new(),
    };
    println!(
        "STRESS | {} | {} | max speed {} m/s ({:.3} of bound); {energy}{clearance}{last} | {} steps, {:.2} s",
        case.name,
        if failures.is_empty() { "yes" } else { "NO" },
        sig(o.max_speed),
        o.speed_ratio,
        o.steps,
        o.seconds
    );
    (!failures.is_empty()).then(|| format!("{}: {}", case.name, failures.join("; ")))
}

// ---------------------------------------------------------------------------------------------
// Geometry helpers for the scenes and the checks

/// OBJ text of a grid in the xz plane at height `y` with column positions `xs` and row
/// positions `zs` (vertex (i, j) at (xs[j], y, zs[i]), index i·len(xs) + j), two triangles per
/// quad as the core's grids; `edit` may move vertex k.
fn grid_obj_at(
    xs: &[f64],
    zs: &[f64],
    y: f64,
    edit: impl Fn(usize, [f64; 3]) -> [f64; 3],
) -> String {
    let n = xs.len();
    let mut s = String::new();
    for (i, z) in zs.iter().enumerate() {
        for (j, x) in xs.iter().enumerate() {
            let p = edit(i * n + j, [*x, y, *z]);
            s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
    }
    for i in 0..zs.len() - 1 {
        for j in 0..n - 1 {
            let a = i * n + j + 1;
            let (b, c) = (a + 1, a + n);
            let d = c + 1;
            s += &format!("f {a} {b} {d}\nf {a} {d} {c}\n");
        }
    }
    s
}

/// A regular `n × n` grid of `size` metres (see [`grid_obj_at`]).
fn grid_obj(n: usize, size: f64, edit: impl Fn(usize, [f64; 3]) -> [f64; 3]) -> String {
    let ticks: Vec<f64> = (0..n).map(|k| k as f64 * size / (n - 1) as f64).collect();
    grid_obj_at(&ticks, &ticks, 0.0, edit)
}

fn range_of(sim: &Simulation, name: &str) -> std::ops::Range<usize> {
    let o = sim.object(name).expect("object");
    o.first as usize..(o.first + o.count) as usize
}

/// The closest point to `p` on the segment `ab`.
fn on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + t * ab
}

/// The closest point to `p` on the triangle `abc` (its edges, or the orthogonal projection when
/// it falls inside; zero-area triangles are their edges).
fn on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let mut best = on_segment(p, a, b);
    for q in [on_segment(p, b, c), on_segment(p, c, a)] {
        if (q - p).length_squared() < (best - p).length_squared() {
            best = q;
        }
    }
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (abab, acac, abac) = (ab.dot(ab), ac.dot(ac), ab.dot(ac));
    let det = abab * acac - abac * abac;
    if det > 0.0 {
        let v = (ap.dot(ab) * acac - ap.dot(ac) * abac) / det;
        let w = (ap.dot(ac) * abab - ap.dot(ab) * abac) / det;
        let q = a + v * ab + w * ac;
        if v >= 0.0
            && w >= 0.0
            && v + w <= 1.0
            && (q - p).length_squared() < (best - p).length_squared()
        {
            best = q;
        }
    }
    best
}

/// Signed distance of `p` to the closest triangle of object `name`: positive on the side its
/// winding's normal points to.
fn signed_distance_to(sim: &Simulation, p: DVec3, name: &str) -> f64 {
    let x = sim.positions();
    let mut best = (f64::INFINITY, 0.0);
    for t in &sim.object(name).expect("object").triangles {
        let [a, b, c] = t.map(|i| x[i as usize]);
        let q = on_triangle(p, a, b, c);
        let d = (p - q).length();
        if d < best.0 {
            best = (d, (p - q).dot((b - a).cross(c - a)).signum());
        }
    }
    best.1 * best.0
}

/// The lowest height of any particle (m).
fn min_height(sim: &Simulation) -> f64 {
    sim.positions()
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min)
}

/// Moves every dynamic particle to `to` plus `jitter` times a fixed pseudo-random offset in
/// [−1, 1]³: with no jitter all their edges have zero length, all their triangles zero area.
fn collapse(sim: &mut Simulation, to: [f64; 3], jitter: f64) {
    let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let p = &mut sim.particles;
    for k in 0..p.x.len() {
        let offset = [next(), next(), next()];
        if p.inv_mass[k] > 0.0 {
            p.x[k] = [0, 1, 2].map(|c| to[c] + jitter * offset[c]);
            p.x0[k] = p.x[k];
        }
    }
}

/// Mirrors every particle of `name` through the plane x = `x`: every tetrahedron turns inside
/// out.
fn mirror_x(sim: &mut Simulation, name: &str, x: f64) {
    for k in range_of(sim, name) {
        let p = &mut sim.particles;
        p.x[k][0] = 2.0 * x - p.x[k][0];
        p.x0[k] = p.x[k];
    }
}

/// The number of tets of `name` whose orientation differs from their rest orientation.
fn inverted_tets(sim: &Simulation, name: &str) -> usize {
    let x = sim.positions();
    let r = nucleus_sdk::view::as_dvec3(&sim.particles.rest);
    let vol = |p: &[DVec3], t: &[u32; 4]| {
        let [a, b, c, d] = t.map(|i| p[i as usize]);
        (b - a).cross(c - a).dot(d - a)
    };
    sim.object(name)
        .expect("object")
        .tets
        .iter()
        .filter(|t| vol(x, t) * vol(r, t) <= 0.0)
        .count()
}

/// The largest residual of the group named `group` now, as a figure.
fn residual_figure(sim: &mut Simulation, group: &str) -> Result<String, String> {
    let k = sim
        .groups
        .iter()
        .position(|g| g.name == group)
        .expect("group");
    let r = sim.residuals().map_err(|e| e.to_string())?[k];
    Ok(format!(
        "{group} residual at the end: max {}, RMS {} {}",
        sig(r.max),
        sig(r.rms),
        sim.groups[k].residual_unit
    ))
}

// ---------------------------------------------------------------------------------------------
// Compliance 0 at 1 and 1,000 iterations

/// A cloth of `n × n` vertices, 1 m, pinned at the corners of one edge, with hard stretch,
/// rigid bending (dihedral, compliance 0) and hard tethers.
fn hard_cloth(n: u32, substeps: u32, iterations: u32, frames: u32) -> String {
    format!(
        r#"
[solver]
frames = {frames}
substeps = {substeps}
iterations = {iterations}
[[objects]]
name = "cloth"
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [{n}, {n}]
[[constraints]]
kind = "stretch"
params = {{ compliance = 0.0, compression_compliance = 0.0 }}
[[constraints]]
kind = "bend"
params = {{ compliance = 0.0 }}
[[constraints]]
kind = "tether"
params = {{ compliance = 0.0 }}
"#
    )
}

#[test]
fn hard_cloth_at_one_iteration_never_gains_energy() {
    check(Case::new(
        "compliance 0, 1 iteration, 12 x 12 cloth (stretch, bend, tether)",
        hard_cloth(12, 4, 1, 120),
        Energy::Conserved { from_frame: 0 },
        WHIP,
    ));
}

#[test]
fn hard_cloth_at_1000_iterations_never_gains_energy() {
    check(Case::new(
        "compliance 0, 1,000 iterations, 8 x 8 cloth (stretch, bend, tether)",
        hard_cloth(8, 2, 1000, 10),
        Energy::Conserved { from_frame: 0 },
        WHIP,
    ));
}

#[test]
#[ignore = "stress: run with cargo xtask test --test stress -- --ignored"]
fn hard_32x32_cloth_at_1000_iterations_never_gains_energy() {
    check(Case::new(
        "compliance 0, 1,000 iterations, 32 x 32 cloth, 1 s (stretch, bend, tether)",
        hard_cloth(32, 10, 1000, 60),
        Energy::Conserved { from_frame: 0 },
        WHIP,
    ));
}

// ---------------------------------------------------------------------------------------------
// Mass ratios 1 : 1e6

/// The largest mass ratio across an edge of object `name`, as a figure (an error below 1e6).
fn neighbour_mass_ratio(sim: &mut Simulation, name: &str) -> Result<String, String> {
    let m = &sim.particles.mass;
    let ratio = sim
        .object(name)
        .expect("object")
        .edges
        .iter()
        .map(|&[i, j]| m[i as usize] / m[j as usize])
        .map(|r| r.max(1.0 / r))
        .fold(0.0, f64::max);
    let figure = format!("neighbour mass ratio {}", sig(ratio));
    if ratio < 0.99e6 {
        return Err(format!("{figure}, below 1e6"));
    }
    let stretch = residual_figure(sim, "stretch")?;
    Ok(format!("{figure}; {stretch}"))
}

/// A `size` × 0.3 m cloth of `columns` × 4 vertices, 1 kg/m², pinned at the corners of its top
/// row (row 0), with stretch, tether, bend, shear and air; `mass_maps` makes some vertices
/// 1e6 times lighter than their neighbours (regular triangles: the mass ratio alone, no
/// slivers).
fn mass_ratio_scene(size: f64, columns: u32, mass_maps: &str, blocks: &str) -> String {
    format!(
        r#"
[solver]
frames = 120
substeps = 10
[[objects]]
name = "cloth"
density = 1.0
pins = ["corners:row0"]
mass_maps = [{mass_maps}]
[objects.grid]
size = [{size}, 0.3]
resolution = [{columns}, 4]
plane = "xy"
origin = [0.0, 0.0, 0.0]
[[constraints]]
kind = "stretch"
params = {{ blocks = "{blocks}" }}
[[constraints]]
kind = "tether"
[[constraints]]
kind = "bend"
params = {{ compliance = 10.0 }}
[[constraints]]
kind = "shear"
params = {{ compliance = 10.0 }}
[[constraints]]
kind = "air"
"#
    )
}

#[test]
fn a_cloth_with_a_free_edge_1e6_times_lighter_swings_without_gaining_energy() {
    check(
        Case::new(
            "mass ratio 1:1e6 between neighbours, light free edge (stretch, tether, bend, shear, air)",
            mass_ratio_scene(0.3, 4, r#"{ vertices = ["edge:rowN"], scale = 1e-6 }"#, "edges"),
            Energy::Conserved { from_frame: 0 },
            Speed::Energy,
        )
        .last(|sim| neighbour_mass_ratio(sim, "cloth")),
    );
}

/// Edge-by-edge passes tear this cloth (stretch alone ended at strain 175, 4 km/s; with
/// tethers at 0.45 and 38 %/s of energy growth): each pass moves the light vertex, almost never
/// the heavy one behind it. `stretch` with `blocks = "stars"` solves all the edges at each
/// vertex at once (`nucleus_stretch::star`).
#[test]
fn a_cloth_carried_through_vertices_1e6_times_lighter_never_gains_energy() {
    // Columns at x = 0.3 and 0.6 m of a 0.9 m strip: the load between the pinned corners
    // passes through them.
    let light = |x: f64| {
        format!(
            "{{ min = [{}, -1.0, -1.0], max = [{}, 1.0, 1.0] }}",
            x - 0.01,
            x + 0.01
        )
    };
    check(
        Case::new(
            "mass ratio 1:1e6 between neighbours, load through light columns (stretch with stars, tether, bend, shear, air)",
            mass_ratio_scene(
                0.9,
                10,
                &format!("{{ vertices = [{}, {}], scale = 1e-6 }}", light(0.3), light(0.6)),
                "stars",
            ),
            Energy::Conserved { from_frame: 0 },
            Speed::Energy,
        )
        .last(|sim| neighbour_mass_ratio(sim, "cloth")),
    );
}

/// A 1 m curtain of 32 × 32 vertices hung by its top row from above its pins, its bottom row
/// 1,000 times heavier (a weighted hem): it swings down 2 m and the tethers catch the hem.
const WEIGHTED_HEM: &str = r#"
[solver]
frames = 120
substeps = 10
[[objects]]
name = "curtain"
mass = 0.2
pins = ["edge:row0"]
mass_maps = [{ vertices = ["edge:rowN"], scale = 1000.0 }]
[objects.grid]
size = [1.0, 1.0]
resolution = [32, 32]
plane = "xy"
origin = [0.0, 0.0, 0.0]
[[constraints]]
kind = "stretch"
params = { blocks = "BLOCKS" }
[[constraints]]
kind = "tether"
"#;

fn weighted_hem(blocks: &'static str) -> Case {
    let name = match blocks {
        "stars" => "mass ratio 1:1e3, a weighted hem falls 2 m and is caught by tethers (stretch with stars, tether)",
        _ => "mass ratio 1:1e3, a weighted hem falls 2 m and is caught by tethers (stretch, tether)",
    };
    Case::new(
        name,
        WEIGHTED_HEM.replace("BLOCKS", blocks),
        Energy::Conserved { from_frame: 0 },
        Speed::Energy,
    )
    .last(|sim| residual_figure(sim, "stretch"))
}

#[test]
fn a_weighted_hem_caught_by_tethers_never_gains_energy() {
    check(weighted_hem("edges"));
}

/// Solved a star at a time, this curtain gained 1.4 %/s of its energy when the trust region
/// let a particle move as far as the sum of its star's violations (max speed 70 m/s); bounded
/// by the largest, 0.07 %/s. With the edges' start directions (as the edge step uses) the
/// star's system was not symmetric and ~25 J stayed in motion after the catch.
#[test]
fn a_weighted_hem_caught_by_tethers_with_stars_never_gains_energy() {
    check(weighted_hem("stars"));
}

/// A 0.5 m cloth of 10 × 10 vertices of 1 g each lying on the ground, and a 1,000 kg particle
/// dropped onto its middle.
const HEAVY_ON_LIGHT: &str = r#"
[solver]
frames = 60
substeps = 10
[[objects]]
name = "cloth"
vertex_mass = 0.001
[objects.grid]
size = [0.5, 0.5]
resolution = [10, 10]
origin = [-0.25, 0.005, -0.25]
[[objects]]
name = "weight"
vertex_mass = 1000.0
velocity = [0.0, -1.0, 0.0]
[objects.particles]
min = [0.01, 0.06, 0.02]
max = [0.01, 0.06, 0.02]
count = [1, 1, 1]
[[constraints]]
kind = "stretch"
objects = ["cloth"]
[[constraints]]
kind = "bend"
objects = ["cloth"]
[[constraints]]
kind = "collision"
params = { thickness = 0.002, colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }] }
"#;

#[test]
fn a_particle_1e6_times_heavier_than_the_cloth_under_it_never_passes_through() {
    let case = Case::new(
        "mass ratio 1:1e6 in contact: 1,000 kg onto a cloth of 1 g vertices on the ground (stretch, bend, collision)",
        HEAVY_ON_LIGHT.into(),
        Energy::Conserved { from_frame: 0 },
        Speed::Energy,
    )
    .clearance(|sim| {
        // The cloth's triangles wind so that their normal points down (-y) in the xz plane.
        let w = range_of(sim, "weight").start;
        let above_cloth = -signed_distance_to(sim, sim.positions()[w], "cloth");
        above_cloth.min(min_height(sim))
    });
    check(case);
}

// ---------------------------------------------------------------------------------------------
// Time steps from 1e-6 s to 1 s per substep, and 100,000 steps

/// A 6 × 6 cloth and a rope of 6 segments, each pinned, with stretch, tether, bend, shear,
/// twist, air (still; drag 0.5 and the given lift) and collisions with the ground 2 m below.
fn all_kinds(frame_rate: f64, substeps: u32, frames: u32, lift: f64) -> String {
    format!(
        r#"
[solver]
frame_rate = {frame_rate}
frames = {frames}
substeps = {substeps}
[[objects]]
name = "cloth"
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [6, 6]
[[objects]]
name = "rope"
mass = 0.2
pins = ["start"]
[objects.rope]
start = [0.0, 0.0, 1.5]
end = [1.0, 0.0, 1.5]
segments = 6
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "tether"
[[constraints]]
kind = "bend"
params = {{ compliance = 100.0 }}
[[constraints]]
kind = "shear"
params = {{ compliance = 10.0 }}
[[constraints]]
kind = "twist"
params = {{ compliance = 100.0 }}
[[constraints]]
kind = "air"
params = {{ drag = 0.5, lift = {lift} }}
[[constraints]]
kind = "collision"
params = {{ colliders = [{{ type = "plane", point = [0.0, -2.0, 0.0], normal = [0.0, 1.0, 0.0] }}] }}
"#
    )
}

fn above_ground_2m(sim: &Simulation) -> f64 {
    min_height(sim) + 2.0
}

#[test]
fn a_cloth_and_a_rope_with_1_s_substeps_never_gain_energy_nor_tunnel() {
    check(
        Case::new(
            "h = 1 s, cloth and rope (stretch, tether, bend, shear, twist, air without lift, collision)",
            all_kinds(1.0, 1, 10, 0.0),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .clearance(above_ground_2m),
    );
}

#[test]
fn air_lift_with_1_s_substeps_never_adds_energy() {
    check(
        Case::new(
            "h = 1 s, cloth and rope with lift (stretch, tether, bend, shear, twist, air with lift 0.2, collision)",
            all_kinds(1.0, 1, 10, 0.2),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .clearance(above_ground_2m),
    );
}

#[test]
#[ignore = "fails: hard stretch alone does not converge at h = 1 s in one pass: the 8 x 8 cloth stretches to ~565 m below its pins in 15 s (strain ~500) and its hard constraints then pull it back up, 2,500 J that no residual reports (the measured energy grows 8 %/s of the energy in play). Tethers fix it (`a_cloth_and_a_rope_with_1_s_substeps_never_gain_energy_nor_tunnel`), and so do 1,000 passes (`..._converged_by_1000_passes_...`)"]
fn a_hard_cloth_without_tethers_with_1_s_substeps_never_gains_energy() {
    hard_cloth_at_1_s("h = 1 s, cloth without tethers (stretch)", 1);
}

/// The case above, its projection converged: the strain falls to a few per cent and the
/// energy only flickers around the hanging cloth's, with no trend.
#[test]
fn a_hard_cloth_without_tethers_converged_by_1000_passes_at_1_s_substeps_never_gains_energy() {
    hard_cloth_at_1_s(
        "h = 1 s, cloth without tethers, 1,000 passes (stretch)",
        1000,
    );
}

fn hard_cloth_at_1_s(name: &'static str, iterations: u32) {
    let scene = format!(
        r#"
[solver]
frame_rate = 1.0
frames = 30
substeps = 1
iterations = {iterations}
[[objects]]
name = "cloth"
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [8, 8]
[[constraints]]
kind = "stretch"
"#
    );
    check(
        Case::new(name, scene, Energy::Conserved { from_frame: 0 }, WHIP)
            .last(|sim| residual_figure(sim, "stretch")),
    );
}

#[test]
fn a_cloth_and_a_rope_with_1e_6_s_substeps_never_gain_energy() {
    check(
        Case::new(
            "h = 1e-6 s, 500 steps, cloth and rope (stretch, tether, bend, shear, twist, air, collision)",
            all_kinds(1e4, 100, 5, 0.2),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .clearance(above_ground_2m),
    );
}

#[test]
#[ignore = "stress: run with cargo xtask test --test stress -- --ignored"]
fn a_cloth_and_a_rope_run_100_000_substeps_of_1e_6_s_without_gaining_energy() {
    check(
        Case::new(
            "h = 1e-6 s, 100,000 steps, cloth and rope (stretch, tether, bend, shear, twist, air, collision)",
            all_kinds(1e3, 1000, 100, 0.2),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .clearance(above_ground_2m),
    );
}

#[test]
#[ignore = "stress: run with cargo xtask test --test stress -- --ignored"]
fn a_cloth_and_a_rope_run_100_000_substeps_without_gaining_energy() {
    check(
        Case::new(
            "100,000 steps of 1/600 s (167 s), cloth and rope (stretch, tether, bend, shear, twist, air, collision)",
            all_kinds(60.0, 10, 10_000, 0.2),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .clearance(above_ground_2m),
    );
}

// ---------------------------------------------------------------------------------------------
// Velocities of 1e4 m/s

#[test]
fn a_particle_at_1e4_m_per_s_never_tunnels_through_a_pinned_sheet() {
    let scene = r#"
[solver]
frames = 20
substeps = 1
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "sheet"
pins = ["edge:row0", "edge:rowN", "edge:col0", "edge:colN"]
[objects.grid]
size = [1.0, 1.0]
resolution = [10, 10]
plane = "xy"
[[objects]]
name = "bullet"
mass = 0.001
velocity = [0.0, 0.0, -10000.0]
[objects.particles]
min = [0.47, 0.52, 0.5]
max = [0.47, 0.52, 0.5]
count = [1, 1, 1]
[[constraints]]
kind = "stretch"
objects = ["sheet"]
[[constraints]]
kind = "collision"
params = { thickness = 0.002 }
"#;
    // The sheet (xy plane) winds its triangles with the normal along +z, towards the bullet.
    check(
        Case::new(
            "1e4 m/s particle against a sheet pinned all round, 1 substep (stretch, collision)",
            scene.into(),
            Energy::Conserved { from_frame: 0 },
            motion(1.0, 0.0, 0.0),
        )
        .clearance(|sim| {
            let b = range_of(sim, "bullet").start;
            signed_distance_to(sim, sim.positions()[b], "sheet")
        }),
    );
}

/// Signed distance to the box |x| <= 0.3, -0.2 <= y <= 0, |z| <= 0.3 (positive outside).
fn box_sdf(p: DVec3) -> f64 {
    let c = DVec3::new(0.0, -0.1, 0.0);
    let half = DVec3::new(0.3, 0.1, 0.3);
    let q = (p - c).abs() - half;
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
}

#[test]
fn a_cloth_at_1e4_m_per_s_never_tunnels_into_a_box() {
    let scene = r#"
[solver]
frames = 30
substeps = 1
[[objects]]
name = "cloth"
velocity = [0.0, -10000.0, 0.0]
[objects.grid]
size = [0.5, 0.5]
resolution = [8, 8]
origin = [-0.25, 0.5, -0.25]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "collision"
params = { thickness = 0.005, colliders = [{ type = "box", center = [0.0, -0.1, 0.0], half_extents = [0.3, 0.1, 0.3] }] }
"#;
    check(
        Case::new(
            "1e4 m/s cloth onto a box, 1 substep (stretch, collision)",
            scene.into(),
            Energy::Conserved { from_frame: 0 },
            motion(1.0, 0.0, 0.0),
        )
        .clearance(|sim| {
            sim.positions()
                .iter()
                .map(|&p| box_sdf(p))
                .fold(f64::INFINITY, f64::min)
        }),
    );
}

#[test]
fn a_cloth_a_rope_and_particles_at_1e4_m_per_s_through_still_air_only_slow_down() {
    let scene = r#"
[solver]
frames = 60
substeps = 10
[[objects]]
name = "cloth"
velocity = [3000.0, -9000.0, 3000.0]
[objects.grid]
size = [1.0, 1.0]
resolution = [8, 8]
[[objects]]
name = "rope"
velocity = [0.0, -10000.0, 0.0]
[objects.rope]
start = [0.0, 0.0, 2.0]
end = [1.0, 0.0, 2.0]
segments = 8
[[objects]]
name = "dust"
velocity = [10000.0, 0.0, 0.0]
[objects.particles]
min = [0.0, 0.0, 3.0]
max = [1.0, 0.0, 4.0]
count = [3, 1, 3]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "bend"
[[constraints]]
kind = "air"
params = { drag = 1.2, lift = 0.5, tangential_drag = 0.5 }
"#;
    // Drag only takes energy; lift is perpendicular to the relative velocity and does no work.
    check(Case::new(
        "1e4 m/s cloth, rope and particles through still air (stretch, bend, air)",
        scene.into(),
        Energy::Conserved { from_frame: 0 },
        motion(1.0, 0.0, 0.0),
    ));
}

/// ½ Σ mᵢ |ω × (rᵢ − c)|² of the rest shape for the spin of the scene below (J).
fn nominal_spin_energy(sim: &Simulation) -> f64 {
    let omega = DVec3::new(30.0, 1000.0, 10.0);
    let p = &sim.particles;
    let r = nucleus_sdk::view::as_dvec3(&p.rest);
    let m_total: f64 = p.mass.iter().sum();
    let c = r.iter().zip(&p.mass).map(|(x, m)| *x * *m).sum::<DVec3>() / m_total;
    r.iter()
        .zip(&p.mass)
        .map(|(x, m)| 0.5 * m * omega.cross(*x - c).length_squared())
        .sum()
}

#[test]
fn a_rigid_body_spinning_at_1000_rad_per_s_never_gains_energy() {
    let scene = r#"
[solver]
frames = 60
substeps = 10
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "brick"
density = 700.0
[objects.tet_box]
min = [-0.1, -0.05, -0.02]
max = [0.1, 0.05, 0.02]
resolution = [4, 2, 1]
[[constraints]]
kind = "rigid"
params = { initial_angular_velocity = [30.0, 1000.0, 10.0] }
"#;
    // The spin is given in the first substep (an energy source then): checked from frame 1.
    // A particle's speed is a chord per substep over h, never above ω r (corner radius r).
    let r = (0.1f64.powi(2) + 0.05f64.powi(2) + 0.02f64.powi(2)).sqrt();
    let omega = (30.0f64.powi(2) + 1000.0f64.powi(2) + 10.0f64.powi(2)).sqrt();
    check(
        Case::new(
            "1,000 rad/s spin, 1.7 rad per substep (rigid)",
            scene.into(),
            Energy::Conserved { from_frame: 1 },
            motion(1.0, 0.0, omega * r * (1.0 + 1e-9)),
        )
        .last(|sim| {
            let kept = sim.kinetic_energy() / nominal_spin_energy(sim);
            Ok(format!(
                "kinetic energy {} of the nominal ½Iω² (the first substep's linear prediction of a 1.7 rad turn)",
                sig(kept)
            ))
        }),
    );
}

// ---------------------------------------------------------------------------------------------
// Degenerate geometry: zero-length edges, zero-area triangles, coincident vertices, inverted
// tetrahedra

/// A 5 × 5 grid (1 m) with vertex 6 moved onto vertex 5 (a zero-length edge, two zero-area
/// triangles) and vertex 12 moved onto the segment 11–17 (a zero-area triangle whose edges are
/// not zero).
fn degenerate_grid() -> String {
    let h = 0.25;
    grid_obj(5, 1.0, |k, p| match k {
        6 => [h, 0.0, h],
        12 => [2.5 * h, 0.0, 2.5 * h],
        _ => p,
    })
}

#[test]
fn a_cloth_with_zero_length_edges_and_zero_area_triangles_never_gains_energy() {
    let scene = r#"
[solver]
frames = 120
substeps = 10
[[objects]]
name = "cloth"
pins = [0, 4]
[objects.mesh]
path = "degenerate.obj"
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "tether"
[[constraints]]
kind = "bend"
params = { compliance = 10.0 }
[[constraints]]
kind = "bend_isometric"
params = { compliance = 10.0 }
[[constraints]]
kind = "shear"
params = { compliance = 1.0 }
[[constraints]]
kind = "air"
params = { drag = 1.0, lift = 0.5 }
[[constraints]]
kind = "pressure"
params = { pressure = 0.0 }
[[constraints]]
kind = "collision"
params = { thickness = 0.002 }
"#;
    check(
        Case::new(
            "zero-length edge and zero-area triangles at rest (stretch, tether, bend, bend_isometric, shear, air, pressure, collision)",
            scene.into(),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .file("degenerate.obj", degenerate_grid()),
    );
}

/// A closed cube (8 vertices, 12 triangles, normals out) of side 0.2 m centred at the origin,
/// with vertex 1 moved onto vertex 0 (a zero-length edge and zero-area faces).
fn degenerate_cube() -> String {
    let mut s = String::new();
    for k in 0..8 {
        let k = if k == 1 { 0 } else { k };
        let c = |bit: usize| if k & bit != 0 { 0.1 } else { -0.1 };
        s += &format!("v {} {} {}\n", c(1), c(2), c(4));
    }
    // Faces as quads of 1-based indices whose bits are (x, y, z), wound outwards.
    for f in [
        [1, 5, 7, 3],
        [2, 4, 8, 6],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 3, 4, 2],
        [5, 6, 8, 7],
    ] {
        s += &format!(
            "f {} {} {}\nf {} {} {}\n",
            f[0], f[1], f[2], f[0], f[2], f[3]
        );
    }
    s
}

#[test]
fn closed_meshes_with_degenerate_faces_under_pressure_and_gas_never_gain_energy_nor_tunnel() {
    let scene = r#"
[solver]
frames = 120
substeps = 10
[[objects]]
name = "box"
mass = 0.1
[objects.mesh]
path = "cube.obj"
translate = [0.0, 0.5, 0.0]
[[objects]]
name = "bag"
mass = 0.1
[objects.mesh]
path = "cube.obj"
translate = [0.5, 0.5, 0.0]
[[constraints]]
kind = "stretch"
params = { compliance = 1e-3, compression_compliance = 1e-3 }
[[constraints]]
kind = "pressure"
objects = ["box"]
params = { compliance = 0.0 }
[[constraints]]
kind = "gas"
objects = ["bag"]
[[constraints]]
kind = "collision"
params = { colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }] }
"#;
    check(
        Case::new(
            "closed meshes with a zero-length edge and zero-area faces, dropped (stretch, pressure, gas, collision)",
            scene.into(),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .file("cube.obj", degenerate_cube())
        .clearance(min_height),
    );
}

/// An 8 × 8 cloth pinned at two corners with the given extra constraints.
fn cloth_with(constraints: &str) -> String {
    format!(
        r#"
[solver]
frames = 60
substeps = 10
[[objects]]
name = "cloth"
pins = ["corners:row0"]
[objects.grid]
size = [1.0, 1.0]
resolution = [8, 8]
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "tether"
[[constraints]]
kind = "bend"
[[constraints]]
kind = "bend_isometric"
[[constraints]]
kind = "shear"
params = {{ compliance = 1.0 }}
[[constraints]]
kind = "air"
params = {{ drag = 1.0, lift = 0.5 }}
{constraints}"#
    )
}

/// Undoing a collapse moves a particle by up to the cloth's diagonal (1.5 m) in a substep.
const UNDO_COLLAPSE: Speed = motion(2.0, 0.0, 1.5 * 600.0);

#[test]
fn a_cloth_with_every_free_vertex_coincident_stays_finite() {
    check(
        Case::new(
            "every free vertex coincident (stretch, tether, bend, bend_isometric, shear, air)",
            cloth_with(""),
            Energy::Source("the start violates every hard constraint"),
            UNDO_COLLAPSE,
        )
        .prepare(|sim| collapse(sim, [0.5, 0.0, 0.0], 0.0))
        .last(|sim| residual_figure(sim, "stretch")),
    );
}

#[test]
fn a_cloth_with_every_free_vertex_within_1e_9_m_unfolds_without_nan() {
    check(
        Case::new(
            "every free vertex within 1e-9 m of one point (stretch, tether, bend, bend_isometric, shear, air)",
            cloth_with(""),
            Energy::Source("the start violates every hard constraint"),
            UNDO_COLLAPSE,
        )
        .prepare(|sim| collapse(sim, [0.5, 0.0, 0.0], 1e-9))
        .last(|sim| residual_figure(sim, "stretch")),
    );
}

#[test]
#[ignore = "stress: run with cargo xtask test --test stress -- --ignored"]
fn a_self_colliding_cloth_with_every_free_vertex_coincident_stays_finite() {
    check(
        Case::new(
            "every free vertex coincident, self-collision on (stretch, tether, bend, bend_isometric, shear, air, collision)",
            cloth_with("[[constraints]]\nkind = \"collision\"\n"),
            Energy::Source("the start violates every hard constraint"),
            UNDO_COLLAPSE,
        )
        .prepare(|sim| collapse(sim, [0.5, 0.0, 0.0], 0.0))
        .last(|sim| residual_figure(sim, "stretch")),
    );
}

/// Two icospheres of radius 0.2 m, one with a hard volume (`pressure`), one with gas pumped in.
const BALLOONS: &str = r#"
[solver]
frames = 60
substeps = 10
gravity = [0.0, 0.0, 0.0]
[[objects]]
name = "hard"
mass = 0.05
[objects.sphere]
center = [0.0, 0.0, 0.0]
radius = 0.2
subdivisions = 1
[[objects]]
name = "gas"
mass = 0.05
[objects.sphere]
center = [1.0, 0.0, 0.0]
radius = 0.2
subdivisions = 1
[[constraints]]
kind = "stretch"
params = { compliance = 1e-3, compression_compliance = 1e-2 }
[[constraints]]
kind = "pressure"
objects = ["hard"]
[[constraints]]
kind = "gas"
objects = ["gas"]
params = { pump_rate = 10.0 }
"#;

/// Collapses each balloon onto its centre, within `jitter`.
fn collapse_balloons(sim: &mut Simulation, jitter: f64) {
    let gas = range_of(sim, "gas");
    collapse(sim, [0.0; 3], jitter);
    for k in gas {
        sim.particles.x[k][0] += 1.0;
        sim.particles.x0[k] = sim.particles.x[k];
    }
}

/// Re-inflating moves a vertex by up to the diameter (0.4 m) in a substep.
const UNDO_BALLOON: Speed = motion(2.0, 0.0, 0.4 * 600.0);

#[test]
fn balloons_collapsed_to_a_point_stay_finite() {
    check(
        Case::new(
            "closed meshes collapsed to a point, zero volume (stretch, pressure, gas)",
            BALLOONS.into(),
            Energy::Source("the start violates the volume constraint; the pump"),
            UNDO_BALLOON,
        )
        .prepare(|sim| collapse_balloons(sim, 0.0))
        .last(|sim| residual_figure(sim, "pressure")),
    );
}

#[test]
fn a_balloon_with_a_hard_volume_collapsed_within_1e_9_m_reinflates_without_nan() {
    check(
        Case::new(
            "closed mesh with a hard volume collapsed within 1e-9 m, volume ~1e-27 m³ (stretch, pressure)",
            BALLOONS.replace("objects = [\"gas\"]", "objects = []"),
            Energy::Source("the start violates the volume constraint"),
            UNDO_BALLOON,
        )
        .prepare(|sim| collapse_balloons(sim, 1e-9))
        .last(|sim| residual_figure(sim, "pressure")),
    );
}

#[test]
fn a_gas_balloon_collapsed_within_1e_9_m_reinflates_without_nan() {
    check(
        Case::new(
            "closed mesh of gas collapsed within 1e-9 m, volume ~1e-27 m³ (stretch, gas)",
            BALLOONS.replace("objects = [\"hard\"]", "objects = []"),
            Energy::Source("the start violates the volume constraint; the pump"),
            UNDO_BALLOON,
        )
        .prepare(|sim| collapse_balloons(sim, 1e-9))
        .last(|sim| residual_figure(sim, "gas")),
    );
}

/// A 0.2 × 0.1 × 0.1 m box of 12 tetrahedra named `name` (diagonal 0.24 m), 0.5 m up.
fn tet_box(name: &str) -> String {
    format!(
        r#"
[solver]
frames = 60
substeps = 10
[[objects]]
name = "{name}"
density = 500.0
[objects.tet_box]
min = [-0.1, 0.5, -0.05]
max = [0.1, 0.6, 0.05]
resolution = [2, 1, 1]
"#
    )
}

/// Undoing an inversion moves a particle by up to the box's diagonal (0.24 m) in a substep.
const UNDO_INVERSION: Speed = motion(2.0, 0.0, 0.24 * 600.0);

#[test]
fn inverted_tetrahedra_of_a_rigid_body_are_turned_back_without_nan() {
    check(
        Case::new(
            "every tetrahedron inverted, rigid body (rigid)",
            tet_box("brick") + "[[constraints]]\nkind = \"rigid\"\n",
            Energy::Source("the start violates the rigid constraint"),
            UNDO_INVERSION,
        )
        .prepare(|sim| mirror_x(sim, "brick", 0.0))
        .last(|sim| match inverted_tets(sim, "brick") {
            0 => Ok("every tet turned back".into()),
            n => Err(format!("{n} of 12 tets are still inverted")),
        }),
    );
}

#[test]
fn inverted_tetrahedra_under_a_hard_volume_turn_back_without_nan() {
    let constraints = r#"
[[constraints]]
kind = "stretch"
params = { compliance = 1e-4, compression_compliance = 1e-4 }
[[constraints]]
kind = "pressure"
[[constraints]]
kind = "collision"
params = { self_collision = false, colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }] }
"#;
    // Turning back through itself is the only way out, so self-collision is off.
    check(
        Case::new(
            "every tetrahedron inverted, soft solid with a hard volume (stretch, pressure, collision)",
            tet_box("jelly") + constraints,
            Energy::Source("the start violates the volume constraint"),
            UNDO_INVERSION,
        )
        .prepare(|sim| mirror_x(sim, "jelly", 0.0))
        .clearance(min_height)
        .last(|sim| {
            let n = inverted_tets(sim, "jelly");
            Ok(format!("{n} of 12 tets still inverted at the end"))
        }),
    );
}

#[test]
fn a_rigid_body_falling_with_1_s_substeps_never_tunnels_through_the_ground() {
    let scene = r#"
[solver]
frame_rate = 1.0
frames = 10
substeps = 1
[[objects]]
name = "brick"
density = 500.0
velocity = [0.0, -100.0, 0.0]
[objects.tet_box]
min = [-0.1, 0.5, -0.05]
max = [0.1, 0.6, 0.05]
resolution = [2, 1, 1]
[[constraints]]
kind = "rigid"
[[constraints]]
kind = "collision"
params = { colliders = [{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }] }
"#;
    check(
        Case::new(
            "h = 1 s, rigid body at 100 m/s onto the ground (rigid, collision)",
            scene.into(),
            Energy::Conserved { from_frame: 0 },
            WHIP,
        )
        .clearance(min_height),
    );
}

// ---------------------------------------------------------------------------------------------
// Pins pulled apart beyond the cloth's size

#[test]
fn pins_pulled_three_times_the_cloth_size_apart_leave_it_finite() {
    let scene = r#"
[solver]
frames = 120
substeps = 10
[[objects]]
name = "cloth"
pins = [0, 7]
[objects.mesh]
path = "cloth_0000.obj"
sequence = "cloth_{frame:04}.obj"
[[constraints]]
kind = "stretch"
[[constraints]]
kind = "tether"
[[constraints]]
kind = "bend"
[[constraints]]
kind = "air"
"#;
    // An 8 × 8 cloth (1 m) whose row-0 corners move apart along x, from 1 m to 3 m in the
    // first second (1 m/s each), then hold. The pins force 2 m of stretch on hard
    // constraints: allow that excess to be redistributed within a frame (2 m × 60 /s).
    let mut case = Case::new(
        "two pins pulled 3 m apart across a 1 m cloth (stretch, tether, bend, air)",
        scene.into(),
        Energy::Source("the pins do work"),
        motion(2.0, 1.0, 2.0 * 60.0),
    )
    .last(|sim| residual_figure(sim, "stretch"));
    case.files = (0..=60)
        .map(|f| {
            let d = f as f64 / 60.0;
            let obj = grid_obj(8, 1.0, |k, p| match k {
                0 => [p[0] - d, p[1], p[2]],
                7 => [p[0] + d, p[1], p[2]],
                _ => p,
            });
            (format!("cloth_{f:04}.obj"), obj)
        })
        .collect();
    check(case);
}

// ---------------------------------------------------------------------------------------------
// Invalid input is refused before the run starts (tests/tests/bad_scenes.rs covers malformed
// scenes, NaN and negative `mass`, `substeps = 0`)

/// Runs `nucleus run` on `scene` (in a fresh directory with `files`) with `args`; returns the
/// exit code, the last stderr line, the scene path and the output directory.
fn host_run(
    tag: &str,
    scene: &str,
    files: &[(&str, &str)],
    args: &[&str],
) -> (Option<i32>, String, std::path::PathBuf, std::path::PathBuf) {
    let dir = temp_dir(tag);
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let out = dir.join("out");
    let res = host_command("run", &path, &out)
        .args(args)
        .output()
        .unwrap();
    let (code, last) = exit_and_last_error(&res);
    (code, last, path, out)
}

/// Asserts exit code 2, an error starting with `scene:line:` (just `error:` when `line` is 0)
/// that contains every needle, and no output at all.
fn assert_refused(
    tag: &str,
    scene: &str,
    files: &[(&str, &str)],
    args: &[&str],
    line: usize,
    needles: &[&str],
) {
    let (code, msg, path, out) = host_run(tag, scene, files, args);
    assert_eq!(code, Some(2), "{tag}: exit code; stderr: {msg}");
    if line > 0 {
        let loc = format!("error: {}:{line}:", path.display());
        assert!(msg.starts_with(&loc), "{tag}: expected {loc} in: {msg}");
    } else {
        assert!(msg.starts_with("error: "), "{tag}: {msg}");
    }
    for n in needles {
        assert!(msg.contains(n), "{tag}: expected `{n}` in: {msg}");
    }
    assert!(!out.exists(), "{tag}: refused input must write no output");
}

const MESH_SCENE: &str = r#"[solver]
frames = 2

[[objects]]
name = "cloth"
pins = [0]
[objects.mesh]
path = "mesh.obj"

[[constraints]]
kind = "stretch"
"#;

const GOOD_MESH: &str = "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n";

#[test]
fn nan_or_infinity_in_an_obj_mesh_is_refused_before_the_run() {
    for (tag, v) in [
        ("nan", "nan"),
        ("inf", "inf"),
        ("overflow", "1e999"),
        ("neg-nan", "-NaN"),
    ] {
        let obj = format!("v 0 0 0\nv 1 0 0\nv {v} 0 1\nf 1 2 3\n");
        assert_refused(
            &format!("mesh-{tag}"),
            MESH_SCENE,
            &[("mesh.obj", &obj)],
            &[],
            8,
            &["mesh.obj", "non-finite vertex position"],
        );
    }
    // The control: the same scene with a finite mesh runs.
    let (code, msg, _, out) = host_run("mesh-finite", MESH_SCENE, &[("mesh.obj", GOOD_MESH)], &[]);
    assert_eq!(code, Some(0), "{msg}");
    assert!(out.join("run.json").is_file());
}

#[test]
fn nan_in_an_animated_mesh_frame_is_refused_before_the_run() {
    let scene = MESH_SCENE.replace(
        "path = \"mesh.obj\"",
        "path = \"mesh.obj\"\nsequence = \"mesh_{frame}.obj\"",
    );
    assert_refused(
        "sequence-nan",
        &scene,
        &[
            ("mesh.obj", GOOD_MESH),
            ("mesh_0.obj", GOOD_MESH),
            ("mesh_1.obj", "v 0 0 0\nv nan 0 0\nv 0 0 1\nf 1 2 3\n"),
        ],
        &[],
        9,
        &["mesh_1.obj", "non-finite vertex position"],
    );
}

#[test]
fn negative_density_and_zero_vertex_mass_are_refused_before_the_run() {
    for (tag, mass) in [
        ("neg-density", "density = -1.0"),
        ("zero-vertex-mass", "vertex_mass = 0.0"),
        ("inf-density", "density = inf"),
    ] {
        let scene = MESH_SCENE.replace("pins = [0]", &format!("pins = [0]\n{mass}"));
        assert_refused(
            tag,
            &scene,
            &[("mesh.obj", GOOD_MESH)],
            &[],
            7,
            &["mass must be a positive finite number"],
        );
    }
}

#[test]
fn zero_substeps_or_iterations_on_the_command_line_are_refused_before_the_run() {
    let files = [("mesh.obj", GOOD_MESH)];
    assert_refused(
        "cli-substeps",
        MESH_SCENE,
        &files,
        &["--substeps", "0"],
        0,
        &["--substeps must be at least 1"],
    );
    assert_refused(
        "cli-iterations",
        MESH_SCENE,
        &files,
        &["--iterations", "0"],
        0,
        &["--iterations must be at least 1"],
    );
}

#[test]
fn nan_or_a_negative_constraint_parameter_is_refused_before_the_run() {
    for (tag, value) in [
        ("param-nan", "nan"),
        ("param-neg", "-1.0"),
        ("param-neg-inf", "-inf"),
    ] {
        let scene = format!("{MESH_SCENE}params = {{ compliance = {value} }}\n");
        assert_refused(
            tag,
            &scene,
            &[("mesh.obj", GOOD_MESH)],
            &[],
            12,
            &["parameter `compliance`"],
        );
    }
}

// ---------------------------------------------------------------------------------------------
// The measures themselves, so that the checks above cannot pass vacuously

#[test]
fn the_energy_growth_measure_sees_sustained_growth_and_ignores_decay_and_flicker() {
    // 2 % per second of growth from 1 J, sampled at 10 Hz for 4 s (w = 1 s).
    let grow: Vec<_> = (0..=40)
        .map(|k| (k as f64 * 0.1, 1.0 + 0.02 * k as f64 * 0.1, 0.0))
        .collect();
    let (rate, in_play) = energy_growth(&grow);
    assert!(rate > 0.015 && rate < 0.021, "{rate}");
    assert!((in_play - 1.08).abs() < 1e-12, "{in_play}");
    // Decay with exchange between kinetic and potential energy, and a one-sample flicker of
    // +5 %: no growth.
    let swing: Vec<_> = (0..=40)
        .map(|k| {
            let t = k as f64 * 0.1;
            let e = (-t).exp() * if k == 20 { 1.05 } else { 1.0 };
            (t, e * (t * 5.0).sin().powi(2), e * (t * 5.0).cos().powi(2))
        })
        .collect();
    let (rate, _) = energy_growth(&swing);
    assert!(rate <= 0.0, "{rate}");
}

#[test]
fn the_energy_growth_measure_at_one_sample_a_second_sees_growth_and_ignores_flicker() {
    // h = 1 s: one sample a second, so a window holds three (w = 3 s).
    // 2 % per second of sustained growth from 1 J over 20 s: seen.
    let grow: Vec<_> = (0..=20)
        .map(|k| (k as f64, 1.0 + 0.02 * k as f64, 0.0))
        .collect();
    let (rate, _) = energy_growth(&grow);
    assert!(rate > 0.015 && rate < 0.021, "{rate}");
    // A rise of 10 % held from t = 10 s on (a source that fires once): seen.
    let step: Vec<_> = (0..=20)
        .map(|k| (k as f64, 0.0, if k >= 10 { 1.1 } else { 1.0 }))
        .collect();
    let (rate, _) = energy_growth(&step);
    assert!(rate > 0.01, "{rate}");
    // A cloth that drops 1 J at the first step and then hangs, its sampled energy flickering by
    // ±3 % of that from sample to sample with no trend (h = 1 s, docs/stress.md): not growth.
    // A one-sample window would read it as 6 %/s.
    let flicker: Vec<_> = (0..=20)
        .map(|k| {
            let u = match k {
                0 => 0.0,
                _ if k % 2 == 0 => -1.0 + 0.03,
                _ => -1.0 - 0.03,
            };
            (k as f64, 0.0, u)
        })
        .collect();
    let (rate, _) = energy_growth(&flicker);
    assert!(rate < 0.01, "{rate}");
    // Three samples a second apart cannot hold two windows 3 s apart: no verdict, which the
    // checks fail rather than pass.
    let (rate, _) = energy_growth(&flicker[..3]);
    assert_eq!(rate, f64::NEG_INFINITY);
}

#[test]
fn the_closest_point_on_a_triangle_is_never_beaten_by_sampling() {
    let (a, b, c) = (
        DVec3::new(0.1, -0.2, 0.3),
        DVec3::new(1.2, 0.1, -0.4),
        DVec3::new(-0.3, 0.9, 0.5),
    );
    for p in [
        DVec3::new(0.3, 0.2, 1.0),
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(-1.0, -1.0, -1.0),
        DVec3::new(0.3, 0.3, 0.1),
    ] {
        let q = on_triangle(p, a, b, c);
        let d = (p - q).length();
        for i in 0..=40 {
            for j in 0..=40 - i {
                let (u, v) = (i as f64 / 40.0, j as f64 / 40.0);
                let s = a + u * (b - a) + v * (c - a);
                assert!((p - s).length() >= d - 1e-12, "{p}: {s} beats {q}");
            }
        }
    }
    // Zero-area triangle: the closest point of its longest edge.
    let q = on_triangle(
        DVec3::new(0.5, 1.0, 0.0),
        DVec3::ZERO,
        DVec3::X,
        DVec3::X * 0.5,
    );
    assert!((q - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-15, "{q}");
}

// ---------------------------------------------------------------------------------------------
// The global Newton solve of stretch (`stretch_newton`) at the extremes

/// Checks `scene` (a `stretch_newton` cloth) with the energy conserved and the default speed
/// bound, reporting the group's residual.
fn check_newton_energy(name: &'static str, scene: String) {
    check(newton_energy_case(name, scene));
}

/// The case [`check_newton_energy`] checks.
fn newton_energy_case(name: &'static str, scene: String) -> Case {
    Case::new(name, scene, Energy::Conserved { from_frame: 0 }, WHIP)
        .last(|sim| residual_figure(sim, "stretch_newton"))
}

/// A 1 m cloth of `n × n` vertices pinned at the corners of one edge, its edges solved by
/// `stretch_newton` (compliance `compliance` m/N), with the given solver settings and the
/// object's `extra` TOML lines (velocity, mass maps).
fn newton_cloth(
    n: u32,
    frame_rate: f64,
    substeps: u32,
    iterations: u32,
    frames: u32,
    compliance: f64,
    extra: &str,
) -> String {
    format!(
        r#"
[solver]
frame_rate = {frame_rate}
frames = {frames}
substeps = {substeps}
iterations = {iterations}
[[objects]]
name = "cloth"
pins = ["corners:row0"]
{extra}
[objects.grid]
size = [1.0, 1.0]
resolution = [{n}, {n}]
[[constraints]]
kind = "stretch_newton"
params = {{ compliance = {compliance:e}, compression_compliance = {compliance:e} }}
"#
    )
}

/// One Newton step a substep with the default solves (at most 50 CG iterations to 1e-6) does
/// not converge the substep, and with stiff springs the error left does work: the hanging
/// cloth swings higher and higher (12 x 12 cloth, 2 substeps, 60 frames, compliance 1e-8:
/// +34 %/s of the energy in play). With the substep converged (8 passes, CG to 1e-9) or softer
/// springs (1e-5) it does not (the next test).
#[test]
#[ignore = "fails: stretch_newton at 1 pass, compliance 1e-8, gains 34 %/s of the energy in play (unconverged substeps); converged passes and compliance 1e-5 do not (the next test)"]
fn newton_stretch_at_one_pass_never_gains_energy() {
    check_newton_energy(
        "stretch_newton, 1 pass, 12 x 12 cloth, compliance 1e-8",
        newton_cloth(12, 60.0, 2, 1, 60, 1e-8, ""),
    );
}

/// Two Newton steps a substep with the default solves do not converge the substep either
/// (12 x 12 cloth, 2 substeps, 60 frames, compliance 1e-8: +1.66 %/s of the energy in play).
#[test]
#[ignore = "fails: stretch_newton at 2 passes, compliance 1e-8, gains 1.66 %/s of the energy in play (unconverged substeps)"]
fn newton_stretch_at_two_passes_never_gains_energy() {
    check_newton_energy(
        "stretch_newton, 2 passes, 12 x 12 cloth, compliance 1e-8",
        newton_cloth(12, 60.0, 2, 2, 60, 1e-8, ""),
    );
}

/// Gauss-Seidel passes at the start of each substep (`start_passes`), which make two
/// Newton steps a substep move the drape right (`tests/newton_drape.rs`), make the energy
/// gained larger, not smaller: the same cloth as above gains +13.7 %/s with 10 start passes.
#[test]
#[ignore = "fails: stretch_newton at 2 passes after 10 start passes, compliance 1e-8, gains 13.7 %/s of the energy in play (1.66 %/s without them)"]
fn newton_stretch_at_two_passes_after_start_passes_never_gains_energy() {
    let started = newton_cloth(12, 60.0, 2, 2, 60, 1e-8, "").replace(
        "compression_compliance = 1e-8 }",
        "compression_compliance = 1e-8, start_passes = 10 }",
    );
    assert!(started.contains("start_passes"));
    check_newton_energy(
        "stretch_newton, 2 passes after 10 start passes, 12 x 12 cloth, compliance 1e-8",
        started,
    );
}

/// Implicit Euler solved exactly only dissipates, at any stiffness; so do the default solves
/// at a softer compliance, and at 1,000 passes.
#[test]
fn newton_stretch_with_exact_solves_or_softer_springs_never_gains_energy() {
    let exact = newton_cloth(12, 60.0, 2, 8, 60, 1e-8, "").replace(
        "compression_compliance = 1e-8 }",
        "compression_compliance = 1e-8, cg_iterations = 40, cg_tolerance = 1e-9 }",
    );
    check_all(
        [
            (
                "stretch_newton, 8 exact passes (CG to 1e-9), 12 x 12 cloth, compliance 1e-8",
                exact,
            ),
            (
                "stretch_newton, 1 pass, 12 x 12 cloth, compliance 1e-5",
                newton_cloth(12, 60.0, 2, 1, 60, 1e-5, ""),
            ),
            (
                "stretch_newton, 1,000 passes, 8 x 8 cloth, compliance 1e-8",
                newton_cloth(8, 60.0, 2, 1000, 5, 1e-8, ""),
            ),
        ]
        .map(|(name, scene)| newton_energy_case(name, scene)),
    );
}

/// A cloth thrown at 1e4 m/s past its pins, and one whose hem is 1e6 times heavier than the
/// rest: finite, no energy gained, no particle faster than the bound.
#[test]
fn newton_stretch_at_1e4_m_s_and_mass_ratio_1e6_stays_bounded() {
    let thrown = Case::new(
        "stretch_newton, 16 x 16 cloth thrown at 1e4 m/s, 2 x 2",
        newton_cloth(16, 60.0, 2, 2, 10, 1e-8, "velocity = [0.0, -10000.0, 0.0]"),
        Energy::Conserved { from_frame: 0 },
        WHIP,
    );
    let heavy_hem = Case::new(
        "stretch_newton, 16 x 16 cloth, hem 1e6 times heavier, 2 x 2",
        newton_cloth(
            16,
            60.0,
            2,
            2,
            60,
            1e-8,
            r#"mass_maps = [{ vertices = ["edge:rowN"], scale = 1e6 }]"#,
        ),
        Energy::Conserved { from_frame: 0 },
        Speed::Energy,
    );
    check_all([thrown, heavy_hem]);
}

/// The stiffest springs the kind accepts (1e-15 m/N) and one substep of 1 s stay finite and
/// within the speed bound; their energy is not checked here (see the ignored test below).
#[test]
fn newton_stretch_at_the_least_compliance_and_1_s_substeps_stays_finite() {
    let cases = [
        (
            "stretch_newton, compliance 1e-15, 16 x 16 cloth, 2 x 2",
            newton_cloth(16, 60.0, 2, 2, 30, 1e-15, ""),
        ),
        (
            "h = 1 s, 10 passes, 8 x 8 cloth (stretch_newton)",
            newton_cloth(8, 1.0, 1, 10, 30, 1e-8, ""),
        ),
    ]
    .map(|(name, scene)| {
        Case::new(
            name,
            scene,
            Energy::Source("not checked: see the ignored test"),
            WHIP,
        )
        .last(|sim| residual_figure(sim, "stretch_newton"))
    });
    check_all(cases);
}

/// The least compliance at the energy check: it gains energy (unconverged substeps, as above).
#[test]
#[ignore = "fails: at compliance 1e-15 (2 x 2) the energy grows 50 %/s (80 %/s before the multigrid turned) of the energy in play; unconverged substeps, as newton_stretch_at_one_pass_never_gains_energy"]
fn newton_stretch_at_the_least_compliance_never_gains_energy() {
    check_newton_energy(
        "stretch_newton, compliance 1e-15, 16 x 16 cloth, 2 x 2 (energy)",
        newton_cloth(16, 60.0, 2, 2, 30, 1e-15, ""),
    );
}

/// One substep of 1 s at the energy check.
#[test]
#[ignore = "fails: at h = 1 s with 10 passes the energy grows 10 %/s (15 %/s before the multigrid turned) of the energy in play; unconverged substeps, as newton_stretch_at_one_pass_never_gains_energy"]
fn newton_stretch_with_1_s_substeps_never_gains_energy() {
    check_newton_energy(
        "h = 1 s, 10 passes, 8 x 8 cloth (stretch_newton, energy)",
        newton_cloth(8, 1.0, 1, 10, 30, 1e-8, ""),
    );
}
