//! The dedicated 1 kHz sim thread.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sinew_protocol::rt::{LatencyHistogram, Pacer};
use sinew_protocol::{ForceCommand, ForceMode, encode};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

use super::device_slots::PoseArrival;
use super::{ServerError, Shared};
use crate::sim::{Sim, ToolCommand, ToolOutput};
use crate::tissue::Vec3;

/// Per-device counters kept by the sim thread.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceReport {
    /// Its tool is active (device present, poses fresh).
    pub active: bool,
    /// Force commands published.
    pub forces_sent: u64,
    /// Largest force magnitude published, N.
    pub max_force_n: f32,
    /// The device's last reported round trip, us.
    pub last_round_trip_us: u32,
}

/// What the sim thread reports (copied out every 100 ticks without blocking).
#[derive(Debug, Clone)]
pub struct SimReport {
    /// Ticks run.
    pub ticks: u64,
    /// Periods skipped because a tick started late.
    pub overruns: u64,
    /// Steps whose state went non-finite and was reset.
    pub faults: u64,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Whole-tick compute time (inputs, step, force publishing), ns.
    pub tick_time: LatencyHistogram,
    /// Per tool-bound device.
    pub devices: Vec<DeviceReport>,
}

impl SimReport {
    /// Empty report for `tools` tools.
    pub fn new(tools: usize) -> Self {
        Self {
            ticks: 0,
            overruns: 0,
            faults: 0,
            sim_time_s: 0.0,
            tick_time: LatencyHistogram::new(),
            devices: vec![DeviceReport::default(); tools],
        }
    }

    /// Overwrite with `other`, no allocation.
    pub fn copy_from(&mut self, other: &SimReport) {
        self.ticks = other.ticks;
        self.overruns = other.overruns;
        self.faults = other.faults;
        self.sim_time_s = other.sim_time_s;
        self.tick_time.copy_from(&other.tick_time);
        self.devices.copy_from_slice(&other.devices);
    }
}

pub(super) fn spawn(
    session: &zenoh::Session,
    shared: Arc<Shared>,
    sim: Sim,
    spin_native_accuracy_ns: u32,
) -> Result<JoinHandle<()>, ServerError> {
    let mut publishers = Vec::with_capacity(sim.tools.len());
    for tool in &sim.tools {
        publishers.push(
            session
                .declare_publisher(shared.keys.device_force(&tool.device_id)?)
                .congestion_control(CongestionControl::Drop)
                .express(true)
                .wait()?,
        );
    }
    std::thread::Builder::new()
        .name("sinew-sim".into())
        .spawn(move || run(&shared, sim, &publishers, spin_native_accuracy_ns))
        .map_err(|e| ServerError::Thread(e.to_string()))
}

