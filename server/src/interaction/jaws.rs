//! The articulation of an instrument's jaws, from what its device reports.
//!
//! Owns: [`Jaws`], which turns a device's buttons or gripper angle ([`JawInput`]) into a closed/open state with
//! hysteresis and a drawn opening angle. Pure and allocation-free: it runs on the sim tick and replays bit for
//! bit from the recorded poses.

use super::JawActivation;

/// What the device says about the jaws this tick (`DevicePose.buttons`, `DevicePose.jaw_angle_rad`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JawInput {
    /// Button bits held.
    pub buttons: u32,
    /// Gripper opening, rad (devices without a gripper send 0).
    pub jaw_angle_rad: f32,
}

/// One instrument's jaws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jaws {
    activation: JawActivation,
    open_angle_rad: f32,
    closed: bool,
    angle_rad: f32,
}

impl Jaws {
    /// How fast button-driven jaws open and close, rad/s: 40 degrees in about 90 ms, as a grasper's
    /// ratchet-less handle closes.
    pub const SLEW_RAD_S: f32 = 8.0;

    /// Open jaws, driven by `activation`, opening to `open_angle_rad`.
    pub fn new(activation: JawActivation, open_angle_rad: f32) -> Self {
        Self {
            activation,
            open_angle_rad,
            closed: false,
            angle_rad: open_angle_rad,
        }
    }

    /// Jaws closed on something they were loaded with (a needle driver's on its needle).
    pub fn new_closed(activation: JawActivation, open_angle_rad: f32) -> Self {
        Self {
            activation,
            open_angle_rad,
            closed: true,
            angle_rad: 0.0,
        }
    }

    /// Closed (the activation says so, with hysteresis).
    pub fn closed(&self) -> bool {
        self.closed
    }

    /// Opening drawn by the viewers, rad (0 closed .. the spec's open angle).
    pub fn angle_rad(&self) -> f32 {
        self.angle_rad
    }

    /// How firmly the jaws would hold what is between them, 0..1: button-driven jaws by how far they have
    /// closed (`1 - angle / open angle`), a gripper by how far its angle is below the opening threshold
    /// (`1 - angle / open_above`, which reaches 0 exactly where the jaws open).
    pub fn grip(&self) -> f32 {
        let span_rad = match self.activation {
            JawActivation::Button { .. } => self.open_angle_rad,
            JawActivation::Angle { open_above_rad, .. } => open_above_rad,
        };
        if span_rad > 0.0 {
            (1.0 - self.angle_rad / span_rad).clamp(0.0, 1.0)
        } else {
            f32::from(u8::from(self.closed))
        }
    }

    /// The fastest the grip may change, per second: button-driven jaws close from open in `open angle /
    /// SLEW_RAD_S` (about 90 ms), and a grip takes and lets go of tissue no faster.
    pub fn grip_rate_per_s(&self) -> f32 {
        if self.open_angle_rad > 0.0 {
            Self::SLEW_RAD_S / self.open_angle_rad
        } else {
            f32::INFINITY
        }
    }

    /// Take this tick's input; returns the closed state. A non-finite angle changes nothing.
    pub fn update(&mut self, input: &JawInput, dt_s: f32) -> bool {
        match self.activation {
            JawActivation::Button { mask } => {
                self.closed = input.buttons & mask != 0;
                let target = if self.closed {
                    0.0
                } else {
                    self.open_angle_rad
                };
                let step = Self::SLEW_RAD_S * dt_s.max(0.0);
                self.angle_rad += (target - self.angle_rad).clamp(-step, step);
            }
            JawActivation::Angle {
                close_below_rad,
                open_above_rad,
            } => {
                let angle = input.jaw_angle_rad;
                if angle.is_finite() {
                    if self.closed && angle > open_above_rad {
                        self.closed = false;
                    } else if !self.closed && angle < close_below_rad {
                        self.closed = true;
                    }
                    self.angle_rad = angle.clamp(0.0, self.open_angle_rad);
                }
            }
        }
        self.closed
    }

    /// The device let go of the tool: the jaws open.
    pub fn open(&mut self) {
        self.closed = false;
        self.angle_rad = self.open_angle_rad;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interaction::GraspSpec;

    fn jaws_of(spec: &GraspSpec) -> Jaws {
        Jaws::new(spec.activation, spec.open_angle_rad)
    }

    #[test]
    fn a_button_closes_at_once_and_the_drawn_angle_slews() {
        let mut jaws = jaws_of(&GraspSpec::DEFAULT);
        assert!(!jaws.closed());
        let press = JawInput {
            buttons: 1,
            jaw_angle_rad: 0.0,
        };
        assert!(jaws.update(&press, 0.001));
        let open = GraspSpec::DEFAULT.open_angle_rad;
        assert!((jaws.angle_rad() - (open - 0.008)).abs() < 1e-6);
        for _ in 0..200 {
            jaws.update(&press, 0.001);
        }
        assert_eq!(jaws.angle_rad(), 0.0);
        assert!(!jaws.update(&JawInput::default(), 0.001));
    }

    #[test]
    fn an_angle_closes_and_opens_with_hysteresis() {
        let spec = GraspSpec {
            activation: GraspSpec::ANGLE_DEFAULT,
            ..GraspSpec::DEFAULT
        };
        let mut jaws = jaws_of(&spec);
        let at = |deg: f32| JawInput {
            buttons: 0,
            jaw_angle_rad: deg.to_radians(),
        };
        assert!(!jaws.update(&at(15.0), 0.001));
        assert!(jaws.update(&at(9.0), 0.001));
        // Inside the band it stays closed: a trembling grip does not chatter.
        assert!(jaws.update(&at(15.0), 0.001));
        assert!(jaws.update(&at(11.0), 0.001));
        assert!(!jaws.update(&at(21.0), 0.001));
        assert!(!jaws.update(&at(15.0), 0.001));
        // A NaN angle changes nothing.
        jaws.update(&at(5.0), 0.001);
        let before = jaws;
        jaws.update(
            &JawInput {
                buttons: 0,
                jaw_angle_rad: f32::NAN,
            },
            0.001,
        );
        assert_eq!(jaws, before);
    }
}
