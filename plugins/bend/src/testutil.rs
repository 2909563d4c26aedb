//! Helpers for the unit tests: a tiny deterministic generator and the momentum check.

use glam::DVec3;

/// xorshift64*: deterministic, so the tests need no `rand`.
pub struct Rng(pub u64);

impl Rng {
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

    /// Uniform in the cube of half-side `half`.
    pub fn vec3(&mut self, half: f64) -> DVec3 {
        DVec3::new(
            self.range(-half, half),
            self.range(-half, half),
            self.range(-half, half),
        )
    }

    /// A random unit vector.
    pub fn unit(&mut self) -> DVec3 {
        loop {
            let v = self.vec3(1.0);
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return v / l;
            }
        }
    }

    /// A random orthonormal pair.
    pub fn frame(&mut self) -> (DVec3, DVec3) {
        let u = self.unit();
        let v = u.cross(self.unit()).normalize();
        (u, v)
    }

    /// An inverse mass for masses from 1 g to 1 t (ratios up to 1e6).
    pub fn inv_mass(&mut self) -> f64 {
        10f64.powf(self.range(-3.0, 3.0))
    }
}

/// Asserts that the corrections `dx` of particles at `x` with inverse masses `w` change
/// neither the linear momentum `Σ mΔx` nor the angular momentum `Σ m x × Δx`, relative to
/// the size of the momenta involved.
pub fn assert_conserves_momentum(x: &[DVec3], w: &[f64], dx: &[DVec3]) {
    let mut p = DVec3::ZERO;
    let mut p_scale = 0.0;
    let mut l = DVec3::ZERO;
    let mut l_scale = 0.0;
    for ((x, &w), dx) in x.iter().zip(w).zip(dx) {
        assert!(w > 0.0, "momentum needs finite masses");
        let m = 1.0 / w;
        p += m * *dx;
        p_scale += m * dx.length();
        l += m * x.cross(*dx);
        l_scale += m * x.length() * dx.length();
    }
    assert!(p_scale > 0.0, "nothing moved");
    assert!(p.length() <= 1e-11 * p_scale, "linear: {p} vs {p_scale}");
    assert!(l.length() <= 1e-11 * l_scale, "angular: {l} vs {l_scale}");
}
