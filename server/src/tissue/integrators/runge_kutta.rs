//! Explicit Runge-Kutta methods: RK2 (midpoint) and classic RK4, on the first-order system `(x, v)`.

use super::{Integrator, acceleration, fit, flush_subnormal};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// Accelerations of every node at `(x, v)`, written into `acc` (forces go through `forces` scratch).
fn accelerations(
    model: &MassSpringModel,
    x: &[Vec3],
    v: &[Vec3],
    external: &[Vec3],
    forces: &mut [Vec3],
    acc: &mut [Vec3],
) {
    model.compute_forces(x, v, Some(external), forces);
    let drag = model.drag_per_s();
    for (((a, f), v), &w) in acc
        .iter_mut()
        .zip(forces.iter())
        .zip(v)
        .zip(model.accel_per_force())
    {
        *a = acceleration(w, *f, *v, drag);
    }
}

/// Midpoint method: evaluate the slope at the start, step half way, evaluate again, take the whole step with
/// the midpoint slope. Second order; like explicit Euler it gains energy on an undamped oscillator (slowly:
/// amplification `sqrt(1 + (h w)^4 / 4)`), so it needs damping to be stable.
#[derive(Debug, Default, Clone)]
pub struct Rk2 {
    x_mid: Vec<Vec3>,
    v_mid: Vec<Vec3>,
    acc: Vec<Vec3>,
}

impl Integrator for Rk2 {
    fn name(&self) -> &'static str {
        "rk2"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        let n = model.node_count();
        fit(&mut self.x_mid, n);
        fit(&mut self.v_mid, n);
        fit(&mut self.acc, n);
        let half = 0.5 * dt_s;
        accelerations(
            model,
            &state.positions_mm,
            &state.velocities_mm_s,
            &state.external_forces_n,
            &mut state.forces_n,
            &mut self.acc,
        );
        for i in 0..n {
            self.x_mid[i] = state.positions_mm[i] + state.velocities_mm_s[i] * half;
            self.v_mid[i] = state.velocities_mm_s[i] + self.acc[i] * half;
        }
        accelerations(
            model,
            &self.x_mid,
            &self.v_mid,
            &state.external_forces_n,
            &mut state.forces_n,
            &mut self.acc,
        );
        for (i, &w) in model.accel_per_force().iter().enumerate() {
            if w == 0.0 {
                continue;
            }
            state.positions_mm[i] = flush_subnormal(state.positions_mm[i] + self.v_mid[i] * dt_s);
            state.velocities_mm_s[i] =
                flush_subnormal(state.velocities_mm_s[i] + self.acc[i] * dt_s);
        }
        0
    }
}

/// Classic fourth-order Runge-Kutta: four slope evaluations weighted 1-2-2-1. Its error falls 16x per halving
/// of `h`; stable for an undamped oscillator up to `h w = 2.83`.
#[derive(Debug, Default, Clone)]
pub struct Rk4 {
    x_stage: Vec<Vec3>,
    v_stage: Vec<Vec3>,
    acc: Vec<Vec3>,
    sum_dx: Vec<Vec3>,
    sum_dv: Vec<Vec3>,
}

impl Integrator for Rk4 {
    fn name(&self) -> &'static str {
        "rk4"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32 {
        let n = model.node_count();
        for buffer in [
            &mut self.x_stage,
            &mut self.v_stage,
            &mut self.acc,
            &mut self.sum_dx,
            &mut self.sum_dv,
        ] {
            fit(buffer, n);
        }
        let (x0, v0) = (&state.positions_mm, &state.velocities_mm_s);
        // Stage 1 at (x0, v0).
        accelerations(
            model,
            x0,
            v0,
            &state.external_forces_n,
            &mut state.forces_n,
            &mut self.acc,
        );
        for i in 0..n {
            self.sum_dx[i] = v0[i];
            self.sum_dv[i] = self.acc[i];
            self.x_stage[i] = x0[i] + v0[i] * (0.5 * dt_s);
            self.v_stage[i] = v0[i] + self.acc[i] * (0.5 * dt_s);
        }
        // Stages 2 and 3: slope at the stage, then the next stage from (x0, v0).
        for next_fraction in [0.5f32, 1.0] {
            accelerations(
                model,
                &self.x_stage,
                &self.v_stage,
                &state.external_forces_n,
                &mut state.forces_n,
                &mut self.acc,
            );
            for i in 0..n {
                let v_stage = self.v_stage[i];
                self.sum_dx[i] += v_stage * 2.0;
                self.sum_dv[i] += self.acc[i] * 2.0;
                self.x_stage[i] = x0[i] + v_stage * (next_fraction * dt_s);
                self.v_stage[i] = v0[i] + self.acc[i] * (next_fraction * dt_s);
            }
        }
        // Stage 4.
        accelerations(
            model,
            &self.x_stage,
            &self.v_stage,
            &state.external_forces_n,
            &mut state.forces_n,
            &mut self.acc,
        );
        let sixth = dt_s / 6.0;
        for (i, &w) in model.accel_per_force().iter().enumerate() {
            if w == 0.0 {
                continue;
            }
            let dx = (self.sum_dx[i] + self.v_stage[i]) * sixth;
            let dv = (self.sum_dv[i] + self.acc[i]) * sixth;
            state.positions_mm[i] = flush_subnormal(state.positions_mm[i] + dx);
            state.velocities_mm_s[i] = flush_subnormal(state.velocities_mm_s[i] + dv);
        }
        0
    }
}
