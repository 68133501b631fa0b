//! The versioned envelope around every message, and its typed errors.
//!
//! Layout on the wire: `[version: u16 LE][kind: u8][sender: u64 LE][postcard body]`. The version leads every
//! message so a peer built against another protocol revision is recognised before anything is parsed. The
//! sender is the [`InstanceId`] of the run that wrote it (as RTPS puts its participant prefix in every
//! message header): a receiver tells two hapticservers claiming one device id, or two servers for one scene,
//! apart by it, whatever the message. Decoding checks, in order: length, version, kind, sender (non-zero),
//! body (postcard, no trailing bytes), then the message's own [`Message::validate`] (finite numbers, unit
//! quaternions, index ranges).

use serde::{Serialize, de::DeserializeOwned};
use thiserror::Error;

/// Protocol revision carried by every message. Bump on any incompatible change.
pub const PROTOCOL_VERSION: u16 = 18;

/// Bytes of envelope before the postcard body.
pub const HEADER_LEN: usize = 11;

/// One run of one participant: drawn at random when a server, hapticserver or viewer starts, written into
/// the envelope of everything it sends, never zero. A restarted process is a new instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub struct InstanceId(pub u64);

impl InstanceId {
    /// No instance (a slot nobody holds). Never on the wire.
    pub const NONE: InstanceId = InstanceId(0);

    /// A fresh random instance id (std's per-process random hash keys, mixed with the clock and pid).
    pub fn random() -> Self {
        use std::hash::{BuildHasher, Hasher};
        let mut hasher = std::collections::hash_map::RandomState::new().build_hasher();
        hasher.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        hasher.write_u32(std::process::id());
        InstanceId(hasher.finish().max(1))
    }

    /// Whether this is [`InstanceId::NONE`].
    pub fn is_none(self) -> bool {
        self.0 == 0
    }
}

impl std::fmt::Display for InstanceId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:016x}", self.0)
    }
}

/// Which message a payload carries (the byte after the version).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum MessageKind {
    /// [`crate::DevicePose`]
    DevicePose = 1,
    /// [`crate::ForceCommand`]
    ForceCommand = 2,
    /// [`crate::SceneSnapshot`]
    SceneSnapshot = 3,
    /// [`crate::MeshDelta`]
    MeshDelta = 4,
    /// [`crate::ToolStates`]
    ToolStates = 5,
    /// [`crate::ServerStats`]
    ServerStats = 6,
    /// [`crate::ParticipantHello`]
    ParticipantHello = 7,
}

impl MessageKind {
    /// Human-readable name used in error messages and counters.
    pub fn name(self) -> &'static str {
        match self {
            MessageKind::DevicePose => "DevicePose",
            MessageKind::ForceCommand => "ForceCommand",
            MessageKind::SceneSnapshot => "SceneSnapshot",
            MessageKind::MeshDelta => "MeshDelta",
            MessageKind::ToolStates => "ToolStates",
            MessageKind::ServerStats => "ServerStats",
            MessageKind::ParticipantHello => "ParticipantHello",
        }
    }
}

/// Why a payload was refused. Every variant names the message kind it was expected to be.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    /// Shorter than the envelope header.
    #[error("{kind}: truncated payload ({len} bytes, header needs {HEADER_LEN})", kind = expected.name())]
    Truncated {
        /// The kind the receiver expected.
        expected: MessageKind,
        /// Payload length in bytes.
        len: usize,
    },
    /// Built against another protocol revision.
    #[error("{kind}: protocol version {got}, this build speaks {PROTOCOL_VERSION}", kind = expected.name())]
    WrongVersion {
        /// The kind the receiver expected.
        expected: MessageKind,
        /// Version found on the wire.
        got: u16,
    },
    /// The kind byte names another message.
    #[error("{kind}: payload carries message kind byte {got}", kind = expected.name())]
    WrongKind {
        /// The kind the receiver expected.
        expected: MessageKind,
        /// Kind byte found on the wire.
        got: u8,
    },
    /// The body does not parse (truncated, garbage, trailing bytes).
    #[error("{kind}: malformed body: {detail}", kind = expected.name())]
    Malformed {
        /// The kind the receiver expected.
        expected: MessageKind,
        /// What postcard reported.
        detail: String,
    },
    /// The body parses but a field is out of its domain (NaN, non-unit quaternion, bad index).
    #[error("{kind}: invalid field `{field}`: {reason}", kind = expected.name())]
    Invalid {
        /// The kind the receiver expected.
        expected: MessageKind,
        /// Offending field.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
}

