//! A running hapticserver: zenoh declarations, the paced device-loop thread, the hello thread, and the handle.
//!
//! Owns: [`HapticServer::start`], which opens the zenoh session, declares the presence token, the pose
//! publisher (congestion drop, express), the force subscriber (its callback feeds a
//! [`crate::force_inbox::ForceInbox`]) and the hello publisher, then spawns the named device-loop thread
//! (`hapticserver-<id>`, paced by [`Pacer`]) and a hello thread (1 Hz); and [`HapticHandle`], which reports,
//! stops (ramping the force to zero, undeclaring everything) or kills the server.
//!
//! Must not: do any per-tick work itself (that is [`crate::haptic_loop`]), use a tokio timer for the loop, or
//! let the loop wait on a lock (reports are published with `try_lock`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::keys::SceneKeys;
use sinew_protocol::rt::realtime::{self, RealtimeRequest};
use sinew_protocol::rt::{DelayedSender, Pacer};
use sinew_protocol::{InstanceId, ParticipantHello, Role, ServerStats, decode_from};
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Reliability};

use crate::calibration::CalibratedDevice;
use crate::clock::MonotonicClock;
use crate::error::HapticError;
use crate::force_inbox::ForceInbox;
use crate::haptic_config::HapticConfig;
use crate::haptic_loop::HapticLoop;
use crate::report::HapticReport;
use crate::safety::{ForceSafety, SafetyConfig};
use crate::server_watch::{Say, ServerWatch, WATCH_PERIOD};
use crate::trace::Trace;
use crate::zenoh_session::{UDP_LINK_WAIT, open_session, wait_for_udp_link, wants_udp_link};

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

/// Where poses go: straight to zenoh, or through the emulated network first.
enum PoseOutlet {
    Direct(Publisher<'static>),
    Delayed(DelayedSender),
}

impl PoseOutlet {
    fn send(&mut self, bytes: &[u8]) -> bool {
        match self {
            PoseOutlet::Direct(publisher) => publisher.put(bytes).wait().is_ok(),
            PoseOutlet::Delayed(sender) => {
                sender.send(bytes);
                true
            }
        }
    }
}

/// Everything the device-loop thread owns.
struct DeviceLoop {
    haptic: HapticLoop,
    outlet: PoseOutlet,
    trace: Arc<Mutex<Trace>>,
    clock: MonotonicClock,
    period: Duration,
    spin_accuracy_ns: u32,
    realtime: bool,
    report_every_ticks: u64,
    wind_down_ticks: u64,
    report: Arc<Mutex<HapticReport>>,
    stop: Arc<AtomicBool>,
    abrupt: Arc<AtomicBool>,
    panic_at_tick: Option<u64>,
}

impl DeviceLoop {
    /// The thread body: paced ticks until stopped, then a ramp to zero (unless killed) and a final zero force.
    ///
    /// A panic in a tick is caught here: the motor's last force is ramped to zero over the safety ramp time,
    /// written straight to the device (nothing else of the loop runs again), the failure goes into the report
    /// (`loop_failure`), and the thread ends; the process must then exit non-zero.
    fn run(mut self) {
        lock_report(&self.report).running = true;
        let grant = realtime::configure_this_thread(if self.realtime {
            RealtimeRequest::Fifo {
                priority: realtime::DEVICE_LOOP_PRIORITY,
            }
        } else {
            RealtimeRequest::Normal
        });
        let mut pacer = Pacer::new(self.period, grant.spin_window_ns(self.spin_accuracy_ns));
        lock_report(&self.report).realtime = Some(grant);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            self.tick_until_stopped(&mut pacer);
        }));
        if let Err(payload) = outcome {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".to_owned());
            self.haptic.ramp_out(self.wind_down_ticks, || {
                pacer.wait();
            });
            if let Ok(mut trace) = self.trace.lock() {
                *trace = self.haptic.take_trace();
            }
            let mut report = lock_report(&self.report);
            self.haptic.write_report(&mut report);
            report.loop_failure = Some(format!(
                "the device loop panicked: {message} (force ramped to zero over {} ticks)",
                self.wind_down_ticks
            ));
            report.running = false;
            return;
        }
        let outlet = &mut self.outlet;
        let mut publish = |bytes: &[u8]| outlet.send(bytes);
        if !self.abrupt.load(Ordering::Acquire) {
            self.haptic.begin_shutdown();
            for _ in 0..self.wind_down_ticks {
                if self.haptic.rendered_force_n() == [0.0; 3] {
                    break;
                }
                let interval = pacer.wait();
                self.haptic
                    .tick(self.clock.now_ns(), interval, &mut publish);
            }
        }
        self.haptic.write_zero_force();
        if let Ok(mut trace) = self.trace.lock() {
            *trace = self.haptic.take_trace();
        }
        let mut report = lock_report(&self.report);
        self.haptic.write_report(&mut report);
        report.running = false;
    }
}

