//! For a plugin's tests and benchmarks, not for simulation: a small deterministic random
//! generator, so that no plugin needs `rand` and every test draws the same numbers on every
//! platform; and [`CoreState`], the particle state the core owns, to drive a group in-process
//! through its ABI trait object exactly as the host calls it.

use glam::{DQuat, DVec3};

use crate::{GroupBox, Residual, SolveContext, FLAG_KINEMATIC};

/// The particle state the core owns — positions, velocities, the positions at the substep's
/// start, inverse masses, object indices and flags — with the substep length, time, frame and
/// gravity it passes in each [`SolveContext`]: enough to call a group's stages in a test or a
/// benchmark as the host does. The substep itself (prediction, velocity update) is the test's
/// own, so that it can step exactly as it needs.
///
/// ```
/// use nucleus_sdk::testing::CoreState;
/// let mut state = CoreState::at_rest(vec![[0.0; 3], [1.0, 0.0, 0.0]], vec![0.0, 1.0], 1.0 / 240.0);
/// state.gravity = [0.0, 0.0, -9.81];
/// let ctx = state.ctx();
/// assert_eq!(ctx.h, 1.0 / 240.0);
/// assert_eq!(ctx.flags.as_slice(), &[nucleus_sdk::FLAG_KINEMATIC, 0]); // inverse mass 0
/// ```
#[derive(Clone, Debug)]
pub struct CoreState {
    /// Positions (m).
    pub x: Vec<[f64; 3]>,
    /// Velocities (m/s).
    pub v: Vec<[f64; 3]>,
    /// Positions at the start of the substep (m).
    pub x0: Vec<[f64; 3]>,
    /// Inverse masses (1/kg); 0 for a pinned particle.
    pub inv_mass: Vec<f64>,
    /// The object of each particle.
    pub object: Vec<u32>,
    /// Per-particle flags ([`FLAG_KINEMATIC`] for a pinned particle).
    pub flags: Vec<u32>,
    /// Substep length (s).
    pub h: f64,
    /// Simulated time (s).
    pub time: f64,
    /// Gravity (m/s²).
    pub gravity: [f64; 3],
    /// Frame number.
    pub frame: u64,
    /// Substeps per frame.
    pub substeps: u32,
    /// Displacements by constraints against kinematic colliders (m): empty, as the core
    /// passes them to a scene without a group that takes them; give it one entry per particle
    /// to record or feed them ([`SolveContext::pushes`]).
    pub pushes: Vec<[f64; 3]>,
    /// Velocity changes by the same (m/s), empty likewise ([`SolveContext::kicks`]).
    pub kicks: Vec<[f64; 3]>,
}

impl CoreState {
    /// At rest at `x`, every particle of object 0, flagged kinematic where its inverse mass is
    /// 0 (as the core flags pins), substeps of `h`, time and frame 0, no gravity, 10 substeps a
    /// frame.
    pub fn at_rest(x: Vec<[f64; 3]>, inv_mass: Vec<f64>, h: f64) -> Self {
        let n = x.len();
        let flags = inv_mass
            .iter()
            .map(|&w| if w == 0.0 { FLAG_KINEMATIC } else { 0 })
            .collect();
        Self {
            x0: x.clone(),
            x,
            v: vec![[0.0; 3]; n],
            inv_mass,
            object: vec![0; n],
            flags,
            h,
            time: 0.0,
            gravity: [0.0; 3],
            frame: 0,
            substeps: 10,
            pushes: Vec::new(),
            kicks: Vec::new(),
        }
    }

    /// Marks the substep's start, as the core does before its prediction: `x0 = x`.
    pub fn start_substep(&mut self) {
        self.x0.clone_from(&self.x);
    }

    /// The context a stage is called with.
    pub fn ctx(&mut self) -> SolveContext<'_> {
        SolveContext {
            time: self.time,
            gravity: self.gravity,
            frame: self.frame,
            substeps: self.substeps,
            pushes: abi_stable::std_types::RSliceMut::from_mut_slice(&mut self.pushes),
            kicks: abi_stable::std_types::RSliceMut::from_mut_slice(&mut self.kicks),
            ..SolveContext::new(
                &mut self.x,
                &mut self.v,
                &self.x0,
                &self.inv_mass,
                &self.object,
                &self.flags,
                self.h,
            )
        }
    }

    /// Calls the group's `force` stage. Panics with the group's error.
    pub fn force(&mut self, group: &mut GroupBox) {
        let result = group.force(&mut self.ctx()).into_result();
        result.unwrap_or_else(|e| panic!("force: {e}"));
    }

    /// Calls the group's `begin_substep` stage. Panics with the group's error.
    pub fn begin(&mut self, group: &mut GroupBox) {
        let result = group.begin_substep(&mut self.ctx()).into_result();
        result.unwrap_or_else(|e| panic!("begin_substep: {e}"));
    }

    /// Calls the group's `project` stage (one pass). Panics with the group's error.
    pub fn project(&mut self, group: &mut GroupBox) {
        let result = group.project(&mut self.ctx()).into_result();
        result.unwrap_or_else(|e| panic!("project: {e}"));
    }

    /// The group's residual. Panics with the group's error.
    pub fn residual(&mut self, group: &GroupBox) -> Residual {
        let result = group.residual(&self.ctx()).into_result();
        result.unwrap_or_else(|e| panic!("residual: {e}"))
    }

    /// Every statistic the group reports, by name. Panics with the group's error.
    pub fn report(&mut self, group: &GroupBox) -> Vec<(String, f64)> {
        let result = group.report(&self.ctx()).into_result();
        let stats = result.unwrap_or_else(|e| panic!("report: {e}"));
        stats
            .iter()
            .map(|s| (s.name.to_string(), s.value))
            .collect()
    }

    /// The statistic `name` the group reports. Panics if it reports none of that name.
    pub fn stat(&mut self, group: &GroupBox, name: &str) -> f64 {
        let stats = self.report(group);
        let found = stats.iter().find(|(n, _)| n == name);
        found.unwrap_or_else(|| panic!("no stat {name}")).1
    }

    /// Whether every position and velocity is finite.
    pub fn all_finite(&self) -> bool {
        self.x
            .iter()
            .chain(&self.v)
            .flatten()
            .all(|c| c.is_finite())
    }
}

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
