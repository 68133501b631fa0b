//! Regression for issue 30's defect: under oversubscription (more pool threads than cores) one chunk of a pass
//! ran twice. Many passes of changing length (a short pass followed by a longer one is what exposed it), at 2
//! to 8 threads on whatever cores the machine has, each chunk's runs counted one by one.
#![cfg(not(loom))]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::sync::atomic::{AtomicU32, Ordering};

use sinew_parallel::{ChunkRunner, WorkerPool, for_chunks_mut};

/// Chunk counts cycled through, short and long passes mixed.
const LENGTHS: [usize; 6] = [1, 16, 2, 143, 3, 64];

#[test]
fn every_chunk_of_every_pass_runs_exactly_once_with_more_threads_than_cores() {
    let passes = 20_000;
    let runs: Vec<AtomicU32> = (0..256).map(|_| AtomicU32::new(0)).collect();
    for threads in 2..=8 {
        let pool = WorkerPool::new(threads, None).unwrap();
        for pass in 0..passes {
            let chunks = LENGTHS[pass % LENGTHS.len()];
            pool.run(chunks, &|c| {
                runs[c].fetch_add(1, Ordering::Relaxed);
            });
            for (c, n) in runs.iter().enumerate() {
                let n = n.swap(0, Ordering::Relaxed);
                let expected = u32::from(c < chunks);
                assert_eq!(
                    n, expected,
                    "chunk {c} ran {n} times in pass {pass} of {chunks} chunks with {threads} threads"
                );
            }
        }
    }
}

#[test]
fn every_item_is_written_by_its_own_chunk_once_per_pass_with_more_threads_than_cores() {
    let passes = 5_000u32;
    for threads in [2, 5, 8] {
        let pool = WorkerPool::new(threads, None).unwrap();
        let mut out = vec![0u32; 1000];
        for pass in 0..passes {
            let chunk_len = if pass % 2 == 0 { 7 } else { 64 };
            for_chunks_mut(&pool, &mut out, chunk_len, |c, part| {
                for (k, x) in part.iter_mut().enumerate() {
                    *x += (c * chunk_len + k) as u32;
                }
            });
        }
        for (i, x) in out.iter().enumerate() {
            assert_eq!(*x, passes * i as u32, "item {i} with {threads} threads");
        }
    }
}
