//! The energy budget across ports: how much energy each device may output beyond what its own hand put in.
//!
//! Owns: [`EnergyBudget`]. A device's time-domain passivity controller keeps its port's energy account
//! `E_i = -sum F . v dt` (what the hand gave the port) non-negative. With one surgeon that is right: a passive
//! tissue gives back at most what the hand stored in it. With two, the tissue also passes on what the OTHER
//! hand does: when `left` pushes the tissue under `right`'s tool, `right`'s port outputs energy that `right`
//! never put in, and a per-port controller would delete exactly that shared pull.
//!
//! The server sees every tool, so it keeps the account across ports: per tool `j` the work its tool does on the
//! tissue, `W_j += -F_j . dx_j` (mJ; `F_j` the force on the tool, `dx_j` the tool's motion this tick). Energy
//! put in is dissipated by the tissue's dampers and drag, so `W_j` leaks with time constant
//! [`EnergyBudget::LEAK_TIME_S`]; a tool's negative work (the tissue pushing it back out) is its own business
//! and grants nothing. Port `i` is granted `A_i = sum over j != i of max(0, W_j)`, capped at
//! [`EnergyBudget::MAX_ALLOWANCE_MJ`], and the grant travels with every local model. The device's controller
//! then acts only when `E_i + A_i < 0`: energy another surgeon sent through the tissue passes, energy the
//! delayed loop made up does not.
//!
//! A port's hand also puts in energy the device cannot measure: the work of turning the instrument (a needle
//! driver rolled about its shaft drives a curved needle through the tissue; a 3-DOF device senses the turn but
//! renders no torque, so its account sees only `F . v`). The server measures it (the needle's loads times the
//! motion the turn gave their points, [`EnergyBudget::record_turn`]) and grants it to the same port, leaking
//! alike: the force a turned needle builds is the hand's own energy coming back, not energy the delayed loop
//! made up. Before, a remote surgeon driving a needle felt 0.09 N of the tissue's 0.9 N: the controller
//! withheld the rest.
//!
//! Must not: change forces (that is the device's controller) or allocate after construction.

use crate::tissue::Vec3;

/// Per-tool work on the tissue and the allowances it grants.
#[derive(Debug, Clone, Default)]
pub struct EnergyBudget {
    work_mj: Vec<f64>,
    /// Per tool, the leaky work its hand did on the tissue by turning the instrument, mJ.
    turn_mj: Vec<f64>,
}

impl EnergyBudget {
    /// Work leaks away with this time constant, s (the pad's drag damps a dent's motion within about 1 s).
    pub const LEAK_TIME_S: f64 = 1.0;
    /// Largest allowance granted to one port, mJ (about what the pad stores at the 3.3 N force limit).
    pub const MAX_ALLOWANCE_MJ: f64 = 50.0;

    /// A budget for `tools` tools.
    pub fn new(tools: usize) -> Self {
        Self {
            work_mj: vec![0.0; tools],
            turn_mj: vec![0.0; tools],
        }
    }

    /// Record one tick: tool `t` moved by `step_mm` while the tissue pushed it with `force_on_tool_n`.
    /// No allocation, never panics (non-finite input is ignored).
    pub fn record(&mut self, t: usize, force_on_tool_n: &Vec3, step_mm: &Vec3, dt_s: f32) {
        let Some(work) = self.work_mj.get_mut(t) else {
            return;
        };
        leak_and_add(work, -f64::from(force_on_tool_n.dot(step_mm)), dt_s);
    }

    /// Record one tick of tool `t`'s turning work on the tissue, `turn_work_mj` (mJ; the work beyond its
    /// force times its translation). No allocation, never panics (non-finite input is ignored).
    pub fn record_turn(&mut self, t: usize, turn_work_mj: f64, dt_s: f32) {
        if let Some(work) = self.turn_mj.get_mut(t) {
            leak_and_add(work, turn_work_mj, dt_s);
        }
    }

