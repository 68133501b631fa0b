//! Haptics on the server: how tools follow their devices, and the local model each device renders.
//!
//! Owns: the virtual coupling of a tool to its (late) device pose ([`coupling`]), the tissue's condensed
//! stiffness and damping at a contact ([`contact_stiffness`], with its normal stiffness fitted to the tissue's
//! answer by [`stiffness_estimate`], and its sliding friction measured by [`friction_estimate`]), nearby
//! untouched surfaces as unilateral planes
//! ([`surface_planes`], with the stiffness of a first touch-down: [`touchdown`]) and the energy budget across ports ([`energy_budget`]). The per-device stream of
//! force commands and its deadband sit one layer up, with the tick that feeds them
//! (`crate::server_tick::model_stream`): this layer never reads the sim's output.
//!
//! Must not: touch zenoh or threads, read the sim, or move the tissue.

pub mod contact_stiffness;
pub mod coupling;
pub mod energy_budget;
pub mod friction_estimate;
pub mod stiffness_estimate;
pub mod surface_planes;
pub mod touchdown;

pub use contact_stiffness::{ContactResponse, ContactStiffness};
pub use coupling::{CouplingParams, VirtualCoupling};
pub use energy_budget::EnergyBudget;
pub use friction_estimate::KineticFrictionEstimate;
pub use stiffness_estimate::NormalStiffnessEstimate;
pub use surface_planes::{Surface, WorldPlane, nearest_shaft_plane, nearest_surface_plane};
pub use touchdown::{TOUCHDOWN_DEPTH_PER_REACH, Touchdown};

/// Planes a local model carries (the wire's limit).
pub const MAX_PLANES: usize = sinew_protocol::MAX_CONTACT_PLANES;
