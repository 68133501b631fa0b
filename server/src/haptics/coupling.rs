//! Virtual coupling: how a simulated tool follows its (late, possibly jumping) device pose.
//!
//! Owns: [`CouplingParams`] and [`VirtualCoupling`], the tool's position and velocity in the world. The tool is
//! joined to the device pose by a spring-damper (`k_c`, `b_c`) and pushed by the tissue; it has no mass, so each
//! tick solves the force balance implicitly with the tissue linearised by its contact stiffness `K`:
//!
//! ```text
//!   b_c (dx/dt - v_d) = k_c (x_d - x - dx) + F_tissue - K dx
//!   (b_c/dt + k_c + K) dx = k_c (x_d - x) + b_c v_d + F_tissue
//! ```
//!
//! which is stable for any stiffness and step. The step is then limited to `max_speed_mm_s * dt`, so a pose
//! that jumps (a late burst, a restart) drags the tool over several ticks instead of teleporting it into the
//! tissue. At rest in contact the tool sits `F / k_c` short of the device pose; the local model the device
//! renders extrapolates from the tool to the device (`f0 - K (x - x0)`), so the hand still feels the force at
//! its own position. The coupling is what the tissue feels: the tool moves only as this balance allows.
//!
//! Must not: know about the network or the tissue's internals (it sees only the force and the stiffness).

use nalgebra::Matrix3;

use crate::tissue::Vec3;

/// Coupling of a tool to its device pose (world file: `coupling = { stiffness_n_per_mm, damping_n_s_per_mm,
/// max_speed_mm_s }`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CouplingParams {
    /// Spring between device pose and tool, N/mm.
    pub stiffness_n_per_mm: f32,
    /// Damper on their relative velocity, N s/mm.
    pub damping_n_s_per_mm: f32,
    /// Fastest the tool may move, mm/s.
    pub max_speed_mm_s: f32,
}

impl Default for CouplingParams {
    /// 5 N/mm (at the 3.3 N force limit the tool sits 0.66 mm short of the device pose), 0.02 N s/mm (a
    /// 4 ms time constant: the tool catches a still pose in about 20 ms), 500 mm/s (0.5 mm a tick: under an
    /// eighth of the smallest shipped probe radius, so a jump cannot carry the tool through a sheet).
    fn default() -> Self {
        Self {
            stiffness_n_per_mm: 5.0,
            damping_n_s_per_mm: 0.02,
            max_speed_mm_s: 500.0,
        }
    }
}

/// The state of one tool's coupling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualCoupling {
    params: CouplingParams,
    position_mm: Vec3,
    velocity_mm_s: Vec3,
}

