use super::*;

use nucleus_sdk::testing::Rng;

const A: DVec3 = DVec3::new(0.0, 0.0, 0.0);
const B: DVec3 = DVec3::new(1.0, 0.0, 0.0);
const C: DVec3 = DVec3::new(0.0, 1.0, 0.0);

fn close(x: f64, y: f64) -> bool {
    (x - y).abs() <= 1e-12 * (1.0 + x.abs().max(y.abs()))
}

#[test]
fn point_above_face_projects_inside() {
    let (bary, d2) = point_triangle_closest(DVec3::new(0.25, 0.25, 2.0), A, B, C);
    assert!(close(d2, 4.0), "{d2}");
    assert!(close(bary[0], 0.5) && close(bary[1], 0.25) && close(bary[2], 0.25));
}

#[test]
fn point_beyond_each_vertex_and_edge_snaps_to_it() {
    // Vertex regions.
    let (bary, d2) = point_triangle_closest(DVec3::new(-1.0, -1.0, 0.0), A, B, C);
    assert_eq!(bary, [1.0, 0.0, 0.0]);
    assert!(close(d2, 2.0));
    let (bary, _) = point_triangle_closest(DVec3::new(3.0, -0.5, 1.0), A, B, C);
    assert_eq!(bary, [0.0, 1.0, 0.0]);
    // Edge bc region: beyond the hypotenuse, at distance √2/2 in the plane.
    let (bary, d2) = point_triangle_closest(DVec3::new(1.0, 1.0, 0.0), A, B, C);
    assert!(close(bary[0], 0.0) && close(bary[1], 0.5) && close(bary[2], 0.5));
    assert!(close(d2, 0.5));
}

#[test]
fn degenerate_triangles_give_the_distance_to_their_segment_or_point() {
    // Collinear vertices: the triangle is the segment from (0,0,0) to (2,0,0).
    let m = DVec3::new(1.0, 0.0, 0.0);
    let e = DVec3::new(2.0, 0.0, 0.0);
    let (bary, d2) = point_triangle_closest(DVec3::new(1.5, 3.0, 4.0), A, m, e);
    assert!(close(d2, 25.0), "{d2}");
    let q = bary[0] * A + bary[1] * m + bary[2] * e;
    assert!((q - DVec3::new(1.5, 0.0, 0.0)).length() < 1e-12);
    assert!(bary.iter().all(|b| b.is_finite() && *b >= 0.0));
    // All three vertices coincide.
    let (bary, d2) = point_triangle_closest(DVec3::new(0.0, 0.0, 1.0), B, B, B);
    assert!(close(d2, 2.0));
    assert!(close(bary.iter().sum::<f64>(), 1.0));
}

/// Brute-force minimum of |p − q|² over a fine barycentric grid of the triangle.
fn sampled_point_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let n = 120;
    let mut best = f64::INFINITY;
    for i in 0..=n {
        for j in 0..=n - i {
            let (v, w) = (i as f64 / n as f64, j as f64 / n as f64);
            let q = (1.0 - v - w) * a + v * b + w * c;
            best = best.min((q - p).length_squared());
        }
    }
    best
}

#[test]
fn point_triangle_closest_is_never_beaten_by_sampling() {
    let mut rng = Rng(7);
    for _ in 0..200 {
        let (a, b, c) = (rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0));
        let p = rng.vec3(1.5);
        let (bary, d2) = point_triangle_closest(p, a, b, c);
        let q = bary[0] * a + bary[1] * b + bary[2] * c;
        assert!(close((q - p).length_squared(), d2));
        assert!(close(bary.iter().sum::<f64>(), 1.0) && bary.iter().all(|&x| x >= 0.0));
        let sampled = sampled_point_triangle(p, a, b, c);
        assert!(d2 <= sampled + 1e-12, "closest {d2} > sampled {sampled}");
        // And sampling comes close (grid spacing 1/120 of edges ≤ 2√3).
        assert!(sampled.sqrt() - d2.sqrt() < 0.05);
    }
}

#[test]
fn crossing_segments_meet_at_their_crossing() {
    let (s, t, d2) = segment_segment_closest(
        DVec3::new(-1.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.5, -1.0, 1.0),
        DVec3::new(0.5, 3.0, 1.0),
    );
    assert!(
        close(s, 0.75) && close(t, 0.25) && close(d2, 1.0),
        "{s} {t} {d2}"
    );
}

