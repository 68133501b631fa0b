//! A running hapticserver: zenoh declarations, the paced device-loop thread, the hello thread, and the handle.
//!
//! Owns: [`HapticServer::start`], which opens the zenoh session, declares the presence token, the pose
//! publisher (congestion drop, express), the force subscriber (its callback feeds a
//! [`crate::force_inbox::ForceInbox`]) and the hello publisher, then spawns the named device-loop thread
//! (`hapticserver-<id>`, paced by [`Pacer`], the body in `device_loop`) and a hello thread (1 Hz, the body in
//! `supervision`); and [`HapticHandle`] (in `handle`), which reports, stops (ramping the force to zero,
//! undeclaring everything) or kills the server.
//!
//! Must not: do any per-tick work itself (that is [`crate::haptic_loop`]), use a tokio timer for the loop, or
//! let the loop wait on a lock (reports are published with `try_lock`).
//!
//! [`Pacer`]: sinew_protocol::rt::Pacer

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::keys::SceneKeys;
use sinew_protocol::rt::DelayedSender;
use sinew_protocol::{InstanceId, ParticipantHello, Role, ServerStats, decode_from};
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Reliability};

use crate::calibration::CalibratedDevice;
use crate::clock::MonotonicClock;
use crate::error::HapticError;
use crate::force_inbox::ForceInbox;
use crate::haptic_config::HapticConfig;
use crate::haptic_loop::HapticLoop;
use crate::report::HapticReport;
use crate::safety::{ForceSafety, SafetyConfig};
use crate::server_watch::ServerWatch;
use crate::trace::Trace;
use crate::zenoh_session::{UDP_LINK_WAIT, open_session, wait_for_udp_link, wants_udp_link};

mod device_loop;
mod handle;
mod supervision;

use device_loop::{DeviceLoop, PoseOutlet};
pub use handle::HapticHandle;
use supervision::Supervision;

/// How often the hello is repeated.
pub const HELLO_PERIOD: Duration = Duration::from_secs(1);
/// How long [`HapticHandle::stop`] waits for zenoh's goodbyes once the force is at zero.
pub const CLOSE_TIMEOUT: Duration = Duration::from_millis(500);
/// How often the loop publishes its report.
pub const REPORT_PERIOD: Duration = Duration::from_millis(100);

fn lock_report(report: &Mutex<HapticReport>) -> MutexGuard<'_, HapticReport> {
    match report.lock() {
        Ok(guard) => guard,
        Err(poisoned) => poisoned.into_inner(),
    }
}

/// Starts hapticservers.
#[derive(Debug)]
pub struct HapticServer;

