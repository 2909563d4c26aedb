//! The core's own cost per substep, with no plugin at all: what every scene pays before its
//! groups run. Three scenes, each stepped one substep at a time through
//! [`Simulation::substep`]:
//!
//! * `empty` — a scene without objects: the fixed overhead of a substep;
//! * `free_fall_64x64` — a 64 × 64 cloth (4,096 particles) with no constraint group: gravity,
//!   prediction, velocity update and damping over the particle arrays;
//! * `pins_only_64x64` — the same cloth with every vertex pinned and moving (`pin_motion` with a
//!   velocity and a spin): the kinematic targets of 4,096 pins.
//!
//! `cargo bench -p nucleus-core --bench step`

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use nucleus_core::{Registry, Simulation};

const CLOTH: &str = r#"
[solver]
frames = 1000000
substeps = 10
damping = 0.1
[[objects]]
name = "cloth"
PINS
[objects.grid]
size = [1.0, 1.0]
resolution = [64, 64]
"#;

fn simulation(text: &str) -> Simulation {
    Simulation::from_toml(text, &Registry::discover(&[])).expect("scene")
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("core_substep");
    group.measurement_time(Duration::from_secs(3));
    let scenes = [
        ("empty", "[solver]\nframes = 1000000\nsubsteps = 10\n".to_string()),
        ("free_fall_64x64", CLOTH.replace("PINS", "")),
        (
            "pins_only_64x64",
            CLOTH.replace(
                "PINS",
                "pins = [\"all\"]\npin_motion = { velocity = [0.1, 0.0, 0.0], angular_velocity = [0.0, 1.0, 0.0] }",
            ),
        ),
    ];
    for (name, text) in scenes {
        let mut sim = simulation(&text);
        let mut k = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                sim.substep(k % 10).expect("substep");
                k += 1;
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
