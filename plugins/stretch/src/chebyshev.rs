//! Chebyshev semi-iterative acceleration of the passes within a substep (Wang 2015, "A
//! Chebyshev Semi-Iterative Approach for Accelerating Projective and Position-based
//! Dynamics"), an option of the `stretch` kind (`chebyshev_rho > 0`).
//!
//! After pass `k` (counted from 0 in each substep) has produced `q̂`, the group's particles
//! move to
//!
//! ```text
//! q(k+1) = ω(k) · (γ (q̂ − q(k)) + q(k) − q(k−1)) + q(k−1)
//! ```
//!
//! where `q(k)` is the state the pass started from, `q(k−1)` the one before it, `γ` an
//! under-relaxation and `ω` the Chebyshev weights of [`omega`] for `ρ`, an estimate of the
//! spectral radius of one pass. The first `delay` passes are left alone (`ω = 1`, `γ = 1`).
//! Pinned particles (inverse mass 0) never move.
//!
//! Measured on the drape (see the crate docs and `docs/peers.md`): it lowers the strain at
//! a given number of passes per substep (N = 64, 20 substeps × 8 passes: RMS 0.70 % → 0.39 %
//! at ρ = 0.9), but spending the same passes on substeps instead lowers it far more
//! (160 × 1: 0.16 %), and ρ ≥ 0.99 diverges. So it is off by default.

use glam::DVec3;

/// Largest accepted `ρ`: at 1 the weights grow to 2 and the iteration no longer converges.
pub const MAX_RHO: f64 = 0.9999;

/// The Chebyshev weight of pass `pass` (from 0), given the weight of the pass before:
/// 1 for the first `delay` passes, `2/(2 − ρ²)` for pass `delay`, then `4/(4 − ρ² ω)`.
/// From `2/(2 − ρ²)` the weights fall towards `2/(1 + √(1 − ρ²))`, the optimal
/// over-relaxation for `ρ`.
pub fn omega(pass: u32, delay: u32, rho: f64, previous: f64) -> f64 {
    let r2 = rho * rho;
    if pass < delay {
        1.0
    } else if pass == delay {
        2.0 / (2.0 - r2)
    } else {
        4.0 / (4.0 - r2 * previous)
    }
}

/// The accelerated update of one particle: `ω (γ (q̂ − q) + q − q_prev) + q_prev`.
#[inline]
pub fn accelerate(q_hat: DVec3, q: DVec3, q_prev: DVec3, omega: f64, gamma: f64) -> DVec3 {
    omega * (gamma * (q_hat - q) + q - q_prev) + q_prev
}

/// The acceleration state of one group: its particles and their last two iterates.
#[derive(Clone, Debug)]
pub struct Chebyshev {
    /// `ρ`, in `(0, MAX_RHO]`.
    rho: f64,
    /// Passes per substep left alone before the weights start.
    delay: u32,
    /// Under-relaxation `γ`, in `(0, 1]`.
    gamma: f64,
    /// The particles the group moves, ascending and unique.
    particles: Vec<u32>,
    /// `q(k)`: each particle's position at the start of the current pass.
    current: Vec<DVec3>,
    /// `q(k−1)`: at the start of the previous pass.
    previous: Vec<DVec3>,
    /// Passes done in this substep.
    pass: u32,
    /// The weight of the last pass.
    omega: f64,
}

impl Chebyshev {
    /// For the particles of `ids`; all memory is taken here, none per pass.
    pub fn new(ids: &[[u32; 2]], rho: f64, delay: u32, gamma: f64) -> Self {
        let mut particles: Vec<u32> = ids.iter().flatten().copied().collect();
        particles.sort_unstable();
        particles.dedup();
        let n = particles.len();
        Self {
            rho,
            delay: delay.max(1),
            gamma,
            particles,
            current: vec![DVec3::ZERO; n],
            previous: vec![DVec3::ZERO; n],
            pass: 0,
            omega: 1.0,
        }
    }

    /// Starts a substep: the next pass is pass 0.
    pub fn begin_substep(&mut self) {
        self.pass = 0;
        self.omega = 1.0;
    }

    /// Records `q(k)`, the positions a pass starts from. `x` must hold every particle of the
    /// group (the caller checked the indices).
    pub fn before_pass(&mut self, x: &[DVec3]) {
        std::mem::swap(&mut self.current, &mut self.previous);
        for (q, &p) in self.current.iter_mut().zip(&self.particles) {
            *q = x[p as usize];
        }
    }

