//! A simulated haptic device: a scripted hand holding a stylus that the rendered force really pushes.
//!
//! Owns: script time, the current hand target and the force last written, and a [`HandModel`]. Each
//! [`Device::read`] advances script time by `dt_s`, samples the [`HandScript`] and integrates the stylus under
//! the hand and the last written force, so a force field resists the scripted motion exactly as it would
//! resist a surgeon's hand. A start time ([`SimDevice::with_start_at`]) holds the hand still at the
//! script's start, jaws open, until the wall clock reaches it (script time starts there), as a surgeon waits
//! for the scene to come up before moving; devices in several processes given one start time move together.
//!
//! Must not: filter or clamp forces beyond refusing non-finite ones (that is [`crate::safety`]); it renders
//! what it is given, like a motor.

use crate::device::{Device, DeviceError, DeviceModel, DeviceReading};
use crate::hand_model::{HandModel, HandParams, HandTarget};
use crate::hand_script::HandScript;

/// Model name announced for the simulated device.
pub const SIM_MODEL_NAME: &str = "sim-hand";

/// Limits of the simulated device: a Touch-like 3.3 N peak force in a generous +/-150 mm cube.
pub fn sim_device_model() -> DeviceModel {
    DeviceModel {
        name: SIM_MODEL_NAME.to_owned(),
        max_force_n: 3.3,
        max_force_rate_n_per_s: 200.0,
        workspace_min_mm: [-150.0; 3],
        workspace_max_mm: [150.0; 3],
    }
}

/// The simulated device.
#[derive(Debug)]
pub struct SimDevice {
    script: HandScript,
    hand: HandModel,
    model: DeviceModel,
    target: HandTarget,
    script_time_s: f64,
    force_n: [f32; 3],
    start_at: Option<std::time::Instant>,
}

impl SimDevice {
    /// A device whose hand follows `script`, with the default hand and limits. The stylus starts at rest on
    /// the script's first target.
    pub fn new(script: HandScript) -> Self {
        Self::with_params(script, HandParams::default(), sim_device_model())
    }

    /// A device with explicit hand parameters and limits.
    pub fn with_params(script: HandScript, params: HandParams, model: DeviceModel) -> Self {
        let start_mm = script.start_mm();
        Self {
            script,
            hand: HandModel::new(params, start_mm),
            model,
            target: HandTarget::at_rest(start_mm),
            script_time_s: 0.0,
            force_n: [0.0; 3],
            start_at: None,
        }
    }

    /// The script has started: no start time was set, or it has passed (read by [`DeviceBackend::read`]).
    pub fn started(&self) -> bool {
        self.start_at.is_none()
    }

    /// Hold the hand still at the script's start, jaws open, until `start_at`; script time starts at the
    /// first read at or after it.
    pub fn with_start_at(mut self, start_at: std::time::Instant) -> Self {
        self.start_at = Some(start_at);
        self
    }

    /// Script time, s (zero while waiting for the start time).
    pub fn script_time_s(&self) -> f64 {
        self.script_time_s
    }

    /// The hand's current target.
    pub fn target(&self) -> HandTarget {
        self.target
    }

    /// The force being rendered, N.
    pub fn force_n(&self) -> [f32; 3] {
        self.force_n
    }
}

impl Device for SimDevice {
    fn model(&self) -> DeviceModel {
        self.model.clone()
    }

