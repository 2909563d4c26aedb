//! The hot loops: one `project` pass of each kind, called through the ABI trait object exactly
//! as the host calls it, over a 128 × 128 cloth (32,258 triangles, 48,005 hinges, 96,774
//! corners) and a 16,384-segment helical rope (16,383 joints, 16,382 twist chains). Criterion
//! reports constraints per second; ns per constraint per pass is its inverse. The pass runs on
//! a thread team of `RAYON_NUM_THREADS` (default: the machine's cores), lent to the context as
//! the host lends its own (as `stretch`'s benchmark does).
//!
//! `cargo bench -p nucleus-bend --bench bend`

use std::collections::BTreeMap;
use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use nucleus_sdk::abi_stable::std_types::RSlice;
use nucleus_sdk::prelude::*;
use nucleus_sdk::testing::CoreState;
use nucleus_sdk::{EdgePair, GroupBox, TrianglePair};

/// Vertices per side of the cloth.
const N: u32 = 128;
/// Segments of the rope.
const SEGMENTS: u32 = 16_384;

struct Shape {
    rest: Vec<[f64; 3]>,
    inv_mass: Vec<f64>,
    triangles: Vec<[u32; 3]>,
    pairs: Vec<TrianglePair>,
    edge_pairs: Vec<EdgePair>,
}

/// One triangle at an edge: its index, the edge as its winding runs, its third vertex.
type Side = (u32, [u32; 2], u32);

/// A 1 m square cloth of N × N vertices, two triangles per quad, and its hinges.
fn cloth() -> Shape {
    let spacing = 1.0 / (N - 1) as f64;
    let rest = (0..N * N)
        .map(|k| [(k % N) as f64 * spacing, 0.0, (k / N) as f64 * spacing])
        .collect();
    let mut triangles = Vec::new();
    for r in 0..N - 1 {
        for c in 0..N - 1 {
            let a = r * N + c;
            triangles.push([a, a + 1, a + N + 1]);
            triangles.push([a, a + N + 1, a + N]);
        }
    }
    // Hinges: the two triangles of every interior edge, the edge oriented by the first.
    let mut by_edge: BTreeMap<[u32; 2], Vec<Side>> = BTreeMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for s in 0..3 {
            let (i, j, k) = (tri[s], tri[(s + 1) % 3], tri[(s + 2) % 3]);
            by_edge
                .entry([i.min(j), i.max(j)])
                .or_default()
                .push((t as u32, [i, j], k));
        }
    }
    let pairs = by_edge
        .values()
        .filter(|v| v.len() == 2)
        .map(|v| TrianglePair {
            triangles: [v[0].0, v[1].0],
            edge: v[0].1,
            opposite: [v[0].2, v[1].2],
        })
        .collect();
    Shape {
        rest,
        inv_mass: vec![1.0; (N * N) as usize],
        triangles,
        pairs,
        edge_pairs: Vec::new(),
    }
}

/// A helix of SEGMENTS edges, 16 segments per turn.
fn rope() -> Shape {
    let rest = (0..=SEGMENTS)
        .map(|k| {
            let t = k as f64 * std::f64::consts::TAU / 16.0;
            [0.1 * t.cos(), 0.002 * k as f64, 0.1 * t.sin()]
        })
        .collect();
    Shape {
        rest,
        inv_mass: vec![1.0; SEGMENTS as usize + 1],
        triangles: Vec::new(),
        pairs: Vec::new(),
        edge_pairs: (1..SEGMENTS)
            .map(|k| EdgePair {
                vertices: [k - 1, k, k + 1],
            })
            .collect(),
    }
}

fn group(shape: &Shape, kind: &str, params: &str) -> GroupBox {
    let objects = [ObjectView {
        triangles: RSlice::from_slice(&shape.triangles),
        triangle_pairs: RSlice::from_slice(&shape.pairs),
        edge_pairs: RSlice::from_slice(&shape.edge_pairs),
        ..ObjectView::new("shape", 0, shape.rest.len() as u32)
    }];
    let scene = SceneView {
        gravity: [0.0, -9.81, 0.0],
        substeps: 10,
        ..SceneView::new(&objects, &[0], &shape.rest, &shape.inv_mass)
    };
    match nucleus_bend::nucleus_plugin().create_group(kind, params, &scene) {
        Ok(g) => g,
        Err(e) => panic!("cannot build the {kind} group: {e}"),
    }
}

fn project_pass(c: &mut Criterion) {
    let cases = [
        ("cloth", cloth(), "bend", "dihedral_bend"),
        ("cloth", cloth(), "bend_isometric", "isometric_bend"),
        ("cloth", cloth(), "shear", "shear"),
        ("rope", rope(), "bend", "curve_bend"),
        ("rope", rope(), "twist", "twist"),
    ];
    let team = nucleus_sdk::team::Team::new(nucleus_sdk::team::configured_threads() - 1);
    let mut bench = c.benchmark_group("bend");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (what, shape, kind, name) in &cases {
        // Deformed so that every constraint does real work: a ripple across the cloth, a
        // stretched and wobbling coil.
        let x: Vec<[f64; 3]> = shape
            .rest
            .iter()
            .enumerate()
            .map(|(k, p)| match *what {
                "cloth" => [p[0], 0.02 * (9.0 * p[0]).sin() * (7.0 * p[2]).cos(), p[2]],
                _ => [
                    p[0] * 1.05,
                    p[1] * 1.2,
                    p[2] + 0.01 * (k as f64 * 0.3).sin(),
                ],
            })
            .collect();
        let mut state = CoreState::at_rest(x, shape.inv_mass.clone(), 1.0 / 600.0);
        state.gravity = [0.0, -9.81, 0.0];
        let mut g = group(shape, kind, r#"{"compliance": 1e-2}"#);
        bench.throughput(Throughput::Elements(g.constraint_count()));
        let mut ctx = SolveContext {
            team: nucleus_sdk::TeamRef::new(&team),
            ..state.ctx()
        };
        if let Err(e) = g.begin_substep(&mut ctx).into_result() {
            panic!("begin_substep failed: {e}");
        }
        bench.bench_function(*name, |b| {
            b.iter(|| black_box(g.project(black_box(&mut ctx))).is_ok())
        });
    }
    bench.finish();
}

criterion_group!(benches, project_pass);
criterion_main!(benches);
