//! The viewer's counters, as a small `Copy` struct published by the sync worker.
//!
//! Owns: the names and meaning of every viewer counter and rate. Must not: compute them (the client does) or
//! hold anything that allocates.

use sinew_protocol::DecodeError;

/// Payloads the viewer refused to decode, by [`DecodeError::class`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecodeErrorCounts {
    /// Shorter than the envelope header.
    pub truncated: u64,
    /// Another protocol version.
    pub wrong_version: u64,
    /// Another message kind on this key.
    pub wrong_kind: u64,
    /// Body does not parse.
    pub malformed: u64,
    /// Body parses but a field is out of domain.
    pub invalid: u64,
}

impl DecodeErrorCounts {
    /// Count one refusal.
    pub fn record(&mut self, err: &DecodeError) {
        match err {
            DecodeError::Truncated { .. } => self.truncated += 1,
            DecodeError::WrongVersion { .. } => self.wrong_version += 1,
            DecodeError::WrongKind { .. } => self.wrong_kind += 1,
            DecodeError::Malformed { .. } => self.malformed += 1,
            DecodeError::Invalid { .. } => self.invalid += 1,
        }
    }

    /// All refusals.
    pub fn total(&self) -> u64 {
        self.truncated + self.wrong_version + self.wrong_kind + self.malformed + self.invalid
    }
}

/// A viewer's health: counts since start, rates over the last second, and the replica's position.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ViewerStats {
    /// A snapshot has been applied at least once.
    pub has_snapshot: bool,
    /// A server presence token is currently live.
    pub server_present: bool,
    /// Messages dropped because another live server for the scene sent them (this viewer stays with the
    /// server it joined).
    pub from_other_server: u64,
    /// Snapshot queries sent.
    pub snapshot_queries: u64,
    /// Snapshots received and applied.
    pub snapshots_fetched: u64,
    /// Queries that ended without a usable snapshot (timeout, no queryable, undecodable reply).
    pub snapshot_failures: u64,
    /// Round trip of the last successful snapshot query, milliseconds.
    pub snapshot_fetch_last_ms: f32,
    /// Longest successful snapshot round trip, milliseconds.
    pub snapshot_fetch_max_ms: f32,
    /// Deltas folded into the replica.
    pub deltas_applied: u64,
    /// Deltas ignored because the replica already had their frame.
    pub deltas_stale: u64,
    /// Deltas that revealed a missed delta (each triggers a re-snapshot).
    pub gaps: u64,
    /// Deltas refused as protocol errors (unknown object, index out of range); each triggers a re-snapshot.
    pub protocol_errors: u64,
    /// Deltas waiting for a snapshot right now.
    pub deltas_buffered: u64,
    /// Deltas dropped from the full wait buffer.
    pub deltas_dropped: u64,
    /// Tool-state messages taken (one per server publish frame).
    pub tool_updates: u64,
    /// Server stats messages received.
    pub server_stats_received: u64,
    /// Payload bytes received on every subscription and snapshot reply.
    pub bytes_received: u64,
    /// Payloads refused by the decoder.
    pub decode_errors: DecodeErrorCounts,
    /// Server publish frames received per second (tool-state heartbeats), over the last second.
    pub frames_per_s: f64,
    /// Mesh deltas received per second, over the last second.
    pub deltas_per_s: f64,
    /// Payload bytes received per second, over the last second.
    pub bytes_per_s: f64,
    /// Newest publish frame folded into the replica.
    pub replica_frame: u64,
    /// The replica's worst-case position error over all objects, mm.
    pub replica_error_bound_mm: f32,
}
