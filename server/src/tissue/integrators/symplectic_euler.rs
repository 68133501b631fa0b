//! Semi-implicit (symplectic) Euler, the default.

use super::{Integrator, flush_subnormal};
use crate::tissue::springs::NODE_CHUNK;
use crate::tissue::{MassSpringModel, TissueState};
use sinew_parallel::{chunk_range, for_chunks_mut2};

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
        let (forces, accel_per_force) = (&state.forces_n, model.accel_per_force());
        // Node by node, so any chunking of the nodes gives the same bits.
        for_chunks_mut2(
            model.chunk_runner(),
            &mut state.positions_mm,
            &mut state.velocities_mm_s,
            NODE_CHUNK,
            |c, xs, vs| {
                let nodes = chunk_range(c, forces.len().min(accel_per_force.len()), NODE_CHUNK);
                for ((x, v), i) in xs.iter_mut().zip(vs.iter_mut()).zip(nodes) {
                    let w = accel_per_force[i];
                    if w == 0.0 {
                        continue;
                    }
                    *v = flush_subnormal((*v + forces[i] * (w * dt_s)) * drag_factor);
                    *x = flush_subnormal(*x + *v * dt_s);
                }
            },
        );
        0
    }
}
