//! The wire tap: what a scene publishes, exactly as published, handed to a recorder. Mesh deltas, tool states,
//! stats (with every device's round trip), hellos and participant presence; poses and force commands too when
//! the recorder is not the server (the server records those exactly in its tick records already).
//!
//! Owns: one zenoh subscriber on `sinew/<scene>/**`, one liveliness subscriber (with history, so participants
//! already present are recorded as joining), and its hand-off to the writer's queue
//! ([`WireSink`], which drops and counts when full). Runs on zenoh's threads, never on the sim thread, so it may allocate.
//!
//! Must not: publish, declare anything but subscribers, or block a zenoh callback.

use std::sync::Arc;

use sinew_protocol::keys::SceneKeys;
use zenoh::Wait;
use zenoh::sample::SampleKind;

use super::queue::{WireItem, WireSink};

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
