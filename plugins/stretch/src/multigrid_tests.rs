//! Unit tests of the multigrid linear algebra: the block matrix against dense products, the
//! Galerkin coarse operators against explicit `Pᵀ A P`, the dense Cholesky factor, the
//! V-cycle's symmetry and PCG's convergence on a cloth-like "mass + stiff spring" Hessian.

use super::*;
use crate::hierarchy::coarsen;
use nucleus_sdk::team::Team;

/// No thread team: every job on the caller, as below [`PARALLEL_MIN_ROWS`].
fn serial() -> TeamRef<'static> {
    TeamRef::serial()
}

/// An edge graph by local index: `graph[a]` lists `(b, rest length)`.
type Graph = Vec<Vec<(u32, f64)>>;

/// xorshift64: deterministic pseudo-random numbers for the tests.
struct Rng(u64);

impl Rng {
    /// Uniform in [-1, 1).
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn vec3(&mut self) -> DVec3 {
        DVec3::new(self.next(), self.next(), self.next())
    }

    fn mat3(&mut self) -> DMat3 {
        DMat3::from_cols(self.vec3(), self.vec3(), self.vec3())
    }

    /// A random symmetric positive definite block `R Rᵀ + shift I`.
    fn spd3(&mut self, shift: f64) -> DMat3 {
        let r = self.mat3();
        r * r.transpose() + DMat3::IDENTITY * shift
    }

    fn vector(&mut self, n: usize) -> Vec<DVec3> {
        (0..n).map(|_| self.vec3()).collect()
    }
}

/// The matrix as a dense `3n × 3n` row-major array.
fn dense(a: &BlockMatrix) -> Vec<f64> {
    let m = 3 * a.n();
    let mut d = vec![0.0; m * m];
    for i in 0..a.n() {
        for s in a.start[i] as usize..a.start[i + 1] as usize {
            let j = a.col[s] as usize;
            for r in 0..3 {
                for c in 0..3 {
                    d[(3 * i + r) * m + 3 * j + c] = a.val[s].col(c)[r];
                }
            }
        }
    }
    d
}

/// Entry `e`'s block, built from its definition: `w I`, or `w S(r)` with column `k` of `S(r)`
/// the rotation `eₖ × r`.
fn entry_block(p: &Prolongation, e: usize) -> DMat3 {
    let w = p.weight[e];
    if p.turn[e] {
        let r = p.arm[e];
        DMat3::from_cols(DVec3::X.cross(r), DVec3::Y.cross(r), DVec3::Z.cross(r)) * w
    } else {
        DMat3::IDENTITY * w
    }
}

/// `P` as a dense `3 fine × 3 coarse` row-major array.
fn dense_prolongation(p: &Prolongation) -> Vec<f64> {
    let (rows, cols) = (3 * p.fine(), 3 * p.coarse);
    let mut d = vec![0.0; rows * cols];
    for i in 0..p.fine() {
        for e in p.start[i] as usize..p.start[i + 1] as usize {
            let b = entry_block(p, e);
            for r in 0..3 {
                for k in 0..3 {
                    d[(3 * i + r) * cols + 3 * p.col[e] as usize + k] += b.col(k)[r];
                }
            }
        }
    }
    d
}

/// `Aᵀ B` for row-major `a` (`r × ca`) and `b` (`r × cb`).
fn dense_tn(a: &[f64], b: &[f64], r: usize, ca: usize, cb: usize) -> Vec<f64> {
    let mut out = vec![0.0; ca * cb];
    for k in 0..r {
        for i in 0..ca {
            let aki = a[k * ca + i];
            if aki == 0.0 {
                continue;
            }
            for j in 0..cb {
                out[i * cb + j] += aki * b[k * cb + j];
            }
        }
    }
    out
}

/// `A B` for row-major `a` (`r × k`) and `b` (`k × c`).
fn dense_nn(a: &[f64], b: &[f64], r: usize, k: usize, c: usize) -> Vec<f64> {
    let mut out = vec![0.0; r * c];
    for i in 0..r {
        for l in 0..k {
            let ail = a[i * k + l];
            if ail == 0.0 {
                continue;
            }
            for j in 0..c {
                out[i * c + j] += ail * b[l * c + j];
            }
        }
    }
    out
}

/// `|b − A x| / |b|` for the hierarchy's fine matrix `A`.
fn relative_residual(h: &Hierarchy, b: &[DVec3], x: &[DVec3]) -> f64 {
    let mut ax = vec![DVec3::ZERO; b.len()];
    h.fine().mul(serial(), x, &mut ax);
    let r: Vec<DVec3> = b.iter().zip(&ax).map(|(p, q)| *p - *q).collect();
    norm(&r) / norm(b)
}

fn flat(v: &[DVec3]) -> Vec<f64> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

fn norm(v: &[DVec3]) -> f64 {
    dot(v, v).sqrt()
}

/// `a · b` summed row after row (the tests' reference; CG's own [`super::dot`] sums in chunks).
fn dot(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(*y)).sum()
}

