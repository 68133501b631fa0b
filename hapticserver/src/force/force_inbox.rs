//! Inbound force commands: from zenoh's callback thread to the device loop.
//!
//! Owns: decoding of [`ForceCommand`] payloads, per-class counts of refused payloads ([`DecodeRejects`]), the
//! server this device joined ([`JoinedServer`]: commands from any other live server for the scene are refused
//! and counted), the refusal of commands meant for another instance using the same device id, and the
//! single-slot mailbox ([`LatestValue`]) holding the newest valid command with its arrival time.
//!
//! Must not: hold a lock the loop waits on (the loop only `try_lock`s the mailbox), queue commands (only the
//! newest matters), or decide what force to render (that is [`crate::safety`]).

use std::sync::atomic::{AtomicU64, Ordering};

use sinew_protocol::rt::{JoinedServer, LatestValue};
use sinew_protocol::{DecodeError, ForceCommand, InstanceId, decode_from};

/// A valid command and when it arrived.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ReceivedForce {
    /// The command.
    pub command: ForceCommand,
    /// Arrival time on the hapticserver's [`crate::clock::MonotonicClock`], ns.
    pub received_ns: u64,
}

/// Refused force payloads, by [`DecodeError::class`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecodeRejects {
    /// Shorter than the envelope header.
    pub truncated: u64,
    /// Another protocol version.
    pub wrong_version: u64,
    /// Another message kind.
    pub wrong_kind: u64,
    /// Body does not parse.
    pub malformed: u64,
    /// A field out of its domain (e.g. a NaN force).
    pub invalid: u64,
}

impl DecodeRejects {
    /// All refused payloads.
    pub fn total(&self) -> u64 {
        self.truncated + self.wrong_version + self.wrong_kind + self.malformed + self.invalid
    }
}

/// Why a valid command was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// The payload does not decode.
    Decode,
    /// From a server other than the one this device joined.
    OtherServer,
    /// It answers another instance's poses: that instance holds this device id.
    OtherInstance,
}

/// Mailbox and reject counters for one device's force key.
#[derive(Debug, Default)]
pub struct ForceInbox {
    own: InstanceId,
    server: JoinedServer,
    other_instance: AtomicU64,
    latest: LatestValue<ReceivedForce>,
    truncated: AtomicU64,
    wrong_version: AtomicU64,
    wrong_kind: AtomicU64,
    malformed: AtomicU64,
    invalid: AtomicU64,
}

impl ForceInbox {
    /// An empty inbox for the device instance `own`.
    pub fn new(own: InstanceId) -> Self {
        Self {
            own,
            ..Self::default()
        }
    }

    /// Decode `payload`, received at `received_ns`; store it if valid, from the joined server and for this
    /// instance, else count the refusal and say why. Called from zenoh's callback thread; never panics.
    pub fn accept(&self, payload: &[u8], received_ns: u64) -> Result<(), Refusal> {
        match decode_from::<ForceCommand>(payload) {
            Ok((from, command)) => {
                if command.device_instance != self.own.0 {
                    self.other_instance.fetch_add(1, Ordering::Relaxed);
                    return Err(Refusal::OtherInstance);
                }
                if !self.server.admit(from, received_ns).admitted() {
                    return Err(Refusal::OtherServer);
                }
                self.latest.store(ReceivedForce {
                    command,
                    received_ns,
                });
                Ok(())
            }
            Err(err) => {
                let counter = match &err {
                    DecodeError::Truncated { .. } => &self.truncated,
                    DecodeError::WrongVersion { .. } => &self.wrong_version,
                    DecodeError::WrongKind { .. } => &self.wrong_kind,
                    DecodeError::Malformed { .. } => &self.malformed,
                    DecodeError::Invalid { .. } => &self.invalid,
                };
                counter.fetch_add(1, Ordering::Relaxed);
                Err(Refusal::Decode)
            }
        }
    }

    /// This device's instance.
    pub fn own_instance(&self) -> InstanceId {
        self.own
    }