impl VirtualCoupling {
    /// A tool at rest at `position_mm`.
    pub fn new(params: CouplingParams, position_mm: Vec3) -> Self {
        Self {
            params,
            position_mm,
            velocity_mm_s: Vec3::zeros(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &CouplingParams {
        &self.params
    }

    /// Tool position, world, mm.
    pub fn position_mm(&self) -> Vec3 {
        self.position_mm
    }

    /// Tool velocity, world, mm/s.
    pub fn velocity_mm_s(&self) -> Vec3 {
        self.velocity_mm_s
    }

    /// Put the tool at `position_mm`, still (a device that just bound its tool).
    pub fn reset(&mut self, position_mm: Vec3) {
        self.position_mm = position_mm;
        self.velocity_mm_s = Vec3::zeros();
    }

    /// The force the coupling exerts on the tool (and so, at balance, passes on to the tissue), N.
    pub fn force_n(&self, device_mm: &Vec3, device_velocity_mm_s: &Vec3) -> Vec3 {
        (device_mm - self.position_mm) * self.params.stiffness_n_per_mm
            + (device_velocity_mm_s - self.velocity_mm_s) * self.params.damping_n_s_per_mm
    }

    /// Advance by `dt_s` toward the device pose (`device_mm`, moving at `device_velocity_mm_s`), pushed by
    /// the tissue's `tissue_force_n` on the tool and resisting with the tissue's contact `stiffness_n_per_mm`
    /// (symmetric positive semi-definite). Returns the tool position.
    ///
    /// Real-time contract: no allocation, never panics; non-finite inputs leave the tool where it is.
    pub fn step(
        &mut self,
        dt_s: f32,
        device_mm: &Vec3,
        device_velocity_mm_s: &Vec3,
        tissue_force_n: &Vec3,
        stiffness_n_per_mm: &Matrix3<f32>,
    ) -> Vec3 {
        let finite = device_mm.iter().all(|c| c.is_finite())
            && device_velocity_mm_s.iter().all(|c| c.is_finite())
            && tissue_force_n.iter().all(|c| c.is_finite())
            && stiffness_n_per_mm.iter().all(|c| c.is_finite())
            && dt_s.is_finite()
            && dt_s > 0.0;
        if !finite {
            self.velocity_mm_s = Vec3::zeros();
            return self.position_mm;
        }
        let CouplingParams {
            stiffness_n_per_mm: k_c,
            damping_n_s_per_mm: b_c,
            max_speed_mm_s,
        } = self.params;
        let system = Matrix3::identity() * (b_c / dt_s + k_c) + stiffness_n_per_mm;
        let rhs =
            (device_mm - self.position_mm) * k_c + device_velocity_mm_s * b_c + tissue_force_n;
        let mut step_mm = system
            .lu()
            .solve(&rhs)
            .filter(|s| s.iter().all(|c| c.is_finite()))
            .unwrap_or_else(Vec3::zeros);
        let max_step_mm = max_speed_mm_s * dt_s;
        let length_mm = step_mm.norm();
        if length_mm > max_step_mm {
            step_mm *= max_step_mm / length_mm;
        }
        self.position_mm += step_mm;
        self.velocity_mm_s = step_mm / dt_s;
        self.position_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f32 = 0.001;

    #[test]
    fn free_tool_follows_a_moving_pose_without_lag() {
        let mut c = VirtualCoupling::new(CouplingParams::default(), Vec3::zeros());
        let v = Vec3::new(100.0, 0.0, 0.0);
        let mut worst: f32 = 0.0;
        for tick in 1..=500 {
            let t = tick as f32 * DT;
            let x = c.step(DT, &(v * t), &v, &Vec3::zeros(), &Matrix3::zeros());
            if tick > 50 {
                worst = worst.max((x - v * t).norm());
            }
        }
        // The damper's feed-forward of the device velocity removes the steady lag of a spring-only coupling.
        assert!(worst < 1e-3, "lag {worst} mm at 100 mm/s");
    }

    #[test]
    fn at_rest_against_tissue_the_tool_sits_force_over_stiffness_short() {
        // Tissue below z = 0 with stiffness 1 N/mm; the device pose is 2 mm inside.
        let k_tissue = 1.0;
        let mut c = VirtualCoupling::new(CouplingParams::default(), Vec3::new(0.0, 0.0, 5.0));
        let device = Vec3::new(0.0, 0.0, -2.0);
        let k = Matrix3::from_diagonal(&Vec3::new(0.0, 0.0, k_tissue));
        let mut x = c.position_mm();
        for _ in 0..2000 {
            let force = Vec3::new(0.0, 0.0, (-x.z * k_tissue).max(0.0));
            x = c.step(DT, &device, &Vec3::zeros(), &force, &k);
        }
        // Balance: 5 (-2 - z) + 1 (-z) = 0  ->  z = -10/6.
        assert!((x.z + 10.0 / 6.0).abs() < 1e-3, "{x:?}");
    }

    #[test]
    fn a_jumping_pose_drags_the_tool_at_the_speed_limit() {
        let mut c = VirtualCoupling::new(CouplingParams::default(), Vec3::zeros());
        let far = Vec3::new(0.0, 0.0, -50.0);
        let mut previous = c.position_mm();
        for _ in 0..20 {
            let x = c.step(DT, &far, &Vec3::zeros(), &Vec3::zeros(), &Matrix3::zeros());
            assert!(
                (x - previous).norm() <= 0.5 + 1e-5,
                "moved {}",
                (x - previous).norm()
            );
            previous = x;
        }
        assert!(previous.z < -9.9 && previous.z > -10.1);
    }

    #[test]
    fn non_finite_input_holds_the_tool() {
        let mut c = VirtualCoupling::new(CouplingParams::default(), Vec3::new(1.0, 2.0, 3.0));
        let x = c.step(
            DT,
            &Vec3::new(f32::NAN, 0.0, 0.0),
            &Vec3::zeros(),
            &Vec3::zeros(),
            &Matrix3::zeros(),
        );
        assert_eq!(x, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(c.velocity_mm_s(), Vec3::zeros());
    }
}
