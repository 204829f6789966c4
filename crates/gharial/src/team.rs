//! A team of threads for the stage-wise passes of a solve (evaluation, derivatives).
//!
//! A solver alternates short parallel passes over the stages (tens to hundreds of
//! microseconds) with serial work (rollouts, the backward pass). A general pool puts its
//! idle threads to sleep within microseconds and the calling thread waits for them, so
//! every pass pays two wake-ups; on a two-core machine that cost ate the gain. Here the
//! calling thread works too, the helpers stay awake for [`SPIN`] after a pass (spinning,
//! then yielding their core to any other thread that wants it) before they park, and a
//! helper that has not started when the caller runs out of work is cancelled instead of
//! waited for; one that keeps missing passes (its core is taken) is asked only now and
//! then, so that a busy machine costs little more than one thread. A pass allocates
//! nothing. Passes do not nest: a job must not start another pass of the same team.
//!
//! The one unsafe step is in [`Team::run`]: the job, a reference to the caller's closure,
//! is handed to the helpers with its lifetime erased. It is sound because `run` does not
//! return (nor unwind) before every helper has either finished the job or been
//! cancelled before reading it (the `turn` protocol below).
#![allow(unsafe_code)]

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long an idle helper spins before it parks: longer than the serial work between
/// two passes of a small problem, short enough not to hold a core after a solve.
const SPIN: Duration = Duration::from_micros(300);

/// A pass shorter than this is not worth waking a helper for.
const SHORT_PASS: Duration = Duration::from_micros(10);

/// One kind of pass of a solver (stage evaluation, stage derivatives, Riccati legs):
/// whether the last pass of this kind was too short to share, so that the next runs on
/// the caller alone. Owned by the code that runs the passes.
#[derive(Debug, Default)]
pub(crate) struct PassKind {
    alone: AtomicBool,
}

/// Passes in a row a helper may miss before it is asked only every [`PROBE_EVERY`]th
/// pass.
const MISS_LIMIT: usize = 4;

/// How often a helper that keeps missing passes is asked again.
const PROBE_EVERY: usize = 16;

/// Busy-wait iterations before a waiting thread starts yielding its core.
const SPIN_LOOPS: u32 = 64;

/// Teams kept for reuse when their solvers are gone (see [`Team::for_threads`]).
const KEPT_TEAMS: usize = 8;

static KEPT: Mutex<Vec<Arc<Team>>> = Mutex::new(Vec::new());

/// `Slot::turn` when the helper has nothing to do (done, or cancelled before starting).
const IDLE: usize = 0;
/// `Slot::turn` while the helper runs the job.
const RUNNING: usize = usize::MAX;

type Job = &'static (dyn Fn() + Sync);

/// One helper's handshake, on its own cache line.
#[repr(align(128))]
#[derive(Default)]
struct Slot {
    /// `IDLE`, `RUNNING`, or the number of a pass the helper is asked to join.
    turn: AtomicUsize,
    /// Set by the helper before it parks.
    parked: AtomicBool,
    /// Passes in a row the helper was asked to join and was not there before the caller
    /// had done all the work (kept by the caller).
    misses: AtomicUsize,
    /// Whether the current pass asked this helper (kept by the caller).
    asked: AtomicBool,
}

#[derive(Default)]
struct Shared {
    slots: Vec<Slot>,
    job: Mutex<Option<Job>>,
    /// Helpers that have started their loop.
    started: AtomicUsize,
    panicked: AtomicBool,
    shutdown: AtomicBool,
}

/// The calling thread and `size - 1` helper threads; shared (`Arc`) by the parts of a
/// solver that run stage-wise passes, one pass at a time.
pub(crate) struct Team {
    shared: Arc<Shared>,
    helpers: Vec<JoinHandle<()>>,
    /// The number of the last shared pass; held for the whole of a pass.
    pass: Mutex<usize>,
}

impl std::fmt::Debug for Team {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Team").field("size", &self.size()).finish()
    }
}