#[test]
fn cg_dot_products_have_the_same_bits_on_any_team_and_the_row_sums_value() {
    let mut rng = Rng(11);
    let team = Team::new(1);
    let two = TeamRef::new(&team);
    assert_eq!(two.parts(), 2);
    for n in [1, DOT_CHUNK - 1, DOT_CHUNK, 3 * DOT_CHUNK + 17, 16_382] {
        let (a, b) = (rng.vector(n), rng.vector(n));
        let mut partial = vec![f64::NAN; n.div_ceil(DOT_CHUNK)];
        let on_one = super::dot(serial(), &a, &b, &mut partial);
        let on_two = super::dot(two, &a, &b, &mut partial);
        assert_eq!(on_one.to_bits(), on_two.to_bits(), "{n} rows");
        let rows = dot(&a, &b);
        let scale: f64 = a.iter().zip(&b).map(|(x, y)| x.abs().dot(y.abs())).sum();
        assert!(
            (on_one - rows).abs() <= 1e-14 * scale,
            "{n} rows: {on_one} against {rows}"
        );
        if n <= DOT_CHUNK {
            assert_eq!(on_one.to_bits(), rows.to_bits(), "{n} rows, one chunk");
        }
    }
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// The graph of an `n × n` grid of spacing `1/(n − 1)` with one diagonal per quad, its edge
/// pairs `(a, b)` with `a < b`, and the rest positions in the plane z = 0.
fn grid(n: u32) -> (Graph, Vec<(u32, u32)>, Vec<DVec3>) {
    let s = 1.0 / (n - 1) as f64;
    let pos: Vec<DVec3> = (0..n * n)
        .map(|k| DVec3::new((k % n) as f64 * s, (k / n) as f64 * s, 0.0))
        .collect();
    let mut pairs = Vec::new();
    for r in 0..n {
        for c in 0..n {
            let a = r * n + c;
            if c + 1 < n {
                pairs.push((a, a + 1));
            }
            if r + 1 < n {
                pairs.push((a, a + n));
            }
            if c + 1 < n && r + 1 < n {
                pairs.push((a, a + n + 1));
            }
        }
    }
    let mut graph: Graph = vec![Vec::new(); pos.len()];
    for &(a, b) in &pairs {
        let len = pos[a as usize].distance(pos[b as usize]);
        graph[a as usize].push((b, len));
        graph[b as usize].push((a, len));
    }
    (graph, pairs, pos)
}

/// The plain prolongations of `graph`'s coarsening, finest first, built as `newton.rs` builds
/// them with `rotations = false`.
fn prolongations(graph: &Graph, coarsest: usize) -> Vec<Prolongation> {
    let identity: Vec<u32> = (0..graph.len() as u32).collect();
    super::prolongations(&identity, &coarsen(graph, &[], 64, coarsest), false, 0)
}

/// The rigid prolongations of `graph`'s coarsening (`rotations = true`), lever arms fitted to
/// the particles' positions `x`.
fn rigid_prolongations(graph: &Graph, coarsest: usize, x: &[DVec3]) -> Vec<Prolongation> {
    rigid_past(graph, coarsest, x, 0)
}

/// The same with the first `plain` coarse levels translating only (`plain_levels`).
fn rigid_past(graph: &Graph, coarsest: usize, x: &[DVec3], plain: usize) -> Vec<Prolongation> {
    let identity: Vec<u32> = (0..graph.len() as u32).collect();
    let mut ps = super::prolongations(&identity, &coarsen(graph, &[], 64, coarsest), true, plain);
    ps.iter_mut().for_each(|p| p.refit(x));
    ps
}

/// A crumpled shape of `rest`: every position moved by a pseudo-random 0.3 m, so that lever
/// arms point every which way.
fn crumpled(rest: &[DVec3], rng: &mut Rng) -> Vec<DVec3> {
    rest.iter().map(|p| *p + rng.vec3() * 0.3).collect()
}

/// A random symmetric positive definite matrix on `pairs`: a random SPD diagonal block per
/// row ("mass") plus, per pair, a random SPD block `K` added as `[K −K; −K K]` ("spring").
fn random_spd(n: usize, pairs: &[(u32, u32)], rng: &mut Rng) -> BlockMatrix {
    let mut a = BlockMatrix::with_pattern(n, pairs.iter().copied());
    for i in 0..n {
        a.val[a.diag[i] as usize] = rng.spd3(0.1);
    }
    for &(i, j) in pairs {
        let k = rng.spd3(0.0) * 10.0;
        let (ii, jj) = (a.diag[i as usize] as usize, a.diag[j as usize] as usize);
        let (ij, ji) = (a.slot(i, j).unwrap(), a.slot(j, i).unwrap());
        a.val[ii] += k;
        a.val[jj] += k;
        a.val[ij] -= k;
        a.val[ji] -= k;
    }
    a
}

/// A cloth-like Newton Hessian: a `side × side` grid, 1 m and 1 kg, the two corners of row 0
/// pinned (not unknowns), stretched by 1 % with a pseudo-random 1 cm wobble out of the plane;
/// `M/h² + Σ k [n nᵀ + max(0, 1 − L/l)(I − n nᵀ)]` with h = 1/120 s and k = 1e8 N/m (the
/// kind's default compliance). Returns the hierarchy over it (coarsest 16, as the kind's
/// default; with rotations if `rigid`) with the fine values set but not updated. `folded`:
/// the half of the cloth beyond x = 0.5 is folded down by 90° (a crease along y).
fn cloth_hessian(side: u32, rigid: bool, folded: bool) -> Hierarchy {
    let (_, pairs, rest) = grid(side);
    let n = rest.len();
    let pinned = |i: u32| i == 0 || i == side - 1;
    let mut unknown = vec![u32::MAX; n];
    let mut count = 0u32;
    for (i, u) in unknown.iter_mut().enumerate() {
        if !pinned(i as u32) {
            *u = count;
            count += 1;
        }
    }
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let x: Vec<DVec3> = rest
        .iter()
        .map(|p| {
            let p = if folded && p.x > 0.5 {
                DVec3::new(0.5, p.y, 0.5 - p.x)
            } else {
                *p
            };
            p * 1.01 + DVec3::Z * 0.01 * rng.next()
        })
        .collect();
    let free_pairs: Vec<(u32, u32)> = pairs
        .iter()
        .map(|&(a, b)| (unknown[a as usize], unknown[b as usize]))
        .filter(|&(a, b)| a != u32::MAX && b != u32::MAX)
        .collect();
    let mut graph: Graph = vec![Vec::new(); count as usize];
    for &(a, b) in &pairs {
        let (ua, ub) = (unknown[a as usize], unknown[b as usize]);
        if ua != u32::MAX && ub != u32::MAX {
            let len = rest[a as usize].distance(rest[b as usize]);
            graph[ua as usize].push((ub, len));
            graph[ub as usize].push((ua, len));
        }
    }
    let mut a = BlockMatrix::with_pattern(count as usize, free_pairs);
    let (h, k) = (1.0 / 120.0, 1e8);
    let m = 1.0 / n as f64;
    for u in 0..count as usize {
        a.val[a.diag[u] as usize] = DMat3::IDENTITY * (m / (h * h));
    }
    for &(i, j) in &pairs {
        let d = x[j as usize] - x[i as usize];
        let l = d.length();
        let len = rest[i as usize].distance(rest[j as usize]);
        let nv = d / l;
        let nn = DMat3::from_cols(nv * nv.x, nv * nv.y, nv * nv.z);
        let block = (nn + (DMat3::IDENTITY - nn) * (1.0 - len / l).max(0.0)) * k;
        let (ua, ub) = (unknown[i as usize], unknown[j as usize]);
        for (p, q, b) in [
            (ua, ua, block),
            (ub, ub, block),
            (ua, ub, -block),
            (ub, ua, -block),
        ] {
            if p != u32::MAX && q != u32::MAX {
                let s = a.slot(p, q).unwrap();
                a.val[s] += b;
            }
        }
    }
    let ps = if rigid {
        let x_free: Vec<DVec3> = (0..n)
            .filter(|&i| unknown[i] != u32::MAX)
            .map(|i| x[i])
            .collect();
        rigid_prolongations(&graph, 16, &x_free)
    } else {
        prolongations(&graph, 16)
    };
    Hierarchy::new(a, ps)
}

#[test]
fn with_pattern_and_mul_match_a_dense_product() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let n = 23;
    // Duplicates, both orders and self pairs: the pattern holds each block once.
    let mut pairs = Vec::new();
    for _ in 0..60 {
        let i = ((rng.next() + 1.0) * 0.5 * n as f64) as u32 % n as u32;
        let j = ((rng.next() + 1.0) * 0.5 * n as f64) as u32 % n as u32;
        pairs.push((i, j));
    }
    pairs.push(pairs[0]);
    pairs.push((pairs[1].1, pairs[1].0));
    pairs.push((5, 5));
    let mut a = BlockMatrix::with_pattern(n, pairs.iter().copied());
    assert_eq!(a.n(), n);
    assert_eq!(a.start.len(), n + 1);
    assert_eq!(a.val.len(), a.col.len());
    for i in 0..n {
        let row = &a.col[a.start[i] as usize..a.start[i + 1] as usize];
        assert!(row.windows(2).all(|w| w[0] < w[1]), "row {i}: {row:?}");
        assert_eq!(a.col[a.diag[i] as usize], i as u32, "diagonal of row {i}");
    }
    // Arbitrary (non-symmetric) block values: the product must not assume symmetry.
    for v in a.val.iter_mut() {
        *v = rng.mat3();
    }
    let x = rng.vector(n);
    let mut y = vec![DVec3::splat(f64::NAN); n];
    a.mul(serial(), &x, &mut y);
    let d = dense(&a);
    let reference = dense_nn(&d, &flat(&x), 3 * n, 3 * n, 1);
    let err: Vec<f64> = flat(&y)
        .iter()
        .zip(&reference)
        .map(|(p, q)| p - q)
        .collect();
    let rel = max_abs(&err) / max_abs(&reference);
    assert!(rel < 1e-14, "relative error {rel:e}");
    // `zero` keeps the pattern.
    let cols = a.col.clone();
    a.zero();
    assert_eq!(a.col, cols);
    assert!(a.val.iter().all(|b| *b == DMat3::ZERO));
}

#[test]
fn slot_finds_every_pattern_pair_and_nothing_else() {
    let (_, pairs, _) = grid(6);
    let n = 36;
    let a = BlockMatrix::with_pattern(n, pairs.iter().copied());
    let mut expected: Vec<Vec<bool>> = (0..n).map(|i| (0..n).map(|j| i == j).collect()).collect();
    for &(i, j) in &pairs {
        expected[i as usize][j as usize] = true;
        expected[j as usize][i as usize] = true;
    }
    let mut found = 0;
    for (i, row) in expected.iter().enumerate() {
        for (j, &want) in row.iter().enumerate() {
            match a.slot(i as u32, j as u32) {
                Some(s) => {
                    assert!(want, "({i}, {j}) is not in the pattern but has slot {s}");
                    assert!((a.start[i] as usize..a.start[i + 1] as usize).contains(&s));
                    assert_eq!(a.col[s], j as u32);
                    found += 1;
                }
                None => assert!(!want, "({i}, {j}) is in the pattern but has no slot"),
            }
        }
    }
    // 36 diagonal blocks plus both triangles of every edge, and every slot found once.
    assert_eq!(found, n + 2 * pairs.len());
    assert_eq!(found, a.val.len());
    assert_eq!(a.slot(0, n as u32), None, "a column past the last");
}

