//! The hot loop: one `project` pass of the `stretch` group over every edge of a 128 × 128
//! cloth (48,641 distance constraints), called through the ABI trait object exactly as the
//! host calls it. Criterion reports constraints per second; ns per constraint is its inverse.
//! The pass runs on a thread team of `RAYON_NUM_THREADS` (default: the machine's cores), lent
//! to the context as the host lends its own. `project_hard_stars` is the same pass with a star
//! at every particle (`blocks = "stars"`): the same constraints, each solved twice.
//! `project_newton` is one pass of the `stretch_newton` group over the same cloth — one Newton
//! step: assembly, Galerkin update of the multigrid, four preconditioned CG iterations
//! (`cg_tolerance = 0`, so never fewer) and the line search, in the setting the README's
//! part 6 measures (compliance 1e-6, `plain_levels = 1`) — from the same stretched state
//! every time (the positions are copied back before each pass, ~20 µs of the figure).
//! `project_tether` and `project_hierarchy` are one pass of the `tether` group (two tethers a
//! particle, to the two corners of the first row, pinned for them; taut, since the cloth is
//! stretched) and of the `stretch_hierarchy` group (straight lengths) over the same cloth;
//! Criterion's elements are their constraints (tethers; coarse edges).

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
    edges: Vec<[u32; 2]>,
    triangles: Vec<[u32; 3]>,
}

/// A 1 m square of N × N particles, each quad split into two triangles, with every edge of
/// the triangles (2·N·(N−1) axis-aligned edges and (N−1)² diagonals).
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
    let mut edges: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    Cloth {
        rest,
        inv_mass: vec![1.0; (N * N) as usize],
        edges,
        triangles,
    }
}

fn group(cloth: &Cloth, kind: &str, params: &str) -> GroupBox {
    let objects = [ObjectView {
        edges: RSlice::from_slice(&cloth.edges),
        triangles: RSlice::from_slice(&cloth.triangles),
        ..ObjectView::new("cloth", 0, N * N)
    }];
    let scene = SceneView {
        gravity: [0.0, 0.0, -9.81],
        frame_dt: 1.0 / 24.0,
        substeps: 10,
        ..SceneView::new(&objects, &[0], &cloth.rest, &cloth.inv_mass)
    };
    match nucleus_stretch::nucleus_plugin().create_group(kind, params, &scene) {
        Ok(g) => g,
        Err(e) => panic!("cannot build the {kind} group: {e}"),
    }
}

fn project_pass(c: &mut Criterion) {
    let (cloth, mut pinned) = (cloth(), cloth());
    pinned.inv_mass[0] = 0.0;
    pinned.inv_mass[N as usize - 1] = 0.0;
    // Stretched by 5 % with a ripple in z, so every constraint does real work.
    let x: Vec<[f64; 3]> = cloth
        .rest
        .iter()
        .map(|p| [1.05 * p[0], 1.05 * p[1], 0.01 * (20.0 * p[0]).sin()])
        .collect();
    let mut state = CoreState::at_rest(x, cloth.inv_mass.clone(), 1.0 / 240.0);
    state.x0.clone_from(&cloth.rest);
    state.gravity = [0.0, 0.0, -9.81];

    let team = nucleus_sdk::team::Team::new(nucleus_sdk::team::configured_threads() - 1);
    let mut bench = c.benchmark_group("stretch");
    bench
        .sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    // `restart`: the positions are copied back before every pass (the Newton pass, from the
    // state the stretch passes before it left); otherwise each pass continues from the last.
    for (name, kind, params, restart) in [
        ("project_hard", "stretch", "{}", false),
        (
            "project_soft_damped",
            "stretch",
            r#"{"compliance": 1e-6, "compression_compliance": 1e-3, "damping": 1}"#,
            false,
        ),
        (
            "project_hard_stars",
            "stretch",
            r#"{"blocks": "stars"}"#,
            false,
        ),
        (
            "project_newton",
            "stretch_newton",
            r#"{"cg_tolerance": 0, "cg_iterations": 4, "compliance": 1e-6,
                "compression_compliance": 1e-6, "plain_levels": 1}"#,
            true,
        ),
        ("project_tether", "tether", "{}", false),
        (
            "project_hierarchy",
            "stretch_hierarchy",
            r#"{"straight_lengths": true}"#,
            false,
        ),
    ] {
        let start = state.x.clone();
        let mut g = match kind {
            // Tethers and the hierarchy's coarse masses start from pins.
            "tether" | "stretch_hierarchy" => group(&pinned, kind, params),
            _ => group(&cloth, kind, params),
        };
        bench.throughput(Throughput::Elements(g.constraint_count()));
        let mut ctx = SolveContext {
            team: nucleus_sdk::TeamRef::new(&team),
            ..state.ctx()
        };
        if let Err(e) = g.begin_substep(&mut ctx).into_result() {
            panic!("begin_substep failed: {e}");
        }
        bench.bench_function(name, |b| {
            b.iter(|| {
                if restart {
                    ctx.x.as_mut_slice().copy_from_slice(&start);
                }
                black_box(g.project(black_box(&mut ctx))).is_ok()
            })
        });
    }
    bench.finish();
}

criterion_group!(benches, project_pass);
criterion_main!(benches);