    /// Forget tool `t`'s work (it was released).
    pub fn release(&mut self, t: usize) {
        if let Some(work) = self.work_mj.get_mut(t) {
            *work = 0.0;
        }
        if let Some(work) = self.turn_mj.get_mut(t) {
            *work = 0.0;
        }
    }

    /// Tool `t`'s leaky work on the tissue, mJ.
    pub fn work_mj(&self, t: usize) -> f64 {
        self.work_mj.get(t).copied().unwrap_or(0.0)
    }

    /// The energy port `t` may output beyond its own input, mJ: the other tools' positive work and its own
    /// hand's turning work, capped.
    pub fn allowance_mj(&self, t: usize) -> f64 {
        let others: f64 = self
            .work_mj
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != t)
            .map(|(_, w)| w.max(0.0))
            .sum();
        let turned = self.turn_mj.get(t).copied().unwrap_or(0.0).max(0.0);
        (others + turned).min(Self::MAX_ALLOWANCE_MJ)
    }
}

/// One tick of a leaky account: `work` decays over `dt_s` with [`EnergyBudget::LEAK_TIME_S`], then takes `done`
/// (ignored when not finite).
fn leak_and_add(work: &mut f64, done: f64, dt_s: f32) {
    *work *= (-f64::from(dt_s) / EnergyBudget::LEAK_TIME_S).exp();
    if done.is_finite() {
        *work += done;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turning_grants_the_port_itself_and_leaks_away() {
        let mut budget = EnergyBudget::new(2);
        // A needle turned through the tissue: 1 mJ a second of work the device cannot see.
        for _ in 0..1000 {
            budget.record_turn(0, 0.001, 0.001);
        }
        let granted = budget.allowance_mj(0);
        assert!(granted > 0.6 && granted < 0.65, "{granted}");
        assert_eq!(
            budget.allowance_mj(1),
            0.0,
            "the other port's hand did not turn it"
        );
        // Negative turning work (the tissue turning the tool back) grants nothing; garbage is ignored.
        budget.record_turn(0, -5.0, 0.001);
        budget.record_turn(0, f64::NAN, 0.001);
        assert_eq!(budget.allowance_mj(0), 0.0);
        budget.release(0);
        budget.record_turn(1, 2.0, 0.001);
        budget.release(1);
        assert_eq!(budget.allowance_mj(1), 0.0);
    }

    #[test]
    fn pushing_grants_the_other_port_and_leaks_away() {
        let mut budget = EnergyBudget::new(2);
        // Tool 0 pushes 1 N into the tissue over 2 mm (the tissue pushes back +z, the tool moves -z).
        for _ in 0..100 {
            budget.record(
                0,
                &Vec3::new(0.0, 0.0, 1.0),
                &Vec3::new(0.0, 0.0, -0.02),
                0.001,
            );
            budget.record(1, &Vec3::zeros(), &Vec3::zeros(), 0.001);
        }
        let granted = budget.allowance_mj(1);
        assert!(granted > 1.85 && granted < 2.0, "{granted}");
        assert_eq!(
            budget.allowance_mj(0),
            0.0,
            "its own work grants itself nothing"
        );
        for _ in 0..3000 {
            budget.record(0, &Vec3::zeros(), &Vec3::zeros(), 0.001);
        }
        assert!(budget.allowance_mj(1) < 0.1, "{}", budget.allowance_mj(1));
    }

    #[test]
    fn being_pushed_out_grants_nothing_and_the_cap_holds() {
        let mut budget = EnergyBudget::new(2);
        budget.record(
            0,
            &Vec3::new(0.0, 0.0, 1.0),
            &Vec3::new(0.0, 0.0, 5.0),
            0.001,
        );
        assert_eq!(budget.allowance_mj(1), 0.0);
        budget.record(
            0,
            &Vec3::new(0.0, 0.0, 1000.0),
            &Vec3::new(0.0, 0.0, -5.0),
            0.001,
        );
        assert_eq!(budget.allowance_mj(1), EnergyBudget::MAX_ALLOWANCE_MJ);
    }
}
