//! No allocation inside the step loop: after building, stepping a scene allocates nothing —
//! not in the core, not in the plugins. The plugins are linked in-process here (the same code
//! as their cdylibs) so this binary's counting allocator sees every allocation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use nucleus_core::{Registry, Simulation};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Held by each test for its whole run: the counter is process-wide (a helper thread of the
/// step's team must be counted too), so the tests of this binary, which the harness runs on
/// parallel threads, take turns.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn turn() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

fn allocations_while(f: impl FnOnce()) -> usize {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    COUNTING.store(true, Ordering::SeqCst);
    f();
    COUNTING.store(false, Ordering::SeqCst);
    ALLOCATIONS.load(Ordering::SeqCst)
}

/// The fewest allocations made while `sim` steps `frames` frames, over three such windows.
/// The counter sees every thread of the process, the test harness's too: as one test ends and
/// the next begins counting, the harness may still be allocating its report of the first (14
/// allocations seen once in a window of the default scene). An allocation in the step loop
/// shows in every window; the harness's does not.
fn allocations_stepping(sim: &mut Simulation, frames: usize) -> usize {
    (0..3)
        .map(|_| {
            allocations_while(|| {
                for _ in 0..frames {
                    sim.step_frame().unwrap();
                }
            })
        })
        .min()
        .unwrap_or(0)
}

fn registry() -> Registry {
    let mut reg = Registry::default();
    reg.add_in_process(nucleus_stretch::nucleus_plugin());
    reg
}

const SCENE: &str = r#"
[solver]
substeps = 4
iterations = 2
damping = 0.3
[[objects]]
name = "cloth"
pins = ["corners:row0"]
pin_motion = { velocity = [0.1, 0.0, 0.0] }
[objects.grid]
size = [1.0, 1.0]
resolution = [12, 12]
[[objects]]
name = "rope"
pins = ["start"]
[objects.rope]
start = [0.0, 1.0, 0.0]
end = [1.0, 1.0, 0.0]
segments = 10
[[constraints]]
kind = "stretch"
params = { compliance = 1e-6, damping = 0.1 }
[[constraints]]
kind = "tether"
objects = ["cloth"]
params = { compliance = 1e-7 }
"#;

#[test]
fn stepping_allocates_nothing() {
    let _turn = turn();
    let mut sim = Simulation::from_toml(SCENE, &registry()).unwrap();
    sim.step_frame().unwrap();
    let n = allocations_stepping(&mut sim, 10);
    assert_eq!(n, 0, "{n} allocations in 10 frames of stepping");
}

#[test]
fn the_counter_sees_allocations() {
    let _turn = turn();
    let n = allocations_while(|| {
        let v: Vec<u64> = std::hint::black_box(vec![1, 2, 3]);
        drop(v);
    });
    assert!(n >= 1);
}

/// [`SCENE`] with a 72 × 72 cloth at 2 substeps: 5,184 particles (the core's loops are split
/// over the team) and colours of more than 256 edges and more than 2,048 tethers (the plugin's
/// passes are too).
fn large_scene() -> String {
    SCENE
        .replace("resolution = [12, 12]", "resolution = [72, 72]")
        .replace("substeps = 4", "substeps = 2")
}

/// Asserts that `scene` steps 3 frames on 2 threads, after one of warm-up, allocating nothing.
fn assert_two_threads_allocate_nothing(scene: &str) {
    let mut sim = Simulation::from_toml(scene, &registry()).unwrap();
    sim.threads = 2;
    sim.step_frame().unwrap();
    let n = allocations_stepping(&mut sim, 3);
    assert_eq!(n, 0, "{n} allocations in 3 frames of stepping on 2 threads");
}

#[test]
fn stepping_a_cloth_split_over_the_thread_team_allocates_nothing() {
    let _turn = turn();
    assert_two_threads_allocate_nothing(&large_scene());
}

