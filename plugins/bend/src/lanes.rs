//! The dihedral hinge pass, the edge-angle pass and the isometric hinge pass four constraints
//! at a time, in the processor's 256-bit lanes (AVX2), where the processor has them: the same
//! arithmetic as [`project_dihedral`], [`project_edge_angle`] and [`project_isometric`],
//! operation for operation and in the same order (no fused multiply-add, whose single rounding would differ), so every position,
//! multiplier and skip comes out with the same bits as the one-at-a-time kernel. The four
//! constraints of a lane group are consecutive constraints of one colour, so they share no
//! particle: their corrections are computed together and written back one by one. The
//! constraints left over after the last group of four, those of a batch whose constraints may
//! share particles, and every constraint on a processor without AVX2 take the one-at-a-time
//! kernel.
//!
//! The one-at-a-time kernels branch on data, and the lanes compute every branch and keep, lane
//! by lane, the value the branch taken would give:
//!
//! * the degenerate constraints and [`xpbd_correction`]'s weighted gradient norm: a lane that
//!   the one-at-a-time kernel skips is computed through (NaN, infinities and divisions by zero
//!   do no harm in a lane) and then neither moved nor given a multiplier, and counted as
//!   skipped. For a hinge, [`crate::dihedral`]'s `hinge` tests and the finiteness of `φ` and
//!   of the gradient; for an angle, [`edge_angle_gradient`]'s: an edge shorter than
//!   `MIN_LENGTH`, collinear edges (`|a × b|² < MIN_SIN² |a|² |b|²` or NaN), and the
//!   finiteness of `φ` and of the gradient;
//! * [`atan2`]: the swap `|y| ≤ |x|`, the range reduction (`t > tan 3π/8`, `t ≤ 0.66`, else)
//!   as a choice of numerator, denominator and constants before one division, `x < 0`,
//!   `copysign`, and `(0, 0)` giving `+0`;
//! * [`wrap_angle`] (hinges only): both wrapped values, kept by the two comparisons;
//! * [`delta_lambda`]'s guard on the denominator: `+0` where it returns `0.0`, and the
//!   correction still applied then (it may turn a `−0` coordinate into `+0`, as the scalar
//!   code does);
//! * [`project_isometric`]'s tests (isometric hinges only; its XPBD step is its own, one
//!   division for `Δλ` and `Δx`): `|v|² ≥ MIN_V²` and finite, and the denominator above the
//!   smallest normal number and finite with `Σ wK'² > 0`; a lane failing any of them is skipped,
//!   as the scalar code skips the hinge. Each hinge's weights `K'` are loaded four hinges at a
//!   time and transposed into lanes.
//!
//! Why: within a colour the constraints are independent, but the one-at-a-time kernel is a
//! long chain of dependent operations (for a hinge three cross products, a square root, two
//! divisions in `atan2` and one for the gradient, the rational polynomial of `atan`: some
//! hundred and forty operations; for an angle three cross products, a square root and the same
//! `atan2`, some hundred), and the processor's reorder window holds few constraints at once;
//! the lanes do each operation for four, and take no branch on the data (the one-at-a-time
//! `atan2` mispredicts often). Measured in the crate docs' "Cost" section: 3–4.5× per pass. The
//! isometric hinge (some forty operations, no `atan2`) gains as much: one at a time it took
//! twice as long as a dihedral hinge in the lanes.
//!
//! The lanes' loads, stores and `DVec3` arithmetic are the SDK's [`nucleus_sdk::lanes`]; the
//! operations only these kernels need (`cross`, `atan2`, ...) and the end both share (the XPBD
//! step and the write-back) are here.
//!
//! [`project_dihedral`]: crate::dihedral::project_dihedral
//! [`project_edge_angle`]: crate::angle::project_edge_angle
//! [`project_isometric`]: crate::bergou2006_isometric::project_isometric
//! [`edge_angle_gradient`]: crate::angle::edge_angle_gradient
//! [`xpbd_correction`]: crate::step::xpbd_correction
//! [`atan2`]: crate::trig::atan2
//! [`wrap_angle`]: crate::dihedral::wrap_angle
//! [`delta_lambda`]: nucleus_sdk::xpbd::delta_lambda

use glam::DVec3;
#[cfg(any(test, target_arch = "x86_64"))]
use nucleus_sdk::lanes::avx2_available;
use nucleus_sdk::team::SharedArray;

use crate::angle::project_edge_angle;
use crate::bergou2006_isometric::project_isometric;
use crate::dihedral::project_dihedral;
use crate::step::Correction;

/// What every constraint of a pass shares: the compliance `alpha` (rad/(N·m)) and the substep
/// `h` (s).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PassTerms {
    pub alpha: f64,
    pub h: f64,
}

/// A kind of constraint of `N` particles that the lanes project: its one-at-a-time kernel
/// and, on x86_64, its four-lane kernel with the same bits.
pub(crate) trait Lanes<const N: usize> {
    /// What each constraint holds besides its particles: a rest angle (rad), or the
    /// isometric weights `K'` (1/m).
    type Rest: Copy;

    /// The one-at-a-time kernel: `(positions, inverse masses, rest, alpha, λ, h)` to a
    /// correction, `None` to skip.
    fn one(
        x: &[DVec3; N],
        w: &[f64; N],
        rest: Self::Rest,
        alpha: f64,
        lambda: f64,
        h: f64,
    ) -> Option<Correction<N>>;

    /// The four-lane kernel on constraints in groups of four (`ids.len()`, `rest.len()` and
    /// `lambda.len()` equal and a multiple of 4). Returns how many were skipped.
    ///
    /// # Safety
    /// As [`project_colour`]; AVX2 is present.
    #[cfg(target_arch = "x86_64")]
    unsafe fn fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; N]],
        rest: &[Self::Rest],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64;
}

/// The dihedral hinges ([`project_dihedral`] towards a rest angle): `bend` on surfaces,
/// `twist`.
pub(crate) struct Dihedral;

/// The edge angles ([`project_edge_angle`] towards a rest angle): `shear`, `bend` on curves.
pub(crate) struct EdgeAngle;

/// Bergou's isometric hinges ([`project_isometric`] with the hinge's weights):
/// `bend_isometric`.
pub(crate) struct Isometric;

impl Lanes<4> for Dihedral {
    type Rest = f64;

    #[inline]
    fn one(
        x: &[DVec3; 4],
        w: &[f64; 4],
        rest: f64,
        alpha: f64,
        l: f64,
        h: f64,
    ) -> Option<Correction<4>> {
        project_dihedral(x, w, rest, alpha, l, h)
    }

    #[cfg(target_arch = "x86_64")]
    unsafe fn fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; 4]],
        rest: &[f64],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64 {
        // SAFETY: the caller's contract.
        unsafe { avx2::project_hinge_fours(x, w, ids, rest, lambda, terms) }
    }
}

impl Lanes<3> for EdgeAngle {
    type Rest = f64;

    #[inline]
    fn one(
        x: &[DVec3; 3],
        w: &[f64; 3],
        rest: f64,
        alpha: f64,
        l: f64,
        h: f64,
    ) -> Option<Correction<3>> {
        project_edge_angle(x, w, rest, alpha, l, h)
    }

    #[cfg(target_arch = "x86_64")]
    unsafe fn fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; 3]],
        rest: &[f64],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64 {
        // SAFETY: the caller's contract.
        unsafe { avx2::project_angle_fours(x, w, ids, rest, lambda, terms) }
    }
}

impl Lanes<4> for Isometric {
    type Rest = [f64; 4];

    #[inline]
    fn one(
        x: &[DVec3; 4],
        w: &[f64; 4],
        k: [f64; 4],
        alpha: f64,
        l: f64,
        h: f64,
    ) -> Option<Correction<4>> {
        project_isometric(x, &k, w, alpha, l, h)
    }

    #[cfg(target_arch = "x86_64")]
    unsafe fn fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; 4]],
        weights: &[[f64; 4]],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64 {
        // SAFETY: the caller's contract.
        unsafe { avx2::project_isometric_fours(x, w, ids, weights, lambda, terms) }
    }
}

