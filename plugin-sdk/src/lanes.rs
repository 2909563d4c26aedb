//! Four points at a time in the processor's 256-bit lanes (AVX2): the primitives the plugins'
//! four-lane kernels share (`stretch`'s edge pass, `bend`'s dihedral hinge pass).
//!
//! Why it exists: a plugin's hot loop projects the constraints of one colour
//! ([`crate::colour`]), which share no particle, so a kernel may project four of them per
//! instruction, one constraint per lane, and write the four back one by one. Such a kernel must
//! give the same bits as the one-at-a-time scalar code it stands for (a pass must not depend on
//! whether the processor has AVX2), so every primitive here does the same IEEE operations, in
//! the same order, as the [`DVec3`] operation it names: a separate multiply and add where glam
//! multiplies and adds, never a fused multiply-add (whose single rounding would differ).
//!
//! Use [`avx2_available`] to choose the lanes at run time, and call the [`avx2`] functions only
//! from a function compiled with `#[target_feature(enable = "avx2")]`: there they are safe to
//! call (but for the raw-pointer [`avx2::load`] and [`avx2::store`]) and, being `#[inline]`,
//! are inlined into the caller's loop across the crate boundary.
//!
//! This is plain Rust API for plugins built with the SDK, not part of the stable ABI: nothing
//! here crosses the host–plugin boundary, and it may change without a bump of
//! [`SDK_ABI_VERSION`](crate::SDK_ABI_VERSION) (see the crate docs' "Versioning").
//!
//! [`DVec3`]: glam::DVec3

/// Whether this processor has AVX2, so that the [`avx2`] functions may run (checked once by
/// the standard library, then cached by it). On processors other than x86_64 it is always
/// false.
#[inline]
pub fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The AVX2 primitives: [`Lanes3`](avx2::Lanes3), three coordinates of four points, with
/// their loads, stores and the [`DVec3`](glam::DVec3) arithmetic lane by lane, each with the
/// bits of the scalar operation it names.
///
/// Every function requires AVX2 (`#[target_feature(enable = "avx2")]`): call them from a
/// function that enables it too, after [`avx2_available`] returned true.
#[cfg(target_arch = "x86_64")]
pub mod avx2 {
    use std::arch::x86_64::*;

    use glam::DVec3;

    /// Three coordinates of four points, one register each: lane `l` of `x`, `y`, `z` is
    /// point `l`.
    #[derive(Clone, Copy, Debug)]
    pub struct Lanes3 {
        /// The four points' `x`.
        pub x: __m256d,
        /// The four points' `y`.
        pub y: __m256d,
        /// The four points' `z`.
        pub z: __m256d,
    }

