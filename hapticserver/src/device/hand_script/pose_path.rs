//! A scripted hand's path as keyframes of the stylus's whole pose and the jaws: positions joined by straight
//! segments at constant speed, orientations by the shortest rotation between them (slerp), the buttons held
//! from one keyframe to the next. What an instrument that must turn (a needle driver rolling a curved needle
//! through tissue) needs from a simulated hand; a planner (a demo's stitch, a test) builds it.
//!
//! Owns: [`PoseKey`], [`PosePath`] (validated once, when built) and its samples at a script time. The hand sets
//! the orientation exactly: a Touch-like device senses its gimbal and renders no torque, so nothing pushes the
//! stylus's orientation off the hand's.
//!
//! Must not: allocate, block or panic when sampled (it runs in the device loop).

use nalgebra::{Quaternion, UnitQuaternion};
use thiserror::Error;

use crate::hand_model::HandTarget;

/// One keyframe: where the hand puts the stylus at script time `t_s`, and the buttons it holds from then on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseKey {
    /// Script time, s.
    pub t_s: f64,
    /// Stylus position, device frame, mm.
    pub position_mm: [f32; 3],
    /// Stylus orientation, device frame, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
    /// Button bits held from this keyframe to the next (bit 0 closes a grasper's or a driver's jaws).
    pub buttons: u32,
}

/// Why keyframes do not make a path.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PosePathError {
    /// No keyframe.
    #[error("a pose path needs at least one keyframe")]
    Empty,
    /// A keyframe's time is not after the one before it.
    #[error("keyframe {index}: its time {t_s} s is not after the previous keyframe's")]
    NotIncreasing {
        /// The keyframe.
        index: usize,
        /// Its time, s.
        t_s: f64,
    },
    /// A keyframe holds a non-finite number.
    #[error("keyframe {index}: a time, position or orientation is not a finite number")]
    NotFinite {
        /// The keyframe.
        index: usize,
    },
    /// A keyframe's orientation is not a unit quaternion (to within 1%).
    #[error("keyframe {index}: the orientation's norm is {norm}, not 1")]
    NotUnit {
        /// The keyframe.
        index: usize,
        /// Its norm.
        norm: f32,
    },
}

/// A validated path of keyframes (module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct PosePath {
    keys: Vec<PoseKey>,
}

impl PosePath {
    /// A path through `keys`, in time order. Orientations within 1% of unit are normalised; anything else is
    /// refused with the keyframe's index.
    pub fn new(mut keys: Vec<PoseKey>) -> Result<Self, PosePathError> {
        if keys.is_empty() {
            return Err(PosePathError::Empty);
        }
        let mut last_t_s = f64::NEG_INFINITY;
        for (index, key) in keys.iter_mut().enumerate() {
            let finite = key.t_s.is_finite()
                && key.position_mm.iter().all(|c| c.is_finite())
                && key.orientation_xyzw.iter().all(|c| c.is_finite());
            if !finite {
                return Err(PosePathError::NotFinite { index });
            }
            if key.t_s <= last_t_s {
                return Err(PosePathError::NotIncreasing {
                    index,
                    t_s: key.t_s,
                });
            }
            last_t_s = key.t_s;
            let norm = key
                .orientation_xyzw
                .iter()
                .map(|c| c * c)
                .sum::<f32>()
                .sqrt();
            if (norm - 1.0).abs() > 0.01 {
                return Err(PosePathError::NotUnit { index, norm });
            }
            key.orientation_xyzw = key.orientation_xyzw.map(|c| c / norm);
        }
        Ok(Self { keys })
    }

    /// The keyframes.
    pub fn keys(&self) -> &[PoseKey] {
        &self.keys
    }

    /// When the last keyframe is reached, s.
    pub fn end_s(&self) -> f64 {
        self.keys.last().map_or(0.0, |k| k.t_s)
    }

