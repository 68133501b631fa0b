//! The tissue step's worker threads: a small pool of pinned, briefly spinning workers that run the chunks of
//! a pass beside the thread that asked for it.
//!
//! Owns: [`WorkerPool`] (`sinew-work-<k>` threads). A pass is handed over on a [`Board`]: the caller stores a
//! pointer to the job, then opens the pass (a new epoch with its chunk count); workers (and the caller, which
//! works too) claim chunk indices from the board, which gives each index of the current pass out once. The
//! caller returns when every chunk has reported done, so the job (on its stack) outlives every use.
//!
//! Idle workers spin for [`SPIN_AFTER_WORK`] after their last chunk (the passes of one step follow each other
//! within microseconds), then park; a pass wakes parked workers, and the caller starts on the chunks at once,
//! so a late worker means less help, never a wrong result or a stall. A pool that is already running a pass
//! (a multi-rate object's thread and the tick at once) runs the second one inline. Nothing here allocates,
//! locks or logs once the pool is built.
//!
//! Must not: decide anything about the results (the passes in [`crate`] make them thread-count-proof).
#![allow(unsafe_code)] // one lifetime erasure (the job pointer); its block says why it is sound

use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicPtr, Ordering};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

use crate::board::{Board, MAX_CHUNKS};
use crate::{ChunkRunner, Inline};

/// How long an idle worker spins for the next pass before it parks.
pub const SPIN_AFTER_WORK: Duration = Duration::from_micros(100);

/// The job of the current pass: a `&(dyn Fn(usize) + Sync)` on the caller's stack.
type Job<'a> = &'a (dyn Fn(usize) + Sync);

/// What the caller and the workers share.
#[derive(Debug, Default)]
struct Hand {
    /// The current pass's epoch, claims and completions.
    board: Board,
    /// Points at the current pass's [`Job`] (valid while the pass is running).
    job: AtomicPtr<()>,
    /// A worker's chunk panicked in the current pass.
    panicked: AtomicBool,
    shutdown: AtomicBool,
}

impl Hand {
    /// Run `job` on chunk `c` and count it done; a panic is caught, flagged, and counted done too.
    fn run_chunk(&self, job: Job<'_>, c: usize) {
        if catch_unwind(AssertUnwindSafe(|| job(c))).is_err() {
            self.panicked.store(true, Ordering::Release);
        }
        self.board.finish_chunk();
    }
}

/// One worker thread.
#[derive(Debug)]
struct Worker {
    thread: Thread,
    sleeping: Arc<AtomicBool>,
    handle: Option<JoinHandle<()>>,
}

/// What the pool was given at start, for the start-up report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoolReport {
    /// Threads that run chunks, the caller included.
    pub threads: usize,
    /// Per worker: the CPU it was pinned to, or why not.
    pub pinned: Vec<Result<usize, String>>,
}

impl std::fmt::Display for PoolReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} tissue thread(s)", self.threads)?;
        for (k, pin) in self.pinned.iter().enumerate() {
            match pin {
                Ok(cpu) => write!(f, "; worker {k} on CPU {cpu}")?,
                Err(why) => write!(f, "; worker {k} unpinned ({why})")?,
            }
        }
        Ok(())
    }
}

/// The pool (see the module doc).
#[derive(Debug)]
pub struct WorkerPool {
    hand: Arc<Hand>,
    workers: Vec<Worker>,
    /// A pass is running (a second caller runs inline).
    busy: AtomicBool,
    report: PoolReport,
}

/// Pins the calling thread to a CPU, or says why it could not (`sinew_protocol::rt::realtime::pin_this_thread`
/// in the server).
pub type PinFn = fn(usize) -> Result<(), String>;