    /// Advance script time and the stylus by `dt_s`. Real-time: no allocation, never panics.
    fn read(&mut self, dt_s: f32) -> Result<DeviceReading, DeviceError> {
        if let Some(start_at) = self.start_at {
            if std::time::Instant::now() >= start_at {
                self.start_at = None;
            }
        } else if dt_s.is_finite() && dt_s > 0.0 {
            self.script_time_s += f64::from(dt_s);
        }
        if self.start_at.is_some() {
            // Waiting for the start time: still at the start, jaws open.
            self.target = HandTarget::at_rest(self.script.start_mm());
            self.hand.step(dt_s, &self.target, self.force_n);
            self.hand
                .confine(self.model.workspace_min_mm, self.model.workspace_max_mm);
            return Ok(DeviceReading {
                position_mm: self.hand.position_mm(),
                orientation_xyzw: self.script.orientation_xyzw(0.0),
                linear_velocity_mm_s: self.hand.velocity_mm_s(),
                jaw_angle_rad: crate::hand_script::SCRIPT_JAW_OPEN_RAD,
                ..DeviceReading::default()
            });
        }
        if let Some(target) = self.script.target(self.script_time_s) {
            self.target = target;
        } else {
            // A Follow script with nothing new: hold the last target still.
            self.target.velocity_mm_s = [0.0; 3];
        }
        self.hand.step(dt_s, &self.target, self.force_n);
        self.hand
            .confine(self.model.workspace_min_mm, self.model.workspace_max_mm);
        let grip = self.script.grip(self.script_time_s);
        Ok(DeviceReading {
            position_mm: self.hand.position_mm(),
            orientation_xyzw: self.script.orientation_xyzw(self.script_time_s),
            linear_velocity_mm_s: self.hand.velocity_mm_s(),
            buttons: grip.buttons,
            jaw_angle_rad: grip.jaw_angle_rad,
        })
    }

