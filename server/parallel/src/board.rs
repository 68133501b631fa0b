//! The hand-off of one pass between the thread that asks for it and the workers that help: which pass is
//! current, which of its chunks is next, and how many are done.
//!
//! Owns: [`Board`], one 64-bit word holding the pass's epoch (high 32 bits), its chunk count (16 bits) and the
//! next unclaimed chunk (low 16 bits), and the done counter. A claim reads that one word and advances it with
//! one compare-and-swap, so it succeeds only for the pass that is current, and only for a chunk that pass has.
//!
//! Why the count lives in the word (the defect of issue 30): it used to be a separate atomic, stored before the
//! new epoch. A worker still in its claim loop for the finished pass `e` could read `e`'s exhausted index, then
//! the next pass's larger count, and win its compare-and-swap on `e`'s word (not yet bumped): it ran a chunk
//! of the next pass under the old epoch, and that chunk was claimed again once the pass opened. One chunk ran
//! twice: a spring block's forces were added twice, and two threads held the same `&mut` sub-slice. The
//! model check below (`--cfg loom`) explores every interleaving of a caller and a worker over two passes.
//!
//! Must not: know what a chunk does, or wait (the pool decides how to spin, yield and park).

#[cfg(loom)]
use loom::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
#[cfg(not(loom))]
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// The most chunks one pass may have (a pass with more runs inline).
pub const MAX_CHUNKS: usize = 0xffff;

const FIELD_MASK: u64 = 0xffff;
const EPOCH_MASK: u64 = 0xffff_ffff;

/// The current pass, its claims and its completions (see the module doc).
#[derive(Debug, Default)]
pub struct Board {
    /// Epoch << 32 | chunks << 16 | next.
    state: AtomicU64,
    /// Chunks of the current pass that have finished.
    done: AtomicUsize,
}

impl Board {
    /// Open a pass of `chunks` chunks (`1..=MAX_CHUNKS`) and return its epoch. The caller must have seen the
    /// previous pass [`finished`](Self::finished): then every claim of it has been made and counted.
    pub fn open(&self, chunks: usize) -> u64 {
        debug_assert!((1..=MAX_CHUNKS).contains(&chunks));
        // Ordered before the state below: a worker counts done only after a claim that read the new state.
        self.done.store(0, Ordering::Release);
        let mut epoch = ((self.state.load(Ordering::Acquire) >> 32) + 1) & EPOCH_MASK;
        if epoch == 0 {
            // 0 is the board before its first pass, which a new worker has already "seen".
            epoch = 1;
        }
        let chunks = (chunks as u64).min(FIELD_MASK);
        self.state
            .store(epoch << 32 | chunks << 16, Ordering::SeqCst);
        epoch
    }

    /// The current pass's epoch (0 before the first).
    pub fn epoch(&self) -> u64 {
        self.state.load(Ordering::SeqCst) >> 32
    }

    /// Claim the next chunk of pass `epoch`, if that pass is still current and has one left.
    pub fn claim(&self, epoch: u64) -> Option<usize> {
        let mut state = self.state.load(Ordering::Acquire);
        loop {
            let next = state & FIELD_MASK;
            if state >> 32 != epoch || next >= (state >> 16) & FIELD_MASK {
                return None;
            }
            match self.state.compare_exchange_weak(
                state,
                state + 1,
                Ordering::AcqRel,
                Ordering::Acquire,
            ) {
                Ok(_) => return Some(next as usize),
                Err(now) => state = now,
            }
        }
    }

    /// Count one claimed chunk of the current pass done.
    pub fn finish_chunk(&self) {
        self.done.fetch_add(1, Ordering::AcqRel);
    }

