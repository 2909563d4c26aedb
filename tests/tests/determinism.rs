//! Determinism: the same scene with the same plugins gives bit-identical output — every OBJ
//! frame byte for byte, and every stats column except the wall-clock time — whatever the
//! thread count (`RAYON_NUM_THREADS`, the size of the host's thread team, on which the core's
//! particle loops and the plugins' passes run).

use std::process::Command;

use nucleus_tests::*;

fn run_once(tag: &str, scene: &str, threads: &str) -> std::path::PathBuf {
    run_with(tag, scene, threads, &["--frames", "30"])
}

fn run_with(tag: &str, scene: &str, threads: &str, extra: &[&str]) -> std::path::PathBuf {
    let out = temp_dir(tag);
    let status = host_command("run", std::path::Path::new(scene), &out)
        .args(extra)
        .env("RAYON_NUM_THREADS", threads)
        .status()
        .unwrap();
    assert!(status.success());
    out
}

/// Every OBJ frame `0..=frames` of run `a` is byte for byte that of run `b`.
fn assert_same_frames(a: &std::path::Path, b: &std::path::Path, frames: u32, what: &str) {
    for f in 0..=frames {
        let name = format!("frame_{f:04}.obj");
        let fa = std::fs::read(a.join(&name)).unwrap();
        let fb = std::fs::read(b.join(&name)).unwrap();
        assert!(fa == fb, "{name} differs between {what}");
    }
}

/// Writes `text` as a scene, runs it for its 4 frames on 1 and on 2 threads, and asserts that
/// every frame is byte for byte the same and that the cloth moved (so the comparison means
/// something).
fn assert_one_and_two_threads_agree(tag: &str, text: &str) {
    let scene = temp_dir(&format!("{tag}-scene")).join("scene.toml");
    std::fs::write(&scene, text).unwrap();
    let scene = scene.to_str().unwrap();
    let a = run_with(&format!("{tag}-threads-1"), scene, "1", &[]);
    let b = run_with(&format!("{tag}-threads-2"), scene, "2", &[]);
    assert_same_frames(&a, &b, 4, &format!("1 and 2 threads ({tag})"));
    let first = std::fs::read(a.join("frame_0000.obj")).unwrap();
    let last = std::fs::read(a.join("frame_0004.obj")).unwrap();
    assert!(first != last, "the cloth must have moved ({tag})");
}

/// [`assert_one_and_two_threads_agree`] on the drape of `n × n` vertices (4 frames of 4
/// substeps, one pass each) with `constraints`.
fn assert_drape_agrees_on_one_and_two_threads(tag: &str, n: u32, constraints: &str) {
    assert_one_and_two_threads_agree(tag, &drape_text(n, 4, 4, 1, constraints));
}

fn stats_without_wall(dir: &std::path::Path) -> Vec<String> {
    let text = std::fs::read_to_string(dir.join("stats.csv")).unwrap();
    let wall = text
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|c| c == "wall_s")
        .unwrap();
    text.lines()
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| *i != wall)
                .map(|(_, c)| c)
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect()
}

#[test]
fn two_runs_of_the_default_scene_are_bit_identical() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/hanging_cloth.toml");
    let a = run_once("det-a", scene, "1");
    let b = run_once("det-b", scene, "2");
    assert_same_frames(&a, &b, 30, "two runs");
    assert_eq!(stats_without_wall(&a), stats_without_wall(&b));
}

#[test]
fn one_two_and_three_threads_give_bit_identical_frames() {
    // 96 × 96: every colour of the stretch batch is large enough to be split over threads, and
    // the 9,216 particles are enough for the core's loops to be split too (damping on, so its
    // loop is among them). Three threads split every range unevenly (and oversubscribe a
    // 2-core machine, which changes which thread claims which part, not the bits).
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/drape.toml");
    let set = [
        "--set",
        "objects.0.grid.resolution=[96,96]",
        "--set",
        "solver.damping=0.5",
        "--frames",
        "4",
    ];
    let a = run_with("threads-1", scene, "1", &set);
    let b = run_with("threads-2", scene, "2", &set);
    assert_same_frames(&a, &b, 4, "1 and 2 threads");
    let c = run_with("threads-3", scene, "3", &set);
    assert_same_frames(&a, &c, 4, "1 and 3 threads");
}

