//! For a plugin's tests and benchmarks, not for simulation: a small deterministic random
//! generator, so that no plugin needs `rand` and every test draws the same numbers on every
//! platform.

use glam::{DQuat, DVec3};

/// xorshift64* (Vigna 2016): a 64-bit state, one multiply per draw. The state is the seed
/// (`Rng(7)`); it must not be 0, which the generator never leaves.
///
/// ```
/// use nucleus_sdk::testing::Rng;
/// let (mut a, mut b) = (Rng(7), Rng(7));
/// let x = a.range(-1.0, 1.0);
/// assert!((-1.0..1.0).contains(&x));
/// assert_eq!(x, b.range(-1.0, 1.0));
/// assert!((a.unit().length() - 1.0).abs() < 1e-12);
/// ```
#[derive(Clone, Debug)]
pub struct Rng(pub u64);

impl Rng {
    /// Uniform in `[0, 1)`, 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let bits = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
        bits as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }

    /// Uniform in the cube of half-side `half` about the origin.
    pub fn vec3(&mut self, half: f64) -> DVec3 {
        DVec3::new(
            self.range(-half, half),
            self.range(-half, half),
            self.range(-half, half),
        )
    }

    /// Uniform among the integers `-n..=n`.
    pub fn int(&mut self, n: i64) -> i64 {
        (self.next_f64() * (2 * n + 1) as f64) as i64 - n
    }

    /// A vector of three integers of `-n..=n` (exact coordinates, for exact-arithmetic tests).
    pub fn ivec(&mut self, n: i64) -> DVec3 {
        DVec3::new(self.int(n) as f64, self.int(n) as f64, self.int(n) as f64)
    }

    /// Uniform among `0..n`.
    pub fn pick(&mut self, n: usize) -> usize {
        (self.next_f64() * n as f64) as usize
    }

    /// Uniform in the ball of radius `r` about the origin.
    pub fn in_ball(&mut self, r: f64) -> DVec3 {
        loop {
            let v = self.vec3(1.0);
            if v.length_squared() <= 1.0 {
                return v * r;
            }
        }
    }

    /// A unit vector, uniform over directions.
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let v = self.vec3(1.0);
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }

    /// A rotation, uniform over rotations.
    pub fn rotation(&mut self) -> DQuat {
        loop {
            let v = self.vec3(1.0);
            let w = self.range(-1.0, 1.0);
            let q = DQuat::from_xyzw(v.x, v.y, v.z, w);
            if q.length() > 0.1 && q.length() <= 1.0 {
                return q.normalize();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_uniform_enough_and_stay_in_range() {
        let mut rng = Rng(0x5eed);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let x = rng.next_f64();
            assert!((0.0..1.0).contains(&x));
            sum += x;
        }
        // The mean of n uniforms has standard deviation 1/sqrt(12 n) ≈ 0.0009.
        assert!((sum / n as f64 - 0.5).abs() < 0.005, "{}", sum / n as f64);
        let mut seen = [false; 7];
        for _ in 0..1000 {
            let k = rng.int(3);
            assert!((-3..=3).contains(&k));
            seen[(k + 3) as usize] = true;
            assert!(rng.pick(5) < 5);
            assert!(rng.in_ball(2.0).length() <= 2.0);
            assert!((rng.rotation().length() - 1.0).abs() < 1e-12);
        }
        assert!(seen.iter().all(|&s| s), "every integer of -3..=3 drawn");
    }
}
