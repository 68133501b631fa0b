//! Chunked passes: the [`ChunkRunner`] seam, its sequential implementation [`Inline`], and the helpers that hand
//! each chunk its own disjoint slice of an output buffer ([`for_chunks_mut`], [`for_chunks_mut2`]).
//!
//! Must not: allocate, lock, or block inside a pass (a runner that is already busy runs the pass inline).
#![allow(unsafe_code)] // the slice helpers split a buffer between threads; each block says why it is sound

/// Runs `job(c)` for every chunk index `c` in `0..chunks`.
///
/// # Safety
/// An implementation must call `job` exactly once for each index in `0..chunks` (never twice, never skip
/// one), and return only after every call has returned. The slice helpers below rely on it: they give chunk
/// `c` a `&mut` to its own part of a buffer, which is sound only if no two calls share an index.
pub unsafe trait ChunkRunner: Send + Sync + std::fmt::Debug {
    /// Run every chunk (possibly concurrently, in any order) and return when all are done. A panic in a chunk
    /// is re-raised on the calling thread once the others have finished.
    fn run(&self, chunks: usize, job: &(dyn Fn(usize) + Sync));

    /// Threads that may run chunks at once, the caller included (1 for [`Inline`]).
    fn threads(&self) -> usize;

    /// A hint that passes are coming soon (the start of a tick): idle threads may get ready. Changes no result.
    fn prepare(&self) {}
}

/// Every chunk in order on the calling thread.
#[derive(Debug, Default, Clone, Copy)]
pub struct Inline;

// SAFETY: each index once, in order, on this thread, and `run` returns after the last.
unsafe impl ChunkRunner for Inline {
    fn run(&self, chunks: usize, job: &(dyn Fn(usize) + Sync)) {
        for c in 0..chunks {
            job(c);
        }
    }

    fn threads(&self) -> usize {
        1
    }
}

/// Scratch buffers a `&self` pass writes (the spring kernel's padded copies, say), shareable between threads
/// so a model can be read by several at once (each tool's contact solve on its own worker). A pass takes the
/// buffers with a `try_lock` that never waits; should another thread hold them (two passes on one model at
/// once, which the tick never does) it works in fresh buffers instead: slower, allocating, the same result,
/// since scratch never carries anything from one pass to the next. A clone starts with empty buffers.
#[derive(Debug, Default)]
pub struct ScratchCell<T>(std::sync::Mutex<T>);

impl<T: Default> ScratchCell<T> {
    /// Run `pass` with the buffers.
    pub fn with<R>(&self, pass: impl FnOnce(&mut T) -> R) -> R {
        match self.0.try_lock() {
            Ok(mut buffers) => pass(&mut buffers),
            // A pass that panicked holding them left buffers, not results: keep using them.
            Err(std::sync::TryLockError::Poisoned(poisoned)) => pass(&mut poisoned.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => pass(&mut T::default()),
        }
    }
}

impl<T: Default> Clone for ScratchCell<T> {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// The number of chunks of `chunk_len` items that cover `len` items (the last may be short).
pub fn chunk_count(len: usize, chunk_len: usize) -> usize {
    len.div_ceil(chunk_len.max(1))
}

/// The item range of chunk `c`.
pub fn chunk_range(c: usize, len: usize, chunk_len: usize) -> std::ops::Range<usize> {
    let chunk_len = chunk_len.max(1);
    let start = (c * chunk_len).min(len);
    start..(start + chunk_len).min(len)
}

/// A raw pointer that may cross threads: only ever turned back into disjoint sub-slices (see the helpers).
#[derive(Clone, Copy)]
struct SharedMut<T>(*mut T);
// SAFETY: the pointer is only dereferenced as the disjoint chunk slices the runner contract guarantees, and
// `T: Send` makes handing each slice to another thread sound.
unsafe impl<T: Send> Send for SharedMut<T> {}
// SAFETY: as above: no two threads ever reach the same element through it.
unsafe impl<T: Send> Sync for SharedMut<T> {}

impl<T> SharedMut<T> {
    /// Chunk `range` of the buffer this points into.
    ///
    /// # Safety
    /// `range` must lie inside the buffer, and no other live reference may overlap it.
    #[allow(clippy::mut_from_ref)] // the point of the type: disjoint `&mut` chunks from a shared handle
    unsafe fn slice(&self, range: std::ops::Range<usize>) -> &mut [T] {
        // SAFETY: the caller's contract (in bounds, not aliased).
        unsafe { std::slice::from_raw_parts_mut(self.0.add(range.start), range.len()) }
    }
}

/// `job(c, chunk)` for each chunk of `chunk_len` items of `out`, chunk `c` being `out[chunk_range(c, ..)]`.
pub fn for_chunks_mut<T: Send>(
    runner: &dyn ChunkRunner,
    out: &mut [T],
    chunk_len: usize,
    job: impl Fn(usize, &mut [T]) + Sync,
) {
    let len = out.len();
    let base = SharedMut(out.as_mut_ptr());
    let each = |c: usize| {
        let range = chunk_range(c, len, chunk_len);
        // SAFETY: chunk ranges are disjoint and inside `out` (which stays mutably borrowed for this whole
        // call), and the runner contract gives each `c` to exactly one call.
        let part = unsafe { base.slice(range) };
        job(c, part);
    };
    runner.run(chunk_count(len, chunk_len), &each);
}

/// [`for_chunks_mut`] over two buffers of the same length, chunked alike (positions and velocities, say):
/// `job(c, a_chunk, b_chunk)`. Items past the shorter buffer's end are not visited.
pub fn for_chunks_mut2<A: Send, B: Send>(
    runner: &dyn ChunkRunner,
    a: &mut [A],
    b: &mut [B],
    chunk_len: usize,
    job: impl Fn(usize, &mut [A], &mut [B]) + Sync,
) {
    let len = a.len().min(b.len());
    let (base_a, base_b) = (SharedMut(a.as_mut_ptr()), SharedMut(b.as_mut_ptr()));
    let each = |c: usize| {
        let range = chunk_range(c, len, chunk_len);
        // SAFETY: as in `for_chunks_mut`, for each buffer: disjoint ranges, inside both, one call per `c`.
        let (part_a, part_b) = unsafe { (base_a.slice(range.clone()), base_b.slice(range)) };
        job(c, part_a, part_b);
    };
    runner.run(chunk_count(len, chunk_len), &each);
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_every_item_once() {
        for (len, chunk_len) in [(0, 4), (1, 4), (4, 4), (9, 4), (10, 3)] {
            let mut seen = vec![0u32; len];
            for c in 0..chunk_count(len, chunk_len) {
                for i in chunk_range(c, len, chunk_len) {
                    seen[i] += 1;
                }
            }
            assert!(
                seen.iter().all(|&n| n == 1),
                "{len} items in chunks of {chunk_len}"
            );
        }
    }

    #[test]
    fn inline_fills_each_chunk_with_its_index() {
        let (mut a, mut b) = (vec![0usize; 10], vec![0.0f32; 10]);
        for_chunks_mut2(&Inline, &mut a, &mut b, 3, |c, a, b| {
            a.fill(c);
            b.fill(c as f32 * 0.5);
        });
        assert_eq!(a, vec![0, 0, 0, 1, 1, 1, 2, 2, 2, 3]);
        assert_eq!(b[9], 1.5);
    }
}
