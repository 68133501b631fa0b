//! Tool-tissue interactions. For now: probing.
//!
//! Owns: turning tool contacts into node corrections and the force each tool feels. Must not: integrate
//! the tissue (that is [`crate::tissue`]) or find candidates (that is [`crate::collision`]).

mod probe;

pub use probe::ProbeContacts;
