//! Closest points and intersection tests between simplices, at one instant.
//!
//! These are the static queries of the collision plugin: the response needs the closest
//! points of a contact found by [`crate::narrow_phase::ccd`] (barycentric weights to distribute the
//! correction), and tests need ground truth.
//!
//! * [`point_segment_closest`], [`point_triangle_closest`], [`segment_segment_closest`]:
//!   closest points in `f64`. None of them divides by a quantity that can vanish on
//!   degenerate input: every answer is the best of a few *candidate* points that all lie
//!   on the simplices (the interior solution when the simplex is well shaped, and the
//!   closest points of the boundary pieces, which are always well defined), so a zero-length
//!   edge, a zero-area triangle or parallel segments give a valid, accurate answer, never a
//!   NaN. The squared distance returned is the one between the returned points.
//! * [`triangles_intersect`]: an **exact** test — the answer is the one exact real
//!   arithmetic on the `f64` inputs would give. It uses only the signs of the orientation
//!   determinants `orient3d` and `orient2d`, computed with a floating-point filter and, when
//!   the filter cannot decide, exactly with Shewchuk's expansion arithmetic
//!   ("Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates",
//!   1997). The only assumption is that no product of two coordinate differences overflows
//!   or underflows (|coordinates| between about 1e-140 and 1e140, or 0), far beyond any scene.
//!
//! ## Triangle–triangle intersection
//!
//! Two closed triangles (possibly degenerate: collinear or coincident vertices) intersect
//! iff an edge of one meets the other. If they meet and are not coplanar, their
//! intersection is a segment or a point on the line common to both planes, whose ends lie on
//! the boundary of one of them; if coplanar, either two edges cross or one triangle contains
//! a vertex of the other; a degenerate triangle is the union of its edges. So the test is
//! six exact segment–triangle tests:
//!
//! * segment `pq` against a non-degenerate triangle `abc` whose plane it does not lie in:
//!   `pq` meets the plane (`orient3d(a,b,c,p)` and `orient3d(a,b,c,q)` not of the same strict
//!   sign) and the line `pq` passes through the closed triangle (the three volumes
//!   `orient3d(p,q,a,b)`, `orient3d(p,q,b,c)`, `orient3d(p,q,c,a)` not of strictly opposite
//!   signs);
//! * coplanar: project along an axis on which the triangle's shadow is not degenerate
//!   (an exact `orient2d ≠ 0`); then an endpoint inside the triangle or a crossing with one
//!   of its edges (exact 2-D segment test);
//! * a degenerate triangle: the segment against each of its three edges. Two segments
//!   meet iff they are coplanar (`orient3d = 0`) and their shadows meet on all three
//!   coordinate planes (necessary always; sufficient because at least one projection is
//!   one-to-one on their common plane or line).
//!
//! Triangles that share a vertex do intersect under this test; excluding mesh neighbours is
//! the caller's business.

use glam::{DVec2, DVec3};

/// The point of segment `(a, b)` closest to `p`: returns `(s, squared distance)` with the
/// point `a + s (b − a)`, `s ∈ [0, 1]`. A zero-length segment gives `s = 0`.
#[inline]
pub fn point_segment_closest(p: DVec3, a: DVec3, b: DVec3) -> (f64, f64) {
    let ab = b - a;
    let len2 = ab.length_squared();
    let s = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    // `is_nan` guard: an infinite `len2` gives NaN above; keep the answer on the segment.
    let s = if s.is_nan() { 0.0 } else { s };
    (s, (a + s * ab - p).length_squared())
}

