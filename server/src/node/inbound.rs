//! zenoh callbacks: poses, presence tokens, hellos. Each decodes, validates, counts what it refuses, and
//! stores into a device slot. Never blocks for long, never panics on any input.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use sinew_protocol::rt::Throttle;
use sinew_protocol::{
    DecodeError, DevicePose, InstanceId, ParticipantHello, RejectCounts, Role, ServerStats,
    decode_from,
};
use zenoh::Wait;
use zenoh::sample::{Sample, SampleKind};

use super::Shared;
use super::device_slots::{Claim, PoseArrival};

/// The shortest claim timeout: a holder silent this long lets another instance take its device id, s.
pub const MIN_CLAIM_TIMEOUT_S: f64 = 0.5;

/// Refused inbound messages, by reason.
#[derive(Debug, Default)]
pub struct RejectCounters {
    malformed: AtomicU64,
    wrong_version: AtomicU64,
    invalid: AtomicU64,
    unknown_device: AtomicU64,
    duplicate_device: AtomicU64,
    wrong_tool: AtomicU64,
    no_hello: AtomicU64,
    /// The process's access-control refusals when this server started (the count is process-wide).
    access_denied_base: u64,
    /// The process's refused TLS accepts when this server started.
    tls_refused_base: u64,
}

impl RejectCounters {
    /// Counters from zero, access refusals counted from now.
    pub fn new() -> Self {
        Self {
            access_denied_base: super::access_refusals::refusals(),
            tls_refused_base: super::access_refusals::tls_refusals(),
            ..Self::default()
        }
    }

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
            duplicate_device: self.duplicate_device.load(Ordering::Relaxed),
            wrong_tool: self.wrong_tool.load(Ordering::Relaxed),
            no_hello: self.no_hello.load(Ordering::Relaxed),
            access_denied: super::access_refusals::refusals()
                .saturating_sub(self.access_denied_base),
            tls_refused: super::access_refusals::tls_refusals()
                .saturating_sub(self.tls_refused_base),
        }
    }
}

/// Other servers heard publishing stats for this scene: two servers are live (one started while another was
/// unreachable, or two partitioned servers met again). Clients stay with the server they joined; this server
/// counts and says so, at most every 10 s.
#[derive(Debug)]
pub struct ForeignServers {
    own: InstanceId,
    count: AtomicU64,
    last: AtomicU64,
    log: Throttle,
    epoch: Instant,
}

impl ForeignServers {
    /// For the server `own`.
    pub fn new(own: InstanceId) -> Self {
        Self {
            own,
            count: AtomicU64::new(0),
            last: AtomicU64::new(0),
            log: Throttle::new(10_000_000_000),
            epoch: Instant::now(),
        }
    }

    /// Stats messages heard from other servers.
    pub fn foreign(&self) -> u64 {
        self.count.load(Ordering::Relaxed)
    }

    /// The latest other server heard.
    pub fn last_foreign(&self) -> InstanceId {
        InstanceId(self.last.load(Ordering::Relaxed))
    }
}

/// The declared subscribers; dropping undeclares them.
pub struct Inbound {
    _poses: zenoh::pubsub::Subscriber<()>,
    _presence: zenoh::pubsub::Subscriber<()>,
    _hellos: zenoh::pubsub::Subscriber<()>,
    _stats: zenoh::pubsub::Subscriber<()>,
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
    let s = shared.clone();
    let stats = session
        .declare_subscriber(shared.keys.stats())
        .callback(move |sample: Sample| on_stats(&s, &sample))
        .wait()?;
    Ok(Inbound {
        _poses: poses,
        _presence: presence,
        _hellos: hellos,
        _stats: stats,
    })
}

