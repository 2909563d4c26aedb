//! The wind: a uniform directional velocity plus a seeded, smooth, space- and time-varying
//! turbulence, as a pure function of position and time.
//!
//! ```text
//! w(p, t) = U d̂ + a · N(seed, (p − U d̂ t)/L, f t)
//! ```
//!
//! `U` is the wind speed (m/s), `d̂` the unit direction, `a` the noise amplitude (m/s), `L` the
//! spatial scale of the gusts (m) and `f` their frequency (Hz). `N` is a vector of three
//! independent 4-D value noises, each in `[−1, 1]`: random values on the integer lattice of
//! (space, time), hashed from the seed and the lattice point (SplitMix64), blended with the
//! quintic fade `6s⁵ − 15s⁴ + 10s³`, so the wind is C² in space and time. The pattern is
//! carried downstream with the mean wind (Taylor's frozen turbulence) while it evolves in
//! time, so gusts travel along the flag instead of pulsing in place.
//!
//! `N` depends only on its arguments: the same seed gives bit-identical wind on every run,
//! machine and thread count, and two groups with the same wind parameters see the same field.

use glam::DVec3;

/// The wind a group sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wind {
    /// Mean wind velocity `U d̂` (m/s).
    pub velocity: DVec3,
    /// Turbulence amplitude `a` (m/s): each component of the turbulence lies in `[−a, a]`.
    pub noise: f64,
    /// Gust frequency `f` (Hz): the lattice spacing in time is `1/f`.
    pub frequency: f64,
    /// Gust size `L` (m): the lattice spacing in space.
    pub scale: f64,
    /// Seed of the turbulence.
    pub seed: u64,
}

impl Wind {
    /// A steady, uniform wind.
    pub fn steady(velocity: DVec3) -> Self {
        Self {
            velocity,
            noise: 0.0,
            frequency: 0.0,
            scale: 1.0,
            seed: 0,
        }
    }

    /// Whether the wind is the same everywhere and always.
    pub fn is_uniform(&self) -> bool {
        self.noise == 0.0
    }

    /// The wind velocity (m/s) at `p` (m) and time `t` (s).
    #[inline]
    pub fn at(&self, p: DVec3, t: f64) -> DVec3 {
        if self.is_uniform() {
            return self.velocity;
        }
        let q = (p - self.velocity * t) / self.scale;
        let s = t * self.frequency;
        let at = [q.x, q.y, q.z, s];
        self.velocity + self.noise * DVec3::from_array(value_noise(self.seed, at))
    }
}

/// SplitMix64's finaliser: a bijective, well-mixing hash of 64 bits.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Bits per component of a corner's hash.
const BITS: u32 = 21;

/// Three values uniform in `[−1, 1]` (to 2⁻²⁰) from the three 21-bit fields of one hash, so
/// the three components of the turbulence share the lattice hashing.
#[inline]
fn corner(h: u64) -> [f64; 3] {
    let mask = (1u64 << BITS) - 1;
    let scale = 2.0 / mask as f64;
    [
        ((h >> (64 - BITS)) & mask) as f64 * scale - 1.0,
        ((h >> (64 - 2 * BITS)) & mask) as f64 * scale - 1.0,
        ((h >> (64 - 3 * BITS)) & mask) as f64 * scale - 1.0,
    ]
}

