//! A lock-free log throttle: say a lasting condition once when it starts, then at most once a period, with
//! how many times it happened in between.
//!
//! The roles log what changes (a device refused, a server lost) once, and repeat a condition that lasts at
//! most every [`Throttle::period_ns`], so a log read an hour later shows the condition and its count, not
//! a thousand identical lines.

use std::sync::atomic::{AtomicU64, Ordering};

/// One throttled message.
#[derive(Debug)]
pub struct Throttle {
    period_ns: u64,
    last_ns: AtomicU64,
    since_last: AtomicU64,
}

impl Throttle {
    /// Speak at most once per `period_ns` (the first occurrence always speaks).
    pub const fn new(period_ns: u64) -> Self {
        Self {
            period_ns,
            last_ns: AtomicU64::new(u64::MAX),
            since_last: AtomicU64::new(0),
        }
    }

    /// The repeat period, ns.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// The condition happened at `now_ns` (any monotonic clock). `Some(n)` when it is to be logged now, with
    /// `n` the occurrences since the previous log line, this one included; `None` to stay quiet.
    pub fn hit(&self, now_ns: u64) -> Option<u64> {
        let count = self.since_last.fetch_add(1, Ordering::AcqRel) + 1;
        let last = self.last_ns.load(Ordering::Acquire);
        let due = last == u64::MAX || now_ns.saturating_sub(last) >= self.period_ns;
        if due
            && self
                .last_ns
                .compare_exchange(last, now_ns, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
        {
            let _ = self.since_last.fetch_sub(count, Ordering::AcqRel);
            return Some(count);
        }
        None
    }

    /// The condition ended: the next occurrence speaks at once.
    pub fn reset(&self) {
        self.last_ns.store(u64::MAX, Ordering::Release);
        self.since_last.store(0, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speaks_first_then_once_a_period_with_the_count() {
        let s = 1_000_000_000;
        let t = Throttle::new(10 * s);
        assert_eq!(t.hit(0), Some(1));
        for k in 1..10 {
            assert_eq!(t.hit(k * s), None);
        }
        assert_eq!(t.hit(10 * s), Some(10));
        assert_eq!(t.hit(11 * s), None);
        t.reset();
        assert_eq!(t.hit(12 * s), Some(1));
    }
}
