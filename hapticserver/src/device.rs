//! The haptic device abstraction: what the 1 kHz loop needs from any backend.
//!
//! Owns: the [`Device`] trait, the device's static description ([`DeviceModel`]), one sample of its sensors
//! ([`DeviceReading`]) and its errors ([`DeviceError`]); and, in `device/`, the backends that implement it: the
//! simulated hand ([`sim_device`], [`hand_model`], [`hand_script`]), a recorded hand ([`replay_device`]), the
//! vendor's HD API behind feature `openhaptics` (`openhaptics`), and the mounting calibration that wraps any of
//! them ([`calibration`]).
//!
//! Must not: know about zenoh, the wire format or force safety. A backend renders exactly the force it is given;
//! [`crate::safety::ForceSafety`] is the only code that decides that force.

pub mod calibration;
pub mod hand_model;
pub mod hand_script;
#[cfg(feature = "openhaptics")]
pub mod openhaptics;
pub mod replay_device;
pub mod sim_device;

use thiserror::Error;

/// Static description of a device, read once at start.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceModel {
    /// Model name announced in the hello, e.g. "sim-hand" or "Touch".
    pub name: String,
    /// Largest force the motors may render, newtons.
    pub max_force_n: f32,
    /// Largest force change the device tolerates, newtons per second (the safety default is 200 N/s; the
    /// effective limit is the smaller of the two).
    pub max_force_rate_n_per_s: f32,
    /// Lower corner of the reachable workspace, device frame, mm.
    pub workspace_min_mm: [f32; 3],
    /// Upper corner of the reachable workspace, device frame, mm.
    pub workspace_max_mm: [f32; 3],
}

/// One sample of the device's sensors, in the device frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceReading {
    /// Stylus tip position, mm.
    pub position_mm: [f32; 3],
    /// Stylus orientation, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
    /// Stylus tip linear velocity, mm/s.
    pub linear_velocity_mm_s: [f32; 3],
    /// Button bitmask (bit 0 = primary).
    pub buttons: u32,
    /// Jaw (grasper) opening angle, radians; 0 for a probe.
    pub jaw_angle_rad: f32,
}

impl DeviceReading {
    /// Every field is finite (a reading that is not must not be published).
    pub fn is_finite(&self) -> bool {
        self.position_mm
            .iter()
            .chain(&self.orientation_xyzw)
            .chain(&self.linear_velocity_mm_s)
            .chain(std::iter::once(&self.jaw_angle_rad))
            .all(|c| c.is_finite())
    }
}

impl Default for DeviceReading {
    fn default() -> Self {
        Self {
            position_mm: [0.0; 3],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            linear_velocity_mm_s: [0.0; 3],
            buttons: 0,
            jaw_angle_rad: 0.0,
        }
    }
}

/// Why a device call failed. Variants carry no heap data so the hot loop can receive them without allocating.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DeviceError {
    /// The device is unplugged or was never opened.
    #[error("device is not connected")]
    NotConnected,
    /// The backend reported a fault (driver error code and what was being done).
    #[error("device fault {code} while {during}")]
    Fault {
        /// Backend error code.
        code: i32,
        /// The operation that failed, e.g. "reading the pose".
        during: &'static str,
    },
    /// A force with a NaN or infinite component was refused (nothing was rendered).
    #[error("refused a non-finite force command")]
    NonFiniteForce,
    /// The sensors returned a non-finite value.
    #[error("device returned a non-finite {field}")]
    NonFiniteReading {
        /// Which field.
        field: &'static str,
    },
}

/// What a motor may be given for `force_n`: the force itself when every component is finite, else zero with
/// [`DeviceError::NonFiniteForce`] to return (the rule every backend's `write_force` follows).
pub fn finite_or_zero(force_n: [f32; 3]) -> ([f32; 3], Result<(), DeviceError>) {
    if force_n.iter().all(|c| c.is_finite()) {
        (force_n, Ok(()))
    } else {
        ([0.0; 3], Err(DeviceError::NonFiniteForce))
    }
}

/// A haptic device: read its pose, render a force.
///
/// Real-time contract for implementors: [`Device::read`] and [`Device::write_force`] are called from the 1 kHz
/// loop thread, once each per tick, read first. They must not allocate, block on locks, log, or panic (whatever
/// the input). `Send` because the loop thread owns the device.
pub trait Device: Send {
    /// The device's static description. Called once at start (may allocate).
    fn model(&self) -> DeviceModel;

    /// Sample the sensors. `dt_s` is the time since the previous read (the loop period), so simulated backends
    /// advance on it and tests run on virtual time; hardware backends may ignore it.
    fn read(&mut self, dt_s: f32) -> Result<DeviceReading, DeviceError>;

    /// Command the force the motors render until the next call, newtons, device frame.
    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError>;
}