/// `⟨P c, f⟩ = ⟨c, Pᵀ f⟩` for random `c` and `f`.
fn restriction_is_the_transpose(p: &Prolongation, rng: &mut Rng) {
    let (cv, fv) = (rng.vector(p.coarse), rng.vector(p.fine()));
    let mut pc = vec![DVec3::ZERO; p.fine()];
    p.add_to_fine(serial(), &cv, &mut pc);
    let mut ptf = vec![DVec3::splat(f64::NAN); p.coarse];
    p.restrict(&fv, &mut ptf);
    let (lhs, rhs) = (dot(&pc, &fv), dot(&cv, &ptf));
    assert!(
        (lhs - rhs).abs() < 1e-13 * norm(&pc) * norm(&fv),
        "{lhs} vs {rhs}"
    );
    // The transpose by coarse rows gives the scatter's bits.
    let mut gathered = vec![DVec3::splat(f64::NAN); p.coarse];
    Restriction::new(p).apply(p, serial(), &fv, &mut gathered);
    assert_eq!(bits(&gathered), bits(&ptf));
}

#[test]
fn restriction_by_coarse_rows_on_two_parts_has_the_bits_of_the_scatter() {
    let (graph, _, rest) = grid(97);
    let mut rng = Rng(31);
    let x = crumpled(&rest, &mut rng);
    let team = Team::new(1);
    let team = TeamRef::new(&team);
    for mut p in [
        prolongations(&graph, 16),
        rigid_prolongations(&graph, 16, &x),
    ] {
        let p = p.remove(0);
        assert!(p.coarse >= PARALLEL_MIN_ROWS, "{} coarse nodes", p.coarse);
        let fine = rng.vector(p.fine());
        let mut scattered = vec![DVec3::ZERO; p.coarse];
        p.restrict(&fine, &mut scattered);
        let mut gathered = vec![DVec3::splat(f64::NAN); p.coarse];
        Restriction::new(&p).apply(&p, team, &fine, &mut gathered);
        assert_eq!(bits(&gathered), bits(&scattered), "rigid: {}", p.rotates());
    }
}

#[test]
fn prolongation_interpolates_and_restriction_is_its_transpose() {
    let (graph, _, _) = grid(9);
    let ps = prolongations(&graph, 4);
    assert!(ps.len() >= 2, "{} coarse levels", ps.len());
    let c = coarsen(&graph, &[], 64, 4);
    let mut rng = Rng(77);
    for (l, p) in ps.iter().enumerate() {
        assert_eq!(p.coarse, c.kept[l].len());
        // Kept particles copy their coarse self; every row's weights sum to 1, so a uniform
        // coarse displacement is interpolated exactly.
        for (k, &f) in c.kept[l].iter().enumerate() {
            let range = p.start[f as usize] as usize..p.start[f as usize + 1] as usize;
            assert_eq!(&p.col[range.clone()], &[k as u32]);
            assert_eq!(&p.weight[range], &[1.0]);
        }
        let shift = DVec3::new(0.3, -1.2, 2.0);
        let mut fine = vec![DVec3::ZERO; p.fine()];
        p.add_to_fine(serial(), &vec![shift; p.coarse], &mut fine);
        for f in &fine {
            assert!((*f - shift).length() < 1e-15, "{f} from {shift}");
        }
        restriction_is_the_transpose(p, &mut rng);
    }
}

#[test]
fn rigid_prolongation_carries_rigid_motions_of_the_current_shape_exactly() {
    let (graph, _, rest) = grid(9);
    let mut rng = Rng(4242);
    let x = crumpled(&rest, &mut rng);
    let ps = rigid_prolongations(&graph, 4, &x);
    let c = coarsen(&graph, &[], 64, 4);
    assert!(ps.len() >= 2, "{} coarse levels", ps.len());
    // A rigid motion of the whole shape: velocity t + θ × (x − o).
    let (t, theta, o) = (rng.vec3(), rng.vec3(), rng.vec3());
    let motion = |p: DVec3| t + theta.cross(p - o);
    // The finest particle each level's particles stand for.
    let mut origin: Vec<usize> = (0..rest.len()).collect();
    for (l, p) in ps.iter().enumerate() {
        let coarse_origin: Vec<usize> = c.kept[l].iter().map(|&k| origin[k as usize]).collect();
        assert_eq!(p.coarse, 2 * coarse_origin.len());
        // Coarse particle k: translation node 2k moves as the motion at its position, rotation
        // node 2k + 1 is θ.
        let coarse: Vec<DVec3> = coarse_origin
            .iter()
            .flat_map(|&f| [motion(x[f]), theta])
            .collect();
        let mut fine = vec![DVec3::ZERO; p.fine()];
        p.add_to_fine(serial(), &coarse, &mut fine);
        let expect: Vec<DVec3> = if l == 0 {
            origin.iter().map(|&f| motion(x[f])).collect()
        } else {
            origin.iter().flat_map(|&f| [motion(x[f]), theta]).collect()
        };
        assert_eq!(fine.len(), expect.len());
        let scale = norm(&expect);
        for (i, (got, want)) in fine.iter().zip(&expect).enumerate() {
            assert!(
                (*got - *want).length() < 1e-14 * scale,
                "level {l}, fine node {i}: {got} against {want}"
            );
        }
        // A plain prolongation is exact for translations only: the rotation is what it misses.
        if l == 0 {
            let plain = &prolongations(&graph, 4)[0];
            let moved: Vec<DVec3> = coarse_origin.iter().map(|&f| motion(x[f])).collect();
            let mut linear = vec![DVec3::ZERO; plain.fine()];
            plain.add_to_fine(serial(), &moved, &mut linear);
            let miss = linear
                .iter()
                .zip(&expect)
                .map(|(a, b)| (*a - *b).length())
                .fold(0.0, f64::max);
            assert!(
                miss > 1e-3 * scale,
                "linear interpolation misses only {miss:e}"
            );
        }
        // With turns too.
        restriction_is_the_transpose(p, &mut rng);
        origin = coarse_origin;
    }
}

#[test]
fn coarse_operators_are_the_dense_galerkin_products() {
    let (graph, pairs, _) = grid(9);
    let mut rng = Rng(0x0123_4567_89ab_cdef);
    let a = random_spd(graph.len(), &pairs, &mut rng);
    galerkin_products_match(a, prolongations(&graph, 4));
}

#[test]
fn coarse_operators_with_rotations_are_the_dense_galerkin_products() {
    let (graph, pairs, rest) = grid(9);
    let mut rng = Rng(0xfeed_beef_1234_5678);
    let a = random_spd(graph.len(), &pairs, &mut rng);
    let x = crumpled(&rest, &mut rng);
    let ps = rigid_prolongations(&graph, 4, &x);
    assert!(ps.iter().all(Prolongation::rotates));
    galerkin_products_match(a, ps);
}

#[test]
fn coarse_operators_with_a_plain_first_level_are_the_dense_galerkin_products() {
    // `plain_levels = 1`: the first coarse level translates only, the ones past it turn.
    let (graph, pairs, rest) = grid(17);
    let mut rng = Rng(0x5eed_0001_2345_6789);
    let a = random_spd(graph.len(), &pairs, &mut rng);
    let x = crumpled(&rest, &mut rng);
    let ps = rigid_past(&graph, 4, &x, 1);
    assert!(ps.len() >= 3, "levels {}", ps.len() + 1);
    assert!(!ps[0].rotates() && ps[1..].iter().all(Prolongation::rotates));
    // Level 1 has one node per coarse particle (translations), level 2 two (and rotations).
    assert_eq!(ps[1].fine(), ps[0].coarse);
    assert_eq!(ps[1].coarse % 2, 0);
    galerkin_products_match(a, ps);
}