impl Team {
    /// A team of [`crate::pool_threads`]`(threads)` threads, or `None` for one thread.
    ///
    /// Teams outlive their solvers: one that no solver holds any more is handed to the
    /// next solver that asks for its size, so that its threads, already placed on their
    /// cores by the scheduler, serve solve after solve (at most [`KEPT_TEAMS`] are kept;
    /// beyond them teams end with their last solver).
    ///
    /// # Errors
    /// If a helper thread cannot be started.
    pub(crate) fn for_threads(threads: usize) -> std::io::Result<Option<Arc<Self>>> {
        let size = crate::pool_threads(threads);
        if size == 1 {
            return Ok(None);
        }
        let mut kept = lock(&KEPT);
        if let Some(t) = kept.iter().find(|t| t.size() == size && Arc::strong_count(t) == 1) {
            return Ok(Some(Arc::clone(t)));
        }
        let team = Arc::new(Self::new(size)?);
        if kept.len() < KEPT_TEAMS {
            kept.push(Arc::clone(&team));
        }
        Ok(Some(team))
    }

    /// Starts `size - 1` helpers (`size >= 2`).
    pub(crate) fn new(size: usize) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            slots: (1..size).map(|_| Slot::default()).collect(),
            ..Shared::default()
        });
        let mut helpers = Vec::with_capacity(size - 1);
        for i in 0..size - 1 {
            let s = Arc::clone(&shared);
            let spawned = std::thread::Builder::new()
                .name(format!("gharial-stage-{}", i + 1))
                .spawn(move || helper(&s, i));
            match spawned {
                Ok(h) => helpers.push(h),
                Err(e) => {
                    stop(&shared, &mut helpers);
                    return Err(e);
                }
            }
        }
        // A thread's start-up allocates (its name for the stack-overflow handler): wait
        // for it here, so that none happens during a solve.
        while shared.started.load(Ordering::Acquire) < size - 1 {
            std::thread::yield_now();
        }
        Ok(Self {
            shared,
            helpers,
            pass: Mutex::new(0),
        })
    }

    /// Threads of the team, the caller's included.
    pub(crate) fn size(&self) -> usize {
        self.helpers.len() + 1
    }

    /// Runs `f` on every item of `items`, the team's threads taking the next item in
    /// turn (the calling thread included).
    pub(crate) fn for_each<I: Iterator + Send>(&self, kind: &PassKind, items: I, f: impl Fn(I::Item) + Sync) {
        let items = Mutex::new(items);
        self.run(kind, &|| {
            loop {
                let next = lock(&items).next();
                let Some(item) = next else { break };
                f(item);
            }
        });
    }

    /// Runs `job` on the calling thread and on every helper that joins before the caller
    /// returns from its own call; `job` must share the work out itself (each call takes
    /// pieces until none are left), so any number of calls completes it. A pass of a
    /// `kind` whose last pass was too short to share (under [`SHORT_PASS`] on the caller
    /// alone, under half of it shared) runs on the caller alone.
    ///
    /// # Panics
    /// If `job` panicked on a helper (after every helper has stopped using it).
    pub(crate) fn run(&self, kind: &PassKind, job: &(dyn Fn() + Sync)) {
        let start = Instant::now();
        if kind.alone.load(Ordering::Relaxed) {
            job();
            kind.alone.store(start.elapsed() < SHORT_PASS, Ordering::Relaxed);
            return;
        }
        self.run_shared(job, &mut lock(&self.pass));
        kind.alone.store(start.elapsed() < SHORT_PASS / 2, Ordering::Relaxed);
    }

    /// A pass shared with the helpers (see [`Team::run`]).
    fn run_shared(&self, job: &(dyn Fn() + Sync), pass: &mut usize) {
        // SAFETY: the reference is only used by helpers between a successful claim of
        // their turn and their reset of it to IDLE; `Finish` (also on unwinding) takes
        // every turn back or waits for that reset before this function ends, so no
        // helper uses `job` after its borrow ends.
        let erased: Job = unsafe { std::mem::transmute::<&(dyn Fn() + Sync), Job>(job) };
        *lock(&self.shared.job) = Some(erased);
        self.shared.panicked.store(false, Ordering::Relaxed);
        *pass = if *pass >= RUNNING - 1 { 1 } else { *pass + 1 };
        for (slot, h) in self.shared.slots.iter().zip(&self.helpers) {
            // A helper that keeps missing passes has no core to run on (another process
            // holds it, or the scheduler put it beside the caller): ask it only now and
            // then, so that it parks instead of competing with the caller.
            let ask = slot.misses.load(Ordering::Relaxed) < MISS_LIMIT || pass.is_multiple_of(PROBE_EVERY);
            slot.asked.store(ask, Ordering::Relaxed);
            if !ask {
                continue;
            }
            slot.turn.store(*pass, Ordering::SeqCst);
            if slot.parked.load(Ordering::SeqCst) {
                h.thread().unpark();
            }
        }
        let finish = Finish {
            shared: &self.shared,
            pass: *pass,
        };
        job();
        drop(finish);
        if self.shared.panicked.swap(false, Ordering::AcqRel) {
            panic!("a stage-wise task panicked on a helper thread");
        }
    }
}

