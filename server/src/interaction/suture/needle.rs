//! A needle driver and the curved needle in its jaws: where the needle sits on the tool.
//!
//! Owns: [`NeedleDriverSpec`] (the driver's jaws, the needle's arc and thickness, where along the arc the jaws
//! hold it) and the fixed pose of the needle in the tool frame while the jaws hold it ([`NeedleDriverSpec::
//! tool_from_needle`]).
//!
//! The grip, as a surgeon loads a needle: the jaws run along the tool's -z from the tool origin and close in
//! its y direction; the needle is clamped at the tool origin, square to the jaws (its tangent there along the
//! tool's +x, toward the tip), and its plane is square to the shaft (the needle frame's z is the tool's z). The
//! arc curves toward the tool's +y: its centre sits at `(0, radius, 0)` in the tool frame. Turning the driver
//! about its shaft (pronation, supination) therefore swings the needle about an axis parallel to its own, which
//! is how a curved needle is driven along its curve. `sinew_protocol::needle_point_in_tool_mm` is the same map
//! for viewers; a test holds the two equal.
//!
//! Pure and allocation-free.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use super::{NeedleArc, ThreadSpec};
use crate::tissue::Vec3;

/// A needle driver holding a curved needle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedleDriverSpec {
    /// Length of each jaw from the tool origin up the shaft's side, mm (drawn by the viewers).
    pub jaw_length_mm: f32,
    /// The needle's arc, tail to tip.
    pub arc: NeedleArc,
    /// The needle's wire diameter, mm (a 3-0 skin needle is about 0.5 mm).
    pub diameter_mm: f32,
    /// Where along the arc the jaws hold it: the angle from the tail, rad (surgeons load a needle a third to a
    /// half of the way from the swage).
    pub grasp_at_rad: f32,
    /// The thread swaged to the needle's tail.
    pub thread: ThreadSpec,
}

impl NeedleDriverSpec {
    /// Defaults of `kind = "needle_driver"`: 10 mm jaws holding iMSTK's default needle (10.7 mm radius, 116
    /// degrees), 0.5 mm thick, 40 degrees from its tail (a third of the way).
    pub const DEFAULT: NeedleDriverSpec = NeedleDriverSpec {
        jaw_length_mm: 10.0,
        arc: NeedleArc::IMSTK_DEFAULT,
        diameter_mm: 0.5,
        grasp_at_rad: 40.0 * std::f32::consts::PI / 180.0,
        thread: ThreadSpec::DEFAULT,
    };

    /// The needle's pose in the tool frame while the jaws hold it (see the module doc).
    pub fn tool_from_needle(&self) -> Isometry3<f32> {
        // Turn the needle frame about z so that the held point's outward radial lies along the tool's -y (its
        // tangent then lies along +x), then move the held point to the tool origin.
        let turn = -std::f32::consts::FRAC_PI_2 - self.grasp_at_rad;
        let rotation = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), turn);
        let held = rotation * self.arc.at(self.grasp_at_rad).point_mm;
        Isometry3::from_parts(Translation3::from(-held), rotation)
    }

    /// The needle's reach from the tool origin, mm: its farthest point, plus half its thickness.
    pub fn reach_mm(&self) -> f32 {
        let tool_from_needle = self.tool_from_needle();
        let mut reach: f32 = 0.0;
        for k in 0..=32 {
            let theta = self.arc.sweep_rad() * k as f32 / 32.0;
            let p = tool_from_needle * nalgebra::Point3::from(self.arc.at(theta).point_mm);
            reach = reach.max(p.coords.norm());
        }
        reach + 0.5 * self.diameter_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_jaws_hold_the_needle_at_the_tool_origin_square_to_the_shaft() {
        let spec = NeedleDriverSpec::DEFAULT;
        let pose = spec.tool_from_needle();
        let held = spec.arc.at(spec.grasp_at_rad);
        let at = pose * nalgebra::Point3::from(held.point_mm);
        assert!(at.coords.norm() < 1e-5, "{at:?}");
        assert!((pose * held.tangent - Vec3::x()).norm() < 1e-5);
        assert!((pose * Vec3::z() - Vec3::z()).norm() < 1e-6);
        // The centre on the tool's +y, a radius away; the tip beyond it along +x.
        let centre = pose * nalgebra::Point3::origin();
        assert!((centre.coords - Vec3::new(0.0, 10.7, 0.0)).norm() < 1e-4);
        let tip = pose * nalgebra::Point3::from(spec.arc.tip().point_mm);
        assert!(tip.x > 5.0 && tip.y > 0.0, "{tip:?}");
        assert!(spec.reach_mm() > tip.coords.norm());
    }

    #[test]
    fn the_viewers_map_of_the_needle_is_the_servers() {
        let mut spec = NeedleDriverSpec::DEFAULT;
        for (radius, sweep, grasp) in [(10.7, 116.0, 40.0), (6.0, 180.0, 90.0), (20.0, 60.0, 0.0)] {
            spec.arc = NeedleArc::new(radius, sweep).unwrap();
            spec.grasp_at_rad = f32::to_radians(grasp);
            let pose = spec.tool_from_needle();
            for k in 0..=8 {
                let theta = spec.arc.sweep_rad() * k as f32 / 8.0;
                let server = pose * nalgebra::Point3::from(spec.arc.at(theta).point_mm);
                let viewer = Vec3::from(sinew_protocol::needle_point_in_tool_mm(
                    radius,
                    spec.grasp_at_rad,
                    theta,
                ));
                assert!(
                    (server.coords - viewer).norm() < 1e-4,
                    "{server:?} {viewer:?}"
                );
            }
        }
    }
}
