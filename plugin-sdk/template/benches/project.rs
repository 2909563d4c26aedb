//! The hot loop: one `project` pass of the group over 100,000 particles, called through the
//! ABI trait object exactly as the host calls it. Criterion reports constraints per second;
//! ns per constraint is its inverse.

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use nucleus_sdk::abi_stable::std_types::RSlice;
use nucleus_sdk::prelude::*;
use nucleus_sdk::testing::CoreState;

/// Particles per axis of the cloud.
const N: u32 = 47;

fn project_pass(c: &mut Criterion) {
    let count = (N * N * N) as usize;
    // A 2 m cube of particles around the centre, so most are outside the 0.3 m free ball.
    let rest: Vec<[f64; 3]> = (0..count as u32)
        .map(|k| {
            let (i, j, l) = (k % N, (k / N) % N, k / (N * N));
            let s = 2.0 / (N - 1) as f64;
            [i as f64 * s - 1.0, j as f64 * s - 1.0, l as f64 * s - 1.0]
        })
        .collect();
    let inv_mass = vec![1000.0; count];
    let points: Vec<u32> = (0..count as u32).collect();
    let objects = [ObjectView {
        points: RSlice::from_slice(&points),
        ..ObjectView::new("cloud", 0, count as u32)
    }];
    let scene = SceneView {
        gravity: [0.0, -9.81, 0.0],
        substeps: 10,
        ..SceneView::new(&objects, &[0], &rest, &inv_mass)
    };
    let kind = nucleus_template_attract::KIND;
    let mut group = nucleus_template_attract::nucleus_plugin()
        .create_group(kind, r#"{"radius": 0.3, "period": 0.5}"#, &scene)
        .unwrap_or_else(|e| panic!("cannot build the group: {e}"));

    // The particle state the core owns, at rest, and the context of a call as the host builds it.
    let mut state = CoreState::at_rest(rest, inv_mass, 1.0 / 600.0);
    state.gravity = [0.0, -9.81, 0.0];
    let mut ctx = state.ctx();

    let mut bench = c.benchmark_group("attract");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    bench.throughput(Throughput::Elements(group.constraint_count()));
    bench.bench_function("project", |b| {
        // Each iteration starts a substep (λ = 0) and projects once, so every particle outside
        // the ball does the full work of a first pass.
        b.iter(|| {
            let _ = group.begin_substep(&mut ctx);
            black_box(group.project(black_box(&mut ctx))).is_ok()
        })
    });
    bench.finish();
}

criterion_group!(benches, project_pass);
criterion_main!(benches);
