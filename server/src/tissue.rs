//! Soft tissue: the mass-spring model, its state, and the time integrators that advance it.
//!
//! Owns: node masses, edges (spring-dampers from the unique mesh edges), anchors to rest, fixed nodes, and
//! the integrator seam ([`Integrator`]). Must not: know about tools, collision or the network.
//!
//! Units: positions mm, velocities mm/s, forces N, masses kg, stiffness N/mm, damping N s/mm. Newton's law in
//! these units is `a_mm_per_s2 = 1000 * f_n / m_kg` ([`MM_PER_M`]).

mod integrator;
mod mass_spring;
mod state;

pub use integrator::{Integrator, SymplecticEuler, integrator_for};
pub use mass_spring::MassSpringModel;
pub use state::TissueState;

/// Millimetres per metre: converts N/kg (m/s^2) to mm/s^2.
pub const MM_PER_M: f32 = 1000.0;

/// nalgebra vector used throughout the tissue core.
pub type Vec3 = nalgebra::Vector3<f32>;
