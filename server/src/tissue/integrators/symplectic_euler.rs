//! Semi-implicit (symplectic) Euler, the default.

use super::{Integrator, flush_subnormal};
use crate::tissue::{MassSpringModel, TissueState};

/// `v += h a(x, v)`, then `x += h v` with the new velocity. Drag is applied implicitly (`v /= 1 + h drag`).
/// Conditionally stable (see [`crate::tissue::stability`]); energy stays bounded on undamped oscillators,
/// unlike explicit Euler, at the same cost.
#[derive(Debug, Default, Clone, Copy)]
pub struct SymplecticEuler;

impl Integrator for SymplecticEuler {
    fn name(&self) -> &'static str {
        "symplectic-euler"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        model.compute_forces(
            &state.positions_mm,
            &state.velocities_mm_s,
            Some(&state.external_forces_n),
            &mut state.forces_n,
        );
        let drag_factor = 1.0 / (1.0 + dt_s * model.drag_per_s());
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
            *v = flush_subnormal((*v + f * (w * dt_s)) * drag_factor);
            *x = flush_subnormal(*x + *v * dt_s);
        }
        0
    }
}
