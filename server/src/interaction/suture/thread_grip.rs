//! Jaws on the thread: a grasper (or any tool with jaws) holding one node of a suture thread.
//!
//! Owns: [`ThreadGrip`] (which tool holds which node, where on the tool, and the thread's pull on the jaws).
//! The thread steps it (`thread.rs`): jaws clamp the thread, so its node is held as the needle's tail is (no
//! inverse mass, [`ThreadChain::set_held`](super::ThreadChain::set_held)) and moved each substep from last
//! tick's place on the tool to this tick's on a straight line; the chain's length solve then pulls on it
//! with the tensions either side, the pull of whatever the rest of the thread runs through, and nothing
//! (contacts, itself) moves it off the jaws. The pull on the jaws is those tensions; past [`GRIP_SLIP_N`] the
//! thread slips out of the jaws (the grip lets go). The grasper takes and lets go of grips
//! (`sim/instruments/grasper.rs`).
//!
//! Must not: allocate, or pass on a non-finite pull.

use nalgebra::{Point3, UnitQuaternion};

use crate::tissue::Vec3;

/// The most grips on one thread at once.
pub const MAX_GRIPS: usize = 4;
/// The pull past which the thread slips out of the jaws, N (a needle holder's serrated jaws hold a 3-0 suture
/// to about its knot strength; a grasper's smooth jaws less: 10 N is below the suture's 19 N knotted).
pub const GRIP_SLIP_N: f32 = 10.0;

/// A tool's jaws on one node of the thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThreadGrip {
    /// The tool holding it.
    pub tool: u16,
    /// The node held.
    pub node: u32,
    /// Where on the tool it is held, tool frame, mm.
    pub at_tool_mm: Vec3,
    /// Its place last tick and this tick, world, mm (None last tick: taken this tick).
    last_place_mm: Option<Vec3>,
    place_mm: Vec3,
    /// The thread's pull on the jaws at the end of the last step, world, N.
    pull_n: Vec3,
}

impl ThreadGrip {
    /// Tool `tool` takes node `node` at `at_tool_mm` (tool frame).
    pub fn new(tool: u16, node: u32, at_tool_mm: Vec3) -> Self {
        Self {
            tool,
            node,
            at_tool_mm,
            last_place_mm: None,
            place_mm: Vec3::zeros(),
            pull_n: Vec3::zeros(),
        }
    }

    /// This tick's tool pose: where the node is to be held. False (the grip must go) for a non-finite place.
    pub fn aim(&mut self, position_mm: &Vec3, rotation: &UnitQuaternion<f32>) -> bool {
        let place = position_mm + rotation * self.at_tool_mm;
        if !place.iter().all(|c| c.is_finite()) {
            return false;
        }
        self.last_place_mm = Some(self.last_place_mm.map_or(place, |_| self.place_mm));
        self.place_mm = place;
        true
    }

    /// Where its node is held at `s` (0..1) of the way through this tick.
    pub fn place_at(&self, s: f32) -> Vec3 {
        let from = self.last_place_mm.unwrap_or(self.place_mm);
        from + (self.place_mm - from) * s
    }

    /// After the tick's last substep, the thread pulling its node with `pull_n` (world, N: the tensions either
    /// side). False (the grip must go) when that is more than [`GRIP_SLIP_N`] or not finite.
    pub fn after_step(&mut self, pull_n: Vec3) -> bool {
        let pull = pull_n;
        if !pull.iter().all(|c| c.is_finite()) || pull.norm() > GRIP_SLIP_N {
            self.pull_n = Vec3::zeros();
            return false;
        }
        self.pull_n = pull;
        true
    }

    /// The thread's pull on the jaws, world, N.
    pub fn pull_n(&self) -> Vec3 {
        self.pull_n
    }

    /// Where it holds the node, world, mm (this tick).
    pub fn place_mm(&self) -> Vec3 {
        self.place_mm
    }
}

/// The point `world_mm` in the frame of a tool at `position_mm`, `rotation`.
pub fn in_tool_frame(world_mm: &Vec3, position_mm: &Vec3, rotation: &UnitQuaternion<f32>) -> Vec3 {
    rotation
        .inverse_transform_point(&Point3::from(world_mm - position_mm))
        .coords
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grip_moves_its_place_over_the_tick_and_lets_go_past_its_slip_pull() {
        let rotation = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 0.5);
        let at = in_tool_frame(
            &Vec3::new(1.0, 2.0, 3.0),
            &Vec3::new(1.0, 1.0, 1.0),
            &rotation,
        );
        let mut grip = ThreadGrip::new(1, 5, at);
        assert!(grip.aim(&Vec3::new(1.0, 1.0, 1.0), &rotation));
        assert!((grip.place_mm() - Vec3::new(1.0, 2.0, 3.0)).norm() < 1e-5);
        // Taken this tick: held at its place all the way through.
        assert!((grip.place_at(0.0) - grip.place_mm()).norm() < 1e-6);
        assert!(grip.aim(&Vec3::new(3.0, 1.0, 1.0), &rotation));
        let half = grip.place_at(0.5);
        assert!((half - Vec3::new(2.0, 2.0, 3.0)).norm() < 1e-5, "{half:?}");
        // The thread's pull is the jaws'; past the slip, or not finite, the grip goes.
        assert!(grip.after_step(Vec3::new(0.0, 0.0, 2.0)));
        assert_eq!(grip.pull_n(), Vec3::new(0.0, 0.0, 2.0));
        assert!(!grip.after_step(Vec3::new(0.0, 0.0, GRIP_SLIP_N * 1.01)));
        assert_eq!(grip.pull_n(), Vec3::zeros());
        assert!(!grip.after_step(Vec3::new(f32::NAN, 0.0, 0.0)));
        assert!(!grip.aim(&Vec3::new(f32::INFINITY, 0.0, 0.0), &rotation));
    }
}
