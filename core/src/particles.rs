//! The particle state ([`Particles`], flat arrays) and the core's loops over it, which the
//! step's stages run: gravity, the prediction, the velocity update, damping, the finite checks
//! after every group call, and the energy sums of the stats.
//!
//! **Threads.** A substep holds the process's one thread team ([`nucleus_sdk::team`]; its size
//! is `RAYON_NUM_THREADS`, default the machine's cores). The core's particle loops (gravity,
//! prediction, velocities, damping, the finite checks after every call) split over it from
//! [`PARALLEL_MIN_PARTICLES`] particles up, each part its own contiguous range, and every
//! group receives it as `ctx.team` for its passes. Each particle's arithmetic is the same
//! whatever the split, so a scene gives the same bits on any number of threads. Measured on
//! the 2-core VM, 128 × 128 drape at 40 × 1 on two threads: 15.0 → 12.7 ms per frame (median)
//! once the core's loops share the team the stretch plugin used alone before; 64 × 64 at
//! 160 × 1: 18.2 → 14.2 ms.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use nucleus_sdk::team::{SharedArray, TeamRef};

use crate::object::{MovingPins, ObjectData};

/// Below this many particles the core's particle loops run on the calling thread: a loop over
/// 4,096 particles takes a few microseconds, a few times the team's hand-off. Chosen, not
/// tuned.
pub const PARALLEL_MIN_PARTICLES: usize = 4096;

/// Particle state in struct-of-arrays form.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Particles {
    /// Positions (m).
    pub x: Vec<[f64; 3]>,
    /// Positions at the start of the substep (m).
    pub x0: Vec<[f64; 3]>,
    /// Velocities (m/s).
    pub v: Vec<[f64; 3]>,
    /// Inverse masses (1/kg); 0 for kinematic particles.
    pub inv_mass: Vec<f64>,
    /// Masses (kg), including those of kinematic particles (for reporting).
    pub mass: Vec<f64>,
    /// Object index.
    pub object: Vec<u32>,
    /// Flags (`FLAG_*`).
    pub flags: Vec<u32>,
    /// Rest positions (m).
    pub rest: Vec<[f64; 3]>,
    /// Displacements by constraints against kinematic colliders since the force stage (m),
    /// one per particle when a group takes them ([`Stages::TAKES_PUSHES`]), else empty.
    ///
    /// [`Stages::TAKES_PUSHES`]: nucleus_sdk::Stages::TAKES_PUSHES
    pub pushes: Vec<[f64; 3]>,
    /// Velocity changes by the same since the force stage (m/s), likewise.
    pub kicks: Vec<[f64; 3]>,
}

impl Particles {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.x.len()
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// `v += g` (`g` = gravity × h) for every free particle.
    pub(crate) fn apply_gravity(&mut self, g: [f64; 3], team: TeamRef<'_>) {
        let inv_mass = &self.inv_mass;
        for_ranges_mut(team, &mut self.v, &|r, v| gravity_range(v, &inv_mass[r], g));
    }

    /// `x0 = x`, then `x += h v` for every free particle, over the flat arrays (which the
    /// compiler vectorises), after `v += g` when `gravity` is given (a scene without force
    /// groups: [`predict_range`]); then each moving pin goes to its target, with the velocity
    /// that takes it there. The moving pins are listed in particle order, so those of a range
    /// are a run of the list, and the part that owns the range moves them (a pins-only scene of
    /// 4,096 moving pins was 1.3× slower on two threads than on one while the main thread moved
    /// them after the split loop: it had to fetch every pin's position back from the other
    /// core's cache).
    pub(crate) fn predict(
        &mut self,
        h: f64,
        gravity: Option<[f64; 3]>,
        pins: &MovingPins,
        objects: &[ObjectData],
        team: TeamRef<'_>,
    ) {
        let (inv_mass, object, rest) = (&self.inv_mass, &self.object, &self.rest);
        let n = self.x.len();
        let (x, x0, v) = (
            SharedArray::new(&mut self.x),
            SharedArray::new(&mut self.x0),
            SharedArray::new(&mut self.v),
        );
        for_ranges(team, n, &|r| {
            // SAFETY: each range is its own part of `x`, `x0` and `v` (exclusively borrowed for
            // this call; every particle array has the same length).
            let (x, x0, v) = unsafe {
                (
                    x.slice(r.start, r.len()),
                    x0.slice(r.start, r.len()),
                    v.slice(r.start, r.len()),
                )
            };
            predict_range(x, x0, v, &inv_mass[r.clone()], h, gravity);
            for &i in pins.within(r.clone()) {
                let i = i as usize;
                let target = pins.target(objects, i, object[i], rest[i]);
                let k = i - r.start;
                v[k] = ((target - DVec3::from_array(x0[k])) / h).to_array();
                x[k] = target.to_array();
            }
        });
    }

