//! The inclusion test of one cell of the parameter domain (the module docs' points 2 and 3):
//! the proven error bound of its corner values, the box and hull exclusion tests, and the
//! acceptance of a cell as a contact.

use glam::DVec3;

use super::search::Examined;
use super::{CcdResult, GUARD};

/// Unit roundoff of `f64`.
const U: f64 = f64::EPSILON * 0.5;
/// Relative error bound of a computed corner coordinate (a proven `7u`, with margin).
const ERR_REL: f64 = 16.0 * U;
/// Absolute error bound for underflow (seven products of at most `2⁻¹⁰⁷⁵` each, with margin).
const ERR_ABS: f64 = f64::MIN_POSITIVE;
/// GJK iterations looking for a separating direction of one cell.
const HULL_STEPS: usize = 8;

/// Per-query constants of the search.
pub(super) struct Bounds {
    /// Error bound of every computed corner coordinate, per coordinate.
    pub(super) eps: DVec3,
    /// Thickness.
    pub(super) d: f64,
    /// Acceptance width `δ`.
    pub(super) delta: f64,
    /// The guaranteed distance margin `η = √3 (δ + 2 max ε)`, rounded up.
    pub(super) margin: f64,
    /// `(d + 2|ε|)²`: a cell whose hull has a point this close to 0 cannot be proven apart.
    pub(super) hopeless: f64,
}

impl Bounds {
    /// From every difference vector `eᵏ` of the query; `None` if any is not finite.
    pub(super) fn new<'a>(
        e: impl Iterator<Item = &'a DVec3>,
        d: f64,
        tolerance: f64,
    ) -> Option<Self> {
        let mut size = DVec3::ZERO;
        for x in e {
            if !x.is_finite() {
                return None;
            }
            size = size.max(x.abs());
        }
        let eps = size * ERR_REL + DVec3::splat(ERR_ABS);
        let tolerance = if tolerance > 0.0 { tolerance } else { 0.0 };
        let delta = tolerance * size.max_element();
        let margin = 1.733 * (delta + 2.0 * eps.max_element()) * GUARD + (GUARD - 1.0) * d;
        let hopeless = (d + 2.0 * eps.length()).powi(2);
        Some(Self {
            eps,
            d,
            delta,
            margin,
            hopeless,
        })
    }

    /// The answer `t = 0` when the squared distance `d2` at `t = 0`, computed from the
    /// difference vectors (rounding error a few `u·E`, below `|ε|` and the margin), is within
    /// `d + 2|ε|`: a contact up to rounding, so no false positive beyond rounding.
    pub(super) fn contact_at_start(&self, d2: f64) -> Option<CcdResult> {
        self.touches(d2).then_some(CcdResult {
            toi: Some(0.0),
            margin: self.margin,
            boxes: 0,
            certified: true,
        })
    }

    /// Is the cell a contact within the tolerance at its start time `t₀`? Either its image is
    /// at most `δ` wide (every point of the cell, `t₀` included, is then within
    /// `d + √3 (δ + 2ε)` of contact), or one of its corners at `t₀` is within `d + δ` of
    /// contact (a computed distance; the true one is within `|ε|` of it). The second test
    /// accepts large cells at a tangential first contact (a sphere or cylinder of thickness
    /// grazing a face, whose near-contact set is wide along the tangent).
    #[inline]
    pub(super) fn accepts(&self, ex: &Examined) -> bool {
        if (ex.hi - ex.lo).max_element() <= self.delta {
            return true;
        }
        let reach = self.d + self.delta;
        ex.corners[..ex.n / 2]
            .iter()
            .any(|f| f.length_squared() <= reach * reach)
    }

    /// Is a squared distance `d2` computed from the differences (rounding error a few
    /// `u·E`, below `|ε|`) within `d + 2|ε|`: a contact up to rounding?
    #[inline]
    pub(super) fn touches(&self, d2: f64) -> bool {
        let reach = self.d + 2.0 * self.eps.length();
        d2 <= reach * reach
    }

    /// Is every point of the cell farther than the thickness from contact? First the box
    /// of the corner values, then separating directions from the convex hull of the corners.
    #[inline]
    pub(super) fn excludes(&self, ex: &Examined, hint: &mut DVec3) -> bool {
        self.box_excludes(ex.lo, ex.hi) || self.hull_excludes(&ex.corners[..ex.n], hint)
    }

    /// Is every point of a box with corner values in `[lo, hi]` (computed) farther than the
    /// thickness from 0? Proven: the true values lie in `[lo − ε, hi + ε]`; the gaps to 0
    /// are rounded monotonically (a positive computed gap is a positive true gap, at most
    /// `1 + u` larger), and the comparisons carry the [`GUARD`].
    #[inline]
    pub(super) fn box_excludes(&self, lo: DVec3, hi: DVec3) -> bool {
        let gap = (lo - self.eps).max(-(hi + self.eps)).max(DVec3::ZERO);
        let m = gap.max_element();
        if m <= 0.0 {
            return false;
        }
        if m > self.d * GUARD {
            // One coordinate alone is farther than d.
            return true;
        }
        // Here d ≥ m / GUARD > 0, so d/m ≈ 1 or more: no underflow in (d/m)².
        let g = gap / m;
        let r = self.d / m;
        g.length_squared() > r * r * GUARD
    }

    /// Look for a direction `n` along which the whole convex hull of the corner values
    /// (which contains the cell's image) is farther than `d` from 0. The candidates are the
    /// iterates of GJK (Gilbert, Johnson, Keerthi 1988) converging to the point of the hull
    /// closest to 0, whose direction separates best. GJK is only a heuristic here: every
    /// candidate is verified rigorously ([`Self::separates`]), so its rounding can cost
    /// work, never correctness.
    pub(super) fn hull_excludes(&self, f: &[DVec3], hint: &mut DVec3) -> bool {
        // The direction that last separated a cell often separates its neighbours too.
        if *hint != DVec3::ZERO && self.separates(*hint, f).0 {
            return true;
        }
        let mut x = f[0];
        for y in &f[1..] {
            if y.length_squared() < x.length_squared() {
                x = *y;
            }
        }
        let mut simplex = [x; 4];
        let mut n = 1;
        for _ in 0..HULL_STEPS {
            // A point of the hull this close to 0 leaves no room for a proof.
            if x.length_squared() <= self.hopeless {
                return false;
            }
            let scale = x.abs().max_element();
            let dir = x / scale;
            let (separated, support) = self.separates(dir, f);
            if separated {
                *hint = dir;
                return true;
            }
            // No progress possible: x is (nearly) the closest point, and not far enough.
            if x.dot(x - support) <= 1e-9 * x.length_squared() {
                return false;
            }
            simplex[n] = support;
            n += 1;
            match closest_on_simplex(&mut simplex, &mut n) {
                Some(closer) => x = closer,
                None => return false,
            }
        }
        false
    }

    /// Is the hull of the (true) corner values farther than `d` from 0 along `n` (scaled to
    /// `max |nᶜ| = 1`)? Also returns the corner with the least `n · f`. Proven: the true
    /// corner values differ from the computed ones by at most `ε` per coordinate, so
    /// `n · f` by at most `|n|·ε`; the rounding of the dot products adds at most
    /// `3.1u |n|·max|f| < 0.2 |n|·ε`, so `1.5 |n|·ε` bounds both with room for the rounding
    /// of the bound itself.
    #[inline]
    pub(super) fn separates(&self, n: DVec3, f: &[DVec3]) -> (bool, DVec3) {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let mut support = f[0];
        for x in f {
            let p = n.dot(*x);
            if p < lo {
                lo = p;
                support = *x;
            }
            hi = hi.max(p);
        }
        let err = 1.5 * n.abs().dot(self.eps);
        let reach = self.d * n.length() * GUARD;
        (lo - err > reach || -hi - err > reach, support)
    }
}