impl HapticServer {
    /// Open zenoh, declare presence, pose, force and hello, and start the device loop. Returns once the loop
    /// thread runs; every declaration is undone when the handle stops or drops.
    pub fn start(config: HapticConfig) -> Result<HapticHandle, HapticError> {
        let HapticConfig {
            scene,
            device_id,
            tool,
            network,
            device,
            mount,
            loop_rate_hz,
            spin_accuracy_ns,
            realtime,
            safety,
            passivity,
            mode,
            phase_align,
            phase_target_us,
            emulation,
            trace_ticks,
            panic_at_tick,
        } = config;
        emulation
            .validate()
            .map_err(|reason| HapticError::Emulation { reason })?;
        if !(1..=20_000).contains(&loop_rate_hz) {
            return Err(HapticError::LoopRate {
                rate_hz: loop_rate_hz,
            });
        }
        let period_us = 1e6 / loop_rate_hz as f32;
        if !(0.0..period_us).contains(&phase_target_us) {
            return Err(HapticError::PhaseTarget {
                target_us: phase_target_us,
                period_us,
            });
        }
        let keys = SceneKeys::new(&scene)?;
        let pose_key = keys.device_pose(&device_id)?;
        let force_key = keys.device_force(&device_id)?;
        let presence_key = keys.presence(Role::Haptic, &device_id)?;
        let hello_key = keys.hello(Role::Haptic, &device_id)?;

        // Everything from here on sees the device in the wire frame.
        let device = CalibratedDevice::wrap(device, mount);
        let model = device.model();
        let safety_config = match safety {
            Some(config) => config.limited_to(&model),
            None => SafetyConfig::for_device(&model),
        };
        let safety = ForceSafety::new(safety_config)?;
        let instance = InstanceId::random();
        let hello_bytes = encode_to_vec(
            instance,
            &ParticipantHello {
                participant_id: device_id.clone(),
                role: Role::Haptic,
                device_model: model.name.clone(),
                max_force_n: safety_config.max_force_n,
                tool,
            },
        );

        let session = open_session(&network)?;
        let token = session
            .liveliness()
            .declare_token(presence_key.clone())
            .wait()
            .map_err(HapticError::zenoh(format!(
                "declaring the presence token {presence_key}"
            )))?;
        let pose_publisher = session
            .declare_publisher(pose_key.clone())
            .congestion_control(CongestionControl::Drop)
            .reliability(Reliability::BestEffort)
            .express(true)
            .wait()
            .map_err(HapticError::zenoh(format!(
                "declaring the pose publisher on {pose_key}"
            )))?;
        // Dropped rather than blocked when the link is congested or cut: it repeats every second, and a
        // blocked put must never hold the watch thread (or a shutdown) during a partition.
        let hello_publisher = session
            .declare_publisher(hello_key.clone())
            .congestion_control(CongestionControl::Drop)
            .wait()
            .map_err(HapticError::zenoh(format!(
                "declaring the hello publisher on {hello_key}"
            )))?;

        let clock = MonotonicClock::start();
        let inbox = Arc::new(ForceInbox::new(instance));
        let callback_inbox = inbox.clone();
        let subscriber = session
            .declare_subscriber(force_key.clone())
            .callback(move |sample: zenoh::sample::Sample| {
                let received_ns = clock.now_ns();
                let payload = sample.payload().to_bytes();
                // A refused payload is counted by class in the inbox; nothing else to do with it here.
                let _ = callback_inbox.accept(&payload, received_ns);
            })
            .wait()
            .map_err(HapticError::zenoh(format!(
                "declaring the force subscriber on {force_key}"
            )))?;

        // The joined server's latest stats, for the supervision thread's watch.
        let latest_stats: Arc<Mutex<Option<ServerStats>>> = Arc::new(Mutex::new(None));
        let stats_inbox = inbox.clone();
        let stats_slot = latest_stats.clone();
        let stats_subscriber = session
            .declare_subscriber(keys.stats())
            .callback(move |sample: zenoh::sample::Sample| {
                let Ok((from, stats)) = decode_from::<ServerStats>(&sample.payload().to_bytes())
                else {
                    return;
                };
                if stats_inbox.server().admit(from, clock.now_ns()).admitted()
                    && let Ok(mut slot) = stats_slot.lock()
                {
                    *slot = Some(stats);
                }
            })
            .wait()
            .map_err(HapticError::zenoh("declaring the stats subscriber"))?;
        // A server whose presence token goes away has left: the next server heard is followed at once. A
        // server that appears (a restart, a healed partition) gets this device's hello within a watch period:
        // it lets no instance drive a tool before its hello.
        let hello_now = Arc::new(AtomicBool::new(false));
        let presence_hello = hello_now.clone();
        let presence_inbox = inbox.clone();
        let server_presence = session
            .liveliness()
            .declare_subscriber(keys.all_presence(Role::Server))
            .callback(move |sample: zenoh::sample::Sample| {
                if sample.kind() == zenoh::sample::SampleKind::Delete {
                    presence_inbox.server().release();
                } else {
                    presence_hello.store(true, Ordering::Release);
                }
            })
            .wait()
            .map_err(HapticError::zenoh(
                "declaring the server presence subscriber",
            ))?;

        // Multilink: start the loop once poses and forces can take UDP (or after UDP_LINK_WAIT, on TCP alone).
        let udp_link_wait = wants_udp_link(&network).then(|| {
            let waited = wait_for_udp_link(&session, UDP_LINK_WAIT);
            match waited {
                Some(d) => tracing::info!(device = %device_id, waited_ms = d.as_millis(), "UDP link up"),
                None => tracing::warn!(
                    device = %device_id,
                    "no UDP link to the server after {} s: poses and forces ride TCP (head-of-line blocking under loss)",
                    UDP_LINK_WAIT.as_secs()
                ),
            }
            waited
        });
        let mut report = HapticReport::new(&device_id);
        report.instance = instance;
        report.udp_link_wait_ms = udp_link_wait.map(|waited| waited.map(|d| d.as_secs_f32() * 1e3));

        let period = Duration::from_nanos(1_000_000_000 / u64::from(loop_rate_hz));
        let mut handle = HapticHandle {
            device_id: device_id.clone(),
            pose_key,
            force_key,
            session: Some(session),
            token: Some(token),
            subscriber: Some(subscriber),
            watch_subscribers: vec![stats_subscriber, server_presence],
            loop_thread: None,
            hello_thread: None,
            stop: Arc::new(AtomicBool::new(false)),
            abrupt: Arc::new(AtomicBool::new(false)),
            report: Arc::new(Mutex::new(report)),
            inbox: inbox.clone(),
            trace: Arc::new(Mutex::new(Trace::default())),
            clock,
        };

        let mut haptic = HapticLoop::new(device, safety, inbox.clone(), period);
        haptic.set_passivity_mode(passivity);
        haptic.set_mode_policy(mode);
        haptic.set_phase_align(phase_align, phase_target_us);
        haptic.record_trace(trace_ticks);
        let outlet = if emulation.is_off() {
            PoseOutlet::Direct(pose_publisher)
        } else {
            PoseOutlet::Delayed(
                DelayedSender::start(
                    &format!("hapticserver-{device_id}-delay"),
                    emulation,
                    move |bytes: &[u8]| {
                        let _ = pose_publisher.put(bytes).wait();
                    },
                )
                .map_err(|source| HapticError::Thread {
                    name: format!("hapticserver-{device_id}-delay"),
                    source,
                })?,
            )
        };
        let device_loop = DeviceLoop {
            haptic,
            outlet,
            trace: handle.trace.clone(),
            clock,
            period,
            spin_accuracy_ns,
            realtime,
            report_every_ticks: (REPORT_PERIOD.as_nanos() / period.as_nanos().max(1)).max(1) as u64,
            wind_down_ticks: (safety_config.ramp_to_zero_s / period.as_secs_f64()).ceil() as u64
                + 2,
            report: handle.report.clone(),
            stop: handle.stop.clone(),
            abrupt: handle.abrupt.clone(),
            panic_at_tick,
        };
        // The hello goes out before the first pose: the server lets no instance drive a tool before its hello.
        let hello_name = format!("hapticserver-{device_id}-watch");
        let supervision = Supervision {
            hello_publisher,
            hello_bytes,
            hello_now,
            stop: handle.stop.clone(),
            watch: ServerWatch::new(&device_id, instance),
            inbox,
            latest_stats,
            report: handle.report.clone(),
            clock,
        };
        handle.hello_thread = Some(
            std::thread::Builder::new()
                .name(hello_name.clone())
                .spawn(move || supervision.run())
                .map_err(|source| HapticError::Thread {
                    name: hello_name,
                    source,
                })?,
        );
        let loop_name = format!("hapticserver-{device_id}");
        handle.loop_thread = Some(
            std::thread::Builder::new()
                .name(loop_name.clone())
                .spawn(move || device_loop.run())
                .map_err(|source| HapticError::Thread {
                    name: loop_name,
                    source,
                })?,
        );
        tracing::info!(
            device = %device_id,
            model = %model.name,
            max_force_n = safety_config.max_force_n,
            rate_hz = loop_rate_hz,
            pose = %handle.pose_key,
            force = %handle.force_key,
            "hapticserver started"
        );
        Ok(handle)
    }
}
