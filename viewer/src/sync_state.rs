//! The viewer's synchronisation state machine: when to apply, buffer, or re-query.
//!
//! Owns: the replica plus everything around it that the zenoh callbacks and the sync worker share (the wait
//! buffer of deltas that arrive while a snapshot is pending, the "needs a snapshot" flag, server presence,
//! the latest server stats, counters and rates). The client keeps it under one mutex.
//!
//! Rules: until the first snapshot, and from any gap until the next snapshot, deltas go into a bounded
//! drop-oldest buffer; after a snapshot is installed the buffer is replayed in arrival order (stale deltas are
//! skipped). A gap or a protocol error (unknown object, index out of range) asks for a new snapshot.
//!
//! Must not: touch zenoh, block, sleep, or decode (callers decode outside the lock and pass the result in).
//! Every method is O(payload) and never panics.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use sinew_protocol::rt::LatencyHistogram;
use sinew_protocol::{DecodeError, MeshDelta, SceneSnapshot, ServerStats, ToolStates};

use crate::bounded_queue::BoundedQueue;
use crate::rate_meter::RateMeter;
use crate::replica::{DeltaOutcome, ReplicaError, SceneReplica};
use crate::viewer_stats::ViewerStats;

/// Rates are refreshed over windows of this length.
const RATE_WINDOW: Duration = Duration::from_secs(1);

/// Replica, wait buffer, flags and counters shared by the callbacks and the sync worker.
#[derive(Debug)]
pub(crate) struct SyncState {
    replica: SceneReplica,
    waiting: BoundedQueue<MeshDelta>,
    needs_snapshot: bool,
    retry_now: bool,
    server_stats: Option<ServerStats>,
    servers: BTreeSet<String>,
    counters: ViewerStats,
    deltas_received: u64,
    fetch_time: LatencyHistogram,
    frames_meter: RateMeter,
    deltas_meter: RateMeter,
    bytes_meter: RateMeter,
}

impl SyncState {
    /// Waiting for the first snapshot, buffering at most `buffer_capacity` deltas meanwhile.
    pub(crate) fn new(buffer_capacity: usize) -> Self {
        Self {
            replica: SceneReplica::new(),
            waiting: BoundedQueue::new(buffer_capacity),
            needs_snapshot: true,
            retry_now: false,
            server_stats: None,
            servers: BTreeSet::new(),
            counters: ViewerStats::default(),
            deltas_received: 0,
            fetch_time: LatencyHistogram::new(),
            frames_meter: RateMeter::new(RATE_WINDOW),
            deltas_meter: RateMeter::new(RATE_WINDOW),
            bytes_meter: RateMeter::new(RATE_WINDOW),
        }
    }

    /// The replica.
    pub(crate) fn replica(&self) -> &SceneReplica {
        &self.replica
    }

    /// The latest server stats, if any arrived.
    pub(crate) fn server_stats(&self) -> Option<&ServerStats> {
        self.server_stats.as_ref()
    }

    /// A snapshot query is due (first join, after a gap, or after a server (re)joined).
    pub(crate) fn needs_snapshot(&self) -> bool {
        self.needs_snapshot
    }

    /// Take the "retry the snapshot query now, skip the backoff" request, if any.
    pub(crate) fn take_retry_now(&mut self) -> bool {
        std::mem::take(&mut self.retry_now)
    }

    /// A mesh delta payload of `payload_len` bytes arrived and decoded to `decoded`. Returns whether the sync
    /// worker must wake (a snapshot became due).
    pub(crate) fn on_delta(
        &mut self,
        payload_len: usize,
        decoded: Result<MeshDelta, DecodeError>,
    ) -> bool {
        self.counters.bytes_received += payload_len as u64;
        self.deltas_received += 1;
        let delta = match decoded {
            Ok(delta) => delta,
            Err(err) => {
                self.counters.decode_errors.record(&err);
                tracing::debug!(%err, "mesh delta refused");
                return false;
            }
        };
        if self.needs_snapshot {
            self.waiting.push(delta);
            return false;
        }
        match self.replica.apply_delta(&delta) {
            Ok(outcome) => {
                self.count_outcome(outcome);
                false
            }
            Err(err) => {
                self.count_refusal(&err);
                if !err.is_protocol_error() {
                    // It may apply right after the snapshot it will be replayed on.
                    self.waiting.push(delta);
                }
                self.needs_snapshot = true;
                true
            }
        }
    }

    /// A tool-state payload arrived (one per server publish frame).
    pub(crate) fn on_tools(
        &mut self,
        payload_len: usize,
        decoded: Result<ToolStates, DecodeError>,
    ) {
        self.counters.bytes_received += payload_len as u64;
        match decoded {
            Ok(tool_states) => {
                self.counters.tool_updates += 1;
                self.replica.apply_tools(tool_states);
            }
            Err(err) => {
                self.counters.decode_errors.record(&err);
                tracing::debug!(%err, "tool states refused");
            }
        }
    }

