//! The hapticserver's monotonic clock: nanoseconds since the server started.
//!
//! Owns: [`MonotonicClock`], shared (it is `Copy`) by the device loop, which stamps poses with it, and the
//! force callback, which stamps arrivals with it, so round trips and staleness are measured on one clock.
//!
//! Must not: be used for wall-clock time or be compared across processes (the server only echoes it back).

use std::time::Instant;

/// Monotonic time since a fixed start.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock {
    start: Instant,
}

impl MonotonicClock {
    /// A clock whose zero is now.
    pub fn start() -> Self {
        Self {
            start: Instant::now(),
        }
    }

    /// Nanoseconds since the start. Real-time safe: no allocation, never panics (saturates after 584 years).
    pub fn now_ns(&self) -> u64 {
        u64::try_from(self.start.elapsed().as_nanos()).unwrap_or(u64::MAX)
    }
}

/// Nanoseconds to seconds.
pub fn ns_to_s(ns: u64) -> f64 {
    ns as f64 * 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clock_is_monotonic() {
        let clock = MonotonicClock::start();
        let a = clock.now_ns();
        let b = clock.now_ns();
        assert!(b >= a);
        assert_eq!(ns_to_s(1_500_000_000), 1.5);
    }
}
