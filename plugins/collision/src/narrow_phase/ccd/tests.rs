use super::*;
use crate::narrow_phase::distance::{point_triangle_closest, segment_segment_closest};

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// The unit right triangle in the plane z = 0.
const TRI: [DVec3; 3] = [
    DVec3::new(0.0, 0.0, 0.0),
    DVec3::new(1.0, 0.0, 0.0),
    DVec3::new(0.0, 1.0, 0.0),
];

/// Point–triangle CCD of a point moving `p0 → p1` against a static triangle.
fn pt_static(p0: DVec3, p1: DVec3, tri: [DVec3; 3], d: f64) -> CcdResult {
    point_triangle_ccd(
        [p0, tri[0], tri[1], tri[2]],
        [p1, tri[0], tri[1], tri[2]],
        d,
        &CcdOptions::default(),
    )
}

fn ee(start: [DVec3; 4], end: [DVec3; 4], d: f64) -> CcdResult {
    edge_edge_ccd(start, end, d, &CcdOptions::default())
}

fn at(x0: [DVec3; 4], x1: [DVec3; 4], t: f64) -> [DVec3; 4] {
    [0, 1, 2, 3].map(|i| (1.0 - t) * x0[i] + t * x1[i])
}

fn pt_distance(x: [DVec3; 4]) -> f64 {
    point_triangle_closest(x[0], x[1], x[2], x[3]).1.sqrt()
}

fn ee_distance(x: [DVec3; 4]) -> f64 {
    segment_segment_closest(x[0], x[1], x[2], x[3]).2.sqrt()
}

/// The answer `t` is a contact time no later than `latest`, and the distance at it is
/// within the result's margin of the thickness.
#[track_caller]
fn assert_contact(r: CcdResult, latest: f64, distance_at: impl Fn(f64) -> f64, d: f64) {
    let t = r
        .toi
        .unwrap_or_else(|| panic!("missed contact (latest {latest}): {r:?}"));
    assert!(
        (0.0..=latest).contains(&t),
        "toi {t} later than {latest}: {r:?}"
    );
    assert!(r.certified, "{r:?}");
    let dist = distance_at(t);
    assert!(
        dist <= d + r.margin * 1.001 + 1e-14,
        "distance {dist} at toi {t}: {r:?}"
    );
}

#[test]
fn static_point_on_static_triangle_touches_at_zero() {
    // Inside the face, on an edge, on a vertex: all exactly in the plane.
    for p in [
        v(0.25, 0.25, 0.0),
        v(0.5, 0.5, 0.0),
        v(0.0, 0.3, 0.0),
        TRI[1],
    ] {
        let r = pt_static(p, p, TRI, 0.0);
        assert_eq!(r.toi, Some(0.0), "{p}: {r:?}");
    }
    // Just off the plane, statically: never.
    let r = pt_static(v(0.25, 0.25, 1e-3), v(0.25, 0.25, 1e-3), TRI, 0.0);
    assert_eq!(r.toi, None);
}

