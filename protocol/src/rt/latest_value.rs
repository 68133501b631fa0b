//! Single-slot latest-value mailbox.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Holds the newest value written; readers take it if it is newer than what they saw.
///
/// Writers (zenoh callbacks) lock briefly to copy a `Copy` value in. The reader (a 1 kHz loop) only ever
/// `try_lock`s: it never blocks, and if a writer holds the slot at that instant it simply sees the value on its
/// next tick. No allocation anywhere.
#[derive(Debug, Default)]
pub struct LatestValue<T: Copy> {
    slot: Mutex<Option<T>>,
    writes: AtomicU64,
}

impl<T: Copy> LatestValue<T> {
    /// An empty mailbox.
    pub fn new() -> Self {
        Self {
            slot: Mutex::new(None),
            writes: AtomicU64::new(0),
        }
    }

    /// Replace the value. May block for the length of a copy if another writer or the reader holds it.
    pub fn store(&self, value: T) {
        let mut slot = match self.slot.lock() {
            Ok(slot) => slot,
            Err(poisoned) => poisoned.into_inner(),
        };
        *slot = Some(value);
        self.writes.fetch_add(1, Ordering::Release);
    }

    /// How many values were ever stored.
    pub fn writes(&self) -> u64 {
        self.writes.load(Ordering::Acquire)
    }

    /// The newest value if one was stored after `*seen` (a write count the caller keeps), updating `*seen`.
    /// Real-time safe: never blocks, never allocates.
    pub fn take_newer(&self, seen: &mut u64) -> Option<T> {
        let writes = self.writes.load(Ordering::Acquire);
        if writes == *seen {
            return None;
        }
        let slot = self.slot.try_lock().ok()?;
        let value = *slot;
        drop(slot);
        *seen = writes;
        value
    }

    /// The newest value, whatever was seen before. Never blocks (None if contended or empty).
    pub fn peek(&self) -> Option<T> {
        self.slot.try_lock().ok().and_then(|slot| *slot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reader_sees_only_newer_values() {
        let mailbox = LatestValue::new();
        let mut seen = 0;
        assert_eq!(mailbox.take_newer(&mut seen), None);
        mailbox.store(1u32);
        mailbox.store(2u32);
        assert_eq!(mailbox.take_newer(&mut seen), Some(2));
        assert_eq!(mailbox.take_newer(&mut seen), None);
        mailbox.store(3);
        assert_eq!(mailbox.take_newer(&mut seen), Some(3));
        assert_eq!(mailbox.peek(), Some(3));
    }

    #[test]
    fn concurrent_writers_and_reader_never_tear() {
        let mailbox = std::sync::Arc::new(LatestValue::new());
        let writers: Vec<_> = (0..2)
            .map(|w| {
                let mailbox = mailbox.clone();
                std::thread::spawn(move || {
                    for i in 0..20_000u64 {
                        mailbox.store([i + w, i + w, i + w]);
                    }
                })
            })
            .collect();
        let mut seen = 0;
        let mut reads = 0;
        while writers.iter().any(|w| !w.is_finished()) {
            if let Some(v) = mailbox.take_newer(&mut seen) {
                assert!(v[0] == v[1] && v[1] == v[2]);
                reads += 1;
            }
        }
        for w in writers {
            w.join().unwrap();
        }
        assert!(mailbox.writes() == 40_000);
        assert!(reads > 0 || mailbox.peek().is_some());
    }
}