/// Closest point on triangle `(a, b, c)` to `p`: returns (barycentric `[u, v, w]` with
/// `u + v + w = 1`, all `≥ 0`, the point being `u a + v b + w c`; squared distance). Robust
/// for degenerate (zero-area) triangles: then the answer is the closest point of its edges.
pub fn point_triangle_closest(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> ([f64; 3], f64) {
    // Boundary candidates: the three edges (always well defined).
    let (s_ab, d_ab) = point_segment_closest(p, a, b);
    let (s_bc, d_bc) = point_segment_closest(p, b, c);
    let (s_ca, d_ca) = point_segment_closest(p, c, a);
    let mut best = ([1.0 - s_ab, s_ab, 0.0], d_ab);
    if d_bc < best.1 {
        best = ([0.0, 1.0 - s_bc, s_bc], d_bc);
    }
    if d_ca < best.1 {
        best = ([s_ca, 0.0, 1.0 - s_ca], d_ca);
    }
    // Interior candidate: the orthogonal projection, when it falls inside.
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    let (abab, acac, abac) = (ab.dot(ab), ac.dot(ac), ab.dot(ac));
    let det = abab * acac - abac * abac;
    if det > 0.0 && det.is_finite() {
        let v = (d1 * acac - d2 * abac) / det;
        let w = (d2 * abab - d1 * abac) / det;
        if v >= 0.0 && w >= 0.0 && v + w <= 1.0 {
            let u = 1.0 - v - w;
            let q = u * a + v * b + w * c;
            let d = (q - p).length_squared();
            if d < best.1 {
                best = ([u, v, w], d);
            }
        }
    }
    best
}

/// The squared distance from `p` to triangle `(a, b, c)`: [`point_triangle_closest`]'s to
/// rounding, in about half its work, for the separations a pass keeps
/// ([`crate::narrow_phase::pairs::vertex_face_separation`]). The Voronoi region of `p` (a corner, an edge or
/// the face) found from six dot products, then the one closest point of that region
/// (Ericson, *Real-Time Collision Detection*, 5.1.5): exact for a proper triangle. Slivers
/// (the squared sine of the angle at `a` at most 1e-6) and degenerate ones take
/// [`point_triangle_closest`]'s candidates instead.
#[inline]
pub fn point_triangle_distance_squared(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let ab = b - a;
    let ac = c - a;
    let (abab, acac, abac) = (ab.dot(ab), ac.dot(ac), ab.dot(ac));
    // A NaN is not well conditioned either: the robust path decides.
    let well_conditioned = abab * acac - abac * abac > 1e-6 * abab * acac;
    if !well_conditioned {
        return point_triangle_closest(p, a, b, c).1;
    }
    let ap = p - a;
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (ap - v * ab).length_squared();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (ap - w * ac).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (bp - w * (c - b)).length_squared();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (ap - v * ab - w * ac).length_squared()
}

/// Closest points between segments `(a, b)` and `(c, d)`: returns `(s, t, squared distance)`
/// with the points `a + s (b − a)` and `c + t (d − c)`, `s, t ∈ [0, 1]`. Robust for parallel
/// and zero-length segments: the minimum is either the interior stationary point (used when
/// the segments are not parallel) or involves an endpoint (the four endpoint–segment
/// candidates), and the best candidate is returned.
pub fn segment_segment_closest(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> (f64, f64, f64) {
    let (t_a, d_a) = point_segment_closest(a, c, d);
    let (t_b, d_b) = point_segment_closest(b, c, d);
    let (s_c, d_c) = point_segment_closest(c, a, b);
    let (s_d, d_d) = point_segment_closest(d, a, b);
    let mut best = (0.0, t_a, d_a);
    if d_b < best.2 {
        best = (1.0, t_b, d_b);
    }
    if d_c < best.2 {
        best = (s_c, 0.0, d_c);
    }
    if d_d < best.2 {
        best = (s_d, 1.0, d_d);
    }
    // Interior candidate: both parameters strictly inside, from the 2×2 normal equations.
    let u = b - a;
    let v = d - c;
    let r = a - c;
    let (uu, vv, uv) = (u.dot(u), v.dot(v), u.dot(v));
    let (ur, vr) = (u.dot(r), v.dot(r));
    let det = uu * vv - uv * uv;
    if det > 0.0 && det.is_finite() {
        let s = (uv * vr - ur * vv) / det;
        let t = (uu * vr - uv * ur) / det;
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            let dist = (a + s * u - (c + t * v)).length_squared();
            if dist < best.2 {
                best = (s, t, dist);
            }
        }
    }
    best
}

/// The squared distance between segments `(a, b)` and `(c, d)`: [`segment_segment_closest`]'s
/// to rounding, in about a third of its work, for the separations a pass keeps
/// ([`crate::narrow_phase::pairs::edge_edge_separation`]). The stationary point of `|a + s u − c − t v|²`
/// with `s` clamped, `t` solved for that `s` and, if it falls outside, clamped with `s` solved
/// again (Ericson, *Real-Time Collision Detection*, 5.1.9): exact for segments that are not
/// parallel. Near-parallel pairs (`sin² θ ≤ 1e-6`) and zero-length ones, where the stationary
/// point is ill-conditioned, take [`segment_segment_closest`]'s candidates instead.
#[inline]
pub fn segment_segment_distance_squared(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    let u = b - a;
    let v = d - c;
    let (uu, vv, uv) = (u.dot(u), v.dot(v), u.dot(v));
    let det = uu * vv - uv * uv;
    // A NaN is not well conditioned either: the robust path decides.
    let well_conditioned = det > 1e-6 * uu * vv;
    if !well_conditioned {
        return segment_segment_closest(a, b, c, d).2;
    }
    let r = a - c;
    let (ur, vr) = (u.dot(r), v.dot(r));
    let s = ((uv * vr - ur * vv) / det).clamp(0.0, 1.0);
    let t = (uv * s + vr) / vv;
    let (s, t) = if t < 0.0 {
        ((-ur / uu).clamp(0.0, 1.0), 0.0)
    } else if t > 1.0 {
        (((uv - ur) / uu).clamp(0.0, 1.0), 1.0)
    } else {
        (s, t)
    };
    (r + s * u - t * v).length_squared()
}

/// Exact triangle–triangle intersection test of the closed triangles `t1` and `t2`
/// (touching counts; degenerate triangles allowed). See the module docs for the method.
/// Triangles sharing vertices are the caller's business (they intersect here).
pub fn triangles_intersect(t1: [DVec3; 3], t2: [DVec3; 3]) -> bool {
    (0..3).any(|i| segment_triangle_intersect(t1[i], t1[(i + 1) % 3], t2))
        || (0..3).any(|i| segment_triangle_intersect(t2[i], t2[(i + 1) % 3], t1))
}

/// Exact test: does the closed segment `pq` meet the closed triangle `tri` (possibly
/// degenerate)?
pub fn segment_triangle_intersect(p: DVec3, q: DVec3, tri: [DVec3; 3]) -> bool {
    let [a, b, c] = tri;
    let Some(axis) = shadow_axis(a, b, c) else {
        // Degenerate triangle: the union of its edges.
        return segments_intersect(p, q, a, b)
            || segments_intersect(p, q, b, c)
            || segments_intersect(p, q, c, a);
    };
    let op = exact::orient3d(a, b, c, p);
    let oq = exact::orient3d(a, b, c, q);
    if op == 0 && oq == 0 {
        // Coplanar with a proper triangle: 2-D test in a one-to-one shadow.
        let (p, q) = (project(p, axis), project(q, axis));
        let (a, b, c) = (project(a, axis), project(b, axis), project(c, axis));
        return point_in_triangle_2d(p, a, b, c)
            || point_in_triangle_2d(q, a, b, c)
            || segments_intersect_2d(p, q, a, b)
            || segments_intersect_2d(p, q, b, c)
            || segments_intersect_2d(p, q, c, a);
    }
    if op * oq > 0 {
        return false;
    }
    // The segment meets the plane in one point; is that point in the triangle?
    let s1 = exact::orient3d(p, q, a, b);
    let s2 = exact::orient3d(p, q, b, c);
    let s3 = exact::orient3d(p, q, c, a);
    !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0))
}

