//! sinew-parallel: data-parallel passes over fixed chunks, with results that do not depend on how many threads
//! ran them, and the pinned worker pool that runs them.
//!
//! Owns: the [`ChunkRunner`] seam the tissue passes are written against and its helpers ([`chunks`]), the
//! hand-off of a pass between threads ([`board`], model-checked with loom), and [`WorkerPool`] ([`pool`]). The
//! server's simulation core takes a `&dyn ChunkRunner` and stays free of threads; its node layer builds the pool.
//!
//! The determinism rule every pass keeps: a chunk is a fixed range of items (springs, nodes), cut by a fixed
//! chunk length that depends on nothing but the data; each chunk's result is written to its own slot; anything
//! combined across chunks is combined afterwards, in chunk order, by one thread. So 1 thread and N threads
//! produce the same bits, and who ran which chunk, or when, never shows.
//!
//! Must not: know about tissue, zenoh or the world file.
#![warn(missing_docs)]

pub mod board;
pub mod chunks;
pub mod pool;

pub use chunks::{
    ChunkRunner, Inline, ScratchCell, chunk_count, chunk_range, for_chunks_mut, for_chunks_mut2,
};
pub use pool::{PinFn, PoolReport, WorkerPool};