/// The hierarchy's coarse operators against dense `Pᵀ A P`, level by level, symmetric, and
/// recomputed from zero by a second update.
fn galerkin_products_match(a: BlockMatrix, ps: Vec<Prolongation>) {
    let mut h = Hierarchy::new(a.clone(), ps.clone());
    assert_eq!(h.depth(), ps.len() + 1);
    assert!(h.depth() >= 3, "sizes {:?}", h.sizes());
    assert!(h.update(serial()), "a random SPD matrix is SPD");
    // The fine values are the ones given.
    assert_eq!(dense(h.fine()), dense(&a));
    let mut reference = dense(&a);
    let mut worst: f64 = 0.0;
    for (l, p) in ps.iter().enumerate() {
        let (mf, mc) = (3 * p.fine(), 3 * p.coarse);
        let pd = dense_prolongation(p);
        let ap = dense_nn(&reference, &pd, mf, mf, mc);
        let mut ptap = dense_tn(&pd, &ap, mf, mc, mc);
        if p.rotates() {
            // The rigid levels' regularisation (`BlockMatrix::regularize_diagonal`).
            for i in 0..mc / 3 {
                let trace: f64 = (0..3).map(|k| ptap[(3 * i + k) * mc + 3 * i + k]).sum();
                assert!(trace > 0.0, "level {}: node {i} has a zero diagonal", l + 1);
                for k in 0..3 {
                    ptap[(3 * i + k) * mc + 3 * i + k] += ROTATION_REGULARIZATION * trace / 3.0;
                }
            }
        }
        let coarse = dense(&h.levels[l + 1].a);
        let err: Vec<f64> = coarse.iter().zip(&ptap).map(|(x, y)| x - y).collect();
        let rel = max_abs(&err) / max_abs(&ptap);
        worst = worst.max(rel);
        assert!(rel < 1e-12, "level {}: relative error {rel:e}", l + 1);
        // Symmetric, as the V-cycle needs.
        for i in 0..mc {
            for j in 0..i {
                let (x, y) = (coarse[i * mc + j], coarse[j * mc + i]);
                assert!((x - y).abs() <= 1e-12 * max_abs(&ptap), "({i}, {j})");
            }
        }
        reference = ptap;
    }
    // A second update after changing the fine values recomputes from zero (no accumulation).
    for v in h.fine_mut().val.iter_mut() {
        *v *= 2.0;
    }
    assert!(h.update(serial()));
    let last = dense(&h.levels[h.depth() - 1].a);
    let rel = last
        .iter()
        .zip(&reference)
        .map(|(x, y)| (x - 2.0 * y).abs())
        .fold(0.0, f64::max)
        / max_abs(&reference);
    assert!(rel < 1e-12, "after a second update: {rel:e}");
    println!("Galerkin operators: worst relative error {worst:e}");
}

#[test]
fn dot_in_fours_sums_four_lanes_in_a_fixed_order() {
    // Integers: every order gives the exact sum, at every length (remainders 0..3).
    for n in 0..13 {
        let a: Vec<f64> = (0..n).map(|k| (k + 1) as f64).collect();
        let b: Vec<f64> = (0..n).map(|k| (2 * k + 3) as f64).collect();
        let exact: f64 = (0..n).map(|k| ((k + 1) * (2 * k + 3)) as f64).sum();
        assert_eq!(dot_in_fours(&a, &b), exact, "n = {n}");
        // The shorter length counts.
        assert_eq!(dot_in_fours(&a, &b[..n / 2]), dot_in_fours(&a[..n / 2], &b));
    }
    // The order: lane sums (k mod 4), then (s0 + s1) + (s2 + s3). 1 + 1e16 − 1e16 in one
    // lane, against a 1 in another, tells the orders apart.
    let a = [1e16, 1.0, 0.0, 0.0, -1e16, 0.0, 0.0, 0.0, 1.0];
    let b = [1.0; 9];
    // Lane 0: (1e16 + −1e16) + 1 = 1; lane 1: 1 → 2. A plain left-to-right sum gives 1.
    assert_eq!(dot_in_fours(&a, &b), 2.0);
    let plain: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    assert_eq!(plain, 1.0);
}

#[test]
fn cholesky_reproduces_the_matrix_and_refuses_an_indefinite_one() {
    let mut rng = Rng(5);
    let m = 24;
    let b: Vec<f64> = (0..m * m).map(|_| rng.next()).collect();
    // A = B Bᵀ + I: symmetric positive definite.
    let mut a = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            a[i * m + j] = (0..m).map(|k| b[i * m + k] * b[j * m + k]).sum::<f64>()
                + if i == j { 1.0 } else { 0.0 };
        }
    }
    let mut l = a.clone();
    assert!(cholesky_in_place(&mut l, m));
    let mut worst: f64 = 0.0;
    for i in 0..m {
        assert!(l[i * m + i] > 0.0);
        for j in 0..=i {
            let llt: f64 = (0..=j).map(|k| l[i * m + k] * l[j * m + k]).sum();
            worst = worst.max((llt - a[i * m + j]).abs());
        }
    }
    let rel = worst / max_abs(&a);
    assert!(rel < 1e-13, "L Lᵀ − A: relative {rel:e}");

    // The solve with the factor and its transpose beside it: A x = b to rounding.
    mirror_factor(&mut l, m);
    for i in 0..m {
        for k in i + 1..m {
            assert_eq!(l[i * m + k], l[k * m + i], "the upper triangle is Lᵀ");
        }
    }
    let want: Vec<f64> = (0..m).map(|_| rng.next()).collect();
    let mut x: Vec<f64> = (0..m)
        .map(|i| (0..m).map(|k| a[i * m + k] * want[k]).sum())
        .collect();
    cholesky_solve_in_place(&l, &mut x);
    let err = x
        .iter()
        .zip(&want)
        .map(|(x, w)| (x - w).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-11 * max_abs(&want), "solve: {err:e}");

    // Indefinite: eigenvalues 3 and −1; a negative pivot; a singular matrix; NaN.
    for (mut bad, what) in [
        (vec![1.0, 2.0, 2.0, 1.0], "indefinite"),
        (vec![-1.0, 0.0, 0.0, 1.0], "negative pivot"),
        (vec![1.0, 1.0, 1.0, 1.0], "singular"),
        (vec![f64::NAN, 0.0, 0.0, 1.0], "NaN"),
    ] {
        assert!(!cholesky_in_place(&mut bad, 2), "{what} accepted");
    }
}

#[test]
fn a_single_level_is_solved_exactly_and_an_indefinite_matrix_is_refused() {
    let (_, pairs, _) = grid(4);
    let mut rng = Rng(11);
    let a = random_spd(16, &pairs, &mut rng);
    let mut h = Hierarchy::new(a, Vec::new());
    assert_eq!(h.depth(), 1);
    assert_eq!(h.operator_complexity(), 1.0);
    assert!(h.update(serial()));
    let b = rng.vector(16);
    let mut x = vec![DVec3::ZERO; 16];
    h.v_cycle(serial(), &b, &mut x);
    let residual = relative_residual(&h, &b, &x);
    assert!(residual < 1e-12, "{residual:e}");

    // Positive definite diagonal blocks, indefinite matrix: [I 2I; 2I I].
    let mut bad = BlockMatrix::with_pattern(2, [(0, 1)]);
    for i in 0..2 {
        bad.val[bad.diag[i] as usize] = DMat3::IDENTITY;
    }
    let (s01, s10) = (bad.slot(0, 1).unwrap(), bad.slot(1, 0).unwrap());
    bad.val[s01] = DMat3::IDENTITY * 2.0;
    bad.val[s10] = DMat3::IDENTITY * 2.0;
    assert!(!Hierarchy::new(bad.clone(), Vec::new()).update(serial()));
    // A negative diagonal block on the fine level of a multilevel hierarchy.
    let (graph, pairs, _) = grid(9);
    let mut a = random_spd(graph.len(), &pairs, &mut rng);
    let d = a.diag[40] as usize;
    a.val[d] = -a.val[d];
    assert!(!Hierarchy::new(a, prolongations(&graph, 4)).update(serial()));
}