    /// Every one of the current pass's `chunks` chunks is done (what each did is visible to the caller).
    pub fn finished(&self, chunks: usize) -> bool {
        self.done.load(Ordering::Acquire) >= chunks
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    #[test]
    fn a_pass_hands_out_each_of_its_chunks_once() {
        let board = Board::default();
        let epoch = board.open(3);
        let claimed: Vec<_> = std::iter::from_fn(|| board.claim(epoch)).collect();
        assert_eq!(claimed, vec![0, 1, 2]);
        assert!(!board.finished(3));
        (0..3).for_each(|_| board.finish_chunk());
        assert!(board.finished(3));
    }

    /// The interleaving that ran a chunk twice (issue 30), step by step: a worker that saw the short pass
    /// claims nothing once it is exhausted, whether or not the next, longer pass has opened.
    #[test]
    fn a_worker_late_from_a_short_pass_claims_nothing_of_the_next_longer_one() {
        let board = Board::default();
        let short = board.open(1);
        assert_eq!(board.claim(short), Some(0));
        board.finish_chunk();
        assert!(board.finished(1));
        assert_eq!(board.claim(short), None, "the short pass is exhausted");
        let long = board.open(16);
        assert_eq!(
            board.claim(short),
            None,
            "an old epoch claims nothing of the new pass"
        );
        let claimed: Vec<_> = std::iter::from_fn(|| board.claim(long)).collect();
        assert_eq!(claimed, (0..16).collect::<Vec<_>>());
    }

    #[test]
    fn epochs_skip_zero_when_they_wrap() {
        let board = Board::default();
        board.state.store(EPOCH_MASK << 32, Ordering::SeqCst);
        assert_eq!(board.open(2), 1);
        assert_eq!(board.claim(1), Some(0));
    }
}

/// Model check: every interleaving of a caller running two passes (1 chunk, then 2) and a worker helping.
/// Run with `RUSTFLAGS="--cfg loom" cargo test -p sinew-parallel --release --target-dir target/loom board`
/// (`.ci/run` does). Before the fix it found the double run in a few hundred interleavings.
#[cfg(all(test, loom))]
mod loom_tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)] // test code

    use super::*;
    use loom::sync::Arc;
    use loom::sync::atomic::AtomicBool;
    use loom::thread;

    /// Chunk counts of the passes, in order (epochs 1, 2, ...).
    const PASSES: [usize; 2] = [1, 2];

    /// Each (pass, chunk) ran exactly once, and only chunks the pass has.
    #[derive(Default)]
    struct Runs([AtomicUsize; 4]);

    impl Runs {
        fn record(&self, epoch: u64, chunk: usize) {
            let pass = epoch as usize - 1;
            assert!(
                chunk < PASSES[pass],
                "pass {pass} has no chunk {chunk}: claimed under an old epoch"
            );
            let slot = PASSES[..pass].iter().sum::<usize>() + chunk;
            let before = self.0[slot].fetch_add(1, Ordering::SeqCst);
            assert_eq!(before, 0, "chunk {chunk} of pass {pass} ran twice");
        }
    }

    #[test]
    fn every_chunk_of_every_pass_runs_exactly_once() {
        let mut model = loom::model::Builder::new();
        // Bounded, as loom advises: unbounded, the yield loops do not finish. The old hand-off failed at 3.
        model.preemption_bound = Some(3);
        model.check(|| {
            let board = Arc::new(Board::default());
            let runs = Arc::new(Runs::default());
            let stop = Arc::new(AtomicBool::new(false));
            let worker = {
                let (board, runs, stop) = (board.clone(), runs.clone(), stop.clone());
                thread::spawn(move || {
                    let mut seen = 0;
                    while !stop.load(Ordering::SeqCst) {
                        let epoch = board.epoch();
                        if epoch == seen {
                            thread::yield_now();
                            continue;
                        }
                        seen = epoch;
                        while let Some(c) = board.claim(epoch) {
                            runs.record(epoch, c);
                            board.finish_chunk();
                        }
                    }
                })
            };
            for chunks in PASSES {
                let epoch = board.open(chunks);
                while let Some(c) = board.claim(epoch) {
                    runs.record(epoch, c);
                    board.finish_chunk();
                }
                while !board.finished(chunks) {
                    thread::yield_now();
                }
            }
            stop.store(true, Ordering::SeqCst);
            worker.join().unwrap();
            for (slot, n) in runs.0.iter().enumerate().take(PASSES.iter().sum()) {
                assert_eq!(n.load(Ordering::SeqCst), 1, "slot {slot}");
            }
        });
    }
}