/// Exact test: do the closed segments `ab` and `cd` in space meet (zero lengths allowed)?
pub fn segments_intersect(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> bool {
    exact::orient3d(a, b, c, d) == 0
        && (0..3).all(|axis| {
            segments_intersect_2d(
                project(a, axis),
                project(b, axis),
                project(c, axis),
                project(d, axis),
            )
        })
}

/// An axis along which the shadow of triangle `abc` on the other two coordinates is a proper
/// triangle (exactly), or `None` if the triangle is degenerate (its vertices collinear).
fn shadow_axis(a: DVec3, b: DVec3, c: DVec3) -> Option<usize> {
    (0..3).find(|&axis| exact::orient2d(project(a, axis), project(b, axis), project(c, axis)) != 0)
}

/// Drop coordinate `axis`.
#[inline]
fn project(p: DVec3, axis: usize) -> DVec2 {
    match axis {
        0 => DVec2::new(p.y, p.z),
        1 => DVec2::new(p.z, p.x),
        _ => DVec2::new(p.x, p.y),
    }
}

/// `p` in the closed, non-degenerate 2-D triangle `abc` (exact).
fn point_in_triangle_2d(p: DVec2, a: DVec2, b: DVec2, c: DVec2) -> bool {
    let s1 = exact::orient2d(a, b, p);
    let s2 = exact::orient2d(b, c, p);
    let s3 = exact::orient2d(c, a, p);
    !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0))
}

