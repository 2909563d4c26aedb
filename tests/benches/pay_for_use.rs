//! A scene pays only for what it uses, measured: the step time of one scene built three ways,
//! through the real, dynamically loaded plugins.
//!
//! * `stretch_dir_only` — the 64 × 64 drape (hard stretch, 10 substeps) discovered from a
//!   directory holding only the stretch plugin;
//! * `every_plugin` — the same scene discovered from the directory of every plugin (bend, air,
//!   pressure, rigid, collision and the rest are found but never loaded into the schedule);
//! * `with_idle_collision` — the same scene plus a `collision` group whose objects cannot
//!   collide (self-collision off, no colliders): the group is empty and never scheduled.
//!
//! The three should agree within noise (a few %): compare them as ratios of one run.
//!
//! `cargo xtask plugins --release && cargo bench -p nucleus-tests --bench pay_for_use`

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use nucleus_core::{Registry, Scene, Simulation};
use nucleus_tests::{lib_name, plugin_dir, plugin_dir_with};

fn drape() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/drape.toml");
    std::fs::read_to_string(path).expect("scenes/drape.toml")
}

fn build(text: &str, registry: &Registry) -> Simulation {
    let scene = Scene::parse(text, std::path::Path::new("drape.toml")).expect("scene");
    Simulation::build(&scene, registry).expect("build")
}

fn bench(c: &mut Criterion) {
    let all = plugin_dir();
    let only_stretch = plugin_dir_with("pay-for-use", &[all.join(lib_name("nucleus_stretch"))]);
    let idle_collision = format!(
        "{}\n[[constraints]]\nkind = \"collision\"\nparams = {{ self_collision = false }}\n",
        drape()
    );
    let cases = [
        (
            "stretch_dir_only",
            build(&drape(), &Registry::discover(&[only_stretch])),
        ),
        (
            "every_plugin",
            build(&drape(), &Registry::discover(std::slice::from_ref(&all))),
        ),
        (
            "with_idle_collision",
            build(
                &idle_collision,
                &Registry::discover(std::slice::from_ref(&all)),
            ),
        ),
    ];
    let mut group = c.benchmark_group("pay_for_use_drape_64x64_substep");
    group.measurement_time(Duration::from_secs(5));
    for (name, mut sim) in cases {
        let groups: Vec<String> = sim.groups.iter().map(|g| g.name.clone()).collect();
        eprintln!(
            "{name}: groups {groups:?}, {} calls per substep",
            sim.calls.len()
        );
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