impl DeviceLoop {
    fn tick_until_stopped(&mut self, pacer: &mut Pacer) {
        let outlet = &mut self.outlet;
        let mut publish = |bytes: &[u8]| outlet.send(bytes);
        while !self.stop.load(Ordering::Acquire) {
            let interval = pacer.wait();
            self.haptic.set_overruns(pacer.overruns());
            assert!(
                self.panic_at_tick != Some(self.haptic.ticks()),
                "fault drill: panic at tick {} (--fault-panic-at-tick)",
                self.haptic.ticks()
            );
            self.haptic
                .tick(self.clock.now_ns(), interval, &mut publish);
            pacer.shift_ns(self.haptic.take_phase_shift_ns());
            if self.haptic.ticks().is_multiple_of(self.report_every_ticks) {
                self.haptic.try_publish_report(&self.report);
            }
        }
    }
}

/// The supervision thread: the hello every [`HELLO_PERIOD`], and the server watch every [`WATCH_PERIOD`]
/// (its log lines and the report's link and standing).
struct Supervision {
    hello_publisher: Publisher<'static>,
    hello_bytes: Vec<u8>,
    hello_now: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    watch: ServerWatch,
    inbox: Arc<ForceInbox>,
    latest_stats: Arc<Mutex<Option<ServerStats>>>,
    report: Arc<Mutex<HapticReport>>,
    clock: MonotonicClock,
}

impl Supervision {
    /// Until stopped (woken by `unpark`).
    fn run(mut self) {
        let mut next_hello = Instant::now();
        while !self.stop.load(Ordering::Acquire) {
            let now = Instant::now();
            if now >= next_hello || self.hello_now.swap(false, Ordering::AcqRel) {
                if let Err(err) = self.hello_publisher.put(self.hello_bytes.as_slice()).wait() {
                    tracing::debug!(%err, "hello not published");
                }
                next_hello = now + HELLO_PERIOD;
            }
            let stats = self.latest_stats.lock().ok().and_then(|mut s| s.take());
            for say in self
                .watch
                .step(self.clock.now_ns(), self.inbox.server(), stats.as_ref())
            {
                match say {
                    Say::Info(line) => tracing::info!("{line}"),
                    Say::Warn(line) => tracing::warn!("{line}"),
                    Say::Error(line) => tracing::error!("{line}"),
                }
            }
            {
                let mut report = lock_report(&self.report);
                report.server_link = self.watch.link();
                if report.standing != *self.watch.standing() {
                    report.standing = self.watch.standing().clone();
                }
            }
            std::thread::park_timeout(WATCH_PERIOD);
        }
    }
}

/// A running hapticserver. Dropping it stops it (see [`HapticHandle::stop`]).
pub struct HapticHandle {
    device_id: String,
    pose_key: String,
    force_key: String,
    session: Option<zenoh::Session>,
    token: Option<LivelinessToken>,
    subscriber: Option<Subscriber<()>>,
    watch_subscribers: Vec<Subscriber<()>>,
    loop_thread: Option<JoinHandle<()>>,
    hello_thread: Option<JoinHandle<()>>,
    stop: Arc<AtomicBool>,
    abrupt: Arc<AtomicBool>,
    report: Arc<Mutex<HapticReport>>,
    inbox: Arc<ForceInbox>,
    trace: Arc<Mutex<Trace>>,
    clock: MonotonicClock,
}

impl std::fmt::Debug for HapticHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HapticHandle")
            .field("device_id", &self.device_id)
            .field("pose_key", &self.pose_key)
            .field("force_key", &self.force_key)
            .field("running", &self.is_running())
            .finish_non_exhaustive()
    }
}

impl HapticHandle {
    /// The device id served.
    pub fn device_id(&self) -> &str {
        &self.device_id
    }

    /// The key poses are published on.
    pub fn pose_key(&self) -> &str {
        &self.pose_key
    }

    /// The key force commands are read from.
    pub fn force_key(&self) -> &str {
        &self.force_key
    }

    /// Now on the loop's clock, s: the time base of the trace's `t_s` and of the silence rule (so a test can
    /// say when, on that clock, something happened outside the loop).
    pub fn clock_s(&self) -> f64 {
        crate::clock::ns_to_s(self.clock.now_ns())
    }

    /// Whether the device loop thread is still running.
    pub fn is_running(&self) -> bool {
        self.loop_thread
            .as_ref()
            .is_some_and(|thread| !thread.is_finished())
    }