/// Do the closed 2-D segments `pq` and `rs` meet (exact; zero lengths allowed)?
fn segments_intersect_2d(p: DVec2, q: DVec2, r: DVec2, s: DVec2) -> bool {
    let d1 = exact::orient2d(r, s, p);
    let d2 = exact::orient2d(r, s, q);
    let d3 = exact::orient2d(p, q, r);
    let d4 = exact::orient2d(p, q, s);
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    (d1 == 0 && in_box(r, s, p))
        || (d2 == 0 && in_box(r, s, q))
        || (d3 == 0 && in_box(p, q, r))
        || (d4 == 0 && in_box(p, q, s))
}

/// `x` in the bounding box of `a` and `b` (exact comparisons).
fn in_box(a: DVec2, b: DVec2, x: DVec2) -> bool {
    a.x.min(b.x) <= x.x && x.x <= a.x.max(b.x) && a.y.min(b.y) <= x.y && x.y <= a.y.max(b.y)
}

/// Exact signs of orientation determinants (Shewchuk 1997): a floating-point evaluation with
/// a proven error bound, and, when that cannot decide, an exact evaluation as a
/// floating-point *expansion* (a sum of non-overlapping doubles).
pub mod exact {
    use glam::{DVec2, DVec3};

    /// Half an ulp of 1: the unit roundoff of `f64` (2⁻⁵³).
    const EPS: f64 = f64::EPSILON * 0.5;
    /// Shewchuk's `ccwerrboundA` and `o3derrboundA`.
    const CCW_BOUND: f64 = (3.0 + 16.0 * EPS) * EPS;
    const O3D_BOUND: f64 = (7.0 + 56.0 * EPS) * EPS;

    /// `x + y = s + e` exactly, `s = fl(x + y)`.
    #[inline]
    fn two_sum(x: f64, y: f64) -> (f64, f64) {
        let s = x + y;
        let bv = s - x;
        let av = s - bv;
        (s, (x - av) + (y - bv))
    }

    /// `x − y = s + e` exactly.
    #[inline]
    fn two_diff(x: f64, y: f64) -> (f64, f64) {
        let s = x - y;
        let bv = x - s;
        let av = s + bv;
        (s, (x - av) + (bv - y))
    }

    /// `x · y = p + e` exactly (fused multiply-add gives the rounding error).
    #[inline]
    fn two_product(x: f64, y: f64) -> (f64, f64) {
        let p = x * y;
        (p, x.mul_add(y, -p))
    }

