//! Phase alignment of the device loop with the server's tick, for a device rendering directly.
//!
//! Owns: [`PhaseAligner`]. The server says in each force command how long the answered pose waited before the
//! tick that used it (`ForceCommand::pose_wait_us`). When the device loop and the server tick run at unrelated
//! phases that wait is anywhere in one period, and the force for pose n often reaches the device after its tick
//! n+1: rendered at n+2, two periods of round trip. The aligner shifts the loop's next deadline so that the
//! waits settle at a small target: each pose arrives just before a server tick, and its force (the tick's
//! compute and the way back) is there for the device's next tick.
//!
//! The target leaves room on both sides. A pose that arrives after the tick waits a whole period; a force that
//! arrives after the device's next tick is rendered a period late. With `x` the rest of the round trip (the
//! way there and back and the tick's compute: the wire round trip minus the wait, measured per echo), a force
//! is in time when `0 <= wait <= P - x`. The aligner aims at the middle of that room, `(P - x) / 2` with `x`
//! the window's median, capped at the configured target (enough margin against a jittered pose when the
//! server is quick) and floored at `MIN_TARGET_WAIT_US`. On a loaded server (a long tick) the target
//! shrinks, so the force still makes the next device tick.
//!
//! The wait is a phase: it wraps at the period (a pose that arrives just after a tick waits almost a whole
//! one). The error `wait - target` is wrapped into (-P/2, P/2], so a pose that just missed asks for a small
//! shift earlier, not a large one later. The median of a window of errors decides a correction (one late pose
//! or a VM stall moves nothing), a deadband keeps a converged loop still, and a correction is paid out in
//! steps of at most `max_step_us` per tick, so the loop's period never changes by more than that. Echoes of
//! poses published before a correction was paid out are not used for the next one (they measure the old
//! phase).
//!
//! Pure: no clock, no allocation, no lock; the device loop applies the shifts to its pacer.

/// The default wait to settle at, us.
pub const DEFAULT_TARGET_WAIT_US: f32 = 150.0;

/// The smallest target wait, us: a pose must still make the server's tick.
pub const MIN_TARGET_WAIT_US: f32 = 20.0;

/// Errors in one decision window.
pub const PHASE_WINDOW: usize = 32;

/// How the aligner behaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseConfig {
    /// The loop period, us (the server tick is assumed to run at the same rate).
    pub period_us: f32,
    /// The largest wait to settle at, us: the margin that keeps a jittered pose ahead of the server's tick
    /// when the server is quick (a loaded one gets a smaller target: the module doc).
    pub target_wait_us: f32,
    /// Median errors within this are left alone, us.
    pub deadband_us: f32,
    /// The largest shift of one deadline, us.
    pub max_step_us: f32,
}

impl PhaseConfig {
    /// Defaults for a loop of `period_us`: target 150 us, deadband 15 us, steps of at most 10 us (1% of a 1 ms
    /// period).
    pub fn for_period_us(period_us: f32) -> Self {
        Self {
            period_us,
            target_wait_us: DEFAULT_TARGET_WAIT_US,
            deadband_us: 15.0,
            max_step_us: 10.0,
        }
    }
}

/// What the aligner has done (copied into the report).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseCounters {
    /// Alignment is on.
    pub enabled: bool,
    /// Corrections decided.
    pub corrections: u64,
    /// Net shift applied to the loop since start, us (positive: later).
    pub net_shift_us: f64,
    /// The median wrapped error of the latest window, us (wait minus target).
    pub last_error_us: f32,
    /// The median wait of the latest window, us.
    pub last_median_wait_us: f32,
    /// The target wait of the latest window, us.
    pub last_target_us: f32,
    /// The median of the rest of the round trip (wire round trip minus wait) of the latest window, us.
    pub last_rest_us: f32,
    /// The latest window was within the deadband.
    pub aligned: bool,
    /// Waits used (echoes that counted).
    pub waits_used: u64,
}

/// Shifts the device loop's phase so the server's reported pose waits settle at a target.
#[derive(Debug, Clone)]
pub struct PhaseAligner {
    config: PhaseConfig,
    waits_us: [f32; PHASE_WINDOW],
    rests_us: [f32; PHASE_WINDOW],
    len: usize,
    pending_us: f32,
    ignore_through_seq: u64,
    counters: PhaseCounters,
}

