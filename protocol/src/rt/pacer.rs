//! Fixed-rate pacing for 1 kHz loops.

use std::time::{Duration, Instant};

/// Paces a loop at a fixed period against absolute deadlines, with spin_sleep (sub-microsecond accuracy).
///
/// If the loop falls more than one whole period behind (a VM stall), the missed periods are counted as
/// overruns and the schedule restarts from now: it never bursts ticks to catch up, which would hand a device
/// a flurry of stale forces.
#[derive(Debug)]
pub struct Pacer {
    period: Duration,
    next: Instant,
    sleeper: spin_sleep::SpinSleeper,
    overruns: u64,
    last_wake: Option<Instant>,
}

impl Pacer {
    /// A pacer with the given period, starting now. `spin_native_accuracy_ns` is how long before a deadline
    /// spin_sleep stops sleeping and spins (100 us spins well on these machines; 0 means plain sleep only,
    /// for tests that run many loops on two cores).
    pub fn new(period: Duration, spin_native_accuracy_ns: u32) -> Self {
        Self {
            period,
            next: Instant::now() + period,
            sleeper: spin_sleep::SpinSleeper::new(spin_native_accuracy_ns)
                .with_spin_strategy(spin_sleep::SpinStrategy::YieldThread),
            overruns: 0,
            last_wake: None,
        }
    }

    /// The loop period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Sleep until the next deadline. Returns the actual interval since the previous wake (None on the first).
    /// Never allocates.
    pub fn wait(&mut self) -> Option<Duration> {
        let now = Instant::now();
        if self.next > now {
            self.sleeper.sleep(self.next - now);
        }
        let woke = Instant::now();
        let late = woke.saturating_duration_since(self.next);
        if late > self.period {
            self.overruns += (late.as_nanos() / self.period.as_nanos().max(1)) as u64;
            self.next = woke + self.period;
        } else {
            self.next += self.period;
        }
        let interval = self.last_wake.map(|last| woke - last);
        self.last_wake = Some(woke);
        interval
    }

    /// Move the next deadline (and every one after it) by `ns`: later when positive. A loop aligning its phase
    /// with another's calls this with small steps; a shift is bounded to half a period.
    pub fn shift_ns(&mut self, ns: i64) {
        let half = i64::try_from(self.period.as_nanos() / 2).unwrap_or(i64::MAX);
        let ns = ns.clamp(-half, half);
        let by = Duration::from_nanos(ns.unsigned_abs());
        if ns >= 0 {
            self.next += by;
        } else {
            // The next deadline was at least one period after the previous wake: half a period back stays
            // after it.
            self.next = self.next.checked_sub(by).unwrap_or(self.next);
        }
    }

    /// Periods skipped because the loop ran late.
    pub fn overruns(&self) -> u64 {
        self.overruns
    }
}
