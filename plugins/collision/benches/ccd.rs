//! Narrow-phase CCD speed: the 1,240 reference queries of `tests/data/ccd/` (zero thickness),
//! each file on its own, and the common case of a broad-phase candidate whose swept boxes are
//! apart. Criterion reports queries per second; ns per query is its inverse.
//!
//! `cargo bench -p nucleus-collision --bench ccd`

use std::path::PathBuf;
use std::time::Duration;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use nucleus_collision::narrow_phase::ccd::{edge_edge_toi, point_triangle_toi};

/// `(point–triangle?, start, end)` of every query of one file of the reference set.
fn load(name: &str) -> Vec<(bool, [DVec3; 4], [DVec3; 4])> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/ccd")
        .join(name);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let num = |k: usize| -> f64 {
                f[k].parse()
                    .unwrap_or_else(|e| panic!("{name}: field {k}: {e}"))
            };
            let v = |k: usize| DVec3::new(num(k), num(k + 1), num(k + 2));
            (
                f[0] == "pt",
                [v(1), v(4), v(7), v(10)],
                [v(13), v(16), v(19), v(22)],
            )
        })
        .collect()
}

fn run(queries: &[(bool, [DVec3; 4], [DVec3; 4])], thickness: f64) -> usize {
    queries
        .iter()
        .filter(|(pt, [x0, x1, x2, x3], [y0, y1, y2, y3])| {
            let (x0, x1, x2, x3) = (*x0, *x1, *x2, *x3);
            let (y0, y1, y2, y3) = (*y0, *y1, *y2, *y3);
            if *pt {
                point_triangle_toi(x0, x1, x2, x3, y0, y1, y2, y3, thickness).is_some()
            } else {
                edge_edge_toi(x0, x1, x2, x3, y0, y1, y2, y3, thickness).is_some()
            }
        })
        .count()
}

fn reference_set(c: &mut Criterion) {
    let files = [
        "benchmark_pt.csv",
        "benchmark_ee.csv",
        "generated_pt.csv",
        "generated_ee.csv",
    ];
    let all: Vec<_> = files.iter().flat_map(|f| load(f)).collect();
    let mut group = c.benchmark_group("ccd");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    group.throughput(Throughput::Elements(all.len() as u64));
    group.bench_function("reference_all_1240", |b| {
        b.iter(|| black_box(run(black_box(&all), 0.0)))
    });
    for name in files {
        let queries = load(name);
        group.throughput(Throughput::Elements(queries.len() as u64));
        group.bench_function(name.trim_end_matches(".csv"), |b| {
            b.iter(|| black_box(run(black_box(&queries), 0.0)))
        });
    }
    // The common case: a broad-phase candidate whose swept boxes (inflated by the
    // thickness) are apart. 1,000 point–triangle and edge–edge pairs, 1 mm thick.
    let apart: Vec<_> = all
        .iter()
        .enumerate()
        .take(1000)
        .map(|(i, (pt, x, y))| {
            let extent = x
                .iter()
                .chain(y)
                .map(|p| p.abs().max_element())
                .fold(0.0, f64::max);
            let shift = DVec3::new(0.0, 0.0, 2.0 * extent + 1.0 + i as f64 * 1e-3);
            let mut y = *y;
            y[0] += shift;
            let mut x = *x;
            x[0] += shift;
            if !*pt {
                x[1] += shift;
                y[1] += shift;
            }
            (*pt, x, y)
        })
        .collect();
    assert_eq!(run(&apart, 1e-3), 0, "the shifted pairs should be apart");
    group.throughput(Throughput::Elements(apart.len() as u64));
    group.bench_function("swept_boxes_apart", |b| {
        b.iter(|| black_box(run(black_box(&apart), 1e-3)))
    });
    group.finish();
}

criterion_group!(benches, reference_set);
criterion_main!(benches);
