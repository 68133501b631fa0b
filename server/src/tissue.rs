//! Soft tissue: the mass-spring model, its state, the time integrators that advance it, and what keeps them
//! honest (stability bounds, the anti-divergence guard).
//!
//! Owns: node masses, springs (structure-of-arrays, one kernel for every integrator), spring laws, anchors to
//! rest, fixed nodes, volume terms, tie-nodes between objects, the integrator seam ([`Integrator`]), and the
//! region of deformation that limits integration to the part that moves ([`RegionTracker`]).
//! Must not: know about tools, collision or the network.
//!
//! Units: positions mm, velocities mm/s, forces N, masses kg, stiffness N/mm, damping N s/mm. Newton's law in
//! these units is `a_mm_per_s2 = 1000 * f_n / m_kg` ([`MM_PER_M`]).

pub mod calibration;
pub mod fem;
pub mod fem_assembly;
pub mod guard;
pub mod guarded_step;
mod integrator_name;
pub mod integrators;
mod kuhn;
mod mass_spring;
mod object_desc;
pub mod pattern_cut;
mod puncture_material;
pub mod region;
mod rod;
pub mod seams;
pub mod spring_law;
pub mod springs;
pub mod stability;
mod state;
pub mod subdivision;
mod surface_mesh;
pub mod ties;
pub mod volume;
pub mod wound_gap;

pub use guard::{DivergenceGuard, Verdict};
pub use guarded_step::{GuardedStep, MAX_HALVINGS, Stepped, step_guarded};
pub use integrator_name::IntegratorName;
pub use integrators::{
    ExplicitEuler, ImplicitEuler, Integrator, QuasiStatic, Rk2, Rk4, SymplecticEuler, Xpbd,
    integrator_for,
};
pub use kuhn::KUHN;
pub use mass_spring::{MassSpringModel, ModelParts};
pub use object_desc::{FixedSelection, MassSpec, MaterialSpec, ObjectSpec, SpringCalibration};
pub use puncture_material::PunctureSpec;
pub use region::{RegionParams, RegionTracker, RegionUpdate};
pub use rod::{RodError, RodSpec};
pub use spring_law::SpringLaw;
pub use state::TissueState;
pub use surface_mesh::SurfaceMesh;
pub use ties::TieSet;

/// Millimetres per metre: converts N/kg (m/s^2) to mm/s^2.
pub const MM_PER_M: f32 = 1000.0;

/// nalgebra vector used throughout the tissue core.
pub type Vec3 = nalgebra::Vector3<f32>;
