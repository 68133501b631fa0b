//! The mounting calibration of a device: where its frame sits in the scene's device frame, and a device
//! wrapper that applies it.
//!
//! Owns: [`WorldFromDevice`] (a rotation and an offset, parsed from `--mount-rotation-deg` and
//! `--mount-offset-mm`) and [`CalibratedDevice`], which maps every reading into the wire frame and every force
//! back into the hardware frame. Everything above the wrapper (the loop, the local-model renderer, force
//! safety, the wire) works in the wire frame: world axes, origin at the tool's `device_origin_in_world_mm` in the world
//! file. A rotation preserves lengths, so clamping and rate limiting give the same force in either frame.
//!
//! Frames: `hardware` is the frame the driver reports (a Touch: +y up, +z toward the user); `wire` is the
//! frame of [`sinew_protocol::DevicePose`] and [`sinew_protocol::ForceCommand`]. `wire = R hardware + t`.
//!
//! Must not: filter forces (that is [`crate::safety`]), allocate in `read`/`write_force`, or accept a
//! non-finite or non-orthonormal calibration.

use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};
use thiserror::Error;

use crate::device::{Device, DeviceError, DeviceModel, DeviceReading};

/// A calibration that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CalibrationError {
    /// The text is not three finite numbers.
    #[error("`{flag} {text}`: expected three finite numbers x,y,z")]
    BadVector {
        /// The flag or key it came from.
        flag: &'static str,
        /// What was given.
        text: String,
    },
    /// A number is out of range.
    #[error("`{flag}`: {message}")]
    OutOfRange {
        /// The flag or key it came from.
        flag: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// Largest offset accepted, mm (a device mounted a metre away from the tool origin is a typing error).
pub const MAX_MOUNT_OFFSET_MM: f32 = 1000.0;

/// Where the hardware frame sits in the wire frame: `wire = rotation * hardware + offset_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldFromDevice {
    rotation: Rotation3<f32>,
    offset_mm: Vector3<f32>,
}

impl Default for WorldFromDevice {
    fn default() -> Self {
        Self::identity()
    }
}

impl WorldFromDevice {
    /// No rotation, no offset: the hardware frame is the wire frame.
    pub fn identity() -> Self {
        Self {
            rotation: Rotation3::identity(),
            offset_mm: Vector3::zeros(),
        }
    }

    /// Rotate about the fixed x, then y, then z axes by `rotation_deg` (R = Rz Ry Rx), then shift by
    /// `offset_mm`. A device mounted upside down (a reach-in display) is `[180, 0, 0]`; a Touch on a desk,
    /// whose +y is up, in a scene whose +z is up, is `[90, 0, 0]`.
    pub fn from_degrees(
        rotation_deg: [f32; 3],
        offset_mm: [f32; 3],
    ) -> Result<Self, CalibrationError> {
        if !rotation_deg
            .iter()
            .all(|a| a.is_finite() && a.abs() <= 360.0)
        {
            return Err(CalibrationError::OutOfRange {
                flag: "--mount-rotation-deg",
                message: format!(
                    "{rotation_deg:?}: each angle must be finite, within +-360 degrees"
                ),
            });
        }
        if !offset_mm
            .iter()
            .all(|c| c.is_finite() && c.abs() <= MAX_MOUNT_OFFSET_MM)
        {
            return Err(CalibrationError::OutOfRange {
                flag: "--mount-offset-mm",
                message: format!(
                    "{offset_mm:?}: each component must be finite, within +-{MAX_MOUNT_OFFSET_MM} mm"
                ),
            });
        }
        let [rx, ry, rz] = rotation_deg.map(f32::to_radians);
        Ok(Self {
            rotation: Rotation3::from_euler_angles(rx, ry, rz),
            offset_mm: Vector3::from(offset_mm),
        })
    }

    /// Whether this is the identity (no wrapper needed).
    pub fn is_identity(&self) -> bool {
        *self == Self::identity()
    }

    /// A hardware-frame point in the wire frame, mm.
    pub fn point_to_wire(&self, hardware_mm: [f32; 3]) -> [f32; 3] {
        (self.rotation * Vector3::from(hardware_mm) + self.offset_mm).into()
    }

    /// A wire-frame point in the hardware frame, mm.
    pub fn point_to_hardware(&self, wire_mm: [f32; 3]) -> [f32; 3] {
        (self.rotation.inverse() * (Vector3::from(wire_mm) - self.offset_mm)).into()
    }

    /// A hardware-frame direction (velocity, force) in the wire frame.
    pub fn vector_to_wire(&self, hardware: [f32; 3]) -> [f32; 3] {
        (self.rotation * Vector3::from(hardware)).into()
    }

    /// A wire-frame direction (velocity, force) in the hardware frame.
    pub fn vector_to_hardware(&self, wire: [f32; 3]) -> [f32; 3] {
        (self.rotation.inverse() * Vector3::from(wire)).into()
    }

    /// A hardware-frame orientation (x, y, z, w) in the wire frame.
    pub fn orientation_to_wire(&self, hardware_xyzw: [f32; 4]) -> [f32; 4] {
        let [x, y, z, w] = hardware_xyzw;
        let device = UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z));
        let wire = UnitQuaternion::from_rotation_matrix(&self.rotation) * device;
        let q = wire.quaternion();
        [q.i, q.j, q.k, q.w]
    }

    /// The axis-aligned box in the wire frame that holds the hardware box `[min_mm, max_mm]`.
    pub fn box_to_wire(&self, min_mm: [f32; 3], max_mm: [f32; 3]) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for corner in 0..8 {
            let p = [
                if corner & 1 == 0 {
                    min_mm[0]
                } else {
                    max_mm[0]
                },
                if corner & 2 == 0 {
                    min_mm[1]
                } else {
                    max_mm[1]
                },
                if corner & 4 == 0 {
                    min_mm[2]
                } else {
                    max_mm[2]
                },
            ];
            let w = self.point_to_wire(p);
            for axis in 0..3 {
                lo[axis] = lo[axis].min(w[axis]);
                hi[axis] = hi[axis].max(w[axis]);
            }
        }
        (lo, hi)
    }
}

