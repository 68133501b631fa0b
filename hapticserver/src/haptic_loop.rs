//! One tick of the device loop, independent of zenoh and of wall-clock time.
//!
//! Owns: the per-device loop state: the [`Device`], the local-model renderer ([`ModelRenderer`]), the mode
//! switch ([`ModeSwitch`]), the [`ForceSafety`] filter, the passivity controller, pose sequencing and encoding
//! into a reused buffer, round-trip measurement from echoed poses, the trace, and the loop's counters and
//! histograms. [`HapticLoop::tick`] is the whole 1 kHz body: read the device, publish the pose (saying how
//! this device renders), take the newest force command (a new local model is blended in), measure the round
//! trip, evaluate the model against the CURRENT position, blend it with the streamed force as the mode says,
//! apply passivity (in moderated mode the controller is on, with the server's energy allowance), filter
//! through safety, render. Time and the publish sink are passed in, so tests drive it
//! on virtual time with a closure as the network.
//!
//! Must not: sleep, spawn, lock (except `try_lock`), log, or allocate in a tick (the encode buffer and
//! histograms are allocated once at construction). Pacing and zenoh live in [`crate::haptic_server`].

use std::sync::{Arc, Mutex};
use std::time::Duration;

use sinew_protocol::rt::LatencyHistogram;
use sinew_protocol::{DevicePose, ForceMode, RenderMode, encode};

use crate::clock::ns_to_s;
use crate::device::Device;
use crate::force_inbox::{ForceInbox, ReceivedForce};
use crate::passivity::{Passivity, PassivityMode};
use crate::phase_align::{PhaseAligner, PhaseConfig};
use crate::render::{ModelRenderer, RenderConfig};
use crate::render_mode::{ModePolicy, ModeSwitch};
use crate::report::HapticReport;
use crate::safety::ForceSafety;
use crate::stillness::Stillness;
use crate::trace::{Trace, TraceSample};

/// Scalar loop counters (`Copy`, copied into the report).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct LoopCounters {
    ticks: u64,
    poses_published: u64,
    publish_errors: u64,
    device_read_errors: u64,
    device_write_errors: u64,
    overruns: u64,
    max_rendered_force_n: f32,
    last_rendered_force_n: [f32; 3],
    last_commanded_force_n: [f32; 3],
    last_position_mm: [f32; 3],
    models_received: u64,
    longest_command_gap_ms: f32,
    keepalives_received: u64,
}

/// The state of one device loop.
pub struct HapticLoop {
    device: Box<dyn Device>,
    safety: ForceSafety,
    passivity: Passivity,
    passivity_mode: PassivityMode,
    renderer: ModelRenderer,
    mode: ModeSwitch,
    phase: PhaseAligner,
    phase_shift_ns: i64,
    allowance_mj: f64,
    trace: Trace,
    last_velocity_mm_s: [f32; 3],
    stillness: Stillness,
    inbox: Arc<ForceInbox>,
    period: Duration,
    dt_s: f32,
    pose_seq: u64,
    pose_bytes: Vec<u8>,
    seen_writes: u64,
    latest: Option<ReceivedForce>,
    last_echo_seq: u64,
    last_round_trip_us: u32,
    shutting_down: bool,
    round_trip: LatencyHistogram,
    wire_round_trip: LatencyHistogram,
    interval_deviation: LatencyHistogram,
    counters: LoopCounters,
}

impl std::fmt::Debug for HapticLoop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HapticLoop")
            .field("period", &self.period)
            .field("pose_seq", &self.pose_seq)
            .field("counters", &self.counters)
            .field("safety", &self.safety)
            .finish_non_exhaustive()
    }
}

/// Longest time one read advances a simulated device by, s: a longer stall is taken as this much (the hand
/// model's substeps cover it; a pause of the whole process is not the hand's motion).
const MAX_READ_INTERVAL_S: f32 = 0.25;

