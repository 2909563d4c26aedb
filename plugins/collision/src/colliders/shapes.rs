//! Analytic colliders: plane, sphere, box and capsule, as pure functions of their rest
//! frame (their motion is [`super::motion`]'s).
//!
//! A shape is defined in its *rest frame* (the coordinates written in the scene); its pose at
//! time `t` maps the rest frame to the world, `x = R(t) q + T(t)`. Every query is done in the
//! rest frame: a particle's motion over a substep `[x0, x1]` becomes `[q0, q1]` with
//! `q0 = pose(t)⁻¹ x0`, `q1 = pose(t + h)⁻¹ x1` — exact for translations, and a linear
//! interpolation of the relative motion for rotations (both ends exact).
//!
//! [`Shape::signed_distance`] returns the exact Euclidean signed distance `φ` (negative
//! inside) and its gradient `n` (the outward normal of the closest surface point). `φ` is
//! 1-Lipschitz, so [`first_contact`] finds the earliest `t ∈ [0, 1]` where
//! `φ(q0 + t (q1 − q0)) ≤ r` without missing any: in closed form for the plane (linear) and
//! the sphere (quadratic), by conservative advancement for the box and the capsule
//! (`t ← t + (φ − r)/|q1 − q0|` never steps past the first root).

use glam::{DQuat, DVec3};

use super::motion::Motion;

/// A shape in its rest frame. The solid side is the inside (`φ < 0`); for the plane, the
/// side opposite its normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// The half-space below the plane through `point` with unit `normal`.
    Plane {
        /// A point of the plane (m).
        point: DVec3,
        /// Unit outward normal.
        normal: DVec3,
    },
    /// A ball.
    Sphere {
        /// Centre (m).
        center: DVec3,
        /// Radius (m).
        radius: f64,
    },
    /// An oriented box.
    Box {
        /// Centre (m).
        center: DVec3,
        /// Half side lengths (m).
        half_extents: DVec3,
        /// Orientation.
        rotation: DQuat,
    },
    /// All points within `radius` of the segment `a–b`.
    Capsule {
        /// First end of the axis (m).
        a: DVec3,
        /// Second end of the axis (m).
        b: DVec3,
        /// Radius (m).
        radius: f64,
    },
}

/// An analytic collider: a shape, its motion, and its own thickness (added to the
/// vertices').
#[derive(Clone, Debug, PartialEq)]
pub struct Collider {
    /// The shape in its rest frame.
    pub shape: Shape,
    /// Its motion.
    pub motion: Motion,
    /// Extra collision radius of the shape (m).
    pub thickness: f64,
    /// Collision layers (bitmask): only objects sharing a bit collide with it.
    pub layers: u32,
}

/// A unit vector perpendicular-ish fallback when a direction is undefined.
const FALLBACK_NORMAL: DVec3 = DVec3::Y;

fn normalize_or(v: DVec3, fallback: DVec3) -> DVec3 {
    let l = v.length();
    if l > 1e-300 && l.is_finite() {
        v / l
    } else {
        fallback
    }
}