    /// The server this device follows (shared with the stats and presence callbacks).
    pub fn server(&self) -> &JoinedServer {
        &self.server
    }

    /// Valid commands refused because they answered another instance holding this device id.
    pub fn for_other_instance(&self) -> u64 {
        self.other_instance.load(Ordering::Relaxed)
    }

    /// The mailbox the loop reads.
    pub fn latest(&self) -> &LatestValue<ReceivedForce> {
        &self.latest
    }

    /// Valid commands received so far.
    pub fn received(&self) -> u64 {
        self.latest.writes()
    }

    /// Refused payloads so far.
    pub fn rejects(&self) -> DecodeRejects {
        let load = |c: &AtomicU64| c.load(Ordering::Relaxed);
        DecodeRejects {
            truncated: load(&self.truncated),
            wrong_version: load(&self.wrong_version),
            wrong_kind: load(&self.wrong_kind),
            malformed: load(&self.malformed),
            invalid: load(&self.invalid),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sinew_protocol::codec::encode_to_vec;
    use sinew_protocol::{DevicePose, PROTOCOL_VERSION};

    const ME: InstanceId = InstanceId(0x1e);
    const SERVER: InstanceId = InstanceId(0x5e);

    fn encode_to_vec_from_server<M: sinew_protocol::Message>(m: &M) -> Vec<u8> {
        encode_to_vec(SERVER, m)
    }

    #[test]
    fn only_the_joined_server_and_commands_for_this_instance_are_taken() {
        let inbox = ForceInbox::new(ME);
        let mine = ForceCommand {
            seq: 1,
            device_instance: ME.0,
            ..ForceCommand::default()
        };
        inbox.accept(&encode_to_vec(SERVER, &mine), 1_000).unwrap();
        assert_eq!(
            inbox.accept(&encode_to_vec(InstanceId(0x77), &mine), 2_000),
            Err(Refusal::OtherServer)
        );
        let theirs = ForceCommand {
            device_instance: 0x99,
            ..mine
        };
        assert_eq!(
            inbox.accept(&encode_to_vec(SERVER, &theirs), 3_000),
            Err(Refusal::OtherInstance)
        );
        assert_eq!(inbox.received(), 1);
        assert_eq!(inbox.server().foreign(), 1);
        assert_eq!(inbox.for_other_instance(), 1);
        assert_eq!(inbox.server().current(), SERVER);
    }

    #[test]
    fn valid_commands_are_stored_and_bad_ones_counted_by_class() {
        let inbox = ForceInbox::new(ME);
        let command = ForceCommand {
            seq: 7,
            force_n: [0.0, 0.0, 1.0],
            device_instance: ME.0,
            ..ForceCommand::default()
        };
        inbox
            .accept(&encode_to_vec_from_server(&command), 42)
            .unwrap();
        let mut seen = 0;
        let got = inbox.latest().take_newer(&mut seen).unwrap();
        assert_eq!(got.command, command);
        assert_eq!(got.received_ns, 42);

        assert!(inbox.accept(&[1], 0).is_err());
        let mut wrong_version = encode_to_vec_from_server(&command);
        wrong_version[..2].copy_from_slice(&(PROTOCOL_VERSION + 1).to_le_bytes());
        assert!(inbox.accept(&wrong_version, 0).is_err());
        assert!(
            inbox
                .accept(&encode_to_vec_from_server(&DevicePose::default()), 0)
                .is_err()
        );
        let whole = encode_to_vec_from_server(&command);
        assert!(inbox.accept(&whole[..whole.len() - 1], 0).is_err());
        let nan = ForceCommand {
            force_n: [f32::NAN, 0.0, 0.0],
            ..command
        };
        assert!(inbox.accept(&encode_to_vec_from_server(&nan), 0).is_err());

        assert_eq!(
            inbox.rejects(),
            DecodeRejects {
                truncated: 1,
                wrong_version: 1,
                wrong_kind: 1,
                malformed: 1,
                invalid: 1,
            }
        );
        assert_eq!(inbox.received(), 1);
        assert_eq!(inbox.latest().take_newer(&mut seen), None);
    }
}
