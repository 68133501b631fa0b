//! Participant hello: who is taking part, and with what device limits.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};

/// A participant's role in a scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Role {
    /// The authoritative simulation.
    Server,
    /// A hapticserver driving one device.
    Haptic,
    /// A viewer: reads the scene, never writes it.
    Viewer,
}

impl Role {
    /// The key segment used for presence tokens.
    pub fn key_segment(self) -> &'static str {
        match self {
            Role::Server => "server",
            Role::Haptic => "haptic",
            Role::Viewer => "viewer",
        }
    }
}

/// Announces a participant and, for a hapticserver, its device's limits.
///
/// Direction: any participant -> everyone, on `sinew/<scene>/hello/<role>/<id>`. Rate: on start, then 1 Hz
/// (so a server that starts later still learns it). Reliability: reliable, block.
/// Units: newtons. Presence itself (join/leave) is a zenoh liveliness token, not this message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParticipantHello {
    /// Participant id (also the key segment).
    pub participant_id: String,
    /// Its role.
    pub role: Role,
    /// Device model, e.g. "sim-hand" or "Touch"; empty for non-haptic roles.
    pub device_model: String,
    /// Largest force the device may render, newtons (0 for non-haptic roles).
    pub max_force_n: f32,
    /// Tool the device asks to drive (empty: whichever tool the world binds to this device id). The server
    /// refuses to bind a device whose requested tool is not the one the world gives it.
    pub tool: String,
}

impl Message for ParticipantHello {
    const KIND: MessageKind = MessageKind::ParticipantHello;
    fn validate(&self) -> Result<(), FieldError> {
        check::finite("max_force_n", &[self.max_force_n])?;
        if self.max_force_n < 0.0 {
            return Err(("max_force_n", "negative"));
        }
        if self.participant_id.is_empty() {
            return Err(("participant_id", "empty"));
        }
        Ok(())
    }
}
