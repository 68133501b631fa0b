//! A multi-rate object's surface ahead of a tool, rendered on the tick until the object's step answers.
//!
//! The object steps every `N` ticks and sees a tool only at its pose of the launch tick, so a tool that
//! reaches the surface waits up to two step periods for the push of the step that finds it there (the liver
//! at 25 Hz: 40-80 ms; a probe coming down at 20 mm/s went 1.6 mm into the lobe before it felt anything, and a
//! slow one 0.5 mm). Between hand-offs the tick renders the object through planes, as a distant device does
//! (Mark et al., "Adding force feedback to graphics systems", SIGGRAPH 1996: an intermediate representation
//! updated at the simulation's rate, rendered at the haptic rate): the tool's tip plane on the object (the
//! surface node nearest it, offset by the tool's reach, carrying the touch-down's or the last contact's
//! stiffness) pushes the tool out from the moment it crosses the plane until the step's own contact takes
//! over.
//!
//! Owns: [`LanePlane`]. The plane is rendered only on the way in: armed while the tool is outside it, disarmed
//! when the step's contact begins, and armed again only once the tool is back outside (a blade that has cut
//! in, or a tool the step found and let go, is not pushed by a plane it is already through), and only near
//! the node it passes through (not under a plane that extends past the object's edge).
//!
//! Must not: allocate, or render anything non-finite.

use crate::haptics::WorldPlane;
use crate::tissue::Vec3;

/// How far beyond the tool's reach, along the plane, the tool may be from the plane's node for the plane to
/// push it, mm: the largest surface edge of a coarse organ (the liver's are 3-5 mm), so that a tool over
/// the surface is always within reach of its nearest node, and one past the object's edge is not.
pub const LANE_PLANE_SPAN_MM: f32 = 5.0;

/// One tool's plane on one multi-rate object.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LanePlane {
    plane: Option<WorldPlane>,
    /// Where the plane's node is, mm (world).
    node_mm: Vec3,
    /// The tool's reach along the plane's inward normal, mm.
    reach_mm: f32,
    /// The tool was outside the plane since the step's contact last began.
    armed: bool,
}

impl LanePlane {
    /// The tool's plane this tick (None: no surface within look-ahead), through the node at `node_mm`, for a
    /// tool of `reach_mm` whose origin is at `position_mm`: arms once the tool is outside it.
    pub fn update(
        &mut self,
        plane: Option<WorldPlane>,
        node_mm: Vec3,
        reach_mm: f32,
        position_mm: &Vec3,
    ) {
        self.plane = plane;
        self.node_mm = node_mm;
        self.reach_mm = reach_mm;
        if let Some(p) = &plane
            && p.normal.dot(position_mm) >= p.offset_mm
        {
            self.armed = true;
        }
    }

    /// The step's contact began (or the jaws hold the object): the plane is done until the tool is outside
    /// it again.
    pub fn contact_began(&mut self) {
        self.plane = None;
        self.armed = false;
    }

    /// The plane's push on a tool at `position_mm`, N: its stiffness times how far the tool is past it, along
    /// its normal; zero when not armed, outside, beyond the node's span, or not finite.
    pub fn force_at(&self, position_mm: &Vec3) -> Vec3 {
        let Some(p) = self.plane.filter(|_| self.armed) else {
            return Vec3::zeros();
        };
        let depth_mm = p.offset_mm - p.normal.dot(position_mm);
        let from_node = position_mm - self.node_mm;
        let along_mm = (from_node - p.normal * p.normal.dot(&from_node)).norm();
        if depth_mm <= 0.0 || along_mm > self.reach_mm + LANE_PLANE_SPAN_MM {
            return Vec3::zeros();
        }
        let force = p.normal * (p.stiffness_n_per_mm * depth_mm);
        if force.iter().all(|c| c.is_finite()) {
            force
        } else {
            Vec3::zeros()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(offset_mm: f32, k: f32) -> WorldPlane {
        WorldPlane {
            normal: Vec3::z(),
            offset_mm,
            stiffness_n_per_mm: k,
            damping_n_s_per_mm: 0.0,
            node: 7,
        }
    }

    #[test]
    fn pushes_only_on_the_way_in_near_its_node() {
        let mut lane = LanePlane::default();
        let above = Vec3::new(0.0, 0.0, 5.0);
        let below = Vec3::new(0.0, 0.0, 1.0);
        // First seen from inside (a tool that starts in the tissue): not armed.
        lane.update(Some(plane(2.0, 0.05)), Vec3::zeros(), 4.0, &below);
        assert_eq!(lane.force_at(&below), Vec3::zeros());
        // Outside, then in by 1 mm: 0.05 N along the normal.
        lane.update(Some(plane(2.0, 0.05)), Vec3::zeros(), 4.0, &above);
        assert_eq!(lane.force_at(&above), Vec3::zeros());
        let f = lane.force_at(&below);
        assert!((f - Vec3::new(0.0, 0.0, 0.05)).norm() < 1e-6, "{f:?}");
        // Past the node's span along the plane: nothing.
        assert_eq!(lane.force_at(&Vec3::new(9.5, 0.0, 1.0)), Vec3::zeros());
        assert!(lane.force_at(&Vec3::new(8.5, 0.0, 1.0)).z > 0.0);
        // The step's contact began: no plane until the tool is outside again, even if one is offered.
        lane.contact_began();
        assert_eq!(lane.force_at(&below), Vec3::zeros());
        lane.update(Some(plane(2.0, 0.05)), Vec3::zeros(), 4.0, &below);
        assert_eq!(lane.force_at(&below), Vec3::zeros());
        lane.update(Some(plane(2.0, 0.05)), Vec3::zeros(), 4.0, &above);
        assert!(lane.force_at(&below).z > 0.0);
        // None offered: nothing. Garbage: nothing.
        lane.update(None, Vec3::zeros(), 4.0, &above);
        assert_eq!(lane.force_at(&below), Vec3::zeros());
        lane.update(Some(plane(2.0, f32::INFINITY)), Vec3::zeros(), 4.0, &above);
        assert_eq!(lane.force_at(&below), Vec3::zeros());
    }
}