impl DecodeError {
    /// Short class name for per-kind rejection counters.
    pub fn class(&self) -> &'static str {
        match self {
            DecodeError::Truncated { .. } => "truncated",
            DecodeError::WrongVersion { .. } => "wrong_version",
            DecodeError::WrongKind { .. } => "wrong_kind",
            DecodeError::Malformed { .. } => "malformed",
            DecodeError::Invalid { .. } => "invalid",
        }
    }
}

/// A field that failed validation: (field name, reason).
pub type FieldError = (&'static str, &'static str);

/// A wire message: serde-serialisable, with a fixed kind and a domain check.
pub trait Message: Serialize + DeserializeOwned {
    /// The kind byte written after the version.
    const KIND: MessageKind;
    /// Check field domains after parsing. Never panics.
    fn validate(&self) -> Result<(), FieldError>;
}

/// Encode `msg`, sent by `from`, into `out` (cleared first). Reuses `out`'s capacity: no allocation once it
/// is large enough.
pub fn encode<M: Message>(from: InstanceId, msg: &M, out: &mut Vec<u8>) {
    debug_assert!(!from.is_none(), "a message must name its sender");
    out.clear();
    out.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    out.push(M::KIND as u8);
    out.extend_from_slice(&from.0.to_le_bytes());
    // Serialising plain data into a Vec cannot fail: postcard only errors on unsupported serde features
    // (none used here) or a full fixed buffer (a Vec grows).
    if let Err(err) = postcard::to_io(msg, &mut *out) {
        debug_assert!(false, "postcard encode of {} failed: {err}", M::KIND.name());
    }
}

/// Encode into a fresh buffer (for non-real-time paths).
pub fn encode_to_vec<M: Message>(from: InstanceId, msg: &M) -> Vec<u8> {
    let mut out = Vec::with_capacity(64);
    encode(from, msg, &mut out);
    out
}

/// Decode and validate a payload expected to carry `M`, dropping the sender. Never panics, whatever the bytes.
pub fn decode<M: Message>(bytes: &[u8]) -> Result<M, DecodeError> {
    decode_from(bytes).map(|(_, msg)| msg)
}

/// Decode and validate a payload expected to carry `M`: its sender and the message. Never panics.
pub fn decode_from<M: Message>(bytes: &[u8]) -> Result<(InstanceId, M), DecodeError> {
    let expected = M::KIND;
    let truncated = || DecodeError::Truncated {
        expected,
        len: bytes.len(),
    };
    // The version first, from the first two bytes alone: an older, shorter envelope is named as such.
    let [v0, v1, ..] = *bytes else {
        return Err(truncated());
    };
    let version = u16::from_le_bytes([v0, v1]);
    if version != PROTOCOL_VERSION {
        return Err(DecodeError::WrongVersion {
            expected,
            got: version,
        });
    }
    if bytes.len() < HEADER_LEN {
        return Err(truncated());
    }
    if bytes[2] != expected as u8 {
        return Err(DecodeError::WrongKind {
            expected,
            got: bytes[2],
        });
    }
    let mut sender = [0u8; 8];
    sender.copy_from_slice(&bytes[3..HEADER_LEN]);
    let from = InstanceId(u64::from_le_bytes(sender));
    if from.is_none() {
        return Err(DecodeError::Invalid {
            expected,
            field: "sender",
            reason: "zero (every participant sends its non-zero instance id)",
        });
    }
    let (msg, rest) = postcard::take_from_bytes::<M>(&bytes[HEADER_LEN..]).map_err(|e| {
        DecodeError::Malformed {
            expected,
            detail: e.to_string(),
        }
    })?;
    if !rest.is_empty() {
        return Err(DecodeError::Malformed {
            expected,
            detail: format!("{} trailing bytes", rest.len()),
        });
    }
    msg.validate()
        .map_err(|(field, reason)| DecodeError::Invalid {
            expected,
            field,
            reason,
        })?;
    Ok((from, msg))
}

/// Helpers for [`Message::validate`] implementations.
pub mod check {
    use super::FieldError;

    /// All components finite.
    pub fn finite(field: &'static str, values: &[f32]) -> Result<(), FieldError> {
        if values.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err((field, "not finite"))
        }
    }

    /// A unit quaternion (norm within 1e-3 of one), components finite.
    pub fn unit_quaternion(field: &'static str, q: &[f32; 4]) -> Result<(), FieldError> {
        finite(field, q)?;
        let norm = q.iter().map(|c| c * c).sum::<f32>().sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err((field, "quaternion is not unit length"));
        }
        Ok(())
    }
}
