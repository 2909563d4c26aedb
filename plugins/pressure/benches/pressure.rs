//! The cost of the pressure groups per triangle: one chamber, a closed icosphere of 20,480
//! triangles (10,242 vertices; subdivision 5), built by the core from a scene and called
//! through the ABI trait object exactly as the host calls it. Criterion reports triangles per
//! second; ns per triangle is its inverse.
//!
//! * `project_*`: one pass — the volume at the current positions (a triple product per
//!   triangle), the scalar step, and the displacement of every vertex along its frozen normal.
//! * `force_*`: once per substep — the pressure normals at the start of the substep (a cross
//!   product per triangle, scattered to its three vertices), `S = Σ w|g|²`, and the warm-start
//!   velocity change.
//! * `begin_substep_gas`: the pump and leak update (scalar per chamber).

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use nucleus_core::{Registry, Simulation};
use nucleus_sdk::testing::CoreState;

fn scene(constraint: &str) -> Simulation {
    let text = format!(
        r#"
[solver]
substeps = 10
[[objects]]
name = "balloon"
mass = 0.5
[objects.sphere]
center = [0.0, 0.0, 0.0]
radius = 0.5
subdivisions = 5
[[constraints]]
{constraint}
"#
    );
    let mut reg = Registry::default();
    reg.add_in_process(nucleus_pressure::nucleus_plugin());
    match Simulation::from_toml(&text, &reg) {
        Ok(sim) => sim,
        Err(e) => panic!("cannot build the bench scene: {e}"),
    }
}

fn passes(c: &mut Criterion) {
    let mut bench = c.benchmark_group("pressure");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (name, constraint) in [
        (
            "gas",
            "kind = \"gas\"\nparams = { start_pressure = 1000.0 }",
        ),
        (
            "pressure",
            "kind = \"pressure\"\nparams = { pressure_scale = 1.2 }",
        ),
    ] {
        let mut sim = scene(constraint);
        let triangles = sim.objects[0].triangles.len() as u64;
        // Inflated by 1 % with a ripple, so every step does real work.
        let x: Vec<[f64; 3]> = sim
            .particles
            .x
            .iter()
            .map(|p| {
                let s = 1.01 + 0.002 * (20.0 * p[0]).sin();
                [s * p[0], s * p[1], s * p[2]]
            })
            .collect();
        // The core's state at the start of a substep from the rest shape (`x0`), the
        // objects and flags as the core built them.
        let p = &sim.particles;
        let mut state = CoreState {
            x0: p.x.clone(),
            object: p.object.clone(),
            flags: p.flags.clone(),
            ..CoreState::at_rest(x, p.inv_mass.clone(), 1.0 / 600.0)
        };
        let mut ctx = state.ctx();
        let group = &mut sim.groups[0].group;
        for stage in [group.force(&mut ctx), group.begin_substep(&mut ctx)] {
            if let Err(e) = stage.into_result() {
                panic!("setting up the substep failed: {e}");
            }
        }
        bench.throughput(Throughput::Elements(triangles));
        bench.bench_function(format!("project_{name}"), |b| {
            b.iter(|| black_box(group.project(black_box(&mut ctx))).is_ok())
        });
        bench.bench_function(format!("force_{name}"), |b| {
            b.iter(|| black_box(group.force(black_box(&mut ctx))).is_ok())
        });
        if name == "gas" {
            bench.bench_function("begin_substep_gas", |b| {
                b.iter(|| black_box(group.begin_substep(black_box(&mut ctx))).is_ok())
            });
        }
    }
    bench.finish();
}

criterion_group!(benches, passes);
criterion_main!(benches);
