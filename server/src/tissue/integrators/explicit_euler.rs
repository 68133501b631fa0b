//! Forward (explicit) Euler: the classic simulators' baseline, kept for comparison.

use super::{Integrator, acceleration, flush_subnormal};
use crate::tissue::{MassSpringModel, TissueState};

/// `x += h v`, `v += h a(x, v)`, both from the state at the start of the step. Adds energy to an undamped
/// oscillator every step (its amplification is `sqrt(1 + h^2 w^2) > 1`), so it is stable only with enough
/// damping: `h <= g / w^2`. That is why symplectic Euler, at the same cost, is the default.
#[derive(Debug, Default, Clone, Copy)]
pub struct ExplicitEuler;

impl Integrator for ExplicitEuler {
    fn name(&self) -> &'static str {
        "explicit-euler"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        model.compute_forces(
            &state.positions_mm,
            &state.velocities_mm_s,
            Some(&state.external_forces_n),
            &mut state.forces_n,
        );
        let drag = model.drag_per_s();
        for (((x, v), f), &w) in state
            .positions_mm
            .iter_mut()
            .zip(state.velocities_mm_s.iter_mut())
            .zip(&state.forces_n)
            .zip(model.accel_per_force())
        {
            if w == 0.0 {
                continue;
            }
            let a = acceleration(w, *f, *v, drag);
            *x = flush_subnormal(*x + *v * dt_s);
            *v = flush_subnormal(*v + a * dt_s);
        }
        0
    }
}