impl Shape {
    /// The signed distance `φ(q)` (m, negative inside) and the outward unit normal of the
    /// closest surface point (the gradient of `φ` where it exists).
    pub fn signed_distance(&self, q: DVec3) -> (f64, DVec3) {
        match *self {
            Shape::Plane { point, normal } => (normal.dot(q - point), normal),
            Shape::Sphere { center, radius } => {
                let d = q - center;
                let l = d.length();
                (l - radius, normalize_or(d, FALLBACK_NORMAL))
            }
            Shape::Capsule { a, b, radius } => {
                let ab = b - a;
                let len2 = ab.length_squared();
                let s = if len2 > 0.0 {
                    ((q - a).dot(ab) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let d = q - (a + ab * s);
                let fallback = normalize_or(ab.any_orthonormal_vector(), FALLBACK_NORMAL);
                (d.length() - radius, normalize_or(d, fallback))
            }
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => {
                let p = rotation.inverse() * (q - center);
                let d = p.abs() - half_extents;
                let outside = d.max(DVec3::ZERO);
                let (dist, local_n) = if d.max_element() > 0.0 {
                    let l = outside.length();
                    (l, normalize_or(outside * p.signum(), FALLBACK_NORMAL))
                } else {
                    // Inside: the nearest face.
                    let k = if d.x >= d.y && d.x >= d.z {
                        0
                    } else if d.y >= d.z {
                        1
                    } else {
                        2
                    };
                    let mut n = DVec3::ZERO;
                    n[k] = if p[k] >= 0.0 { 1.0 } else { -1.0 };
                    (d[k], n)
                };
                (dist, rotation * local_n)
            }
        }
    }

    /// An axis-aligned box (in the rest frame) containing every point within `margin` of the
    /// shape; infinite for the plane.
    pub fn bounds(&self, margin: f64) -> (DVec3, DVec3) {
        match *self {
            Shape::Plane { .. } => (DVec3::splat(f64::NEG_INFINITY), DVec3::splat(f64::INFINITY)),
            Shape::Sphere { center, radius } => {
                let r = DVec3::splat(radius + margin);
                (center - r, center + r)
            }
            Shape::Capsule { a, b, radius } => {
                let r = DVec3::splat(radius + margin);
                (a.min(b) - r, a.max(b) + r)
            }
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => {
                let m = glam::DMat3::from_quat(rotation);
                let e = DVec3::new(
                    m.row(0).abs().dot(half_extents),
                    m.row(1).abs().dot(half_extents),
                    m.row(2).abs().dot(half_extents),
                ) + DVec3::splat(margin);
                (center - e, center + e)
            }
        }
    }
}

/// The core of a shape and its sharp features, in the rest frame: the shape is the set of
/// points within `radius` of the convex core (a sphere: its centre; a capsule: its axis; a
/// box: the box itself, radius 0), and `points` and `edges` are the vertices and edges of
/// that core. See [`Shape::features`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Features {
    /// Vertices of the core (m, rest frame).
    pub points: Vec<DVec3>,
    /// Edges of the core (m, rest frame).
    pub edges: Vec<[DVec3; 2]>,
    /// Distance from the core to the shape's surface (m).
    pub radius: f64,
}

impl Shape {
    /// The sharp features a cloth face or edge must be tested against so that no part of it
    /// (not only its vertices) enters the shape. The distance between a triangle and the
    /// shape is its distance to the core minus `radius`, and the distance between two convex
    /// polytopes (the triangle and the core) is attained at a vertex of one against the other,
    /// or at an edge of each. The triangle's vertices are the vertex–collider test
    /// ([`first_contact`], exact signed distance); the rest is the core's vertices against
    /// the triangle and the core's edges against the triangle's edges, both ordinary
    /// point–triangle and edge–edge queries of [`crate::narrow_phase::ccd`] with thickness `radius` plus
    /// the thicknesses in play. The plane has none: a half-space's distance to a triangle or
    /// a segment is attained at a vertex.
    pub fn features(&self) -> Features {
        match *self {
            Shape::Plane { .. } => Features::default(),
            Shape::Sphere { center, radius } => Features {
                points: vec![center],
                edges: Vec::new(),
                radius,
            },
            Shape::Capsule { a, b, radius } => Features {
                points: if a == b { vec![a] } else { vec![a, b] },
                edges: if a == b { Vec::new() } else { vec![[a, b]] },
                radius,
            },
            Shape::Box {
                center,
                half_extents,
                rotation,
            } => {
                // Corner k has the sign of axis i negative when bit i of k is 0.
                let corner = |k: usize| {
                    let s = |i: usize| if k & (1 << i) == 0 { -1.0 } else { 1.0 };
                    center
                        + rotation
                            * DVec3::new(
                                s(0) * half_extents.x,
                                s(1) * half_extents.y,
                                s(2) * half_extents.z,
                            )
                };
                let points: Vec<DVec3> = (0..8).map(corner).collect();
                let mut edges = Vec::with_capacity(12);
                for k in 0..8 {
                    for i in 0..3 {
                        if k & (1 << i) == 0 {
                            edges.push([points[k], points[k | (1 << i)]]);
                        }
                    }
                }
                Features {
                    points,
                    edges,
                    radius: 0.0,
                }
            }
        }
    }
}

/// Iteration cap of the conservative advancement; reaching it reports a (conservative) hit.
pub const MAX_ADVANCEMENT_STEPS: usize = 100;

/// The earliest `t ∈ [0, 1]` at which `q(t) = q0 + t (q1 − q0)` comes within `r` of the
/// shape (`φ(q(t)) ≤ r`), or `None` if it never does. Never misses a contact: closed form for
/// the plane and the sphere, conservative advancement otherwise (a grazing path that does not
/// converge within [`MAX_ADVANCEMENT_STEPS`] is reported as a hit at the last safe `t`).
pub fn first_contact(shape: &Shape, q0: DVec3, q1: DVec3, r: f64) -> Option<f64> {
    let (phi0, _) = shape.signed_distance(q0);
    if phi0 <= r {
        return Some(0.0);
    }
    let d = q1 - q0;
    match *shape {
        Shape::Plane { point, normal } => {
            let phi1 = normal.dot(q1 - point);
            if phi1 > r {
                return None;
            }
            Some(((phi0 - r) / (phi0 - phi1)).clamp(0.0, 1.0))
        }
        Shape::Sphere { center, radius } => {
            // |q0 − c + t d|² = (R + r)²: the smaller root.
            let m = q0 - center;
            let rr = radius + r;
            let a = d.length_squared();
            if a == 0.0 {
                return None;
            }
            let b = m.dot(d);
            let c = m.length_squared() - rr * rr; // > 0: q0 is outside
            let disc = b * b - a * c;
            if b >= 0.0 || disc < 0.0 {
                return None;
            }
            // Numerically stable smaller root: t = c / (−b + √disc).
            let t = c / (-b + disc.sqrt());
            (t <= 1.0).then_some(t.max(0.0))
        }
        _ => {
            let len = d.length();
            if len == 0.0 {
                return None;
            }
            let (phi1, _) = shape.signed_distance(q1);
            let tol = 1e-9 * (1.0 + r);
            let mut t = 0.0;
            let mut gap = phi0 - r;
            for _ in 0..MAX_ADVANCEMENT_STEPS {
                t += gap / len;
                if t > 1.0 {
                    return (phi1 <= r).then_some(1.0);
                }
                gap = shape.signed_distance(q0 + d * t).0 - r;
                if gap <= tol {
                    return Some(t);
                }
            }
            Some(t)
        }
    }
}

/// Whether the segment `p–q` meets the *open* box of half extents `h` centred at the origin
/// (axis-aligned): some point of it is strictly inside. Touching the surface is not meeting
/// it. Slab test: the parameters where the segment is strictly within each slab, intersected.
pub fn segment_enters_box(p: DVec3, q: DVec3, h: DVec3) -> bool {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let d = q - p;
    for k in 0..3 {
        if d[k] == 0.0 {
            if p[k].abs() >= h[k] {
                return false;
            }
            continue;
        }
        let (a, b) = ((-h[k] - p[k]) / d[k], (h[k] - p[k]) / d[k]);
        let (a, b) = (a.min(b), a.max(b));
        lo = lo.max(a);
        hi = hi.min(b);
        if lo >= hi {
            return false;
        }
    }
    lo < hi
}

/// Whether the triangle `t` meets the *open* box of half extents `h` centred at the origin
/// (axis-aligned), by separating axes: the box's three face normals, the triangle's normal and
/// the nine cross products of their edges; an axis along which the projections at most touch
/// separates them. A degenerate triangle is tested as its edges.
pub fn triangle_enters_box(t: [DVec3; 3], h: DVec3) -> bool {
    let e = [t[1] - t[0], t[2] - t[1], t[0] - t[2]];
    let normal = e[0].cross(e[1]);
    if normal.length_squared() <= f64::MIN_POSITIVE {
        return (0..3).any(|i| segment_enters_box(t[i], t[(i + 1) % 3], h));
    }
    let separates = |axis: DVec3| {
        let r = h.x * axis.x.abs() + h.y * axis.y.abs() + h.z * axis.z.abs();
        let s = t.map(|v| v.dot(axis));
        let (lo, hi) = (s[0].min(s[1]).min(s[2]), s[0].max(s[1]).max(s[2]));
        lo >= r || hi <= -r
    };
    if [DVec3::X, DVec3::Y, DVec3::Z, normal]
        .into_iter()
        .any(separates)
    {
        return false;
    }
    for edge in e {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let a = edge.cross(axis);
            if a.length_squared() > 1e-30 * edge.length_squared() && separates(a) {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colliders::motion::euler_xyz_degrees;

    #[test]
    fn a_segment_enters_a_box_only_through_its_interior() {
        let h = DVec3::new(1.0, 2.0, 3.0);
        let v = DVec3::new;
        // Through the middle, one end inside, both ends far outside across a corner region.
        assert!(segment_enters_box(v(-5.0, 0.0, 0.0), v(5.0, 0.0, 0.0), h));
        assert!(segment_enters_box(v(0.5, 0.5, 0.5), v(9.0, 9.0, 9.0), h));
        assert!(segment_enters_box(v(0.5, -3.0, 0.0), v(1.5, 3.0, 0.0), h));
        // Along a face, through an edge, touching a corner, passing by: not in the interior.
        assert!(!segment_enters_box(v(-5.0, 2.0, 0.0), v(5.0, 2.0, 0.0), h));
        assert!(!segment_enters_box(v(0.0, 3.0, 0.0), v(2.0, 1.0, 0.0), h));
        assert!(!segment_enters_box(v(1.0, 2.0, 3.0), v(2.0, 3.0, 4.0), h));
        assert!(!segment_enters_box(v(1.5, 0.0, 0.0), v(1.5, 5.0, 5.0), h));
        // A point segment.
        assert!(segment_enters_box(v(0.0, 0.0, 0.0), v(0.0, 0.0, 0.0), h));
        assert!(!segment_enters_box(v(1.0, 0.0, 0.0), v(1.0, 0.0, 0.0), h));
    }

    #[test]
    fn a_triangle_enters_a_box_when_they_share_interior_points() {
        let h = DVec3::splat(1.0);
        let v = DVec3::new;
        // A big triangle the box pokes through (no vertex inside, no edge through it).
        assert!(triangle_enters_box(
            [v(-10.0, -10.0, 0.5), v(10.0, -10.0, 0.5), v(0.0, 10.0, 0.5)],
            h
        ));
        // A triangle cutting a corner of the box (z = 0, along x + y = 1.9 < 2).
        assert!(triangle_enters_box(
            [v(0.4, 1.5, 0.0), v(1.5, 0.4, 0.0), v(1.5, 1.5, 0.0)],
            h
        ));
        // The same beyond the corner (x + y = 2.3): the faces' normals and its own do not
        // separate it, the cross product of its edge and the box's z edge does.
        assert!(!triangle_enters_box(
            [v(0.8, 1.5, 0.0), v(1.5, 0.8, 0.0), v(1.5, 1.5, 0.0)],
            h
        ));
        // Lying on a face, or beyond it: no.
        assert!(!triangle_enters_box(
            [v(-0.5, -0.5, 1.0), v(0.5, -0.5, 1.0), v(0.0, 0.5, 1.0)],
            h
        ));
        assert!(!triangle_enters_box(
            [v(-5.0, -5.0, 1.2), v(5.0, -5.0, 1.2), v(0.0, 5.0, 1.2)],
            h
        ));
        // A degenerate triangle is its edges.
        assert!(triangle_enters_box(
            [v(-5.0, 0.0, 0.0), v(5.0, 0.0, 0.0), v(0.0, 0.0, 0.0)],
            h
        ));
    }

    fn shapes() -> Vec<Shape> {
        vec![
            Shape::Plane {
                point: DVec3::new(0.0, -0.2, 0.0),
                normal: DVec3::new(0.3, 1.0, 0.1).normalize(),
            },
            Shape::Sphere {
                center: DVec3::new(0.1, 0.0, -0.1),
                radius: 0.4,
            },
            Shape::Box {
                center: DVec3::new(0.0, 0.1, 0.0),
                half_extents: DVec3::new(0.3, 0.2, 0.5),
                rotation: euler_xyz_degrees(DVec3::new(20.0, 35.0, -10.0)),
            },
            Shape::Capsule {
                a: DVec3::new(-0.3, 0.0, 0.0),
                b: DVec3::new(0.4, 0.2, 0.1),
                radius: 0.15,
            },
        ]
    }

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    fn random_point(seed: &mut u64) -> DVec3 {
        DVec3::new(lcg(seed), lcg(seed), lcg(seed))
    }

    #[test]
    fn signed_distance_gradient_matches_finite_differences() {
        let mut seed = 7;
        for shape in shapes() {
            for _ in 0..200 {
                let q = random_point(&mut seed);
                let (phi, n) = shape.signed_distance(q);
                let e = 1e-6;
                let fd = DVec3::new(
                    shape.signed_distance(q + DVec3::X * e).0
                        - shape.signed_distance(q - DVec3::X * e).0,
                    shape.signed_distance(q + DVec3::Y * e).0
                        - shape.signed_distance(q - DVec3::Y * e).0,
                    shape.signed_distance(q + DVec3::Z * e).0
                        - shape.signed_distance(q - DVec3::Z * e).0,
                ) / (2.0 * e);
                // Skip the medial ridges of the box, where φ has a kink.
                if (fd.length() - 1.0).abs() < 1e-4 {
                    assert!((fd - n).length() < 1e-4, "{shape:?} at {q}: {fd} vs {n}");
                }
                assert!((n.length() - 1.0).abs() < 1e-12);
                // q − φ n lies on the surface.
                let on = shape.signed_distance(q - n * phi).0;
                assert!(on.abs() < 1e-9, "{shape:?} at {q}: φ = {phi}, surface {on}");
            }
        }
    }

    #[test]
    fn first_contact_never_misses_a_sampled_contact_and_is_earliest() {
        let mut seed = 11;
        for shape in shapes() {
            for _ in 0..300 {
                let q0 = random_point(&mut seed) * 1.5;
                let q1 = random_point(&mut seed) * 1.5;
                let r = 0.02;
                let toi = first_contact(&shape, q0, q1, r);
                // Dense sampling: the first sample within r.
                let sampled = (0..=2000)
                    .map(|k| k as f64 / 2000.0)
                    .find(|&t| shape.signed_distance(q0.lerp(q1, t)).0 <= r);
                match (toi, sampled) {
                    (None, Some(t)) => panic!("{shape:?}: missed a contact at t = {t}"),
                    (Some(t), Some(s)) => {
                        assert!(t <= s + 1e-12, "{shape:?}: toi {t} after sample {s}")
                    }
                    _ => {}
                }
                if let Some(t) = toi {
                    // At the time of impact the point is (nearly) at distance r, never inside.
                    let phi = shape.signed_distance(q0.lerp(q1, t)).0;
                    if t > 0.0 {
                        assert!(phi >= r - 1e-9, "{shape:?}: φ {phi} at toi {t}");
                    }
                }
            }
        }
    }

    #[test]
    fn features_are_the_cores_vertices_and_edges_at_depth_radius() {
        for shape in shapes() {
            let f = shape.features();
            let expected = match shape {
                Shape::Plane { .. } => (0, 0),
                Shape::Sphere { .. } => (1, 0),
                Shape::Capsule { .. } => (2, 1),
                Shape::Box { .. } => (8, 12),
            };
            assert_eq!((f.points.len(), f.edges.len()), expected, "{shape:?}");
            // Every point of the core lies `radius` inside the surface.
            let mut core: Vec<DVec3> = f.points.clone();
            for [a, b] in &f.edges {
                core.extend((1..4).map(|k| a.lerp(*b, k as f64 / 4.0)));
            }
            for p in core {
                let (phi, _) = shape.signed_distance(p);
                assert!((phi + f.radius).abs() < 1e-12, "{shape:?} at {p}: {phi}");
            }
            if let Shape::Box { half_extents, .. } = shape {
                // The 12 edges: 4 along each axis, each as long as that side.
                let mut lengths: Vec<f64> = f.edges.iter().map(|[a, b]| a.distance(*b)).collect();
                lengths.sort_by(f64::total_cmp);
                let mut sides = [half_extents.x, half_extents.y, half_extents.z].map(|h| 2.0 * h);
                sides.sort_by(f64::total_cmp);
                for (k, l) in lengths.iter().enumerate() {
                    assert!((l - sides[k / 4]).abs() < 1e-12, "{lengths:?}");
                }
            }
        }
    }

    #[test]
    fn bounds_contain_the_shape_and_margin() {
        let mut seed = 3;
        for shape in shapes().into_iter().skip(1) {
            let (lo, hi) = shape.bounds(0.05);
            for _ in 0..2000 {
                let q = random_point(&mut seed);
                if shape.signed_distance(q).0 <= 0.05 {
                    assert!(q.cmpge(lo).all() && q.cmple(hi).all(), "{shape:?} {q}");
                }
            }
        }
    }
}
