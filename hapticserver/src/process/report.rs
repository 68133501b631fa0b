//! What a running hapticserver reports about itself.
//!
//! Owns: [`HapticReport`], the low-rate snapshot the device loop publishes (about every 100 ms, by `try_lock`, so
//! the loop never waits) and [`crate::HapticHandle::report`] hands out, and its one-line status text.
//!
//! Must not: be written from anywhere but the device loop (plus the inbox counters filled in by the handle).

use std::fmt;

use sinew_protocol::rt::LatencyHistogram;

use crate::force_inbox::DecodeRejects;
use crate::passivity::PassivityCounters;
use crate::phase_align::PhaseCounters;
use crate::safety::SafetyCounters;

/// A snapshot of a hapticserver's health and state.
#[derive(Debug, Clone)]
pub struct HapticReport {
    /// Device id.
    pub device_id: String,
    /// The device loop is running.
    pub running: bool,
    /// Loop ticks run.
    pub ticks: u64,
    /// Poses handed to zenoh.
    pub poses_published: u64,
    /// Poses zenoh refused.
    pub publish_errors: u64,
    /// Valid force commands received.
    pub forces_received: u64,
    /// The longest time between two commands the loop took, ms (0 before the second): how close the stream came
    /// to the silence rule.
    pub longest_command_gap_ms: f32,
    /// The server's keepalives received: its last command again, same sequence number, sent when its sim ran
    /// slower than real time (`sinew_server::node::keepalive`). Only a sign of life.
    pub keepalives_received: u64,
    /// Pose -> rendered force round trips (pose read to the tick that first renders the force answering it), ns.
    pub round_trip: LatencyHistogram,
    /// Pose read -> arrival of the force answering it (no wait for the device's next tick), ns.
    pub wire_round_trip: LatencyHistogram,
    /// The latest round trip, microseconds (0 = none yet).
    pub last_round_trip_us: u32,
    /// |actual tick interval - period|, ns.
    pub interval_deviation: LatencyHistogram,
    /// Periods skipped because the loop ran late (VM stalls).
    pub overruns: u64,
    /// Largest force magnitude rendered, N.
    pub max_rendered_force_n: f32,
    /// Force rendered on the latest tick, N, wire frame (before the mounting calibration).
    pub last_rendered_force_n: [f32; 3],
    /// The latest command's force before safety, N, device frame (zero before any command).
    pub last_commanded_force_n: [f32; 3],
    /// Stylus position on the latest tick, mm, wire frame (after the mounting calibration).
    pub last_position_mm: [f32; 3],
    /// How often each safety rule fired.
    pub safety: SafetyCounters,
    /// What the passivity controller did.
    pub passivity: PassivityCounters,
    /// What the phase alignment did (direct mode).
    pub phase: PhaseCounters,
    /// The device loop's scheduling (None until the loop has started).
    pub realtime: Option<sinew_protocol::rt::realtime::RealtimeGrant>,
    /// Refused force payloads.
    pub decode_rejects: DecodeRejects,
    /// Failed device reads.
    pub device_read_errors: u64,
    /// Failed device force writes.
    pub device_write_errors: u64,
    /// Local models received.
    pub models_received: u64,
    /// The local model is (becoming) the rendered force.
    pub moderated: bool,
    /// The mode policy: direct, moderated or auto.
    pub mode_policy: &'static str,
    /// Times the mode switched.
    pub mode_switches: u64,
    /// Smoothed pose -> force round trip, ms.
    pub smoothed_rtt_ms: f32,
    /// The energy allowance of the latest model, mJ.
    pub energy_allowance_mj: f64,
    /// Needle punctures the local model popped at the device, the tick the hand's push passed the threshold
    /// (`force/render/puncture_pop.rs`), not a round trip later.
    pub needle_pops: u32,
    /// Multilink: how long the start waited for the UDP link, ms (`Some(None)`: it never came, the device runs
    /// on TCP alone; `None`: no UDP endpoint was asked for).
    pub udp_link_wait_ms: Option<Option<f32>>,
    /// Why the device loop stopped by itself (it panicked; the force was ramped to zero first), if it did.
    pub loop_failure: Option<String>,
    /// Stillness of the rendered force and the stylus over the last whole second.
    pub last_second: crate::stillness::StillnessFigures,
    /// This run's instance id (the sender of its poses and hellos).
    pub instance: sinew_protocol::InstanceId,
    /// The link to the server, as the supervision thread last saw it.
    pub server_link: crate::server_watch::Link,
    /// This device's standing with the server (from its stats).
    pub standing: crate::server_watch::Standing,
    /// Valid force commands refused because another live server for the scene sent them.
    pub forces_from_other_server: u64,
    /// Valid force commands refused because they answered another instance using this device id.
    pub forces_for_other_instance: u64,
}