    /// `v = (x − x0) / h` for every particle, block by block; with `check`, each block's
    /// positions and the velocities it replaces are first checked to be finite: the check the
    /// schedule's last call would make ([`NonFinite`]), in the same pass over the positions.
    /// On a non-finite value the velocities are left as they are from that block on, and the
    /// caller stops the step with the error.
    pub(crate) fn update_velocities(
        &mut self,
        h: f64,
        team: TeamRef<'_>,
        check: bool,
    ) -> NonFinite {
        /// Particles checked and updated at a time: the block's positions, start positions and
        /// velocities (72 KiB) stay in the core's cache between the check and the update.
        const BLOCK: usize = 1024;
        let inv_h = 1.0 / h;
        let (x, x0) = (&self.x, &self.x0);
        let found = NonFinite::default();
        for_ranges_mut(team, &mut self.v, &|r, v| {
            let (x, x0) = (&x[r.clone()], &x0[r]);
            for ((v, x), x0) in v
                .chunks_mut(BLOCK)
                .zip(x.chunks(BLOCK))
                .zip(x0.chunks(BLOCK))
            {
                if check && !found.check(x, v) {
                    return;
                }
                velocity_range(v, x, x0, inv_h);
            }
        });
        found
    }

    /// `v *= k` for every particle (global damping).
    pub(crate) fn damp(&mut self, k: f64, team: TeamRef<'_>) {
        for_ranges_mut(team, &mut self.v, &|_, v| {
            for v in v.as_flattened_mut() {
                *v *= k;
            }
        });
    }

    /// Whether every position and velocity is finite (what a group call may have broken).
    pub(crate) fn check_finite(&self, team: TeamRef<'_>) -> NonFinite {
        let found = NonFinite::default();
        // `x` and `v` have one length: every particle array does.
        let (x, v) = (&self.x, &self.v);
        for_ranges(team, x.len(), &|r| {
            found.check(&x[r.clone()], &v[r]);
        });
        found
    }

    /// Kinetic energy of the dynamic particles (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.inv_mass)
            .filter(|(_, &w)| w > 0.0)
            .map(|(v, &w)| 0.5 * DVec3::from_array(*v).length_squared() / w)
            .sum()
    }

    /// Potential energy of the dynamic particles under `gravity` (m/s²), relative to the
    /// origin (J).
    pub fn gravity_energy(&self, gravity: [f64; 3]) -> f64 {
        let g = DVec3::from_array(gravity);
        self.x
            .iter()
            .zip(&self.inv_mass)
            .filter(|(_, &w)| w > 0.0)
            .map(|(x, &w)| -g.dot(DVec3::from_array(*x)) / w)
            .sum()
    }
}

// The particle loops of one range, as functions of distinct slices: the compiler may then
// assume they do not overlap and vectorise each loop without checks (measured: the free-fall
// substep of 4,096 particles 20.0 µs with the loops written inside the range closures, on
// slices made from raw pointers, against 18.4 µs before the split).

/// `v += g` (`g` = gravity × h) for every free particle; pins keep their velocity. A select
/// rather than a branch, so the loop vectorises.
fn gravity_range(v: &mut [[f64; 3]], inv_mass: &[f64], g: [f64; 3]) {
    for (v, &w) in v.iter_mut().zip(inv_mass) {
        let free = w > 0.0;
        for (c, g) in v.iter_mut().zip(g) {
            *c = if free { *c + g } else { *c };
        }
    }
}

/// `x0 = x`, then `x += h v` for every free particle; with `gravity` (`g` = gravity × h),
/// first `v += g` for every free particle, in the same loop: [`gravity_range`]'s arithmetic,
/// so the same bits, one pass over the velocities instead of two.
fn predict_range(
    x: &mut [[f64; 3]],
    x0: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    inv_mass: &[f64],
    h: f64,
    gravity: Option<[f64; 3]>,
) {
    debug_assert!(x0.len() == x.len() && v.len() == x.len() && inv_mass.len() == x.len());
    // `x0` is written in the same loop as `x` (each position read once): a separate copy
    // first was a sixth of the 128 x 128 drape's substep on 2 threads, the arrays streaming
    // from beyond the core's cache twice.
    match gravity {
        Some(g) => {
            for (((x, x0), v), &w) in x.iter_mut().zip(x0).zip(v).zip(inv_mass) {
                let free = w > 0.0;
                *x0 = *x;
                for ((x, v), g) in x.iter_mut().zip(v.iter_mut()).zip(g) {
                    *v = if free { *v + g } else { *v };
                    *x = if free { *x + *v * h } else { *x };
                }
            }
        }
        None => {
            for (((x, x0), v), &w) in x.iter_mut().zip(x0).zip(&*v).zip(inv_mass) {
                let free = w > 0.0;
                *x0 = *x;
                for (x, v) in x.iter_mut().zip(v) {
                    *x = if free { *x + v * h } else { *x };
                }
            }
        }
    }
}

