//! Cost of one `project` pass of the `rigid` group per body, for bodies of 10, 100 and 1,000
//! particles (about 10,000 particles in all: 1,000, 100 and 10 bodies), called through the
//! ABI trait object exactly as the host calls it. Criterion reports bodies per second; the
//! time per body per pass is its inverse.
//!
//! Each pass starts from positions as a substep would leave them: the bodies' last fitted
//! state turned by 0.01 rad (ω h for 6 rad/s at 600 Hz) about a random axis, plus 1 mm noise —
//! alternately from two such states, so the warm start always has a real rotation to find.
//! Two variants: fully rigid (`compliance = 0`) and compliant (`compliance = 1e-4` s²).

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use glam::{DQuat, DVec3};
use nucleus_sdk::prelude::*;
use nucleus_sdk::GroupBox;

use nucleus_sdk::testing::{CoreState, Rng};

struct Scene {
    rest: Vec<[f64; 3]>,
    inv_mass: Vec<f64>,
    names: Vec<String>,
    counts: u32,
    bodies: u32,
}

fn scene(per_body: u32, bodies: u32) -> Scene {
    let mut rng = Rng(0x1234_5678_9abc_def1 ^ per_body as u64);
    let n = (per_body * bodies) as usize;
    let rest = (0..n)
        .map(|k| (rng.vec3(0.5) + DVec3::X * (k as u32 / per_body) as f64).to_array())
        .collect();
    let inv_mass = (0..n).map(|_| 1.0 / (0.5 + rng.next_f64())).collect();
    Scene {
        rest,
        inv_mass,
        names: (0..bodies).map(|b| format!("body{b}")).collect(),
        counts: per_body,
        bodies,
    }
}

fn group(s: &Scene, params: &str) -> GroupBox {
    let objects: Vec<ObjectView<'_>> = (0..s.bodies)
        .map(|b| ObjectView::new(&s.names[b as usize], b * s.counts, s.counts))
        .collect();
    let targets: Vec<u32> = (0..s.bodies).collect();
    let view = SceneView {
        gravity: [0.0, -9.81, 0.0],
        substeps: 10,
        ..SceneView::new(&objects, &targets, &s.rest, &s.inv_mass)
    };
    match nucleus_rigid::nucleus_plugin().create_group("rigid", params, &view) {
        Ok(g) => g,
        Err(e) => panic!("cannot build the rigid group: {e}"),
    }
}

/// The rest shape of every body turned by `angle` about a random axis through its centre,
/// plus 1 mm of noise.
fn turned(s: &Scene, rng: &mut Rng, angle: f64) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(s.rest.len());
    for b in 0..s.bodies as usize {
        let q = DQuat::from_axis_angle(rng.vec3(1.0).normalize(), angle);
        let centre = DVec3::X * b as f64;
        for r in &s.rest[b * s.counts as usize..(b + 1) * s.counts as usize] {
            let p = centre + q * (DVec3::from_array(*r) - centre) + rng.vec3(1e-3);
            out.push(p.to_array());
        }
    }
    out
}

fn project_pass(c: &mut Criterion) {
    let mut bench = c.benchmark_group("rigid");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (per_body, bodies) in [(10, 1000), (100, 100), (1000, 10)] {
        let s = scene(per_body, bodies);
        let mut rng = Rng(7);
        let states = [turned(&s, &mut rng, 0.0), turned(&s, &mut rng, 0.01)];
        // The core's state at the start of a substep from the rest shape (`x0`), one object
        // per body; each pass from one of the two turned states.
        let start = CoreState {
            object: (0..s.rest.len() as u32).map(|i| i / per_body).collect(),
            gravity: [0.0, -9.81, 0.0],
            ..CoreState::at_rest(s.rest.clone(), s.inv_mass.clone(), 1.0 / 600.0)
        };
        for (variant, params) in [("hard", "{}"), ("compliant", r#"{"compliance": 1e-4}"#)] {
            let mut g = group(&s, params);
            bench.throughput(Throughput::Elements(g.constraint_count()));
            let mut which = 0;
            bench.bench_function(format!("{variant}_{per_body}_particles_per_body"), |b| {
                b.iter_batched_ref(
                    || {
                        which ^= 1;
                        CoreState {
                            x: states[which].clone(),
                            ..start.clone()
                        }
                    },
                    |state| black_box(g.project(black_box(&mut state.ctx()))).is_ok(),
                    BatchSize::LargeInput,
                )
            });
        }
    }
    bench.finish();
}

/// The rotation alone: Horn's matrix and its Jacobi eigen-decomposition, warm-started from a
/// hint 0.01 rad off.
fn rotation(c: &mut Criterion) {
    let mut rng = Rng(11);
    let q0 = DQuat::from_scaled_axis(rng.vec3(2.0));
    let cols = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
    let g = glam::DMat3::from_cols(cols[0], cols[1], cols[2]);
    let a = glam::DMat3::from_quat(q0) * (g.transpose() * g + glam::DMat3::IDENTITY * 0.1);
    let hint = DQuat::from_scaled_axis(DVec3::new(0.006, -0.005, 0.006)) * q0;
    let mut bench = c.benchmark_group("rigid");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    bench.bench_function("optimal_rotation", |b| {
        b.iter(|| nucleus_rigid::optimal_rotation(black_box(&a), black_box(hint)))
    });
    bench.finish();
}

criterion_group!(benches, rotation, project_pass);
criterion_main!(benches);