    /// Moves the particles from the pass's result `q̂` (in `x`) to the accelerated iterate.
    pub fn after_pass(&mut self, x: &mut [DVec3], inv_mass: &[f64]) {
        let pass = self.pass;
        self.pass += 1;
        self.omega = omega(pass, self.delay, self.rho, self.omega);
        if pass < self.delay {
            return;
        }
        let (omega, gamma) = (self.omega, self.gamma);
        for ((&p, &q), &q_prev) in self.particles.iter().zip(&self.current).zip(&self.previous) {
            let p = p as usize;
            if inv_mass[p] > 0.0 {
                x[p] = accelerate(x[p], q, q_prev, omega, gamma);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_start_after_the_delay_and_fall_to_the_optimal_over_relaxation() {
        let rho: f64 = 0.95;
        let mut w = 1.0;
        let mut seen = Vec::new();
        for pass in 0..200 {
            w = omega(pass, 3, rho, w);
            seen.push(w);
        }
        assert_eq!(&seen[..3], &[1.0, 1.0, 1.0]);
        assert!((seen[3] - 2.0 / (2.0 - rho * rho)).abs() < 1e-15);
        assert!(seen[3..].windows(2).all(|p| p[1] <= p[0]), "falling");
        let limit = 2.0 / (1.0 + (1.0 - rho * rho).sqrt());
        assert!(
            (seen[199] - limit).abs() < 1e-12,
            "{} vs {limit}",
            seen[199]
        );
        assert!(seen.iter().all(|&w| (1.0..2.0).contains(&w)));
    }

    /// Jacobi on the 1-D Poisson problem `−u'' = 0` with `u = 0` at both ends, whose
    /// iteration matrix has spectral radius `cos(π/(n+1))`: with that `ρ` the error after `k`
    /// passes must fall like the Chebyshev bound, far below plain Jacobi's `ρ^k`.
    #[test]
    fn on_a_linear_iteration_the_error_falls_as_chebyshev_promises() {
        let n = 30;
        let rho = (std::f64::consts::PI / (n + 1) as f64).cos();
        let ids: Vec<[u32; 2]> = (0..n as u32 + 1).map(|k| [k, k + 1]).collect();
        let inv_mass: Vec<f64> = (0..n + 2)
            .map(|k| if k == 0 || k == n + 1 { 0.0 } else { 1.0 })
            .collect();
        let start: Vec<DVec3> = (0..n + 2)
            .map(|k| {
                if inv_mass[k] > 0.0 {
                    DVec3::X * (1.0 + (k % 3) as f64)
                } else {
                    DVec3::ZERO
                }
            })
            .collect();
        let jacobi = |x: &mut Vec<DVec3>| {
            let old = x.clone();
            for k in 1..=n {
                x[k] = 0.5 * (old[k - 1] + old[k + 1]);
            }
        };
        let error = |x: &[DVec3]| x.iter().map(|p| p.length()).fold(0.0, f64::max);
        let passes = 60;
        let mut plain = start.clone();
        for _ in 0..passes {
            jacobi(&mut plain);
        }
        let mut fast = start.clone();
        let mut cheb = Chebyshev::new(&ids, rho, 1, 1.0);
        cheb.begin_substep();
        for _ in 0..passes {
            cheb.before_pass(&fast);
            jacobi(&mut fast);
            cheb.after_pass(&mut fast, &inv_mass);
        }
        let e0 = error(&start);
        // Plain Jacobi: about ρ^k of the start (0.995^60 ≈ 0.75).
        assert!(error(&plain) > 0.5 * e0, "plain {}", error(&plain));
        // Chebyshev: 2 σ^k / (1 + σ^2k) with σ = ρ/(1 + √(1 − ρ²)) ≈ 0.9, about 0.01.
        let sigma = rho / (1.0 + (1.0 - rho * rho).sqrt());
        let bound = 2.0 * sigma.powi(passes) / (1.0 + sigma.powi(2 * passes));
        assert!(
            error(&fast) < 2.0 * bound * e0,
            "chebyshev {} vs bound {}",
            error(&fast),
            bound * e0
        );
        assert!(error(&fast) < 0.05 * error(&plain));
        assert_eq!(fast[0], DVec3::ZERO);
        assert_eq!(fast[n + 1], DVec3::ZERO);
    }
}
