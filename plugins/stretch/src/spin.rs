//! A tiny fork-join team for the colours of one pass: helper threads that stay awake between
//! the short, back-to-back jobs of a substep.
//!
//! One `project` pass over a 128 × 128 cloth is ten colours of about 45 µs each on one thread.
//! Handing each colour (or even each pass) to rayon's pool from the host's thread cost more than
//! it saved on the 2-core VM: a parked worker takes tens of microseconds to wake, and the host's
//! thread sleeps on a condition variable until the job is done, so two threads ran the drape no
//! faster than one (median) — the best frames were 1.4× faster, the typical ones slower. Here the
//! caller runs part 0 of every job itself and `helpers` threads run parts 1..; between jobs a
//! helper spins (for up to [`SPIN`]) before it parks, so within a substep it is always awake.
//! One team serves every group of the plugin ([`shared`]): a team per group left the helpers of
//! one group spinning while the next group's pass ran with its own, so a scene with two
//! `stretch` groups had three busy threads on two cores (measured on the 128 × 128 drape with
//! its diagonals in a second group: 46 ms per frame on 2 threads, against 22 ms for one group
//! holding every edge). A [`Team`] made with [`Team::new`] is stopped and joined when dropped.
//!
//! Determinism: a job is split into parts by index alone, and every part writes only what its
//! index owns, so results do not depend on which thread runs which part, nor on the count.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long an idle helper spins before it parks.
pub const SPIN: Duration = Duration::from_micros(500);

/// A job: called once with each part index `0..parts`.
type Job = dyn Fn(usize) + Sync;

struct Shared {
    /// Incremented for every job; helpers run a job when they see a new value.
    epoch: AtomicUsize,
    /// Parts finished in the current job (the caller's included).
    finished: AtomicUsize,
    /// Set when the team is dropped.
    stop: AtomicBool,
    /// Set when a helper's part panicked.
    panicked: AtomicBool,
    /// The current job, valid from the `epoch` increment until `finished` reaches the part
    /// count (the caller waits for that before returning, so the borrow outlives every use).
    job: UnsafeCell<Option<*const Job>>,
    /// Threads to unpark when a job is posted (those that went to sleep).
    helpers: std::sync::OnceLock<Vec<std::thread::Thread>>,
}

// SAFETY: `job` is written only by the caller, before the `epoch` increment (Release) that
// publishes it, and read by helpers only after they observe that increment (Acquire); the
// caller does not write it again until every helper has reported `finished` for that job.
unsafe impl Sync for Shared {}
// SAFETY: as above; the raw pointer is only dereferenced under that protocol.
unsafe impl Send for Shared {}

/// The team: the caller plus `helpers` spinning threads.
pub struct Team {
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

impl Team {
    /// A team of the caller and `helpers` threads (none: every job runs on the caller).
    pub fn new(helpers: usize) -> Team {
        let shared = Arc::new(Shared {
            epoch: AtomicUsize::new(0),
            finished: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            panicked: AtomicBool::new(false),
            job: UnsafeCell::new(None),
            helpers: std::sync::OnceLock::new(),
        });
        let threads: Vec<JoinHandle<()>> = (1..=helpers)
            .map(|part| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("nucleus-stretch-{part}"))
                    .spawn(move || helper(&shared, part))
                    .expect("spawning a stretch helper thread")
            })
            .collect();
        let _ = shared
            .helpers
            .set(threads.iter().map(|t| t.thread().clone()).collect());
        Team { shared, threads }
    }

    /// The number of parts a job is split into: the caller and the helpers.
    pub fn parts(&self) -> usize {
        self.threads.len() + 1
    }

    /// Runs `job(part)` for every part `0..parts()`, part 0 on this thread, and returns when
    /// all are done. A panic in a helper's part is raised again here, on the caller's thread
    /// (where the SDK's adapter turns it into an error naming the plugin and the group).
    pub fn run(&mut self, job: &(dyn Fn(usize) + Sync)) {
        let parts = self.parts();
        if parts == 1 {
            job(0);
            return;
        }
        let s = &*self.shared;
        s.finished.store(0, Ordering::Relaxed);
        // SAFETY: no helper reads `job` now: the previous job is finished (we waited for it)
        // and the next one is not published until the `epoch` increment below. The pointer
        // stays valid until we return, after every part has finished.
        unsafe {
            let erased: *const Job =
                std::mem::transmute::<&(dyn Fn(usize) + Sync), &'static Job>(job);
            *s.job.get() = Some(erased);
        }
        s.epoch.fetch_add(1, Ordering::Release);
        if let Some(helpers) = s.helpers.get() {
            for t in helpers {
                t.unpark();
            }
        }
        job(0);
        s.finished.fetch_add(1, Ordering::AcqRel);
        while s.finished.load(Ordering::Acquire) < parts {
            std::hint::spin_loop();
        }
        if s.panicked.swap(false, Ordering::AcqRel) {
            panic!("a stretch helper thread panicked in its part of the pass");
        }
    }
}

