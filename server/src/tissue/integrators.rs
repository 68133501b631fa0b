//! The integrator seam: one trait, one implementation per method, chosen per object in the world file.
//!
//! | method | file | stability | cost per step |
//! |---|---|---|---|
//! | explicit Euler | `explicit_euler.rs` | needs damping; `h <= g / w^2` | 1 force pass |
//! | symplectic Euler (default) | `symplectic_euler.rs` | `h w < 2` (undamped) | 1 force pass |
//! | RK2 (midpoint) | `runge_kutta.rs` | needs damping | 2 force passes |
//! | RK4 | `runge_kutta.rs` | `h w < 2.8` | 4 force passes |
//! | quasi-static | `quasi_static.rs` | unconditional (relaxation) | 1 force pass |
//! | implicit Euler + CG | `implicit_euler.rs` | unconditional (linearised) | 1 force pass + CG |
//! | XPBD | `xpbd.rs` | unconditional | `iterations` constraint sweeps |
//!
//! Every implementation keeps its scratch buffers inside itself, sized on first use: a step allocates nothing
//! once warm. Drag is part of every method (explicitly in the explicit ones, implicitly in symplectic Euler,
//! implicit Euler and XPBD).

mod explicit_euler;
mod implicit_euler;
mod quasi_static;
mod runge_kutta;
mod symplectic_euler;
mod xpbd;

pub use explicit_euler::ExplicitEuler;
pub use implicit_euler::ImplicitEuler;
pub use quasi_static::QuasiStatic;
pub use runge_kutta::{Rk2, Rk4};
pub use symplectic_euler::SymplecticEuler;
pub use xpbd::Xpbd;

use super::IntegratorName;
use super::{MassSpringModel, TissueState, Vec3};

/// Advances a tissue by one step.
pub trait Integrator: Send + std::fmt::Debug {
    /// Method name for reports.
    fn name(&self) -> &'static str;
    /// Advance `state` by `dt_s`; returns the solver iterations used (0 for explicit methods). Real-time
    /// contract: no allocation once warm (first call on a model of this size), never panics; a non-finite
    /// result is left for the caller to detect ([`TissueState::is_finite`]).
    fn step(&mut self, model: &MassSpringModel, state: &mut TissueState, dt_s: f32) -> u32;
}

/// The integrator a world file names, with its iteration count (XPBD sweeps, CG iterations, relaxation
/// sweeps per step; `None` takes the method's default).
pub fn integrator_for(name: IntegratorName, iterations: Option<u32>) -> Box<dyn Integrator> {
    match name {
        IntegratorName::ExplicitEuler => Box::new(ExplicitEuler),
        IntegratorName::SymplecticEuler => Box::new(SymplecticEuler),
        IntegratorName::Rk2 => Box::new(Rk2::default()),
        IntegratorName::Rk4 => Box::new(Rk4::default()),
        IntegratorName::QuasiStatic => Box::new(QuasiStatic::new(iterations.unwrap_or(1))),
        IntegratorName::ImplicitEuler => Box::new(ImplicitEuler::new(iterations.unwrap_or(40))),
        IntegratorName::Xpbd => Box::new(Xpbd::new(iterations.unwrap_or(4))),
    }
}

/// Resize a scratch buffer to `n` (allocates only when it grows past its capacity).
pub(crate) fn fit(buffer: &mut Vec<Vec3>, n: usize) {
    if buffer.len() != n {
        buffer.resize(n, Vec3::zeros());
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
pub(crate) fn flush_subnormal(v: Vec3) -> Vec3 {
    v.map(|c| if c.abs() < FLUSH_BELOW { 0.0 } else { c })
}

/// Acceleration of a node with force `f`, velocity `v`, `w = 1000 / m` (0 when fixed) and explicit drag, mm/s^2.
#[inline(always)]
pub(crate) fn acceleration(w: f32, f: Vec3, v: Vec3, drag_per_s: f32) -> Vec3 {
    if w == 0.0 {
        Vec3::zeros()
    } else {
        f * w - v * drag_per_s
    }
}
