//! Force command: server -> hapticserver.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};
use crate::messages::local_model::LocalModel;

/// What a [`ForceCommand`] carries besides the streamed force.
///
/// The model is held inline, not boxed: a command is decoded into a stack value on the device's 1 kHz path,
/// which must not allocate (`hapticserver/tests/no_allocation.rs`); the `Direct` variant is the rare one (a
/// released tool's explicit zero).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[allow(clippy::large_enum_variant)]
pub enum ForceMode {
    /// The streamed force only (the explicit zero a released tool gets): render `force_n` as it is.
    #[default]
    Direct,
    /// The streamed force and the local model it came from. A device in direct (latency-dependent) mode
    /// renders `force_n`; one in latency-moderated mode evaluates the model against its current position every
    /// tick. Both are built from the same server tick, so a device can switch between them without a jump.
    LocalModel(LocalModel),
}

/// The force the server computed for a device's latest pose.
///
/// Direction: server -> hapticserver, on `sinew/<scene>/device/<id>/force`. Rate: one per server tick (1 kHz)
/// while the device's tool is bound and renders directly; for a device in latency-moderated mode only when
/// the model changed by more than the perceptual deadband, and at least every 7 ms (heartbeat).
/// Reliability: best effort (a UDP link where the transport has one), congestion drop, express.
/// Units: newtons, mm, device frame (the world frame shifted to the device's origin, no rotation). The server
/// has already clamped `force_n` to the device's announced maximum; the hapticserver clamps again (it owns
/// the motor).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct ForceCommand {
    /// Monotonic sequence number, per device.
    pub seq: u64,
    /// `seq` of the pose this force answers.
    pub echo_pose_seq: u64,
    /// `device_time_ns` of the pose this force answers: now minus this is the round trip.
    pub echo_device_time_ns: u64,
    /// Force to render on the stylus in direct mode, newtons, device frame: the tissue's force on the tool
    /// after the tick that used the pose this command answers (the local model's `f0`).
    pub force_n: [f32; 3],
    /// How to render it.
    pub mode: ForceMode,
    /// The tool touches tissue.
    pub in_contact: bool,
    /// The instance (envelope sender) of the device whose poses this answers: the one holding the device id.
    /// Another hapticserver started with the same id (refused by the server) must not render it.
    pub device_instance: u64,
    /// How long the answered pose waited at the server, microseconds: from its arrival to the start of the
    /// tick that first used it. A device in direct mode shifts its loop's phase with it, so its poses arrive
    /// just before the server's ticks (one device period of round trip). None when not measured (a replay, a
    /// release, the zeros after a failure).
    pub pose_wait_us: Option<u32>,
}

impl Message for ForceCommand {
    const KIND: MessageKind = MessageKind::ForceCommand;
    fn validate(&self) -> Result<(), FieldError> {
        check::finite("force_n", &self.force_n)?;
        match &self.mode {
            ForceMode::Direct => Ok(()),
            ForceMode::LocalModel(model) => model.validate(),
        }
    }
}
