//! Quasi-static relaxation: move every node toward equilibrium, ignoring inertia.

use super::{Integrator, fit, flush_subnormal};
use crate::tissue::{MassSpringModel, SpringLaw, TissueState, Vec3};

/// Under-relaxation of each Jacobi sweep. The diagonal used is `sum(k) + k_anchor`, an upper bound of each
/// node's true diagonal, so `D^-1 K` has eigenvalues in (0, 2) and any factor below 1 converges; 0.8 damps the
/// highest mode fast without slowing the rest much.
const RELAXATION: f32 = 0.8;

/// Each sweep moves every free node by `0.8 f_i / K_ii` (damped nonlinear Jacobi on the static equilibrium
/// `f(x) = 0`); velocities report the motion (`dx / h`) but carry nothing to the next step. For heavily damped
/// tissue under slow tools: no inertia, no oscillation, unconditionally stable, one force pass per sweep.
/// With a stiffening law the diagonal is the tangent one at the current positions, recomputed every sweep
/// (one more pass over the springs); the small-strain one would overshoot a stiffened spring and diverge.
#[derive(Debug, Clone)]
pub struct QuasiStatic {
    sweeps: u32,
    start: Vec<Vec3>,
    inverse_diagonal: Vec<f32>,
}

impl QuasiStatic {
    /// `sweeps` relaxation sweeps per step (at least 1).
    pub fn new(sweeps: u32) -> Self {
        Self {
            sweeps: sweeps.max(1),
            start: Vec::new(),
            inverse_diagonal: Vec::new(),
        }
    }
}

/// `RELAXATION / K_ii` per node (0 for fixed nodes): the small-strain diagonal, or the tangent one at
/// `positions_mm` when given.
fn inverse_diagonal(model: &MassSpringModel, positions_mm: Option<&[Vec3]>, out: &mut [f32]) {
    match positions_mm {
        None => {
            for (i, d) in out.iter_mut().enumerate() {
                *d = model.diagonal_stiffness_n_per_mm(i);
            }
        }
        Some(x) => {
            out.fill(model.anchor_stiffness_n_per_mm());
            model
                .springs()
                .accumulate_tangent_diagonal(model.law(), x, out);
        }
    }
    for (i, d) in out.iter_mut().enumerate() {
        *d = if model.is_fixed(i) || *d <= 0.0 {
            0.0
        } else {
            RELAXATION / *d
        };
    }
}

impl Integrator for QuasiStatic {
    fn name(&self) -> &'static str {
        "quasi-static"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        let n = model.node_count();
        fit(&mut self.start, n);
        if self.inverse_diagonal.len() != n {
            self.inverse_diagonal.resize(n, 0.0);
        }
        let linear = model.law() == SpringLaw::Linear;
        if linear {
            inverse_diagonal(model, None, &mut self.inverse_diagonal);
        }
        self.start.copy_from_slice(&state.positions_mm);
        for _ in 0..self.sweeps {
            if !linear {
                inverse_diagonal(model, Some(&state.positions_mm), &mut self.inverse_diagonal);
            }
            model.compute_static_forces(
                &state.positions_mm,
                Some(&state.external_forces_n),
                &mut state.forces_n,
            );
            for ((x, f), &inverse) in state
                .positions_mm
                .iter_mut()
                .zip(&state.forces_n)
                .zip(&self.inverse_diagonal)
            {
                *x = flush_subnormal(*x + f * inverse);
            }
        }
        let inv_dt = 1.0 / dt_s;
        for ((v, x), x0) in state
            .velocities_mm_s
            .iter_mut()
            .zip(&state.positions_mm)
            .zip(&self.start)
        {
            *v = flush_subnormal((x - x0) * inv_dt);
        }
        self.sweeps
    }
}
