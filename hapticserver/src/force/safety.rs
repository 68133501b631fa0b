//! Device-side force safety: the only path from a force command to the motor.
//!
//! Owns: [`ForceSafety`], which turns "the newest command and when it arrived" into the force actually
//! rendered, applying in order: non-finite commands never pass (zero target), magnitude clamp to the device
//! maximum, force-rate limit, and a linear ramp to zero when commands go stale. Its [`SafetyCounters`] say how
//! often each rule fired. Its limits, [`SafetyConfig`], their defaults and their domain are in `config`.
//!
//! Must not: read the network, the device or the clock (time and the command are passed in, so tests run on
//! virtual time), allocate, or panic. The time-domain passivity observer from DESIGN.md is a later stage that
//! will sit in front of this filter; this filter stays the last word before the motor.

mod config;

pub use config::{SafetyConfig, SafetyConfigError};

/// How often each rule fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SafetyCounters {
    /// Commands (distinct arrivals) with a NaN or infinite component, replaced by a zero target.
    pub nan_dropped: u64,
    /// Commands (distinct arrivals) whose magnitude exceeded the maximum and were scaled down.
    pub clamped: u64,
    /// Ticks on which the rate limit held the force back.
    pub rate_limited: u64,
    /// Times the command stream went stale (fresh -> stale transitions) and a ramp to zero started.
    pub stale_events: u64,
}

