//! One team of threads for the whole step, the host's and every plugin's: [`Team`] (the host
//! owns it) and [`TeamRef`] (what a group receives in [`SolveContext::team`](crate::SolveContext)).
//!
//! A substep is a chain of short jobs — the core's particle loops, then the colours of each
//! group's passes, tens of microseconds each on a 128 × 128 cloth. Two things decide whether
//! splitting them over threads pays:
//!
//! * **The hand-off.** A parked thread takes tens of microseconds to wake on the 2-core VM, as
//!   long as a job. So the team's helpers spin between jobs (for up to [`SPIN`], then park), and
//!   the caller runs parts of every job itself.
//! * **Nobody waits for a thread that is not running.** The parts of a job are claimed, one at
//!   a time, by the threads of the team, the caller included, and the caller keeps claiming
//!   until none is left: it waits only for parts a helper has started. When the machine is
//!   busy with other work and a helper is not scheduled, the caller runs its part too, instead
//!   of spinning until the helper gets a core back (a fixed part per helper made a step next to
//!   a busy loop two to three times slower than one thread).
//! * **Each thread asks for its own part first** (the caller part 0, helper `n` part `n`;
//!   `claim`), then for any part left. Consecutive jobs split the same arrays the same way,
//!   so a thread finds its part's particles in its own core's cache; when the first thread to
//!   ask took the lowest part, the data crossed between the cores' caches at every job.
//! * **One team per process, not per plugin.** Spinning helpers of two teams take both cores
//!   while only one team has work. So the host owns the only team and lends it to every group
//!   through the context, and the core's own loops (prediction, velocities, the finite checks)
//!   run on it too, while the helpers are awake anyway.
//!
//! The measurements behind each of these: `docs/decisions/thread-team.md`.
//!
//! A job is `Fn(part) + Sync`, called once with each part index `0..parts`; it must split its
//! work by the index alone and write only what that part owns (see [`SharedArray`]), so that
//! the results do not depend on which thread runs which part, nor on the count: the same
//! scene gives the same bits on one thread and on two.
//!
//! Crossing the plugin boundary is one call per job, never per constraint: [`TeamRef::run`]
//! passes the host a pointer to the job and a trampoline compiled into the plugin; each part
//! runs behind `catch_unwind` in the plugin, so a panic never unwinds through the host, and is
//! raised again on the calling thread when the job is done (where the SDK's adapter turns it
//! into an error naming the plugin and the group).
//!
//! The team size is the host's: `RAYON_NUM_THREADS` (default: the machine's cores), read when a
//! simulation is built.

use std::cell::UnsafeCell;
use std::marker::PhantomData;
use std::ops::Range;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use abi_stable::StableAbi;

/// How long an idle helper spins before it parks.
pub const SPIN: Duration = Duration::from_micros(500);

/// A job: called once with each part index `0..parts`.
pub type Job<'j> = dyn Fn(usize) + Sync + 'j;

struct Shared {
    /// The current job's number (high 32 bits, wrapping), incremented for every job, and which
    /// of its parts have been claimed (low 32 bits, one bit a part): helpers look for a new
    /// number, and every thread claims a part by setting its bit in the number it saw
    /// ([`claim`]).
    state: AtomicU64,
    /// Parts finished in the current job (the caller's included).
    finished: AtomicUsize,
    /// Set when the team is dropped.
    stop: AtomicBool,
    /// Set when a helper's part panicked.
    panicked: AtomicBool,
    /// Set while a job runs: a second job posted meanwhile (from another thread, or from
    /// inside a part) runs on its caller alone.
    busy: AtomicBool,
    /// The current job, valid from the `state` store that numbers it until `finished` reaches
    /// the part count (the caller waits for that before returning, so the borrow outlives
    /// every use).
    job: UnsafeCell<Option<*const Job<'static>>>,
    /// Threads to unpark when a job is posted (those that went to sleep).
    helpers: std::sync::OnceLock<Vec<std::thread::Thread>>,
}

// SAFETY: `job` is written only by the caller holding `busy`, before the `state` store
// (Release) that numbers the job, and read by a helper only after it has claimed a part of that
// number (Acquire); the caller does not write it again until every claimed part has reported
// `finished` and it has released `busy`.
unsafe impl Sync for Shared {}
// SAFETY: as above; the raw pointer is only dereferenced under that protocol.
unsafe impl Send for Shared {}

