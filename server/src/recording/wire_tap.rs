//! The wire tap: what a scene publishes, exactly as published, handed to a recorder. Mesh deltas, tool states,
//! stats (with every device's round trip), hellos and participant presence; poses and force commands too when
//! the recorder is not the server (the server records those exactly in its tick records already).
//!
//! Owns: one zenoh subscriber on `sinew/<scene>/**`, one liveliness subscriber (with history, so participants
//! already present are recorded as joining), and the bounded hand-off to the writer ([`WireSink`]), which drops
//! and counts when full. Runs on zenoh's threads, never on the sim thread, so it may allocate.
//!
//! Must not: publish, declare anything but subscribers, or block a zenoh callback.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::SyncSender;

use sinew_protocol::keys::SceneKeys;
use zenoh::Wait;
use zenoh::sample::SampleKind;

use super::writer::Item;

/// Wire items in the writer's queue at most; more are dropped and counted.
pub const WIRE_QUEUE: usize = 512;

/// One thing heard on the wire.
#[derive(Debug, Clone, PartialEq)]
pub enum WireItem {
    /// A message, as published (envelope and postcard body), on its key.
    Sample {
        /// The zenoh key it was published on.
        key: String,
        /// When it was heard, on the recording's clock, ns.
        log_time_ns: u64,
        /// The bytes.
        payload: Vec<u8>,
    },
    /// A participant's presence token appeared or went away.
    Presence {
        /// The token's key (`sinew/<scene>/presence/<role>/<id>`).
        key: String,
        /// Appeared (true) or went away.
        joined: bool,
        /// When, on the recording's clock, ns.
        log_time_ns: u64,
    },
}

/// The tap's end of the recorder's queue: never blocks; drops and counts past [`WIRE_QUEUE`] items in flight.
#[derive(Debug, Clone)]
pub struct WireSink {
    queue: SyncSender<Item>,
    in_flight: Arc<AtomicUsize>,
    dropped: Arc<AtomicU64>,
}

impl WireSink {
    pub(super) fn new(queue: SyncSender<Item>, in_flight: Arc<AtomicUsize>) -> Self {
        Self {
            queue,
            in_flight,
            dropped: Arc::new(AtomicU64::new(0)),
        }
    }

    /// Hand an item over, or count it as dropped.
    pub fn offer(&self, item: WireItem) {
        if self.in_flight.fetch_add(1, Ordering::AcqRel) >= WIRE_QUEUE {
            self.in_flight.fetch_sub(1, Ordering::AcqRel);
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self.queue.try_send(Item::Wire(item)).is_err() {
            self.in_flight.fetch_sub(1, Ordering::AcqRel);
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Items dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// Which of the scene's messages a tap keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TapScope {
    /// Device poses and force commands too (false in the server: its tick records hold them exactly).
    pub poses_and_forces: bool,
}

/// A running tap. Dropping it undeclares its subscribers (after which it hands nothing more over).
pub struct WireTap {
    samples: Option<zenoh::pubsub::Subscriber<()>>,
    presence: Option<zenoh::pubsub::Subscriber<()>>,
    sink: WireSink,
}

impl std::fmt::Debug for WireTap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WireTap")
            .field("dropped", &self.sink.dropped())
            .finish()
    }
}

impl WireTap {
    /// Start tapping `keys`' scene on `session`; `clock` gives the recording's time, ns.
    pub fn start(
        session: &zenoh::Session,
        keys: &SceneKeys,
        scope: TapScope,
        clock: Arc<dyn Fn() -> u64 + Send + Sync>,
        sink: WireSink,
    ) -> zenoh::Result<Self> {
        let presence_prefix = keys.every_presence();
        let presence_prefix = presence_prefix.trim_end_matches("**").to_owned();
        let (to_samples, time_samples) = (sink.clone(), clock.clone());
        let samples = session
            .declare_subscriber(keys.everything())
            .callback(move |sample| {
                let key = sample.key_expr().as_str();
                let device_stream = key.ends_with("/pose") || key.ends_with("/force");
                if (device_stream && !scope.poses_and_forces) || key.starts_with(&presence_prefix) {
                    return;
                }
                to_samples.offer(WireItem::Sample {
                    key: key.to_owned(),
                    log_time_ns: time_samples(),
                    payload: sample.payload().to_bytes().into_owned(),
                });
            })
            .wait()?;
        let to_presence = sink.clone();
        let presence = session
            .liveliness()
            .declare_subscriber(keys.every_presence())
            .history(true)
            .callback(move |sample| {
                to_presence.offer(WireItem::Presence {
                    key: sample.key_expr().as_str().to_owned(),
                    joined: sample.kind() == SampleKind::Put,
                    log_time_ns: clock(),
                });
            })
            .wait()?;
        Ok(Self {
            samples: Some(samples),
            presence: Some(presence),
            sink,
        })
    }

    /// Items dropped because the writer fell behind.
    pub fn dropped(&self) -> u64 {
        self.sink.dropped()
    }

    /// Stop tapping (undeclare both subscribers); returns the items dropped.
    pub fn stop(mut self) -> u64 {
        if let Some(s) = self.samples.take() {
            let _ = s.undeclare().wait();
        }
        if let Some(s) = self.presence.take() {
            let _ = s.undeclare().wait();
        }
        self.sink.dropped()
    }
}