/// Replace the simplex (2 to 4 points) by its smallest face containing the point closest to
/// the origin, and return that point; `None` when the origin is inside (a tetrahedron
/// containing it, as far as floating point tells) or the answer is not finite. Ericson's
/// Voronoi-region tests ("Real-Time Collision Detection", 2005, §5.1): a heuristic here, so
/// rounding can only make it less helpful, never wrong.
fn closest_on_simplex(w: &mut [DVec3; 4], n: &mut usize) -> Option<DVec3> {
    let (face, bary): ([DVec3; 3], [f64; 3]) = match *n {
        2 => {
            let ab = w[1] - w[0];
            let s = (-w[0].dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            if s.is_nan() {
                return None;
            }
            ([w[0], w[1], w[1]], [1.0 - s, s, 0.0])
        }
        3 => ([w[0], w[1], w[2]], closest_on_triangle(w[0], w[1], w[2])),
        _ => {
            let mut best: Option<([DVec3; 3], [f64; 3], f64)> = None;
            for (skip, [i, j, k]) in [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
                .into_iter()
                .enumerate()
            {
                // Only faces that have 0 on their outer side (away from the fourth point).
                let normal = (w[j] - w[i]).cross(w[k] - w[i]);
                if normal.dot(-w[i]) * normal.dot(w[skip] - w[i]) >= 0.0 {
                    continue;
                }
                let b = closest_on_triangle(w[i], w[j], w[k]);
                let x = b[0] * w[i] + b[1] * w[j] + b[2] * w[k];
                let d2 = x.length_squared();
                if best.is_none_or(|(_, _, e)| d2 < e) {
                    best = Some(([w[i], w[j], w[k]], b, d2));
                }
            }
            let (face, b, _) = best?;
            (face, b)
        }
    };
    let x = bary[0] * face[0] + bary[1] * face[1] + bary[2] * face[2];
    if !x.is_finite() {
        return None;
    }
    *n = 0;
    for (p, b) in face.iter().zip(bary) {
        if b > 0.0 {
            w[*n] = *p;
            *n += 1;
        }
    }
    if *n == 0 {
        w[0] = x;
        *n = 1;
    }
    Some(x)
}

/// Barycentric weights of the point of triangle `(a, b, c)` closest to the origin (Ericson
/// §5.1.5); degenerate triangles fall back to the robust [`point_triangle_closest`].
///
/// [`point_triangle_closest`]: crate::narrow_phase::distance::point_triangle_closest
fn closest_on_triangle(a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let ab = b - a;
    let ac = c - a;
    let (d1, d2) = (-ab.dot(a), -ac.dot(a));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let (d3, d4) = (-ab.dot(b), -ac.dot(b));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let (d5, d6) = (-ab.dot(c), -ac.dot(c));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let sum = va + vb + vc;
    if sum > 0.0 && sum.is_finite() {
        let (v, w) = (vb / sum, vc / sum);
        [1.0 - v - w, v, w]
    } else {
        crate::narrow_phase::distance::point_triangle_closest(DVec3::ZERO, a, b, c).0
    }
}