/// The job number of a `state` word.
fn number(state: u64) -> u64 {
    state >> 32
}

/// The most parts a team splits a job into: one bit each in the low half of the `state` word.
/// A larger `RAYON_NUM_THREADS` runs 32 parts (a job's results never depend on the count).
pub const MAX_PARTS: usize = 32;

/// The parts a team runs for `threads` threads asked for: at least one, at most [`MAX_PARTS`].
pub fn parts_for(threads: usize) -> usize {
    threads.clamp(1, MAX_PARTS)
}

/// Claims a part of job `job` (a number, as [`number`] reads it) of `parts` parts: part `own`
/// if it is still unclaimed, else the lowest unclaimed one; `None` when all are claimed or
/// another job is current. The caller asks with `own = 0`, helper `n` with `n`: each thread
/// runs its own part when it can (the module docs say why) and then what is left.
fn claim(state: &AtomicU64, job: u64, parts: usize, own: usize) -> Option<usize> {
    debug_assert!((1..=MAX_PARTS).contains(&parts) && own < parts);
    let all = u64::MAX >> (64 - parts);
    let mut now = state.load(Ordering::Acquire);
    loop {
        let free = !now & all;
        if number(now) != job || free == 0 {
            return None;
        }
        let part = if free & (1 << own) != 0 {
            own
        } else {
            free.trailing_zeros() as usize
        };
        match state.compare_exchange_weak(
            now,
            now | (1 << part),
            Ordering::AcqRel,
            Ordering::Acquire,
        ) {
            Ok(_) => return Some(part),
            Err(seen) => now = seen,
        }
    }
}

/// The team: the caller of each job plus `helpers` spinning threads.
pub struct Team {
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
    /// Parts of every job: the caller and the helpers.
    parts: usize,
}

impl Team {
    /// A team of the caller and `helpers` threads (none: every job runs on the caller), at
    /// most [`MAX_PARTS`] parts in all.
    ///
    /// Panics if the operating system refuses to start a thread.
    pub fn new(helpers: usize) -> Team {
        let mut team = Self::without_threads(helpers);
        team.threads = (1..team.parts)
            .map(|n| {
                let shared = Arc::clone(&team.shared);
                let parts = team.parts;
                std::thread::Builder::new()
                    .name(format!("nucleus-team-{n}"))
                    .spawn(move || helper(&shared, parts, n))
                    .expect("spawning a helper thread of the team")
            })
            .collect();
        let _ = team
            .shared
            .helpers
            .set(team.threads.iter().map(|t| t.thread().clone()).collect());
        team
    }

    /// A team of `helpers + 1` parts whose helper threads are not started: the caller claims
    /// and runs every part (as it does when no helper is scheduled).
    fn without_threads(helpers: usize) -> Team {
        let shared = Arc::new(Shared {
            state: AtomicU64::new(0),
            finished: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            panicked: AtomicBool::new(false),
            busy: AtomicBool::new(false),
            job: UnsafeCell::new(None),
            helpers: std::sync::OnceLock::new(),
        });
        Team {
            shared,
            threads: Vec::new(),
            parts: parts_for(helpers.saturating_add(1)),
        }
    }

    /// The number of parts a job is split into: the caller and the helpers.
    pub fn parts(&self) -> usize {
        self.parts
    }

    /// Runs `job(part)` for every part `0..parts()`, each part on whichever thread of the team
    /// claims it first (this one claims until none is left), and returns when all are done. A
    /// panic in any part is raised again here, on the caller's thread, once all are done.
    /// While another job runs on the team (from another thread, or from inside a part of
    /// this one), every part runs here in turn instead: the same results.
    pub fn run(&self, job: &Job<'_>) {
        if self.try_run(job) {
            panic!("a part of a job on the thread team panicked");
        }
    }

