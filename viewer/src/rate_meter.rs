//! Per-second rates from monotonically growing counters.
//!
//! Owns: turning "total so far" counters into "per second over the last second". Must not: read clocks itself
//! (the caller passes `now`, so tests run on virtual time), allocate, or block.

use std::time::{Duration, Instant};

/// Rate of one growing counter, refreshed once per window.
#[derive(Debug, Clone, Copy)]
pub struct RateMeter {
    window: Duration,
    window_start: Option<Instant>,
    count_at_start: u64,
    per_s: f64,
}

impl RateMeter {
    /// A meter that refreshes its rate every `window`.
    pub fn new(window: Duration) -> Self {
        Self {
            window,
            window_start: None,
            count_at_start: 0,
            per_s: 0.0,
        }
    }

    /// Feed the counter's current total at `now`. Refreshes the rate when a window has passed.
    pub fn update(&mut self, now: Instant, total: u64) {
        let Some(start) = self.window_start else {
            self.window_start = Some(now);
            self.count_at_start = total;
            return;
        };
        let elapsed = now.saturating_duration_since(start);
        if elapsed >= self.window {
            let grown = total.saturating_sub(self.count_at_start);
            self.per_s = grown as f64 / elapsed.as_secs_f64();
            self.window_start = Some(now);
            self.count_at_start = total;
        }
    }

    /// Events per second over the last complete window (0 before the first).
    pub fn per_s(&self) -> f64 {
        self.per_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rate_over_virtual_time() {
        let t0 = Instant::now();
        let mut meter = RateMeter::new(Duration::from_secs(1));
        meter.update(t0, 100);
        meter.update(t0 + Duration::from_millis(500), 130);
        assert_eq!(meter.per_s(), 0.0);
        meter.update(t0 + Duration::from_secs(1), 160);
        assert!((meter.per_s() - 60.0).abs() < 1e-9);
        meter.update(t0 + Duration::from_secs(3), 160);
        assert_eq!(meter.per_s(), 0.0);
    }
}
