//! Fast projection (Goldenthal et al. 2007) on the peers' drape: the stretch constraints of
//! every edge solved together by Newton's method on the multipliers, each iteration one
//! sparse Cholesky factorization of `J W Jᵀ` (faer, AMD ordering) and one solve.
//!
//! Usage: `cargo run --release -- N SUBSTEPS NEWTON [--gs PASSES] [--quads] [--line-search]
//! [--regularize EPS] [--trace]`
//!
//! Per substep: gravity, prediction, `PASSES` sequential Gauss-Seidel passes over the edges
//! (a starting guess), then `NEWTON` iterations of `(J W Jᵀ + ε diag) Δλ = −C`,
//! `x += W Jᵀ Δλ` (with `--line-search`, the step is halved until `Σ C²` falls), then the
//! PBD velocity update. `--quads` keeps only the grid-aligned edges (Goldenthal's quad
//! mesh, no diagonals). Prints the time per frame, the factorization and solve times, and
//! the peers' strain metrics (structural edges, per-frame max and RMS averaged over the last
//! 60 of 120 frames).

use dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{MatMut, Par, Side};
use glam::DVec3;
use std::time::Instant;

struct Options {
    n: usize,
    substeps: usize,
    newton: usize,
    gs: usize,
    quads: bool,
    line_search: bool,
    eps: f64,
    trace: bool,
}

fn options() -> Result<Options, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: cargo run --release -- N SUBSTEPS NEWTON [--gs PASSES] [--quads] [--line-search] [--regularize EPS] [--trace]";
    let num = |k: usize| -> Result<usize, String> {
        args.get(k).and_then(|s| s.parse().ok()).ok_or_else(|| usage.to_string())
    };
    let mut o = Options {
        n: num(0)?,
        substeps: num(1)?,
        newton: num(2)?,
        gs: 0,
        quads: false,
        line_search: false,
        eps: 1e-8,
        trace: false,
    };
    let mut k = 3;
    while k < args.len() {
        match args[k].as_str() {
            "--gs" => {
                o.gs = num(k + 1)?;
                k += 1;
            }
            "--regularize" => {
                o.eps = args.get(k + 1).and_then(|s| s.parse().ok()).ok_or(usage)?;
                k += 1;
            }
            "--quads" => o.quads = true,
            "--line-search" => o.line_search = true,
            "--trace" => o.trace = true,
            _ => return Err(usage.into()),
        }
        k += 1;
    }
    if o.n < 3 || o.substeps == 0 {
        return Err(usage.into());
    }
    Ok(o)
}