fn on_pose(shared: &Shared, sample: &Sample) {
    let received = Instant::now();
    let key = sample.key_expr().as_str();
    let slot = shared
        .keys
        .device_id_of(key)
        .and_then(|id| shared.slots.find(id));
    let Some(slot) = slot else {
        shared
            .rejects
            .unknown_device
            .fetch_add(1, Ordering::Relaxed);
        return;
    };
    let bytes = sample.payload().to_bytes();
    let (from, pose) = match decode_from::<DevicePose>(&bytes) {
        Ok(decoded) => decoded,
        Err(error) => {
            shared.rejects.count(&error);
            return;
        }
    };
    let now_ns = shared.slots.now_ns();
    let timeout_ns = (shared.world.pose_timeout_s * 2.0).max(MIN_CLAIM_TIMEOUT_S) * 1e9;
    match slot.claim(from, now_ns, timeout_ns as u64) {
        Claim::Held => {}
        Claim::Taken { previous } if previous.is_none() => {
            tracing::info!(device = %slot.device_id, tool = %slot.tool_name, instance = %from, "device id held");
        }
        Claim::Taken { previous } => {
            tracing::info!(
                device = %slot.device_id,
                instance = %from,
                %previous,
                "device id taken over: the instance that held it had gone quiet"
            );
        }
        Claim::Duplicate { holder, first } => {
            shared
                .rejects
                .duplicate_device
                .fetch_add(1, Ordering::Relaxed);
            if first {
                slot.duplicate_log.reset();
            }
            if let Some(count) = slot.duplicate_log.hit(now_ns) {
                tracing::error!(
                    device = %slot.device_id,
                    holder = %holder,
                    refused = %from,
                    poses_refused = count,
                    "a second hapticserver uses device id `{}`, which another holds: refused, its poses are ignored",
                    slot.device_id
                );
            }
            return;
        }
        Claim::Refused => {
            shared.rejects.wrong_tool.fetch_add(1, Ordering::Relaxed);
            return;
        }
        Claim::Unannounced => {
            shared.rejects.no_hello.fetch_add(1, Ordering::Relaxed);
            return;
        }
    }
    slot.pose.store(PoseArrival {
        pose,
        received,
        from,
    });
    slot.poses_received.fetch_add(1, Ordering::Relaxed);
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
    if sample.kind() == SampleKind::Delete {
        let holder = slot.release();
        tracing::info!(device = %slot.device_id, tool = %slot.tool_name, instance = %holder, "device left: tool released");
    } else {
        slot.present();
        tracing::info!(device = %slot.device_id, tool = %slot.tool_name, "device present");
    }
}

fn on_hello(shared: &Shared, sample: &Sample) {
    let bytes = sample.payload().to_bytes();
    let (from, hello) = match decode_from::<ParticipantHello>(&bytes) {
        Ok(decoded) => decoded,
        Err(error) => {
            shared.rejects.count(&error);
            return;
        }
    };
    let Some(slot) = shared.slots.find(&hello.participant_id) else {
        if let Some(count) = shared.unknown_hello_log.hit(shared.slots.now_ns()) {
            tracing::warn!(
                device = %hello.participant_id,
                hellos = count,
                bound = %shared.slots.iter().map(|s| s.device_id.as_str()).collect::<Vec<_>>().join(", "),
                "hello from a device id no tool in this world is bound to (repeated at most every 10 s)"
            );
        }
        return;
    };
    let holder = slot.holder();
    if holder.is_none() || holder == from {
        slot.hello_max_force_bits
            .store(hello.max_force_n.to_bits(), Ordering::Release);
    }
    let refused = !hello.tool.is_empty() && hello.tool != slot.tool_name;
    if refused {
        if slot.wrong_tool_instance.swap(from.0, Ordering::AcqRel) != from.0 {
            if let Ok(mut asked) = slot.wrong_tool_asked.lock() {
                asked.clone_from(&hello.tool);
            }
            tracing::error!(
                device = %slot.device_id,
                instance = %from,
                asked = %hello.tool,
                bound = %slot.tool_name,
                "device asked for a tool the world does not bind it to: its poses are ignored"
            );
        }
    } else {
        slot.greet(from);
        let _ = slot.wrong_tool_instance.compare_exchange(
            from.0,
            0,
            Ordering::AcqRel,
            Ordering::Acquire,
        );
    }
}

fn on_stats(shared: &Shared, sample: &Sample) {
    let foreign = &shared.foreign_servers;
    let Ok((from, stats)) = decode_from::<ServerStats>(&sample.payload().to_bytes()) else {
        return;
    };
    if from == foreign.own {
        return;
    }
    foreign.count.fetch_add(1, Ordering::Relaxed);
    foreign.last.store(from.0, Ordering::Relaxed);
    if let Some(count) = foreign.log.hit(foreign.epoch.elapsed().as_nanos() as u64) {
        tracing::error!(
            scene = %shared.world.scene,
            other_server = %stats.server_id,
            other_instance = %from,
            this_instance = %foreign.own,
            messages = count,
            "another server is live for this scene: each client stays with the server it joined; stop one of them"
        );
    }
}
