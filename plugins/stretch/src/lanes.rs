//! The edge pass four edges at a time, in the processor's 256-bit lanes (AVX2), where the
//! processor has them: the same arithmetic as [`project_distance_hard`] (hard edges) and
//! [`project_distance_with`] (compliant ones), operation for operation, so every position and
//! multiplier comes out with the same bits as the one-edge kernels (no fused multiply-add, whose
//! single rounding would differ). The four edges of a lane group are
//! consecutive edges of one colour, so they share no particle: their corrections are computed
//! together and written back one by one. The edges left over after the last group of four, and
//! every edge on a processor without AVX2, take the one-edge kernel.
//!
//! Why: within a colour the edges are independent, but the one-edge kernel spends two square
//! roots, a division and some forty scalar operations on each, and the processor's reorder
//! window holds few edges at once; the lanes do each operation for four edges. Measured in the
//! crate docs' "Cost" section: the hard pass 1.5× faster, the compliant one 2.2×.
//!
//! The lanes' loads, stores and arithmetic are the SDK's [`nucleus_sdk::lanes`].
//!
//! [`project_distance_hard`]: crate::distance::project_distance_hard
//! [`project_distance_with`]: crate::distance::project_distance_with

use glam::DVec3;
#[cfg(any(test, target_arch = "x86_64"))]
use nucleus_sdk::lanes::avx2_available;
use nucleus_sdk::team::SharedArray;

use crate::distance::{project_distance_hard, project_distance_with, Correction, XpbdTerms};

/// Projects the edges `ids[k]` in order, one at a time, each moved by the correction
/// `project(k, positions, start positions, inverse masses, rest length)` returns.
///
/// # Safety
/// `x` points to at least `max index + 1` positions, valid for the duration of the call, and
/// no other thread reads or writes the positions of these edges' particles meanwhile.
#[inline(always)]
unsafe fn each_edge(
    x: SharedArray<DVec3>,
    x0: &[DVec3],
    w: &[f64],
    ids: &[[u32; 2]],
    rest: &[f64],
    mut project: impl FnMut(usize, [DVec3; 2], [DVec3; 2], [f64; 2], f64) -> Option<Correction>,
) {
    for (k, (&[i, j], &rest)) in ids.iter().zip(rest).enumerate() {
        let (i, j) = (i as usize, j as usize);
        let (pi, pj) = (x.at(i), x.at(j));
        // SAFETY: indices are in bounds (checked against the state before the pass) and the
        // caller guarantees exclusive access to particles i and j.
        let (xi, xj) = unsafe { (*pi, *pj) };
        if let Some(c) = project(k, [xi, xj], [x0[i], x0[j]], [w[i], w[j]], rest) {
            // SAFETY: as above.
            unsafe {
                *pi = xi + c.dxi;
                *pj = xj + c.dxj;
            }
        }
    }
}

/// Projects the hard edges `ids[k]`, in order, with the one-edge kernel: the reference the
/// four-lane kernel must match bit for bit, its fallback, and the kernel of a batch whose
/// edges share particles.
///
/// # Safety
/// As [`each_edge`].
pub(crate) unsafe fn project_edges_hard_one_by_one(
    x: SharedArray<DVec3>,
    x0: &[DVec3],
    w: &[f64],
    ids: &[[u32; 2]],
    rest: &[f64],
) {
    // SAFETY: the caller's contract.
    unsafe {
        each_edge(x, x0, w, ids, rest, |_, x, x0, w, rest| {
            project_distance_hard(x, x0, w, rest)
        })
    }
}

