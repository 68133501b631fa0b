//! The names of the time integrators an object can be stepped by: an engine type (the world file's
//! `integrator = "..."` deserialises straight into it, by these kebab-case names).
//!
//! Owns: [`IntegratorName`]. Must not: step anything ([`crate::tissue::integrators`] does).

use serde::Deserialize;

/// Time integrator of a deformable object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntegratorName {
    /// Forward Euler (needs damping to be stable; for comparison).
    ExplicitEuler,
    /// Semi-implicit (symplectic) Euler: velocity first, then position with the new velocity. The default.
    SymplecticEuler,
    /// Second-order Runge-Kutta (midpoint).
    Rk2,
    /// Classic fourth-order Runge-Kutta.
    Rk4,
    /// Relaxation to equilibrium, ignoring inertia.
    QuasiStatic,
    /// Backward Euler, linearised, solved by conjugate gradient.
    ImplicitEuler,
    /// Extended position-based dynamics (distance and volume constraints).
    Xpbd,
}

impl IntegratorName {
    /// Every method, in the order reports list them.
    pub const ALL: [IntegratorName; 7] = [
        IntegratorName::ExplicitEuler,
        IntegratorName::SymplecticEuler,
        IntegratorName::Rk2,
        IntegratorName::Rk4,
        IntegratorName::QuasiStatic,
        IntegratorName::ImplicitEuler,
        IntegratorName::Xpbd,
    ];

    /// The name the world file uses.
    pub fn as_str(self) -> &'static str {
        match self {
            IntegratorName::ExplicitEuler => "explicit-euler",
            IntegratorName::SymplecticEuler => "symplectic-euler",
            IntegratorName::Rk2 => "rk2",
            IntegratorName::Rk4 => "rk4",
            IntegratorName::QuasiStatic => "quasi-static",
            IntegratorName::ImplicitEuler => "implicit-euler",
            IntegratorName::Xpbd => "xpbd",
        }
    }
}