/// The quintic fade `6s⁵ − 15s⁴ + 10s³`: 0 and 1 at the ends with zero first and second
/// derivatives, so the noise is C².
#[inline]
fn fade(s: f64) -> f64 {
    s * s * s * (s * (s * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * s,
        a[1] + (b[1] - a[1]) * s,
        a[2] + (b[2] - a[2]) * s,
    ]
}

/// Three independent 4-D value noises, each in `[−1, 1]`, for `seed` at `p`.
///
/// Coordinates are floored to the lattice in `i64` (`as` saturates, and maps NaN to 0, so no
/// input can panic); each of the 16 corners of the cell is hashed once (SplitMix64, reusing
/// the hashes of the leading coordinates: 2 + 4 + 8 + 16 mixes), its hash split into the
/// three components' values, and the corners blended with the quintic fade.
pub fn value_noise(seed: u64, p: [f64; 4]) -> [f64; 3] {
    let cell = p.map(f64::floor);
    let i = cell.map(|c| c as i64 as u64);
    let s = [0, 1, 2, 3].map(|k| {
        let f = p[k] - cell[k];
        // A non-finite coordinate gives a NaN fraction: use the cell's corner.
        fade(if f.is_finite() { f } else { 0.0 })
    });
    let root = mix(seed);
    let mut vx = [[0.0; 3]; 2];
    for dx in 0..2u64 {
        let hx = mix(root ^ i[0].wrapping_add(dx));
        let mut vy = [[0.0; 3]; 2];
        for dy in 0..2u64 {
            let hy = mix(hx ^ i[1].wrapping_add(dy));
            let mut vz = [[0.0; 3]; 2];
            for dz in 0..2u64 {
                let hz = mix(hy ^ i[2].wrapping_add(dz));
                let a = corner(mix(hz ^ i[3]));
                let b = corner(mix(hz ^ i[3].wrapping_add(1)));
                vz[dz as usize] = lerp(a, b, s[3]);
            }
            vy[dy as usize] = lerp(vz[0], vz[1], s[2]);
        }
        vx[dx as usize] = lerp(vy[0], vy[1], s[1]);
    }
    lerp(vx[0], vx[1], s[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gusty(seed: u64) -> Wind {
        Wind {
            velocity: DVec3::new(8.0, 0.0, 0.0),
            noise: 2.0,
            frequency: 1.5,
            scale: 0.5,
            seed,
        }
    }

    #[test]
    fn steady_wind_is_uniform() {
        let w = Wind::steady(DVec3::new(3.0, 0.0, -4.0));
        for (p, t) in [(DVec3::ZERO, 0.0), (DVec3::splat(1e6), 1e5)] {
            assert_eq!(w.at(p, t), DVec3::new(3.0, 0.0, -4.0));
        }
    }

    #[test]
    fn noise_is_bounded_centred_and_uncorrelated_between_components() {
        let n = 20_000;
        let (mut sum, mut sum_sq, mut cross, mut max) = ([0.0; 3], [0.0; 3], [0.0; 3], 0.0f64);
        for k in 0..n {
            let p = [
                k as f64 * 0.137,
                k as f64 * 0.071,
                -(k as f64) * 0.029,
                k as f64 * 0.013,
            ];
            let v = value_noise(7, p);
            for c in 0..3 {
                sum[c] += v[c];
                sum_sq[c] += v[c] * v[c];
                cross[c] += v[c] * v[(c + 1) % 3];
                max = max.max(v[c].abs());
            }
        }
        assert!(max <= 1.0);
        for c in 0..3 {
            let mean = sum[c] / n as f64;
            let var = sum_sq[c] / n as f64;
            assert!(mean.abs() < 0.05, "component {c}: mean {mean}");
            // Blending 16 uniform values shrinks the spread: rms well inside (0.15, 0.58).
            assert!(
                var.sqrt() > 0.15 && var.sqrt() < 0.58,
                "component {c}: rms {}",
                var.sqrt()
            );
            let corr = cross[c] / n as f64 / var;
            assert!(
                corr.abs() < 0.1,
                "components {c} and {}: correlation {corr}",
                (c + 1) % 3
            );
        }
    }

    #[test]
    fn noise_takes_the_lattice_values_at_lattice_points() {
        // At integer coordinates the blend is exactly one corner value, a hash in [−1, 1].
        let a = value_noise(3, [2.0, -1.0, 5.0, 7.0]);
        let b = value_noise(3, [2.0, -1.0, 5.0, 8.0]);
        for k in 0..3 {
            assert!(a[k].abs() <= 1.0 && b[k].abs() <= 1.0);
            assert_ne!(a[k], b[k]);
            // Half way between them in time, the fade is ½.
            let mid = value_noise(3, [2.0, -1.0, 5.0, 7.5]);
            assert!((mid[k] - 0.5 * (a[k] + b[k])).abs() < 1e-15);
        }
    }

    #[test]
    fn noise_is_smooth_in_space_and_time() {
        // C²: the first differences are O(ε) with a bounded slope, and the second
        // differences O(ε²) — also across lattice cell boundaries.
        let eps = 1e-4;
        let mut worst_slope = 0.0f64;
        let mut worst_curvature = 0.0f64;
        for k in 0..2_000 {
            let base = [
                k as f64 * 0.0371 - 30.0,
                k as f64 * 0.0113,
                1.0 - k as f64 * 0.0057,
                k as f64 * 0.0191,
            ];
            for axis in 0..4 {
                let at = |d: f64| {
                    let mut p = base;
                    p[axis] += d;
                    value_noise(11, p)[2]
                };
                let (m, c, p) = (at(-eps), at(0.0), at(eps));
                worst_slope = worst_slope.max((p - m).abs() / (2.0 * eps));
                worst_curvature = worst_curvature.max((p - 2.0 * c + m).abs() / (eps * eps));
            }
        }
        // The fade's slope is at most 15/8 and its curvature at most 10/√3 ≈ 5.8 per unit
        // of the corner difference (≤ 2).
        assert!(worst_slope <= 2.0 * 15.0 / 8.0 + 1e-6, "{worst_slope}");
        assert!(worst_curvature <= 2.0 * 5.78 + 1e-3, "{worst_curvature}");
    }

    #[test]
    fn same_seed_gives_bit_identical_wind_and_another_seed_differs() {
        let (a, b, c) = (gusty(42), gusty(42), gusty(43));
        let mut differs = 0;
        for k in 0..100 {
            let p = DVec3::new(k as f64 * 0.3, 1.0, -0.2 * k as f64);
            let t = k as f64 * 0.05;
            let (wa, wb, wc) = (a.at(p, t), b.at(p, t), c.at(p, t));
            assert_eq!(
                wa.to_array().map(f64::to_bits),
                wb.to_array().map(f64::to_bits)
            );
            if wa != wc {
                differs += 1;
            }
        }
        assert_eq!(differs, 100);
    }

    #[test]
    fn components_are_independent() {
        let mut same = 0;
        for k in 0..100 {
            let p = [k as f64 * 0.61, 0.3, 0.7, k as f64 * 0.21];
            let v = value_noise(1, p);
            if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
                same += 1;
            }
        }
        assert_eq!(same, 0);
    }

    #[test]
    fn turbulence_is_bounded_by_the_amplitude_and_travels_with_the_wind() {
        let w = gusty(9);
        for k in 0..500 {
            let p = DVec3::new(k as f64 * 0.1, (k % 7) as f64, 0.5);
            let t = k as f64 * 0.01;
            let d = w.at(p, t) - w.velocity;
            assert!(d.abs().max_element() <= w.noise);
        }
        // With a frozen pattern (f = 0) the gust at p, t is the one at p − U t, t = 0.
        let frozen = Wind {
            frequency: 0.0,
            ..gusty(9)
        };
        let p = DVec3::new(0.3, 0.2, 0.1);
        let t = 0.37;
        let here = frozen.at(p + frozen.velocity * t, t);
        let there = frozen.at(p, 0.0);
        assert!((here - there).length() < 1e-12, "{here} vs {there}");
    }

    #[test]
    fn absurd_coordinates_do_not_panic() {
        for p in [
            [f64::NAN, 0.0, 0.0, 0.0],
            [f64::INFINITY, -f64::INFINITY, 1e300, -1e300],
            [1e19, -1e19, 0.5, 0.5],
        ] {
            let v = value_noise(0, p);
            assert!(v.iter().all(|c| c.abs() <= 1.0), "{p:?}: {v:?}");
        }
    }
}