/// `v = (x − x0) / h`, component by component over the flat arrays.
fn velocity_range(v: &mut [[f64; 3]], x: &[[f64; 3]], x0: &[[f64; 3]], inv_h: f64) {
    let (x, x0) = (x.as_flattened(), x0.as_flattened());
    for ((v, x), x0) in v.as_flattened_mut().iter_mut().zip(x).zip(x0) {
        *v = (x - x0) * inv_h;
    }
}

/// [`TeamRef::for_ranges`] from [`PARALLEL_MIN_PARTICLES`] particles on.
fn for_ranges(team: TeamRef<'_>, n: usize, f: &(dyn Fn(Range<usize>) + Sync)) {
    team.for_ranges(n, PARALLEL_MIN_PARTICLES, f);
}

/// [`TeamRef::for_ranges_mut`] from [`PARALLEL_MIN_PARTICLES`] particles on.
fn for_ranges_mut<T: Send>(
    team: TeamRef<'_>,
    items: &mut [T],
    f: &(dyn Fn(Range<usize>, &mut [T]) + Sync),
) {
    team.for_ranges_mut(items, PARALLEL_MIN_PARTICLES, f);
}

/// What a finite check found, over the parts of the team: a non-finite position, velocity.
#[derive(Default)]
pub(crate) struct NonFinite {
    x: AtomicBool,
    v: AtomicBool,
}

impl NonFinite {
    /// Checks one range's positions and velocities, recording what is not finite; whether
    /// both were finite.
    fn check(&self, x: &[[f64; 3]], v: &[[f64; 3]]) -> bool {
        let (good_x, good_v) = (all_finite(x), all_finite(v));
        if !good_x {
            self.x.store(true, Ordering::Relaxed);
        }
        if !good_v {
            self.v.store(true, Ordering::Relaxed);
        }
        good_x && good_v
    }

    /// What was not finite: "position" (first) or "velocity"; `None` if both were.
    pub(crate) fn what(self) -> Option<&'static str> {
        if self.x.into_inner() {
            Some("position")
        } else if self.v.into_inner() {
            Some("velocity")
        } else {
            None
        }
    }
}

/// Whether every component is finite: no component has an all-ones exponent (NaN or ±∞).
///
/// The check runs after every group call, so it is written for speed: an OR over integers
/// (a sum of `x·0` is one long chain of dependent floating-point additions), and without a
/// 64-bit comparison, which the baseline x86-64 vector instructions lack: adding one to the
/// exponent field carries into the sign bit exactly when the field is all ones. Measured on
/// the 128 × 128 drape at 40 × 1 on two threads, the checks took 2.4 ms of a 15.9 ms frame in
/// the comparison form.
pub fn all_finite(xs: &[[f64; 3]]) -> bool {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    const EXPONENT_ONE: u64 = 0x0010_0000_0000_0000;
    let carried = xs.as_flattened().iter().fold(0u64, |bad, v| {
        bad | (v.to_bits() & EXPONENT).wrapping_add(EXPONENT_ONE)
    });
    carried >> 63 == 0
}

#[cfg(test)]
mod tests {
    use super::all_finite;

    #[test]
    fn all_finite_finds_one_nan_or_infinity_anywhere_and_accepts_every_finite_value() {
        let finite = [
            0.0,
            -0.0,
            1.0,
            -1e300,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            5e-324,
        ];
        let mut xs: Vec<[f64; 3]> = (0..1001)
            .map(|k| [finite[k % 8], finite[(k + 3) % 8], 2.0])
            .collect();
        assert!(all_finite(&xs));
        assert!(all_finite(&[]));
        for bad in [f64::NAN, -f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for (k, c) in [(0, 0), (500, 1), (1000, 2), (3, 2)] {
                let keep = xs[k][c];
                xs[k][c] = bad;
                assert!(!all_finite(&xs), "{bad} at [{k}][{c}]");
                xs[k][c] = keep;
            }
        }
        assert!(all_finite(&xs));
    }
}