    /// Render `force_n` from the next read on. A non-finite force is refused and the motor goes to zero.
    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError> {
        let (force_n, result) = crate::device::finite_or_zero(force_n);
        self.force_n = force_n;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hand_script::{ScriptKind, ScriptOptions};

    #[test]
    fn press_with_no_tissue_reaches_depth() {
        let options = ScriptOptions {
            descend_s: 0.5,
            depth_mm: 5.0,
            ..ScriptOptions::default()
        };
        let mut device = SimDevice::new(ScriptKind::Press.build(&options).unwrap());
        assert_eq!(device.read(0.0).unwrap().position_mm, [0.0, 0.0, 20.0]);
        let mut reading = DeviceReading::default();
        for _ in 0..1000 {
            reading = device.read(0.001).unwrap();
            device.write_force([0.0; 3]).unwrap();
        }
        assert!((reading.position_mm[2] + 5.0).abs() < 0.05, "{reading:?}");
        assert!((device.script_time_s() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_pose_path_turns_the_stylus_and_closes_the_jaws_as_planned() {
        use crate::hand_script::{PoseKey, PosePath};
        let quarter = std::f32::consts::FRAC_1_SQRT_2;
        let path = PosePath::new(vec![
            PoseKey {
                t_s: 0.0,
                position_mm: [0.0, 0.0, 10.0],
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                buttons: 0,
            },
            PoseKey {
                t_s: 1.0,
                position_mm: [0.0, 0.0, 10.0],
                orientation_xyzw: [0.0, quarter, 0.0, quarter],
                buttons: 1,
            },
        ])
        .unwrap();
        let mut device = SimDevice::new(HandScript::Path(std::sync::Arc::new(path)));
        let mut reading = DeviceReading::default();
        for k in 0..1200 {
            reading = device.read(0.001).unwrap();
            device.write_force([0.0; 3]).unwrap();
            if k == 499 {
                // Half way: a 45-degree turn about y, jaws still open.
                let [x, y, z, w] = reading.orientation_xyzw;
                let half = (22.5f32).to_radians();
                assert!(x.abs() < 1e-5 && z.abs() < 1e-5, "{reading:?}");
                assert!(
                    (y - half.sin()).abs() < 1e-3 && (w - half.cos()).abs() < 1e-3,
                    "{reading:?}"
                );
                assert_eq!(reading.buttons, 0);
            }
        }
        let [_, y, _, w] = reading.orientation_xyzw;
        assert!((y - quarter).abs() < 1e-5 && (w - quarter).abs() < 1e-5);
        assert_eq!(reading.buttons, 1);
        assert_eq!(reading.jaw_angle_rad, 0.0);
        assert!((reading.position_mm[2] - 10.0).abs() < 1e-3);
    }

    #[test]
    fn a_start_time_holds_the_hand_at_the_start_then_runs_the_script_from_zero() {
        let options = ScriptOptions {
            descend_s: 0.5,
            ..ScriptOptions::default()
        };
        let script = ScriptKind::GraspPull.build(&options).unwrap();
        let start_at = std::time::Instant::now() + std::time::Duration::from_millis(30);
        let mut delayed = SimDevice::new(script.clone()).with_start_at(start_at);
        let mut plain = SimDevice::new(script);
        // Read until the script starts (the clock is read inside `read`, so the loop cannot ask first without
        // racing it): every read before is the start pose, and the start is not before `start_at`.
        let mut held = 0;
        loop {
            let reading = delayed.read(0.001).unwrap();
            assert_eq!(delayed.script_time_s(), 0.0);
            if delayed.started() {
                assert!(std::time::Instant::now() >= start_at);
                break;
            }
            assert_eq!(reading.position_mm, [0.0, 0.0, 20.0]);
            assert_eq!(reading.buttons, 0);
            held += 1;
        }
        assert!(held > 0);
        // The first read past the start time was the script's time zero: from here the delayed device runs a
        // tick behind one that never waited (whose first read is at 1 ms).
        for _ in 0..1500 {
            // Past the close (0.8 s): the same motion and grip as the device that never waited.
            let (a, b) = (delayed.read(0.001).unwrap(), plain.read(0.001).unwrap());
            for axis in 0..3 {
                let d = (a.position_mm[axis] - b.position_mm[axis]).abs();
                // One tick of the descent (50 mm/s) at most.
                assert!(d < 0.06, "{d} mm apart: {a:?} {b:?}");
            }
        }
        assert!((delayed.script_time_s() - 1.5).abs() < 1e-6);
        assert_eq!(delayed.read(0.001).unwrap().buttons, 1);
    }

    #[test]
    fn rendered_force_resists_the_hand() {
        // A stiff floor at z = 0 rendered from the device's own position: the hand aims 5 mm below it and the
        // stylus settles where hand spring and floor balance: 0.4 (-5 - z) = 0.5 z  ->  z = -2.22 mm.
        let options = ScriptOptions {
            descend_s: 0.5,
            depth_mm: 5.0,
            ..ScriptOptions::default()
        };
        let mut device = SimDevice::new(ScriptKind::Press.build(&options).unwrap());
        let floor_n_per_mm = 0.5;
        let mut reading = DeviceReading::default();
        for _ in 0..2000 {
            reading = device.read(0.001).unwrap();
            let penetration_mm = (-reading.position_mm[2]).max(0.0);
            device
                .write_force([0.0, 0.0, floor_n_per_mm * penetration_mm])
                .unwrap();
        }
        let expected_mm = -5.0 * 0.4 / 0.9;
        assert!(
            (reading.position_mm[2] - expected_mm).abs() < 0.05,
            "{reading:?}"
        );
        assert!(
            device.target().position_mm[2] < reading.position_mm[2] - 2.0,
            "stylus lags the target"
        );
    }

    #[test]
    fn follow_tracks_targets_set_from_outside_and_holds_the_last() {
        let mailbox = std::sync::Arc::new(sinew_protocol::rt::LatestValue::new());
        let mut device = SimDevice::new(HandScript::Follow(mailbox.clone()));
        for _ in 0..100 {
            assert_eq!(device.read(0.001).unwrap().position_mm, [0.0; 3]);
        }
        mailbox.store([3.0, -4.0, 5.0]);
        let mut reading = DeviceReading::default();
        for _ in 0..500 {
            reading = device.read(0.001).unwrap();
        }
        let p = reading.position_mm;
        assert!(
            (p[0] - 3.0).abs() < 0.01 && (p[1] + 4.0).abs() < 0.01 && (p[2] - 5.0).abs() < 0.01,
            "{p:?}"
        );
    }

    #[test]
    fn non_finite_force_is_refused() {
        let mut device = SimDevice::new(HandScript::Hold {
            position_mm: [0.0; 3],
        });
        device.write_force([1.0, 0.0, 0.0]).unwrap();
        assert_eq!(
            device.write_force([f32::NAN, 0.0, 0.0]),
            Err(DeviceError::NonFiniteForce)
        );
        assert_eq!(device.force_n(), [0.0; 3]);
        let reading = device.read(0.001).unwrap();
        assert!(reading.position_mm.iter().all(|c| c.is_finite()));
    }
}