    /// [`run`](Self::run), returning `true` instead of panicking when a part that a helper ran
    /// panicked (a panic of a part this thread ran still unwinds from here, once all are done).
    pub fn try_run(&self, job: &Job<'_>) -> bool {
        let parts = self.parts();
        let s = &*self.shared;
        if parts == 1 || s.busy.swap(true, Ordering::Acquire) {
            (0..parts).for_each(job);
            return false;
        }
        s.finished.store(0, Ordering::Relaxed);
        // SAFETY: no helper reads `job` now: the previous job is finished (its caller waited
        // for every claimed part) and no part of this one can be claimed before the `state`
        // store below; `busy` keeps other callers out. The pointer stays valid until we return,
        // after every part has finished.
        unsafe {
            let erased: *const Job<'static> = std::mem::transmute::<&Job<'_>, &Job<'static>>(job);
            *s.job.get() = Some(erased);
        }
        let number = (number(s.state.load(Ordering::Relaxed)) + 1) & 0xffff_ffff;
        s.state.store(number << 32, Ordering::Release);
        if let Some(helpers) = s.helpers.get() {
            for t in helpers {
                t.unpark();
            }
        }
        // A part may panic: run the others and wait for the helpers before unwinding, so the
        // job outlives every use.
        let mut mine = Ok(());
        while let Some(part) = claim(&s.state, number, parts, 0) {
            let ran = catch_unwind(AssertUnwindSafe(|| job(part)));
            if mine.is_ok() {
                mine = ran;
            }
            s.finished.fetch_add(1, Ordering::AcqRel);
        }
        // Only parts a helper has started are left: spin, and let another thread have this
        // core now and then, in case the helper waits for it.
        let mut spins = 0u32;
        while s.finished.load(Ordering::Acquire) < parts {
            spins = spins.wrapping_add(1);
            if spins.is_multiple_of(4096) {
                std::thread::yield_now();
            } else {
                std::hint::spin_loop();
            }
        }
        let panicked = s.panicked.swap(false, Ordering::AcqRel);
        s.busy.store(false, Ordering::Release);
        if let Err(payload) = mine {
            std::panic::resume_unwind(payload);
        }
        panicked
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

/// Helper `own`'s loop: wait for a new job number (spinning, then parked), claim and run its
/// own part and then any part left, report each.
fn helper(s: &Shared, parts: usize, own: usize) {
    let mut seen = 0;
    loop {
        let idle = Instant::now();
        let mut spins = 0u32;
        let job_number = loop {
            if s.stop.load(Ordering::Acquire) {
                return;
            }
            let n = number(s.state.load(Ordering::Acquire));
            if n != seen {
                break n;
            }
            // The clock is read once every 64 turns: on a virtual machine, reading it can
            // cost as much as the wait it measures.
            spins = spins.wrapping_add(1);
            if !spins.is_multiple_of(64) || idle.elapsed() < SPIN {
                std::hint::spin_loop();
            } else {
                std::thread::park_timeout(Duration::from_millis(50));
            }
        };
        seen = job_number;
        while let Some(part) = claim(&s.state, job_number, parts, own) {
            // SAFETY: the job was stored before its number (Release), which this thread read
            // when it claimed the part (Acquire), and the caller keeps it alive until this part
            // reports below.
            let job = unsafe { (*s.job.get()).map(|p| &*p) };
            if let Some(job) = job {
                // A panic must not leave the caller spinning forever: report the part either
                // way and let the caller raise it on its own thread.
                if catch_unwind(AssertUnwindSafe(|| job(part))).is_err() {
                    s.panicked.store(true, Ordering::Release);
                }
            }
            s.finished.fetch_add(1, Ordering::AcqRel);
        }
    }
}

/// The process's one team (see the module docs).
static SHARED: std::sync::Mutex<Option<Team>> = std::sync::Mutex::new(None);

/// The process's team, resized to `parts` parts (the caller and `parts − 1` helpers), for as
/// long as the guard is held; `None` when another thread holds it (two simulations stepping at
/// once, as the tests do): the caller then runs its jobs alone, which gives the same results,
/// since a job's result never depends on the team. The guard holds `None` for one part.
pub fn shared(parts: usize) -> Option<std::sync::MutexGuard<'static, Option<Team>>> {
    let mut guard = match SHARED.try_lock() {
        Ok(g) => g,
        // A panic in a job poisons the lock, but the team is still whole: `run` waits for every
        // part before it raises the panic again.
        Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
        Err(std::sync::TryLockError::WouldBlock) => return None,
    };
    // A team never has more than `MAX_PARTS` parts: compare with what it would have, or a
    // larger request would build a new team at every call.
    let parts = parts_for(parts);
    if guard.as_ref().map_or(1, Team::parts) != parts {
        *guard = (parts > 1).then(|| Team::new(parts - 1));
    }
    Some(guard)
}

/// The thread count the host uses: `RAYON_NUM_THREADS` when it is a positive integer, else the
/// machine's available parallelism; at most [`MAX_PARTS`].
pub fn configured_threads() -> usize {
    parts_for(
        std::env::var("RAYON_NUM_THREADS")
            .ok()
            .and_then(|s| s.trim().parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
    )
}

// ---------------------------------------------------------------------------------------------
// Across the plugin boundary
// ---------------------------------------------------------------------------------------------

/// A job handed to the host: `call(data, part)` runs part `part` and returns `false` if it
/// panicked (the panic is caught on the plugin's side of the boundary).
#[repr(C)]
#[derive(StableAbi, Clone, Copy, Debug)]
pub struct TeamJob {
    data: *const (),
    call: extern "C" fn(data: *const (), part: usize) -> bool,
}

/// The host's team as a group sees it: [`parts`](Self::parts) and [`run`](Self::run). Copied
/// into every [`SolveContext`](crate::SolveContext); [`TeamRef::serial`] (one part, run on the
/// caller) where there is no team, as in [`SolveContext::new`](crate::SolveContext::new).
///
/// Neither `Send` nor `Sync`: a job cannot capture it, so jobs never nest.
#[repr(C)]
#[derive(StableAbi, Clone, Copy, Debug)]
pub struct TeamRef<'a> {
    parts: usize,
    team: *const (),
    run: Option<extern "C" fn(team: *const (), job: TeamJob) -> bool>,
    _team: PhantomData<&'a ()>,
}

impl TeamRef<'static> {
    /// No team: one part, run on the caller.
    pub const fn serial() -> TeamRef<'static> {
        TeamRef {
            parts: 1,
            team: std::ptr::null(),
            run: None,
            _team: PhantomData,
        }
    }
}