#[test]
fn pcg_solves_the_cloth_hessian_to_1e_10() {
    let mut h = cloth_hessian(33, false, false);
    assert!(h.update(serial()));
    let n = h.fine().n();
    assert_eq!(n, 33 * 33 - 2);
    let sizes = h.sizes();
    assert!(sizes.len() >= 3, "levels {sizes:?}");
    assert!(
        *sizes.last().unwrap() >= 16 && *sizes.last().unwrap() < 4 * 16,
        "coarsest {sizes:?}"
    );
    let complexity = h.operator_complexity();
    assert!(complexity < 2.0, "operator complexity {complexity}");
    let mut rng = Rng(3);
    let b = rng.vector(n);
    let mut x = vec![DVec3::ZERO; n];
    let mut pcg = Pcg::new(n);
    let stats = pcg.solve(serial(), &mut h, &b, &mut x, 200, 1e-11, 0.0);
    let true_reduction = relative_residual(&h, &b, &x);
    println!(
        "33 x 33 cloth Hessian, levels {sizes:?}, complexity {complexity:.3}: {} PCG iterations, recursive reduction {:e}, true {true_reduction:e}",
        stats.iterations, stats.reduction
    );
    assert!(stats.reduction <= 1e-11, "{stats:?}");
    assert!(stats.iterations < 200, "{stats:?}");
    assert!(true_reduction < 1e-10, "true residual {true_reduction:e}");
    // Stopping early: the tolerance is honoured and no more iterations are run than given.
    let loose = pcg.solve(serial(), &mut h, &b, &mut x, 200, 1e-3, 0.0);
    assert!(loose.reduction <= 1e-3 && loose.iterations < stats.iterations);
    let capped = pcg.solve(serial(), &mut h, &b, &mut x, 2, 0.0, 0.0);
    // An absolute floor: no iteration once the residual's norm is below it, x = 0 if b's is.
    let floor = 1e-3 * norm(&b);
    let floored = pcg.solve(serial(), &mut h, &b, &mut x, 200, 0.0, floor);
    assert!(
        floored.reduction <= 1e-3 && floored.iterations < stats.iterations,
        "{floored:?}"
    );
    let none = pcg.solve(serial(), &mut h, &b, &mut x, 200, 0.0, 2.0 * norm(&b));
    assert_eq!((none.iterations, none.reduction), (0, 1.0));
    assert!(x.iter().all(|v| *v == DVec3::ZERO));
    assert_eq!(capped.iterations, 2);
    assert!(
        capped.reduction > 0.0 && capped.reduction < 1.0,
        "{capped:?}"
    );
}

#[test]
fn update_to_refreshes_the_first_levels_and_keeps_the_deeper_ones() {
    // A cloth Hessian with turning levels, updated; then its fine matrix scaled by 1.5 and
    // only the first levels refreshed. They match a hierarchy fully updated on the new
    // matrix, bit for bit; the deeper levels and the coarsest factor keep the old values; and
    // PCG still converges, within a few iterations of the fresh hierarchy.
    let mut h = cloth_hessian(33, true, false);
    assert!(h.update(serial()));
    let levels = h.depth();
    assert!(levels >= 4, "levels {:?}", h.sizes());
    let old: Vec<Vec<DMat3>> = h.levels.iter().map(|l| l.a.val.clone()).collect();
    let old_inv: Vec<Vec<DMat3>> = h.levels.iter().map(|l| l.inv_diag.clone()).collect();
    let old_factor = h.dense.clone();
    for v in h.fine_mut().val.iter_mut() {
        *v *= 1.5;
    }
    let mut fresh = h.clone();
    assert!(fresh.update(serial()));
    let n = h.fine().n();
    let mut rng = Rng(8);
    let b = rng.vector(n);
    let mut pcg = Pcg::new(n);
    let mut x = vec![DVec3::ZERO; n];
    let fresh_stats = pcg.solve(serial(), &mut fresh, &b, &mut x, 200, 1e-10, 0.0);
    for refresh in [0, 1, 2] {
        let mut some = h.clone();
        assert!(some.update_to(serial(), refresh));
        for (l, level) in some.levels.iter().enumerate() {
            if l <= refresh {
                assert_eq!(
                    level.a.val, fresh.levels[l].a.val,
                    "depth {refresh}: level {l}"
                );
                assert_eq!(level.inv_diag, fresh.levels[l].inv_diag);
            } else {
                assert_eq!(level.a.val, old[l], "depth {refresh}: level {l} changed");
                assert_eq!(level.inv_diag, old_inv[l]);
            }
        }
        assert_eq!(
            some.dense, old_factor,
            "depth {refresh}: the factor changed"
        );
        let stats = pcg.solve(serial(), &mut some, &b, &mut x, 200, 1e-10, 0.0);
        assert!(
            relative_residual(&some, &b, &x) < 1e-9,
            "depth {refresh}: {stats:?}"
        );
        assert!(
            stats.iterations <= fresh_stats.iterations + 5,
            "depth {refresh}: {stats:?} against {fresh_stats:?}"
        );
    }
    // A depth reaching the coarsest level is the full update, factor included.
    let mut all = h.clone();
    assert!(all.update_to(serial(), levels - 1));
    for (l, level) in all.levels.iter().enumerate() {
        assert_eq!(level.a.val, fresh.levels[l].a.val, "level {l}");
    }
    assert_eq!(all.dense, fresh.dense);
}

#[test]
fn pcg_from_a_zero_or_non_finite_right_hand_side_does_not_iterate() {
    let mut h = cloth_hessian(5, false, false);
    assert!(h.update(serial()));
    let n = h.fine().n();
    let mut pcg = Pcg::new(n);
    let mut x = vec![DVec3::ONE; n];
    let stats = pcg.solve(
        serial(),
        &mut h,
        &vec![DVec3::ZERO; n],
        &mut x,
        10,
        1e-6,
        0.0,
    );
    assert_eq!(stats.iterations, 0);
    assert_eq!(stats.reduction, 0.0);
    assert!(x.iter().all(|v| *v == DVec3::ZERO), "x is reset to zero");
    let mut b = vec![DVec3::ONE; n];
    b[3].y = f64::NAN;
    let stats = pcg.solve(serial(), &mut h, &b, &mut x, 10, 1e-6, 0.0);
    assert_eq!(stats.iterations, 0);
    assert!(stats.reduction.is_nan());
}

/// Conjugate gradients without a preconditioner, from zero, until the residual is `tolerance`
/// times the initial one; returns the iterations.
fn plain_cg(a: &BlockMatrix, b: &[DVec3], tolerance: f64, max_iterations: u32) -> u32 {
    let n = b.len();
    let mut x = vec![DVec3::ZERO; n];
    let mut r = b.to_vec();
    let mut p = r.clone();
    let mut q = vec![DVec3::ZERO; n];
    let r0 = norm(&r);
    let mut rr = dot(&r, &r);
    for it in 1..=max_iterations {
        a.mul(serial(), &p, &mut q);
        let alpha = rr / dot(&p, &q);
        for i in 0..n {
            x[i] += p[i] * alpha;
            r[i] -= q[i] * alpha;
        }
        let rr_new = dot(&r, &r);
        if rr_new.sqrt() <= tolerance * r0 {
            return it;
        }
        let beta = rr_new / rr;
        rr = rr_new;
        for i in 0..n {
            p[i] = r[i] + p[i] * beta;
        }
    }
    max_iterations
}

#[test]
fn the_v_cycle_cuts_the_iterations_far_below_plain_cg() {
    let mut h = cloth_hessian(33, false, false);
    assert!(h.update(serial()));
    let n = h.fine().n();
    let b = Rng(8).vector(n);
    let tolerance = 1e-6;
    let mut x = vec![DVec3::ZERO; n];
    let mg = Pcg::new(n).solve(serial(), &mut h, &b, &mut x, 1000, tolerance, 0.0);
    let plain = plain_cg(h.fine(), &b, tolerance, 20_000);
    println!(
        "33 x 33 cloth Hessian to 1e-6: {} V-cycle PCG iterations, {plain} plain CG iterations",
        mg.iterations
    );
    assert!(mg.reduction <= tolerance, "{mg:?}");
    assert!(plain < 20_000, "plain CG did not reach {tolerance:e}");
    assert!(
        20 * mg.iterations <= plain,
        "V-cycle PCG {} iterations against plain CG {plain}",
        mg.iterations
    );
}

