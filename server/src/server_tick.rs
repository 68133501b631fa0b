//! One server tick without I/O: each device's newest pose in, the simulation step, force commands out.
//!
//! Owns: [`ServerTick`], the body of the 1 kHz sim loop: poses become tool commands (a pose older than the
//! world's `pose_timeout_s`, or from a device that left or was refused, releases the tool), [`Sim::step`]
//! runs, and each device's [`ModelStream`] turns its tool's output into a force command when one is due (a
//! released tool gets one explicit zero). The node's sim thread publishes what this returns; the virtual-time
//! drills in `tests/` drive the same code through an emulated network.
//!
//! Must not: touch zenoh, threads or the wall clock (ages come in as arguments).

use sinew_protocol::{DevicePose, ForceCommand};

pub mod model_stream;

use crate::sim::{Sim, StepReport, ToolCommand, ToolOutput};
use crate::tissue::Vec3;
pub use model_stream::{DeadbandParams, ModelStream, StreamCounters};

/// A device's newest pose as the tick sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseInput {
    /// The pose.
    pub pose: DevicePose,
    /// How long ago it arrived, s.
    pub age_s: f64,
    /// The device may drive its tool (present, not refused).
    pub usable: bool,
}

/// The loop body, with the simulation it owns.
#[derive(Debug)]
pub struct ServerTick {
    sim: Sim,
    dt_s: f32,
    pose_timeout_s: f64,
    commands: Vec<ToolCommand>,
    outputs: Vec<ToolOutput>,
    streams: Vec<ModelStream>,
    was_active: Vec<bool>,
    /// What the last step reported.
    last_step: StepReport,
}

impl ServerTick {
    /// A tick of `dt_s` over `sim`; a pose older than `pose_timeout_s` releases its tool.
    pub fn new(sim: Sim, dt_s: f32, pose_timeout_s: f64, deadband: DeadbandParams) -> Self {
        let n = sim.tools.len();
        let streams = sim
            .tools
            .iter()
            .map(|t| ModelStream::new(deadband, t.device_origin_in_world_mm))
            .collect();
        Self {
            sim,
            dt_s,
            pose_timeout_s,
            commands: vec![ToolCommand::default(); n],
            outputs: vec![ToolOutput::default(); n],
            streams,
            was_active: vec![false; n],
            last_step: StepReport::default(),
        }
    }

    /// What the last step reported (the same [`StepReport`] [`ServerTick::step`] returned).
    pub fn last_step(&self) -> &StepReport {
        &self.last_step
    }

    /// Run the tick's tail ([`Sim::finish_tick`]) once its force commands are published.
    pub fn finish_tick(&mut self) {
        self.sim.finish_tick();
    }

    /// The simulation.
    pub fn sim(&self) -> &Sim {
        &self.sim
    }

    /// Each tool's output from the last step.
    pub fn outputs(&self) -> &[ToolOutput] {
        &self.outputs
    }

    /// Per tool: a device drove it on the last step.
    pub fn tools_active(&self) -> &[bool] {
        &self.was_active
    }

    /// Tool `t`'s stream counters.
    pub fn stream_counters(&self, t: usize) -> StreamCounters {
        self.streams
            .get(t)
            .map(ModelStream::counters)
            .unwrap_or_default()
    }

    /// One tick. `poses[t]` is device `t`'s newest pose (None: never seen), `device_max_force_n[t]` its
    /// announced limit (None: unknown, the tool's applies). Writes each device's command into `out[t]`
    /// (None: nothing to send this tick). Real-time contract: no allocation once warm, never panics.
    pub fn step(
        &mut self,
        poses: &[Option<PoseInput>],
        device_max_force_n: &[Option<f32>],
        out: &mut [Option<ForceCommand>],
    ) -> StepReport {
        for (t, command) in self.commands.iter_mut().enumerate() {
            *command = match poses.get(t).copied().flatten() {
                Some(input) if input.usable && input.age_s < self.pose_timeout_s => ToolCommand {
                    active: true,
                    position_device_mm: input.pose.position_mm,
                    velocity_device_mm_s: input.pose.linear_velocity_mm_s,
                    orientation_xyzw: input.pose.orientation_xyzw,
                    jaws: crate::interaction::JawInput {
                        buttons: input.pose.buttons,
                        jaw_angle_rad: input.pose.jaw_angle_rad,
                    },
                },
                _ => ToolCommand::default(),
            };
        }
        let report = self.sim.step(self.dt_s, &self.commands, &mut self.outputs);
        self.last_step = report;
        let now_s = self.sim.time_s();
        for (t, slot) in out.iter_mut().enumerate() {
            *slot = None;
            let (Some(command), Some(tool), Some(stream)) = (
                self.commands.get(t),
                self.sim.tools.get(t),
                self.streams.get_mut(t),
            ) else {
                continue;
            };
            let pose = poses
                .get(t)
                .copied()
                .flatten()
                .map(|p| p.pose)
                .unwrap_or_default();
            let was_active = self.was_active[t];
            self.was_active[t] = command.active;
            if command.active {
                let limit = device_max_force_n
                    .get(t)
                    .copied()
                    .flatten()
                    .map_or(tool.max_force_n, |m| m.min(tool.max_force_n));
                *slot = stream.command(now_s, &self.outputs[t], &pose, limit);
            } else if was_active {
                *slot = Some(stream.release(&pose));
            }
        }
        report
    }

    /// The positions of object `object`, mm (for tests and the replication hand-off).
    pub fn positions_mm(&self, object: usize) -> Option<&[Vec3]> {
        self.sim
            .objects
            .get(object)
            .map(|o| o.state.positions_mm.as_slice())
    }
}