impl PhaseAligner {
    /// An aligner with `config`, on (`enabled`) or only measuring (the waits' median is still reported).
    pub fn new(config: PhaseConfig, enabled: bool) -> Self {
        Self {
            config,
            waits_us: [0.0; PHASE_WINDOW],
            rests_us: [0.0; PHASE_WINDOW],
            len: 0,
            pending_us: 0.0,
            ignore_through_seq: 0,
            counters: PhaseCounters {
                enabled,
                ..PhaseCounters::default()
            },
        }
    }

    /// The configuration.
    pub fn config(&self) -> PhaseConfig {
        self.config
    }

    /// What it has done.
    pub fn counters(&self) -> PhaseCounters {
        self.counters
    }

    /// `wait - target` wrapped into (-P/2, P/2], us.
    pub fn wrapped_error_us(&self, wait_us: f32, target_us: f32) -> f32 {
        let p = self.config.period_us;
        let e = wait_us - target_us;
        let wrapped = e - p * (e / p).round();
        // `round` sends an exact half period to -P/2; keep the interval half-open on the other side.
        if wrapped <= -0.5 * p {
            wrapped + p
        } else {
            wrapped
        }
    }

    /// The target wait for a window whose rest of the round trip has median `rest_us`.
    pub fn target_for_rest_us(&self, rest_us: f32) -> f32 {
        let room = 0.5 * (self.config.period_us - rest_us);
        room.min(self.config.target_wait_us)
            .max(MIN_TARGET_WAIT_US.min(self.config.target_wait_us))
    }

    /// The server's wait for the pose `echo_seq` (the first command echoing it) and the pose's wire round
    /// trip (pose read to force arrival), us. Ignored while a correction is being paid out and for poses
    /// published before it was. Measured also when alignment is off.
    pub fn observe(&mut self, echo_seq: u64, wait_us: u32, wire_round_trip_us: u32) {
        if self.pending_us != 0.0 || echo_seq <= self.ignore_through_seq {
            return;
        }
        let wait_us = wait_us as f32;
        self.waits_us[self.len] = wait_us;
        // A pose that waited more than a period (a stalled server) measures its rest as if it had not.
        self.rests_us[self.len] =
            wire_round_trip_us as f32 - wait_us.rem_euclid(self.config.period_us);
        self.len += 1;
        self.counters.waits_used += 1;
        if self.len < PHASE_WINDOW {
            return;
        }
        self.len = 0;
        let rest_us = median(&mut self.rests_us);
        let target_us = self.target_for_rest_us(rest_us);
        let mut errors_us = [0.0; PHASE_WINDOW];
        for (e, &w) in errors_us.iter_mut().zip(&self.waits_us) {
            *e = self.wrapped_error_us(w, target_us);
        }
        let error_us = median(&mut errors_us);
        self.counters.last_rest_us = rest_us;
        self.counters.last_target_us = target_us;
        self.counters.last_error_us = error_us;
        self.counters.last_median_wait_us = median(&mut self.waits_us);
        if error_us.abs() <= self.config.deadband_us {
            self.counters.aligned = true;
            return;
        }
        self.counters.aligned = false;
        if !self.counters.enabled {
            // Off: measured and reported, never corrected.
            return;
        }
        self.counters.corrections += 1;
        // A wait above the target: the pose arrives too early, so publish later (a positive shift).
        self.pending_us = error_us;
    }

    /// The shift of the loop's next deadline for this tick, ns (positive: later), at most `max_step_us`.
    /// `published_seq` is the newest pose already published: its echo measures the phase before this shift.
    pub fn shift_ns(&mut self, published_seq: u64) -> i64 {
        if self.pending_us == 0.0 {
            return 0;
        }
        let step = self
            .pending_us
            .clamp(-self.config.max_step_us, self.config.max_step_us);
        self.pending_us -= step;
        if self.pending_us.abs() < 1e-3 {
            self.pending_us = 0.0;
            // The pose published with this tick left at the old phase; the next one leaves at the new one.
            self.ignore_through_seq = published_seq;
        }
        self.counters.net_shift_us += f64::from(step);
        (step * 1000.0).round() as i64
    }
}