    /// Loads the points `p[k[0]]..p[k[3]]` into lanes 0..3: each point's `x, y` as one 16-byte
    /// load, interleaved by two unpacks, and the four `z` one by one.
    ///
    /// # Safety
    /// Every `k[l]` indexes a point of `p`, valid to read, that no other thread writes
    /// meanwhile; AVX2 is present.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub unsafe fn load(p: *const DVec3, k: [usize; 4]) -> Lanes3 {
        // SAFETY: the caller's contract; a `DVec3` is three `f64` in a row (`repr(C)`).
        let [a, b, c, d] = k.map(|k| unsafe { p.add(k) as *const f64 });
        // SAFETY: as above, reading the first two and the third double of each point.
        unsafe {
            let ac = _mm256_set_m128d(_mm_loadu_pd(c), _mm_loadu_pd(a));
            let bd = _mm256_set_m128d(_mm_loadu_pd(d), _mm_loadu_pd(b));
            Lanes3 {
                x: _mm256_unpacklo_pd(ac, bd),
                y: _mm256_unpackhi_pd(ac, bd),
                z: _mm256_setr_pd(*a.add(2), *b.add(2), *c.add(2), *d.add(2)),
            }
        }
    }

    /// Writes lanes 0..3 to the points `p[k[0]]..p[k[3]]`, in that order (so the last lane
    /// wins where two indices are equal): each point's `x, y` as one 16-byte store after two
    /// unpacks, and its `z` alone.
    ///
    /// # Safety
    /// Every `k[l]` indexes a point of `p`, valid to write, that no other thread reads or
    /// writes meanwhile; AVX2 is present.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub unsafe fn store(p: *mut DVec3, k: [usize; 4], v: &Lanes3) {
        // SAFETY: the caller's contract; a `DVec3` is three `f64` in a row (`repr(C)`).
        let [a, b, c, d] = k.map(|k| unsafe { p.add(k) as *mut f64 });
        let ac = _mm256_unpacklo_pd(v.x, v.y); // xa ya xc yc
        let bd = _mm256_unpackhi_pd(v.x, v.y); // xb yb xd yd
        let (z_ab, z_cd) = (_mm256_castpd256_pd128(v.z), _mm256_extractf128_pd::<1>(v.z));
        // SAFETY: as above, writing the first two and the third double of each point.
        unsafe {
            _mm_storeu_pd(a, _mm256_castpd256_pd128(ac));
            _mm_storeu_pd(b, _mm256_castpd256_pd128(bd));
            _mm_storeu_pd(c, _mm256_extractf128_pd::<1>(ac));
            _mm_storeu_pd(d, _mm256_extractf128_pd::<1>(bd));
            _mm_storel_pd(a.add(2), z_ab);
            _mm_storeh_pd(b.add(2), z_ab);
            _mm_storel_pd(c.add(2), z_cd);
            _mm_storeh_pd(d.add(2), z_cd);
        }
    }

    /// `a · b` as [`DVec3::dot`] rounds it: `((a.x b.x) + (a.y b.y)) + (a.z b.z)`, each
    /// product and sum rounded on its own.
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn dot(a: &Lanes3, b: &Lanes3) -> __m256d {
        _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(a.x, b.x), _mm256_mul_pd(a.y, b.y)),
            _mm256_mul_pd(a.z, b.z),
        )
    }

    /// `a − b`, coordinate by coordinate, as `DVec3 - DVec3`.
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn sub(a: &Lanes3, b: &Lanes3) -> Lanes3 {
        Lanes3 {
            x: _mm256_sub_pd(a.x, b.x),
            y: _mm256_sub_pd(a.y, b.y),
            z: _mm256_sub_pd(a.z, b.z),
        }
    }

    /// `a + b`, coordinate by coordinate, as `DVec3 + DVec3`.
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn add(a: &Lanes3, b: &Lanes3) -> Lanes3 {
        Lanes3 {
            x: _mm256_add_pd(a.x, b.x),
            y: _mm256_add_pd(a.y, b.y),
            z: _mm256_add_pd(a.z, b.z),
        }
    }

    /// `a s` (each lane's point times that lane's `s`), as `DVec3 * f64`: `a.x s`, `a.y s`,
    /// `a.z s`.
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn scale(a: &Lanes3, s: __m256d) -> Lanes3 {
        Lanes3 {
            x: _mm256_mul_pd(a.x, s),
            y: _mm256_mul_pd(a.y, s),
            z: _mm256_mul_pd(a.z, s),
        }
    }

    /// `−v`: the sign bit flipped, as Rust's `-v` on an `f64` (not `0 − v`, which gives `+0`
    /// for `+0`).
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn neg(v: __m256d) -> __m256d {
        _mm256_xor_pd(v, _mm256_set1_pd(-0.0))
    }

    /// `keep ? a : b`, lane by lane, bit for bit (`keep` all ones or all zeros per lane, as a
    /// comparison gives; only its sign bit is read).
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn select(keep: __m256d, a: __m256d, b: __m256d) -> __m256d {
        _mm256_blendv_pd(b, a, keep)
    }

    /// `keep ? a : b`, lane by lane, for all three coordinates, as [`select`].
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn select3(keep: __m256d, a: &Lanes3, b: &Lanes3) -> Lanes3 {
        Lanes3 {
            x: select(keep, a.x, b.x),
            y: select(keep, a.y, b.y),
            z: select(keep, a.z, b.z),
        }
    }

    /// `p + d` in the lanes where `apply`, else `p` unchanged (bit for bit, even where `p + d`
    /// is NaN): a correction applied only to the constraints the scalar code would move.
    ///
    /// # Safety
    /// AVX2 is present (a safe call from a function that enables it).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub fn moved(p: &Lanes3, d: &Lanes3, apply: __m256d) -> Lanes3 {
        select3(apply, &add(p, d), p)
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use std::arch::x86_64::*;

    use glam::DVec3;

    use super::avx2::{self, Lanes3};
    use super::avx2_available;
    use crate::testing::Rng;

    /// Whether the lanes can run here; if not, says why the test checks nothing.
    fn lanes_or_say_why_not() -> bool {
        let ok = avx2_available();
        if !ok {
            eprintln!("this processor has no AVX2: the lane primitives are not exercised");
        }
        ok
    }

    fn bits(p: DVec3) -> [u64; 3] {
        [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
    }

    /// Four values into a register and back.
    fn reg(v: [f64; 4]) -> __m256d {
        // SAFETY: four values read; AVX is present (the callers check AVX2 first).
        unsafe { _mm256_loadu_pd(v.as_ptr()) }
    }

    fn unreg(v: __m256d) -> [f64; 4] {
        let mut out = [0.0; 4];
        // SAFETY: four values written; as in `reg`.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        out
    }

    fn lanes(p: [DVec3; 4]) -> Lanes3 {
        Lanes3 {
            x: reg(p.map(|p| p.x)),
            y: reg(p.map(|p| p.y)),
            z: reg(p.map(|p| p.z)),
        }
    }

    fn points(v: &Lanes3) -> [DVec3; 4] {
        let (x, y, z) = (unreg(v.x), unreg(v.y), unreg(v.z));
        [0, 1, 2, 3].map(|l| DVec3::new(x[l], y[l], z[l]))
    }

    /// A random coordinate, now and then one the arithmetic treats apart: ±0, ±∞, NaN, a
    /// subnormal, a huge value whose products overflow.
    fn coordinate(rng: &mut Rng) -> f64 {
        const SPECIAL: [f64; 8] = [
            0.0,
            -0.0,
            f64::INFINITY,
            -f64::INFINITY,
            f64::NAN,
            1e-310,
            -1e300,
            1e300,
        ];
        if rng.next_f64() < 0.2 {
            SPECIAL[rng.pick(SPECIAL.len())]
        } else {
            rng.range(-2.0, 2.0)
        }
    }

    fn point(rng: &mut Rng) -> DVec3 {
        DVec3::new(coordinate(rng), coordinate(rng), coordinate(rng))
    }

    /// Loads four points at scattered indices and stores them, changed, at others: each
    /// lane reads and writes its own point, and every other point keeps its bits.
    #[test]
    fn load_and_store_move_four_scattered_points_and_no_other() {
        if !lanes_or_say_why_not() {
            return;
        }
        let mut rng = Rng(0x1a9e5);
        let mut p: Vec<DVec3> = (0..64).map(|_| point(&mut rng)).collect();
        let before = p.clone();
        for k in [[0, 1, 2, 3], [63, 7, 40, 8], [5, 62, 0, 33]] {
            let at = [9, 61, 1, 30];
            // SAFETY: every index is below 64; AVX2 is present (checked above).
            let v = unsafe { avx2::load(p.as_ptr(), k) };
            assert_eq!(points(&v).map(bits), k.map(|k| bits(p[k])));
            let moved = Lanes3 {
                x: v.y,
                y: v.z,
                z: v.x,
            };
            let mut q = p.clone();
            // SAFETY: as above; one thread owns `q`.
            unsafe { avx2::store(q.as_mut_ptr(), at, &moved) };
            for (i, (&new, &old)) in q.iter().zip(&p).enumerate() {
                let want = match at.iter().position(|&a| a == i) {
                    Some(l) => DVec3::new(p[k[l]].y, p[k[l]].z, p[k[l]].x),
                    None => old,
                };
                assert_eq!(bits(new), bits(want), "point {i}, loaded from {k:?}");
            }
            p = q;
        }
        assert_ne!(
            p.iter().map(|&p| bits(p)).collect::<Vec<_>>(),
            before.iter().map(|&p| bits(p)).collect::<Vec<_>>()
        );
    }

    /// Every arithmetic primitive, on random points and special values, gives in each lane
    /// the bits of the [`DVec3`] or `f64` operation it names (NaN compared as NaN, whatever
    /// its payload, as the scalar code's payload is the processor's choice too).
    #[test]
    fn lane_arithmetic_gives_the_bits_of_the_dvec3_operations() {
        if !lanes_or_say_why_not() {
            return;
        }
        let same = |lane: f64, scalar: f64| {
            lane.to_bits() == scalar.to_bits() || (lane.is_nan() && scalar.is_nan())
        };
        let same3 = |lane: DVec3, scalar: DVec3| {
            same(lane.x, scalar.x) && same(lane.y, scalar.y) && same(lane.z, scalar.z)
        };
        let mut rng = Rng(0xd07);
        for round in 0..20_000 {
            let a = [0; 4].map(|_| point(&mut rng));
            let b = [0; 4].map(|_| point(&mut rng));
            let s = [0; 4].map(|_| coordinate(&mut rng));
            // Lanes where `keep` holds: from a comparison, as the kernels make it.
            let keep_lanes = [0; 4].map(|_| rng.next_f64() < 0.5);
            let keep_in = keep_lanes.map(|k| if k { 1.0 } else { -1.0 });
            let (la, lb, ls) = (lanes(a), lanes(b), reg(s));
            // SAFETY: AVX2 is present (checked above), which these functions need.
            let (dot, sub, add, scale, neg, select, select3, moved) = unsafe {
                let keep = _mm256_cmp_pd::<_CMP_GT_OQ>(reg(keep_in), _mm256_setzero_pd());
                (
                    unreg(avx2::dot(&la, &lb)),
                    points(&avx2::sub(&la, &lb)),
                    points(&avx2::add(&la, &lb)),
                    points(&avx2::scale(&la, ls)),
                    unreg(avx2::neg(ls)),
                    unreg(avx2::select(keep, ls, la.x)),
                    points(&avx2::select3(keep, &la, &lb)),
                    points(&avx2::moved(&la, &lb, keep)),
                )
            };
            for l in 0..4 {
                let why = format!(
                    "round {round}, lane {l}: a {:?}, b {:?}, s {}",
                    a[l], b[l], s[l]
                );
                assert!(same(dot[l], a[l].dot(b[l])), "dot, {why}");
                assert!(same3(sub[l], a[l] - b[l]), "sub, {why}");
                assert!(same3(add[l], a[l] + b[l]), "add, {why}");
                assert!(same3(scale[l], a[l] * s[l]), "scale, {why}");
                // The sign flip keeps NaN's payload: compared bit for bit.
                assert_eq!(neg[l].to_bits(), (-s[l]).to_bits(), "neg, {why}");
                let (pick, pick3, to) = if keep_lanes[l] {
                    (s[l], a[l], a[l] + b[l])
                } else {
                    (a[l].x, b[l], a[l])
                };
                // A selection copies bits, NaN's payload included.
                assert_eq!(select[l].to_bits(), pick.to_bits(), "select, {why}");
                assert_eq!(bits(select3[l]), bits(pick3), "select3, {why}");
                if keep_lanes[l] {
                    assert!(same3(moved[l], to), "moved, {why}");
                } else {
                    assert_eq!(bits(moved[l]), bits(to), "moved, {why}");
                }
            }
        }
    }
}