impl WorkerPool {
    /// A pool where `threads` threads run chunks: the caller and `threads - 1` workers, worker `k` pinned to
    /// CPU `(1 + k) % cpus` by `pin` when given (a refused pin is reported and the worker runs unpinned).
    pub fn new(threads: usize, pin: Option<PinFn>) -> std::io::Result<Self> {
        let hand = Arc::new(Hand::default());
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let mut workers = Vec::new();
        let mut pinned = Vec::new();
        for k in 0..threads.saturating_sub(1) {
            let cpu = (1 + k) % cpus;
            let (pin_tx, pin_rx) = std::sync::mpsc::sync_channel(1);
            let sleeping = Arc::new(AtomicBool::new(false));
            let (theirs, flag) = (hand.clone(), sleeping.clone());
            let handle = std::thread::Builder::new()
                .name(format!("sinew-work-{k}"))
                .spawn(move || {
                    let outcome = match pin {
                        Some(pin) => pin(cpu).map(|()| cpu),
                        None => Err("not asked".to_owned()),
                    };
                    let _ = pin_tx.send(outcome);
                    work(&theirs, &flag);
                })?;
            pinned.push(
                pin_rx
                    .recv()
                    .unwrap_or_else(|_| Err("the worker ended at start".to_owned())),
            );
            workers.push(Worker {
                thread: handle.thread().clone(),
                sleeping,
                handle: Some(handle),
            });
        }
        Ok(Self {
            hand,
            workers,
            busy: AtomicBool::new(false),
            report: PoolReport {
                threads: threads.max(1),
                pinned,
            },
        })
    }

    /// What the pool was given.
    pub fn report(&self) -> &PoolReport {
        &self.report
    }
}

/// A worker's life: wait for a pass (spin, then park), help with it, repeat until shut down.
fn work(hand: &Hand, sleeping: &AtomicBool) {
    let mut seen = 0u64;
    let mut idle_since = Instant::now();
    let mut spins = 0u32;
    loop {
        if hand.shutdown.load(Ordering::Acquire) {
            return;
        }
        let epoch = hand.board.epoch();
        if epoch != seen {
            seen = epoch;
            // Read after the epoch: the caller stores the job before it publishes the epoch.
            let job_ptr = hand.job.load(Ordering::Acquire);
            while let Some(c) = hand.board.claim(epoch) {
                // SAFETY: the claim succeeded for pass `epoch`, so that pass is still running: its caller
                // is inside `run`, which does not return (nor let its stack-held job go) until this chunk has
                // counted done. `job_ptr` was read after the epoch was seen, and the caller stores a new job
                // only after the previous pass's chunks are all claimed and done (so not while this claim
                // could succeed: the board checks epoch, count and index in one word): it points at this
                // pass's job.
                let job: Job<'_> = unsafe { *(job_ptr as *const Job<'_>) };
                hand.run_chunk(job, c);
            }
            idle_since = Instant::now();
            spins = 0;
            continue;
        }
        spins = spins.wrapping_add(1);
        if !spins.is_multiple_of(64) || idle_since.elapsed() < SPIN_AFTER_WORK {
            std::hint::spin_loop();
            continue;
        }
        sleeping.store(true, Ordering::SeqCst);
        // Re-check after saying so: the caller bumps the epoch, then looks for sleepers (both SeqCst), so
        // either it sees this flag and unparks, or this sees the new epoch.
        if hand.board.epoch() == seen && !hand.shutdown.load(Ordering::SeqCst) {
            std::thread::park();
        }
        sleeping.store(false, Ordering::SeqCst);
        idle_since = Instant::now();
    }
}