#[test]
fn rotations_carry_a_swing_of_a_folded_cloth_in_few_iterations() {
    // The residual of a swing of the folded half about the crease (x = 0.5, z = 0), the motion
    // a Newton step truncated at a few CG iterations must carry: the error left after 5
    // iterations, relative, in displacement.
    let side = 33;
    let swing: Vec<DVec3> = (0..side * side)
        .filter(|&i| i != 0 && i != side - 1)
        .map(|i| {
            let px = (i % side) as f64 / (side - 1) as f64;
            if px > 0.5 {
                DVec3::new(-(px - 0.5), 0.0, 0.0)
            } else {
                DVec3::ZERO
            }
        })
        .collect();
    let mut errors = Vec::new();
    for rigid in [false, true] {
        let mut h = cloth_hessian(side, rigid, true);
        assert!(h.update(serial()));
        let n = h.fine().n();
        let mut b = vec![DVec3::ZERO; n];
        h.fine().mul(serial(), &swing, &mut b);
        let mut x = vec![DVec3::ZERO; n];
        let stats = Pcg::new(n).solve(serial(), &mut h, &b, &mut x, 5, 0.0, 0.0);
        assert_eq!(stats.iterations, 5);
        let e: Vec<DVec3> = x.iter().zip(&swing).map(|(p, q)| *p - *q).collect();
        let error = norm(&e) / norm(&swing);
        println!(
            "folded 33 x 33 cloth, a swing, 5 PCG iterations, rotations {rigid}: displacement error {error:.2e}, residual reduction {:.2e}, operator complexity {:.2}",
            stats.reduction,
            h.operator_complexity()
        );
        errors.push(error);
    }
    assert!(errors[1] < 0.02, "with rotations: error {:e}", errors[1]);
    assert!(
        4.0 * errors[1] <= errors[0],
        "with rotations {:e}, without {:e}",
        errors[1],
        errors[0]
    );
}

#[test]
fn the_v_cycle_is_a_symmetric_positive_definite_operator() {
    // On the cloth Hessian and on a random SPD block matrix with random blocks.
    let (graph, pairs, _) = grid(9);
    let mut rng = Rng(21);
    let random = Hierarchy::new(
        random_spd(graph.len(), &pairs, &mut rng),
        prolongations(&graph, 4),
    );
    let x = crumpled(&grid(9).2, &mut rng);
    let random_rigid = Hierarchy::new(
        random_spd(graph.len(), &pairs, &mut rng),
        rigid_prolongations(&graph, 4, &x),
    );
    let mut relaxed = cloth_hessian(33, true, true);
    relaxed.set_relaxation(0.8);
    let mut over = cloth_hessian(33, false, false);
    over.set_relaxation(1.5);
    for (what, mut h) in [
        ("cloth", cloth_hessian(33, false, false)),
        ("random", random),
        ("folded cloth, rotations", cloth_hessian(33, true, true)),
        ("random, rotations", random_rigid),
        ("folded cloth, rotations, relaxation 0.8", relaxed),
        ("cloth, relaxation 1.5", over),
    ] {
        assert!(h.update(serial()));
        assert!(h.depth() >= 3, "{what}: {:?}", h.sizes());
        let n = h.fine().n();
        let mut worst: f64 = 0.0;
        for _ in 0..5 {
            let (u, v) = (rng.vector(n), rng.vector(n));
            let (mut mu, mut mv) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
            h.v_cycle(serial(), &u, &mut mu);
            h.v_cycle(serial(), &v, &mut mv);
            // CG's own call, lending its vectors: the same bits, `v` given back unchanged.
            let (mut lent, mut out) = (v.clone(), vec![DVec3::splat(f64::NAN); n]);
            h.v_cycle_in_place(serial(), &mut lent, &mut out);
            assert_eq!(flat(&lent), flat(&v), "{what}: the right-hand side changed");
            let bits = |v: &[DVec3]| flat(v).into_iter().map(f64::to_bits).collect::<Vec<_>>();
            assert_eq!(bits(&out), bits(&mv), "{what}: in place");
            let (umu, vmv) = (dot(&u, &mu), dot(&v, &mv));
            assert!(umu > 0.0 && vmv > 0.0, "{what}: not positive");
            // |uᵀMv| ≤ √(uᵀMu · vᵀMv) for an SPD M: the scale of the asymmetry.
            let asym = (dot(&u, &mv) - dot(&v, &mu)).abs() / (umu * vmv).sqrt();
            worst = worst.max(asym);
            assert!(asym < 1e-10, "{what}: uᵀMv − vᵀMu relative {asym:e}");
        }
        println!("{what}: V-cycle asymmetry {worst:e}");
    }
}

#[test]
fn the_v_cycle_stays_symmetric_when_blocks_overflow_the_colours() {
    // 70 blocks of GAUSS_SEIDEL_BLOCK rows, every two coupled by one pair of rows: the greedy
    // colouring gives blocks 0..64 a colour each and leaves blocks 64..70 to the last range,
    // swept in sequence (flagged not independent). Two levels, so the fine level is smoothed:
    // coarse particle k interpolates to the rows of parity k.
    let mut rng = Rng(99);
    let mut h = overflowing(&mut rng);
    let (size, n) = (GAUSS_SEIDEL_BLOCK, h.fine().n());
    let (blocks, colours) = (&h.levels[0].blocks, &h.levels[0].colours);
    assert_eq!(blocks.len(), 70);
    assert!(
        colours
            .iter()
            .any(|(range, independent)| !independent && range.len() > 1),
        "no overflowing colour of several blocks: {colours:?}"
    );
    assert!(h.update(serial()));
    // u and v on the overflowing blocks' rows only (the property holds for every u, v).
    let overflow = 64 * size;
    let mut vector = || -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                if i >= overflow {
                    rng.vec3()
                } else {
                    DVec3::ZERO
                }
            })
            .collect()
    };
    let (u, v) = (vector(), vector());
    let (mut mu, mut mv) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
    h.v_cycle(serial(), &u, &mut mu);
    h.v_cycle(serial(), &v, &mut mv);
    let (umu, vmv) = (dot(&u, &mu), dot(&v, &mv));
    let asym = (dot(&u, &mv) - dot(&v, &mu)).abs() / (umu * vmv).sqrt();
    println!("overflowing colours: V-cycle asymmetry {asym:e}");
    assert!(asym < 1e-10, "uᵀMv − vᵀMu relative {asym:e}");
}

/// The bits of a vector of blocks or vectors, for exact comparisons.
fn bits(v: &[DVec3]) -> Vec<u64> {
    v.iter()
        .flat_map(|p| p.to_array().map(f64::to_bits))
        .collect()
}

fn block_bits(v: &[DMat3]) -> Vec<u64> {
    v.iter()
        .flat_map(|m| m.to_cols_array().map(f64::to_bits))
        .collect()
}

#[test]
fn a_two_part_team_gives_the_bits_of_one_thread() {
    // 97 × 97: the two finest levels (9,407 and ~2,400 rows, twice that with rotations) have
    // at least PARALLEL_MIN_ROWS rows, so their products, updates and Gauss-Seidel colours
    // (several independent blocks each) are split over the team.
    same_bits_on_two_parts(cloth_hessian(97, false, false));
    same_bits_on_two_parts(cloth_hessian(97, true, true));
    let mut post = cloth_hessian(97, true, true);
    post.set_pre_smoothing(false);
    post.set_relaxation(0.7);
    same_bits_on_two_parts(post);
}