fn is_finite3(v: &[f32; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

fn norm3(v: &[f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn scale3(v: &[f32; 3], s: f32) -> [f32; 3] {
    [v[0] * s, v[1] * s, v[2] * s]
}

/// A ramp fraction below this is zero: the ramp ends at exactly zero force despite rounding.
const RAMP_END_FRACTION: f64 = 1e-6;

/// The safety filter. One per device, owned by the device loop.
#[derive(Debug, Clone)]
pub struct ForceSafety {
    config: SafetyConfig,
    output_n: [f32; 3],
    stale: bool,
    ramp_from_n: [f32; 3],
    ramp_started_s: f64,
    ramp_fraction: f64,
    ramp_in_started_s: f64,
    /// When the last command arrived (loop clock), s; NaN before the first.
    last_fresh_s: f64,
    last_command_at_bits: u64,
    counters: SafetyCounters,
}

impl ForceSafety {
    /// A filter with `config` (checked), rendering zero until a command arrives.
    pub fn new(config: SafetyConfig) -> Result<Self, SafetyConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            output_n: [0.0; 3],
            stale: true,
            ramp_from_n: [0.0; 3],
            ramp_started_s: 0.0,
            ramp_fraction: 0.0,
            ramp_in_started_s: f64::NAN,
            last_fresh_s: f64::NAN,
            last_command_at_bits: f64::NAN.to_bits(),
            counters: SafetyCounters::default(),
        })
    }

    /// The limits.
    pub fn config(&self) -> &SafetyConfig {
        &self.config
    }

    /// The force returned by the last [`ForceSafety::filter`], N.
    pub fn output_n(&self) -> [f32; 3] {
        self.output_n
    }

    /// Whether the command stream is currently stale (or never started).
    pub fn is_stale(&self) -> bool {
        self.stale
    }

    /// Rule counters so far.
    pub fn counters(&self) -> SafetyCounters {
        self.counters
    }

    /// The force to render this tick, N.
    ///
    /// `now_s` is the loop clock, `dt_s` the time since the previous call, `latest` the newest command as
    /// `(received_at_s, force_n)` on the same clock (pass it every tick, even when it did not change; `None` if
    /// none ever arrived). Rules: a command older than `stale_after_s` (or none) is stale and the output falls
    /// linearly from its value at that moment to exactly zero within `ramp_to_zero_s`, never increasing; a fresh
    /// command with a non-finite component is a zero target; the target is scaled down to `max_force_n`
    /// (direction kept); the output moves toward it by at most `max_force_rate_n_per_s * dt_s` (vector norm).
    ///
    /// Real-time contract: no allocation, never blocks, never panics; the result is always finite with magnitude
    /// at most `max_force_n`, whatever the inputs (NaN times included: a NaN clock counts as stale).
    pub fn filter(&mut self, now_s: f64, dt_s: f32, latest: Option<(f64, [f32; 3])>) -> [f32; 3] {
        let fresh = latest.filter(|(received_at_s, _)| {
            // Written so that NaN ages are stale.
            (now_s - received_at_s) <= self.config.stale_after_s
        });
        let mut out = match fresh {
            Some((received_at_s, force_n)) => self.track(now_s, received_at_s, force_n, dt_s),
            None => self.ramp_down(now_s),
        };
        if !is_finite3(&out) {
            out = [0.0; 3];
        }
        let magnitude_n = norm3(&out);
        if magnitude_n > self.config.max_force_n {
            out = scale3(&out, self.config.max_force_n / magnitude_n);
        }
        self.output_n = out;
        out
    }

    /// Fresh command: zero non-finite, clamp, ramp in after a silence, rate-limit.
    fn track(&mut self, now_s: f64, received_at_s: f64, force_n: [f32; 3], dt_s: f32) -> [f32; 3] {
        // A rejoin (the first command, or one after a long silence) ramps in; a hiccup does not. Written so that
        // a NaN clock counts as a rejoin.
        let brief = now_s - self.last_fresh_s < self.config.ramp_in_after_s;
        if self.stale && !brief {
            self.ramp_in_started_s = now_s;
        }
        self.last_fresh_s = now_s;
        self.stale = false;
        let new_command = received_at_s.to_bits() != self.last_command_at_bits;
        self.last_command_at_bits = received_at_s.to_bits();

        let mut target_n = force_n;
        if !is_finite3(&target_n) {
            if new_command {
                self.counters.nan_dropped += 1;
            }
            target_n = [0.0; 3];
        }
        let magnitude_n = norm3(&target_n);
        if magnitude_n > self.config.max_force_n {
            if new_command {
                self.counters.clamped += 1;
            }
            target_n = scale3(&target_n, self.config.max_force_n / magnitude_n);
        }
        // Written so that a NaN clock gives gain 0 (and the target stays finite).
        let since_s = now_s - self.ramp_in_started_s;
        let gain = if self.config.ramp_in_s <= 0.0 || since_s >= self.config.ramp_in_s {
            1.0
        } else if since_s > 0.0 {
            (since_s / self.config.ramp_in_s) as f32
        } else {
            0.0
        };
        if gain < 1.0 {
            target_n = scale3(&target_n, gain);
        }

        let max_step_n = if dt_s.is_finite() && dt_s > 0.0 {
            self.config.max_force_rate_n_per_s * dt_s
        } else {
            0.0
        };
        let delta_n = [
            target_n[0] - self.output_n[0],
            target_n[1] - self.output_n[1],
            target_n[2] - self.output_n[2],
        ];
        let delta_norm_n = norm3(&delta_n);
        if delta_norm_n <= max_step_n {
            return target_n;
        }
        self.counters.rate_limited += 1;
        let step_n = scale3(&delta_n, max_step_n / delta_norm_n);
        [
            self.output_n[0] + step_n[0],
            self.output_n[1] + step_n[1],
            self.output_n[2] + step_n[2],
        ]
    }

    /// Stale: linear ramp from the output at the moment the stream went stale, never increasing.
    fn ramp_down(&mut self, now_s: f64) -> [f32; 3] {
        if !self.stale {
            self.stale = true;
            self.counters.stale_events += 1;
            self.ramp_from_n = self.output_n;
            self.ramp_started_s = now_s;
            self.ramp_fraction = 1.0;
        }
        let fraction = if self.config.ramp_to_zero_s > 0.0 {
            1.0 - (now_s - self.ramp_started_s) / self.config.ramp_to_zero_s
        } else {
            0.0
        };
        let fraction = if fraction.is_finite() && fraction > RAMP_END_FRACTION {
            fraction.min(1.0)
        } else {
            0.0
        };
        self.ramp_fraction = self.ramp_fraction.min(fraction);
        scale3(&self.ramp_from_n, self.ramp_fraction as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT_S: f32 = 0.001;
    const MAX_N: f32 = 3.3;

    /// The filter with every rule but the ramp-in, which has its own test: these tests feed a first command and
    /// check the clamp, the rate limit, NaN and the silence rule against it directly.
    fn safety() -> ForceSafety {
        ForceSafety::new(SafetyConfig {
            ramp_in_s: 0.0,
            ..SafetyConfig::new(MAX_N)
        })
        .unwrap()
    }

    fn now(tick: u32) -> f64 {
        f64::from(tick) * f64::from(DT_S)
    }

    fn norm(v: [f32; 3]) -> f32 {
        norm3(&v)
    }

    fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
        norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
    }

    #[test]
    fn clamp_keeps_direction_and_caps_magnitude() {
        let mut s = safety();
        let command = [6.0, 0.0, 8.0]; // 10 N
        let mut out = [0.0; 3];
        for tick in 0..200 {
            out = s.filter(now(tick), DT_S, Some((now(tick), command)));
            assert!(norm(out) <= MAX_N + 1e-5, "tick {tick}: {out:?}");
            if norm(out) > 0.0 {
                let cos = (out[0] * 0.6 + out[2] * 0.8) / norm(out);
                assert!(cos > 0.9999 && out[1] == 0.0, "direction changed: {out:?}");
            }
        }
        assert!((norm(out) - MAX_N).abs() < 1e-4, "{out:?}");
        assert!(s.counters().clamped >= 1);
    }

    #[test]
    fn rate_limit_bounds_each_step_and_reaches_the_target() {
        let mut s = safety();
        let rate = s.config().max_force_rate_n_per_s;
        let target = [0.0, 3.0, 0.0];
        let mut previous = [0.0; 3];
        let mut reached_at = None;
        for tick in 0..100 {
            let out = s.filter(now(tick), DT_S, Some((now(tick), target)));
            assert!(
                dist(out, previous) <= rate * DT_S + 1e-5,
                "tick {tick}: jump {previous:?} -> {out:?}"
            );
            if reached_at.is_none() && dist(out, target) < 1e-5 {
                reached_at = Some(tick);
            }
            previous = out;
        }
        // 3 N at 200 N/s takes 15 ms.
        let reached_at = reached_at.expect("never reached the target");
        assert!(
            (14..=16).contains(&reached_at),
            "reached at tick {reached_at}"
        );
        assert!(s.counters().rate_limited >= 14);
    }

    #[test]
    fn stale_commands_ramp_linearly_to_exactly_zero() {
        let mut s = safety();
        let command = [1.0, -1.0, 2.0];
        let mut tick = 0;
        let mut out = [0.0; 3];
        while tick < 100 {
            out = s.filter(now(tick), DT_S, Some((now(tick), command)));
            tick += 1;
        }
        assert!(dist(out, command) < 1e-6);
        let last_arrival_s = now(99);
        let held = out;
        let mut stale_tick = None;
        let mut zero_tick = None;
        let mut previous_norm = norm(out);
        while tick < 300 {
            out = s.filter(now(tick), DT_S, Some((last_arrival_s, command)));
            let age_s = now(tick) - last_arrival_s;
            if age_s < 0.050 - 1e-9 {
                assert_eq!(out, held, "changed before going stale (age {age_s})");
            } else if stale_tick.is_none() {
                stale_tick = Some(tick);
            }
            assert!(
                norm(out) <= previous_norm + 1e-7,
                "magnitude increased at tick {tick}"
            );
            if stale_tick.is_some() && norm(out) > 0.0 {
                // Direction kept while ramping.
                let cos = (out[0] * command[0] + out[1] * command[1] + out[2] * command[2])
                    / (norm(out) * norm(command));
                assert!(cos > 0.9999);
            }
            if zero_tick.is_none() && out == [0.0; 3] {
                zero_tick = Some(tick);
            }
            previous_norm = norm(out);
            tick += 1;
        }
        let stale_tick = stale_tick.unwrap();
        let zero_tick = zero_tick.expect("never reached zero");
        assert!(zero_tick >= stale_tick);
        assert!(
            zero_tick - stale_tick <= 20 + 1,
            "took {} ticks",
            zero_tick - stale_tick
        );
        assert_eq!(out, [0.0; 3]);
        assert_eq!(s.counters().stale_events, 1);
        assert!(s.is_stale());
    }

    #[test]
    fn non_finite_commands_never_pass_and_do_not_jump() {
        let mut s = safety();
        let rate = s.config().max_force_rate_n_per_s;
        let mut previous = [0.0; 3];
        for tick in 0..50 {
            previous = s.filter(now(tick), DT_S, Some((now(tick), [0.0, 0.0, 2.0])));
        }
        assert!(dist(previous, [0.0, 0.0, 2.0]) < 1e-6);
        let bad = [
            [f32::NAN, 0.0, 2.0],
            [0.0, f32::INFINITY, 0.0],
            [0.0, 0.0, f32::NEG_INFINITY],
        ];
        for tick in 50..80 {
            let command = bad[tick as usize % bad.len()];
            let out = s.filter(now(tick), DT_S, Some((now(tick), command)));
            assert!(out.iter().all(|c| c.is_finite()), "{out:?}");
            assert!(
                dist(out, previous) <= rate * DT_S + 1e-5,
                "jumped {previous:?} -> {out:?}"
            );
            assert!(norm(out) <= norm(previous) + 1e-7, "not heading to zero");
            previous = out;
        }
        assert_eq!(previous, [0.0; 3]);
        assert_eq!(s.counters().nan_dropped, 30);
        // A NaN clock is stale, never a pass.
        let out = s.filter(f64::NAN, f32::NAN, Some((f64::NAN, [f32::NAN; 3])));
        assert!(out.iter().all(|c| c.is_finite()));
    }

    #[test]
    fn no_command_ever_renders_zero() {
        let mut s = safety();
        for tick in 0..500 {
            assert_eq!(s.filter(now(tick), DT_S, None), [0.0; 3]);
        }
        assert_eq!(s.counters(), SafetyCounters::default());
    }

    #[test]
    fn random_commands_stay_finite_bounded_and_smooth() {
        let mut rng = fastrand::Rng::with_seed(0x5157);
        let mut s = safety();
        let config = *s.config();
        let ramp_step_n = config.max_force_n * DT_S / config.ramp_to_zero_s as f32;
        let max_step_n = (config.max_force_rate_n_per_s * DT_S).max(ramp_step_n) + 1e-5;
        let mut previous = [0.0; 3];
        let mut latest: Option<(f64, [f32; 3])> = None;
        let component = |rng: &mut fastrand::Rng| match rng.u8(0..20) {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => -1e30,
            _ => (rng.f32() - 0.5) * 20.0,
        };
        for tick in 0..200_000 {
            // 900 ms of irregular commands, then 100 ms of silence (stale) in every second.
            if tick % 1000 < 900 && rng.u8(0..100) < 60 {
                latest = Some((
                    now(tick),
                    [
                        component(&mut rng),
                        component(&mut rng),
                        component(&mut rng),
                    ],
                ));
            }
            let out = s.filter(now(tick), DT_S, latest);
            assert!(out.iter().all(|c| c.is_finite()), "tick {tick}: {out:?}");
            assert!(
                norm(out) <= config.max_force_n + 1e-5,
                "tick {tick}: {out:?}"
            );
            assert!(
                dist(out, previous) <= max_step_n,
                "tick {tick}: {previous:?} -> {out:?}"
            );
            previous = out;
        }
        let counters = s.counters();
        assert!(counters.nan_dropped > 0 && counters.clamped > 0 && counters.rate_limited > 0);
    }

    #[test]
    fn after_a_silence_the_force_ramps_back_in_linearly_over_ramp_in_s() {
        let config = SafetyConfig::new(3.3);
        let mut s = ForceSafety::new(config).unwrap();
        let dt = 0.001f32;
        let at = |tick: u32| f64::from(tick) * 1e-3;
        // A steady 1 N stream from t = 0: the gain rises from 0 to 1 over 300 ms, never faster.
        let mut forces = Vec::new();
        for tick in 0..400 {
            forces.push(s.filter(at(tick), dt, Some((at(tick), [0.0, 0.0, 1.0])))[2]);
        }
        assert_eq!(forces[0], 0.0);
        assert!((forces[150] - 0.5).abs() < 0.01, "{}", forces[150]);
        assert!(forces[299] < 1.0 && (forces[300] - 1.0).abs() < 1e-6);
        assert!(
            forces
                .windows(2)
                .all(|w| w[1] >= w[0] && w[1] - w[0] <= 1.0 / 300.0 + 1e-5)
        );
        // A silence as long as a rejoin's (300 ms: the force goes to zero by the rule); then the stream returns
        // and ramps in again from zero.
        let last = at(399);
        let mut tick = 400;
        while tick < 700 {
            s.filter(at(tick), dt, Some((last, [0.0, 0.0, 1.0])));
            tick += 1;
        }
        assert!(s.is_stale() && s.output_n() == [0.0; 3]);
        let back = s.filter(at(tick), dt, Some((at(tick), [0.0, 0.0, 1.0])))[2];
        assert_eq!(back, 0.0, "the returning force must start from zero");
        let later = s.filter(at(tick + 30), dt, Some((at(tick + 30), [0.0, 0.0, 1.0])))[2];
        assert!((later - 0.1).abs() < 0.01, "30 ms into the ramp: {later}");
    }

    #[test]
    fn a_brief_silence_ends_through_the_rate_limit_alone() {
        let mut s = ForceSafety::new(SafetyConfig::new(3.3)).unwrap();
        let dt = 0.001f32;
        let at = |tick: u32| f64::from(tick) * 1e-3;
        for tick in 0..400 {
            s.filter(at(tick), dt, Some((at(tick), [0.0, 0.0, 1.0])));
        }
        // 80 ms without a command (past the 50 ms rule, so the force ramps to zero), then the stream is back.
        for tick in 400..480 {
            s.filter(at(tick), dt, Some((at(399), [0.0, 0.0, 1.0])));
        }
        assert!(s.is_stale() && s.counters().stale_events == 1);
        let back: Vec<f32> = (480..490)
            .map(|tick| s.filter(at(tick), dt, Some((at(tick), [0.0, 0.0, 1.0])))[2])
            .collect();
        // 200 N/s: 0.2 N a tick, so 1 N again within 5 ticks (a ramp-in would take 300 ms).
        assert!((back[4] - 1.0).abs() < 1e-6, "{back:?}");
    }
}
