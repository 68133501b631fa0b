//! The integrator seam: one trait, one implementation per method, chosen per object in the world file.

use super::{MassSpringModel, TissueState};
use crate::world::IntegratorName;

/// Advances a tissue by one step. Implementations keep their scratch buffers inside themselves or in
/// [`TissueState`], so a step allocates nothing.
pub trait Integrator: Send + std::fmt::Debug {
    /// Method name for reports.
    fn name(&self) -> &'static str;
    /// Advance `state` by `dt_s`. Real-time contract: no allocation, never panics; a non-finite result is
    /// left for the caller to detect ([`TissueState::is_finite`]).
    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32);
}

/// Semi-implicit (symplectic) Euler: `v += dt a(x, v)`, then `x += dt v` with the new velocity. Drag is
/// applied implicitly (`v /= 1 + dt drag`). Conditionally stable: see
/// [`MassSpringModel::stable_dt_bound_s`]. Energy stays bounded on undamped oscillators, unlike explicit Euler.
#[derive(Debug, Default, Clone, Copy)]
pub struct SymplecticEuler;

impl Integrator for SymplecticEuler {
    fn name(&self) -> &'static str {
        "symplectic-euler"
    }

    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) {
        model.compute_forces(
            &state.positions_mm,
            &state.velocities_mm_s,
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
    }
}

/// Values below this magnitude (mm, mm/s) become exactly zero.
const FLUSH_BELOW: f32 = 1e-30;

/// Replace components smaller than [`FLUSH_BELOW`] with zero, branch-free.
///
/// Regression guard: a tissue at rest on z = 0 with drag decays its velocities and z coordinates into
/// subnormal floats, and x86 takes a ~100-cycle penalty on every operation that touches one: the spring
/// kernel slowed from ~6 to ~20 ns per spring once the pad had settled. Nothing physical lives below 1e-30 mm.
#[inline(always)]
pub(crate) fn flush_subnormal(v: super::Vec3) -> super::Vec3 {
    v.map(|c| if c.abs() < FLUSH_BELOW { 0.0 } else { c })
}

/// The integrator a world file names.
pub fn integrator_for(name: IntegratorName) -> Box<dyn Integrator> {
    match name {
        IntegratorName::SymplecticEuler => Box::new(SymplecticEuler),
    }
}
