//! Haptics on the server: how tools follow their devices, and the local model each device renders.
//!
//! Owns: the virtual coupling of a tool to its (late) device pose ([`coupling`]), the tissue's condensed
//! stiffness and damping at a contact ([`contact_stiffness`], with its normal stiffness fitted to the tissue's
//! answer by [`stiffness_estimate`]), nearby untouched surfaces as unilateral planes
//! ([`surface_planes`]), the energy budget across ports ([`energy_budget`]), and the per-device stream of
//! force commands with its perceptual deadband ([`model_stream`]).
//!
//! Must not: touch zenoh or threads (the node sends what [`model_stream`] builds), or move the tissue.

pub mod contact_stiffness;
pub mod coupling;
pub mod energy_budget;
pub mod model_stream;
pub mod stiffness_estimate;
pub mod surface_planes;

pub use contact_stiffness::{ContactResponse, ContactStiffness};
pub use coupling::{CouplingParams, VirtualCoupling};
pub use energy_budget::EnergyBudget;
pub use model_stream::{DeadbandParams, ModelStream, StreamCounters};
pub use stiffness_estimate::NormalStiffnessEstimate;
pub use surface_planes::{WorldPlane, nearest_surface_plane};

/// Planes a local model carries (the wire's limit).
pub const MAX_PLANES: usize = sinew_protocol::MAX_CONTACT_PLANES;
