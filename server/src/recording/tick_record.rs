//! What one server tick hands the recorder: every input of [`crate::server_tick::ServerTick::step`] and every
//! force command it produced, as a fixed-size value (no allocation on the sim thread).

use serde::{Deserialize, Serialize};
use sinew_protocol::{DevicePose, ForceCommand};

use crate::server_tick::PoseInput;
use crate::training::SessionEvent;

/// The most tools a recorded world may have (the record is a fixed array, copied through a bounded queue).
pub const MAX_RECORDED_TOOLS: usize = 8;

/// The most training events one tick records (more are counted in [`TickRecord::events_dropped`]).
pub const MAX_TICK_EVENTS: usize = 16;

/// One device's part of a tick: the pose the tick saw (with its age and whether the device could drive), the
/// device's announced force limit, and the command the tick produced for it.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct DeviceTick {
    /// The newest pose, None before the first.
    pub pose: Option<DevicePose>,
    /// Its age when the tick read it, s (the wall-clock part of the input, recorded so replay needs no clock).
    pub age_s: f64,
    /// The device could drive its tool (present, not refused).
    pub usable: bool,
    /// The device's announced force limit, N.
    pub max_force_n: Option<f32>,
    /// The force command the tick produced (None: nothing sent this tick).
    pub force: Option<ForceCommand>,
}

impl DeviceTick {
    /// The tick's view of this device's pose.
    pub fn pose_input(&self) -> Option<PoseInput> {
        self.pose.map(|pose| PoseInput {
            pose,
            age_s: self.age_s,
            usable: self.usable,
        })
    }
}

/// One tick as recorded. `Copy`, so the sim thread hands it over without allocating.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickRecord {
    /// Tick index from the start of the server (0-based).
    pub tick: u64,
    /// Tools in the world (the first `tools` entries of `devices` are used).
    pub tools: u8,
    /// Per tool-bound device, in world order.
    pub devices: [DeviceTick; MAX_RECORDED_TOOLS],
    /// The training layer's events of this tick (the first `event_count`): a view for Foxglove and the
    /// instructor; replay derives them again and never reads these.
    pub events: [Option<SessionEvent>; MAX_TICK_EVENTS],
    /// Events past [`MAX_TICK_EVENTS`] this tick, not recorded.
    pub events_dropped: u32,
}

impl TickRecord {
    /// A record of tick `tick` from the tick's inputs and outputs (extra tools beyond the maximum are cut; the
    /// recorder refuses such worlds at start).
    pub fn new(
        tick: u64,
        inputs: &[Option<PoseInput>],
        limits: &[Option<f32>],
        commands: &[Option<ForceCommand>],
    ) -> Self {
        let tools = inputs.len().min(MAX_RECORDED_TOOLS);
        let mut devices = [DeviceTick::default(); MAX_RECORDED_TOOLS];
        for (t, device) in devices.iter_mut().enumerate().take(tools) {
            let input = inputs[t];
            *device = DeviceTick {
                pose: input.map(|i| i.pose),
                age_s: input.map_or(0.0, |i| i.age_s),
                usable: input.is_some_and(|i| i.usable),
                max_force_n: limits.get(t).copied().flatten(),
                force: commands.get(t).copied().flatten(),
            };
        }
        Self {
            tick,
            tools: tools as u8,
            devices,
            events: [None; MAX_TICK_EVENTS],
            events_dropped: 0,
        }
    }

    /// Add one of the tick's events (counted as dropped past [`MAX_TICK_EVENTS`]).
    pub fn push_event(&mut self, event: SessionEvent) {
        match self.events.iter_mut().find(|slot| slot.is_none()) {
            Some(slot) => *slot = Some(event),
            None => self.events_dropped += 1,
        }
    }

    /// The recorded events.
    pub fn events(&self) -> impl Iterator<Item = &SessionEvent> {
        self.events.iter().map_while(Option::as_ref)
    }

    /// The used entries.
    pub fn devices(&self) -> &[DeviceTick] {
        &self.devices[..usize::from(self.tools).min(MAX_RECORDED_TOOLS)]
    }
}

/// The exact form of a tick in the file (postcard): what replay reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TickMessage {
    /// Tick index.
    pub tick: u64,
    /// Per tool-bound device.
    pub devices: Vec<DeviceTick>,
}

impl From<&TickRecord> for TickMessage {
    fn from(record: &TickRecord) -> Self {
        Self {
            tick: record.tick,
            devices: record.devices().to_vec(),
        }
    }
}

/// The tissue when the recording ended: every object's node positions, mm, in world order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FinalState {
    /// Ticks run.
    pub ticks: u64,
    /// Per object, per node.
    pub positions_mm: Vec<Vec<[f32; 3]>>,
}