/// The median of a full window (sorted in place; no allocation).
fn median(values: &mut [f32; PHASE_WINDOW]) -> f32 {
    values.sort_unstable_by(f32::total_cmp);
    0.5 * (values[PHASE_WINDOW / 2 - 1] + values[PHASE_WINDOW / 2])
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)] // test code

    use super::*;

    /// A device loop and a server tick at the same period, on virtual time (us): the device publishes at
    /// `device_phase + k P` (+ its loop jitter and the shifts so far), the pose arrives `one_way` later (+
    /// network jitter), the server's ticks are at `server_phase + j P` (+ tick jitter), and the force leaves
    /// `compute` after the tick and arrives `one_way` later. Returns, per device tick, (the wait the server
    /// measured, whether the force was there for the next device tick, the shift applied).
    struct Rig {
        aligner: PhaseAligner,
        rng: fastrand::Rng,
        period: f64,
        server_phase: f64,
        one_way: f64,
        compute: f64,
        jitter: f64,
        shift_total: f64,
    }

    struct Outcome {
        wait_us: f64,
        in_time: bool,
        step_us: f64,
    }

    impl Rig {
        fn new(server_phase: f64, seed: u64, enabled: bool) -> Self {
            Self {
                aligner: PhaseAligner::new(PhaseConfig::for_period_us(1000.0), enabled),
                rng: fastrand::Rng::with_seed(seed),
                period: 1000.0,
                server_phase,
                one_way: 55.0,
                compute: 450.0,
                jitter: 25.0,
                shift_total: 0.0,
            }
        }

        fn jitter(&mut self) -> f64 {
            // One-sided, as scheduling and network delays are.
            self.rng.f64() * self.jitter
        }

        /// Device tick `k` (seq k+1); the echo of this pose is observed before the next tick (a round trip
        /// within one period) or later, but the aligner's logic only depends on the order of observations.
        fn tick(&mut self, k: u64) -> Outcome {
            let published = k as f64 * self.period + self.shift_total + self.jitter();
            let arrival = published + self.one_way + self.jitter();
            // The first server tick at or after the arrival.
            let j = ((arrival - self.server_phase) / self.period).ceil();
            let tick_start = self.server_phase + j * self.period + self.jitter() * 0.5;
            let wait = (tick_start - arrival).max(0.0);
            let force_arrival =
                tick_start + self.compute + self.jitter() + self.one_way + self.jitter();
            let wire_round_trip = force_arrival - published;
            self.aligner
                .observe(k + 1, wait as u32, wire_round_trip as u32);
            let step_us = self.aligner.shift_ns(k + 1) as f64 / 1000.0;
            self.shift_total += step_us;
            let next_device_tick = (k + 1) as f64 * self.period + self.shift_total;
            let in_time = force_arrival < next_device_tick;
            Outcome {
                wait_us: wait,
                in_time,
                step_us,
            }
        }
    }

    #[test]
    fn converges_from_every_phase_within_a_second_in_small_steps() {
        for (i, server_phase) in [0.0, 120.0, 333.0, 499.0, 500.0, 501.0, 700.0, 990.0]
            .into_iter()
            .enumerate()
        {
            let mut rig = Rig::new(server_phase, 7 + i as u64, true);
            let mut late_after_1s = 0;
            let mut largest_step: f64 = 0.0;
            let mut waits_after_1s = Vec::new();
            for k in 0..3000 {
                let out = rig.tick(k);
                largest_step = largest_step.max(out.step_us.abs());
                if k >= 1000 {
                    late_after_1s += u32::from(!out.in_time);
                    waits_after_1s.push(out.wait_us);
                }
            }
            assert!(
                largest_step <= 10.0 + 1e-3,
                "phase {server_phase}: step {largest_step} us"
            );
            assert_eq!(
                late_after_1s, 0,
                "phase {server_phase}: forces late after 1 s"
            );
            waits_after_1s.sort_by(f64::total_cmp);
            let median = waits_after_1s[waits_after_1s.len() / 2];
            assert!(
                (100.0..=220.0).contains(&median),
                "phase {server_phase}: median wait {median} us against the target 150"
            );
            assert!(rig.aligner.counters().aligned, "phase {server_phase}");
        }
    }

    #[test]
    fn on_a_loaded_server_the_target_shrinks_so_forces_still_make_the_next_tick() {
        // A 750 us tick: the rest of the round trip is 860-935 us, so a wait of 150 us would put every force
        // after the device's next tick. The target becomes half the room left, about 50 us.
        for (i, server_phase) in [0.0, 250.0, 610.0, 900.0].into_iter().enumerate() {
            let mut rig = Rig::new(server_phase, 21 + i as u64, true);
            rig.compute = 750.0;
            let mut late_after_1s = 0;
            for k in 0..3000 {
                let out = rig.tick(k);
                if k >= 1000 {
                    late_after_1s += u32::from(!out.in_time);
                }
            }
            let c = rig.aligner.counters();
            assert!(
                (30.0..=80.0).contains(&c.last_target_us),
                "phase {server_phase}: target {} us (rest {} us)",
                c.last_target_us,
                c.last_rest_us
            );
            assert!(
                late_after_1s <= 100,
                "phase {server_phase}: {late_after_1s} of 2000 late"
            );
        }
    }

    #[test]
    fn without_alignment_a_bad_phase_stays_bad() {
        // The control: the same rig with the aligner off leaves a pose that just misses the tick missing it,
        // so the test above measures the aligner, not the rig.
        let mut rig = Rig::new(40.0, 3, false);
        let late = (0..2000).filter(|&k| !rig.tick(k).in_time).count();
        assert!(late > 1900, "{late} of 2000 late");
        assert_eq!(rig.aligner.counters().corrections, 0);
        assert_eq!(rig.shift_total, 0.0);
    }

    #[test]
    fn a_converged_loop_stays_still_and_a_stall_moves_nothing() {
        let mut rig = Rig::new(600.0, 11, true);
        for k in 0..1500 {
            rig.tick(k);
        }
        let corrections = rig.aligner.counters().corrections;
        let shift = rig.shift_total;
        // A few stalled poses (waits of a whole period and more) inside one window: the median ignores them.
        for k in 1500..1503 {
            rig.aligner.observe(k + 1, 1900, 2500);
            rig.aligner.shift_ns(k + 1);
        }
        for k in 1503..3000 {
            rig.tick(k);
        }
        assert_eq!(rig.aligner.counters().corrections, corrections);
        assert_eq!(rig.shift_total, shift);
    }

    #[test]
    fn the_error_wraps_to_the_nearer_direction() {
        let a = PhaseAligner::new(PhaseConfig::for_period_us(1000.0), true);
        assert_eq!(a.wrapped_error_us(150.0, 150.0), 0.0);
        assert_eq!(a.wrapped_error_us(400.0, 150.0), 250.0);
        // Just missed: wait almost a period, shift a little earlier.
        assert_eq!(a.wrapped_error_us(990.0, 150.0), -160.0);
        assert_eq!(a.wrapped_error_us(650.0, 150.0), 500.0);
        assert_eq!(a.wrapped_error_us(651.0, 150.0), -499.0);
        // A stalled server: more than a period.
        assert_eq!(a.wrapped_error_us(1200.0, 150.0), 50.0);
    }

    #[test]
    fn echoes_of_poses_from_before_a_correction_do_not_count() {
        let mut a = PhaseAligner::new(PhaseConfig::for_period_us(1000.0), true);
        for seq in 1..=PHASE_WINDOW as u64 {
            a.observe(seq, 450, 850);
        }
        assert_eq!(a.counters().corrections, 1);
        let mut published = PHASE_WINDOW as u64;
        let mut total_ns = 0;
        while {
            published += 1;
            let step = a.shift_ns(published);
            total_ns += step;
            step != 0
        } {
            // Echoes arriving while the correction is paid out are ignored.
            a.observe(published - 2, 900, 1300);
        }
        assert_eq!(total_ns, 300_000);
        assert_eq!(a.counters().waits_used, PHASE_WINDOW as u64);
        // The pose published with the last step still measures the old phase.
        a.observe(published - 1, 900, 1300);
        assert_eq!(a.counters().waits_used, PHASE_WINDOW as u64);
        a.observe(published + 1, 150, 550);
        assert_eq!(a.counters().waits_used, PHASE_WINDOW as u64 + 1);
    }
}