/// A clone is a team of the same size with threads of its own.
impl Clone for Team {
    fn clone(&self) -> Team {
        Team::new(self.threads.len())
    }
}

impl std::fmt::Debug for Team {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Team")
            .field("parts", &self.parts())
            .finish()
    }
}

impl Drop for Team {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        for t in &self.threads {
            t.thread().unpark();
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// A raw pointer to the first element of an array the parts of one job share, each part
/// reading and writing only the elements it owns. A method gives the addresses, so that a
/// closure captures the whole wrapper (which is `Sync`), not the raw pointer inside it.
#[derive(Clone, Copy, Debug)]
pub struct SharedArray<T>(*mut T);

impl<T> SharedArray<T> {
    /// The array `items`, for as long as the caller does not use it otherwise.
    pub fn new(items: &mut [T]) -> SharedArray<T> {
        SharedArray(items.as_mut_ptr())
    }

    /// The address of element `i` (computing it is safe; using it is the caller's contract).
    pub fn at(self, i: usize) -> *mut T {
        self.0.wrapping_add(i)
    }

    /// The elements `start..start + len` as a slice.
    ///
    /// # Safety
    /// The range is inside the array, the array outlives `'a`, and no other part uses the
    /// range meanwhile.
    pub unsafe fn slice<'a>(self, start: usize, len: usize) -> &'a mut [T] {
        // SAFETY: guaranteed by the caller.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(start), len) }
    }
}

// SAFETY: a `SharedArray` is only dereferenced by the parts of one job, each on the elements it
// owns (every use states why in its own SAFETY comment), and `T: Send` lets those elements be
// written from another thread.
unsafe impl<T: Send> Send for SharedArray<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for SharedArray<T> {}

/// The plugin's one team, shared by every group (see the module docs).
static SHARED: std::sync::Mutex<Option<Team>> = std::sync::Mutex::new(None);

/// The plugin's shared team, resized to `parts` parts (the caller and `parts − 1` helpers), for
/// as long as the guard is held; `None` when another thread holds it (two simulations stepping
/// at once, as the tests do): the caller then runs its jobs alone, which gives the same
/// results, since a job's result never depends on the team.
pub fn shared(parts: usize) -> Option<std::sync::MutexGuard<'static, Option<Team>>> {
    let mut guard = match SHARED.try_lock() {
        Ok(g) => g,
        // A panic in a job poisons the lock, but the team is still whole: `run` waits for every
        // part before it raises the panic again.
        Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
        Err(std::sync::TryLockError::WouldBlock) => return None,
    };
    if guard.as_ref().map_or(1, Team::parts) != parts {
        *guard = (parts > 1).then(|| Team::new(parts - 1));
    }
    Some(guard)
}

/// The shared team for a job worth splitting (`wanted`), sized to `RAYON_NUM_THREADS` (default
/// the machine's cores); `None` when it is not wanted, on one thread, or when another thread
/// holds it (see [`shared`]).
pub fn shared_if(wanted: bool) -> Option<std::sync::MutexGuard<'static, Option<Team>>> {
    let threads = if wanted {
        rayon::current_num_threads().max(1)
    } else {
        1
    };
    if threads > 1 {
        shared(threads)
    } else {
        None
    }
}