impl HapticReport {
    /// An empty report for `device_id` (allocates its histograms once).
    pub fn new(device_id: &str) -> Self {
        Self {
            device_id: device_id.to_owned(),
            running: false,
            ticks: 0,
            poses_published: 0,
            publish_errors: 0,
            forces_received: 0,
            longest_command_gap_ms: 0.0,
            keepalives_received: 0,
            round_trip: LatencyHistogram::new(),
            wire_round_trip: LatencyHistogram::new(),
            last_round_trip_us: 0,
            interval_deviation: LatencyHistogram::new(),
            overruns: 0,
            max_rendered_force_n: 0.0,
            last_rendered_force_n: [0.0; 3],
            last_commanded_force_n: [0.0; 3],
            last_position_mm: [0.0; 3],
            safety: SafetyCounters::default(),
            passivity: PassivityCounters::default(),
            phase: PhaseCounters::default(),
            realtime: None,
            decode_rejects: DecodeRejects::default(),
            device_read_errors: 0,
            device_write_errors: 0,
            models_received: 0,
            moderated: false,
            mode_policy: "auto",
            mode_switches: 0,
            smoothed_rtt_ms: 0.0,
            energy_allowance_mj: 0.0,
            needle_pops: 0,
            last_second: Default::default(),
            udp_link_wait_ms: None,
            loop_failure: None,
            instance: sinew_protocol::InstanceId::NONE,
            server_link: crate::server_watch::Link::NotFound,
            standing: crate::server_watch::Standing::Unknown,
            forces_from_other_server: 0,
            forces_for_other_instance: 0,
        }
    }

    /// Magnitude of the force rendered on the latest tick, N.
    pub fn last_rendered_force_magnitude_n(&self) -> f32 {
        let f = self.last_rendered_force_n;
        (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
    }
}

impl fmt::Display for HapticReport {
    /// One status line: ticks, round trip percentiles, force, position, problems.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.last_position_mm;
        write!(
            f,
            "{id}: {mode} ticks {ticks} rtt p50 {p50:.0} us p99 {p99:.0} us (n={n}) force {force:.2} N pos [{x:.1} {y:.1} {z:.1}] mm \
             forces_rx {rx} longest gap {gap:.1} ms keepalives {keepalives} overruns {over} stale {stale} clamped {clamped} rejects {rej} port energy {energy:+.2} mJ withheld {withheld:.2} mJ \
             udp {udp} server {server} ({standing})",
            id = self.device_id,
            mode = if self.moderated {
                "moderated"
            } else {
                "direct"
            },
            ticks = self.ticks,
            p50 = self.round_trip.percentile_us(50.0),
            p99 = self.round_trip.percentile_us(99.0),
            n = self.round_trip.count(),
            force = self.last_rendered_force_magnitude_n(),
            x = p[0],
            y = p[1],
            z = p[2],
            rx = self.forces_received,
            gap = self.longest_command_gap_ms,
            keepalives = self.keepalives_received,
            over = self.overruns,
            stale = self.safety.stale_events,
            clamped = self.safety.clamped,
            rej = self.decode_rejects.total(),
            energy = self.passivity.energy_mj,
            withheld = self.passivity.withheld_mj,
            udp = match self.udp_link_wait_ms {
                None => "not asked".to_owned(),
                Some(None) => "none (TCP alone)".to_owned(),
                Some(Some(ms)) => format!("up after {ms:.0} ms"),
            },
            server = match self.server_link {
                crate::server_watch::Link::NotFound => "none yet".to_owned(),
                crate::server_watch::Link::Joined(instance) => format!("{instance}"),
                crate::server_watch::Link::Lost { .. } => "LOST".to_owned(),
            },
            standing = self.standing,
        )
    }
}