#[test]
fn stretch_solved_by_stars_on_two_threads_allocates_nothing() {
    let _turn = turn();
    // 72 × 72 with a star at every particle: colours of more than 256 stars, split over the
    // team; compliant and damped, so the stars keep multipliers.
    let scene = large_scene().replace(
        "params = { compliance = 1e-6, damping = 0.1 }",
        "params = { compliance = 1e-6, damping = 0.1, blocks = \"stars\" }",
    );
    assert!(scene.contains("stars"));
    assert_two_threads_allocate_nothing(&scene);
}

#[test]
fn stretch_solved_by_newton_steps_on_two_threads_allocates_nothing() {
    let _turn = turn();
    // 72 × 72 (5,182 unknowns, above the multigrid's 2,048 rows a part): the assembly, the
    // Galerkin products, the V-cycles, CG and the line search split over the team, with the
    // coarse particles turning and start passes (XPBD, with multipliers; colours of more than
    // 256 edges) each substep.
    let scene = large_scene().replace(
        "kind = \"stretch\"\nparams = { compliance = 1e-6, damping = 0.1 }",
        "kind = \"stretch_newton\"\nparams = { cg_iterations = 5, start_passes = 2 }",
    );
    assert!(scene.contains("start_passes"));
    assert_two_threads_allocate_nothing(&scene);
}

#[test]
fn a_colliding_cloth_resting_on_the_ground_on_two_threads_allocates_nothing() {
    let _turn = turn();
    // 24 × 24 (576 vertices, 1,633 edges, self-collision on): the collision broad phase
    // splits its queries over the team, and the cloth, dropped flat 5 cm onto the ground,
    // keeps hundreds of contacts with it.
    let scene = r#"
[solver]
substeps = 4
damping = 2.0
[[objects]]
name = "cloth"
[objects.grid]
size = [0.6, 0.6]
resolution = [24, 24]
plane = "xz"
origin = [-0.3, 0.05, -0.3]
[[constraints]]
kind = "stretch"
params = { compression_compliance = 1e-3 }
[[constraints]]
kind = "collision"
params = { thickness = 0.01, friction_static = 0.5, friction_dynamic = 0.4, colliders = [
  { type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] },
] }
"#;
    let mut reg = registry();
    reg.add_in_process(nucleus_collision::nucleus_plugin());
    let mut sim = Simulation::from_toml(scene, &reg).unwrap();
    sim.threads = 2;
    // Until it rests: the candidate and contact lists reach their size.
    for _ in 0..60 {
        sim.step_frame().unwrap();
    }
    let n = allocations_stepping(&mut sim, 5);
    let contacts = sim
        .reports()
        .unwrap()
        .into_iter()
        .find(|(k, _)| k == "collision.contacts")
        .map_or(0.0, |(_, v)| v);
    assert!(
        contacts > 100.0,
        "only {contacts} contacts: the test means nothing"
    );
    assert_eq!(
        n, 0,
        "{n} allocations in 5 frames of a resting cloth on 2 threads"
    );
}

#[test]
fn rigid_dice_answering_their_pushes_allocate_nothing() {
    let _turn = turn();
    // The shipped dice (rigid + collision), tumbling and then resting on the ground: every
    // substep's pushes are answered with the bodies' masses (the rigid group's push scratch).
    let text = std::fs::read_to_string(nucleus_tests::shipped_scene("dice.toml")).unwrap();
    let mut reg = registry();
    reg.add_in_process(nucleus_rigid::nucleus_plugin());
    reg.add_in_process(nucleus_collision::nucleus_plugin());
    let mut sim = Simulation::from_toml(&text, &reg).unwrap();
    assert!(!sim.particles.pushes.is_empty(), "no pushes kept");
    // Through the tumbling (every list reaches its size) until they rest, each still pushed up
    // by the ground every substep (measured at rest from frames 44-61).
    for _ in 0..70 {
        sim.step_frame().unwrap();
    }
    let n = allocations_stepping(&mut sim, 4);
    assert_eq!(n, 0, "{n} allocations in 4 frames of dice on the ground");
}