/// Projects the hard edges `ids[k]` of one colour (no two share a particle), in order, four at
/// a time where the processor can ([`avx2_available`]), with the same bits as
/// [`project_edges_hard_one_by_one`].
///
/// # Safety
/// As [`each_edge`], and no two of the edges share a particle.
///
/// [`avx2_available`]: nucleus_sdk::lanes::avx2_available
pub(crate) unsafe fn project_colour_hard(
    x: SharedArray<DVec3>,
    x0: &[DVec3],
    w: &[f64],
    ids: &[[u32; 2]],
    rest: &[f64],
) {
    #[cfg(target_arch = "x86_64")]
    if x0.len() == w.len() && avx2_available() {
        let whole = ids.len() / 4 * 4;
        // SAFETY: AVX2 is present (checked above); the rest is the caller's contract.
        unsafe {
            avx2::project_fours(x, x0, w, &ids[..whole], &rest[..whole]);
            project_edges_hard_one_by_one(x, x0, w, &ids[whole..], &rest[whole..]);
        }
        return;
    }
    // SAFETY: the caller's contract.
    unsafe { project_edges_hard_one_by_one(x, x0, w, ids, rest) }
}

/// Projects the compliant edges `ids[k]`, in order, accumulating each edge's multiplier in
/// `lambda[k]`, with the one-edge kernel: the reference of the four-lane kernel, and its
/// fallback.
///
/// # Safety
/// As [`each_edge`].
pub(crate) unsafe fn project_edges_compliant_one_by_one(
    x: SharedArray<DVec3>,
    x0: &[DVec3],
    w: &[f64],
    ids: &[[u32; 2]],
    rest: &[f64],
    lambda: &mut [f64],
    terms: &XpbdTerms,
) {
    let project = |k: usize, x, x0, w, rest| {
        let c = project_distance_with(x, x0, w, rest, terms, lambda[k])?;
        lambda[k] += c.delta_lambda;
        Some(c)
    };
    // SAFETY: the caller's contract.
    unsafe { each_edge(x, x0, w, ids, rest, project) }
}

