//! The hot loop: one `force` pass of the `air` group over every triangle of a 128 × 128 cloth
//! (32,258 triangles, 16,384 particles), called through the ABI trait object exactly as the
//! host calls it, in a steady wind and in a gusty one (turbulence evaluated at every particle).
//! Criterion reports triangles per second; ns per triangle is its inverse.

use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use nucleus_sdk::abi_stable::std_types::RSlice;
use nucleus_sdk::prelude::*;
use nucleus_sdk::testing::CoreState;
use nucleus_sdk::GroupBox;

/// Vertices per side.
const N: u32 = 128;

struct Cloth {
    rest: Vec<[f64; 3]>,
    inv_mass: Vec<f64>,
    triangles: Vec<[u32; 3]>,
}

/// A 1 m square of N × N particles in the xy-plane, each quad split into two triangles.
fn cloth() -> Cloth {
    let spacing = 1.0 / (N - 1) as f64;
    let rest = (0..N * N)
        .map(|k| [(k % N) as f64 * spacing, (k / N) as f64 * spacing, 0.0])
        .collect();
    let mut triangles = Vec::new();
    for r in 0..N - 1 {
        for c in 0..N - 1 {
            let a = r * N + c;
            triangles.push([a, a + 1, a + N + 1]);
            triangles.push([a, a + N + 1, a + N]);
        }
    }
    Cloth {
        rest,
        inv_mass: vec![(N * N) as f64 / 0.15; (N * N) as usize],
        triangles,
    }
}

fn group(cloth: &Cloth, params: &str) -> GroupBox {
    let tet_counts = vec![0u32; cloth.triangles.len()];
    let objects = [ObjectView {
        triangles: RSlice::from_slice(&cloth.triangles),
        triangle_tet_count: RSlice::from_slice(&tet_counts),
        ..ObjectView::new("cloth", 0, N * N)
    }];
    let scene = SceneView {
        gravity: [0.0, -9.81, 0.0],
        substeps: 10,
        ..SceneView::new(&objects, &[0], &cloth.rest, &cloth.inv_mass)
    };
    match nucleus_air::nucleus_plugin().create_group("air", params, &scene) {
        Ok(g) => g,
        Err(e) => panic!("cannot build the air group: {e}"),
    }
}

fn force_pass(c: &mut Criterion) {
    let cloth = cloth();
    // A rippled cloth moving a little, so every triangle has its own normal and velocity.
    let x: Vec<[f64; 3]> = cloth
        .rest
        .iter()
        .map(|p| [p[0], p[1], 0.05 * (12.0 * p[0]).sin() * (7.0 * p[1]).cos()])
        .collect();
    let v0: Vec<[f64; 3]> = cloth
        .rest
        .iter()
        .map(|p| [0.0, 0.0, 0.3 * (9.0 * p[0] + 4.0 * p[1]).sin()])
        .collect();
    let mut state = CoreState::at_rest(x, cloth.inv_mass.clone(), 1.0 / 600.0);
    state.v.clone_from(&v0);
    state.time = 0.25;
    state.gravity = [0.0, -9.81, 0.0];

    let mut bench = c.benchmark_group("air");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (name, params) in [
        (
            "force_steady",
            r#"{"drag": 0.1, "lift": 0.3, "tangential_drag": 0.1, "wind_speed": 10}"#,
        ),
        (
            "force_gusty",
            r#"{"drag": 0.1, "lift": 0.3, "tangential_drag": 0.1, "wind_speed": 10, "noise": 3}"#,
        ),
    ] {
        let mut g = group(&cloth, params);
        bench.throughput(Throughput::Elements(g.constraint_count()));
        let mut ctx = state.ctx();
        bench.bench_function(name, |b| {
            b.iter(|| black_box(g.force(black_box(&mut ctx))).is_ok())
        });
        state.v.clone_from(&v0);
    }
    bench.finish();
}

criterion_group!(benches, force_pass);
criterion_main!(benches);
