//! sinew-protocol: the wire contract between the Sinew server, hapticservers and viewers.
//!
//! Owns: every message that crosses zenoh ([`messages`]), the key expressions they travel on ([`keys`]),
//! the versioned envelope and its typed decode errors ([`codec`]), mesh-position quantization ([`quantize`]),
//! the zenoh endpoint options every role shares ([`network`]), TLS and access control ([`security`]) and a
//! router's zenoh configuration file ([`zenoh_config_file`]). It
//! also holds the three tiny real-time primitives every role uses ([`rt`]: latest-value mailbox, latency
//! histogram, loop pacer) so the roles need not depend on each other. With the `cli` feature, the command-line flags every role shares ([`cli`]).
//!
//! Must not: open a zenoh session, touch parry, or know about the simulation. Plain data only.
#![warn(missing_docs)]

#[cfg(feature = "cli")]
pub mod cli;
pub mod codec;
pub mod keys;
pub mod messages;
pub mod network;
pub mod quantize;
pub mod rt;
pub mod security;
pub mod zenoh_config_file;

pub use codec::{
    DecodeError, InstanceId, Message, MessageKind, PROTOCOL_VERSION, decode, decode_from, encode,
};
pub use messages::*;