/// Projects the compliant edges `ids[k]` of one colour, in order, accumulating each edge's
/// multiplier in `lambda[k]`, four at a time where the processor can ([`avx2_available`]),
/// with the same bits as [`project_edges_compliant_one_by_one`].
///
/// # Safety
/// As [`project_colour_hard`].
///
/// [`avx2_available`]: nucleus_sdk::lanes::avx2_available
pub(crate) unsafe fn project_colour_compliant(
    x: SharedArray<DVec3>,
    x0: &[DVec3],
    w: &[f64],
    ids: &[[u32; 2]],
    rest: &[f64],
    lambda: &mut [f64],
    terms: &XpbdTerms,
) {
    #[cfg(target_arch = "x86_64")]
    if x0.len() == w.len() && lambda.len() == ids.len() && avx2_available() {
        let whole = ids.len() / 4 * 4;
        let (four, left) = lambda.split_at_mut(whole);
        // SAFETY: AVX2 is present (checked above); the rest is the caller's contract.
        unsafe {
            avx2::project_fours_compliant(x, x0, w, &ids[..whole], &rest[..whole], four, terms);
            project_edges_compliant_one_by_one(
                x,
                x0,
                w,
                &ids[whole..],
                &rest[whole..],
                left,
                terms,
            );
        }
        return;
    }
    // SAFETY: the caller's contract.
    unsafe { project_edges_compliant_one_by_one(x, x0, w, ids, rest, lambda, terms) }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use nucleus_sdk::lanes::avx2::{dot, load, moved, neg, scale, select3, store, sub, Lanes3};

    use super::*;
    use crate::distance::{MIN_LENGTH, START_DIRECTION_MIN_COS};

    /// What both kernels compute of four edges, as `distance::EdgeStep` does of one:
    /// the loaded particles, `d = xj − xi`, `|d|`, `wi`, `wj` and their sum, whether the edge can
    /// be projected at all, the correction direction `u` with `d·u` and `|u|`.
    struct Fours {
        ki: [usize; 4],
        kj: [usize; 4],
        xi: Lanes3,
        xj: Lanes3,
        x0i: Lanes3,
        x0j: Lanes3,
        d: Lanes3,
        len: __m256d,
        wi: __m256d,
        wj: __m256d,
        w_sum: __m256d,
        projectable: __m256d,
        u: Lanes3,
        du: __m256d,
        u_len: __m256d,
    }

    /// Loads the four edges `$ids` and computes their [`Fours`]: a macro, so that it is inlined
    /// into each kernel's loop (a function with `target_feature` cannot be `inline(always)`,
    /// and as a call it returned its lanes through the stack).
    ///
    /// Safety: `$p` holds every index of `$ids` (checked against the state before the pass),
    /// `$x0` and `$w` have one length; the four edges share no particle and no other thread
    /// touches them; AVX2 is present. Expands to `unsafe` code, used in `unsafe` blocks.
    macro_rules! fours {
        ($p:expr, $x0:expr, $w:expr, $ids:expr) => {{
            let (p, x0, w, ids): (*mut DVec3, &[DVec3], &[f64], &[[u32; 2]]) = ($p, $x0, $w, $ids);
            let ki = [0, 1, 2, 3].map(|l| ids[l][0] as usize);
            let kj = [0, 1, 2, 3].map(|l| ids[l][1] as usize);
            // `w`'s indexing checks the bounds of `x0` too (the two have one length).
            let wi = _mm256_setr_pd(w[ki[0]], w[ki[1]], w[ki[2]], w[ki[3]]);
            let wj = _mm256_setr_pd(w[kj[0]], w[kj[1]], w[kj[2]], w[kj[3]]);
            let p0 = x0.as_ptr();
            let (xi, xj, x0i, x0j) = (load(p, ki), load(p, kj), load(p0, ki), load(p0, kj));
            let (min_length, infinity) =
                (_mm256_set1_pd(MIN_LENGTH), _mm256_set1_pd(f64::INFINITY));
            let finite_from_min = |v| {
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(v, min_length),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(v, infinity),
                )
            };
            let d = sub(&xj, &xi);
            let len = _mm256_sqrt_pd(dot(&d, &d));
            let w_sum = _mm256_add_pd(wi, wj);
            let projectable = _mm256_and_pd(
                finite_from_min(len),
                _mm256_cmp_pd::<_CMP_GT_OQ>(w_sum, _mm256_setzero_pd()),
            );
            // `correction_direction`: the start edge where it has a length and is within the
            // cosine of `d`, else `d`.
            let e0 = sub(&x0j, &x0i);
            let len0 = _mm256_sqrt_pd(dot(&e0, &e0));
            let de = dot(&d, &e0);
            let min_cos = _mm256_set1_pd(START_DIRECTION_MIN_COS);
            let start_direction = _mm256_and_pd(
                finite_from_min(len0),
                _mm256_cmp_pd::<_CMP_GE_OQ>(de, _mm256_mul_pd(_mm256_mul_pd(min_cos, len), len0)),
            );
            Fours {
                u: select3(start_direction, &e0, &d),
                du: _mm256_blendv_pd(_mm256_mul_pd(len, len), de, start_direction),
                u_len: _mm256_blendv_pd(len, len0, start_direction),
                ki,
                kj,
                xi,
                xj,
                x0i,
                x0j,
                d,
                len,
                wi,
                wj,
                w_sum,
                projectable,
            }
        }};
    }

    /// Moves the four edges' particles (`$e`, a [`Fours`]) by the step `$s` along `u`
    /// (`Δxi = −wi u s`, `Δxj = wj u s`) where `$apply`, and writes them back: a macro, as
    /// [`fours`].
    ///
    /// Safety: as [`fours`], with the same `$p`. Expands to `unsafe` code.
    macro_rules! correct {
        ($p:expr, $e:expr, $s:expr, $apply:expr) => {{
            let (e, s, apply): (&Fours, __m256d, __m256d) = ($e, $s, $apply);
            let step = scale(&e.u, s);
            // `−wi` by its sign bit (`neg`), as the one-edge kernel negates (`0 − wi` gives +0
            // for 0).
            let to_i = moved(&e.xi, &scale(&step, neg(e.wi)), apply);
            let to_j = moved(&e.xj, &scale(&step, e.wj), apply);
            store($p, e.ki, &to_i);
            store($p, e.kj, &to_j);
        }};
    }

    /// The hard edges in groups of four (`ids.len()` a multiple of 4), each group one lane set:
    /// [`project_distance_hard`]'s step `s = (L − |d|) |d| / (Σw d·u)`.
    ///
    /// # Safety
    /// As [`project_colour_hard`]; `x0` and `w` have one length; AVX2
    /// is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn project_fours(
        x: SharedArray<DVec3>,
        x0: &[DVec3],
        w: &[f64],
        ids: &[[u32; 2]],
        rest: &[f64],
    ) {
        let p = x.at(0);
        for (ids, rest) in ids.chunks_exact(4).zip(rest.chunks_exact(4)) {
            // SAFETY: the caller's contract, which is `fours!`'s and `correct!`'s.
            unsafe {
                let e = fours!(p, x0, w, ids);
                let rest = _mm256_loadu_pd(rest.as_ptr());
                let s = _mm256_div_pd(
                    _mm256_mul_pd(_mm256_sub_pd(rest, e.len), e.len),
                    _mm256_mul_pd(e.w_sum, e.du),
                );
                correct!(p, &e, s, e.projectable);
            }
        }
    }

    /// The compliant edges in groups of four (`ids.len()` and `lambda.len()` a multiple of 4,
    /// equal): [`project_distance_with`]'s damped XPBD step, each edge with the terms of the
    /// sign of its `C = |d| − L`, its multiplier accumulated in `lambda`.
    ///
    /// # Safety
    /// As [`project_fours`].
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn project_fours_compliant(
        x: SharedArray<DVec3>,
        x0: &[DVec3],
        w: &[f64],
        ids: &[[u32; 2]],
        rest: &[f64],
        lambda: &mut [f64],
        terms: &XpbdTerms,
    ) {
        let p = x.at(0);
        let zero = _mm256_setzero_pd();
        let one = _mm256_set1_pd(1.0);
        let min_positive = _mm256_set1_pd(f64::MIN_POSITIVE);
        let infinity = _mm256_set1_pd(f64::INFINITY);
        let [stretched_alpha, compressed_alpha] = terms.alpha_tilde.map(|a| _mm256_set1_pd(a));
        let [stretched_gamma, compressed_gamma] = terms.gamma.map(|g| _mm256_set1_pd(g));
        let chunks = ids.chunks_exact(4).zip(rest.chunks_exact(4));
        for ((ids, rest), lambda) in chunks.zip(lambda.chunks_exact_mut(4)) {
            // SAFETY: the caller's contract, which is `fours!`'s and `correct!`'s; `rest` and
            // `lambda` hold four values each (`chunks_exact`).
            unsafe {
                let e = fours!(p, x0, w, ids);
                let c = _mm256_sub_pd(e.len, _mm256_loadu_pd(rest.as_ptr()));
                let compressed = _mm256_cmp_pd::<_CMP_LT_OQ>(c, zero);
                let alpha = _mm256_blendv_pd(stretched_alpha, compressed_alpha, compressed);
                let gamma = _mm256_blendv_pd(stretched_gamma, compressed_gamma, compressed);
                let lambda_in = _mm256_loadu_pd(lambda.as_ptr());
                let c_lambda = _mm256_add_pd(c, _mm256_mul_pd(alpha, lambda_in));
                let undamped = _mm256_mul_pd(neg(c_lambda), e.len);
                // The damper's term `γ d·((xj − x0j) − (xi − x0i))`, only where `γ > 0`.
                let moved_by = sub(&sub(&e.xj, &e.x0j), &sub(&e.xi, &e.x0i));
                let damped = _mm256_sub_pd(undamped, _mm256_mul_pd(gamma, dot(&e.d, &moved_by)));
                let numerator =
                    _mm256_blendv_pd(undamped, damped, _mm256_cmp_pd::<_CMP_GT_OQ>(gamma, zero));
                let denominator = _mm256_add_pd(
                    _mm256_mul_pd(_mm256_mul_pd(_mm256_add_pd(one, gamma), e.w_sum), e.du),
                    _mm256_mul_pd(_mm256_mul_pd(alpha, e.u_len), e.len),
                );
                let apply = _mm256_and_pd(
                    e.projectable,
                    _mm256_and_pd(
                        _mm256_cmp_pd::<_CMP_GT_OQ>(denominator, min_positive),
                        _mm256_cmp_pd::<_CMP_LT_OQ>(denominator, infinity),
                    ),
                );
                let s = _mm256_div_pd(numerator, denominator);
                correct!(p, &e, s, apply);
                let lambda_out = _mm256_add_pd(lambda_in, _mm256_mul_pd(s, e.u_len));
                _mm256_storeu_pd(
                    lambda.as_mut_ptr(),
                    _mm256_blendv_pd(lambda_in, lambda_out, apply),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use nucleus_sdk::testing::Rng;

    use crate::distance::EdgeMaterial;

    /// One colour of edges with its particles.
    struct Colour {
        x: Vec<DVec3>,
        x0: Vec<DVec3>,
        w: Vec<f64>,
        ids: Vec<[u32; 2]>,
        rest: Vec<f64>,
        lambda: Vec<f64>,
    }

    /// A hard colour kernel's signature: [`project_edges_hard_one_by_one`] or
    /// [`project_colour_hard`].
    type HardKernel = unsafe fn(SharedArray<DVec3>, &[DVec3], &[f64], &[[u32; 2]], &[f64]);

    /// A compliant colour kernel's signature: [`project_edges_compliant_one_by_one`] or
    /// [`project_colour_compliant`].
    type CompliantKernel = unsafe fn(
        SharedArray<DVec3>,
        &[DVec3],
        &[f64],
        &[[u32; 2]],
        &[f64],
        &mut [f64],
        &XpbdTerms,
    );

    impl Colour {
        /// The positions after `kernel` projects every edge once, from a copy of `x`.
        fn hard(&self, kernel: HardKernel) -> Vec<DVec3> {
            let mut x = self.x.clone();
            // SAFETY: every index is below 2 × 4,003, the number of particles, no two edges
            // share a particle, and one thread owns the arrays.
            unsafe {
                kernel(
                    SharedArray::new(&mut x),
                    &self.x0,
                    &self.w,
                    &self.ids,
                    &self.rest,
                )
            };
            x
        }

        /// The positions and multipliers after `kernel` projects every edge once, from copies
        /// of `x` and `lambda`.
        fn compliant(&self, kernel: CompliantKernel, terms: &XpbdTerms) -> (Vec<DVec3>, Vec<f64>) {
            let (mut x, mut lambda) = (self.x.clone(), self.lambda.clone());
            // SAFETY: as in `hard`.
            unsafe {
                kernel(
                    SharedArray::new(&mut x),
                    &self.x0,
                    &self.w,
                    &self.ids,
                    &self.rest,
                    &mut lambda,
                    terms,
                )
            };
            (x, lambda)
        }
    }

    /// 4,003 edges pairing 8,006 particles (one colour: no particle shared, and a tail of 3 for
    /// the one-edge kernel), with random positions, start positions, inverse masses and
    /// multipliers, and every case the kernels treat apart: coincident and non-finite
    /// particles, both or one infinitely heavy, a start edge of no length, turned away or
    /// non-finite, negative zeros, an edge exactly at its rest length.
    fn colour(rng: &mut Rng) -> Colour {
        let edges = 4003;
        let particles = 2 * edges;
        let mut x: Vec<DVec3> = (0..particles).map(|_| rng.vec3(1.0)).collect();
        let mut x0: Vec<DVec3> = x.iter().map(|&p| p + rng.vec3(0.01)).collect();
        let mut w: Vec<f64> = (0..particles).map(|_| rng.range(0.1, 10.0)).collect();
        // Edge k joins the odd particle 2k + 1 and the even particle 2 (7919 k mod 4003), a
        // permutation (4,003 is prime), so the partners are scattered.
        let ids: Vec<[u32; 2]> = (0..edges as u32)
            .map(|k| [2 * k + 1, 2 * (k * 7919 % edges as u32)])
            .collect();
        let mut seen = vec![false; particles];
        for &[i, j] in &ids {
            assert!(!seen[i as usize] && !seen[j as usize], "one colour");
            seen[i as usize] = true;
            seen[j as usize] = true;
        }
        let mut rest: Vec<f64> = ids
            .iter()
            .map(|&[i, j]| (x[j as usize] - x[i as usize]).length() * rng.range(0.8, 1.2))
            .collect();
        let lambda = (0..edges).map(|_| rng.range(-1e-3, 1e-3)).collect();
        for (k, &[i, j]) in ids.iter().enumerate() {
            let (i, j) = (i as usize, j as usize);
            match k % 13 {
                0 => x[j] = x[i],                                       // coincident
                1 => x[i].y = f64::NAN,                                 // a NaN position
                2 => x[j].z = f64::INFINITY,                            // an infinite one
                3 => (w[i], w[j]) = (0.0, 0.0),                         // both pinned
                4 => (w[i], x[i]) = (0.0, DVec3::new(-0.0, 0.0, -0.0)), // one pinned, −0
                5 => x0[j] = x0[i],                                     // a start edge of no length
                6 => x0[j] = x0[i] - (x[j] - x[i]),                     // turned away
                7 => x0[i].x = f64::NAN,                                // a NaN start
                8 => w[j] = f64::NAN,                                   // a NaN inverse mass
                9 => rest[k] = (x[j] - x[i]).length(),                  // C = 0 exactly: stretched
                _ => {}
            }
        }
        Colour {
            x,
            x0,
            w,
            ids,
            rest,
            lambda,
        }
    }

    fn bits(x: &[DVec3]) -> Vec<[u64; 3]> {
        x.iter()
            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
            .collect()
    }

    /// The lanes run only where the processor has AVX2: elsewhere the tests below compare the
    /// one-edge kernel with itself, and say so.
    fn lanes_or_say_why_not() {
        if !avx2_available() {
            eprintln!("this processor has no AVX2: the four-lane kernels are not exercised");
        }
    }

    #[test]
    fn four_lanes_give_the_bits_of_the_one_edge_kernel() {
        lanes_or_say_why_not();
        let mut rng = Rng(7);
        for _ in 0..3 {
            let c = colour(&mut rng);
            let one = c.hard(project_edges_hard_one_by_one);
            let four = c.hard(project_colour_hard);
            assert_ne!(bits(&one), bits(&c.x), "the pass moved particles");
            assert_eq!(bits(&one), bits(&four));
        }
    }

    #[test]
    fn four_lanes_give_the_bits_of_the_one_edge_kernel_for_compliant_edges() {
        lanes_or_say_why_not();
        let mut rng = Rng(11);
        let h = 1.0 / 240.0;
        for material in [
            // Soft both ways, undamped.
            EdgeMaterial {
                compliance: 1e-6,
                compression_compliance: 1e-3,
                damping: 0.0,
            },
            // Damped, so the damper's term is on for both signs of C.
            EdgeMaterial {
                compliance: 1e-5,
                compression_compliance: 1e-4,
                damping: 2.0,
            },
            // Hard when stretched, soft and damped when compressed.
            EdgeMaterial {
                compliance: 0.0,
                compression_compliance: 1e-2,
                damping: 0.5,
            },
        ] {
            let terms = material.terms(h);
            let c = colour(&mut rng);
            let (one, lambda_one) = c.compliant(project_edges_compliant_one_by_one, &terms);
            let (four, lambda_four) = c.compliant(project_colour_compliant, &terms);
            assert_ne!(bits(&one), bits(&c.x), "the pass moved particles");
            assert_eq!(bits(&one), bits(&four), "{material:?}");
            let lambda_bits = |l: &[f64]| l.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_ne!(lambda_bits(&lambda_one), lambda_bits(&c.lambda));
            assert_eq!(
                lambda_bits(&lambda_one),
                lambda_bits(&lambda_four),
                "{material:?}"
            );
        }
    }
}