fn main() {
    let o = options().unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let n = o.n;
    let spacing = 1.0 / (n - 1) as f64;
    let nv = n * n;
    let idx = |i: usize, j: usize| i * n + j;
    // Vertex (i, j) at (j h, 0, i h); the corners of row 0 pinned; 1 kg in all.
    let mut x: Vec<DVec3> = (0..nv)
        .map(|k| DVec3::new((k % n) as f64 * spacing, 0.0, (k / n) as f64 * spacing))
        .collect();
    let mut w = vec![nv as f64; nv];
    w[idx(0, 0)] = 0.0;
    w[idx(0, n - 1)] = 0.0;
    let mut edges: Vec<[usize; 2]> = Vec::new();
    let mut structural = Vec::new();
    for i in 0..n {
        for j in 0..n {
            if j + 1 < n {
                structural.push(edges.len());
                edges.push([idx(i, j), idx(i, j + 1)]);
            }
            if i + 1 < n {
                structural.push(edges.len());
                edges.push([idx(i, j), idx(i + 1, j)]);
            }
            if !o.quads && i + 1 < n && j + 1 < n {
                edges.push([idx(i, j), idx(i + 1, j + 1)]);
            }
        }
    }
    let ne = edges.len();
    let rest: Vec<f64> = edges.iter().map(|e| (x[e[0]] - x[e[1]]).length()).collect();

    // The pattern of J W Jᵀ (lower triangle, one column per edge): edges p and q couple
    // through each shared particle v with s_p s_q w_v n_p·n_q (s = +1 at the first end).
    let mut incident: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nv];
    for (e, &[a, b]) in edges.iter().enumerate() {
        incident[a].push((e, 1.0));
        incident[b].push((e, -1.0));
    }
    let mut columns: Vec<Vec<usize>> = (0..ne).map(|e| vec![e]).collect();
    for l in &incident {
        for &(p, _) in l {
            for &(q, _) in l {
                if p > q {
                    columns[q].push(p);
                }
            }
        }
    }
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for c in &mut columns {
        c.sort_unstable();
        c.dedup();
        row_idx.extend_from_slice(c);
        col_ptr.push(row_idx.len());
    }
    let slot = |r: usize, c: usize| {
        let rows = &row_idx[col_ptr[c]..col_ptr[c + 1]];
        col_ptr[c] + rows.binary_search(&r).expect("in the pattern")
    };
    let diagonal: Vec<usize> = (0..ne).map(|e| slot(e, e)).collect();
    // (slot, p, s_p s_q, q, v)
    let mut couplings = Vec::new();
    for (v, l) in incident.iter().enumerate() {
        for &(p, sp) in l {
            for &(q, sq) in l {
                if p > q {
                    couplings.push((slot(p, q), p, sp * sq, q, v));
                }
            }
        }
    }
    let pattern = SymbolicSparseColMatRef::new_checked(ne, ne, &col_ptr, None, &row_idx);
    let t = Instant::now();
    let symbolic = factorize_symbolic_cholesky(
        pattern,
        Side::Lower,
        SymmetricOrdering::Amd,
        Default::default(),
    )
    .expect("symbolic factorization");
    println!(
        "N = {n}: {ne} edges, {} non-zeros in the lower triangle of J W J^T, {} in its factor; symbolic analysis {:.1} ms",
        row_idx.len(),
        symbolic.len_val(),
        t.elapsed().as_secs_f64() * 1e3
    );
    let par = Par::Seq;
    let mut factor = vec![0.0f64; symbolic.len_val()];
    let mut factor_mem =
        MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
    let mut solve_mem = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, par));
    let mut values = vec![0.0f64; row_idx.len()];
    let mut normal = vec![DVec3::ZERO; ne];
    let mut rhs = vec![0.0f64; ne];
    let mut v = vec![DVec3::ZERO; nv];
    let mut start = vec![DVec3::ZERO; nv];
    let mut trial = vec![DVec3::ZERO; nv];
    let g = DVec3::new(0.0, -9.81, 0.0);
    let h = 1.0 / 60.0 / o.substeps as f64;
    let (mut t_factor, mut t_solve, mut factorizations) = (0.0, 0.0, 0usize);
    let (mut strain_max, mut strain_rms) = (0.0, 0.0);
    let sum_c2 = |x: &[DVec3]| -> f64 {
        edges
            .iter()
            .zip(&rest)
            .map(|(&[a, b], &l)| {
                let c = (x[a] - x[b]).length() - l;
                c * c
            })
            .sum()
    };
    let run = Instant::now();
    for frame in 0..120 {
        for _ in 0..o.substeps {
            start.copy_from_slice(&x);
            for k in 0..nv {
                if w[k] > 0.0 {
                    v[k] += h * g;
                    x[k] += h * v[k];
                }
            }
            for _ in 0..o.gs {
                for (&[a, b], &l) in edges.iter().zip(&rest) {
                    let (ws, d) = (w[a] + w[b], x[a] - x[b]);
                    let len = d.length();
                    if ws > 0.0 && len > 1e-12 {
                        let s = (len - l) / ws * (d / len);
                        x[a] -= w[a] * s;
                        x[b] += w[b] * s;
                    }
                }
            }
            for it in 0..o.newton {
                for (e, &[a, b]) in edges.iter().enumerate() {
                    let d = x[a] - x[b];
                    let len = d.length();
                    normal[e] = d / len;
                    rhs[e] = -(len - rest[e]);
                }
                let t = Instant::now();
                values.fill(0.0);
                for (e, &[a, b]) in edges.iter().enumerate() {
                    values[diagonal[e]] = (w[a] + w[b]) * (1.0 + o.eps);
                }
                for &(s, p, sign, q, vtx) in &couplings {
                    values[s] = sign * w[vtx] * normal[p].dot(normal[q]);
                }
                let a = SparseColMatRef::new(pattern, &values);
                let no_regularization = LltRegularization {
                    dynamic_regularization_delta: 0.0,
                    dynamic_regularization_epsilon: 0.0,
                };
                if let Err(e) = symbolic.factorize_numeric_llt::<f64>(
                    &mut factor,
                    a,
                    Side::Lower,
                    no_regularization,
                    par,
                    MemStack::new(&mut factor_mem),
                    Default::default(),
                ) {
                    eprintln!("frame {frame}: J W J^T is not positive definite ({e:?})");
                    std::process::exit(1);
                }
                t_factor += t.elapsed().as_secs_f64();
                factorizations += 1;
                let t = Instant::now();
                LltRef::<usize, f64>::new(&symbolic, &factor).solve_in_place_with_conj(
                    faer::Conj::No,
                    MatMut::from_column_major_slice_mut(&mut rhs, ne, 1),
                    par,
                    MemStack::new(&mut solve_mem),
                );
                t_solve += t.elapsed().as_secs_f64();
                let before = sum_c2(&x);
                let mut step = 1.0;
                loop {
                    trial.copy_from_slice(&x);
                    for (e, &[a, b]) in edges.iter().enumerate() {
                        let dl = step * rhs[e];
                        trial[a] += w[a] * dl * normal[e];
                        trial[b] -= w[b] * dl * normal[e];
                    }
                    if !o.line_search || sum_c2(&trial) < before || step < 1e-3 {
                        break;
                    }
                    step *= 0.5;
                }
                if o.trace && frame % 20 == 0 {
                    println!(
                        "frame {frame} iteration {it}: step {step}, sum C^2 {before:.3e} -> {:.3e}",
                        sum_c2(&trial)
                    );
                }
                x.copy_from_slice(&trial);
            }
            for k in 0..nv {
                v[k] = (x[k] - start[k]) / h;
            }
        }
        if frame >= 60 {
            let (mut max, mut sq) = (0.0f64, 0.0);
            for &e in &structural {
                let [a, b] = edges[e];
                let s = ((x[a] - x[b]).length() / rest[e] - 1.0).abs();
                max = max.max(s);
                sq += s * s;
            }
            strain_max += max / 60.0;
            strain_rms += (sq / structural.len() as f64).sqrt() / 60.0;
        }
    }
    let wall = run.elapsed().as_secs_f64();
    let per = |t: f64, k: usize| if k == 0 { 0.0 } else { t / k as f64 * 1e3 };
    println!(
        "{:.2} ms/frame; factorization {:.2} ms each ({factorizations}), solve {:.2} ms each; strain max {:.4} %, RMS {:.4} %; lowest y {:.3} m",
        wall / 120.0 * 1e3,
        per(t_factor, factorizations),
        per(t_solve, factorizations),
        strain_max * 100.0,
        strain_rms * 100.0,
        x.iter().map(|p| p.y).fold(0.0, f64::min)
    );
}
