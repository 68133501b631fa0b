//! Tool states: server -> viewers.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind, check};

/// One tool's state in the world frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct ToolState {
    /// Tool index (matches [`crate::ToolInfo::tool`]).
    pub tool: u16,
    /// Tool origin in the world, mm.
    pub position_mm: [f32; 3],
    /// Tool orientation in the world, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
    /// Force the tissue exerts on the tool, newtons, world frame.
    pub force_n: [f32; 3],
    /// A device is bound and sending poses (false: released, it does not touch the tissue).
    pub active: bool,
    /// The tool touches tissue.
    pub in_contact: bool,
    /// A grasper's jaw opening, rad (0 closed; 0 for a probe). Protocol 6.
    pub jaw_angle_rad: f32,
    /// Points of tissue the jaws hold (0: not grasping). Protocol 6.
    pub attachments: u16,
}

/// The state of every tool at one publish frame.
///
/// Direction: server -> viewers, on `sinew/<scene>/tools`. Rate: every publish frame (~60 Hz); doubles as the
/// scene heartbeat. Reliability: best effort (the next frame replaces it). Units: mm, newtons, seconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ToolStates {
    /// Publish frame.
    pub frame: u64,
    /// Simulated time, seconds.
    pub sim_time_s: f64,
    /// One entry per tool, in tool order.
    pub tools: Vec<ToolState>,
}

impl Message for ToolStates {
    const KIND: MessageKind = MessageKind::ToolStates;
    fn validate(&self) -> Result<(), FieldError> {
        if !self.sim_time_s.is_finite() {
            return Err(("sim_time_s", "not finite"));
        }
        for tool in &self.tools {
            check::finite("tools.position_mm", &tool.position_mm)?;
            check::unit_quaternion("tools.orientation_xyzw", &tool.orientation_xyzw)?;
            check::finite("tools.force_n", &tool.force_n)?;
            check::finite("tools.jaw_angle_rad", &[tool.jaw_angle_rad])?;
            if !(0.0..=std::f32::consts::PI).contains(&tool.jaw_angle_rad) {
                return Err(("tools.jaw_angle_rad", "outside 0 to pi"));
            }
        }
        Ok(())
    }
}
