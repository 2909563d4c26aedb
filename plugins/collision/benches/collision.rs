//! Broad + narrow phase cost per substep on the 64 × 64 cloth heap (`scenes/cloth_heap.toml`:
//! a 1 m cloth of 4,096 vertices, 8,064 triangles, dropped edge-first onto the ground, where it
//! folds onto itself; self-collision and a ground plane).
//!
//! The scene is simulated in-process (the plugin and `stretch` registered with `nucleus-core`
//! as the host registers loaded libraries) to a folded state with many contacts — frame
//! [`DEFAULT_FRAMES`], or `NUCLEUS_HEAP_FRAMES` — and that state is saved. Every iteration
//! restores it and times one substep from it (the restore is outside the timing):
//!
//! The group's stages get the host's thread team (`RAYON_NUM_THREADS`), as in a run.
//!
//! * `heap/broad_phase`: the collision group's `begin_substep` alone — refit of the two
//!   bounding-volume trees over the swept primitives and collection of the candidate pairs;
//! * `heap/collision_group`: the group's whole substep — `begin_substep`, its passes of
//!   `project` (importance 4: detection, continuous tests, projection; friction, the
//!   projection out of the colliders and the fail-safe in the last) and `end_substep`, on the
//!   core's prediction from the saved state (gravity, then `x = x0 + h v`);
//! * `heap/substep_with_collision` and `heap/substep_without_collision`: the core's whole
//!   substep (stretch and collision, interleaved) and the same without the collision group.
//!
//! Before timing, the counts at the saved state are printed (candidates, contacts, and the
//! frame's stats). Each sample is one substep, so criterion's times are per substep.
//!
//! `cargo bench -p nucleus-collision --bench collision`
//! (`NUCLEUS_HEAP_FRAMES=N` to benchmark another state of the heap).

use std::path::Path;
use std::time::{Duration, Instant};

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nucleus_core::particles::Particles;
use nucleus_core::{Registry, Scene, Simulation};
use nucleus_sdk::Stage;

/// The scene, relative to this crate.
const SCENE: &str = "../../scenes/cloth_heap.toml";
/// Frames simulated before the state is saved: 1.5 s, the cloth lies folded on the ground.
const DEFAULT_FRAMES: u32 = 90;

/// The heap at its saved state.
struct Heap {
    sim: Simulation,
    saved: Particles,
    time: f64,
    frame: u64,
    collision: usize,
    /// Restores so far: every other one flips the last bit of one inverse mass.
    restores: u64,
}

impl Heap {
    fn new() -> Self {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE);
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut registry = Registry::default();
        registry.add_in_process(nucleus_collision::nucleus_plugin());
        registry.add_in_process(nucleus_stretch::nucleus_plugin());
        let mut sim = Simulation::build(&scene, &registry).unwrap_or_else(|e| panic!("{e}"));
        let frames = std::env::var("NUCLEUS_HEAP_FRAMES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(DEFAULT_FRAMES);
        let start = Instant::now();
        for _ in 0..frames {
            sim.step_frame().unwrap_or_else(|e| panic!("{e}"));
        }
        let collision = sim
            .groups
            .iter()
            .position(|g| g.kind == "collision")
            .expect("a collision group");
        let stats: Vec<String> = sim
            .reports()
            .expect("reports")
            .into_iter()
            .filter(|(k, _)| k.starts_with("collision."))
            .map(|(k, v)| format!("{} {v}", &k["collision.".len()..]))
            .collect();
        let top = sim.positions().iter().map(|p| p.y).fold(f64::MIN, f64::max);
        eprintln!(
            "cloth heap after {frames} frames ({:.1} s to simulate): top of the heap at {top:.3} m; \
             frame {frames}'s collision stats: {}",
            start.elapsed().as_secs_f64(),
            stats.join(", ")
        );
        Self {
            saved: sim.particles.clone(),
            time: sim.time,
            frame: sim.frame,
            sim,
            collision,
            restores: 0,
        }
    }