#[test]
fn point_landing_on_the_face_at_the_end_touches_at_one() {
    let (p0, p1) = (v(0.2, 0.3, 1.0), v(0.2, 0.3, 0.0));
    let r = pt_static(p0, p1, TRI, 0.0);
    assert_contact(
        r,
        1.0,
        |t| pt_distance(at([p0, TRI[0], TRI[1], TRI[2]], [p1; 4], t)),
        0.0,
    );
    assert!(r.toi.unwrap() > 1.0 - 1e-5);
    // Stopping 1e-4 short is no contact.
    let r = pt_static(p0, v(0.2, 0.3, 1e-4), TRI, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
}

#[test]
fn point_crossing_the_face_hits_just_before_the_analytic_time() {
    // Crosses z = 0 at t = 0.3 inside the face.
    let (p0, p1) = (v(0.1, 0.2, 0.3), v(0.4, 0.1, -0.7));
    let start = [p0, TRI[0], TRI[1], TRI[2]];
    let end = [p1, TRI[0], TRI[1], TRI[2]];
    let r = point_triangle_ccd(start, end, 0.0, &CcdOptions::default());
    assert_contact(r, 0.3, |t| pt_distance(at(start, end, t)), 0.0);
    assert!(r.toi.unwrap() > 0.3 - 1e-5, "{r:?}");
    // A moving, rotating triangle and a point at rest, with the same relative motion
    // at the crossing: still found.
    let shift = v(-0.3, 0.1, 1.0);
    let end2 = [p0, TRI[0] + shift, TRI[1] + shift, TRI[2] + shift * 1.5];
    let start2 = [p0, TRI[0], TRI[1], TRI[2]];
    let r = point_triangle_ccd(start2, end2, 0.0, &CcdOptions::default());
    assert!(r.toi.is_some(), "{r:?}");
}

#[test]
fn point_passing_outside_an_edge_misses_and_on_it_hits() {
    // Falls through the plane at x + y = 1 + 1e-3 (outside the hypotenuse), then on it.
    let r = pt_static(v(0.5, 0.501, 1.0), v(0.5, 0.501, -1.0), TRI, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
    let (p0, p1) = (v(0.5, 0.5, 1.0), v(0.5, 0.5, -1.0));
    let r = pt_static(p0, p1, TRI, 0.0);
    assert_contact(
        r,
        0.5,
        |t| {
            pt_distance(at(
                [p0, TRI[0], TRI[1], TRI[2]],
                [p1, TRI[0], TRI[1], TRI[2]],
                t,
            ))
        },
        0.0,
    );
    // Exactly through a corner.
    let r = pt_static(v(1.0, 0.0, 2.0), v(1.0, 0.0, -2.0), TRI, 0.0);
    assert!(r.toi.is_some_and(|t| t <= 0.5 && t > 0.49), "{r:?}");
}

#[test]
fn zero_area_triangles_are_hit_as_segments_and_points() {
    // Collinear vertices: the segment from (0,0,0) to (2,0,0).
    let needle = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let r = pt_static(v(1.5, 1.0, 1.0), v(1.5, -1.0, -1.0), needle, 0.0);
    assert!(r.toi.is_some_and(|t| t <= 0.5 && t > 0.49), "{r:?}");
    let r = pt_static(v(1.5, 1.0, 1.01), v(1.5, -1.0, -0.99), needle, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
    // Three coincident vertices: a point.
    let dot = [v(1.0, 2.0, 3.0); 3];
    let r = pt_static(v(0.0, 2.0, 3.0), v(4.0, 2.0, 3.0), dot, 0.0);
    assert!(r.toi.is_some_and(|t| t <= 0.25 && t > 0.249), "{r:?}");
    let r = pt_static(v(0.0, 2.0, 3.001), v(4.0, 2.0, 3.001), dot, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
}

#[test]
fn point_sliding_in_the_plane_enters_the_face_when_it_reaches_it() {
    // Coplanar motion: from (−1, 0.25, 0) to (1, 0.25, 0), entering at x = 0, t = 0.5.
    let r = pt_static(v(-1.0, 0.25, 0.0), v(1.0, 0.25, 0.0), TRI, 0.0);
    assert!(r.toi.is_some_and(|t| t <= 0.5 && t > 0.499), "{r:?}");
    // The same line 1e-3 above the plane: never.
    let r = pt_static(v(-1.0, 0.25, 1e-3), v(1.0, 0.25, 1e-3), TRI, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
    // In the plane but passing beside the face.
    let r = pt_static(v(-1.0, 1.5, 0.0), v(3.0, 1.5, 0.0), TRI, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
}

#[test]
fn bullet_crossing_a_tiny_triangle_in_one_step_is_caught() {
    let s = 1e-3;
    let tiny = [v(5.0, 5.0, 5.0), v(5.0 + s, 5.0, 5.0), v(5.0, 5.0 + s, 5.0)];
    let (p0, p1) = (
        v(5.0 + s / 4.0, 5.0 + s / 4.0, -995.0),
        v(5.0 + s / 4.0, 5.0 + s / 4.0, 1005.0),
    );
    let start = [p0, tiny[0], tiny[1], tiny[2]];
    let end = [p1, tiny[0], tiny[1], tiny[2]];
    let r = point_triangle_ccd(start, end, 0.0, &CcdOptions::default());
    assert_contact(r, 0.5, |t| pt_distance(at(start, end, t)), 0.0);
    // Passing 1e-2 beside it (far more than the margin 1.7e-6 × 2000): never.
    let beside = v(1e-2, 0.0, 0.0);
    let r = pt_static(p0 + beside, p1 + beside, tiny, 0.0);
    assert_eq!(r.toi, None, "{r:?}");
}

#[test]
fn thickness_makes_spheres_cylinders_and_slabs() {
    // Passing 0.5 above the face (slab), beside the hypotenuse (cylinder) and beside the
    // vertex (1, 0, 0) (sphere), each at distance 0.5.
    let slab = (v(-1.0, 0.25, 0.5), v(2.0, 0.25, 0.5));
    let off = 0.5 / 2f64.sqrt();
    let cyl = (v(0.5 + off, 0.5 + off, -1.0), v(0.5 + off, 0.5 + off, 1.0));
    let sph = (v(1.5, -1.0, 0.0), v(1.5, 1.0, 0.0));
    for (p0, p1) in [slab, cyl, sph] {
        let start = [p0, TRI[0], TRI[1], TRI[2]];
        let end = [p1, TRI[0], TRI[1], TRI[2]];
        let closest = (0..=2000)
            .map(|k| pt_distance(at(start, end, k as f64 / 2000.0)))
            .fold(f64::INFINITY, f64::min);
        assert!((closest - 0.5).abs() < 1e-6, "{closest}");
        let r = pt_static(p0, p1, TRI, 0.51);
        assert_contact(r, 1.0, |t| pt_distance(at(start, end, t)), 0.51);
        let r = pt_static(p0, p1, TRI, 0.49);
        assert_eq!(r.toi, None, "{p0} → {p1}: {r:?}");
    }
}

#[test]
fn static_crossing_edges_touch_at_zero() {
    let x = [
        v(-1.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.3, -1.0, 0.0),
        v(0.3, 1.0, 0.0),
    ];
    assert_eq!(ee(x, x, 0.0).toi, Some(0.0));
    // An endpoint exactly on the other edge.
    let y = [x[0], x[1], v(0.3, 0.0, 0.0), v(0.3, 1.0, 5.0)];
    assert_eq!(ee(y, y, 0.0).toi, Some(0.0));
    // Skew, 1e-3 apart: never; with thickness 1e-3 (touching): at once.
    let z = [
        x[0],
        x[1],
        x[2] + v(0.0, 0.0, 1e-3),
        x[3] + v(0.0, 0.0, 1e-3),
    ];
    assert_eq!(ee(z, z, 0.0).toi, None);
    assert_eq!(ee(z, z, 1e-3).toi, Some(0.0));
}

#[test]
fn parallel_edges_sliding_in_contact_or_apart() {
    // Collinear, overlapping, sliding along each other: in contact all the time.
    let a = [
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.5, 0.0, 0.0),
        v(2.0, 0.0, 0.0),
    ];
    let b = [a[0], a[1], v(-0.5, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    assert_eq!(ee(a, b, 0.0).toi, Some(0.0));
    // Parallel at distance 1e-3, sliding: never; with thickness 2e-3: at once.
    let up = v(0.0, 1e-3, 0.0);
    let a2 = [a[0], a[1], a[2] + up, a[3] + up];
    let b2 = [b[0], b[1], b[2] + up, b[3] + up];
    assert_eq!(ee(a2, b2, 0.0).toi, None);
    assert_eq!(ee(a2, b2, 2e-3).toi, Some(0.0));
    // Parallel, landing flat on each other at t = 0.75.
    let start = [a[0], a[1], v(0.5, 0.75, 0.0), v(2.0, 0.75, 0.0)];
    let end = [a[0], a[1], v(0.5, -0.25, 0.0), v(2.0, -0.25, 0.0)];
    let r = ee(start, end, 0.0);
    assert_contact(r, 0.75, |t| ee_distance(at(start, end, t)), 0.0);
    assert!(r.toi.unwrap() > 0.75 - 1e-5, "{r:?}");
}

#[test]
fn zero_length_edges_collide_as_points() {
    // Two points passing through each other at t = 0.5.
    let (p, q) = (v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0));
    let start = [p, p, q, q];
    let end = [q, q, p, p];
    let r = ee(start, end, 0.0);
    assert_contact(r, 0.5, |t| ee_distance(at(start, end, t)), 0.0);
    // Passing 1e-3 apart: never.
    let off = v(1e-3, -1e-3, 0.0);
    let r = ee(start, [q + off, q + off, p, p], 0.0);
    assert_eq!(r.toi, None, "{r:?}");
    // A point hitting the middle of an edge at t = 0.25.
    let start = [
        v(0.5, 1.0, 0.0),
        v(0.5, 1.0, 0.0),
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
    ];
    let end = [v(0.5, -3.0, 0.0), v(0.5, -3.0, 0.0), start[2], start[3]];
    let r = ee(start, end, 0.0);
    assert_contact(r, 0.25, |t| ee_distance(at(start, end, t)), 0.0);
    assert!(r.toi.unwrap() > 0.25 - 1e-5);
}

#[test]
fn endpoint_reaching_the_other_edge_exactly_at_the_end_touches_at_one() {
    let start = [
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.5, 0.0, 1.0),
        v(0.5, 1.0, 2.0),
    ];
    let end = [start[0], start[1], v(0.5, 0.0, 0.0), v(0.5, 1.0, 1.0)];
    let r = ee(start, end, 0.0);
    assert_contact(r, 1.0, |t| ee_distance(at(start, end, t)), 0.0);
    assert!(r.toi.unwrap() > 1.0 - 1e-5);
}

#[test]
fn skew_edges_crossing_hit_just_before_the_analytic_time() {
    // Edge (c, d) along y at height z = 1 − 2t crosses edge (a, b) along x at t = 0.5.
    let start = [
        v(-1.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.2, -1.0, 1.0),
        v(0.2, 1.0, 1.0),
    ];
    let end = [start[0], start[1], v(0.2, -1.0, -1.0), v(0.2, 1.0, -1.0)];
    let r = ee(start, end, 0.0);
    assert_contact(r, 0.5, |t| ee_distance(at(start, end, t)), 0.0);
    assert!(r.toi.unwrap() > 0.5 - 1e-5);
}

#[test]
fn non_finite_input_is_reported_as_an_unproven_contact() {
    let bad = v(f64::NAN, 0.0, 0.0);
    let r = pt_static(bad, bad, TRI, 0.0);
    assert_eq!(r.toi, Some(0.0));
    assert!(!r.certified);
    let inf = v(f64::INFINITY, 0.0, 0.0);
    let r = ee(
        [inf, TRI[0], TRI[1], TRI[2]],
        [inf, TRI[0], TRI[1], TRI[2]],
        0.0,
    );
    assert_eq!(r.toi, Some(0.0));
    // A NaN or negative thickness is 0; an infinite one is contact now.
    let (p0, p1) = (v(0.2, 0.2, 1.0), v(0.2, 0.2, 0.5));
    assert_eq!(pt_static(p0, p1, TRI, f64::NAN).toi, None);
    assert_eq!(pt_static(p0, p1, TRI, -1.0).toi, None);
    assert_eq!(pt_static(p0, p1, TRI, f64::INFINITY).toi, Some(0.0));
}

#[test]
fn work_is_bounded_and_the_fallback_is_never_late() {
    // A crossing at t = 0.3 found with only 5 cells allowed: an early, unproven answer.
    let (p0, p1) = (v(0.1, 0.2, 0.3), v(0.4, 0.1, -0.7));
    let options = CcdOptions {
        max_boxes: 5,
        ..CcdOptions::default()
    };
    let r = point_triangle_ccd(
        [p0, TRI[0], TRI[1], TRI[2]],
        [p1, TRI[0], TRI[1], TRI[2]],
        0.0,
        &options,
    );
    assert!(r.boxes <= 5 && !r.certified, "{r:?}");
    assert!(r.toi.is_some_and(|t| t <= 0.3), "{r:?}");
}

#[test]
fn swept_boxes_apart_need_no_cell() {
    let r = pt_static(v(3.0, 3.0, 3.0), v(3.0, 3.0, 2.0), TRI, 0.5);
    assert_eq!((r.toi, r.boxes), (None, 0));
    // Boxes 1 apart on x with thickness exactly 1 may touch: examined.
    let r = pt_static(v(2.0, 0.0, 0.0), v(2.0, 0.0, 0.0), TRI, 1.0);
    assert_eq!(r.toi, Some(0.0));
}

/// Near misses in a random orientation: a point crossing the triangle's plane just
/// outside an edge, an edge sweeping just past the end of another, and parallel edges
/// sliding past each other, all at a gap `g`. Beyond the margin (`g = 1e-4`) a
/// certified contact is impossible by contract; far inside it (`g = 1e-9`, the
/// adversarial gap of the reference set) the hull test still tells them apart.
#[test]
fn near_misses_are_not_reported() {
    let mut rng = Rng(99);
    for g in [1e-4, 1e-9] {
        for case in 0..60 {
            let axis = rng.vec3(1.0).normalize();
            let (e1, e2) = axis.any_orthonormal_pair();
            let m = |p: DVec3| p.x * e1 + p.y * e2 + p.z * axis + v(0.3, -0.2, 0.7);
            let tri = [
                m(v(0.0, 0.0, 0.0)),
                m(v(1.0, 0.0, 0.0)),
                m(v(0.0, 1.0, 0.0)),
            ];
            let (s, tc) = (rng.next_f64(), rng.next_f64());
            let vel = v(rng.next_f64() - 0.5, -0.5 * rng.next_f64(), 1.0);
            let cross = v(s, -g, 0.0);
            let (p0, p1) = (m(cross - tc * vel), m(cross + (1.0 - tc) * vel));
            let r = point_triangle_ccd(
                [p0, tri[0], tri[1], tri[2]],
                [p1, tri[0], tri[1], tri[2]],
                0.0,
                &CcdOptions::default(),
            );
            assert_eq!(r.toi, None, "point, gap {g}, case {case}: {r:?}");
            let a = [tri[0], tri[1]];
            let b = |z: f64| [m(v(1.0 + g, -0.5, z)), m(v(1.0 + g, 0.5, z))];
            let (b0, b1) = (b(1.0 - tc), b(-tc));
            let r = ee([a[0], a[1], b0[0], b0[1]], [a[0], a[1], b1[0], b1[1]], 0.0);
            assert_eq!(r.toi, None, "skew edges, gap {g}, case {case}: {r:?}");
            let c0 = [m(v(0.5, g, 0.0)), m(v(1.5, g, 0.0))];
            let c1 = [m(v(-0.5, g, 0.0)), m(v(0.5, g, 0.0))];
            let r = ee([a[0], a[1], c0[0], c0[1]], [a[0], a[1], c1[0], c1[1]], 0.0);
            assert_eq!(r.toi, None, "parallel edges, gap {g}, case {case}: {r:?}");
        }
    }
}

use nucleus_sdk::testing::Rng;

/// Random linear motions with a contact built in exactly: at a dyadic time `t*` the
/// positions are small integers and the contact point a dyadic combination of them, so
/// every coordinate is exact and the distance at `t*` is exactly 0. A fifth of the cases
/// each are degenerate: zero area / zero length, coplanar or parallel motion, no motion.
#[test]
fn exact_contacts_built_into_random_motions_are_never_missed() {
    let mut rng = Rng(0x5eed);
    let mut hard = 0;
    for case in 0..3000 {
        let t_star = rng.pick(9) as f64 / 8.0;
        let kind = case % 5;
        let point_triangle = case % 2 == 0;
        let mut x = [rng.ivec(8), rng.ivec(8), rng.ivec(8), DVec3::ZERO];
        let w = [rng.pick(5) as f64 / 4.0, rng.pick(5) as f64 / 4.0];
        if point_triangle {
            let (a, b, c) = (x[0], x[1], x[2]);
            let (a, b, c) = match kind {
                1 => (a, b, a + 2.0 * (b - a)), // collinear
                2 => (a, a, a),                 // a point
                _ => (a, b, c),
            };
            let (u, v) = (w[0], w[1] * (1.0 - w[0]));
            let p = (1.0 - u - v) * a + u * b + v * c;
            x = [p, a, b, c];
        } else {
            let (a, b) = match kind {
                1 => (x[0], x[0]), // zero-length
                _ => (x[0], x[1]),
            };
            let q = a + w[0] * (b - a);
            let dir = match kind {
                2 => 2.0 * (b - a), // collinear, overlapping
                1 => DVec3::ZERO,   // zero-length too
                _ => rng.ivec(8),
            };
            x = [a, b, q - w[1] * dir, q + (1.0 - w[1]) * dir];
        }
        let mut vel = [rng.ivec(8), rng.ivec(8), rng.ivec(8), rng.ivec(8)];
        match kind {
            3 => {
                // Everything moves in one plane z = const through... the same z
                // velocity: coplanar relative motion along z is zero.
                let vz = vel[0].z;
                for u in &mut vel {
                    u.z = vz;
                }
            }
            4 => vel = [DVec3::ZERO; 4],
            _ => {}
        }
        let start = [0, 1, 2, 3].map(|i| x[i] - t_star * vel[i]);
        let end = [0, 1, 2, 3].map(|i| x[i] + (1.0 - t_star) * vel[i]);
        let (r, dist): (CcdResult, fn([DVec3; 4]) -> f64) = if point_triangle {
            (
                point_triangle_ccd(start, end, 0.0, &CcdOptions::default()),
                pt_distance,
            )
        } else {
            (
                edge_edge_ccd(start, end, 0.0, &CcdOptions::default()),
                ee_distance,
            )
        };
        assert_eq!(
            dist(at(start, end, t_star)),
            0.0,
            "case {case}: not built exactly"
        );
        let toi = r
            .toi
            .unwrap_or_else(|| panic!("case {case} missed: {start:?} → {end:?}"));
        assert!(toi <= t_star, "case {case}: toi {toi} > {t_star}");
        if r.certified {
            assert!(
                dist(at(start, end, toi)) <= r.margin * 1.001 + 1e-14,
                "case {case}"
            );
        }
        hard += (r.boxes > 1000) as u32;
    }
    assert!(hard < 30, "{hard} of 3000 cases needed over 1000 cells");
}

/// Random motions, random thickness, against an oracle: the exact distance at 400
/// sampled times. A miss is a sampled time at which the oracle finds the distance at most
/// the thickness (less 1e-12 for the oracle's own rounding) while the CCD says `None` or
/// a later time. Configurations are drawn so that close approaches are common.
#[test]
fn random_motions_are_never_missed_against_a_sampled_oracle() {
    let mut rng = Rng(42);
    let (mut contacts, mut reported) = (0, 0);
    for case in 0..1500 {
        let point_triangle = case % 2 == 0;
        let d = if case % 3 == 0 {
            0.0
        } else {
            0.3 * rng.next_f64()
        };
        // Start around the origin, end around the origin too, so paths cross.
        let start = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
        let end = [rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0), rng.vec3(1.0)];
        let (r, dist): (CcdResult, fn([DVec3; 4]) -> f64) = if point_triangle {
            (
                point_triangle_ccd(start, end, d, &CcdOptions::default()),
                pt_distance,
            )
        } else {
            (
                edge_edge_ccd(start, end, d, &CcdOptions::default()),
                ee_distance,
            )
        };
        let first = (0..=400)
            .map(|k| k as f64 / 400.0)
            .find(|&t| dist(at(start, end, t)) <= d - 1e-12);
        if let Some(t) = first {
            contacts += 1;
            let toi = r
                .toi
                .unwrap_or_else(|| panic!("case {case} missed at {t}: {r:?}"));
            assert!(toi <= t, "case {case}: toi {toi} after sampled contact {t}");
        }
        if let Some(toi) = r.toi {
            reported += 1;
            assert!((0.0..=1.0).contains(&toi));
            if r.certified {
                let gap = dist(at(start, end, toi));
                assert!(
                    gap <= d + r.margin * 1.001 + 1e-14,
                    "case {case}: {gap} at {toi}"
                );
            }
        }
    }
    // The test has teeth: many contacts, and not everything reported.
    assert!(
        contacts > 300 && reported < 1400,
        "{contacts} contacts, {reported} reported"
    );
}