    /// The keyframes either side of `t_s` and how far between them (0 to 1); before the first or after the
    /// last, that keyframe twice. (`None` only for an empty path, which [`PosePath::new`] never builds.)
    fn segment(&self, t_s: f64) -> Option<(&PoseKey, &PoseKey, f64)> {
        let after = self.keys.partition_point(|k| k.t_s <= t_s);
        let (first, last) = (self.keys.first()?, self.keys.last()?);
        if after == 0 {
            return Some((first, first, 0.0));
        }
        let (Some(a), Some(b)) = (self.keys.get(after - 1), self.keys.get(after)) else {
            return Some((last, last, 0.0));
        };
        let share = ((t_s - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
        Some((a, b, share))
    }

    /// Where the hand aims at `t_s` and how fast that point moves (constant along each segment; at rest
    /// before the first keyframe and after the last).
    pub fn target(&self, t_s: f64) -> HandTarget {
        let Some((a, b, share)) = self.segment(t_s) else {
            return HandTarget::default();
        };
        let dt_s = (b.t_s - a.t_s) as f32;
        let mut target = HandTarget::at_rest(a.position_mm);
        for k in 0..3 {
            let d = b.position_mm[k] - a.position_mm[k];
            target.position_mm[k] = a.position_mm[k] + d * share as f32;
            if dt_s > 0.0 {
                target.velocity_mm_s[k] = d / dt_s;
            }
        }
        target
    }

    /// The stylus's orientation at `t_s`, unit quaternion (x, y, z, w).
    pub fn orientation_xyzw(&self, t_s: f64) -> [f32; 4] {
        let Some((a, b, share)) = self.segment(t_s) else {
            return [0.0, 0.0, 0.0, 1.0];
        };
        let unit =
            |q: [f32; 4]| UnitQuaternion::new_normalize(Quaternion::new(q[3], q[0], q[1], q[2]));
        let q = unit(a.orientation_xyzw)
            .try_slerp(&unit(b.orientation_xyzw), share as f32, 1e-6)
            .unwrap_or_else(|| unit(a.orientation_xyzw));
        let c = q.as_ref().coords;
        [c.x, c.y, c.z, c.w]
    }

    /// The buttons held at `t_s`: the last keyframe's at or before it (none before the first).
    pub fn buttons(&self, t_s: f64) -> u32 {
        let after = self.keys.partition_point(|k| k.t_s <= t_s);
        after
            .checked_sub(1)
            .and_then(|i| self.keys.get(i))
            .map_or(0, |k| k.buttons)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn key(t_s: f64, x: f32, turn_deg: f32, buttons: u32) -> PoseKey {
        let q =
            UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), turn_deg.to_radians());
        let c = q.as_ref().coords;
        PoseKey {
            t_s,
            position_mm: [x, 0.0, 10.0],
            orientation_xyzw: [c.x, c.y, c.z, c.w],
            buttons,
        }
    }

    #[test]
    fn between_keyframes_the_hand_moves_straight_turns_evenly_and_holds_the_buttons() {
        let path = PosePath::new(vec![key(1.0, 0.0, 0.0, 0), key(3.0, 10.0, 90.0, 1)]).unwrap();
        // Before the first keyframe: at it, still.
        let before = path.target(0.0);
        assert_eq!(before.position_mm, [0.0, 0.0, 10.0]);
        assert_eq!(before.velocity_mm_s, [0.0; 3]);
        let mid = path.target(2.0);
        assert!((mid.position_mm[0] - 5.0).abs() < 1e-5);
        assert!((mid.velocity_mm_s[0] - 5.0).abs() < 1e-5);
        let q = path.orientation_xyzw(2.0);
        let turn = UnitQuaternion::new_normalize(Quaternion::new(q[3], q[0], q[1], q[2]));
        assert!((turn.angle().to_degrees() - 45.0).abs() < 1e-3, "{q:?}");
        assert_eq!(path.buttons(0.5), 0);
        assert_eq!(path.buttons(2.9), 0);
        assert_eq!(path.buttons(3.0), 1);
        // After the last: held there, still, closed.
        let after = path.target(9.0);
        assert_eq!(after.position_mm, [10.0, 0.0, 10.0]);
        assert_eq!(after.velocity_mm_s, [0.0; 3]);
        assert_eq!(path.buttons(9.0), 1);
        assert_eq!(path.end_s(), 3.0);
    }

    #[test]
    fn bad_keyframes_are_refused_with_their_index() {
        assert_eq!(PosePath::new(vec![]), Err(PosePathError::Empty));
        assert_eq!(
            PosePath::new(vec![key(1.0, 0.0, 0.0, 0), key(1.0, 1.0, 0.0, 0)]),
            Err(PosePathError::NotIncreasing { index: 1, t_s: 1.0 })
        );
        let mut nan = key(2.0, 0.0, 0.0, 0);
        nan.position_mm[1] = f32::NAN;
        assert_eq!(
            PosePath::new(vec![key(1.0, 0.0, 0.0, 0), nan]),
            Err(PosePathError::NotFinite { index: 1 })
        );
        let mut long = key(1.0, 0.0, 0.0, 0);
        long.orientation_xyzw = [0.0, 0.0, 0.0, 2.0];
        assert!(matches!(
            PosePath::new(vec![long]),
            Err(PosePathError::NotUnit { index: 0, .. })
        ));
    }
}