/// Projects the constraints `ids[k]` in order, one at a time, with `K`'s one-constraint
/// kernel ([`project_dihedral`], [`project_edge_angle`], [`project_isometric`]) and `rest[k]`,
/// accumulating each one's multiplier in `lambda[k]`: the reference the four-lane kernel must
/// match bit for bit, its fallback, and the kernel of a batch whose
/// constraints share particles. Returns how many were skipped.
///
/// # Safety
/// `x` points to more positions than the largest index of `ids`, valid for the duration of the
/// call; each constraint's indices are distinct; no other thread reads or writes the positions
/// of these constraints' particles meanwhile.
pub(crate) unsafe fn project_one_by_one<const N: usize, K: Lanes<N>>(
    x: SharedArray<DVec3>,
    w: &[f64],
    ids: &[[u32; N]],
    rest: &[K::Rest],
    lambda: &mut [f64],
    terms: PassTerms,
) -> u64 {
    let mut skipped = 0;
    for ((c, &rest), lambda) in ids.iter().zip(rest).zip(lambda) {
        let ws = c.map(|i| w[i as usize]);
        // SAFETY: the caller's contract: every index is in bounds, the `N` are distinct and
        // no other thread touches them.
        unsafe {
            let pos = c.map(|i| *x.at(i as usize));
            match K::one(&pos, &ws, rest, terms.alpha, *lambda, terms.h) {
                Some(correction) => {
                    for (&i, dx) in c.iter().zip(&correction.dx) {
                        *x.at(i as usize) += *dx;
                    }
                    *lambda += correction.delta_lambda;
                }
                None => skipped += 1,
            }
        }
    }
    skipped
}