fn run(
    shared: &Shared,
    mut sim: Sim,
    publishers: &[zenoh::pubsub::Publisher<'static>],
    spin_native_accuracy_ns: u32,
) {
    let world = &shared.world;
    let n = sim.tools.len();
    let tick_dt_s = (1.0 / world.tick_hz) as f32;
    let ticks_per_frame = (world.tick_hz / world.publish_hz).round().max(1.0) as u64;
    let pose_timeout = Duration::from_secs_f64(world.pose_timeout_s);
    let mut pacer = Pacer::new(
        Duration::from_secs_f64(1.0 / world.tick_hz),
        spin_native_accuracy_ns,
    );

    let mut commands = vec![ToolCommand::default(); n];
    let mut outputs = vec![ToolOutput::default(); n];
    let mut seen = vec![0u64; n];
    let mut last_pose: Vec<Option<PoseArrival>> = vec![None; n];
    let mut was_active = vec![false; n];
    let mut force_seq = vec![0u64; n];
    let mut local = SimReport::new(n);
    let mut buf = Vec::with_capacity(128);
    let mut frame_due = false;

    while !shared.stop.load(Ordering::Acquire) {
        pacer.wait();
        let start = Instant::now();
        for t in 0..n {
            let Some(slot) = shared.slots.get(t) else {
                continue;
            };
            if let Some(arrival) = slot.pose.take_newer(&mut seen[t]) {
                last_pose[t] = Some(arrival);
            }
            let usable =
                !slot.gone.load(Ordering::Acquire) && !slot.refused.load(Ordering::Acquire);
            commands[t] = match last_pose[t] {
                Some(a) if usable && start.saturating_duration_since(a.received) < pose_timeout => {
                    ToolCommand {
                        active: true,
                        position_device_mm: a.pose.position_mm,
                        orientation_xyzw: a.pose.orientation_xyzw,
                    }
                }
                _ => ToolCommand::default(),
            };
        }

        let report = sim.step(tick_dt_s, &commands, &mut outputs);
        local.faults += u64::from(report.faults);

        for t in 0..n {
            let active = commands[t].active;
            local.devices[t].active = active;
            if !active && !was_active[t] {
                continue;
            }
            let (Some(slot), Some(publisher)) = (shared.slots.get(t), publishers.get(t)) else {
                continue;
            };
            // Released this tick: one explicit zero, then silence (the device ramps down on its own).
            let force = if active {
                let limit = slot
                    .hello_max_force_n()
                    .map_or(sim.tools[t].max_force_n, |m| {
                        m.min(sim.tools[t].max_force_n)
                    });
                clamp_finite(outputs[t].force_world_n, limit)
            } else {
                Vec3::zeros()
            };
            let echo = last_pose[t].map(|a| a.pose).unwrap_or_default();
            force_seq[t] += 1;
            encode(
                &ForceCommand {
                    seq: force_seq[t],
                    echo_pose_seq: echo.seq,
                    echo_device_time_ns: echo.device_time_ns,
                    force_n: [force.x, force.y, force.z],
                    mode: ForceMode::Direct,
                    in_contact: active && outputs[t].in_contact,
                },
                &mut buf,
            );
            // A failed put (session closing) is not fatal to the tick; the device ramps down on silence.
            let _ = publisher.put(buf.as_slice()).wait();
            let d = &mut local.devices[t];
            d.forces_sent += 1;
            d.max_force_n = d.max_force_n.max(force.norm());
            d.last_round_trip_us = echo.round_trip_us;
            was_active[t] = active;
        }

        frame_due |= sim.steps().is_multiple_of(ticks_per_frame);
        if frame_due && shared.frames.try_offer(&sim, &outputs) {
            frame_due = false;
        }
        local.ticks += 1;
        local.overruns = pacer.overruns();
        local.sim_time_s = sim.time_s();
        local.tick_time.record(start.elapsed());
        if local.ticks.is_multiple_of(100)
            && let Ok(mut shared_report) = shared.report.try_lock()
        {
            shared_report.copy_from(&local);
        }
    }
    if let Ok(mut shared_report) = shared.report.lock() {
        shared_report.copy_from(&local);
    }
}

/// Clamp to `limit_n`; a non-finite force becomes zero. Pure, no allocation.
fn clamp_finite(force: Vec3, limit_n: f32) -> Vec3 {
    if !force.iter().all(|c| c.is_finite()) {
        return Vec3::zeros();
    }
    let magnitude = force.norm();
    if magnitude > limit_n {
        force * (limit_n / magnitude)
    } else {
        force
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn server_side_clamp_limits_and_zeroes_non_finite() {
        assert_eq!(
            clamp_finite(Vec3::new(f32::NAN, 0.0, 0.0), 3.0),
            Vec3::zeros()
        );
        assert!((clamp_finite(Vec3::new(0.0, 0.0, 9.0), 2.0).z - 2.0).abs() < 1e-6);
        assert_eq!(
            clamp_finite(Vec3::new(0.0, 1.0, 0.0), 2.0),
            Vec3::new(0.0, 1.0, 0.0)
        );
    }
}