impl<'a> TeamRef<'a> {
    /// `team`, lent for `'a`.
    pub fn new(team: &'a Team) -> TeamRef<'a> {
        extern "C" fn run_on(team: *const (), job: TeamJob) -> bool {
            // SAFETY: `team` is the `&'a Team` this `TeamRef` was made from, alive for `'a`,
            // which outlives every use of the `TeamRef`.
            let team = unsafe { &*(team as *const Team) };
            let job = SyncJob(job);
            let failed = AtomicBool::new(false);
            let part = |p: usize| {
                if !job.call(p) {
                    failed.store(true, Ordering::Relaxed);
                }
            };
            // The plugin's parts never unwind (its trampoline catches), and neither may this
            // function, which the plugin calls.
            let panicked = catch_unwind(AssertUnwindSafe(|| team.try_run(&part))).unwrap_or(true);
            !panicked && !failed.load(Ordering::Relaxed)
        }
        TeamRef {
            parts: team.parts(),
            team: team as *const Team as *const (),
            run: Some(run_on),
            _team: PhantomData,
        }
    }

    /// The number of parts a job is split into (1 without a team).
    pub fn parts(&self) -> usize {
        if self.run.is_some() {
            self.parts.max(1)
        } else {
            1
        }
    }

    /// Runs `f` over `0..n` (not at all for `n = 0`): split into the team's parts (each its own
    /// contiguous range, by [`span`]) when `n` reaches `min_split`, else in one piece on this
    /// thread. `f` must write only what its range owns; the results are then the same for any
    /// team.
    pub fn for_ranges(&self, n: usize, min_split: usize, f: &(dyn Fn(Range<usize>) + Sync)) {
        if n == 0 {
            return;
        }
        let parts = self.parts();
        if parts > 1 && n >= min_split {
            self.run(&|part| f(span(part, parts, n)));
        } else {
            f(0..n);
        }
    }

    /// [`for_ranges`](Self::for_ranges) over `0..items.len()`, each range given its own part
    /// of `items` to write: `f(range, &mut items[range])`.
    pub fn for_ranges_mut<T: Send>(
        &self,
        items: &mut [T],
        min_split: usize,
        f: &(dyn Fn(Range<usize>, &mut [T]) + Sync),
    ) {
        let n = items.len();
        let shared = SharedArray::new(items);
        self.for_ranges(n, min_split, &|r| {
            // SAFETY: the ranges of `for_ranges` are disjoint and inside `0..n`, and `items` is
            // exclusively borrowed for this call.
            f(r.clone(), unsafe { shared.slice(r.start, r.len()) })
        });
    }

    /// Runs `job(part)` for every part `0..parts()` on the host's team and returns when all are
    /// done; one part, on this thread, without a team. A panic in any part is raised again
    /// here once every part is done.
    pub fn run(&self, job: &Job<'_>) {
        let Some(run) = self.run.filter(|_| self.parts > 1) else {
            job(0);
            return;
        };
        extern "C" fn call(data: *const (), part: usize) -> bool {
            // SAFETY: `data` is the `&&Job` made below, alive until `run` returns, which is
            // after every part has run.
            let job = unsafe { &*(data as *const &Job<'_>) };
            catch_unwind(AssertUnwindSafe(|| job(part))).is_ok()
        }
        let data: *const &Job<'_> = &job;
        let ok = run(
            self.team,
            TeamJob {
                data: data as *const (),
                call,
            },
        );
        if !ok {
            panic!("a part of a job on the host's thread team panicked");
        }
    }
}

/// A [`TeamJob`] that may be called from the team's threads.
struct SyncJob(TeamJob);

// SAFETY: a `TeamJob`'s data is a `&Job`, whose target is `Sync`, and its `call` only reads it:
// calling it from several threads at once is what `Job` allows.
unsafe impl Sync for SyncJob {}

impl SyncJob {
    /// Runs part `part`; `false` if it panicked.
    fn call(&self, part: usize) -> bool {
        (self.0.call)(self.0.data, part)
    }
}

/// A raw pointer to the first element of an array the parts of one job share, each part
/// reading and writing only the elements it owns. A method gives the addresses, so that a
/// closure captures the whole wrapper (which is `Sync`), not the raw pointer inside it.
#[derive(Debug)]
pub struct SharedArray<T>(*mut T);

// Copied by hand: a derive would ask `T: Copy`, and the pointer is copyable whatever `T` is.
impl<T> Clone for SharedArray<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for SharedArray<T> {}

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

/// The index range part `part` of `parts` owns in `0..n`: contiguous, in order, covering
/// `0..n` exactly once over the parts, and a function of the three numbers alone.
pub fn span(part: usize, parts: usize, n: usize) -> std::ops::Range<usize> {
    let parts = parts.max(1);
    part * n / parts..(part + 1) * n / parts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_claims_its_own_part_first_then_the_lowest_left() {
        let job = 7;
        let state = AtomicU64::new(job << 32);
        // Helper 2 of 4 asks first: it gets its own part, not part 0.
        assert_eq!(claim(&state, job, 4, 2), Some(2));
        // The caller then gets its own, part 0.
        assert_eq!(claim(&state, job, 4, 0), Some(0));
        // Helper 2 again: its part is taken, so the lowest unclaimed, 1, then 3, then none.
        assert_eq!(claim(&state, job, 4, 2), Some(1));
        assert_eq!(claim(&state, job, 4, 2), Some(3));
        assert_eq!(claim(&state, job, 4, 3), None);
        assert_eq!(claim(&state, job, 4, 0), None);
        // A thread still holding the last job's number claims nothing of the next job.
        state.store((job + 1) << 32, Ordering::Release);
        assert_eq!(claim(&state, job, 4, 1), None);
        assert_eq!(claim(&state, job + 1, 4, 1), Some(1));
        // The widest team: all 32 parts, each once.
        let state = AtomicU64::new(job << 32);
        let mut got: Vec<usize> = (0..32)
            .map(|k| claim(&state, job, MAX_PARTS, (k * 5) % 32).unwrap())
            .collect();
        assert_eq!(claim(&state, job, MAX_PARTS, 0), None);
        got.sort_unstable();
        assert_eq!(got, (0..32).collect::<Vec<_>>());
    }

    #[test]
    fn for_ranges_mut_hands_each_range_its_own_items_once() {
        for helpers in [0, 1, 3] {
            let team = Team::new(helpers);
            let team = TeamRef::new(&team);
            for (n, min_split) in [(0, 1), (7, 100), (10_001, 1)] {
                let mut items = vec![0usize; n];
                team.for_ranges_mut(&mut items, min_split, &|r, part| {
                    assert_eq!(r.len(), part.len(), "a range and its items");
                    for (i, item) in r.zip(part) {
                        *item += i + 1;
                    }
                });
                let expected: Vec<usize> = (1..=n).collect();
                assert_eq!(items, expected, "{helpers} helpers, n = {n}");
            }
        }
    }

    #[test]
    fn a_team_has_at_most_max_parts_parts() {
        assert_eq!(Team::without_threads(1).parts(), 2);
        assert_eq!(Team::without_threads(MAX_PARTS - 1).parts(), MAX_PARTS);
        assert_eq!(Team::without_threads(100).parts(), MAX_PARTS);
        // The process's team asked for more parts than it may have is built once, not at
        // every request (its threads would be spawned again each substep).
        let first = shared(100).map(|g| g.as_ref().map(|t| Arc::as_ptr(&t.shared)));
        let again = shared(100).map(|g| g.as_ref().map(|t| Arc::as_ptr(&t.shared)));
        if let (Some(Some(a)), Some(Some(b))) = (first, again) {
            assert_eq!(a, b, "the capped team was rebuilt");
        }
        assert!(shared(100).is_none_or(|g| g.as_ref().is_some_and(|t| t.parts() == MAX_PARTS)));
        assert!(configured_threads() <= MAX_PARTS);
    }

    #[test]
    fn every_part_runs_once_per_job_and_the_caller_waits_for_all() {
        for helpers in [0, 1, 3] {
            let team = Team::new(helpers);
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
    fn a_job_completes_on_the_caller_when_no_helper_comes() {
        // Helpers that never run (not scheduled, as on a machine busy with other work): the
        // caller claims and runs every part itself, once each, instead of waiting for them.
        let team = Team::without_threads(2);
        let caller = std::thread::current().id();
        let counts: Vec<AtomicUsize> = (0..team.parts()).map(|_| AtomicUsize::new(0)).collect();
        for _ in 0..100 {
            team.run(&|p| {
                assert_eq!(std::thread::current().id(), caller);
                counts[p].fetch_add(1, Ordering::Relaxed);
            });
        }
        assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 100));
        // A panicking part still lets the others run, and is raised once they are done.
        let done = AtomicUsize::new(0);
        let raised = catch_unwind(AssertUnwindSafe(|| {
            team.run(&|p| {
                if p == 0 {
                    panic!("boom");
                }
                done.fetch_add(1, Ordering::Relaxed);
            })
        }));
        assert!(raised.is_err());
        assert_eq!(done.load(Ordering::Relaxed), 2);
    }

    #[test]
    fn parts_go_to_whichever_thread_claims_them_and_each_runs_once() {
        // Parts that take turns being slow: the other thread claims what is left.
        let team = Team::new(1);
        let counts: Vec<AtomicUsize> = (0..2).map(|_| AtomicUsize::new(0)).collect();
        for round in 0..200u64 {
            team.run(&|p| {
                if (round + p as u64).is_multiple_of(7) {
                    std::thread::sleep(Duration::from_micros(200));
                }
                counts[p].fetch_add(1, Ordering::Relaxed);
            });
        }
        assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 200));
    }

    /// A job that writes `f(k)` for every `k` of `0..n` by spans, on `team`.
    fn spans_job(team: TeamRef<'_>, n: usize) -> Vec<u64> {
        let out: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
        let parts = team.parts();
        team.run(&|p| {
            let r = span(p, parts, n);
            for (k, slot) in out[r.clone()].iter().enumerate() {
                let v = ((r.start + k) as u64).wrapping_mul(2_654_435_761) % 1000;
                slot.store(v as usize, Ordering::Relaxed);
            }
        });
        out.iter()
            .map(|a| a.load(Ordering::Relaxed) as u64)
            .collect()
    }

    #[test]
    fn parts_write_disjoint_data_and_results_do_not_depend_on_the_team() {
        let reference: Vec<u64> = (0..10_000u64)
            .map(|k| k.wrapping_mul(2_654_435_761) % 1000)
            .collect();
        assert_eq!(spans_job(TeamRef::serial(), 10_000), reference);
        for helpers in [0, 1, 2] {
            let team = Team::new(helpers);
            assert_eq!(TeamRef::new(&team).parts(), helpers + 1);
            assert_eq!(spans_job(TeamRef::new(&team), 10_000), reference);
        }
    }

    #[test]
    fn spans_cover_the_range_once_in_order() {
        for n in [0, 1, 5, 1000, 1001] {
            // More pieces than a team has parts too (collision splits its queries into chunks).
            for parts in [1, 2, 3, 7, MAX_PARTS + 1, 100] {
                let all: Vec<usize> = (0..parts).flat_map(|p| span(p, parts, n)).collect();
                assert_eq!(all, (0..n).collect::<Vec<_>>(), "n {n}, parts {parts}");
            }
        }
    }

    #[test]
    fn a_panic_in_a_helper_is_raised_on_the_caller_and_the_team_goes_on() {
        let team = Team::new(1);
        let raised = catch_unwind(AssertUnwindSafe(|| {
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
    fn a_panic_in_any_part_across_the_boundary_is_raised_on_the_caller_once_all_are_done() {
        let team = Team::new(1);
        for bad in [0, 1] {
            let done = AtomicUsize::new(0);
            let raised = catch_unwind(AssertUnwindSafe(|| {
                TeamRef::new(&team).run(&|p| {
                    if p == bad {
                        panic!("boom");
                    }
                    done.fetch_add(1, Ordering::Relaxed);
                })
            }));
            assert!(raised.is_err(), "part {bad}");
            assert_eq!(done.load(Ordering::Relaxed), 1, "the other part ran");
        }
        // The team is whole afterwards.
        assert_eq!(spans_job(TeamRef::new(&team), 100).len(), 100);
    }

    #[test]
    fn a_job_posted_while_another_runs_runs_alone_on_its_caller() {
        let team = Team::new(1);
        let inner = AtomicUsize::new(0);
        let outer_parts = AtomicUsize::new(0);
        team.run(&|_| {
            outer_parts.fetch_add(1, Ordering::Relaxed);
            // From inside a part (both parts do this): the team is busy, so every part of
            // the nested job runs here, in turn.
            team.run(&|_| {
                inner.fetch_add(1, Ordering::Relaxed);
            });
        });
        assert_eq!(outer_parts.load(Ordering::Relaxed), 2);
        assert_eq!(inner.load(Ordering::Relaxed), 4);
    }

    #[test]
    fn the_shared_team_serves_one_caller_at_a_time_and_takes_the_asked_size() {
        // Other tests of this process may hold the team for a moment: wait for it.
        let guard = loop {
            if let Some(g) = shared(3) {
                break g;
            }
            std::thread::yield_now();
        };
        assert_eq!(guard.as_ref().map(Team::parts), Some(3));
        let hits = AtomicUsize::new(0);
        if let Some(team) = guard.as_ref() {
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
        let team = Team::new(1);
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

    #[test]
    fn without_a_team_a_job_is_one_part_on_the_caller() {
        let serial = TeamRef::serial();
        assert_eq!(serial.parts(), 1);
        let caller = std::thread::current().id();
        let ran = AtomicUsize::new(0);
        serial.run(&|p| {
            assert_eq!(p, 0);
            assert_eq!(std::thread::current().id(), caller);
            ran.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(ran.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn for_ranges_covers_the_range_once_split_only_from_the_threshold() {
        let team = Team::new(1);
        let team = TeamRef::new(&team);
        for (n, min_split, pieces) in [(0, 1, 0), (10, 11, 1), (10, 10, 2), (1001, 2, 2)] {
            let seen = std::sync::Mutex::new(Vec::new());
            team.for_ranges(n, min_split, &|r| seen.lock().unwrap().push(r));
            let mut seen = seen.into_inner().unwrap();
            seen.sort_by_key(|r| r.start);
            assert_eq!(seen.len(), pieces, "n {n}, min {min_split}: {seen:?}");
            let all: Vec<usize> = seen.into_iter().flatten().collect();
            assert_eq!(all, (0..n).collect::<Vec<_>>());
        }
    }
}