/// Projects the constraints `ids[k]` of one colour (no two share a particle), in order, as
/// [`project_one_by_one`] does and with its bits, four at a time where the processor can
/// ([`avx2_available`]). Returns how many were skipped.
///
/// # Safety
/// As [`project_one_by_one`], and no two of the constraints share a particle.
///
/// [`avx2_available`]: nucleus_sdk::lanes::avx2_available
pub(crate) unsafe fn project_colour<const N: usize, K: Lanes<N>>(
    x: SharedArray<DVec3>,
    w: &[f64],
    ids: &[[u32; N]],
    rest: &[K::Rest],
    lambda: &mut [f64],
    terms: PassTerms,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if rest.len() == ids.len() && lambda.len() == ids.len() && avx2_available() {
        let whole = ids.len() / 4 * 4;
        let (four, left) = lambda.split_at_mut(whole);
        // SAFETY: AVX2 is present (checked above); the rest is the caller's contract.
        unsafe {
            return K::fours(x, w, &ids[..whole], &rest[..whole], four, terms)
                + project_one_by_one::<N, K>(x, w, &ids[whole..], &rest[whole..], left, terms);
        }
    }
    // SAFETY: the caller's contract.
    unsafe { project_one_by_one::<N, K>(x, w, ids, rest, lambda, terms) }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

    use nucleus_sdk::lanes::avx2::{add, dot, load, moved, neg, scale, select, store, sub, Lanes3};

    use super::*;
    use crate::angle::{MIN_LENGTH as EDGE_MIN_LENGTH, MIN_SIN};
    use crate::bergou2006_isometric::MIN_V;
    use crate::dihedral::MIN_LENGTH as HINGE_MIN_LENGTH;
    use crate::trig::{MOREBITS, P, Q, T3P8, UNREDUCED_MAX};

    /// `a × b` as [`DVec3::cross`] rounds it: `(a.y b.z − b.y a.z, a.z b.x − b.z a.x,
    /// a.x b.y − b.x a.y)` (each product is commutative, so only the differences' order
    /// matters).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn cross(a: &Lanes3, b: &Lanes3) -> Lanes3 {
        Lanes3 {
            x: _mm256_sub_pd(_mm256_mul_pd(a.y, b.z), _mm256_mul_pd(b.y, a.z)),
            y: _mm256_sub_pd(_mm256_mul_pd(a.z, b.x), _mm256_mul_pd(b.z, a.x)),
            z: _mm256_sub_pd(_mm256_mul_pd(a.x, b.y), _mm256_mul_pd(b.x, a.y)),
        }
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn neg3(a: &Lanes3) -> Lanes3 {
        Lanes3 {
            x: neg(a.x),
            y: neg(a.y),
            z: neg(a.z),
        }
    }

    /// `|v|`: the sign bit cleared, as `f64::abs`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn abs(v: __m256d) -> __m256d {
        _mm256_andnot_pd(_mm256_set1_pd(-0.0), v)
    }

    /// All ones in the lanes where `v` is finite (`|v| < ∞`, false for NaN), as
    /// `f64::is_finite`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn finite(v: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_LT_OQ>(abs(v), _mm256_set1_pd(f64::INFINITY))
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn finite3(a: &Lanes3) -> __m256d {
        _mm256_and_pd(_mm256_and_pd(finite(a.x), finite(a.y)), finite(a.z))
    }

    /// [`atan_nonnegative`](crate::trig) of four lanes: each lane's branch picks the
    /// numerator and denominator of the reduced argument (`−1/t`, `(t − 1)/(t + 1)`) before
    /// one division, and the base and low bits added after; the unreduced lanes keep `t`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn atan_nonnegative(t: __m256d) -> __m256d {
        let one = _mm256_set1_pd(1.0);
        let zero = _mm256_setzero_pd();
        let big = _mm256_cmp_pd::<_CMP_GT_OQ>(t, _mm256_set1_pd(T3P8));
        let small = _mm256_cmp_pd::<_CMP_LE_OQ>(t, _mm256_set1_pd(UNREDUCED_MAX));
        let num = select(big, _mm256_set1_pd(-1.0), _mm256_sub_pd(t, one));
        let den = select(big, t, _mm256_add_pd(t, one));
        // `big` and `small` never hold together (T3P8 > 0.66).
        let x = select(small, t, _mm256_div_pd(num, den));
        let base = select(
            big,
            _mm256_set1_pd(FRAC_PI_2),
            select(small, zero, _mm256_set1_pd(FRAC_PI_4)),
        );
        let extra = select(
            big,
            _mm256_set1_pd(MOREBITS),
            select(small, zero, _mm256_set1_pd(0.5 * MOREBITS)),
        );
        let z = _mm256_mul_pd(x, x);
        let [p0, p1, p2, p3, p4] = P.map(|c| _mm256_set1_pd(c));
        let [q0, q1, q2, q3, q4] = Q.map(|c| _mm256_set1_pd(c));
        let step = |acc: __m256d, c: __m256d| _mm256_add_pd(_mm256_mul_pd(acc, z), c);
        let p = step(step(step(step(p0, p1), p2), p3), p4);
        let q = step(step(step(step(_mm256_add_pd(z, q0), q1), q2), q3), q4);
        let ratio = _mm256_div_pd(_mm256_mul_pd(z, p), q);
        _mm256_add_pd(
            base,
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x, ratio), x), extra),
        )
    }

    /// [`atan2`](crate::trig::atan2) of four lanes: the smaller of `|y|, |x|` over the larger
    /// (one division), the quadrant by `x < 0` and the sign of `y`, and `+0` for `(0, 0)`.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn atan2(y: __m256d, x: __m256d) -> __m256d {
        let zero = _mm256_setzero_pd();
        let (ay, ax) = (abs(y), abs(x));
        let y_smaller = _mm256_cmp_pd::<_CMP_LE_OQ>(ay, ax);
        // `|y| ≤ |x| = 0`: the scalar code returns +0 at once (neither is NaN there).
        let origin = _mm256_and_pd(y_smaller, _mm256_cmp_pd::<_CMP_EQ_OQ>(ax, zero));
        let t = _mm256_div_pd(select(y_smaller, ay, ax), select(y_smaller, ax, ay));
        let atn = atan_nonnegative(t);
        let a = select(
            y_smaller,
            atn,
            _mm256_sub_pd(_mm256_set1_pd(FRAC_PI_2), atn),
        );
        let a = select(
            _mm256_cmp_pd::<_CMP_LT_OQ>(x, zero),
            _mm256_sub_pd(_mm256_set1_pd(PI), a),
            a,
        );
        // `a.copysign(y)`: the magnitude of `a`, the sign bit of `y`.
        let sign = _mm256_set1_pd(-0.0);
        let a = _mm256_or_pd(_mm256_andnot_pd(sign, a), _mm256_and_pd(sign, y));
        select(origin, zero, a)
    }

    /// [`wrap_angle`](crate::dihedral::wrap_angle) of four lanes: both wrapped values, kept
    /// where `d > π` or `d ≤ −π`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn wrap_angle(d: __m256d) -> __m256d {
        let (pi, tau) = (_mm256_set1_pd(PI), _mm256_set1_pd(TAU));
        let above = _mm256_cmp_pd::<_CMP_GT_OQ>(d, pi);
        let below = _mm256_cmp_pd::<_CMP_LE_OQ>(d, _mm256_set1_pd(-PI));
        let d = select(above, _mm256_sub_pd(d, tau), d);
        select(below, _mm256_add_pd(d, tau), d)
    }

    /// The constants of [`xpbd_correction`] and [`delta_lambda`] in a pass, in every lane.
    ///
    /// [`xpbd_correction`]: crate::step::xpbd_correction
    /// [`delta_lambda`]: nucleus_sdk::xpbd::delta_lambda
    #[derive(Clone, Copy)]
    struct Xpbd {
        /// `delta_lambda`'s `alpha / (h * h)`, one value for every constraint.
        alpha_tilde: __m256d,
    }

    impl Xpbd {
        #[inline]
        #[target_feature(enable = "avx2")]
        fn new(terms: PassTerms) -> Self {
            Self {
                alpha_tilde: _mm256_set1_pd(terms.alpha / (terms.h * terms.h)),
            }
        }

        /// The end of the one-constraint kernel for four constraints of `N` particles whose
        /// value `c` and gradient `grad` are computed, `ok` in the lanes the scalar kernel
        /// gets that far (its degenerate tests passed): [`xpbd_correction`] and
        /// [`delta_lambda`] in the same operations, the particles `k` (role by role, lane by
        /// lane) at `xs` moved by `w ∇C Δλ` and the multipliers at `lambda` (four) increased
        /// by `Δλ` in the lanes that pass its test on the weighted gradient norm too, the
        /// others left as they are. Returns how many lanes were skipped.
        ///
        /// # Safety
        /// Every `k[r][l]` indexes a point of `p` that no other thread reads or writes
        /// meanwhile, the `4 N` distinct; `lambda` holds four values; AVX2 is present.
        ///
        /// [`xpbd_correction`]: crate::step::xpbd_correction
        /// [`delta_lambda`]: nucleus_sdk::xpbd::delta_lambda
        #[allow(clippy::too_many_arguments)]
        #[inline]
        #[target_feature(enable = "avx2")]
        unsafe fn correct<const N: usize>(
            self,
            p: *mut DVec3,
            k: &[[usize; 4]; N],
            xs: &[Lanes3; N],
            ws: &[__m256d; N],
            grad: &[Lanes3; N],
            c: __m256d,
            ok: __m256d,
            lambda: &mut [f64],
        ) -> u64 {
            let zero = _mm256_setzero_pd();
            let infinity = _mm256_set1_pd(f64::INFINITY);
            let alpha_tilde = self.alpha_tilde;
            // `xpbd_correction`: `0.0 + w₀|∇₀C|² + …`, then its test.
            let mut w_grad_sq = zero;
            for (w, g) in ws.iter().zip(grad) {
                w_grad_sq = _mm256_add_pd(w_grad_sq, _mm256_mul_pd(*w, dot(g, g)));
            }
            let movable = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(w_grad_sq, zero),
                _mm256_cmp_pd::<_CMP_LT_OQ>(w_grad_sq, infinity),
            );
            // `delta_lambda`, its guard selecting `0.0`.
            let denom = _mm256_add_pd(w_grad_sq, alpha_tilde);
            let denom_ok = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(denom, _mm256_set1_pd(f64::MIN_POSITIVE)),
                _mm256_cmp_pd::<_CMP_LT_OQ>(denom, infinity),
            );
            debug_assert_eq!(lambda.len(), 4);
            // SAFETY: `lambda` holds four values (the caller's contract).
            let lambda_in = unsafe { _mm256_loadu_pd(lambda.as_ptr()) };
            let delta_lambda = select(
                denom_ok,
                _mm256_div_pd(
                    _mm256_sub_pd(neg(c), _mm256_mul_pd(alpha_tilde, lambda_in)),
                    denom,
                ),
                zero,
            );

            // Apply where the one-constraint kernel returns a correction; skip elsewhere.
            let apply = _mm256_and_pd(ok, movable);
            let dx = |r: usize| scale(&grad[r], _mm256_mul_pd(ws[r], delta_lambda));
            // SAFETY: the caller's contract.
            unsafe { write_back(p, k, xs, dx, apply, lambda_in, delta_lambda, lambda) }
        }
    }

    /// The write-back both ends share: the particles `k` (role by role, lane by lane) at `xs`
    /// moved by `dx(role)` and the multipliers at `lambda` (four, `lambda_in` as loaded) increased by
    /// `delta_lambda`, in the lanes `apply` (where the one-constraint kernel returns a
    /// correction), the others left as they are, bit for bit. Returns how many lanes were
    /// skipped.
    ///
    /// # Safety
    /// As [`Xpbd::correct`].
    #[allow(clippy::too_many_arguments)]
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn write_back<const N: usize>(
        p: *mut DVec3,
        k: &[[usize; 4]; N],
        xs: &[Lanes3; N],
        dx: impl Fn(usize) -> Lanes3,
        apply: __m256d,
        lambda_in: __m256d,
        delta_lambda: __m256d,
        lambda: &mut [f64],
    ) -> u64 {
        for r in 0..N {
            // SAFETY: the caller's contract.
            unsafe { store(p, k[r], &moved(&xs[r], &dx(r), apply)) };
        }
        let lambda_out = select(apply, _mm256_add_pd(lambda_in, delta_lambda), lambda_in);
        debug_assert_eq!(lambda.len(), 4);
        // SAFETY: `lambda` holds four values (the caller's contract).
        unsafe { _mm256_storeu_pd(lambda.as_mut_ptr(), lambda_out) };
        4 - u64::from(_mm256_movemask_pd(apply).count_ones())
    }

    /// The particles of each role `r` of four constraints `ids`, lane by lane, their inverse
    /// masses and their positions. `K`, the calling kernel's kind, is there only to give each
    /// kernel its own copy: LLVM inlines a copy with one caller, and did not inline one shared
    /// by two kernels (a call per four hinges, some 10 % of the dihedral pass).
    ///
    /// # Safety
    /// Every index of `ids` indexes a point of `p` that no other thread writes meanwhile and
    /// is below `w.len()`; AVX2 is present.
    #[allow(clippy::type_complexity, clippy::extra_unused_type_parameters)]
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn gather<const N: usize, K>(
        p: *const DVec3,
        w: &[f64],
        ids: &[[u32; N]],
    ) -> ([[usize; 4]; N], [__m256d; N], [Lanes3; N]) {
        // Plain loops, no `array::map`: its closures would inherit AVX2 and `map` would not,
        // so they would not be inlined into this loop (a call per point, measured slower).
        let zero = _mm256_setzero_pd();
        let mut k = [[0; 4]; N];
        let mut ws = [zero; N];
        let mut xs = [Lanes3 {
            x: zero,
            y: zero,
            z: zero,
        }; N];
        for r in 0..N {
            k[r] = [ids[0][r], ids[1][r], ids[2][r], ids[3][r]].map(|i| i as usize);
            let k = k[r];
            ws[r] = _mm256_setr_pd(w[k[0]], w[k[1]], w[k[2]], w[k[3]]);
            // SAFETY: the caller's contract.
            xs[r] = unsafe { load(p, k) };
        }
        (k, ws, xs)
    }

    /// The hinges in groups of four (`ids.len()`, `rest.len()` and `lambda.len()` equal and a
    /// multiple of 4): [`project_dihedral`] of each lane, its `hinge`, `Hinge::angle`,
    /// `dihedral_angle_gradient`, `wrap_angle`, `xpbd_correction` and `delta_lambda` in the
    /// same operations as the scalar code (each step below names the scalar line it
    /// reproduces). Returns how many hinges were skipped.
    ///
    /// # Safety
    /// As [`super::project_colour`]; AVX2 is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn project_hinge_fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; 4]],
        rest: &[f64],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64 {
        let p = x.at(0);
        let one = _mm256_set1_pd(1.0);
        let infinity = _mm256_set1_pd(f64::INFINITY);
        let min_sq = _mm256_set1_pd(HINGE_MIN_LENGTH * HINGE_MIN_LENGTH);
        let xpbd = Xpbd::new(terms);
        let mut skipped = 0;
        let chunks = ids.chunks_exact(4).zip(rest.chunks_exact(4));
        for ((ids, rest), lambda) in chunks.zip(lambda.chunks_exact_mut(4)) {
            // The particles of role r (i, j, k, l) of the four hinges, lane by lane.
            // SAFETY: every index is below the positions' length and no other thread touches
            // these particles (the caller's contract); AVX2 is present.
            let (k, ws, xs) = unsafe { gather::<_, Dihedral>(p, w, ids) };

            // `hinge`: the axis, the wings, the normals and the degenerate tests.
            let e = sub(&xs[1], &xs[0]);
            let e_sq = dot(&e, &e);
            let axis_ok = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(e_sq, min_sq),
                _mm256_cmp_pd::<_CMP_LT_OQ>(e_sq, infinity),
            );
            let a = sub(&xs[2], &xs[0]);
            let b = sub(&xs[3], &xs[0]);
            let n1 = cross(&e, &a);
            let n2 = cross(&b, &e);
            let (n1_sq, n2_sq) = (dot(&n1, &n1), dot(&n2, &n2));
            let min_wing_sq = _mm256_mul_pd(min_sq, e_sq);
            let wings_ok = _mm256_and_pd(
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(n1_sq, min_wing_sq),
                    _mm256_cmp_pd::<_CMP_GE_OQ>(n2_sq, min_wing_sq),
                ),
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_LT_OQ>(n1_sq, infinity),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(n2_sq, infinity),
                ),
            );
            let e_len = _mm256_sqrt_pd(e_sq);

            // `Hinge::angle`.
            let phi = atan2(
                dot(&cross(&n1, &n2), &e),
                _mm256_mul_pd(dot(&n1, &n2), e_len),
            );

            // `dihedral_angle_gradient`.
            let r = _mm256_div_pd(one, _mm256_mul_pd(_mm256_mul_pd(e_sq, n1_sq), n2_sq));
            let inv_e_sq = _mm256_mul_pd(_mm256_mul_pd(n1_sq, n2_sq), r);
            let minus_len_sq = _mm256_mul_pd(neg(e_len), e_sq);
            let gk = scale(&n1, _mm256_mul_pd(_mm256_mul_pd(minus_len_sq, n2_sq), r));
            let gl = scale(&n2, _mm256_mul_pd(_mm256_mul_pd(minus_len_sq, n1_sq), r));
            let sk = _mm256_mul_pd(dot(&a, &e), inv_e_sq);
            let sl = _mm256_mul_pd(dot(&b, &e), inv_e_sq);
            let gi = neg3(&add(
                &scale(&gk, _mm256_sub_pd(one, sk)),
                &scale(&gl, _mm256_sub_pd(one, sl)),
            ));
            let gj = neg3(&add(&scale(&gk, sk), &scale(&gl, sl)));
            let grad = [gi, gj, gk, gl];
            let finite_ok = _mm256_and_pd(
                _mm256_and_pd(finite(phi), finite3(&gi)),
                _mm256_and_pd(_mm256_and_pd(finite3(&gj), finite3(&gk)), finite3(&gl)),
            );

            // `project_dihedral`'s `C`, then `xpbd_correction` and `delta_lambda`.
            // SAFETY: `rest` holds four values (`chunks_exact`).
            let c = wrap_angle(_mm256_sub_pd(phi, unsafe {
                _mm256_loadu_pd(rest.as_ptr())
            }));
            let ok = _mm256_and_pd(_mm256_and_pd(axis_ok, wings_ok), finite_ok);
            // SAFETY: as for the loads; `lambda` holds four values (`chunks_exact_mut`).
            skipped += unsafe { xpbd.correct(p, &k, &xs, &ws, &grad, c, ok, lambda) };
        }
        skipped
    }

    /// The angles in groups of four (`ids.len()`, `rest.len()` and `lambda.len()` equal and a
    /// multiple of 4): [`project_edge_angle`] of each lane, its `edge_angle_gradient`,
    /// `xpbd_correction` and `delta_lambda` in the same operations as the scalar code (each
    /// step below names the scalar line it reproduces). Returns how many angles were skipped.
    ///
    /// # Safety
    /// As [`super::project_colour`]; AVX2 is present.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn project_angle_fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; 3]],
        rest: &[f64],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64 {
        let p = x.at(0);
        let one = _mm256_set1_pd(1.0);
        let min_sq = _mm256_set1_pd(EDGE_MIN_LENGTH * EDGE_MIN_LENGTH);
        // `MIN_SIN * MIN_SIN * a_sq * b_sq` is `((MIN_SIN * MIN_SIN) * a_sq) * b_sq`.
        let min_sin_sq = _mm256_set1_pd(MIN_SIN * MIN_SIN);
        let xpbd = Xpbd::new(terms);
        let mut skipped = 0;
        let chunks = ids.chunks_exact(4).zip(rest.chunks_exact(4));
        for ((ids, rest), lambda) in chunks.zip(lambda.chunks_exact_mut(4)) {
            // The particles of role r (i, j, k) of the four angles, lane by lane.
            // SAFETY: every index is below the positions' length and no other thread touches
            // these particles (the caller's contract); AVX2 is present.
            let (k, ws, xs) = unsafe { gather::<_, EdgeAngle>(p, w, ids) };

            // `edge_angle_gradient`: the edges and their test,
            // `!(a_sq >= min_sq && b_sq >= min_sq)` (infinite lengths pass).
            let a = sub(&xs[0], &xs[1]);
            let b = sub(&xs[2], &xs[1]);
            let (a_sq, b_sq) = (dot(&a, &a), dot(&b, &b));
            let edges_ok = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(a_sq, min_sq),
                _mm256_cmp_pd::<_CMP_GE_OQ>(b_sq, min_sq),
            );
            // The normal and the collinear test, `n_sq.is_nan() || n_sq < MIN_SIN² a_sq b_sq`:
            // kept where `n_sq` is not NaN and not below (true where the bound is NaN).
            let n = cross(&a, &b);
            let n_sq = dot(&n, &n);
            let bound = _mm256_mul_pd(_mm256_mul_pd(min_sin_sq, a_sq), b_sq);
            let plane_ok = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_ORD_Q>(n_sq, n_sq),
                _mm256_cmp_pd::<_CMP_NLT_UQ>(n_sq, bound),
            );
            let n_len = _mm256_sqrt_pd(n_sq);
            let phi = atan2(n_len, dot(&a, &b));
            // `r = 1.0 / (n_len * a_sq * b_sq)`, `gi = n.cross(a) * (-b_sq * r)`,
            // `gk = n.cross(b) * (a_sq * r)`, `grad = [gi, -(gi + gk), gk]`.
            let r = _mm256_div_pd(one, _mm256_mul_pd(_mm256_mul_pd(n_len, a_sq), b_sq));
            let gi = scale(&cross(&n, &a), _mm256_mul_pd(neg(b_sq), r));
            let gk = scale(&cross(&n, &b), _mm256_mul_pd(a_sq, r));
            let gj = neg3(&add(&gi, &gk));
            let grad = [gi, gj, gk];
            let finite_ok = _mm256_and_pd(
                _mm256_and_pd(finite(phi), finite3(&gi)),
                _mm256_and_pd(finite3(&gj), finite3(&gk)),
            );

            // `project_edge_angle`'s `C = φ − rest`, then `xpbd_correction` and `delta_lambda`.
            // SAFETY: `rest` holds four values (`chunks_exact`).
            let c = _mm256_sub_pd(phi, unsafe { _mm256_loadu_pd(rest.as_ptr()) });
            let ok = _mm256_and_pd(_mm256_and_pd(edges_ok, plane_ok), finite_ok);
            // SAFETY: as for the loads; `lambda` holds four values (`chunks_exact_mut`).
            skipped += unsafe { xpbd.correct(p, &k, &xs, &ws, &grad, c, ok, lambda) };
        }
        skipped
    }

    /// The weights `K'` of four hinges (`weights` holds four), role by role: register `r`
    /// holds `K'ᵣ` of the four hinges, lane by lane (a 4 × 4 transpose, no arithmetic).
    ///
    /// # Safety
    /// AVX2 is present.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn transpose(weights: &[[f64; 4]]) -> [__m256d; 4] {
        debug_assert_eq!(weights.len(), 4);
        // SAFETY: `weights` holds four rows of four values (the caller's contract).
        let [r0, r1, r2, r3] = unsafe {
            [
                _mm256_loadu_pd(weights[0].as_ptr()),
                _mm256_loadu_pd(weights[1].as_ptr()),
                _mm256_loadu_pd(weights[2].as_ptr()),
                _mm256_loadu_pd(weights[3].as_ptr()),
            ]
        };
        let (t0, t1) = (_mm256_unpacklo_pd(r0, r1), _mm256_unpackhi_pd(r0, r1));
        let (t2, t3) = (_mm256_unpacklo_pd(r2, r3), _mm256_unpackhi_pd(r2, r3));
        [
            _mm256_permute2f128_pd::<0x20>(t0, t2),
            _mm256_permute2f128_pd::<0x20>(t1, t3),
            _mm256_permute2f128_pd::<0x31>(t0, t2),
            _mm256_permute2f128_pd::<0x31>(t1, t3),
        ]
    }

    /// The isometric hinges in groups of four (`ids.len()`, `weights.len()` and
    /// `lambda.len()` equal and a multiple of 4): [`project_isometric`] of each lane, its
    /// `curvature_vector`, its two tests and its XPBD step in the same operations as the
    /// scalar code (each step below names the scalar line it reproduces). Its step is its own
    /// (`Δλ` and `Δx` through one division, and a denominator out of range skips the hinge),
    /// so only the write-back is [`Xpbd::correct`]'s. Returns how many hinges were skipped.
    ///
    /// # Safety
    /// As [`super::project_colour`]; AVX2 is present.
    ///
    /// [`project_isometric`]: crate::bergou2006_isometric::project_isometric
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn project_isometric_fours(
        x: SharedArray<DVec3>,
        w: &[f64],
        ids: &[[u32; 4]],
        weights: &[[f64; 4]],
        lambda: &mut [f64],
        terms: PassTerms,
    ) -> u64 {
        let p = x.at(0);
        let zero = _mm256_setzero_pd();
        let infinity = _mm256_set1_pd(f64::INFINITY);
        let min_v_sq = _mm256_set1_pd(MIN_V * MIN_V);
        let Xpbd { alpha_tilde } = Xpbd::new(terms);
        let mut skipped = 0;
        let chunks = ids.chunks_exact(4).zip(weights.chunks_exact(4));
        for ((ids, weights), lambda) in chunks.zip(lambda.chunks_exact_mut(4)) {
            // The particles of role r (i, j, k, l) of the four hinges, lane by lane, and
            // their weights.
            // SAFETY: every index is below the positions' length and no other thread touches
            // these particles (the caller's contract); AVX2 is present; `weights` holds four
            // (`chunks_exact`).
            let (k, ws, xs) = unsafe { gather::<_, Isometric>(p, w, ids) };
            let kw = unsafe { transpose(weights) };

            // `curvature_vector`: `(x₁ − x₀) K'₁ + (x₂ − x₀) K'₂ + (x₃ − x₀) K'₃`.
            let v = add(
                &add(
                    &scale(&sub(&xs[1], &xs[0]), kw[1]),
                    &scale(&sub(&xs[2], &xs[0]), kw[2]),
                ),
                &scale(&sub(&xs[3], &xs[0]), kw[3]),
            );
            // `c_sq = v.length_squared()`, `!(c_sq >= MIN_V * MIN_V && c_sq.is_finite())`.
            let c_sq = dot(&v, &v);
            let bent = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_GE_OQ>(c_sq, min_v_sq),
                _mm256_cmp_pd::<_CMP_LT_OQ>(c_sq, infinity),
            );
            let c = _mm256_sqrt_pd(c_sq);
            // `w₀ K'₀ K'₀ + w₁ K'₁ K'₁ + w₂ K'₂ K'₂ + w₃ K'₃ K'₃`, left to right; `w K'` is
            // also each particle's factor of the correction.
            let mut wk = kw;
            for r in 0..4 {
                wk[r] = _mm256_mul_pd(ws[r], kw[r]);
            }
            let w_grad_sq = _mm256_add_pd(
                _mm256_add_pd(
                    _mm256_add_pd(_mm256_mul_pd(wk[0], kw[0]), _mm256_mul_pd(wk[1], kw[1])),
                    _mm256_mul_pd(wk[2], kw[2]),
                ),
                _mm256_mul_pd(wk[3], kw[3]),
            );
            // `denom = w_grad_sq + alpha_tilde`,
            // `!(denom > f64::MIN_POSITIVE && denom.is_finite() && w_grad_sq > 0.0)`.
            let denom = _mm256_add_pd(w_grad_sq, alpha_tilde);
            let movable = _mm256_and_pd(
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GT_OQ>(denom, _mm256_set1_pd(f64::MIN_POSITIVE)),
                    _mm256_cmp_pd::<_CMP_LT_OQ>(denom, infinity),
                ),
                _mm256_cmp_pd::<_CMP_GT_OQ>(w_grad_sq, zero),
            );
            // `f = (−c − alpha_tilde λ) / (denom c)`, `Δxᵢ = v (wᵢ K'ᵢ f)`, `Δλ = f c`.
            // SAFETY: `lambda` holds four values (`chunks_exact_mut`).
            let lambda_in = unsafe { _mm256_loadu_pd(lambda.as_ptr()) };
            let f = _mm256_div_pd(
                _mm256_sub_pd(neg(c), _mm256_mul_pd(alpha_tilde, lambda_in)),
                _mm256_mul_pd(denom, c),
            );
            let dx = |r: usize| scale(&v, _mm256_mul_pd(wk[r], f));
            let apply = _mm256_and_pd(bent, movable);
            // SAFETY: as for the loads; the sixteen particles are distinct (one colour).
            skipped += unsafe {
                write_back(
                    p,
                    &k,
                    &xs,
                    dx,
                    apply,
                    lambda_in,
                    _mm256_mul_pd(f, c),
                    lambda,
                )
            };
        }
        skipped
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::bergou2006_isometric::isometric_weights;
    use crate::testutil::{Draws, Rng};

    /// One colour of constraints of `N` particles (hinges, angles) with its particles, and
    /// each constraint's rest angle or weights.
    struct Colour<const N: usize, R = f64> {
        x: Vec<DVec3>,
        w: Vec<f64>,
        ids: Vec<[u32; N]>,
        rest: Vec<R>,
        lambda: Vec<f64>,
    }

    /// A colour kernel's signature: [`project_one_by_one`] or [`project_colour`] of a
    /// [`Lanes`] kind.
    type Kernel<const N: usize, R> =
        unsafe fn(SharedArray<DVec3>, &[f64], &[[u32; N]], &[R], &mut [f64], PassTerms) -> u64;

    /// What a pass leaves: the positions' and multipliers' bits and the skip count.
    type Outcome = (Vec<[u64; 3]>, Vec<u64>, u64);

    fn bits(x: &[DVec3]) -> Vec<[u64; 3]> {
        x.iter()
            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
            .collect()
    }

    impl<const N: usize, R> Colour<N, R> {
        /// The positions, multipliers and skip count after `kernel` projects every constraint
        /// once, from copies of `x` and `lambda`.
        fn pass(&self, kernel: Kernel<N, R>, terms: PassTerms) -> Outcome {
            let (mut x, mut lambda) = (self.x.clone(), self.lambda.clone());
            // SAFETY: every index is below the number of particles, the `N` of a constraint
            // are distinct, no two constraints share a particle, and one thread owns the
            // arrays.
            let skipped = unsafe {
                kernel(
                    SharedArray::new(&mut x),
                    &self.w,
                    &self.ids,
                    &self.rest,
                    &mut lambda,
                    terms,
                )
            };
            let lambda = lambda.iter().map(|l| l.to_bits()).collect();
            (bits(&x), lambda, skipped)
        }

        /// 4,003 constraints on `4,003 N` particles, no particle shared: constraint `k` takes
        /// the particles `N (7919 k mod 4003) + roles[r]` (a permutation, 4,003 being prime, so
        /// its `N` are scattered over the array). Random inverse masses and multipliers;
        /// positions at the origin and no rest values, for the caller to set.
        fn scattered(rng: &mut Rng, roles: [u32; N]) -> Self {
            let count = 4003;
            let particles = N * count;
            let w = (0..particles).map(|_| rng.inv_mass()).collect();
            let ids = (0..count as u32)
                .map(|k| roles.map(|r| N as u32 * (k * 7919 % count as u32) + r))
                .collect();
            let lambda = (0..count).map(|_| rng.range(-1e-4, 1e-4)).collect();
            Self {
                x: vec![DVec3::ZERO; particles],
                w,
                ids,
                rest: Vec::with_capacity(count),
                lambda,
            }
        }

        /// Asserts that the particles are one colour: no particle in two constraints.
        fn assert_one_colour(&self) {
            let mut seen = vec![false; self.x.len()];
            for &i in self.ids.iter().flatten() {
                assert!(!seen[i as usize], "one colour");
                seen[i as usize] = true;
            }
        }

        /// Asserts that `one` and `four` (passes of the one-at-a-time and the colour kernel
        /// with compliance `alpha`) have the same bits, and that the pass did something.
        fn assert_same_bits(&self, one: &Outcome, four: &Outcome, alpha: f64) {
            let ((x_one, lambda_one, skipped_one), (x_four, lambda_four, skipped_four)) =
                (one, four);
            if alpha < 1e300 {
                assert_ne!(*x_one, bits(&self.x), "the pass moved particles");
            }
            // Everything skipped only where `α̃` is infinite (the isometric kernel's guard).
            assert!(*skipped_one > 0);
            assert!((*skipped_one as usize) < self.ids.len() || alpha > 1e300);
            assert_eq!(skipped_one, skipped_four, "α = {alpha}");
            for (k, (one, four)) in x_one.iter().zip(x_four).enumerate() {
                assert_eq!(one, four, "α = {alpha}, particle {k}");
            }
            for (k, (one, four)) in lambda_one.iter().zip(lambda_four).enumerate() {
                assert_eq!(one, four, "α = {alpha}, constraint {k}");
            }
        }
    }

    /// A hinge with signed angle `phi` about an axis of length `len` from `o` along `u`, wings
    /// at heights `hk`, `hl` (as the dihedral tests build them), all scaled by `scale`.
    fn hinge(rng: &mut Rng, phi: f64, scale: f64) -> [DVec3; 4] {
        let o = rng.vec3(1.0) * scale;
        let (u, v) = rng.frame();
        let len = rng.range(0.2, 2.0) * scale;
        let (sk, hk) = (rng.range(-0.5, 1.5), rng.range(0.2, 1.5) * scale);
        let (sl, hl) = (rng.range(-0.5, 1.5), rng.range(0.2, 1.5) * scale);
        let n = u.cross(v);
        let l_dir = -(v * phi.cos()) - n * phi.sin();
        [
            o,
            o + u * len,
            o + u * (sk * len) + v * hk,
            o + u * (sl * len) + l_dir * hl,
        ]
    }

    /// 4,003 hinges on 16,012 particles (one colour: no particle shared, and a tail of 3 for
    /// the one-hinge kernel), with random shapes, rest angles, inverse masses and multipliers,
    /// and every case the kernels treat apart: flat, near flat, folded to ±π and near it
    /// (wrapping both ways), all four points coincident, a zero-length or too short axis, a
    /// zero-area wing or one just at the height limit, NaN and infinite positions, sizes whose
    /// squares overflow, negative zeros, two or all inverse masses zero, a NaN one, subnormal ones.
    fn hinge_colour(rng: &mut Rng) -> Colour<4> {
        let mut c = Colour::scattered(rng, [2, 0, 3, 1]);
        for k in 0..c.ids.len() {
            let ids = c.ids[k];
            let case = k % 23;
            let phi = match case {
                0 => 0.0,
                1 => rng.range(-1e-9, 1e-9),
                2 => PI,
                3 => -PI + rng.range(0.0, 1e-9),
                4 => PI - rng.range(0.0, 1e-9),
                _ => rng.range(-PI, PI),
            };
            let scale = match case {
                5 => 1e-12, // heights and axis about the limits
                6 => 1e77,  // squares finite, the normals' squares not
                7 => 1e150, // the axis' square overflows
                _ => 1.0,
            };
            let mut p = hinge(rng, phi, scale);
            let [i, j, kk, l] = ids.map(|i| i as usize);
            match case {
                8 => p = [p[0]; 4],                                             // all coincident
                9 => p[1] = p[0],                                               // zero-length axis
                10 => p[2] = p[0] + (p[1] - p[0]) * 0.37,                       // zero-area wing k
                11 => p[3] = p[1] + (p[1] - p[0]) * 2.0, // wing l on the axis
                12 => p[3].y = f64::NAN,                 // a NaN position
                13 => p[0].z = f64::INFINITY,            // an infinite one
                14 => (c.w[i], c.w[j], c.w[kk], c.w[l]) = (0.0, 0.0, 0.0, 0.0), // all pinned
                15 => (c.w[i], c.w[l]) = (0.0, 0.0),     // two pinned
                16 => c.w[kk] = f64::NAN,                // a NaN inverse mass
                17 => p[1] = p[0] + (p[1] - p[0]) * 1e-13, // axis just below the limit
                18 => {
                    // Negative zeros where the correction may be ±0.
                    p[0] = DVec3::new(-0.0, 0.0, -0.0);
                    c.w[i] = 0.0;
                }
                19 => {
                    // Subnormal inverse masses: `delta_lambda`'s denominator below the
                    // smallest normal number when rigid, so Δλ = 0.
                    (c.w[i], c.w[j], c.w[kk], c.w[l]) = (1e-310, 1e-310, 1e-310, 1e-310);
                }
                _ => {}
            }
            for (r, q) in ids.iter().zip(p) {
                c.x[*r as usize] = q;
            }
            // Rest angles across ±π from the current ones, exactly the current one, or any.
            c.rest.push(match k % 7 {
                0 => -phi.signum() * (PI - rng.range(0.0, 0.3)),
                1 => crate::dihedral::dihedral_angle(&p).unwrap_or(0.5),
                2 => PI,
                _ => rng.range(-PI, PI),
            });
        }
        c.assert_one_colour();
        c
    }

    /// The lanes run only where the processor has AVX2: elsewhere the test below compares the
    /// one-hinge kernel with itself, and says so.
    fn lanes_or_say_why_not() {
        if !avx2_available() {
            eprintln!("this processor has no AVX2: the four-lane kernel is not exercised");
        }
    }

    #[test]
    fn four_lanes_give_the_bits_of_the_one_hinge_kernel_on_colours_with_every_degenerate_case() {
        lanes_or_say_why_not();
        let mut rng = Rng(0xd1ed);
        let h = 1.0 / 600.0;
        // Rigid, stiff, cotton, silk, and so soft that `delta_lambda`'s denominator
        // overflows (its guard then gives Δλ = 0, a correction of ±0).
        for alpha in [0.0, 1e-2, 5e3, 1e5, 1e305] {
            let terms = PassTerms { alpha, h };
            let c = hinge_colour(&mut rng);
            let one = c.pass(project_one_by_one::<4, Dihedral>, terms);
            let four = c.pass(project_colour::<4, Dihedral>, terms);
            c.assert_same_bits(&one, &four, alpha);
        }
    }

    /// Three points whose angle at the middle one is `phi`, edges of lengths `la`, `lb`
    /// about a random point of size `scale` in a random orientation.
    fn angle(rng: &mut Rng, phi: f64, la: f64, lb: f64, scale: f64) -> [DVec3; 3] {
        let j = rng.vec3(1.0) * scale;
        let (u, v) = rng.frame();
        [j + u * la, j, j + (u * phi.cos() + v * phi.sin()) * lb]
    }

    /// 4,003 angles on 12,009 particles (one colour: no particle shared, and a tail of 3 for
    /// the one-angle kernel), with random shapes, rest angles, inverse masses and multipliers,
    /// and every case the kernels treat apart: collinear both ways (φ = 0 and π, exactly, with
    /// a cross product of exactly zero, and through rounding), near collinear on both sides of
    /// `MIN_SIN` at 0 and at π, and exactly at it or one ulp off ([`at_a_limit`]), all three
    /// points coincident, a zero-length edge on either side, edges just below and above
    /// `MIN_LENGTH` and exactly at it or one ulp off, NaN and infinite positions, sizes from
    /// 1e-160 (squares underflow) to 1e150 (squares overflow), negative zeros, all or two
    /// inverse masses zero, a NaN one, subnormal ones.
    /// Three points exactly at a limit of the one-angle kernel's tests, or one ulp of the
    /// limit below or above it (`k % 3`), with no rounding in the quantities compared:
    /// `|a × b|² = MIN_SIN² |a|² |b|²` near 0 (`case` 29) or near π (30), or `|a|²` or `|b|²`
    /// (`k % 2`) equal to `MIN_LENGTH²` at a right angle (31). Edges of a power of two, and
    /// the axes permuted.
    fn at_a_limit(case: usize, k: usize) -> [DVec3; 3] {
        use crate::angle::{MIN_LENGTH, MIN_SIN};
        let ulps = |v: f64| [v.next_down(), v, v.next_up()][k % 3];
        let s = 2f64.powi((k % 21) as i32 - 10);
        let (a, b) = match case {
            29 => (
                DVec3::new(s, 0.0, 0.0),
                DVec3::new(s, ulps(MIN_SIN) * s, 0.0),
            ),
            30 => (
                DVec3::new(s, 0.0, 0.0),
                DVec3::new(-s, ulps(MIN_SIN) * s, 0.0),
            ),
            _ => {
                let (short, long) = (
                    DVec3::new(ulps(MIN_LENGTH), 0.0, 0.0),
                    DVec3::new(0.0, s, 0.0),
                );
                if k.is_multiple_of(2) {
                    (short, long)
                } else {
                    (long, short)
                }
            }
        };
        let j = DVec3::new(0.0, 0.0, 3.0);
        [j + a, j, j + b].map(|v| match k / 3 % 3 {
            0 => v,
            1 => DVec3::new(v.y, v.z, v.x),
            _ => DVec3::new(v.z, v.x, v.y),
        })
    }

    /// Three points whose `|a × b|²` lies between the two roundings of the collinear test's
    /// bound `MIN_SIN² |a|² |b|²`, `(MIN_SIN² |a|²) |b|²` (the scalar code's) and
    /// `MIN_SIN² (|a|² |b|²)`: kept by one order of the products and skipped by the other.
    fn between_the_bounds(rng: &mut Rng) -> [DVec3; 3] {
        use crate::angle::MIN_SIN;
        let j = DVec3::new(0.0, 0.0, 3.0);
        loop {
            let (ax, bx) = (rng.range(0.5, 2.0), rng.range(-2.0, 2.0));
            let aim = MIN_SIN * bx.abs();
            let mut by = aim;
            for _ in 0..8 {
                by = by.next_down();
            }
            for _ in 0..16 {
                by = by.next_up();
                let (a, b) = (DVec3::new(ax, 0.0, 0.0), DVec3::new(bx, by, 0.0));
                let (a_sq, b_sq) = (a.length_squared(), b.length_squared());
                let n_sq = a.cross(b).length_squared();
                let ours = MIN_SIN * MIN_SIN * a_sq * b_sq;
                let other = MIN_SIN * MIN_SIN * (a_sq * b_sq);
                if (n_sq < ours) != (n_sq < other) {
                    return [j + a, j, j + b];
                }
            }
        }
    }

    fn angle_colour(rng: &mut Rng) -> Colour<3> {
        use crate::angle::{edge_angle, edge_angle_gradient, MIN_SIN};
        let mut c = Colour::scattered(rng, [2, 0, 1]);
        // The near-collinear angles the one-angle kernel projects and skips.
        let (mut near_kept, mut near_skipped) = (0, 0);
        for k in 0..c.ids.len() {
            let ids = c.ids[k];
            let case = k % 33;
            let phi = match case {
                0 => 0.0,
                1 => PI,
                2 => MIN_SIN * rng.range(0.5, 2.0),
                3 => PI - MIN_SIN * rng.range(0.5, 2.0),
                4 => rng.range(1e-9, 1e-7),
                5 => PI - rng.range(1e-9, 1e-7),
                _ => rng.range(0.0, PI),
            };
            let scale = match case {
                6 => 1e-12,   // edges about the length limit
                7 => 1e77,    // squares finite, the normal's not
                8 => 1e150,   // squares overflow
                9 => 1e-160,  // squares underflow
                10 => 1e50,   // large and projectable
                27 => 1e60,   // the gradient's denominator overflows: a zero gradient
                28 => 1e-100, // the normal's square and its bound underflow to 0
                _ => 1.0,
            };
            let (la, lb) = (rng.range(0.2, 2.0) * scale, rng.range(0.2, 2.0) * scale);
            let mut p = angle(rng, phi, la, lb, scale);
            let [i, j, kk] = ids.map(|i| i as usize);
            match case {
                11 => p = [p[1]; 3],                       // all coincident
                12 => p[0] = p[1],                         // zero-length edge a
                13 => p[2] = p[1],                         // zero-length edge b
                14 => p[0] = p[1] + (p[0] - p[1]) * 1e-12, // a about the length limit
                15 => p[2] = p[1] + (p[2] - p[1]) * 1e-12, // b about it
                16 => p[2] = p[1] + (p[1] - p[0]) * 0.7,   // straight through rounding
                17 => p[2] = p[1] + (p[0] - p[1]) * 1.3,   // folded back through rounding
                18 => (p[0], p[2]) = (p[1] + DVec3::X * la, p[1] - DVec3::X * lb), // straight
                19 => (p[0], p[2]) = (p[1] + DVec3::Y * la, p[1] + DVec3::Y * lb), // folded
                20 => p[2].y = f64::NAN,                   // a NaN position
                21 => p[0].z = f64::INFINITY,              // an infinite one
                22 => (c.w[i], c.w[j], c.w[kk]) = (0.0, 0.0, 0.0), // all pinned
                23 => (c.w[i], c.w[kk]) = (0.0, 0.0),      // two pinned
                24 => c.w[j] = f64::NAN,                   // a NaN inverse mass
                25 => {
                    // Negative zeros where the correction may be ±0.
                    p[1] = DVec3::new(-0.0, 0.0, -0.0);
                    c.w[j] = 0.0;
                }
                26 => {
                    // Subnormal inverse masses: `delta_lambda`'s denominator below the
                    // smallest normal number when rigid, so Δλ = 0.
                    (c.w[i], c.w[j], c.w[kk]) = (1e-310, 1e-310, 1e-310);
                }
                29..=31 => p = at_a_limit(case, k / 33),
                32 => p = between_the_bounds(rng),
                _ => {}
            }
            if case == 29 && k / 33 % 3 == 1 {
                assert!(edge_angle_gradient(&p).is_some(), "kept at MIN_SIN: {p:?}");
            }
            if matches!(case, 2 | 3) {
                match edge_angle_gradient(&p) {
                    Some(_) => near_kept += 1,
                    None => near_skipped += 1,
                }
            }
            for (r, q) in ids.iter().zip(p) {
                c.x[*r as usize] = q;
            }
            // Rest angles: the current one, straight, folded, or any.
            c.rest.push(match k % 7 {
                0 => edge_angle(&p).unwrap_or(0.5),
                1 => PI,
                2 => 0.0,
                _ => rng.range(0.0, PI),
            });
        }
        assert!(
            near_kept > 10 && near_skipped > 10,
            "{near_kept} {near_skipped}"
        );
        c.assert_one_colour();
        c
    }

    #[test]
    fn four_lanes_give_the_bits_of_the_one_angle_kernel_on_colours_with_every_degenerate_case() {
        lanes_or_say_why_not();
        let mut rng = Rng(0xa261e);
        let h = 1.0 / 600.0;
        // Rigid, the shear of a sample scene, stiff, cotton, silk, and so soft that
        // `delta_lambda`'s denominator overflows (its guard then gives Δλ = 0).
        for alpha in [0.0, 1e-3, 1e-2, 5e3, 1e5, 1e305] {
            let terms = PassTerms { alpha, h };
            let c = angle_colour(&mut rng);
            let one = c.pass(project_one_by_one::<3, EdgeAngle>, terms);
            let four = c.pass(project_colour::<3, EdgeAngle>, terms);
            c.assert_same_bits(&one, &four, alpha);
        }
    }

    /// A random hinge of size `scale` (as [`hinge`]) flat, the weights `K'` of that rest
    /// shape, and the same hinge folded by `phi`.
    fn isometric_hinge(rng: &mut Rng, phi: f64, scale: f64) -> ([DVec3; 4], [f64; 4], [DVec3; 4]) {
        let flat = hinge(&mut rng.clone(), 0.0, scale);
        let k = isometric_weights(&flat).expect("a regular rest shape");
        (flat, k, hinge(rng, phi, scale))
    }

    /// 4,003 isometric hinges on 16,012 particles (one colour, a tail of 3 for the one-hinge
    /// kernel), with random shapes, fold angles, inverse masses and multipliers, and every
    /// case the kernels treat apart: flat in the rest shape's plane (`|v|` of rounding only),
    /// `v` exactly zero (all points coincident, zero weights, weights only on `x₀`), near flat
    /// on both sides of `MIN_V`, `|v|²` exactly at `MIN_V²` or one ulp of `|v|` off, folded to
    /// ±π and near it, random weights (not summing to zero) and huge or NaN ones, two points
    /// coincident, NaN and infinite positions, sizes from 1e-160 (`|v|²` underflows) to 1e150
    /// (it overflows) and 1e100 (`denom |v|` overflows when very soft), tiny and huge rest
    /// shapes with their weights, negative zeros, two or all inverse masses zero, a NaN one,
    /// subnormal ones.
    fn isometric_colour(rng: &mut Rng) -> Colour<4, [f64; 4]> {
        use crate::bergou2006_isometric::MIN_V;
        let mut c = Colour::scattered(rng, [1, 3, 0, 2]);
        let (mut flat_kept, mut flat_skipped) = (0, 0);
        for k in 0..c.ids.len() {
            let ids = c.ids[k];
            let case = k % 31;
            let phi = match case {
                5 => PI - rng.range(0.0, 1e-9),
                6 => -PI + rng.range(0.0, 1e-9),
                7 => PI,
                _ => rng.range(-PI, PI),
            };
            let scale = match case {
                8 => 1e-7,
                9 => 1e7,
                _ => 1.0,
            };
            let (flat, mut kw, mut p) = isometric_hinge(rng, phi, scale);
            let [i, j, kk, l] = ids.map(|i| i as usize);
            match case {
                0 => p = flat, // flat: `v` of rounding only, below `MIN_V`
                1 => {
                    // Near flat: wing l lifted off the plane by about `MIN_V / |K'₃|`, so
                    // `|v|` falls on either side of `MIN_V`.
                    let n = (flat[1] - flat[0]).cross(flat[2] - flat[0]).normalize();
                    p = flat;
                    p[3] += n * (MIN_V * rng.range(0.3, 3.0) / kw[3].abs());
                }
                2 => p = [p[0]; 4],               // all coincident: `v` = 0
                3 => kw = [0.0; 4],               // no weights: `v` = 0, nothing movable
                4 => kw = [kw[0], 0.0, 0.0, 0.0], // `v` = 0, yet movable
                10 => kw[1 + k / 31 % 3] = 0.0,   // one zero weight
                11 => kw = [0; 4].map(|_| rng.range(-3.0, 3.0)), // any weights
                12 => kw[k / 31 % 4] = 1e160,     // `w K'²` overflows
                13 => kw[k / 31 % 4] = f64::NAN,
                14 => {
                    // `|v|² = MIN_V²` exactly, or `|v|` one ulp below or above `MIN_V`.
                    let m = [MIN_V.next_down(), MIN_V, MIN_V.next_up()][k / 31 % 3];
                    p = [
                        DVec3::ZERO,
                        DVec3::new(0.0, m, 0.0),
                        DVec3::new(0.5, 0.0, 1.0),
                        DVec3::new(0.5, 0.0, -1.0),
                    ];
                    kw = [-1.0, 1.0, 0.0, 0.0];
                }
                15 => p[2] = p[0],               // two points coincident
                16 => p[3].y = f64::NAN,         // a NaN position
                17 => p[0].z = f64::INFINITY,    // an infinite one
                18 => p = p.map(|q| q * 1e-160), // `|v|²` underflows to 0
                19 => p = p.map(|q| q * 1e150),  // `|v|²` overflows
                20 => p = p.map(|q| q * 1e100),  // `denom |v|` overflows when very soft
                21 => (c.w[i], c.w[j], c.w[kk], c.w[l]) = (0.0, 0.0, 0.0, 0.0), // all pinned
                22 => (c.w[i], c.w[l]) = (0.0, 0.0), // two pinned
                23 => c.w[kk] = f64::NAN,        // a NaN inverse mass
                24 => {
                    // Negative zeros where the correction may be ±0.
                    p[0] = DVec3::new(-0.0, 0.0, -0.0);
                    c.w[i] = 0.0;
                }
                25 => {
                    // Subnormal inverse masses: the denominator below the smallest normal
                    // number when rigid.
                    (c.w[i], c.w[j], c.w[kk], c.w[l]) = (1e-310, 1e-310, 1e-310, 1e-310);
                }
                26 => kw = kw.map(|k| k * 1e-160), // `w K'²` underflows
                _ => {}
            }
            if case == 1 {
                match project_isometric(&p, &kw, &[1.0; 4], 0.0, 0.0, 1.0) {
                    Some(_) => flat_kept += 1,
                    None => flat_skipped += 1,
                }
            }
            if case == 14 {
                let kept = project_isometric(&p, &kw, &[1.0; 4], 0.0, 0.0, 1.0).is_some();
                assert_eq!(kept, k / 31 % 3 != 0, "at MIN_V: {p:?}");
            }
            for (r, q) in ids.iter().zip(p) {
                c.x[*r as usize] = q;
            }
            c.rest.push(kw);
        }
        assert!(
            flat_kept > 5 && flat_skipped > 5,
            "{flat_kept} {flat_skipped}"
        );
        c.assert_one_colour();
        c
    }

    #[test]
    fn four_lanes_give_the_bits_of_the_one_isometric_kernel_on_colours_with_every_degenerate_case()
    {
        lanes_or_say_why_not();
        if !avx2_available() {
            return;
        }
        let mut rng = Rng(0x150);
        let h = 1.0 / 600.0;
        // Rigid, stiff, cotton, silk, so soft that `denom |v|` overflows for large hinges, and
        // so soft that `α̃` is infinite (every hinge skipped).
        for alpha in [0.0, 1e-2, 5e3, 1e5, 1e300, 1e305] {
            let terms = PassTerms { alpha, h };
            let c = isometric_colour(&mut rng);
            let one = c.pass(project_one_by_one::<4, Isometric>, terms);
            let four = c.pass(project_colour::<4, Isometric>, terms);
            c.assert_same_bits(&one, &four, alpha);
        }
    }

    /// `atan2` of four lanes as [`crate::trig::atan2`] of each, through every branch: the
    /// three ranges of the reduced argument, both swaps, all four quadrants, ±0, infinities
    /// and NaN (NaN compared as NaN, whatever its payload).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn four_lane_atan2_gives_the_bits_of_the_one_lane_atan2() {
        use std::arch::x86_64::{_mm256_loadu_pd, _mm256_storeu_pd};
        lanes_or_say_why_not();
        if !avx2_available() {
            return;
        }
        let mut rng = Rng(0xa7a2);
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f64::INFINITY,
            -f64::INFINITY,
            f64::NAN,
            1e-310,
        ];
        let mut args = Vec::new();
        for &y in &special {
            for &x in &special {
                args.push((y, x));
            }
        }
        for k in 0..400_000 {
            let x = 10f64.powf(rng.range(-20.0, 20.0)) * if k % 2 == 0 { 1.0 } else { -1.0 };
            // Ratios |y/x| through every branch of the reduction and their boundaries.
            let t = match k % 5 {
                0 => rng.range(0.0, 0.66),
                1 => rng.range(0.66, 1.0),
                2 => rng.range(1.0, 2.5),
                3 => 10f64.powf(rng.range(0.0, 20.0)),
                _ => [0.66, 1.0, crate::trig::T3P8][k % 3] * rng.range(1.0 - 1e-15, 1.0 + 1e-15),
            };
            let y = x * t * if k % 3 == 0 { -1.0 } else { 1.0 };
            args.push((y, x));
        }
        for four in args.chunks_exact(4) {
            let (y, x): (Vec<f64>, Vec<f64>) = four.iter().copied().unzip();
            let mut out = [0.0; 4];
            // SAFETY: AVX2 is present (checked above); four values in and out.
            unsafe {
                let a = avx2::atan2(_mm256_loadu_pd(y.as_ptr()), _mm256_loadu_pd(x.as_ptr()));
                _mm256_storeu_pd(out.as_mut_ptr(), a);
            }
            for l in 0..4 {
                let one = crate::trig::atan2(y[l], x[l]);
                assert!(
                    one.to_bits() == out[l].to_bits() || (one.is_nan() && out[l].is_nan()),
                    "atan2({}, {}): {one} vs {}",
                    y[l],
                    x[l],
                    out[l]
                );
            }
        }
    }
}
