//! The hot loop: one `project` pass of the group over 100,000 particles, called through the
//! ABI trait object exactly as the host calls it. Criterion reports constraints per second;
//! ns per constraint is its inverse.

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use nucleus_sdk::abi_stable::std_types::{RSlice, RStr};
use nucleus_sdk::prelude::*;

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
        name: RStr::from_str("cloud"),
        first: 0,
        count: count as u32,
        points: RSlice::from_slice(&points),
        edges: RSlice::EMPTY,
        edge_triangle_count: RSlice::EMPTY,
        triangles: RSlice::EMPTY,
        triangle_tet_count: RSlice::EMPTY,
        tets: RSlice::EMPTY,
        triangle_pairs: RSlice::EMPTY,
        edge_pairs: RSlice::EMPTY,
        boundary_edges: RSlice::EMPTY,
        closed: 0,
        manifold: 1,
    }];
    let scene = SceneView {
        objects: RSlice::from_slice(&objects),
        targets: RSlice::from_slice(&[0]),
        rest: RSlice::from_slice(&rest),
        inv_mass: RSlice::from_slice(&inv_mass),
        attributes: RSlice::EMPTY,
        gravity: [0.0, -9.81, 0.0],
        frame_dt: 1.0 / 60.0,
        substeps: 10,
    };
    let kind = nucleus_template_attract::KIND;
    let mut group = nucleus_template_attract::nucleus_plugin()
        .create_group(kind, r#"{"radius": 0.3, "period": 0.5}"#, &scene)
        .unwrap_or_else(|e| panic!("cannot build the group: {e}"));

    let mut x = rest.clone();
    let x0 = rest.clone();
    let mut v = vec![[0.0; 3]; count];
    let object = vec![0u32; count];
    let flags = vec![0u32; count];
    let mut ctx = SolveContext {
        gravity: [0.0, -9.81, 0.0],
        substeps: 10,
        ..SolveContext::new(&mut x, &mut v, &x0, &inv_mass, &object, &flags, 1.0 / 600.0)
    };

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
