//! How still the hand and the force were over the last whole second: the stability figures of a hold, kept
//! live by the device loop for reports and the demo's summary.
//!
//! Owns: a tumbling one-second window of the rendered force's per-axis range, the stylus speed's mean square
//! and the mean force magnitude, and the figures of the last completed window. Fixed size; no allocation.

/// Figures of one completed window.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StillnessFigures {
    /// Largest peak-to-peak of a rendered force component, N.
    pub force_p2p_n: f32,
    /// RMS stylus speed, mm/s.
    pub speed_rms_mm_s: f32,
    /// Mean rendered force magnitude, N.
    pub mean_force_n: f32,
    /// Ticks in the window (0: no window completed yet).
    pub ticks: u32,
}

impl StillnessFigures {
    /// The latency acceptance's hold rule: force peak-to-peak < 0.05 N and stylus speed RMS < 1 mm/s.
    pub fn still(&self) -> bool {
        self.ticks > 0 && self.force_p2p_n < 0.05 && self.speed_rms_mm_s < 1.0
    }
}

/// The running window.
#[derive(Debug, Clone, Copy)]
pub struct Stillness {
    window_s: f64,
    start_s: Option<f64>,
    lo_n: [f32; 3],
    hi_n: [f32; 3],
    speed2_sum: f64,
    force_sum_n: f64,
    ticks: u32,
    last: StillnessFigures,
}

impl Default for Stillness {
    fn default() -> Self {
        Self::new(1.0)
    }
}

impl Stillness {
    /// Windows of `window_s` seconds.
    pub fn new(window_s: f64) -> Self {
        Self {
            window_s,
            start_s: None,
            lo_n: [f32::MAX; 3],
            hi_n: [f32::MIN; 3],
            speed2_sum: 0.0,
            force_sum_n: 0.0,
            ticks: 0,
            last: StillnessFigures::default(),
        }
    }

    /// Account one tick's rendered force and stylus velocity at `now_s`. Non-finite input is skipped.
    pub fn push(&mut self, now_s: f64, force_n: [f32; 3], velocity_mm_s: [f32; 3]) {
        if !now_s.is_finite() || !force_n.iter().chain(&velocity_mm_s).all(|v| v.is_finite()) {
            return;
        }
        let start = *self.start_s.get_or_insert(now_s);
        if now_s - start >= self.window_s && self.ticks > 0 {
            let n = f64::from(self.ticks);
            self.last = StillnessFigures {
                force_p2p_n: (0..3)
                    .map(|i| self.hi_n[i] - self.lo_n[i])
                    .fold(0.0, f32::max),
                speed_rms_mm_s: (self.speed2_sum / n).sqrt() as f32,
                mean_force_n: (self.force_sum_n / n) as f32,
                ticks: self.ticks,
            };
            *self = Self {
                start_s: Some(now_s),
                last: self.last,
                ..Self::new(self.window_s)
            };
        }
        for ((lo, hi), f) in self.lo_n.iter_mut().zip(&mut self.hi_n).zip(force_n) {
            *lo = lo.min(f);
            *hi = hi.max(f);
        }
        let speed2: f32 = velocity_mm_s.iter().map(|v| v * v).sum();
        self.speed2_sum += f64::from(speed2);
        self.force_sum_n += f64::from(force_n.iter().map(|f| f * f).sum::<f32>().sqrt());
        self.ticks += 1;
    }

    /// The last completed window.
    pub fn last(&self) -> StillnessFigures {
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_hold_is_still_and_a_chattering_one_is_not() {
        let mut meter = Stillness::new(1.0);
        assert!(!meter.last().still(), "no window yet");
        for tick in 0..2001 {
            meter.push(tick as f64 * 1e-3, [0.0, 0.0, 0.8], [0.0, 0.0, 0.1]);
        }
        let still = meter.last();
        assert!(still.still(), "{still:?}");
        assert!((still.mean_force_n - 0.8).abs() < 1e-4);
        assert_eq!(still.ticks, 1000);
        for tick in 2001..4001 {
            let chatter = if tick % 2 == 0 { 0.0 } else { 3.3 };
            meter.push(tick as f64 * 1e-3, [0.0, 0.0, chatter], [0.0, 0.0, 40.0]);
        }
        let chattering = meter.last();
        assert!(!chattering.still());
        assert!(
            (chattering.force_p2p_n - 3.3).abs() < 1e-4,
            "{chattering:?}"
        );
        assert!((chattering.speed_rms_mm_s - 40.0).abs() < 1e-3);
    }

    #[test]
    fn non_finite_input_is_skipped() {
        let mut meter = Stillness::new(1.0);
        for tick in 0..1500 {
            let f = if tick == 700 { f32::NAN } else { 0.5 };
            meter.push(tick as f64 * 1e-3, [f, 0.0, 0.0], [0.0; 3]);
        }
        meter.push(f64::NAN, [0.0; 3], [0.0; 3]);
        let last = meter.last();
        assert!(
            last.force_p2p_n.is_finite() && last.force_p2p_n == 0.0,
            "{last:?}"
        );
        assert_eq!(last.ticks, 999);
    }
}