/// Pieces of an array per thread in [`for_each_indexed`]: more than one, so that a
/// thread that starts late or meets slower items leaves its share to the others.
const PIECES_PER_THREAD: usize = 4;

/// Runs `f(i, &mut items[i])` for every item: on `team` in contiguous pieces,
/// [`PIECES_PER_THREAD`] per thread, taken in turn; in order on the caller without a team.
pub(crate) fn for_each_indexed<T: Send>(
    team: Option<&Team>,
    kind: &PassKind,
    items: &mut [T],
    f: impl Fn(usize, &mut T) + Sync,
) {
    match team {
        Some(team) => {
            let piece = items.len().div_ceil(PIECES_PER_THREAD * team.size()).max(1);
            team.for_each(kind, items.chunks_mut(piece).enumerate(), |(k, chunk)| {
                for (j, item) in chunk.iter_mut().enumerate() {
                    f(k * piece + j, item);
                }
            });
        }
        None => items.iter_mut().enumerate().for_each(|(i, item)| f(i, item)),
    }
}

/// Ends a pass: cancels the helpers that have not started and waits for the others.
struct Finish<'a> {
    shared: &'a Shared,
    pass: usize,
}

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        for slot in &self.shared.slots {
            if !slot.asked.load(Ordering::Relaxed) {
                continue;
            }
            if slot
                .turn
                .compare_exchange(self.pass, IDLE, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
            {
                let m = slot.misses.load(Ordering::Relaxed);
                slot.misses.store(m.saturating_add(1), Ordering::Relaxed);
                continue;
            }
            slot.misses.store(0, Ordering::Relaxed);
            let mut spins = 0u32;
            while slot.turn.load(Ordering::Acquire) != IDLE {
                spins = spins.saturating_add(1);
                if spins < SPIN_LOOPS {
                    std::hint::spin_loop();
                } else {
                    std::thread::yield_now();
                }
            }
        }
        *lock(&self.shared.job) = None;
    }
}

impl Drop for Team {
    fn drop(&mut self) {
        stop(&self.shared, &mut self.helpers);
    }
}