#[test]
fn parallel_and_zero_length_segments_have_the_right_distance() {
    // Parallel, overlapping on [1, 2] at distance 2.
    let (s, t, d2) = segment_segment_closest(
        DVec3::ZERO,
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(1.0, 2.0, 0.0),
        DVec3::new(5.0, 2.0, 0.0),
    );
    assert!(close(d2, 4.0), "{d2}");
    assert!((1.0..=2.0).contains(&(2.0 * s)) && close(2.0 * s, 1.0 + 4.0 * t));
    // Parallel, disjoint along the line: endpoint to endpoint.
    let (_, _, d2) = segment_segment_closest(
        DVec3::ZERO,
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(4.0, 0.0, 0.0),
        DVec3::new(3.0, 0.0, 0.0),
    );
    assert!(close(d2, 4.0));
    // A zero-length segment is a point.
    let p = DVec3::new(0.5, 1.0, 1.0);
    let (s, t, d2) = segment_segment_closest(A, B, p, p);
    assert!(close(s, 0.5) && t == 0.0 && close(d2, 2.0));
    // Two points.
    let (_, _, d2) = segment_segment_closest(A, A, B, B);
    assert!(close(d2, 1.0));
}

#[test]
fn segment_segment_closest_is_never_beaten_by_sampling() {
    let mut rng = Rng(11);
    for k in 0..300 {
        let (a, b, c) = (rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0));
        // Every third pair is exactly parallel, every fifth has a zero-length edge.
        let d = match k % 15 {
            0 | 3 | 6 | 9 | 12 => c + 0.7 * (b - a),
            5 | 10 => c,
            _ => rng.vec3(1.0),
        };
        let (s, t, d2) = segment_segment_closest(a, b, c, d);
        assert!((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t));
        let gap = a + s * (b - a) - (c + t * (d - c));
        assert!(close(gap.length_squared(), d2));
        let n = 200;
        let mut sampled = f64::INFINITY;
        for i in 0..=n {
            let q = a + (i as f64 / n as f64) * (b - a);
            sampled = sampled.min(point_segment_closest(q, c, d).1);
        }
        assert!(d2 <= sampled + 1e-12, "closest {d2} > sampled {sampled}");
    }
}

#[test]
fn the_quick_segment_distance_is_the_robust_one_to_rounding() {
    let mut rng = Rng(23);
    let mut quick_paths = 0;
    for k in 0..3000 {
        let scale = [1.0, 1e-3, 1e3][k % 3];
        let (a, b, c) = (rng.vec3(scale), rng.vec3(scale), rng.vec3(scale));
        // Exactly and nearly parallel, zero-length, short against long, and general.
        let d = match k % 10 {
            0 => c + 0.7 * (b - a),
            1 => c + 0.7 * (b - a) + rng.vec3(1e-5 * scale),
            2 => c,
            3 => c + rng.vec3(1e-4 * scale),
            _ => rng.vec3(scale),
        };
        let robust = segment_segment_closest(a, b, c, d).2;
        let quick = segment_segment_distance_squared(a, b, c, d);
        let size2 = [a, b, c, d].iter().map(|p| p.length_squared()).sum::<f64>();
        assert!(
            (quick - robust).abs() <= 1e-13 * size2,
            "case {k}: quick {quick:e} robust {robust:e}"
        );
        let u = b - a;
        let v = d - c;
        let det = u.length_squared() * v.length_squared() - u.dot(v).powi(2);
        quick_paths += usize::from(det > 1e-6 * u.length_squared() * v.length_squared());
    }
    // Most general pairs take the quick path (the clamped stationary point).
    assert!(quick_paths > 1800, "{quick_paths}");
}

#[test]
fn the_quick_point_triangle_distance_is_the_robust_one_to_rounding() {
    let mut rng = Rng(29);
    let mut quick_paths = 0;
    for k in 0..3000 {
        let scale = [1.0, 1e-3, 1e3][k % 3];
        let (a, b, p) = (rng.vec3(scale), rng.vec3(scale), rng.vec3(1.5 * scale));
        // Degenerate (a point, a segment), slivers, near the plane, and general.
        let (c, p) = match k % 10 {
            0 => (a, p),
            1 => (a + 0.4 * (b - a), p),
            2 => (a + 0.4 * (b - a) + rng.vec3(1e-5 * scale), p),
            3 => {
                let c = rng.vec3(scale);
                (c, (a + b + c) / 3.0 + rng.vec3(1e-6 * scale))
            }
            _ => (rng.vec3(scale), p),
        };
        let robust = point_triangle_closest(p, a, b, c).1;
        let quick = point_triangle_distance_squared(p, a, b, c);
        let size2 = [a, b, c, p].iter().map(|q| q.length_squared()).sum::<f64>();
        assert!(
            (quick - robust).abs() <= 1e-13 * size2,
            "case {k}: quick {quick:e} robust {robust:e}"
        );
        let (ab, ac) = (b - a, c - a);
        let det = ab.length_squared() * ac.length_squared() - ab.dot(ac).powi(2);
        quick_paths += usize::from(det > 1e-6 * ab.length_squared() * ac.length_squared());
    }
    assert!(quick_paths > 2000, "{quick_paths}");
}

