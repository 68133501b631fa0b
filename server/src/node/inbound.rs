//! zenoh callbacks: poses, presence tokens, hellos. Each decodes, validates, counts what it refuses, and
//! stores into a device slot. Never blocks for long, never panics on any input.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use sinew_protocol::{DecodeError, DevicePose, ParticipantHello, RejectCounts, Role, decode};
use zenoh::Wait;
use zenoh::sample::{Sample, SampleKind};

use super::Shared;
use super::device_slots::PoseArrival;

/// Refused inbound messages, by reason.
#[derive(Debug, Default)]
pub struct RejectCounters {
    malformed: AtomicU64,
    wrong_version: AtomicU64,
    invalid: AtomicU64,
    unknown_device: AtomicU64,
}

impl RejectCounters {
    fn count(&self, error: &DecodeError) {
        let counter = match error {
            DecodeError::WrongVersion { .. } => &self.wrong_version,
            DecodeError::Invalid { .. } => &self.invalid,
            DecodeError::Truncated { .. }
            | DecodeError::WrongKind { .. }
            | DecodeError::Malformed { .. } => &self.malformed,
        };
        counter.fetch_add(1, Ordering::Relaxed);
    }

    /// Snapshot for the stats message.
    pub fn snapshot(&self) -> RejectCounts {
        RejectCounts {
            malformed: self.malformed.load(Ordering::Relaxed),
            wrong_version: self.wrong_version.load(Ordering::Relaxed),
            invalid: self.invalid.load(Ordering::Relaxed),
            unknown_device: self.unknown_device.load(Ordering::Relaxed),
        }
    }
}

/// The declared subscribers; dropping undeclares them.
pub struct Inbound {
    _poses: zenoh::pubsub::Subscriber<()>,
    _presence: zenoh::pubsub::Subscriber<()>,
    _hellos: zenoh::pubsub::Subscriber<()>,
}

pub(super) fn declare(session: &zenoh::Session, shared: &Arc<Shared>) -> zenoh::Result<Inbound> {
    let s = shared.clone();
    let poses = session
        .declare_subscriber(shared.keys.all_device_poses())
        .callback(move |sample: Sample| on_pose(&s, &sample))
        .wait()?;
    let s = shared.clone();
    let presence = session
        .liveliness()
        .declare_subscriber(shared.keys.all_presence(Role::Haptic))
        .history(true)
        .callback(move |sample: Sample| on_presence(&s, &sample))
        .wait()?;
    let s = shared.clone();
    let hellos = session
        .declare_subscriber(shared.keys.all_hello(Role::Haptic))
        .callback(move |sample: Sample| on_hello(&s, &sample))
        .wait()?;
    Ok(Inbound {
        _poses: poses,
        _presence: presence,
        _hellos: hellos,
    })
}

fn on_pose(shared: &Shared, sample: &Sample) {
    let received = Instant::now();
    let key = sample.key_expr().as_str();
    let slot = shared
        .keys
        .device_id_of(key)
        .and_then(|id| shared.slots.find(id))
        .filter(|slot| !slot.refused.load(Ordering::Acquire));
    let Some(slot) = slot else {
        shared
            .rejects
            .unknown_device
            .fetch_add(1, Ordering::Relaxed);
        return;
    };
    let bytes = sample.payload().to_bytes();
    match decode::<DevicePose>(&bytes) {
        Ok(pose) => {
            slot.pose.store(PoseArrival { pose, received });
            slot.poses_received.fetch_add(1, Ordering::Relaxed);
        }
        Err(error) => shared.rejects.count(&error),
    }
}

fn on_presence(shared: &Shared, sample: &Sample) {
    let key = sample.key_expr().as_str();
    let Some(slot) = shared
        .keys
        .presence_id_of(Role::Haptic, key)
        .and_then(|id| shared.slots.find(id))
    else {
        return;
    };
    let gone = sample.kind() == SampleKind::Delete;
    slot.gone.store(gone, Ordering::Release);
    if gone {
        tracing::info!(device = %slot.device_id, tool = %slot.tool_name, "device left: tool released");
    } else {
        tracing::info!(device = %slot.device_id, tool = %slot.tool_name, "device present");
    }
}

fn on_hello(shared: &Shared, sample: &Sample) {
    let bytes = sample.payload().to_bytes();
    let hello = match decode::<ParticipantHello>(&bytes) {
        Ok(hello) => hello,
        Err(error) => {
            shared.rejects.count(&error);
            return;
        }
    };
    let Some(slot) = shared.slots.find(&hello.participant_id) else {
        tracing::warn!(device = %hello.participant_id, "hello from a device no tool in this world is bound to");
        return;
    };
    slot.hello_max_force_bits
        .store(hello.max_force_n.to_bits(), Ordering::Release);
    let refused = !hello.tool.is_empty() && hello.tool != slot.tool_name;
    if refused && !slot.refused.swap(true, Ordering::AcqRel) {
        tracing::error!(
            device = %slot.device_id,
            asked = %hello.tool,
            bound = %slot.tool_name,
            "device asked for a tool the world does not bind it to: its poses are ignored"
        );
    } else if !refused {
        slot.refused.store(false, Ordering::Release);
    }
}