    /// A server stats payload arrived.
    pub(crate) fn on_server_stats(
        &mut self,
        payload_len: usize,
        decoded: Result<ServerStats, DecodeError>,
    ) {
        self.counters.bytes_received += payload_len as u64;
        match decoded {
            Ok(stats) => {
                self.counters.server_stats_received += 1;
                self.server_stats = Some(stats);
            }
            Err(err) => {
                self.counters.decode_errors.record(&err);
                tracing::debug!(%err, "server stats refused");
            }
        }
    }

    /// A server presence token appeared (`alive`) or vanished. A server that appears after the replica was
    /// built may be a restarted one counting frames from zero, whose deltas would all look stale: re-query.
    /// Returns whether the sync worker must wake.
    pub(crate) fn on_server_presence(&mut self, server_id: &str, alive: bool) -> bool {
        if !alive {
            self.servers.remove(server_id);
            tracing::info!(server_id, "server left");
            return false;
        }
        let new = self.servers.insert(server_id.to_owned());
        if !new {
            return false;
        }
        tracing::info!(server_id, "server present");
        if self.replica.has_snapshot() && !self.needs_snapshot {
            self.needs_snapshot = true;
        }
        self.retry_now = true;
        true
    }

    /// A snapshot query is being sent.
    pub(crate) fn on_snapshot_query(&mut self) {
        self.counters.snapshot_queries += 1;
    }

    /// A snapshot reply payload arrived (counted whether or not it decoded).
    pub(crate) fn on_snapshot_payload(
        &mut self,
        payload_len: usize,
        decoded: &Result<SceneSnapshot, DecodeError>,
    ) {
        self.counters.bytes_received += payload_len as u64;
        if let Err(err) = decoded {
            self.counters.decode_errors.record(err);
        }
    }

    /// A snapshot query ended without a usable snapshot.
    pub(crate) fn on_snapshot_failed(&mut self) {
        self.counters.snapshot_failures += 1;
    }

    /// Install a fetched snapshot and replay the buffered deltas over it. Returns true when the replica is now
    /// in sync; false when the replay revealed a gap or a protocol error (another snapshot is then due).
    pub(crate) fn install_snapshot(
        &mut self,
        snapshot: SceneSnapshot,
        fetch_time: Duration,
    ) -> bool {
        self.replica.apply_snapshot(snapshot);
        self.counters.snapshots_fetched += 1;
        self.fetch_time.record(fetch_time);
        self.counters.snapshot_fetch_last_ms = fetch_time.as_secs_f32() * 1000.0;
        let mut in_sync = true;
        let buffered: Vec<MeshDelta> = self.waiting.drain().collect();
        for delta in &buffered {
            match self.replica.apply_delta(delta) {
                Ok(outcome) => self.count_outcome(outcome),
                Err(err) => {
                    self.count_refusal(&err);
                    in_sync = false;
                }
            }
        }
        self.needs_snapshot = !in_sync;
        in_sync
    }

    /// Refresh the per-second rates. Call at least once per second.
    pub(crate) fn update_rates(&mut self, now: Instant) {
        self.frames_meter.update(now, self.counters.tool_updates);
        self.deltas_meter.update(now, self.deltas_received);
        self.bytes_meter.update(now, self.counters.bytes_received);
    }

    /// Counters, rates and replica position.
    pub(crate) fn stats(&self) -> ViewerStats {
        ViewerStats {
            has_snapshot: self.replica.has_snapshot(),
            server_present: !self.servers.is_empty(),
            snapshot_fetch_last_ms: self.counters.snapshot_fetch_last_ms,
            snapshot_fetch_max_ms: self.fetch_time.max_ns() as f32 / 1.0e6,
            deltas_buffered: self.waiting.len() as u64,
            deltas_dropped: self.waiting.dropped(),
            frames_per_s: self.frames_meter.per_s(),
            deltas_per_s: self.deltas_meter.per_s(),
            bytes_per_s: self.bytes_meter.per_s(),
            replica_frame: self.replica.frame(),
            replica_error_bound_mm: self.replica.max_error_mm_all(),
            ..self.counters
        }
    }

    fn count_outcome(&mut self, outcome: DeltaOutcome) {
        match outcome {
            DeltaOutcome::Applied => self.counters.deltas_applied += 1,
            DeltaOutcome::Stale => self.counters.deltas_stale += 1,
        }
    }