    /// `e + f` (Shewchuk's `fast_expansion_sum_zeroelim`, written with `two_sum` so it
    /// does not need the two inputs to be strongly non-overlapping). Returns the length.
    fn sum(e: &[f64], f: &[f64], h: &mut [f64]) -> usize {
        // Linear merge by magnitude, then a running two_sum (Shewchuk's `linear` variant
        // would also do; this is his Theorem 13 form, valid for non-overlapping inputs).
        let (mut i, mut j, mut n) = (0, 0, 0);
        let mut q;
        let next = |i: &mut usize, j: &mut usize| -> f64 {
            if *j >= f.len() || (*i < e.len() && e[*i].abs() <= f[*j].abs()) {
                *i += 1;
                e[*i - 1]
            } else {
                *j += 1;
                f[*j - 1]
            }
        };
        if e.is_empty() && f.is_empty() {
            return 0;
        }
        q = next(&mut i, &mut j);
        while i < e.len() || j < f.len() {
            let x = next(&mut i, &mut j);
            let (s, err) = two_sum(q, x);
            if err != 0.0 {
                h[n] = err;
                n += 1;
            }
            q = s;
        }
        if q != 0.0 || n == 0 {
            h[n] = q;
            n += 1;
        }
        n
    }

    /// `e · b` (Shewchuk's `scale_expansion_zeroelim`). Returns the length.
    fn scale(e: &[f64], b: f64, h: &mut [f64]) -> usize {
        let mut n = 0;
        let (mut q, lo) = two_product(e[0], b);
        if lo != 0.0 {
            h[n] = lo;
            n += 1;
        }
        for &x in &e[1..] {
            let (p1, p0) = two_product(x, b);
            let (s, err) = two_sum(q, p0);
            if err != 0.0 {
                h[n] = err;
                n += 1;
            }
            let (s2, err2) = two_sum(p1, s);
            if err2 != 0.0 {
                h[n] = err2;
                n += 1;
            }
            q = s2;
        }
        if q != 0.0 || n == 0 {
            h[n] = q;
            n += 1;
        }
        n
    }

    /// `e · f` for short expansions: Σᵢ e · fᵢ. Returns the length.
    fn product(e: &[f64], f: &[f64], h: &mut [f64]) -> usize {
        let mut acc = [0.0; 64];
        let mut tmp = [0.0; 64];
        let mut term = [0.0; 32];
        let mut n = 0;
        for &x in f {
            let m = scale(e, x, &mut term);
            let k = sum(&acc[..n], &term[..m], &mut tmp);
            acc[..k].copy_from_slice(&tmp[..k]);
            n = k;
        }
        h[..n].copy_from_slice(&acc[..n]);
        n
    }

    /// Sign of an expansion: that of its largest (last) nonzero component.
    fn sign(e: &[f64]) -> i32 {
        e.iter()
            .rev()
            .find(|&&x| x != 0.0)
            .map_or(0, |&x| if x > 0.0 { 1 } else { -1 })
    }

    /// `x − y` as an expansion of length ≤ 2 written into `h`.
    fn diff(x: f64, y: f64, h: &mut [f64; 2]) -> usize {
        let (s, e) = two_diff(x, y);
        match (e != 0.0, s != 0.0) {
            (true, _) => {
                *h = [e, s];
                2
            }
            (false, true) => {
                h[0] = s;
                1
            }
            (false, false) => {
                h[0] = 0.0;
                1
            }
        }
    }

    /// Sign of `(b − a) × (c − a)` (2-D): +1 when `a, b, c` turn counter-clockwise, −1
    /// clockwise, 0 when collinear — exact.
    pub fn orient2d(a: DVec2, b: DVec2, c: DVec2) -> i32 {
        let l = (b.x - a.x) * (c.y - a.y);
        let r = (b.y - a.y) * (c.x - a.x);
        let det = l - r;
        let bound = CCW_BOUND * (l.abs() + r.abs());
        if det > bound {
            return 1;
        }
        if -det > bound {
            return -1;
        }
        orient2d_exact(a, b, c)
    }

