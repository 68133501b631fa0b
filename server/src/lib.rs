//! sinew-server: the authoritative Sinew simulation.
//!
//! The library is a synchronous core ([`world`], [`tissue`], [`collision`], [`interaction`], [`haptics`],
//! [`sim`], [`replication`]) with no
//! zenoh or tokio in it, plus [`node`], which wires that core to zenoh on dedicated threads. `main.rs` only
//! parses flags and calls [`node::ServerNode::start`].
#![warn(missing_docs)]

pub mod collision;
pub mod haptics;
mod incidence;
pub mod interaction;
pub mod multirate;
pub mod node;
pub mod recording;
pub mod replication;
pub mod scene;
pub mod server_tick;
pub mod sim;
pub mod tissue;
pub mod training;
pub mod world;
