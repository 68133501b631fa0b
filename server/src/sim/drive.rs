//! Driving the tools: each command moves its tool's coupling target, and a (re)taken tool starts from its
//! entry point.
//!
//! Owns: [`Sim::apply_commands`]. Must not: touch tissue.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion};

use crate::tissue::Vec3;

use super::*;

impl Sim {
    /// Device poses move the tools through their couplings (a tool that just became active starts at its
    /// device pose).
    pub(super) fn apply_commands(&mut self, dt_s: f32, commands: &[ToolCommand]) {
        for tool in &mut self.tools {
            tool.drive.was_active = tool.active;
            tool.drive.last_position_mm = tool.position_mm;
        }
        for (t, tool) in self.tools.iter_mut().enumerate() {
            let Some(command) = commands.get(t) else {
                tool.active = false;
                continue;
            };
            let p = command.position_device_mm;
            let v = command.velocity_device_mm_s;
            let q = command.orientation_xyzw;
            let finite = p
                .iter()
                .chain(v.iter())
                .chain(q.iter())
                .all(|c| c.is_finite());
            let norm = q.iter().map(|c| c * c).sum::<f32>().sqrt();
            if !command.active || !finite || norm.is_nan() || norm <= 0.5 {
                tool.active = false;
                continue;
            }
            tool.drive.jaw_input = command.jaws;
            tool.drive.device_mm = tool.device_origin_in_world_mm + Vec3::from(p);
            tool.drive.device_velocity_mm_s = Vec3::from(v);
            if tool.active {
                tool.position_mm = tool.drive.coupling.step(
                    dt_s,
                    &tool.drive.device_mm,
                    &tool.drive.device_velocity_mm_s,
                    &tool.haptic.last_force_n,
                    &tool.haptic.contact_k,
                );
            } else {
                // (Re)taken: enter from outside the tissue, never at the device pose, which may lie in or beyond
                // a surface (a device that rejoins while pressing, or a pose that jumped while nobody drove
                // the tool). The coupling brings it to the pose at its speed limit.
                tool.drive.coupling.reset(tool.drive.entry_mm);
                tool.drive.joined = false;
                tool.position_mm = tool.drive.entry_mm;
                tool.drive.last_position_mm = tool.drive.entry_mm;
                tool.haptic.last_force_n = Vec3::zeros();
                tool.haptic.contact_k = Matrix3::zeros();
            }
            tool.active = true;
            tool.rotation =
                UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]));
        }
    }
}
