//! A device command that puts a tool at a world pose: the tests' and benches' way of placing a tool exactly.

use nalgebra::{UnitQuaternion, Vector3};
use sinew_server::sim::ToolCommand;

/// The active command that puts a tool whose device origin sits at `device_origin_in_world_mm` with its origin
/// at `origin_world_mm`, turned by `rotation` (world).
pub fn pose_command(
    origin_world_mm: &Vector3<f32>,
    device_origin_in_world_mm: &Vector3<f32>,
    rotation: &UnitQuaternion<f32>,
) -> ToolCommand {
    let p = origin_world_mm - device_origin_in_world_mm;
    let q = rotation.as_ref().coords;
    ToolCommand {
        active: true,
        position_device_mm: [p.x, p.y, p.z],
        orientation_xyzw: [q.x, q.y, q.z, q.w],
        ..ToolCommand::default()
    }
}
