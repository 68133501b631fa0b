//! Device pose: hapticserver -> server.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};

/// How a hapticserver renders the forces it gets (it tells the server, which then paces what it sends).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum RenderMode {
    /// Latency-dependent: the streamed force, every server tick.
    #[default]
    Direct,
    /// Latency-moderated: the local model against the current position; the server may send below 1 kHz.
    Moderated,
}

/// The pose and sensor state of one haptic device, in the device's own frame.
///
/// Direction: hapticserver -> server, on `sinew/<scene>/device/<id>/pose` (the id is in the key, not the body).
/// Rate: 1 kHz. Reliability: best effort, congestion drop, express (a late pose is worthless; the next replaces it).
/// Units: millimetres, mm/s, radians; `device_time_ns` is the hapticserver's monotonic clock, echoed back in the
/// [`crate::ForceCommand`] that answers it so the device can measure the round trip.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct DevicePose {
    /// Monotonic sequence number, per device.
    pub seq: u64,
    /// Device clock when the pose was read, nanoseconds since the hapticserver started.
    pub device_time_ns: u64,
    /// Stylus tip position in the device frame, mm.
    pub position_mm: [f32; 3],
    /// Stylus orientation in the device frame, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
    /// Stylus tip linear velocity in the device frame, mm/s.
    pub linear_velocity_mm_s: [f32; 3],
    /// Button bitmask (bit 0 = primary).
    pub buttons: u32,
    /// Jaw (grasper) opening angle, radians; 0 for a probe.
    pub jaw_angle_rad: f32,
    /// The device's latest measured pose->force round trip, microseconds (0 = not yet measured).
    pub round_trip_us: u32,
    /// How the device renders forces right now.
    pub render_mode: RenderMode,
}

impl Message for DevicePose {
    const KIND: MessageKind = MessageKind::DevicePose;
    fn validate(&self) -> Result<(), FieldError> {
        check::finite("position_mm", &self.position_mm)?;
        check::unit_quaternion("orientation_xyzw", &self.orientation_xyzw)?;
        check::finite("linear_velocity_mm_s", &self.linear_velocity_mm_s)?;
        check::finite("jaw_angle_rad", &[self.jaw_angle_rad])?;
        Ok(())
    }
}
