//! The hapticserver process around the loop: its configuration ([`haptic_config`]), zenoh session
//! ([`zenoh_session`]), declarations, threads and handle ([`haptic_server`]), what it knows of the server
//! ([`server_watch`]), and what it reports ([`report`], [`trace`], [`stillness`]).
//!
//! Must not: compute a force.

pub mod haptic_config;
pub mod haptic_server;
pub mod report;
pub mod server_watch;
pub mod stillness;
pub mod trace;
pub mod zenoh_session;
