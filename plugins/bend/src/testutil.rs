//! Helpers for the unit tests: a tiny deterministic generator and the momentum check.

use glam::DVec3;

pub use nucleus_sdk::testing::Rng;

/// The draws the bending tests need beyond the SDK's generator.
pub trait Draws {
    /// A random orthonormal pair.
    fn frame(&mut self) -> (DVec3, DVec3);
    /// An inverse mass for masses from 1 g to 1 t (ratios up to 1e6).
    fn inv_mass(&mut self) -> f64;
}

impl Draws for Rng {
    fn frame(&mut self) -> (DVec3, DVec3) {
        let u = self.unit();
        let v = u.cross(self.unit()).normalize();
        (u, v)
    }

    fn inv_mass(&mut self) -> f64 {
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