#[test]
fn without_pre_smoothing_a_cycle_is_the_coarse_solve_of_b_then_a_backward_sweep() {
    // Two levels (the coarse one solved densely) on a random SPD grid matrix, relaxation 0.7:
    // the cycle restricts b, solves the coarse Galerkin system, sets x = P x_c, and sweeps
    // backward from there (rows in the reverse of the forward sweep's order). The reference
    // does each in dense arithmetic, with the sweep's order taken from `in_sweep_order`.
    let (graph, pairs, _) = grid(9);
    let mut rng = Rng(21);
    let a = random_spd(graph.len(), &pairs, &mut rng);
    let p: Vec<Prolongation> = prolongations(&graph, 4).into_iter().take(1).collect();
    let dp = dense_prolongation(&p[0]);
    let mut h = Hierarchy::new(a.clone(), p);
    assert_eq!(h.depth(), 2);
    h.set_relaxation(0.7);
    h.set_pre_smoothing(false);
    assert!(h.update(serial()));
    let (n, m) = (a.n(), h.levels[1].a.n());
    let b = rng.vector(n);
    let mut z = vec![DVec3::ZERO; n];
    h.v_cycle(serial(), &b, &mut z);

    let da = dense(&a);
    let coarse = dense_tn(
        &dp,
        &dense_nn(&da, &dp, 3 * n, 3 * n, 3 * m),
        3 * n,
        3 * m,
        3 * m,
    );
    let mut factor = coarse.clone();
    assert!(cholesky_in_place(&mut factor, 3 * m));
    mirror_factor(&mut factor, 3 * m);
    let mut xc = dense_tn(&dp, &flat(&b), 3 * n, 3 * m, 1);
    cholesky_solve_in_place(&factor, &mut xc);
    let x0 = dense_nn(&dp, &xc, 3 * n, 3 * m, 1);
    let mut x: Vec<DVec3> = x0.chunks(3).map(DVec3::from_slice).collect();
    let order = std::sync::Mutex::new(Vec::new());
    let level = &h.levels[0];
    in_sweep_order(serial(), n, &level.blocks, &level.colours, true, &|rows| {
        order.lock().unwrap().extend(rows.clone().rev())
    });
    let order = order.into_inner().unwrap();
    assert_eq!(order.len(), n);
    for &i in &order {
        let mut sum = b[i];
        for j in (0..n).filter(|&j| j != i) {
            let block = dense_block(&da, n, i, j);
            sum -= block * x[j];
        }
        let diagonal = dense_block(&da, n, i, i);
        let update = diagonal.inverse() * sum;
        let old = x[i];
        x[i] = old + (update - old) * 0.7;
    }
    let error: f64 = z
        .iter()
        .zip(&x)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f64::max);
    assert!(
        error < 1e-10 * norm(&x),
        "{error:e} against |x| {:e}",
        norm(&x)
    );
    // Not the symmetric cycle's result.
    h.set_pre_smoothing(true);
    let mut symmetric = vec![DVec3::ZERO; n];
    h.v_cycle(serial(), &b, &mut symmetric);
    let apart: f64 = symmetric
        .iter()
        .zip(&x)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f64::max);
    assert!(apart > 1e-6 * norm(&x), "{apart:e}");
}

/// Block `(i, j)` of a dense `3n × 3n` row-major matrix.
fn dense_block(d: &[f64], n: usize, i: usize, j: usize) -> DMat3 {
    let at = |r: usize, c: usize| d[(3 * i + r) * 3 * n + 3 * j + c];
    DMat3::from_cols(
        DVec3::new(at(0, 0), at(1, 0), at(2, 0)),
        DVec3::new(at(0, 1), at(1, 1), at(2, 1)),
        DVec3::new(at(0, 2), at(1, 2), at(2, 2)),
    )
}

#[test]
fn flexible_pcg_with_post_smoothing_cycles_solves_the_cloth_hessian_to_1e_10() {
    // The folded cloth's Hessian with turning levels: the unsymmetric V(0,1) cycle with CG's
    // flexible β converges to 1e-10, as the symmetric cycle does.
    let (mut counts, mut early) = (Vec::new(), Vec::new());
    for pre in [true, false] {
        let mut h = cloth_hessian(33, true, true);
        h.set_relaxation(0.7);
        h.set_pre_smoothing(pre);
        assert!(h.update(serial()));
        let n = h.fine().n();
        let b = Rng(5).vector(n);
        let mut x = vec![DVec3::ZERO; n];
        let stats = Pcg::new(n).solve(serial(), &mut h, &b, &mut x, 300, 1e-11, 0.0);
        let true_reduction = relative_residual(&h, &b, &x);
        println!(
            "pre_smoothing {pre}: {} iterations, true reduction {true_reduction:e}",
            stats.iterations
        );
        assert!(stats.reduction <= 1e-11, "pre_smoothing {pre}: {stats:?}");
        assert!(
            true_reduction < 1e-10,
            "pre_smoothing {pre}: {true_reduction:e}"
        );
        counts.push(stats.iterations);
        let three = Pcg::new(n).solve(serial(), &mut h, &b, &mut x, 3, 0.0, 0.0);
        println!(
            "pre_smoothing {pre}: reduction after 3 iterations {:e}",
            three.reduction
        );
        early.push(three.reduction);
    }
    // Run to 1e-11 the cheaper cycle needs about twice the iterations (69 against 31), but
    // its first few take off nearly as much (0.19 against 0.15 of the residual after three),
    // which is what a truncated Newton step's CG uses.
    assert!(counts[1] <= 3 * counts[0], "iterations {counts:?}");
    assert!(
        early[1] < 1.5 * early[0] && early[1] < 0.5,
        "after three: {early:?}"
    );
}

fn same_bits_on_two_parts(mut one: Hierarchy) {
    let mut two = one.clone();
    assert!(one.sizes()[1] >= PARALLEL_MIN_ROWS, "{:?}", one.sizes());
    let (_, colours) = one.fine().block_colours(GAUSS_SEIDEL_BLOCK);
    assert!(
        colours
            .iter()
            .any(|(range, independent)| *independent && range.len() > 1),
        "no colour can be split: {colours:?}"
    );
    let team = Team::new(1);
    let team = TeamRef::new(&team);
    assert_eq!(team.parts(), 2);
    assert!(one.update(serial()));
    assert!(two.update(team));
    for (l, (a, b)) in one.levels.iter().zip(&two.levels).enumerate() {
        assert_eq!(block_bits(&a.a.val), block_bits(&b.a.val), "level {l}");
        assert_eq!(
            block_bits(&a.inv_diag),
            block_bits(&b.inv_diag),
            "level {l}"
        );
    }
    assert!(one
        .dense
        .iter()
        .zip(&two.dense)
        .all(|(p, q)| p.to_bits() == q.to_bits()));
    let n = one.fine().n();
    let b = Rng(4).vector(n);
    let (mut y1, mut y2) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
    one.fine().mul(serial(), &b, &mut y1);
    two.fine().mul(team, &b, &mut y2);
    assert_eq!(bits(&y1), bits(&y2), "product");
    one.v_cycle(serial(), &b, &mut y1);
    two.v_cycle(team, &b, &mut y2);
    assert_eq!(bits(&y1), bits(&y2), "V-cycle");
    let s1 = Pcg::new(n).solve(serial(), &mut one, &b, &mut y1, 5, 0.0, 0.0);
    let s2 = Pcg::new(n).solve(team, &mut two, &b, &mut y2, 5, 0.0, 0.0);
    assert_eq!(s1, s2);
    assert_eq!(bits(&y1), bits(&y2), "PCG");
}

#[test]
fn turning_galerkin_sums_in_the_lanes_have_the_bits_of_the_scalar_terms() {
    let (graph, _, rest) = grid(9);
    let mut rng = Rng(808);
    let x = crumpled(&rest, &mut rng);
    let ps = rigid_past(&graph, 4, &x, 0);
    // The second level turns on both sides: copies and turns on the fine and the coarse side.
    for p in &ps {
        assert!(p.rotates());
        let entries = p.col.len();
        let val: Vec<DMat3> = (0..40).map(|_| rng.mat3()).collect();
        let terms: Vec<(u32, u32, u32, u32)> = (0..200u32)
            .map(|k| {
                (
                    k % 40,
                    0,
                    (k * 7 + 3) % entries as u32,
                    (k * 13 + 1) % entries as u32,
                )
            })
            .collect();
        assert!(terms
            .iter()
            .any(|t| p.turn[t.2 as usize] && p.turn[t.3 as usize]));
        assert!(terms
            .iter()
            .any(|t| !p.turn[t.2 as usize] && !p.turn[t.3 as usize]));
        let mut scalar = DMat3::ZERO;
        for &(s, _, i, j) in &terms {
            scalar += p.galerkin_term(i as usize, val[s as usize], j as usize);
        }
        let bits = |m: DMat3| m.to_cols_array().map(f64::to_bits);
        match crate::block_lanes::turning_sum(&val, &terms, &p.weight, &p.turn, &p.arm) {
            Some(lanes) => assert_eq!(bits(lanes), bits(scalar)),
            None => eprintln!("no AVX2 here: the lanes were not exercised"),
        }
    }
}