    /// Back to the saved state. The group keeps the candidates it found and, at the next
    /// substep, only refreshes the primitives that left their boxes: from the same state
    /// again, none would have, and the timed substep would skip the broad phase. So every other
    /// restore changes the inverse mass of one particle in its last bit (a relative 2e-16),
    /// which the group answers, as it answers a pin change, with a full broad phase: every
    /// timed substep pays one, like the first substep after a collider or a mass changed.
    fn restore(&mut self) {
        self.sim.particles.clone_from(&self.saved);
        self.sim.time = self.time;
        self.sim.frame = self.frame;
        self.restores += 1;
        if self.restores % 2 == 1 {
            let w = &mut self.sim.particles.inv_mass;
            if let Some(k) = w.iter().position(|&w| w > 0.0) {
                w[k] = f64::from_bits(w[k].to_bits() ^ 1);
            }
        }
    }

    /// The core's stages before the groups, from the saved state (pins, gravity, the
    /// prediction), exactly as a substep runs them.
    fn predict(&mut self) {
        self.restore();
        self.sim
            .predict_substep(0)
            .unwrap_or_else(|e| panic!("{e}"));
    }

    /// The collision group's stages of one substep, through the core as a substep calls them
    /// (the same context and thread team): `begin_substep`, and if `full`, its passes and
    /// `end_substep` (the velocity update between them is the core's and cheap).
    fn collision_substep(&mut self, full: bool) {
        let (g, sim) = (self.collision, &mut self.sim);
        let run = |sim: &mut Simulation, stage, pass| {
            sim.run_stage(g, stage, 0, pass)
                .unwrap_or_else(|e| panic!("{e}"))
        };
        run(sim, Stage::BeginSubstep, 0);
        if full {
            let passes = sim.groups[g].importance * sim.settings.iterations;
            for pass in 0..passes {
                run(sim, Stage::Project, pass);
            }
            run(sim, Stage::EndSubstep, 0);
        }
    }
}

/// Times `f` once per iteration after `setup`, which is not timed.
fn timed(
    heap: &mut Heap,
    iters: u64,
    mut setup: impl FnMut(&mut Heap),
    mut f: impl FnMut(&mut Heap),
) -> Duration {
    let mut total = Duration::ZERO;
    for _ in 0..iters {
        setup(heap);
        let t = Instant::now();
        f(heap);
        total += t.elapsed();
        black_box(heap.sim.positions()[0]);
    }
    total
}

fn heap(c: &mut Criterion) {
    let mut heap = Heap::new();
    // The candidates and contacts of one substep from the saved state.
    heap.predict();
    heap.collision_substep(true);
    let stats: Vec<String> = heap
        .sim
        .reports()
        .expect("reports")
        .into_iter()
        .filter(|(k, _)| k == "collision.candidates" || k == "collision.contacts")
        .map(|(k, v)| format!("{} {v}", &k["collision.".len()..]))
        .collect();
    eprintln!("one substep from the saved state: {}", stats.join(", "));

    let mut bench = c.benchmark_group("heap");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(6));
    bench.bench_function("broad_phase", |b| {
        b.iter_custom(|n| timed(&mut heap, n, Heap::predict, |h| h.collision_substep(false)))
    });
    bench.bench_function("collision_group", |b| {
        b.iter_custom(|n| timed(&mut heap, n, Heap::predict, |h| h.collision_substep(true)))
    });
    bench.bench_function("substep_with_collision", |b| {
        b.iter_custom(|n| {
            timed(&mut heap, n, Heap::restore, |h| {
                h.sim.substep(0).unwrap_or_else(|e| panic!("{e}"))
            })
        })
    });
    // The same state and substep without the collision group.
    let collision = heap.collision;
    let removed = heap.sim.groups.remove(collision);
    heap.sim.reschedule();
    bench.bench_function("substep_without_collision", |b| {
        b.iter_custom(|n| {
            timed(&mut heap, n, Heap::restore, |h| {
                h.sim.substep(0).unwrap_or_else(|e| panic!("{e}"))
            })
        })
    });
    heap.sim.groups.insert(collision, removed);
    heap.sim.reschedule();
    bench.finish();
}

criterion_group!(benches, heap);
criterion_main!(benches);
