//! What a multi-rate object's latest finished step left of a tool's contact: the local model the 1 kHz tick
//! renders until the next hand-off (a push, or the held tissue of a grasp), and what it gives at the tool's
//! position now.
//!
//! Owns: [`LaneContact`]. Must not: measure it (the step job does, `multirate.rs`).

use nalgebra::Matrix3;

use crate::tissue::Vec3;

/// A tool's contact with a multi-rate object as its latest finished step left it: the local model the tick
/// renders until the next hand-off.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LaneContact {
    /// The tissue's force on the tool at the end of the step, N (world).
    pub force_n: Vec3,
    /// Where the tool was held during the step (its position at launch), mm (world): the model's `x0`.
    pub position_mm: Vec3,
    /// Unit contact normal (along `force_n`; zero out of contact).
    pub normal: Vec3,
    /// Normal contact stiffness, N/mm (0 until a solve has finished).
    pub stiffness_n_per_mm: f32,
    /// Normal contact damping, N s/mm.
    pub damping_n_s_per_mm: f32,
    /// The stiffness comes from a finished solve (false on the first steps of a contact).
    pub solved: bool,
    /// Nodes the tool held at the end of the step.
    pub held_nodes: u32,
    /// While the jaws held points: the tissue's force on the tool at the end of the step, N (world; the
    /// points' pull and the body's push, not scaled by the grip). `force_n` is then zero: held tissue is
    /// rendered whole, bilaterally.
    pub grasp_force_n: Vec3,
    /// The held tissue's condensed stiffness `K`, full 3x3, N/mm (zero until a solve has finished).
    pub grasp_stiffness_n_per_mm: Matrix3<f32>,
    /// Its damping, N s/mm.
    pub grasp_damping_n_s_per_mm: Matrix3<f32>,
    /// Nodes the jaws' points moved during the step (0: no grasp).
    pub grasped_points: u32,
}

impl LaneContact {
    /// The force on a tool at `position_mm`: `f0 - K (x - x0)` with `K = k n n^T`, and zero once the normal part
    /// would pull (the tool has left the dent). Zero out of contact. Until the contact's first solve has
    /// finished, `k` is `unsolved_n_per_mm` (the tool's prior: its touch-down's or last contact's stiffness;
    /// with none the force stood at `f0` for whole steps, and a probe pressing into the liver at 20 mm/s felt
    /// it in 0.03 N stairs 40 ms apart). Pure, finite for finite inputs.
    pub fn force_at(&self, position_mm: &Vec3, unsolved_n_per_mm: f32) -> Vec3 {
        if self.held_nodes == 0 {
            return Vec3::zeros();
        }
        let k_n_per_mm = if self.solved {
            self.stiffness_n_per_mm
        } else {
            unsolved_n_per_mm
        };
        let push_n = self.force_n.dot(&self.normal)
            - k_n_per_mm * self.normal.dot(&(position_mm - self.position_mm));
        if push_n <= 0.0 {
            return Vec3::zeros();
        }
        // The step's tangential part (friction) rides along unchanged; the normal part follows the model.
        self.force_n + self.normal * (push_n - self.force_n.dot(&self.normal))
    }

    /// The held tissue's force on a tool at `position_mm`: `g0 - K (x - x0)`, bilateral (held tissue pulls back
    /// whichever way the jaws move it). Zero when the step held no points. Pure, finite for finite inputs.
    pub fn grasp_force_at(&self, position_mm: &Vec3) -> Vec3 {
        if self.grasped_points == 0 {
            return Vec3::zeros();
        }
        self.grasp_force_n - self.grasp_stiffness_n_per_mm * (position_mm - self.position_mm)
    }

    /// `K = k n n^T`, N/mm.
    pub fn stiffness_matrix(&self) -> Matrix3<f32> {
        self.normal * self.normal.transpose() * self.stiffness_n_per_mm
    }

    /// `D = d n n^T`, N s/mm.
    pub fn damping_matrix(&self) -> Matrix3<f32> {
        self.normal * self.normal.transpose() * self.damping_n_s_per_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pressed() -> LaneContact {
        LaneContact {
            force_n: Vec3::new(0.0, 0.0, 1.0),
            position_mm: Vec3::new(0.0, 0.0, -2.0),
            normal: Vec3::z(),
            stiffness_n_per_mm: 0.5,
            damping_n_s_per_mm: 0.0,
            solved: true,
            held_nodes: 10,
            ..LaneContact::default()
        }
    }

    #[test]
    fn the_local_model_is_linear_in_the_tools_motion_and_never_pulls() {
        let c = pressed();
        // Deeper by 1 mm: 0.5 N more; 1 mm back: 0.5 N less; 3 mm back: out of the dent.
        assert!((c.force_at(&Vec3::new(0.0, 0.0, -3.0), 9.0).z - 1.5).abs() < 1e-6);
        assert!((c.force_at(&Vec3::new(0.0, 0.0, -1.0), 9.0).z - 0.5).abs() < 1e-6);
        assert_eq!(c.force_at(&Vec3::new(0.0, 0.0, 1.0), 9.0), Vec3::zeros());
        // Sliding along the surface changes nothing (K is normal only).
        assert_eq!(c.force_at(&Vec3::new(5.0, 0.0, -2.0), 9.0), c.force_n);
        assert_eq!(
            LaneContact::default().force_at(&Vec3::zeros(), 9.0),
            Vec3::zeros()
        );
        let k = c.stiffness_matrix();
        assert!((k[(2, 2)] - 0.5).abs() < 1e-6 && k[(0, 0)] == 0.0);
        // Before the first solve: the prior's slope, 1 mm deeper 0.2 N more.
        let first = LaneContact {
            solved: false,
            stiffness_n_per_mm: 0.0,
            ..c
        };
        assert!((first.force_at(&Vec3::new(0.0, 0.0, -3.0), 0.2).z - 1.2).abs() < 1e-6);
    }
}
