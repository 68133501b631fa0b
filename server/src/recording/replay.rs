//! Replay: the recorded ticks re-run through [`ServerTick`] on virtual time, every force command and the final
//! tissue compared with the recording bit for bit.

use crate::scene::World;
use crate::server_tick::DeadbandParams;
use crate::server_tick::{PoseInput, ServerTick};
use crate::sim::{Sim, SimBuildError};
use crate::training::TickView;

use super::reader::Recording;
use super::tick_record::DeviceTick;

/// What a replay found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayOutcome {
    /// Ticks re-run.
    pub ticks: u64,
    /// Force commands compared (ticks x devices where either side had one).
    pub forces_compared: u64,
    /// Of those, how many differed in any bit.
    pub force_mismatches: u64,
    /// The first difference, described.
    pub first_mismatch: Option<String>,
    /// The recording had a final state and it was compared.
    pub final_compared: bool,
    /// Node coordinates that differed in any bit from the recorded final state.
    pub final_mismatches: u64,
    /// Ticks the recording is missing (dropped while recording, or damage): replay stops at the first gap.
    pub stopped_at_gap: Option<u64>,
    /// Simulated time re-run, s.
    pub sim_s: f64,
}

impl ReplayOutcome {
    /// Every force and the final tissue reproduced exactly.
    pub fn exact(&self) -> bool {
        self.force_mismatches == 0
            && self.stopped_at_gap.is_none()
            && self.final_compared
            && self.final_mismatches == 0
    }
}

/// Re-run `recording` on `world` (its own, loaded with [`Recording::load_world`]).
pub fn replay(recording: &Recording, world: &World) -> Result<ReplayOutcome, SimBuildError> {
    replay_observed(recording, world, |_| {})
}

/// [`replay`], showing `observe` every re-run tick (what the training layer measures).
pub fn replay_observed(
    recording: &Recording,
    world: &World,
    mut observe: impl FnMut(&TickView<'_>),
) -> Result<ReplayOutcome, SimBuildError> {
    replay_inspected(recording, world, |view, _| observe(view))
}

/// [`replay`], showing `inspect` every re-run tick and the tick itself (its tissue, for pictures).
pub fn replay_inspected(
    recording: &Recording,
    world: &World,
    mut inspect: impl FnMut(&TickView<'_>, &ServerTick),
) -> Result<ReplayOutcome, SimBuildError> {
    let sim = Sim::new(world)?;
    let n = sim.tools.len();
    let mut tick = ServerTick::new(
        sim,
        (1.0 / world.tick_hz) as f32,
        world.pose_timeout_s,
        DeadbandParams::default(),
    );
    let mut inputs: Vec<Option<PoseInput>> = vec![None; n];
    let mut limits: Vec<Option<f32>> = vec![None; n];
    let mut out = vec![None; n];
    let mut outcome = ReplayOutcome::default();
    for (expected_tick, record) in (0u64..).zip(&recording.ticks) {
        if record.tick != expected_tick || record.devices.len() != n {
            outcome.stopped_at_gap = Some(expected_tick);
            break;
        }
        for (t, device) in record.devices.iter().enumerate() {
            inputs[t] = device.pose_input();
            limits[t] = device.max_force_n;
        }
        let step = tick.step(&inputs, &limits, &mut out);
        inspect(
            &TickView {
                tick: record.tick,
                active: tick.tools_active(),
                outputs: tick.outputs(),
                step: &step,
            },
            &tick,
        );
        for (t, (device, replayed)) in record.devices.iter().zip(&out).enumerate() {
            if device.force.is_none() && replayed.is_none() {
                continue;
            }
            outcome.forces_compared += 1;
            if !same_bits(device, replayed) {
                outcome.force_mismatches += 1;
                if outcome.first_mismatch.is_none() {
                    outcome.first_mismatch = Some(format!(
                        "tick {}, device {t}: recorded {:?}, replayed {:?}",
                        record.tick, device.force, replayed
                    ));
                }
            }
        }
        outcome.ticks += 1;
    }
    outcome.sim_s = tick.sim().time_s();
    if let Some(state) = &recording.final_state
        && outcome.stopped_at_gap.is_none()
        && state.ticks == outcome.ticks
    {
        outcome.final_compared = true;
        for (o, recorded) in state.positions_mm.iter().enumerate() {
            let replayed = tick.positions_mm(o).unwrap_or_default();
            if replayed.len() != recorded.len() {
                outcome.final_mismatches += recorded.len() as u64 * 3;
                continue;
            }
            for (a, b) in recorded.iter().zip(replayed) {
                for k in 0..3 {
                    if a[k].to_bits() != b[k].to_bits() {
                        outcome.final_mismatches += 1;
                    }
                }
            }
        }
    }
    Ok(outcome)
}

/// The recorded and replayed commands are the same to the bit (the device instance and the pose's wait are the
/// node's stamps, not the tick's output, and are left out).
pub(crate) fn same_bits(
    device: &DeviceTick,
    replayed: &Option<sinew_protocol::ForceCommand>,
) -> bool {
    let strip = |c: &Option<sinew_protocol::ForceCommand>| {
        c.map(|mut c| {
            c.device_instance = 0;
            c.pose_wait_us = None;
            postcard::to_allocvec(&c).unwrap_or_default()
        })
    };
    strip(&device.force) == strip(replayed)
}