    fn orient2d_exact(a: DVec2, b: DVec2, c: DVec2) -> i32 {
        let (mut bax, mut cay, mut bay, mut cax) = ([0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2]);
        let n_bax = diff(b.x, a.x, &mut bax);
        let n_cay = diff(c.y, a.y, &mut cay);
        let n_bay = diff(b.y, a.y, &mut bay);
        let n_cax = diff(c.x, a.x, &mut cax);
        let mut l = [0.0; 8];
        let mut r = [0.0; 8];
        let nl = product(&bax[..n_bax], &cay[..n_cay], &mut l);
        let nr = product(&bay[..n_bay], &cax[..n_cax], &mut r);
        for x in &mut r[..nr] {
            *x = -*x;
        }
        let mut det = [0.0; 16];
        let n = sum(&l[..nl], &r[..nr], &mut det);
        sign(&det[..n])
    }

    /// Sign of `det[b − a; c − a; d − a]` (the triple product `(b − a)·((c − a) × (d − a))`):
    /// 0 exactly when the four points are coplanar — exact.
    pub fn orient3d(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> i32 {
        let (u, v, w) = (b - a, c - a, d - a);
        let m1 = v.y * w.z;
        let m2 = v.z * w.y;
        let m3 = v.z * w.x;
        let m4 = v.x * w.z;
        let m5 = v.x * w.y;
        let m6 = v.y * w.x;
        let det = u.x * (m1 - m2) + u.y * (m3 - m4) + u.z * (m5 - m6);
        let permanent = (m1.abs() + m2.abs()) * u.x.abs()
            + (m3.abs() + m4.abs()) * u.y.abs()
            + (m5.abs() + m6.abs()) * u.z.abs();
        // Shewchuk's bound is for differences taken exactly; ours are rounded, which his
        // orient3d also does (its `adx = pa[0] - pd[0]` etc.), so the same bound holds.
        let bound = O3D_BOUND * permanent;
        if det.is_finite() && bound.is_finite() {
            if det > bound {
                return 1;
            }
            if -det > bound {
                return -1;
            }
        }
        orient3d_exact(a, b, c, d)
    }

    fn orient3d_exact(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> i32 {
        let mut u = [[0.0; 2]; 3];
        let mut v = [[0.0; 2]; 3];
        let mut w = [[0.0; 2]; 3];
        let mut nu = [0; 3];
        let mut nv = [0; 3];
        let mut nw = [0; 3];
        for k in 0..3 {
            nu[k] = diff(b[k], a[k], &mut u[k]);
            nv[k] = diff(c[k], a[k], &mut v[k]);
            nw[k] = diff(d[k], a[k], &mut w[k]);
        }
        // det = Σ over the cyclic (i, j, k): u_i (v_j w_k − v_k w_j).
        let mut total = [0.0; 192];
        let mut n_total = 0;
        for (i, j, k) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
            let mut p = [0.0; 8];
            let mut q = [0.0; 8];
            let np = product(&v[j][..nv[j]], &w[k][..nw[k]], &mut p);
            let nq = product(&v[k][..nv[k]], &w[j][..nw[j]], &mut q);
            for x in &mut q[..nq] {
                *x = -*x;
            }
            let mut minor = [0.0; 16];
            let nm = sum(&p[..np], &q[..nq], &mut minor);
            let mut term = [0.0; 64];
            let nt = product(&minor[..nm], &u[i][..nu[i]], &mut term);
            let mut acc = [0.0; 192];
            let na = sum(&total[..n_total], &term[..nt], &mut acc);
            total[..na].copy_from_slice(&acc[..na]);
            n_total = na;
        }
        sign(&total[..n_total])
    }
}

// Beside this file rather than in `distance/`: the workspace tests include this file by path
// (`tests/tests/collision_*.rs`), and a path is resolved from the file that names it.
#[cfg(test)]
#[path = "distance_tests.rs"]
mod tests;
