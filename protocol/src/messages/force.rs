//! Force command: server -> hapticserver.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};

/// How the hapticserver should render a [`ForceCommand`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum ForceMode {
    /// Latency-dependent mode: render `force_n` as it is (after device-side safety). Right on a LAN.
    #[default]
    Direct,
}

/// The force the server computed for a device's latest pose.
///
/// Direction: server -> hapticserver, on `sinew/<scene>/device/<id>/force`. Rate: one per server tick (1 kHz)
/// while the device's tool is bound. Reliability: best effort, congestion drop, express.
/// Units: newtons, in the device frame. The server has already clamped it to the device's announced maximum;
/// the hapticserver clamps again (it owns the motor).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct ForceCommand {
    /// Monotonic sequence number, per device.
    pub seq: u64,
    /// `seq` of the pose this force answers.
    pub echo_pose_seq: u64,
    /// `device_time_ns` of the pose this force answers: now minus this is the round trip.
    pub echo_device_time_ns: u64,
    /// Force to render on the stylus, newtons, device frame.
    pub force_n: [f32; 3],
    /// How to render it.
    pub mode: ForceMode,
    /// The tool touches tissue.
    pub in_contact: bool,
}

impl Message for ForceCommand {
    const KIND: MessageKind = MessageKind::ForceCommand;
    fn validate(&self) -> Result<(), FieldError> {
        check::finite("force_n", &self.force_n)
    }
}