/// After a forward sweep from zero (relaxation weight `omega`) on each level but the
/// coarsest, the residual from the diagonal and the later columns ([`later_residuals`]) against `b − A x` by a full product: the largest
/// difference relative to the larger of `|b|` and the residual's norm.
fn sweep_residual_error(h: &mut Hierarchy, rng: &mut Rng, omega: f64) -> f64 {
    let mut worst: f64 = 0.0;
    let depth = h.levels.len();
    for level in &mut h.levels[..depth - 1] {
        let n = level.a.n();
        level.b = rng.vector(n);
        level.x.iter_mut().for_each(|v| *v = DVec3::ZERO);
        gauss_seidel(serial(), level, false, omega);
        let mut ax = vec![DVec3::ZERO; n];
        level.a.mul(serial(), &level.x, &mut ax);
        let mut from_sweep = vec![DVec3::ZERO; n];
        later_residuals(
            &level.a,
            &level.later_start,
            &level.later,
            &level.x,
            0..n,
            &mut from_sweep,
            (1.0 - omega) / omega,
        );
        let r = norm(&from_sweep);
        let scale = norm(&level.b).max(r);
        for i in 0..n {
            let full = level.b[i] - ax[i];
            worst = worst.max((full - from_sweep[i]).length() / scale);
        }
        // Not the trivial case: the sweep left a residual.
        assert!(r > 1e-3 * scale, "residual {r:e} against {scale:e}");
    }
    worst
}

#[test]
fn the_residual_from_the_forward_sweep_is_b_minus_a_x() {
    let mut rng = Rng(5);
    for (what, mut h) in [
        ("cloth", cloth_hessian(33, false, false)),
        ("folded cloth, rotations", cloth_hessian(33, true, true)),
    ] {
        assert!(h.update(serial()));
        assert!(h.depth() >= 3, "{what}: {:?}", h.sizes());
        for omega in [1.0, 0.8, 1.3] {
            let error = sweep_residual_error(&mut h, &mut rng, omega);
            println!(
                "{what}, relaxation {omega}: residual from the sweep, largest difference {error:e}"
            );
            assert!(error < 1e-12, "{what}, relaxation {omega}: {error:e}");
        }
    }
    // Blocks that overflow the colours (swept in sequence), as in the test above.
    let mut h = overflowing(&mut rng);
    assert!(h.update(serial()));
    for omega in [1.0, 0.8] {
        let error = sweep_residual_error(&mut h, &mut rng, omega);
        println!("overflowing colours, relaxation {omega}: residual from the sweep, largest difference {error:e}");
        assert!(
            error < 1e-12,
            "overflowing colours, relaxation {omega}: {error:e}"
        );
    }
}

#[test]
fn a_grid_rows_later_and_earlier_slots_are_at_most_two_runs_each() {
    // The residual after the forward sweep reads each row's later slots, and the forward sweep
    // from zero its earlier ones, run by run: on the fine level of a cloth grid (blocks of
    // consecutive rows) each is the row's own block on one side of it and whole neighbouring
    // blocks, one or two runs; with the diagonal they are every slot of the row, once.
    let h = cloth_hessian(65, false, false);
    let fine = &h.levels[0];
    let n = fine.a.n();
    for (what, start, runs) in [
        ("later", &fine.later_start, &fine.later),
        ("earlier", &fine.earlier_start, &fine.earlier),
    ] {
        let count = |i: usize| (start[i + 1] - start[i]) as usize;
        let slots: usize = runs.iter().map(|r| (r[1] - r[0]) as usize).sum();
        let most = (0..n).map(count).max().unwrap_or(0);
        println!(
            "fine level: {n} rows, {} slots, {slots} {what} ({:.2} a row) in {:.2} runs a row, at most {most}",
            fine.a.val.len(),
            slots as f64 / n as f64,
            runs.len() as f64 / n as f64
        );
        assert!(most <= 2, "{what}: {most} runs in a row");
        // Fewer than half the slots: the point of reading them alone.
        assert!(
            2 * slots < fine.a.val.len(),
            "{what}: {slots} of {}",
            fine.a.val.len()
        );
    }
    for i in 0..n {
        let row = fine.a.start[i] as usize..fine.a.start[i + 1] as usize;
        let mut seen = vec![0; row.len()];
        seen[fine.a.diag[i] as usize - row.start] += 1;
        for (start, runs) in [
            (&fine.later_start, &fine.later),
            (&fine.earlier_start, &fine.earlier),
        ] {
            for r in &runs[start[i] as usize..start[i + 1] as usize] {
                assert!(
                    r[0] < r[1] && row.contains(&(r[0] as usize)) && r[1] as usize <= row.end,
                    "row {i}: {r:?}"
                );
                (r[0]..r[1]).for_each(|s| seen[s as usize - row.start] += 1);
            }
        }
        assert!(seen.iter().all(|&k| k == 1), "row {i}: slots seen {seen:?}");
    }
}

#[test]
fn the_forward_sweep_from_zero_has_the_bits_of_zeroing_and_sweeping() {
    // Every level but the coarsest of a plain, a turning and an overflowing-colour hierarchy,
    // plain and relaxed, on one thread and on two.
    let mut rng = Rng(17);
    let team = Team::new(1);
    let two = TeamRef::new(&team);
    let over = overflowing(&mut rng);
    for (what, mut h) in [
        ("cloth", cloth_hessian(65, false, false)),
        ("folded cloth, rotations", cloth_hessian(65, true, true)),
        ("overflowing colours", over),
    ] {
        assert!(h.update(serial()));
        let depth = h.levels.len();
        for omega in [1.0, 0.8] {
            for level in &mut h.levels[..depth - 1] {
                let n = level.a.n();
                level.b = rng.vector(n);
                level.x.iter_mut().for_each(|v| *v = DVec3::ZERO);
                gauss_seidel(serial(), level, false, omega);
                let swept = flat(&level.x);
                for team in [serial(), two] {
                    // Whatever x held before: the sweep from zero never reads it.
                    level.x = rng.vector(n);
                    forward_from_zero(team, level, omega);
                    let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                    assert_eq!(
                        bits(&flat(&level.x)),
                        bits(&swept),
                        "{what}, {n} rows, relaxation {omega}, {} parts",
                        team.parts()
                    );
                }
            }
        }
    }
}

/// 70 blocks of [`GAUSS_SEIDEL_BLOCK`] rows, every two coupled by one pair of rows (so that
/// blocks 64..70 overflow the colours and are swept in sequence), and a coarse level of two
/// particles, one for the rows of each parity.
fn overflowing(rng: &mut Rng) -> Hierarchy {
    let size = GAUSS_SEIDEL_BLOCK;
    let count = 70u32;
    let n = count as usize * size;
    let pairs: Vec<(u32, u32)> = (0..count)
        .flat_map(|p| (p + 1..count).map(move |q| (p * size as u32, q * size as u32 + 1)))
        .collect();
    let a = random_spd(n, &pairs, rng);
    let p = Prolongation {
        coarse: 2,
        start: (0..=n as u32).collect(),
        col: (0..n as u32).map(|i| i % 2).collect(),
        weight: vec![1.0; n],
        turn: vec![false; n],
        arm: vec![DVec3::ZERO; n],
        origin: vec![[u32::MAX; 2]; n],
    };
    Hierarchy::new(a, vec![p])
}