// SAFETY: the board hands each index of a pass out once (one compare-and-swap per index, on a word that also
// holds the pass's epoch and chunk count), and `run` returns only after the board has counted every chunk done.
unsafe impl ChunkRunner for WorkerPool {
    fn run(&self, chunks: usize, job: &(dyn Fn(usize) + Sync)) {
        if chunks == 0 {
            return;
        }
        if self.workers.is_empty()
            || chunks == 1
            || chunks > MAX_CHUNKS
            || self.busy.swap(true, Ordering::Acquire)
        {
            Inline.run(chunks, job);
            return;
        }
        let hand = &*self.hand;
        let job_ref: Job<'_> = job;
        hand.job
            .store(&job_ref as *const Job<'_> as *mut (), Ordering::Release);
        let epoch = hand.board.open(chunks);
        for worker in &self.workers {
            if worker.sleeping.load(Ordering::SeqCst) {
                worker.thread.unpark();
            }
        }
        // Work too; a panic in our own chunk waits for the workers before it unwinds (they hold the job).
        let mut own_panic = None;
        while let Some(c) = hand.board.claim(epoch) {
            if let Err(payload) = catch_unwind(AssertUnwindSafe(|| job(c))) {
                own_panic.get_or_insert(payload);
            }
            hand.board.finish_chunk();
        }
        let mut waits = 0u32;
        while !hand.board.finished(chunks) {
            waits = waits.wrapping_add(1);
            if waits.is_multiple_of(1024) {
                // A worker was preempted mid-chunk: let the scheduler run it.
                std::thread::yield_now();
            } else {
                std::hint::spin_loop();
            }
        }
        let worker_panicked = hand.panicked.swap(false, Ordering::AcqRel);
        self.busy.store(false, Ordering::Release);
        if let Some(payload) = own_panic {
            resume_unwind(payload);
        }
        if worker_panicked {
            panic!("a tissue worker's chunk panicked (see its message above)");
        }
    }

    fn threads(&self) -> usize {
        self.report.threads
    }

    /// Wake parked workers, so they are spinning when the tick's first pass comes (a wake takes tens of
    /// microseconds on a VM).
    fn prepare(&self) {
        for worker in &self.workers {
            if worker.sleeping.load(Ordering::SeqCst) {
                worker.thread.unpark();
            }
        }
    }
}

impl Drop for WorkerPool {
    fn drop(&mut self) {
        self.hand.shutdown.store(true, Ordering::SeqCst);
        for worker in &mut self.workers {
            worker.thread.unpark();
            if let Some(handle) = worker.handle.take() {
                let _ = handle.join();
            }
        }
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)] // test code

    use super::*;
    use crate::for_chunks_mut;

    #[test]
    fn every_chunk_runs_once_per_pass_whatever_the_thread_count() {
        for threads in [1, 2, 3, 5] {
            let pool = WorkerPool::new(threads, None).unwrap();
            assert_eq!(pool.threads(), threads);
            let mut out = vec![0u32; 1000];
            for pass in 0..200u32 {
                // Alternate short and long passes, and pauses long enough for the workers to park.
                if pass % 50 == 49 {
                    std::thread::sleep(SPIN_AFTER_WORK * 3);
                }
                let chunk = if pass % 2 == 0 { 7 } else { 64 };
                for_chunks_mut(&pool, &mut out, chunk, |c, part| {
                    for (k, x) in part.iter_mut().enumerate() {
                        *x += (c * chunk + k) as u32;
                    }
                });
            }
            for (i, x) in out.iter().enumerate() {
                assert_eq!(*x, 200 * i as u32, "item {i} with {threads} threads");
            }
        }
    }

    #[test]
    fn the_workers_really_take_chunks() {
        let pool = WorkerPool::new(2, None).unwrap();
        let here = std::thread::current().id();
        let mut elsewhere = false;
        for _ in 0..200 {
            let mut ran_on = vec![here; 64];
            for_chunks_mut(&pool, &mut ran_on, 1, |_, slot| {
                // Slow chunks, so the caller cannot take them all before a worker wakes.
                let t = Instant::now();
                while t.elapsed() < Duration::from_micros(20) {}
                slot[0] = std::thread::current().id();
            });
            if ran_on.iter().any(|id| *id != here) {
                elsewhere = true;
                break;
            }
        }
        assert!(elsewhere, "no chunk ever ran on a worker");
    }

    #[test]
    fn a_panicking_chunk_panics_the_caller_after_the_pass_and_the_pool_goes_on() {
        let pool = WorkerPool::new(2, None).unwrap();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            pool.run(32, &|c| {
                assert!(c != 17, "chunk 17 fails");
            });
        }));
        assert!(outcome.is_err());
        let mut out = vec![0u8; 100];
        for_chunks_mut(&pool, &mut out, 10, |_, part| part.fill(1));
        assert!(out.iter().all(|&x| x == 1));
    }

    #[test]
    fn pinned_workers_say_where_they_run() {
        let pool = WorkerPool::new(2, Some(|_cpu| Ok(()))).unwrap();
        assert_eq!(pool.report().pinned.len(), 1);
        assert!(pool.report().to_string().starts_with("2 tissue thread(s)"));
        let unpinned = WorkerPool::new(2, None).unwrap();
        assert!(
            unpinned
                .report()
                .to_string()
                .contains("unpinned (not asked)")
        );
    }
}
