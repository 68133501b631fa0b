//! A counting global allocator for the no-allocation tests (included with `#[path]` by each test binary that
//! declares it): it forwards to `System` and counts allocations and reallocations while counting is on, for
//! every thread ([`count_all_threads`]) or for the calling thread alone ([`count_this_thread`], so a hand-off
//! to a thread that may allocate, such as the recorder's writer, does not count).
//!
//! "Every thread" leaves out the process's main thread: libtest's harness runs there and runs each test on a
//! thread of its own, and the harness allocates on its own schedule (its "has been running for over 60
//! seconds" notice did, in the middle of a counted window of a slow run).
#![allow(dead_code)] // each test binary uses its own subset
#![allow(unsafe_code)] // a global allocator implements the unsafe `GlobalAlloc`; this one only forwards

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Forwards to `System`, counting.
pub struct Counting;

static ALL_THREADS: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static THIS_THREAD: Cell<bool> = const { Cell::new(false) };
}

fn counting() -> bool {
    (ALL_THREADS.load(Ordering::Relaxed) && !on_main_thread())
        || THIS_THREAD.try_with(Cell::get).unwrap_or(false)
}

/// The calling thread is the process's main thread (the test harness's). Two system calls, no allocation.
fn on_main_thread() -> bool {
    // SAFETY: gettid and getpid take no arguments and cannot fail.
    unsafe { libc::gettid() == libc::getpid() }
}

// SAFETY: every method forwards to `System` with the caller's own arguments, so `System`'s guarantees hold;
// the counter is a relaxed atomic and the flag a const-initialised thread local (reading it never allocates).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if counting() {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if counting() {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations made on any thread while `work` runs.
pub fn count_all_threads(work: impl FnOnce()) -> u64 {
    ALLOCATIONS.store(0, Ordering::Relaxed);
    ALL_THREADS.store(true, Ordering::Relaxed);
    work();
    ALL_THREADS.store(false, Ordering::Relaxed);
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// Allocations made on the calling thread while `work` runs (other threads' do not count, unless a
/// [`count_all_threads`] runs at the same time: keep each binary's counting in one test function).
pub fn count_this_thread(work: impl FnOnce()) -> u64 {
    ALLOCATIONS.store(0, Ordering::Relaxed);
    THIS_THREAD.with(|c| c.set(true));
    work();
    THIS_THREAD.with(|c| c.set(false));
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// Panics unless the allocator is installed and counts (else a no-allocation test could not fail).
pub fn assert_counting_works() {
    let all = count_all_threads(|| drop(std::hint::black_box(vec![1u8; 64])));
    let here = count_this_thread(|| drop(std::hint::black_box(vec![1u8; 64])));
    assert!(all > 0 && here > 0, "the counting allocator is not in use");
}

/// Run the tests of a binary that counts across all threads one at a time: hold the guard for the test.
pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SERIAL
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}