/// A device seen through its mounting calibration: readings in the wire frame, forces taken in the wire
/// frame and rendered in the hardware frame.
pub struct CalibratedDevice {
    inner: Box<dyn Device>,
    world_from_device: WorldFromDevice,
}

impl std::fmt::Debug for CalibratedDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CalibratedDevice")
            .field("world_from_device", &self.world_from_device)
            .finish_non_exhaustive()
    }
}

impl CalibratedDevice {
    /// `inner` mounted as `world_from_device` says.
    pub fn new(inner: Box<dyn Device>, world_from_device: WorldFromDevice) -> Self {
        Self {
            inner,
            world_from_device,
        }
    }

    /// `inner` itself when the calibration is the identity, else wrapped.
    pub fn wrap(inner: Box<dyn Device>, world_from_device: WorldFromDevice) -> Box<dyn Device> {
        if world_from_device.is_identity() {
            inner
        } else {
            Box::new(Self::new(inner, world_from_device))
        }
    }
}

impl Device for CalibratedDevice {
    /// The inner model with its workspace as a wire-frame box.
    fn model(&self) -> DeviceModel {
        let mut model = self.inner.model();
        let (lo, hi) = self
            .world_from_device
            .box_to_wire(model.workspace_min_mm, model.workspace_max_mm);
        model.workspace_min_mm = lo;
        model.workspace_max_mm = hi;
        model
    }

    fn read(&mut self, dt_s: f32) -> Result<DeviceReading, DeviceError> {
        let reading = self.inner.read(dt_s)?;
        let c = &self.world_from_device;
        Ok(DeviceReading {
            position_mm: c.point_to_wire(reading.position_mm),
            orientation_xyzw: c.orientation_to_wire(reading.orientation_xyzw),
            linear_velocity_mm_s: c.vector_to_wire(reading.linear_velocity_mm_s),
            ..reading
        })
    }

    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError> {
        if !force_n.iter().all(|c| c.is_finite()) {
            // The inner device refuses it too, and zeroes its motor.
            return self.inner.write_force(force_n);
        }
        self.inner
            .write_force(self.world_from_device.vector_to_hardware(force_n))
    }
}

/// Parse `x,y,z` for a calibration flag.
pub fn parse_vec3(flag: &'static str, text: &str) -> Result<[f32; 3], CalibrationError> {
    let bad = || CalibrationError::BadVector {
        flag,
        text: text.to_owned(),
    };
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut out = [0.0f32; 3];
    for (slot, part) in out.iter_mut().zip(parts) {
        *slot = part.trim().parse().map_err(|_| bad())?;
        if !slot.is_finite() {
            return Err(bad());
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3]) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-4)
    }

    #[test]
    fn upside_down_mount_flips_y_and_z() {
        let c = WorldFromDevice::from_degrees([180.0, 0.0, 0.0], [0.0; 3]).unwrap();
        assert!(close(c.point_to_wire([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0]));
        assert!(close(
            c.vector_to_hardware([0.0, 0.0, 1.0]),
            [0.0, 0.0, -1.0]
        ));
    }

    #[test]
    fn desk_touch_maps_its_up_axis_to_scene_up() {
        // A Touch's +y is up and +z points at the user; the scene's +z is up.
        let c = WorldFromDevice::from_degrees([90.0, 0.0, 0.0], [0.0, 0.0, 10.0]).unwrap();
        assert!(close(c.point_to_wire([0.0, 1.0, 0.0]), [0.0, 0.0, 11.0]));
        assert!(close(c.point_to_wire([0.0, 0.0, 1.0]), [0.0, -1.0, 10.0]));
        let p = [3.0, -4.0, 5.0];
        assert!(close(c.point_to_hardware(c.point_to_wire(p)), p));
        // The identity orientation of the stylus becomes the mount's rotation.
        let q = c.orientation_to_wire([0.0, 0.0, 0.0, 1.0]);
        let half = std::f32::consts::FRAC_PI_4;
        assert!((q[0] - half.sin()).abs() < 1e-5 && (q[3] - half.cos()).abs() < 1e-5);
    }

    #[test]
    fn bad_calibrations_are_refused() {
        assert!(WorldFromDevice::from_degrees([f32::NAN, 0.0, 0.0], [0.0; 3]).is_err());
        assert!(WorldFromDevice::from_degrees([0.0; 3], [0.0, 1e6, 0.0]).is_err());
        assert!(parse_vec3("--mount-rotation-deg", "1,2").is_err());
        assert!(parse_vec3("--mount-rotation-deg", "1,2,inf").is_err());
        assert_eq!(
            parse_vec3("--mount-offset-mm", " 1, 2,3").unwrap(),
            [1.0, 2.0, 3.0]
        );
    }

    #[test]
    fn workspace_box_is_rotated() {
        let c = WorldFromDevice::from_degrees([90.0, 0.0, 0.0], [0.0; 3]).unwrap();
        let (lo, hi) = c.box_to_wire([-1.0, -2.0, -3.0], [1.0, 2.0, 3.0]);
        assert!(
            close(lo, [-1.0, -3.0, -2.0]) && close(hi, [1.0, 3.0, 2.0]),
            "{lo:?} {hi:?}"
        );
    }
}