/// A helper's loop: wait for a new epoch (spinning, then parked), run its part, report.
fn helper(s: &Shared, part: usize) {
    let mut seen = 0;
    loop {
        let idle = Instant::now();
        let epoch = loop {
            if s.stop.load(Ordering::Acquire) {
                return;
            }
            let e = s.epoch.load(Ordering::Acquire);
            if e != seen {
                break e;
            }
            if idle.elapsed() < SPIN {
                std::hint::spin_loop();
            } else {
                std::thread::park_timeout(Duration::from_millis(50));
            }
        };
        seen = epoch;
        // SAFETY: the job was published before `epoch` (Release/Acquire above), and the caller
        // keeps it alive until this part reports below.
        let job = unsafe { (*s.job.get()).map(|p| &*p) };
        if let Some(job) = job {
            // A panic must not leave the caller spinning forever: report the part either way
            // and let the caller raise it on its own thread.
            let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(part)));
            if ran.is_err() {
                s.panicked.store(true, Ordering::Release);
            }
        }
        s.finished.fetch_add(1, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_part_runs_once_per_job_and_the_caller_waits_for_all() {
        for helpers in [0, 1, 3] {
            let mut team = Team::new(helpers);
            let counts: Vec<AtomicUsize> = (0..team.parts()).map(|_| AtomicUsize::new(0)).collect();
            for _ in 0..1000 {
                team.run(&|p| {
                    counts[p].fetch_add(1, Ordering::Relaxed);
                });
            }
            for c in &counts {
                assert_eq!(c.load(Ordering::Relaxed), 1000);
            }
        }
    }

    #[test]
    fn parts_write_disjoint_data_and_results_do_not_depend_on_the_team() {
        let mut reference = vec![0u64; 10_000];
        for (k, v) in reference.iter_mut().enumerate() {
            *v = (k as u64).wrapping_mul(2_654_435_761) % 1000;
        }
        for helpers in [0, 1, 2] {
            let mut team = Team::new(helpers);
            let parts = team.parts();
            let out: Vec<AtomicUsize> = (0..10_000).map(|_| AtomicUsize::new(0)).collect();
            team.run(&|p| {
                let n = out.len();
                let span = p * n / parts..(p + 1) * n / parts;
                for (k, slot) in out[span.clone()].iter().enumerate() {
                    let v = ((span.start + k) as u64).wrapping_mul(2_654_435_761) % 1000;
                    slot.store(v as usize, Ordering::Relaxed);
                }
            });
            let got: Vec<u64> = out
                .iter()
                .map(|a| a.load(Ordering::Relaxed) as u64)
                .collect();
            assert_eq!(got, reference);
        }
    }

    #[test]
    fn a_panic_in_a_helper_is_raised_on_the_caller_and_the_team_goes_on() {
        let mut team = Team::new(1);
        let raised = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            team.run(&|p| {
                if p == 1 {
                    panic!("boom");
                }
            })
        }));
        assert!(raised.is_err());
        let hits = AtomicUsize::new(0);
        team.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(hits.load(Ordering::Relaxed), 2);
    }

    #[test]
    fn the_shared_team_serves_one_caller_at_a_time_and_takes_the_asked_size() {
        // Other tests of this process may hold the team for a moment: wait for it.
        let mut guard = loop {
            if let Some(g) = shared(3) {
                break g;
            }
            std::thread::yield_now();
        };
        assert_eq!(guard.as_ref().map(Team::parts), Some(3));
        let hits = AtomicUsize::new(0);
        if let Some(team) = guard.as_mut() {
            team.run(&|_| {
                hits.fetch_add(1, Ordering::Relaxed);
            });
        }
        assert_eq!(hits.load(Ordering::Relaxed), 3);
        let second = std::thread::spawn(|| shared(2).is_none()).join();
        assert!(matches!(second, Ok(true)), "a second caller must run alone");
        drop(guard);
        let one = loop {
            if let Some(g) = shared(1) {
                break g.is_none();
            }
            std::thread::yield_now();
        };
        assert!(one, "one part needs no helper threads");
    }

    #[test]
    fn a_team_that_slept_wakes_for_the_next_job() {
        let mut team = Team::new(1);
        let hits = AtomicUsize::new(0);
        team.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        std::thread::sleep(SPIN * 4);
        team.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(hits.load(Ordering::Relaxed), 4);
    }
}