/// The time a device read advances by: the measured interval since the previous tick, or the loop period on
/// the first tick or when the interval is unusable; at most [`MAX_READ_INTERVAL_S`].
fn read_interval_s(interval: Option<Duration>, period_s: f32) -> f32 {
    interval
        .map(|d| d.as_secs_f32())
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(period_s)
        .min(MAX_READ_INTERVAL_S)
}

fn norm3(v: &[f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

impl HapticLoop {
    /// A loop driving `device` at `period`, reading commands from `inbox`, rendering through `safety`.
    pub fn new(
        device: Box<dyn Device>,
        safety: ForceSafety,
        inbox: Arc<ForceInbox>,
        period: Duration,
    ) -> Self {
        Self {
            device,
            safety,
            passivity: Passivity::new(PassivityMode::Observe),
            passivity_mode: PassivityMode::Observe,
            renderer: ModelRenderer::new(RenderConfig::default()),
            mode: ModeSwitch::new(ModePolicy::default()),
            phase: PhaseAligner::new(PhaseConfig::for_period_us(period.as_secs_f32() * 1e6), true),
            phase_shift_ns: 0,
            allowance_mj: 0.0,
            trace: Trace::default(),
            last_velocity_mm_s: [0.0; 3],
            stillness: Stillness::default(),
            inbox,
            period,
            dt_s: period.as_secs_f32(),
            pose_seq: 0,
            // A DevicePose is under 100 bytes on the wire; room to spare so encode never reallocates.
            pose_bytes: Vec::with_capacity(256),
            seen_writes: 0,
            latest: None,
            last_echo_seq: 0,
            last_round_trip_us: 0,
            shutting_down: false,
            round_trip: LatencyHistogram::new(),
            wire_round_trip: LatencyHistogram::new(),
            interval_deviation: LatencyHistogram::new(),
            counters: LoopCounters::default(),
        }
    }

    /// Choose whether the passivity controller may correct forces while rendering directly (default: observe
    /// only). While the local model is rendered the controller is always on, with the server's allowance.
    pub fn set_passivity_mode(&mut self, mode: PassivityMode) {
        self.passivity_mode = mode;
        self.passivity = Passivity::new(mode);
    }

    /// Choose between the streamed force and the local model (default: auto).
    pub fn set_mode_policy(&mut self, policy: ModePolicy) {
        self.mode = ModeSwitch::new(policy);
    }

    /// Align the loop's phase with the server's tick while rendering directly (default on), settling at a
    /// pose wait of `target_wait_us` at the server.
    pub fn set_phase_align(&mut self, enabled: bool, target_wait_us: f32) {
        let config = PhaseConfig {
            target_wait_us,
            ..self.phase.config()
        };
        self.phase = PhaseAligner::new(config, enabled);
    }

    /// The shift of the loop's next deadline the latest tick asked for, ns (positive: later); the pacer
    /// applies it. Zero once taken.
    pub fn take_phase_shift_ns(&mut self) -> i64 {
        std::mem::take(&mut self.phase_shift_ns)
    }

    /// Record up to `capacity` ticks (allocated now).
    pub fn record_trace(&mut self, capacity: usize) {
        self.trace = Trace::with_capacity(capacity);
    }

    /// The recorded ticks.
    pub fn trace(&self) -> &Trace {
        &self.trace
    }

    /// Take the recorded ticks (the loop records no more).
    pub fn take_trace(&mut self) -> Trace {
        std::mem::take(&mut self.trace)
    }

    /// The mode switch.
    pub fn mode(&self) -> &ModeSwitch {
        &self.mode
    }

    /// Ticks run.
    pub fn ticks(&self) -> u64 {
        self.counters.ticks
    }

    /// The force rendered on the latest tick, N.
    pub fn rendered_force_n(&self) -> [f32; 3] {
        self.counters.last_rendered_force_n
    }

    /// The safety filter.
    pub fn safety(&self) -> &ForceSafety {
        &self.safety
    }

    /// Record the pacer's overrun count (it owns the schedule).
    pub fn set_overruns(&mut self, overruns: u64) {
        self.counters.overruns = overruns;
    }

    /// Ignore commands from now on, so the safety filter ramps the force to zero.
    pub fn begin_shutdown(&mut self) {
        self.shutting_down = true;
    }

    /// One loop iteration at `now_ns` (the [`crate::clock::MonotonicClock`]). `interval` is the measured time
    /// since the previous tick (None on the first). `publish` sends an encoded [`DevicePose`] and says whether
    /// the network took it. Returns the force rendered, N.
    ///
    /// Real-time contract: no allocation (beyond what `publish` does), never blocks, never panics, never
    /// renders a non-finite force.
    pub fn tick(
        &mut self,
        now_ns: u64,
        interval: Option<Duration>,
        publish: &mut dyn FnMut(&[u8]) -> bool,
    ) -> [f32; 3] {
        self.counters.ticks += 1;
        if let Some(interval) = interval {
            self.interval_deviation
                .record(interval.abs_diff(self.period));
        }

        // 1. Sense and publish. A simulated hand or a replay lives in wall time, as a real hand does: it moves
        // on by the time since the previous read, so a loop that skipped periods in a VM stall does not fall
        // behind its script (the pacer never bursts ticks to catch up).
        match self.device.read(read_interval_s(interval, self.dt_s)) {
            Ok(reading) if reading.is_finite() => {
                self.pose_seq += 1;
                let pose = DevicePose {
                    seq: self.pose_seq,
                    device_time_ns: now_ns,
                    position_mm: reading.position_mm,
                    orientation_xyzw: reading.orientation_xyzw,
                    linear_velocity_mm_s: reading.linear_velocity_mm_s,
                    buttons: reading.buttons,
                    jaw_angle_rad: reading.jaw_angle_rad,
                    round_trip_us: self.last_round_trip_us,
                    render_mode: if self.mode.moderated() {
                        RenderMode::Moderated
                    } else {
                        RenderMode::Direct
                    },
                };
                encode(self.inbox.own_instance(), &pose, &mut self.pose_bytes);
                if publish(&self.pose_bytes) {
                    self.counters.poses_published += 1;
                } else {
                    self.counters.publish_errors += 1;
                }
                self.counters.last_position_mm = reading.position_mm;
                self.last_velocity_mm_s = reading.linear_velocity_mm_s;
                self.renderer.set_orientation(reading.orientation_xyzw);
            }
            // A failed or non-finite reading is not published; the force path below still runs.
            Ok(_) | Err(_) => self.counters.device_read_errors += 1,
        }

        // 2. Newest command, and the round trip of the pose it answers.
        let position_mm = self.counters.last_position_mm;
        let velocity_mm_s = self.last_velocity_mm_s;
        let now_s = ns_to_s(now_ns);
        let newest = self.inbox.latest().take_newer(&mut self.seen_writes);
        if let (Some(received), Some(previous)) = (newest, self.latest) {
            // The silence the safety rule saw, between two commands (the last one, a lost server's, is not a
            // gap: it never ends).
            let gap_ms = received.received_ns.saturating_sub(previous.received_ns) as f32 * 1e-6;
            self.counters.longest_command_gap_ms = self.counters.longest_command_gap_ms.max(gap_ms);
        }
        // The server's keepalive is its last command again, same sequence number (its sim ran slower than real
        // time): a sign of life for the silence rule, nothing new to render or measure.
        let keepalive = newest.is_some_and(|received| {
            self.latest.is_some_and(|previous| {
                previous.command.seq == received.command.seq
                    && previous.command.device_instance == received.command.device_instance
            })
        });
        if keepalive {
            self.latest = newest;
            self.counters.keepalives_received += 1;
        }
        if let Some(received) = newest.filter(|_| !keepalive) {
            self.latest = Some(received);
            let command = received.command;
            self.counters.last_commanded_force_n = command.force_n;
            match &command.mode {
                ForceMode::LocalModel(model) => {
                    self.renderer
                        .accept(model, now_s, position_mm, velocity_mm_s);
                    self.allowance_mj = f64::from(model.energy_allowance_mj);
                    self.counters.models_received += 1;
                }
                // The explicit zero of a released tool: no model any more.
                ForceMode::Direct => {
                    self.renderer.clear();
                    self.allowance_mj = 0.0;
                }
            }
            let echoes_our_pose = command.echo_pose_seq > self.last_echo_seq
                && command.echo_pose_seq <= self.pose_seq
                && command.echo_device_time_ns <= now_ns;
            if echoes_our_pose {
                self.last_echo_seq = command.echo_pose_seq;
                let round_trip_ns = now_ns - command.echo_device_time_ns;
                self.round_trip.record_ns(round_trip_ns);
                self.wire_round_trip.record_ns(
                    received
                        .received_ns
                        .saturating_sub(command.echo_device_time_ns),
                );
                self.last_round_trip_us = u32::try_from(round_trip_ns / 1000).unwrap_or(u32::MAX);
                self.mode.observe_round_trip(round_trip_ns as f32 * 1e-6);
                // The phase matters only while the streamed force is rendered; a local model is evaluated
                // against the current position whenever it arrives.
                if let Some(wait_us) = command.pose_wait_us
                    && !self.mode.moderated()
                {
                    let wire_us = received
                        .received_ns
                        .saturating_sub(command.echo_device_time_ns)
                        / 1000;
                    self.phase.observe(
                        command.echo_pose_seq,
                        wait_us,
                        u32::try_from(wire_us).unwrap_or(u32::MAX),
                    );
                }
            }
        }

        // 3. The force to render: the streamed one, the local model against the current position, or a
        // cross-fade between them while the mode switches.
        let direct_n = self.latest.map_or([0.0; 3], |r| r.command.force_n);
        let model_n = if self.renderer.has_model() {
            self.renderer.force_n(now_s, position_mm, velocity_mm_s)
        } else {
            direct_n
        };
        let target_n = self.mode.blend(self.dt_s, direct_n, model_n);

        // 4. Passivity may only remove force; it acts on the target BEFORE safety, so its corrections are
        // rate-limited like everything else (applied after safety it could drop the force in one tick). While
        // the local model is rendered the controller is on, with the energy the other ports sent (the
        // server's allowance).
        let passive_n = if self.mode.weight() > 0.0 {
            self.passivity.set_mode(PassivityMode::Control);
            self.passivity.apply_with_allowance(
                target_n,
                velocity_mm_s,
                self.dt_s,
                self.allowance_mj,
            )
        } else {
            self.passivity.set_mode(self.passivity_mode);
            self.passivity.apply(target_n, velocity_mm_s, self.dt_s)
        };

        // 5. Safety, the only way to the motor: the last word on every force.
        let latest = if self.shutting_down {
            None
        } else {
            self.latest
                .map(|received| (ns_to_s(received.received_ns), passive_n))
        };
        let force_n = self.safety.filter(now_s, self.dt_s, latest);
        if self.safety.is_stale() {
            // The silence rule is ramping down: the model it came from is never rendered again.
            self.renderer.clear();
            self.allowance_mj = 0.0;
        }

        // 6. Render.
        if self.device.write_force(force_n).is_err() {
            self.counters.device_write_errors += 1;
        }
        self.trace.push(TraceSample {
            t_s: now_s,
            position_mm,
            velocity_mm_s,
            force_n,
            model_weight: self.mode.weight(),
            stale: self.safety.is_stale(),
            target_n,
            blend_offset_n: self.renderer.blend_offset_n(now_s),
            passivity_energy_mj: self.passivity.counters().energy_mj,
        });
        self.stillness.push(now_s, force_n, velocity_mm_s);
        self.phase_shift_ns = self.phase.shift_ns(self.pose_seq);
        self.counters.last_rendered_force_n = force_n;
        self.counters.max_rendered_force_n =
            self.counters.max_rendered_force_n.max(norm3(&force_n));
        force_n
    }

    /// After the loop itself failed: ramp the motor's last force linearly to zero over `steps` periods,
    /// written straight to the device (no tick runs; a non-finite last force is replaced by zero), then zero.
    /// `wait` paces the steps (the loop's pacer).
    pub fn ramp_out(&mut self, steps: u64, mut wait: impl FnMut()) {
        let last = self.counters.last_rendered_force_n;
        let from = if last.iter().all(|f| f.is_finite()) {
            last
        } else {
            [0.0; 3]
        };
        let steps = steps.max(1);
        for k in (1..steps).rev() {
            let scale = k as f32 / steps as f32;
            if self
                .device
                .write_force([from[0] * scale, from[1] * scale, from[2] * scale])
                .is_err()
            {
                self.counters.device_write_errors += 1;
            }
            wait();
        }
        self.write_zero_force();
    }

    /// Command exactly zero force, outside the safety filter (zero is always safe). Used when the loop ends.
    pub fn write_zero_force(&mut self) {
        if self.device.write_force([0.0; 3]).is_err() {
            self.counters.device_write_errors += 1;
        }
        self.counters.last_rendered_force_n = [0.0; 3];
    }

    /// Copy the loop's state into `report`. No allocation (histograms are copied in place).
    pub fn write_report(&self, report: &mut HapticReport) {
        let c = &self.counters;
        report.ticks = c.ticks;
        report.poses_published = c.poses_published;
        report.publish_errors = c.publish_errors;
        report.forces_received = self.inbox.received();
        report.longest_command_gap_ms = c.longest_command_gap_ms;
        report.keepalives_received = c.keepalives_received;
        report.round_trip.copy_from(&self.round_trip);
        report.wire_round_trip.copy_from(&self.wire_round_trip);
        report.last_round_trip_us = self.last_round_trip_us;
        report
            .interval_deviation
            .copy_from(&self.interval_deviation);
        report.overruns = c.overruns;
        report.max_rendered_force_n = c.max_rendered_force_n;
        report.last_rendered_force_n = c.last_rendered_force_n;
        report.last_commanded_force_n = c.last_commanded_force_n;
        report.last_position_mm = c.last_position_mm;
        report.safety = self.safety.counters();
        report.passivity = self.passivity.counters();
        report.phase = self.phase.counters();
        report.decode_rejects = self.inbox.rejects();
        report.device_read_errors = c.device_read_errors;
        report.device_write_errors = c.device_write_errors;
        report.models_received = c.models_received;
        report.moderated = self.mode.moderated();
        report.mode_policy = self.mode.policy().name();
        report.mode_switches = self.mode.switches();
        report.smoothed_rtt_ms = self.mode.smoothed_rtt_ms().unwrap_or(0.0);
        report.energy_allowance_mj = self.allowance_mj;
        report.needle_pops = self.renderer.pops();
        report.last_second = self.stillness.last();
    }

    /// Publish into the shared report if nobody holds it right now. Never blocks; returns whether it published.
    pub fn try_publish_report(&self, shared: &Mutex<HapticReport>) -> bool {
        match shared.try_lock() {
            Ok(mut report) => {
                self.write_report(&mut report);
                true
            }
            Err(_) => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hand_script::HandScript;
    use crate::safety::SafetyConfig;
    use crate::sim_device::SimDevice;
    use sinew_protocol::codec::encode_to_vec as encode_from;
    use sinew_protocol::{ForceCommand, InstanceId, decode};

    const PERIOD: Duration = Duration::from_millis(1);
    const ME: InstanceId = InstanceId(0x1e);

    /// A command for this device from the one server of these tests.
    fn encode_to_vec(command: &ForceCommand) -> Vec<u8> {
        let command = ForceCommand {
            device_instance: ME.0,
            ..*command
        };
        encode_from(InstanceId(0x5e), &command)
    }

    fn make_loop(inbox: &Arc<ForceInbox>) -> HapticLoop {
        let device = SimDevice::new(HandScript::Hold {
            position_mm: [0.0; 3],
        });
        // No ramp-in: these tests check the first commanded forces against the rate limit directly.
        let safety = ForceSafety::new(SafetyConfig {
            ramp_in_s: 0.0,
            ..SafetyConfig::new(3.3)
        })
        .unwrap();
        HapticLoop::new(Box::new(device), safety, inbox.clone(), PERIOD)
    }

    /// Where a pressing hand is after `ticks` ticks `every` apart, mm (z).
    fn pressed_hand_z_mm(ticks: u64, every: Duration) -> f32 {
        let inbox = Arc::new(ForceInbox::new(ME));
        let device = SimDevice::new(HandScript::Press {
            at_mm: [0.0; 3],
            depth_mm: 10.0,
            approach_mm: 10.0,
            descend_s: 1.0,
        });
        let safety = ForceSafety::new(SafetyConfig::new(3.3)).unwrap();
        let mut haptic = HapticLoop::new(Box::new(device), safety, inbox, PERIOD);
        haptic.record_trace(1024);
        let step_ns = u64::try_from(every.as_nanos()).unwrap();
        haptic.tick(step_ns, None, &mut |_: &[u8]| true);
        for k in 2..=ticks {
            haptic.tick(k * step_ns, Some(every), &mut |_: &[u8]| true);
        }
        haptic.trace().samples().last().unwrap().position_mm[2]
    }

    #[test]
    fn a_simulated_hand_keeps_to_wall_time_when_the_loop_skips_periods() {
        // 501 ticks 1 ms apart and 26 ticks 20 ms apart both end 0.5 s after the first: the hand is halfway
        // down either way (a loop that skipped periods in a stall does not leave its script behind).
        let paced = pressed_hand_z_mm(501, PERIOD);
        let stalled = pressed_hand_z_mm(26, Duration::from_millis(20));
        assert!((paced - 0.0).abs() < 0.5, "paced hand at {paced} mm");
        // The hand model extrapolates its target over each read's interval: a 20 ms read runs 0.4 mm ahead
        // at this 20 mm/s descent. A loop whose script counted ticks would still be 9.5 mm up.
        assert!(
            (stalled - paced).abs() < 0.5,
            "stalled loop's hand at {stalled} mm, paced {paced} mm"
        );
        assert_eq!(read_interval_s(None, 0.001), 0.001);
        assert_eq!(read_interval_s(Some(Duration::ZERO), 0.001), 0.001);
        assert_eq!(
            read_interval_s(Some(Duration::from_secs(9)), 0.001),
            MAX_READ_INTERVAL_S
        );
    }

    #[test]
    fn poses_carry_sequence_time_and_round_trip() {
        let inbox = Arc::new(ForceInbox::new(ME));
        let mut haptic = make_loop(&inbox);
        let mut sent: Vec<DevicePose> = Vec::new();
        let mut sink = |bytes: &[u8]| {
            sent.push(decode::<DevicePose>(bytes).unwrap());
            true
        };
        let ms = 1_000_000u64;
        haptic.tick(ms, None, &mut sink);
        haptic.tick(2 * ms, Some(PERIOD), &mut sink);
        // The server answers pose 2 and its answer arrives 300 us later.
        let answer = ForceCommand {
            seq: 1,
            echo_pose_seq: 2,
            echo_device_time_ns: 2 * ms,
            force_n: [0.0, 0.0, 1.0],
            ..ForceCommand::default()
        };
        inbox
            .accept(&encode_to_vec(&answer), 2 * ms + 300_000)
            .unwrap();
        let force = haptic.tick(3 * ms, Some(PERIOD), &mut sink);
        haptic.tick(4 * ms, Some(PERIOD), &mut sink);
        let seqs: Vec<u64> = sent.iter().map(|p| p.seq).collect();
        assert_eq!(seqs, [1, 2, 3, 4]);
        assert_eq!(sent[1].device_time_ns, 2 * ms);
        assert_eq!(sent[2].round_trip_us, 0, "measured after pose 3 was read");
        assert_eq!(sent[3].round_trip_us, 1000);
        assert!(
            (force[2] - 0.2).abs() < 1e-6,
            "rate limited first step: {force:?}"
        );

        let mut report = HapticReport::new("left");
        haptic.write_report(&mut report);
        assert_eq!(report.ticks, 4);
        assert_eq!(report.poses_published, 4);
        assert_eq!(report.forces_received, 1);
        assert_eq!(report.round_trip.count(), 1);
        assert_eq!(report.last_commanded_force_n, [0.0, 0.0, 1.0]);
        assert!((report.last_rendered_force_n[2] - 0.4).abs() < 1e-6);
    }

    #[test]
    fn a_repeated_sequence_number_keeps_the_stream_alive_and_nothing_else() {
        let inbox = Arc::new(ForceInbox::new(ME));
        let mut haptic = make_loop(&inbox);
        let mut sink = |_: &[u8]| true;
        let ms = 1_000_000u64;
        haptic.tick(ms, None, &mut sink);
        let command = ForceCommand {
            seq: 7,
            echo_pose_seq: 1,
            echo_device_time_ns: ms,
            force_n: [0.0, 0.0, 1.0],
            ..ForceCommand::default()
        };
        inbox.accept(&encode_to_vec(&command), 2 * ms).unwrap();
        // The server's sim runs slow: its keepalive repeats command 7 every 8 ms for 200 ms, well past the
        // 50 ms silence rule, and the force stays on.
        for tick in 2..=200u64 {
            if tick > 2 && tick % 8 == 2 {
                inbox.accept(&encode_to_vec(&command), tick * ms).unwrap();
            }
            haptic.tick(tick * ms, Some(PERIOD), &mut sink);
            assert!(!haptic.safety().is_stale(), "stale at {tick} ms");
        }
        assert_eq!(haptic.rendered_force_n(), [0.0, 0.0, 1.0]);
        let mut report = HapticReport::new("left");
        haptic.write_report(&mut report);
        assert_eq!(report.forces_received, 25);
        assert_eq!(report.keepalives_received, 24);
        assert_eq!(report.round_trip.count(), 1, "a keepalive is no round trip");
        assert!(report.longest_command_gap_ms <= 8.0);
        // Silence: the rule fires 50 ms after the last keepalive.
        for tick in 201..=260u64 {
            haptic.tick(tick * ms, Some(PERIOD), &mut sink);
        }
        assert!(haptic.safety().is_stale());
    }

    #[test]
    fn foreign_echoes_are_not_round_trips_and_shutdown_ramps_to_zero() {
        let inbox = Arc::new(ForceInbox::new(ME));
        let mut haptic = make_loop(&inbox);
        let mut sink = |_: &[u8]| true;
        let ms = 1_000_000u64;
        // An echo of a pose this server never sent (a previous run): rendered, but no round trip.
        let stray = ForceCommand {
            echo_pose_seq: 1000,
            echo_device_time_ns: 5,
            force_n: [1.0, 0.0, 0.0],
            ..ForceCommand::default()
        };
        for tick in 1..=40u64 {
            inbox.accept(&encode_to_vec(&stray), tick * ms).unwrap();
            haptic.tick(tick * ms, Some(PERIOD), &mut sink);
        }
        assert_eq!(haptic.rendered_force_n(), [1.0, 0.0, 0.0]);
        let mut report = HapticReport::new("left");
        haptic.write_report(&mut report);
        assert_eq!(report.round_trip.count(), 0);

        haptic.begin_shutdown();
        let mut tick = 41u64;
        while haptic.rendered_force_n() != [0.0; 3] && tick < 100 {
            inbox.accept(&encode_to_vec(&stray), tick * ms).unwrap();
            haptic.tick(tick * ms, Some(PERIOD), &mut sink);
            tick += 1;
        }
        assert!(tick <= 41 + 21, "ramp took {} ticks", tick - 41);
        assert_eq!(haptic.rendered_force_n(), [0.0; 3]);
    }
}
