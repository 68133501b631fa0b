//! Inbound force commands: from zenoh's callback thread to the device loop.
//!
//! Owns: decoding of [`ForceCommand`] payloads, per-class counts of refused payloads ([`DecodeRejects`]) and the
//! single-slot mailbox ([`LatestValue`]) holding the newest valid command with its arrival time.
//!
//! Must not: hold a lock the loop waits on (the loop only `try_lock`s the mailbox), queue commands (only the
//! newest matters), or decide what force to render (that is [`crate::safety`]).

use std::sync::atomic::{AtomicU64, Ordering};

use sinew_protocol::rt::LatestValue;
use sinew_protocol::{DecodeError, ForceCommand, decode};

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

/// Mailbox and reject counters for one device's force key.
#[derive(Debug, Default)]
pub struct ForceInbox {
    latest: LatestValue<ReceivedForce>,
    truncated: AtomicU64,
    wrong_version: AtomicU64,
    wrong_kind: AtomicU64,
    malformed: AtomicU64,
    invalid: AtomicU64,
}

impl ForceInbox {
    /// An empty inbox.
    pub fn new() -> Self {
        Self::default()
    }

    /// Decode `payload`, received at `received_ns`; store it if valid, else count the reject and return why.
    /// Called from zenoh's callback thread; never panics.
    pub fn accept(&self, payload: &[u8], received_ns: u64) -> Result<(), DecodeError> {
        match decode::<ForceCommand>(payload) {
            Ok(command) => {
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
                Err(err)
            }
        }
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

    #[test]
    fn valid_commands_are_stored_and_bad_ones_counted_by_class() {
        let inbox = ForceInbox::new();
        let command = ForceCommand {
            seq: 7,
            force_n: [0.0, 0.0, 1.0],
            ..ForceCommand::default()
        };
        inbox.accept(&encode_to_vec(&command), 42).unwrap();
        let mut seen = 0;
        let got = inbox.latest().take_newer(&mut seen).unwrap();
        assert_eq!(got.command, command);
        assert_eq!(got.received_ns, 42);

        assert!(inbox.accept(&[1], 0).is_err());
        let mut wrong_version = encode_to_vec(&command);
        wrong_version[..2].copy_from_slice(&(PROTOCOL_VERSION + 1).to_le_bytes());
        assert!(inbox.accept(&wrong_version, 0).is_err());
        assert!(
            inbox
                .accept(&encode_to_vec(&DevicePose::default()), 0)
                .is_err()
        );
        let whole = encode_to_vec(&command);
        assert!(inbox.accept(&whole[..whole.len() - 1], 0).is_err());
        let nan = ForceCommand {
            force_n: [f32::NAN, 0.0, 0.0],
            ..command
        };
        assert!(inbox.accept(&encode_to_vec(&nan), 0).is_err());

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