/// Exact `det[b − a; c − a; d − a]` of integer points, in i128.
fn orient3d_i128(p: [[i64; 3]; 4]) -> i32 {
    let [a, b, c, d] = p.map(|x| x.map(|v| v as i128));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    let det = u[0] * (v[1] * w[2] - v[2] * w[1])
        + u[1] * (v[2] * w[0] - v[0] * w[2])
        + u[2] * (v[0] * w[1] - v[1] * w[0]);
    det.signum() as i32
}

#[test]
fn orient3d_is_exact_on_nearly_coplanar_points() {
    // Integer points up to 2^36, three of them exactly on the plane through the first
    // with normal n, and the fourth nudged by ±1 or 0 off it: far beyond f64's naive
    // accuracy (the products reach 2^108), exact in i128.
    let mut rng = Rng(3);
    let mut naive_wrong = 0;
    for k in 0..2000 {
        let big = 1i64 << 36;
        let a = [rng.int(big), rng.int(big), rng.int(big)];
        // Points a + i·e1 + j·e2 on a lattice plane spanned by small-ish integer vectors.
        let e1 = [rng.int(1 << 20), rng.int(1 << 20), rng.int(1 << 20)];
        let e2 = [rng.int(1 << 20), rng.int(1 << 20), rng.int(1 << 20)];
        let on = |i: i64, j: i64| [0, 1, 2].map(|m| a[m] + i * e1[m] + j * e2[m]);
        let b = on(rng.int(64), rng.int(64));
        let c = on(rng.int(64), rng.int(64));
        let mut d = on(rng.int(64), rng.int(64));
        d[k % 3] += (k as i64 % 3) - 1;
        let pts = [a, b, c, d];
        let want = orient3d_i128(pts);
        let [pa, pb, pc, pd] = pts.map(|x| DVec3::new(x[0] as f64, x[1] as f64, x[2] as f64));
        assert_eq!(exact::orient3d(pa, pb, pc, pd), want, "case {k}: {pts:?}");
        let (u, v, w) = (pb - pa, pc - pa, pd - pa);
        let naive = u.dot(v.cross(w));
        if (naive > 0.0) as i32 - ((naive < 0.0) as i32) != want {
            naive_wrong += 1;
        }
    }
    // The cases are hard: the plain floating-point determinant gets many wrong.
    assert!(
        naive_wrong > 100,
        "only {naive_wrong} naive failures: cases too easy"
    );
}

#[test]
fn orient3d_is_exact_with_non_representable_differences() {
    // Four points exactly on the plane z = x + y (each sum is exact), with coordinates
    // of wildly different magnitudes, so differences like 2^40 − 2^-35 are not doubles.
    let p = |x: f64, y: f64| DVec3::new(x, y, x + y);
    let (a, b, c) = (p(1.0, 3.0), p(2f64.powi(40), -7.0), p(-5.0, 2f64.powi(-20)));
    let d = p(2f64.powi(-35), 1.0);
    assert_eq!(exact::orient3d(a, b, c, d), 0);
    let above = DVec3::new(d.x, d.y, d.z.next_up());
    let below = DVec3::new(d.x, d.y, d.z.next_down());
    let s = exact::orient3d(a, b, c, above);
    assert_ne!(s, 0);
    assert_eq!(exact::orient3d(a, b, c, below), -s);
    // Every permutation of an exactly coplanar quadruple is still exactly coplanar.
    assert_eq!(exact::orient3d(d, c, b, a), 0);
    assert_eq!(exact::orient3d(b, d, a, c), 0);
}

#[test]
fn orient2d_is_exact_on_collinear_points() {
    let a = DVec2::new(0.1, 0.1);
    let b = DVec2::new(0.3, 0.3);
    // 0.1 and 0.3 are not exact in binary, but 0.1 + k·(0.3 − 0.1) stays on y = x.
    for k in 0..100 {
        let x = 0.1 + k as f64 * 0.37;
        assert_eq!(exact::orient2d(a, b, DVec2::new(x, x)), 0);
        assert_eq!(exact::orient2d(a, b, DVec2::new(x, x.next_up())), 1);
        assert_eq!(exact::orient2d(a, b, DVec2::new(x, x.next_down())), -1);
    }
}

fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
    [a.into(), b.into(), c.into()]
}