fn stop(shared: &Shared, helpers: &mut Vec<JoinHandle<()>>) {
    shared.shutdown.store(true, Ordering::SeqCst);
    for h in helpers.iter() {
        h.thread().unpark();
    }
    for h in helpers.drain(..) {
        let _ = h.join();
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A helper's loop: wait for a turn (spinning, then parked), claim it, run the job.
fn helper(shared: &Shared, i: usize) {
    let slot = &shared.slots[i];
    crate::linalg::reserve_packing_buffer();
    shared.started.fetch_add(1, Ordering::Release);
    loop {
        let Some(pass) = wait_for_turn(shared, slot) else {
            return;
        };
        if slot
            .turn
            .compare_exchange(pass, RUNNING, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            continue; // cancelled: the caller finished the pass alone
        }
        let job = *lock(&shared.job);
        if let Some(job) = job
            && std::panic::catch_unwind(std::panic::AssertUnwindSafe(job)).is_err()
        {
            shared.panicked.store(true, Ordering::Release);
        }
        slot.turn.store(IDLE, Ordering::Release);
    }
}

/// The number of the pass this helper is asked to join, or `None` at shutdown.
fn wait_for_turn(shared: &Shared, slot: &Slot) -> Option<usize> {
    let mut start = Instant::now();
    let mut spins = 0u32;
    loop {
        if shared.shutdown.load(Ordering::Acquire) {
            return None;
        }
        let t = slot.turn.load(Ordering::Acquire);
        if t != IDLE && t != RUNNING {
            return Some(t);
        }
        spins = spins.saturating_add(1);
        if spins < SPIN_LOOPS {
            std::hint::spin_loop();
            continue;
        }
        // Yield rather than spin: a thread sharing this core (the caller, if the
        // scheduler put both here) runs, and on a core of its own the call returns at once.
        if start.elapsed() < SPIN {
            std::thread::yield_now();
            continue;
        }
        // Announce the park before the last look at the turn; `run` stores the turn
        // before it looks at the flag, so one of the two sees the other.
        slot.parked.store(true, Ordering::SeqCst);
        if slot.turn.load(Ordering::SeqCst) == IDLE && !shared.shutdown.load(Ordering::SeqCst) {
            std::thread::park();
        }
        slot.parked.store(false, Ordering::SeqCst);
        start = Instant::now();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shares `0..n` out in pieces of `chunk`, as the stage passes do.
    fn sum_in_pieces(team: &Team, n: usize, chunk: usize) -> Vec<usize> {
        let mut out = vec![0usize; n];
        team.for_each(&PassKind::default(), out.chunks_mut(chunk).enumerate(), |(k, piece)| {
            for (j, v) in piece.iter_mut().enumerate() {
                // Some work per item (about a microsecond), so that long passes are
                // shared and short ones run alone.
                std::hint::black_box((0..1000).fold(0usize, |a, i| std::hint::black_box(a ^ i)));
                *v += (k * chunk + j) * 3 + 1;
            }
        });
        out
    }

    #[test]
    fn every_piece_is_done_once_over_many_passes() {
        let team = Team::new(3).unwrap();
        assert_eq!(team.size(), 3);
        for pass in 0..2000 {
            let n = 1 + pass % 97;
            let out = sum_in_pieces(&team, n, 1 + pass % 7);
            let want: Vec<usize> = (0..n).map(|i| i * 3 + 1).collect();
            assert_eq!(out, want, "pass {pass}");
            if pass % 500 == 0 {
                // Let the helpers park, then wake them.
                std::thread::sleep(SPIN * 3);
            }
        }
    }

    #[test]
    fn a_team_in_use_is_never_handed_out_again() {
        let Some(a) = Team::for_threads(2).unwrap() else {
            return; // one core: no team
        };
        let held: Vec<_> = (0..3).map(|_| Team::for_threads(2).unwrap().unwrap()).collect();
        for (i, t) in held.iter().enumerate() {
            assert!(!Arc::ptr_eq(&a, t), "team {i}");
            assert!(held[..i].iter().all(|u| !Arc::ptr_eq(u, t)), "team {i}");
        }
        // Two solvers' passes at once, each on its own team.
        std::thread::scope(|s| {
            s.spawn(|| assert_eq!(sum_in_pieces(&held[0], 50, 3)[49], 148));
            assert_eq!(sum_in_pieces(&a, 50, 7)[49], 148);
        });
    }

    #[test]
    fn a_panic_on_any_thread_reaches_the_caller_and_the_team_goes_on() {
        let team = Team::new(2).unwrap();
        let calls = AtomicUsize::new(0);
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            team.run(&PassKind::default(), &|| {
                calls.fetch_add(1, Ordering::SeqCst);
                panic!("boom");
            });
        }));
        assert!(r.is_err());
        assert!(calls.load(Ordering::SeqCst) >= 1);
        assert_eq!(
            sum_in_pieces(&team, 10, 3),
            (0..10).map(|i| i * 3 + 1).collect::<Vec<_>>()
        );
    }
}
