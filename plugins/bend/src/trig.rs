//! `atan2` without the C library's slow paths.
//!
//! Every angle of this plugin is an `atan2`, evaluated once per constraint per pass. glibc's
//! correctly rounded `atan2` takes a slow path for some arguments and was half the time of a
//! curve-bend pass on a nearly straight rope. This is Cephes' `atan` (S. L. Moshier; range
//! reduction to |t| ≤ 0.66 and a degree 4/5 rational approximation, relative error about
//! 2e-16), extended to the four quadrants: within one ulp of π (4.4e-16 rad) of `f64::atan2`
//! for finite arguments (checked below), and branch-light.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

pub(crate) const P: [f64; 5] = [
    -8.750_608_600_031_904e-1,
    -1.615_753_718_733_365e1,
    -7.500_855_792_314_705e1,
    -1.228_866_684_490_136_2e2,
    -6.485_021_904_942_025e1,
];
pub(crate) const Q: [f64; 5] = [
    2.485_846_490_142_306_4e1,
    1.650_270_098_316_988_6e2,
    4.328_810_604_912_902_5e2,
    4.853_903_996_359_137e2,
    1.945_506_571_482_614e2,
];
/// tan(3π/8).
pub(crate) const T3P8: f64 = 2.414_213_562_373_095;
/// At most this, `atan_nonnegative` takes its argument unreduced.
pub(crate) const UNREDUCED_MAX: f64 = 0.66;
/// The low bits of π/2 that `FRAC_PI_2` cannot hold.
pub(crate) const MOREBITS: f64 = 6.123_233_995_736_766e-17;

/// `atan(t)` for `t ≥ 0` (finite or +∞).
#[inline]
fn atan_nonnegative(t: f64) -> f64 {
    let (base, x, extra) = if t > T3P8 {
        (FRAC_PI_2, -1.0 / t, MOREBITS)
    } else if t <= UNREDUCED_MAX {
        (0.0, t, 0.0)
    } else {
        (FRAC_PI_4, (t - 1.0) / (t + 1.0), 0.5 * MOREBITS)
    };
    let z = x * x;
    let p = (((P[0] * z + P[1]) * z + P[2]) * z + P[3]) * z + P[4];
    let q = ((((z + Q[0]) * z + Q[1]) * z + Q[2]) * z + Q[3]) * z + Q[4];
    base + (x * (z * p / q) + x + extra)
}

/// The angle of the point `(x, y)` in `[−π, π]`, as `f64::atan2` (to within 4.5e-16 rad) for
/// finite arguments; 0 for `(0, 0)`. NaN in, NaN out.
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ay, ax) = (y.abs(), x.abs());
    // The angle in [0, π/2] of (|x|, |y|), from the smaller ratio for accuracy.
    let a = if ay <= ax {
        if ax == 0.0 {
            return if y.is_nan() || x.is_nan() {
                f64::NAN
            } else {
                0.0
            };
        }
        atan_nonnegative(ay / ax)
    } else {
        FRAC_PI_2 - atan_nonnegative(ax / ay)
    };
    let a = if x < 0.0 { PI - a } else { a };
    a.copysign(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::Rng;

    #[test]
    fn matches_the_library_atan2_to_one_ulp_of_pi_everywhere() {
        let mut rng = Rng(17);
        let mut worst: f64 = 0.0;
        for k in 0..200_000 {
            // Magnitudes over 40 decades, every sign, and points near the axes.
            let mag = |rng: &mut Rng| 10f64.powf(rng.range(-20.0, 20.0));
            let (mut y, mut x) = (mag(&mut rng), mag(&mut rng));
            if k % 3 == 0 {
                y = x * rng.range(-1e-9, 1e-9);
            }
            if k % 5 == 0 {
                x = y * rng.range(-1e-9, 1e-9);
            }
            if rng.next_f64() < 0.5 {
                y = -y;
            }
            if rng.next_f64() < 0.5 {
                x = -x;
            }
            let err = (atan2(y, x) - y.atan2(x)).abs();
            worst = worst.max(err);
        }
        assert!(worst <= 4.5e-16, "worst error {worst}");
    }

    #[test]
    fn special_values() {
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert_eq!(atan2(0.0, 1.0), 0.0);
        assert_eq!(atan2(0.0, -1.0), PI);
        assert_eq!(atan2(-0.0, -1.0), -PI);
        assert_eq!(atan2(1.0, 0.0), FRAC_PI_2);
        assert_eq!(atan2(-1.0, 0.0), -FRAC_PI_2);
        assert!((atan2(1.0, 1.0) - FRAC_PI_4).abs() < 1e-16);
        assert!((atan2(1.0, -1.0) - 3.0 * FRAC_PI_4).abs() < 1e-15);
        assert!(atan2(f64::NAN, 1.0).is_nan());
        assert!(atan2(1.0, f64::NAN).is_nan());
        assert!(atan2(0.0, f64::NAN).is_nan());
        assert_eq!(atan2(1.0, f64::INFINITY), 0.0);
        assert_eq!(atan2(f64::INFINITY, 1.0), FRAC_PI_2);
    }
}