    /// The latest report (published by the loop about every 100 ms; final after stop), with the inbox
    /// counters read now.
    pub fn report(&self) -> HapticReport {
        let mut report = lock_report(&self.report).clone();
        report.forces_received = self.inbox.received();
        report.decode_rejects = self.inbox.rejects();
        report.forces_from_other_server = self.inbox.server().foreign();
        report.forces_for_other_instance = self.inbox.for_other_instance();
        report
    }

    /// The trace the loop recorded (`HapticConfig::trace_ticks`), available once the loop has stopped
    /// (empty before).
    pub fn take_trace(&self) -> Trace {
        self.trace
            .lock()
            .map(|mut t| std::mem::take(&mut *t))
            .unwrap_or_default()
    }

    /// Stop gracefully: the loop ignores further commands, ramps the force to zero within the safety ramp
    /// time, writes zero, and ends. Only then the goodbyes: the hello thread ends, the subscribers and
    /// presence token are undeclared and the session closed, all within [`CLOSE_TIMEOUT`]: when the network
    /// cannot carry them (a partition), they are abandoned with a warning and the server notices by its lease.
    /// Idempotent. Returns the first failure, after attempting every step.
    pub fn stop(&mut self) -> Result<(), HapticError> {
        self.stop.store(true, Ordering::Release);
        let mut first_error = None;
        // The force first: the loop never waits on the network.
        if let Some(thread) = self.loop_thread.take() {
            thread.thread().unpark();
            if thread.join().is_err() {
                first_error.get_or_insert(HapticError::Panicked {
                    name: format!("hapticserver-{} device loop", self.device_id),
                });
            }
        }
        let hello = self.hello_thread.take();
        let subscriber = self.subscriber.take();
        let watch_subscribers = std::mem::take(&mut self.watch_subscribers);
        let token = self.token.take();
        let session = self.session.take();
        if hello.is_none() && subscriber.is_none() && token.is_none() && session.is_none() {
            return first_error.map_or(Ok(()), Err);
        }
        let errors: Arc<Mutex<Vec<HapticError>>> = Arc::default();
        let teardown_errors = errors.clone();
        let device_id = self.device_id.clone();
        let finished = sinew_protocol::rt::finish_within(
            &format!("hapticserver-{}-close", self.device_id),
            CLOSE_TIMEOUT,
            move || {
                let push = |e| {
                    if let Ok(mut errors) = teardown_errors.lock() {
                        errors.push(e);
                    }
                };
                if let Some(thread) = hello {
                    thread.thread().unpark();
                    if thread.join().is_err() {
                        push(HapticError::Panicked {
                            name: format!("hapticserver-{device_id} watch"),
                        });
                    }
                }
                if let Some(subscriber) = subscriber
                    && let Err(err) = subscriber.undeclare().wait()
                {
                    push(HapticError::zenoh("undeclaring the force subscriber")(err));
                }
                drop(watch_subscribers);
                if let Some(token) = token
                    && let Err(err) = token.undeclare().wait()
                {
                    push(HapticError::zenoh("undeclaring the presence token")(err));
                }
                if let Some(session) = session
                    && let Err(err) = session.close().wait()
                {
                    tracing::warn!(device = %device_id, %err, "the zenoh session did not close cleanly (server unreachable?)");
                }
            },
        );
        if !finished {
            tracing::warn!(
                device = %self.device_id,
                "force at zero; zenoh could not say goodbye within {} ms (server unreachable?): the server \
                 will notice by its lease",
                CLOSE_TIMEOUT.as_millis()
            );
        }
        if let Ok(mut errors) = errors.lock()
            && !errors.is_empty()
        {
            first_error.get_or_insert(errors.remove(0));
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Stop abruptly, as a crash would look to the network: the loop ends at once (no ramp; the device gets
    /// zero force) and every zenoh object is dropped without undeclaring first.
    pub fn kill(mut self) {
        self.abrupt.store(true, Ordering::Release);
        self.stop.store(true, Ordering::Release);
        for thread in [self.hello_thread.take(), self.loop_thread.take()]
            .into_iter()
            .flatten()
        {
            thread.thread().unpark();
            // A panicked thread is already gone, which is all a kill wants.
            let _ = thread.join();
        }
        drop(self.subscriber.take());
        self.watch_subscribers.clear();
        drop(self.token.take());
        drop(self.session.take());
    }
}

impl Drop for HapticHandle {
    fn drop(&mut self) {
        if let Err(err) = self.stop() {
            tracing::warn!(device = %self.device_id, %err, "hapticserver did not stop cleanly");
        }
    }
}
