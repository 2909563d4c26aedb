//! The drape's stretch constraints with an exact, linear-time solve on a spanning forest of the
//! mesh rooted at the pins (Baraff 1996's sparse elimination of the KKT system of a tree), in
//! turn with Gauss-Seidel passes over every edge. The forest is the shortest-path forest from
//! the pins (the paths tethers follow): the load reaches the pins along it in one solve, where a
//! Gauss-Seidel pass carries it a few edges.
//!
//! Usage: `cargo run --release -- N SUBSTEPS PASSES [--tree K] [--tree-last]`
//!
//! Per substep: gravity, prediction, then `PASSES` times: `K` tree solves (default 0: plain
//! Gauss-Seidel) and one Gauss-Seidel pass over every edge in index order; with `--tree-last`
//! the tree solves come after the pass. Prints the time per frame and the peers' strain
//! metrics (structural edges, per-frame max and RMS averaged over the last 60 of 120 frames).

use glam::DVec3;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Instant;

struct Options {
    n: usize,
    substeps: usize,
    passes: usize,
    tree: usize,
    tree_last: bool,
}

fn options() -> Result<Options, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: cargo run --release -- N SUBSTEPS PASSES [--tree K] [--tree-last]";
    let num = |k: usize| -> Result<usize, String> {
        args.get(k)
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| usage.to_string())
    };
    let mut o = Options {
        n: num(0)?,
        substeps: num(1)?,
        passes: num(2)?,
        tree: 0,
        tree_last: false,
    };
    let mut k = 3;
    while k < args.len() {
        match args[k].as_str() {
            "--tree" => {
                o.tree = num(k + 1)?;
                k += 1;
            }
            "--tree-last" => o.tree_last = true,
            _ => return Err(usage.into()),
        }
        k += 1;
    }
    if o.n < 3 || o.substeps == 0 {
        return Err(usage.into());
    }
    Ok(o)
}

/// A symmetric 3 × 3 matrix `[xx, yy, zz, xy, xz, yz]`.
#[derive(Clone, Copy, Default)]
struct Sym([f64; 6]);

impl Sym {
    fn scaled_identity(s: f64) -> Sym {
        Sym([s, s, s, 0.0, 0.0, 0.0])
    }
    /// `self + s n nᵀ`.
    fn add_outer(&mut self, n: DVec3, s: f64) {
        let m = &mut self.0;
        m[0] += s * n.x * n.x;
        m[1] += s * n.y * n.y;
        m[2] += s * n.z * n.z;
        m[3] += s * n.x * n.y;
        m[4] += s * n.x * n.z;
        m[5] += s * n.y * n.z;
    }
    /// The inverse (the matrix is symmetric positive definite here).
    fn inverse(&self) -> Sym {
        let [a, d, f, b, c, e] = self.0; // [[a b c] [b d e] [c e f]]
        let (c00, c01, c02) = (d * f - e * e, c * e - b * f, b * e - c * d);
        let det = a * c00 + b * c01 + c * c02;
        let r = 1.0 / det;
        Sym([
            c00 * r,
            (a * f - c * c) * r,
            (a * d - b * b) * r,
            c01 * r,
            c02 * r,
            (b * c - a * e) * r,
        ])
    }
    fn mul(&self, v: DVec3) -> DVec3 {
        let m = &self.0;
        DVec3::new(
            m[0] * v.x + m[3] * v.y + m[4] * v.z,
            m[3] * v.x + m[1] * v.y + m[5] * v.z,
            m[4] * v.x + m[5] * v.y + m[2] * v.z,
        )
    }
}

/// The shortest-path forest from the pins: every free vertex's parent and the rest length of
/// the edge to it, and the free vertices in an order where parents come first.
struct Forest {
    parent: Vec<u32>,
    rest: Vec<f64>,
    order: Vec<u32>,
    /// Scratch, one per vertex: `D_v` (then its inverse), `b_v`, the tree edge's direction,
    /// `D_e`, `b_e`.
    d: Vec<Sym>,
    b: Vec<DVec3>,
    n: Vec<DVec3>,
    de: Vec<f64>,
    be: Vec<f64>,
    dx: Vec<DVec3>,
}

const NONE: u32 = u32::MAX;