#[test]
fn the_threads_flag_sets_the_team_over_the_environment_with_the_same_bits() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/drape.toml");
    let set = [
        "--set",
        "objects.0.grid.resolution=[96,96]",
        "--frames",
        "3",
    ];
    let with = |threads: &'static str| [&set[..], &["--threads", threads]].concat();
    let a = run_with("flag-threads-2", scene, "1", &with("2"));
    let b = run_with("flag-threads-1", scene, "2", &with("1"));
    assert_same_frames(&a, &b, 3, "--threads 2 and --threads 1");
    let summary = |dir: &std::path::Path| std::fs::read_to_string(dir.join("run.json")).unwrap();
    assert!(
        summary(&a).contains("ms/frame on 2 threads"),
        "{}",
        summary(&a)
    );
    assert!(
        summary(&b).contains("ms/frame on 1 thread;"),
        "{}",
        summary(&b)
    );
    // No thread at all is refused before the run.
    let out = temp_dir("flag-threads-0");
    let status = Command::new(host_bin())
        .args(["run", scene, "--quiet", "--threads", "0", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert_eq!(status.code(), Some(2));
    assert!(!out.join("run.json").exists());
}

#[test]
fn in_process_runs_match_to_the_bit() {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/chain.toml"))
            .unwrap();
    let bits = |mut sim: nucleus_core::Simulation| -> Vec<u64> {
        for _ in 0..20 {
            sim.step_frame().unwrap();
        }
        sim.particles
            .x
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect()
    };
    let a = bits(simulation(&text, &[]));
    let b = bits(simulation(&text, &[]));
    assert_eq!(a, b);
}

#[test]
fn two_stretch_groups_and_two_simulations_at_once_give_the_bits_of_one_alone() {
    // Two `stretch` groups share the host's one thread team; two simulations stepping at
    // once contend for it, and a substep that finds it taken runs alone. 96 × 96: every colour
    // is large enough to be split over the team.
    let text = drape_text(
        96,
        3,
        4,
        1,
        r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
[[constraints]]
kind = "stretch"
objects = ["cloth"]
params = { compliance = 1e-7 }
"#,
    );
    let bits = |text: String| -> Vec<u64> {
        let mut sim = simulation(&text, &[]);
        for _ in 0..3 {
            sim.step_frame().unwrap();
        }
        sim.particles
            .x
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect()
    };
    let alone = bits(text.clone());
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(|| bits(text.clone()));
        let b = s.spawn(|| bits(text.clone()));
        (a.join().unwrap(), b.join().unwrap())
    });
    assert!(
        alone == a,
        "the first of two simulations at once differs from one alone"
    );
    assert!(
        alone == b,
        "the second of two simulations at once differs from one alone"
    );
    let start = simulation(&text, &[]);
    let moved = alone
        .iter()
        .zip(start.particles.x.iter().flatten())
        .filter(|(p, q)| **p != q.to_bits())
        .count();
    assert!(
        moved > 0,
        "the cloth must have moved for the comparison to mean anything"
    );
}

#[test]
fn tethers_on_one_and_two_threads_give_bit_identical_frames() {
    // 96 × 96 with two tethers per particle: 18,430 tethers, a pass split over the team.
    assert_drape_agrees_on_one_and_two_threads(
        "tether",
        96,
        r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
[[constraints]]
kind = "tether"
objects = ["cloth"]
"#,
    );
}

#[test]
fn more_threads_than_a_team_may_have_give_the_bits_of_one_thread() {
    // 64 threads asked for: the team runs its 32 parts (one bit each in its claim word), every
    // job split 32 ways with most parts stolen by whichever thread is running, on two cores.
    let scene = temp_dir("wide-team-scene").join("scene.toml");
    let constraints = "[[constraints]]\nkind = \"stretch\"\nobjects = [\"cloth\"]\n\
                       [[constraints]]\nkind = \"tether\"\nobjects = [\"cloth\"]\n";
    std::fs::write(&scene, drape_text(64, 4, 4, 1, constraints)).unwrap();
    let scene = scene.to_str().unwrap();
    let one = run_with("wide-team-1", scene, "1", &[]);
    let wide = run_with("wide-team-64", scene, "64", &[]);
    assert_same_frames(&one, &wide, 4, "1 and 64 threads");
    let summary = std::fs::read_to_string(wide.join("run.json")).unwrap();
    assert!(
        summary.contains("on 32 threads"),
        "the summary names the threads that ran: {summary}"
    );
    let (first, last) = (
        std::fs::read(one.join("frame_0000.obj")).unwrap(),
        std::fs::read(one.join("frame_0004.obj")).unwrap(),
    );
    assert!(first != last, "the cloth must have moved");
}