#[test]
fn piercing_and_separated_triangles() {
    let t1 = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let pierce = tri([0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.3, 0.25, 1.0]);
    assert!(triangles_intersect(t1, pierce));
    assert!(triangles_intersect(pierce, t1));
    let above = pierce.map(|p| p + DVec3::new(0.0, 0.0, 1.0 + 1e-15));
    assert!(!triangles_intersect(t1, above));
    // Touching exactly at a point: the lowest vertex at z = 0 on the face.
    let touch = pierce.map(|p| p + DVec3::new(0.0, 0.0, 1.0));
    assert!(triangles_intersect(t1, touch));
    // The same, moved outside the face by one ulp in x beyond the hypotenuse.
    let edge = tri([0.5, 0.5, 0.0], [0.5, 0.5, 1.0], [0.6, 0.6, 1.0]);
    assert!(triangles_intersect(t1, edge));
    let out = edge.map(|p| DVec3::new(p.x.next_up(), p.y, p.z));
    assert!(!triangles_intersect(t1, out));
}

#[test]
fn coplanar_triangles_overlap_touch_or_miss() {
    let t1 = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    // Inside one another (no edge crossings).
    let inner = tri([0.1, 0.1, 0.0], [0.2, 0.1, 0.0], [0.1, 0.2, 0.0]);
    assert!(triangles_intersect(t1, inner) && triangles_intersect(inner, t1));
    // Sharing only the vertex (1,0,0).
    let corner = tri([1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0]);
    assert!(triangles_intersect(t1, corner));
    let apart = tri([1.0 + 1e-15, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0]);
    assert!(!triangles_intersect(t1, apart));
    // In a tilted plane with inexact coordinates: a reflection across the hypotenuse
    // of a tilted triangle touches along that edge.
    let m = |x: f64, y: f64| DVec3::new(x, y, 0.1 * x + 0.3 * y);
    let s1 = [m(0.0, 0.0), m(1.0, 0.0), m(0.0, 1.0)];
    let s2 = [m(1.0, 0.0), m(0.0, 1.0), m(1.0, 1.0)];
    assert!(triangles_intersect(s1, s2));
}

#[test]
fn degenerate_triangles_intersect_as_segments_and_points() {
    let t1 = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    // A needle (collinear vertices) through the face.
    let needle = tri([0.3, 0.3, -1.0], [0.3, 0.3, 0.0], [0.3, 0.3, 2.0]);
    assert!(triangles_intersect(t1, needle) && triangles_intersect(needle, t1));
    let beside = needle.map(|p| p + DVec3::new(0.5, 0.5, 0.0));
    assert!(!triangles_intersect(t1, beside));
    // A point triangle on the face, on an edge, and just off it.
    let on = DVec3::new(0.25, 0.0, 0.0);
    assert!(triangles_intersect(t1, [on; 3]));
    assert!(!triangles_intersect(
        t1,
        [on - DVec3::new(0.0, 1e-300, 0.0); 3]
    ));
    let inside = DVec3::new(0.25, 0.25, 0.0);
    assert!(triangles_intersect([inside; 3], t1));
    // Two needles crossing, and two parallel ones.
    let n1 = tri([-1.0, 0.0, 0.5], [0.0, 0.0, 0.5], [1.0, 0.0, 0.5]);
    let n2 = tri([0.0, -1.0, 0.5], [0.0, 1.0, 0.5], [0.0, 0.0, 0.5]);
    assert!(triangles_intersect(n1, n2));
    let n3 = n1.map(|p| p + DVec3::new(0.0, 1e-9, 0.0));
    assert!(!triangles_intersect(n1, n3));
}

#[test]
fn triangles_intersect_agrees_with_a_sampled_distance_on_clear_cases() {
    // Random pairs. Two triangles meet iff an edge of one meets the other, so the
    // minimum over points sampled along the edges of the distance to the other triangle
    // is 0 up to the sampling resolution (< 0.009 here) exactly when they intersect.
    let mut rng = Rng(5);
    let mut hits = 0;
    for _ in 0..300 {
        let t1 = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
        let t2 = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
        // Minimum distance between the triangles: over edges of one against the other.
        let mut dmin = f64::INFINITY;
        for (s, o) in [(t1, t2), (t2, t1)] {
            for i in 0..3 {
                let (p, q) = (s[i], s[(i + 1) % 3]);
                for k in 0..=200 {
                    let x = p + (k as f64 / 200.0) * (q - p);
                    dmin = dmin.min(point_triangle_closest(x, o[0], o[1], o[2]).1.sqrt());
                }
            }
        }
        let meet = triangles_intersect(t1, t2);
        hits += meet as u32;
        if dmin > 1e-2 {
            assert!(!meet, "separated by {dmin} yet intersecting");
        }
        if meet {
            // Some edge point of one is within the sampling resolution of the other.
            assert!(dmin < 2e-2, "intersecting but {dmin} apart");
        }
    }
    assert!(
        hits > 20,
        "too few intersecting pairs ({hits}) for a meaningful test"
    );
}