impl Forest {
    fn new(x: &[DVec3], w: &[f64], edges: &[[usize; 2]]) -> Forest {
        let nv = x.len();
        let mut adjacent: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nv];
        for &[a, b] in edges {
            let l = (x[a] - x[b]).length();
            adjacent[a].push((b, l));
            adjacent[b].push((a, l));
        }
        let mut dist = vec![f64::INFINITY; nv];
        let mut parent = vec![NONE; nv];
        let mut rest = vec![0.0; nv];
        let mut heap = BinaryHeap::new();
        for v in 0..nv {
            if w[v] == 0.0 {
                dist[v] = 0.0;
                heap.push(Reverse((0u64, v)));
            }
        }
        let mut order = Vec::with_capacity(nv);
        let mut done = vec![false; nv];
        while let Some(Reverse((_, v))) = heap.pop() {
            if std::mem::replace(&mut done[v], true) {
                continue;
            }
            if w[v] > 0.0 {
                order.push(v as u32);
            }
            for &(u, l) in &adjacent[v] {
                let du = dist[v] + l;
                if w[u] > 0.0 && du < dist[u] - 1e-12 {
                    dist[u] = du;
                    parent[u] = v as u32;
                    rest[u] = l;
                    heap.push(Reverse(((du * 1e12) as u64, u)));
                }
            }
        }
        Forest {
            parent,
            rest,
            order,
            d: vec![Sym::default(); nv],
            b: vec![DVec3::ZERO; nv],
            n: vec![DVec3::ZERO; nv],
            de: vec![0.0; nv],
            be: vec![0.0; nv],
            dx: vec![DVec3::ZERO; nv],
        }
    }

    /// One Newton step on the forest's constraints, exact for their linearisation:
    /// `M Δx = Jᵀ Δλ`, `J Δx = −C`, by elimination from the leaves and substitution from the
    /// roots.
    fn solve(&mut self, x: &mut [DVec3], w: &[f64]) {
        for &v in &self.order {
            let v = v as usize;
            self.d[v] = Sym::scaled_identity(1.0 / w[v]);
            self.b[v] = DVec3::ZERO;
            let e = x[v] - x[self.parent[v] as usize];
            let len = e.length();
            self.n[v] = e / len;
            self.be[v] = len - self.rest[v];
        }
        // Leaves first: eliminate v into its edge, the edge into the parent vertex.
        for &v in self.order.iter().rev() {
            let v = v as usize;
            let inv = self.d[v].inverse();
            self.d[v] = inv;
            let n = self.n[v];
            let dn = inv.mul(n);
            let de = -n.dot(dn);
            let be = self.be[v] + dn.dot(self.b[v]);
            self.de[v] = de;
            self.be[v] = be;
            let p = self.parent[v] as usize;
            if w[p] > 0.0 {
                self.d[p].add_outer(n, -1.0 / de);
                self.b[p] -= n * (be / de);
            }
        }
        // Roots first: the edge's multiplier, then the vertex's displacement.
        for &v in &self.order {
            let v = v as usize;
            let p = self.parent[v] as usize;
            let n = self.n[v];
            let dxp = if w[p] > 0.0 { self.dx[p] } else { DVec3::ZERO };
            let dl = (self.be[v] - n.dot(dxp)) / self.de[v];
            self.dx[v] = self.d[v].mul(self.b[v] + n * dl);
        }
        for &v in &self.order {
            x[v as usize] += self.dx[v as usize];
        }
        if std::env::var("TREE_CHECK").is_ok() {
            let worst = self
                .order
                .iter()
                .map(|&v| {
                    let v = v as usize;
                    ((x[v] - x[self.parent[v] as usize]).length() / self.rest[v] - 1.0).abs()
                })
                .fold(0.0, f64::max);
            let before = self.be.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            eprintln!("tree strain after the solve: max {worst:.3e} (|b_e| max {before:.3e})");
        }
    }
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
            if i + 1 < n && j + 1 < n {
                edges.push([idx(i, j), idx(i + 1, j + 1)]);
            }
        }
    }
    let rest: Vec<f64> = edges
        .iter()
        .map(|e| (x[e[0]] - x[e[1]]).length())
        .collect();
    let mut forest = Forest::new(&x, &w, &edges);
    let mut v = vec![DVec3::ZERO; nv];
    let mut start = vec![DVec3::ZERO; nv];
    let g = DVec3::new(0.0, -9.81, 0.0);
    let h = 1.0 / 60.0 / o.substeps as f64;
    let (mut strain_max, mut strain_rms) = (0.0, 0.0);
    let (mut t_tree, mut t_gs) = (0.0, 0.0);
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
            for _ in 0..o.passes {
                if !o.tree_last {
                    let t = Instant::now();
                    for _ in 0..o.tree {
                        forest.solve(&mut x, &w);
                    }
                    t_tree += t.elapsed().as_secs_f64();
                }
                let t = Instant::now();
                // The stretch plugin's projection: along the edge's start-of-substep
                // direction when it turned by less than ~26° (SHAKE), else along the edge.
                for (&[a, b], &l) in edges.iter().zip(&rest) {
                    let (ws, d) = (w[a] + w[b], x[a] - x[b]);
                    let len = d.length();
                    if ws > 0.0 && len > 1e-12 {
                        let e0 = start[a] - start[b];
                        let len0 = e0.length();
                        let de = d.dot(e0);
                        let (u, du) = if len0 > 1e-12 && de >= 0.9 * len * len0 {
                            (e0, de)
                        } else {
                            (d, len * len)
                        };
                        let s = u * ((len - l) * len / (ws * du));
                        x[a] -= w[a] * s;
                        x[b] += w[b] * s;
                    }
                }
                t_gs += t.elapsed().as_secs_f64();
                if o.tree_last {
                    let t = Instant::now();
                    for _ in 0..o.tree {
                        forest.solve(&mut x, &w);
                    }
                    t_tree += t.elapsed().as_secs_f64();
                }
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
        if !x.iter().all(|p| p.is_finite()) {
            println!("frame {frame}: not finite");
            std::process::exit(1);
        }
    }
    let wall = run.elapsed().as_secs_f64();
    println!(
        "N = {n}, {} x {} (tree {}{}): {:.2} ms/frame (tree {:.2}, passes {:.2}); strain max {:.4} %, RMS {:.4} %; lowest y {:.3} m",
        o.substeps,
        o.passes,
        o.tree,
        if o.tree_last { ", last" } else { "" },
        wall / 120.0 * 1e3,
        t_tree / 120.0 * 1e3,
        t_gs / 120.0 * 1e3,
        strain_max * 100.0,
        strain_rms * 100.0,
        x.iter().map(|p| p.y).fold(0.0, f64::min)
    );
}