#[test]
fn bending_on_one_and_two_threads_gives_bit_identical_frames() {
    // 64 × 64: about 12,000 hinges per bend group in colours of several hundred, and 24,000
    // shear corners, each colour split over the team (`PARALLEL_MIN_CONSTRAINTS`).
    assert_drape_agrees_on_one_and_two_threads(
        "bend",
        64,
        r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
[[constraints]]
kind = "bend"
objects = ["cloth"]
params = { compliance = 1e3 }
[[constraints]]
kind = "bend_isometric"
objects = ["cloth"]
params = { compliance = 1e4 }
[[constraints]]
kind = "shear"
objects = ["cloth"]
params = { compliance = 1e2 }
"#,
    );
}

#[test]
fn a_stretch_hierarchy_on_one_and_two_threads_gives_bit_identical_frames() {
    // 96 × 96: the finest coarse level drops about 6,900 particles, whose prolongation is split
    // over the team (`PARALLEL_MIN_DROPPED`).
    assert_drape_agrees_on_one_and_two_threads(
        "hierarchy",
        96,
        r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
[[constraints]]
kind = "stretch_hierarchy"
objects = ["cloth"]
params = { straight_lengths = true }
"#,
    );
}

#[test]
fn stars_on_one_and_two_threads_give_bit_identical_frames() {
    // 96 × 96 with a star at every particle (`blocks = "stars"`): colours of ~700 stars, split
    // over the team; then a cloth with a column 1,000 times lighter.
    let light_column = r#"
[solver]
frames = 4
substeps = 4
[[objects]]
name = "cloth"
mass = 1.0
pins = ["corners:row0"]
mass_maps = [{ vertices = [{ min = [0.49, -1.0, -1.0], max = [0.51, 1.0, 1.0] }], scale = 1e-3 }]
[objects.grid]
size = [1.0, 1.0]
resolution = [96, 96]
plane = "xz"
[[constraints]]
kind = "stretch"
params = { blocks = "stars" }
"#;
    assert_drape_agrees_on_one_and_two_threads(
        "stars",
        96,
        r#"
[[constraints]]
kind = "stretch"
objects = ["cloth"]
params = { blocks = "stars" }
"#,
    );
    assert_one_and_two_threads_agree("light-column", light_column);
}

#[test]
fn a_cloth_colliding_with_itself_and_a_sphere_gives_the_same_bits_on_one_two_and_three_threads() {
    // 32 × 32 (1,024 vertices, 2,945 edges): the broad phase's vertex–face and edge–edge
    // queries are split over the team; the cloth reaches the sphere and folds over it.
    let dir = temp_dir("collision-threads-scene");
    let scene = dir.join("cloth_on_sphere.toml");
    std::fs::write(
        &scene,
        r#"
[solver]
frames = 24
substeps = 5
[[objects]]
name = "cloth"
mass = 0.3
[objects.grid]
size = [1.0, 1.0]
resolution = [32, 32]
plane = "xz"
origin = [-0.5, 0.35, -0.5]
[[constraints]]
kind = "stretch"
params = { compression_compliance = 1e-3 }
[[constraints]]
kind = "collision"
params = { thickness = 0.01, friction_static = 0.3, friction_dynamic = 0.2, colliders = [
  { type = "sphere", center = [0.0, 0.0, 0.0], radius = 0.3 },
] }
"#,
    )
    .unwrap();
    let scene = scene.to_str().unwrap();
    let a = run_with("collision-threads-1", scene, "1", &[]);
    let b = run_with("collision-threads-2", scene, "2", &[]);
    assert_same_frames(&a, &b, 24, "1 and 2 threads");
    assert_eq!(stats_without_wall(&a), stats_without_wall(&b));
    let c = run_with("collision-threads-3", scene, "3", &[]);
    assert_same_frames(&a, &c, 24, "1 and 3 threads");
    assert_eq!(stats_without_wall(&a), stats_without_wall(&c));
    // Meaningful only if the cloth met the sphere and itself: contacts in the last frames.
    let stats = stats_without_wall(&a);
    let header: Vec<&str> = stats[0].split(',').collect();
    let col = header
        .iter()
        .position(|c| *c == "collision.contacts")
        .unwrap();
    let last: f64 = stats
        .last()
        .unwrap()
        .split(',')
        .nth(col)
        .unwrap()
        .parse()
        .unwrap();
    assert!(last > 100.0, "only {last} contacts in the last frame");
}

#[test]
fn rigid_dice_answering_their_pushes_give_bit_identical_frames_on_one_and_two_threads() {
    // Through the tumbling (first impacts about frame 10) into the rest: the collision group
    // records its pushes, the rigid group answers them.
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/dice.toml");
    let frames = ["--frames", "60"];
    let a = run_with("dice-threads-1", scene, "1", &frames);
    let b = run_with("dice-threads-2", scene, "2", &frames);
    assert_same_frames(&a, &b, 60, "1 and 2 threads (dice)");
    assert_eq!(stats_without_wall(&a), stats_without_wall(&b));
}