    fn count_refusal(&mut self, err: &ReplicaError) {
        if err.is_protocol_error() {
            self.counters.protocol_errors += 1;
            tracing::warn!(%err, "protocol error in mesh delta; re-querying the snapshot");
        } else {
            self.counters.gaps += 1;
            tracing::info!(%err, "mesh delta gap; re-querying the snapshot");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    // The shared builders, under the short names these tests use.
    use crate::test_fixtures::{triangle_snapshot as snapshot, vertex_delta as delta};

    #[test]
    fn deltas_before_the_snapshot_are_buffered_then_replayed() {
        let mut state = SyncState::new(16);
        assert!(state.needs_snapshot());
        // Published around the snapshot: 9 is folded into it, 11 and 12 follow it.
        for d in [
            delta(8, 9, 0, 9),
            delta(10, 11, 1, 11),
            delta(11, 12, 2, 12),
        ] {
            assert!(!state.on_delta(40, Ok(d)));
        }
        assert_eq!(state.stats().deltas_buffered, 3);
        assert!(state.install_snapshot(snapshot(10, 10), Duration::from_millis(3)));
        assert!(!state.needs_snapshot());
        assert_eq!(state.replica().quantized(0), &[[0; 3], [11; 3], [12; 3]]);
        let stats = state.stats();
        assert_eq!((stats.deltas_applied, stats.deltas_stale), (2, 1));
        assert_eq!(stats.deltas_buffered, 0);
        assert_eq!(stats.bytes_received, 120);
        assert_eq!(stats.replica_frame, 12);
    }

    #[test]
    fn gap_asks_for_a_snapshot_and_buffers_until_it_arrives() {
        let mut state = SyncState::new(16);
        assert!(state.install_snapshot(snapshot(10, 10), Duration::ZERO));
        assert!(!state.on_delta(10, Ok(delta(10, 11, 0, 1))));
        // Frame 12 is lost; 13 reveals the gap.
        assert!(state.on_delta(10, Ok(delta(12, 13, 0, 3))));
        assert!(state.needs_snapshot());
        assert!(!state.on_delta(10, Ok(delta(13, 14, 1, 4))));
        assert_eq!(state.stats().gaps, 1);
        // The server's state at frame 13, then replay: 13 is stale, 14 applies.
        let mut fresh = snapshot(13, 13);
        fresh.objects[0].positions_q[0] = [3; 3];
        assert!(state.install_snapshot(fresh, Duration::ZERO));
        assert_eq!(state.replica().quantized(0), &[[3; 3], [4; 3], [0; 3]]);
        assert_eq!(state.stats().snapshots_fetched, 2);
    }

    #[test]
    fn protocol_error_asks_for_a_snapshot_without_buffering() {
        let mut state = SyncState::new(16);
        assert!(state.install_snapshot(snapshot(10, 10), Duration::ZERO));
        assert!(state.on_delta(10, Ok(delta(10, 11, 7, 1))));
        assert_eq!(state.stats().protocol_errors, 1);
        assert_eq!(state.stats().deltas_buffered, 0);
        assert_eq!(state.replica().quantized(0), &[[0; 3]; 3]);
    }

    #[test]
    fn replay_gap_keeps_the_snapshot_due() {
        let mut state = SyncState::new(16);
        state.on_delta(10, Ok(delta(20, 21, 0, 1)));
        assert!(!state.install_snapshot(snapshot(10, 10), Duration::ZERO));
        assert!(state.needs_snapshot());
        assert!(state.replica().has_snapshot());
    }

    #[test]
    fn decode_errors_are_counted_by_class() {
        let mut state = SyncState::new(4);
        let err = sinew_protocol::decode::<MeshDelta>(&[1]).unwrap_err();
        state.on_delta(1, Err(err));
        let err = sinew_protocol::decode::<ToolStates>(&[9, 9, 5]).unwrap_err();
        state.on_tools(3, Err(err));
        let stats = state.stats();
        assert_eq!(stats.decode_errors.truncated, 1);
        assert_eq!(stats.decode_errors.wrong_version, 1);
        assert_eq!(stats.decode_errors.total(), 2);
        assert_eq!(stats.bytes_received, 4);
    }

    #[test]
    fn a_server_joining_after_sync_triggers_a_resnapshot() {
        let mut state = SyncState::new(4);
        assert!(state.on_server_presence("sim", true));
        assert!(state.take_retry_now());
        assert!(state.install_snapshot(snapshot(10, 10), Duration::ZERO));
        // Same server again (history replay): nothing to do.
        assert!(!state.on_server_presence("sim", true));
        assert!(!state.needs_snapshot());
        state.on_server_presence("sim", false);
        assert!(!state.stats().server_present);
        assert!(state.on_server_presence("sim", true));
        assert!(state.needs_snapshot());
    }

    #[test]
    fn full_buffer_drops_oldest_and_counts_it() {
        let mut state = SyncState::new(2);
        for f in 1..=5 {
            state.on_delta(1, Ok(delta(f - 1, f, 0, f as u16)));
        }
        let stats = state.stats();
        assert_eq!((stats.deltas_buffered, stats.deltas_dropped), (2, 3));
    }
}
