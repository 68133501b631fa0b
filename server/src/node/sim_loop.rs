//! The dedicated 1 kHz sim thread: mailboxes in, [`ServerTick`], force commands out (straight to zenoh, or
//! through the emulated network when `--emulate-*` is set).
//!
//! A panic in the tick is caught at the thread's top: every device that got a force is sent an explicit zero
//! (three times, against loss; the device's rate limit turns it into a ramp), the failure is recorded in
//! `Shared::failure` for the process to exit non-zero, and every other thread is told to stop. A server whose
//! simulation died never keeps running with devices waiting on it.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sinew_protocol::rt::realtime::{self, RealtimeRequest};
use sinew_protocol::rt::{DelayedSender, EmulationConfig, LatencyHistogram, Pacer};
use sinew_protocol::{ForceCommand, ForceMode, InstanceId, RenderMode, encode};
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Reliability};

use super::device_slots::PoseArrival;
use super::keepalive::{Keepalive, KeepaliveSend};
use super::{ServerError, Shared};
use crate::recording::{FinalState, RecorderTap, TickRecord};
use crate::server_tick::DeadbandParams;
use crate::server_tick::{PoseInput, ServerTick};
use crate::sim::Sim;
use crate::tissue::Vec3;
pub use crate::training::LiveTraining;
use crate::training::{ExerciseRun, LiveScore, MetricsConfig, SessionObserver, TickView};

/// Per-device counters kept by the sim thread.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceReport {
    /// Its tool is active (device present, poses fresh).
    pub active: bool,
    /// Force commands published.
    pub forces_sent: u64,
    /// Commands re-sent unchanged because the tick had sent the device nothing for
    /// [`super::keepalive::KEEPALIVE_AFTER`] of wall time (the sim ran slower than real time).
    pub keepalives_sent: u64,
    /// Largest force magnitude published, N.
    pub max_force_n: f32,
    /// The device's last reported round trip, us.
    pub last_round_trip_us: u32,
    /// The device renders the local model (latency-moderated) rather than the streamed force.
    pub moderated: bool,
    /// Ticks on which its model was within the deadband and nothing was sent.
    pub suppressed: u64,
    /// Moderated heartbeats the tick made (models due only because the heartbeat period had passed), published
    /// at once or held for the keepalive; in `forces_sent` once published.
    pub heartbeats_sent: u64,
    /// The force limit the device announced (recorded, in a replay), N.
    pub force_limit_n: Option<f32>,
    /// The training layer's view of the participant (`crate::training`), live.
    pub training: LiveTraining,
}

/// How far a published replay has got ([`super::ReplayFeed`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReplayProgress {
    /// Ticks in the recording.
    pub ticks_total: u64,
    /// Ticks re-run so far.
    pub ticks_done: u64,
    /// Force commands compared with the recorded ones.
    pub forces_compared: u64,
    /// Of those, how many differed in any bit.
    pub force_mismatches: u64,
    /// Every recorded tick was re-run (or the recording had a gap there: see `ticks_done`).
    pub finished: bool,
}

/// What the sim thread reports (copied out every 100 ticks without blocking).
#[derive(Debug, Clone)]
pub struct SimReport {
    /// Ticks run.
    pub ticks: u64,
    /// Periods skipped because a tick started late.
    pub overruns: u64,
    /// Steps whose state went non-finite and was reset.
    pub faults: u64,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Whole-tick compute time (inputs, step, force publishing, the tick's tail), ns.
    pub tick_time: LatencyHistogram,
    /// From the tick's start to its last force command handed to zenoh, ns: the server's share of the pose
    /// -> force round trip.
    pub force_time: LatencyHistogram,
    /// Per tool-bound device.
    pub devices: Vec<DeviceReport>,
    /// The world's exercise, scored live (None: the world is not an exercise).
    pub exercise: Option<LiveScore>,
    /// A published replay's progress (None: a live session).
    pub replay: Option<ReplayProgress>,
}

impl SimReport {
    /// Empty report for `tools` tools.
    pub fn new(tools: usize) -> Self {
        Self {
            ticks: 0,
            overruns: 0,
            faults: 0,
            sim_time_s: 0.0,
            tick_time: LatencyHistogram::new(),
            force_time: LatencyHistogram::new(),
            devices: vec![DeviceReport::default(); tools],
            exercise: None,
            replay: None,
        }
    }

    /// Overwrite with `other`, no allocation.
    pub fn copy_from(&mut self, other: &SimReport) {
        self.ticks = other.ticks;
        self.overruns = other.overruns;
        self.faults = other.faults;
        self.sim_time_s = other.sim_time_s;
        self.tick_time.copy_from(&other.tick_time);
        self.force_time.copy_from(&other.force_time);
        self.devices.copy_from_slice(&other.devices);
        self.exercise = other.exercise;
        self.replay = other.replay;
    }
}

/// How the sim thread runs, beyond the shared state.
pub(super) struct SimThreadOptions {
    /// spin_sleep native accuracy, ns (the most the thread spins before a deadline).
    pub spin_native_accuracy_ns: u32,
    /// Ask for SCHED_FIFO and locked memory.
    pub realtime: bool,
    /// Emulated network on the force commands.
    pub emulation: EmulationConfig,
    /// Fault drill: panic at this tick.
    pub panic_at_tick: Option<u64>,
    /// Where every tick is recorded, if it is.
    pub recorder: Option<RecorderTap>,
    /// Inputs from a recording instead of the devices (a published replay), if any.
    pub replay: Option<super::ReplayFeed>,
}

pub(super) fn spawn(
    session: &zenoh::Session,
    shared: Arc<Shared>,
    sim: Sim,
    options: SimThreadOptions,
) -> Result<JoinHandle<()>, ServerError> {
    let emulation = options.emulation;
    let mut outlets = Vec::with_capacity(sim.tools.len());
    // A replay sends no force to anyone: a device holding a recorded id must not feel the recording.
    let tools = if options.replay.is_some() {
        &[][..]
    } else {
        &sim.tools[..]
    };
    for tool in tools {
        let publisher = session
            .declare_publisher(shared.keys.device_force(&tool.device_id)?)
            .congestion_control(CongestionControl::Drop)
            .reliability(Reliability::BestEffort)
            .express(true)
            .wait()?;
        outlets.push(if emulation.is_off() {
            ForceOutlet::Direct(publisher)
        } else {
            let name = format!("sinew-delay-{}", tool.device_id);
            let sender = DelayedSender::start(&name, emulation, move |bytes: &[u8]| {
                // A failed put (session closing) is not fatal; the device ramps down on silence.
                let _ = publisher.put(bytes).wait();
            })
            .map_err(|e| ServerError::Thread(e.to_string()))?;
            ForceOutlet::Delayed(sender)
        });
    }
    std::thread::Builder::new()
        .name("sinew-sim".into())
        .spawn(move || supervise(&shared, sim, &mut outlets, options))
        .map_err(|e| ServerError::Thread(e.to_string()))
}

/// Where one device's force commands go: straight to zenoh, or through the emulated network first.
enum ForceOutlet {
    Direct(zenoh::pubsub::Publisher<'static>),
    Delayed(DelayedSender),
}

impl ForceOutlet {
    fn send(&mut self, bytes: &[u8]) {
        match self {
            // A failed put (session closing) is not fatal to the tick; the device ramps down on silence.
            ForceOutlet::Direct(publisher) => {
                let _ = publisher.put(bytes).wait();
            }
            ForceOutlet::Delayed(sender) => sender.send(bytes),
        }
    }
}

/// The last command sent to each device: what its farewell zero follows (sequence, echoed pose seq and time,
/// device instance).
type LastSent = Vec<Option<(u64, u64, u64, u64)>>;

/// Run the ticks; if they panic, zero every device, record the failure and stop the server.
fn supervise(shared: &Shared, sim: Sim, outlets: &mut [ForceOutlet], options: SimThreadOptions) {
    let mut last_sent: LastSent = vec![None; sim.tools.len()];
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        run(shared, sim, outlets, &mut last_sent, options);
    }));
    let Err(payload) = outcome else {
        return;
    };
    let message = payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_owned());
    let mut buf = Vec::with_capacity(64);
    let mut told = 0;
    for (outlet, last) in outlets.iter_mut().zip(&last_sent) {
        let Some((seq, echo_pose_seq, echo_device_time_ns, device_instance)) = *last else {
            continue;
        };
        for k in 1..=3 {
            encode(
                shared.instance,
                &ForceCommand {
                    seq: seq + k,
                    echo_pose_seq,
                    echo_device_time_ns,
                    force_n: [0.0; 3],
                    mode: ForceMode::Direct,
                    in_contact: false,
                    device_instance,
                    pose_wait_us: None,
                },
                &mut buf,
            );
            outlet.send(&buf);
        }
        told += 1;
    }
    let _ = shared.failure.set(format!(
        "the simulation thread panicked: {message} ({told} device(s) sent an explicit zero force)"
    ));
    shared.stop.store(true, Ordering::Release);
}

fn run(
    shared: &Shared,
    sim: Sim,
    outlets: &mut [ForceOutlet],
    last_sent: &mut LastSent,
    options: SimThreadOptions,
) {
    let SimThreadOptions {
        spin_native_accuracy_ns,
        realtime,
        emulation: _,
        panic_at_tick,
        mut recorder,
        replay,
    } = options;
    let world = &shared.world;
    let n = sim.tools.len();
    let tick_dt_s = (1.0 / world.tick_hz) as f32;
    let ticks_per_frame = (world.tick_hz / world.publish_hz).round().max(1.0) as u64;
    let speed = replay.as_ref().map_or(1.0, |feed| feed.speed);
    let grant = realtime::configure_this_thread(if realtime {
        RealtimeRequest::Fifo {
            priority: realtime::SIM_LOOP_PRIORITY,
        }
    } else {
        RealtimeRequest::Normal
    });
    tracing::info!(scene = %world.scene, "sim thread: {grant}");
    let spin_ns = grant.spin_window_ns(spin_native_accuracy_ns);
    let _ = shared.realtime.set(grant);
    let mut pacer = Pacer::new(
        Duration::from_secs_f64(1.0 / (world.tick_hz * speed)),
        spin_ns,
    );
    let mut tick = ServerTick::new(
        sim,
        tick_dt_s,
        world.pose_timeout_s,
        DeadbandParams::default(),
    );

    let mut seen = vec![0u64; n];
    let mut last_pose: Vec<Option<PoseArrival>> = vec![None; n];
    let mut pose_wait_us: Vec<Option<u32>> = vec![None; n];
    let mut inputs: Vec<Option<PoseInput>> = vec![None; n];
    let mut limits: Vec<Option<f32>> = vec![None; n];
    let mut commands: Vec<Option<ForceCommand>> = vec![None; n];
    let mut local = SimReport::new(n);
    local.replay = replay.as_ref().map(|feed| ReplayProgress {
        ticks_total: feed.ticks.len() as u64,
        ..ReplayProgress::default()
    });
    let mut buf = Vec::with_capacity(256);
    let mut keepalive = Keepalive::new(n);
    let mut frame_due = false;
    // The training layer watches every tick: live metrics and score in the report, events into the recording
    // (built here: no allocation in the loop).
    let mut observer = {
        // The tick in seconds as the report and replay count it (f64, not the f32 step).
        let dt_s = 1.0 / world.tick_hz;
        let observer = SessionObserver::new(n, MetricsConfig::new(dt_s));
        match &world.exercise {
            Some(spec) => observer.with_exercise(ExerciseRun::new(spec.clone(), n, dt_s)),
            None => observer,
        }
    };

    while !shared.stop.load(Ordering::Acquire) {
        pacer.wait();
        let start = Instant::now();
        // A published replay takes each tick's inputs from the recording, and ends with it.
        let recorded = match &replay {
            Some(feed) => match feed.ticks.get(local.ticks as usize) {
                Some(record) if record.tick == local.ticks && record.devices.len() == n => {
                    Some(record)
                }
                _ => break,
            },
            None => None,
        };
        for t in 0..n {
            if let Some(record) = recorded {
                inputs[t] = record.devices[t].pose_input();
                limits[t] = record.devices[t].max_force_n;
                continue;
            }
            let Some(slot) = shared.slots.get(t) else {
                continue;
            };
            if let Some(arrival) = slot.pose.take_newer(&mut seen[t]) {
                last_pose[t] = Some(arrival);
                // Measured once, at the tick that first uses the pose: the device aligns its phase with it.
                pose_wait_us[t] = Some(wait_us(start, arrival.received));
            }
            let usable = !slot.gone.load(Ordering::Acquire);
            inputs[t] = last_pose[t].map(|a| PoseInput {
                pose: a.pose,
                age_s: start.saturating_duration_since(a.received).as_secs_f64(),
                usable,
            });
            limits[t] = slot.hello_max_force_n();
        }

        assert!(
            panic_at_tick != Some(local.ticks),
            "fault drill: panic at tick {} (--fault-panic-at-tick)",
            local.ticks
        );
        let report = tick.step(&inputs, &limits, &mut commands);
        local.faults += u64::from(report.faults);

        if let (Some(record), Some(progress)) = (recorded, local.replay.as_mut()) {
            for (device, replayed) in record.devices.iter().zip(&commands) {
                if device.force.is_none() && replayed.is_none() {
                    continue;
                }
                progress.forces_compared += 1;
                if !crate::recording::replay::same_bits(device, replayed) {
                    progress.force_mismatches += 1;
                }
            }
            progress.ticks_done += 1;
        }
        for t in 0..n {
            let d = &mut local.devices[t];
            d.active = inputs[t].is_some_and(|i| i.usable && i.age_s < world.pose_timeout_s);
            d.force_limit_n = limits[t];
            let Some(command) = &mut commands[t] else {
                // Nothing from the tick: a device that has heard nothing for a while hears the last command again
                // (a live replay publishes only what was recorded).
                if !d.active || recorded.is_some() {
                    keepalive.forget(t);
                } else if let Some(send) = keepalive.due(t, Instant::now()) {
                    let (KeepaliveSend::Repeat(again) | KeepaliveSend::Held(again)) = send;
                    encode(shared.instance, &again, &mut buf);
                    if let Some(outlet) = outlets.get_mut(t) {
                        outlet.send(&buf);
                    }
                    match send {
                        KeepaliveSend::Repeat(_) => d.keepalives_sent += 1,
                        KeepaliveSend::Held(_) => d.forces_sent += 1,
                    }
                }
                continue;
            };
            command.device_instance = last_pose[t].map_or(InstanceId::NONE, |a| a.from).0;
            command.pose_wait_us = if recorded.is_some() {
                None
            } else {
                pose_wait_us[t]
            };
            // A heartbeat close behind the last message waits for the keepalive (`keepalive`'s module doc);
            // a live replay publishes what was recorded, when it was.
            let heartbeats = tick.stream_counters(t).heartbeats;
            let heartbeat = heartbeats > d.heartbeats_sent;
            d.heartbeats_sent = heartbeats;
            if heartbeat && recorded.is_none() && keepalive.hold(t, command, Instant::now()) {
                last_sent[t] = Some((
                    command.seq,
                    command.echo_pose_seq,
                    command.echo_device_time_ns,
                    command.device_instance,
                ));
                continue;
            }
            encode(shared.instance, command, &mut buf);
            if let Some(outlet) = outlets.get_mut(t) {
                outlet.send(&buf);
            }
            keepalive.sent(t, command, Instant::now());
            last_sent[t] = Some((
                command.seq,
                command.echo_pose_seq,
                command.echo_device_time_ns,
                command.device_instance,
            ));
            d.forces_sent += 1;
            d.max_force_n = d.max_force_n.max(Vec3::from(command.force_n).norm());
            d.last_round_trip_us = inputs[t].map_or(0, |i| i.pose.round_trip_us);
            d.moderated = inputs[t].is_some_and(|i| i.pose.render_mode == RenderMode::Moderated);
        }
        // The forces are out: now the tick's tail (the contact-stiffness iterations for the next ticks).
        local.force_time.record(start.elapsed());
        tick.finish_tick();
        for (t, d) in local.devices.iter_mut().enumerate() {
            d.suppressed = tick.stream_counters(t).suppressed;
        }
        let view = TickView {
            tick: local.ticks,
            active: tick.tools_active(),
            outputs: tick.outputs(),
            step: &report,
        };
        if let Some(tap) = recorder.as_mut() {
            let mut record = TickRecord::new(local.ticks, &inputs, &limits, &commands);
            observer.observe(&view, |event| record.push_event(*event), |_, _| {});
            tap.offer(&record);
        } else {
            observer.observe(&view, |_| {}, |_, _| {});
        }

        let sim = tick.sim();
        frame_due |= sim.steps().is_multiple_of(ticks_per_frame);
        if frame_due && shared.frames.try_offer(sim, tick.outputs()) {
            frame_due = false;
        }
        local.ticks += 1;
        shared.ticks_run.store(local.ticks, Ordering::Relaxed);
        local.overruns = pacer.overruns();
        local.sim_time_s = sim.time_s();
        local.tick_time.record(start.elapsed());
        if local.ticks.is_multiple_of(100) {
            live_training(&observer, &mut local);
        }
        if local.ticks.is_multiple_of(100)
            && let Ok(mut shared_report) = shared.report.try_lock()
        {
            shared_report.copy_from(&local);
        }
    }
    live_training(&observer, &mut local);
    if let Some(progress) = local.replay.as_mut() {
        progress.finished = true;
        // The last state reaches the viewers even when the replay ended between two frames.
        let _ = shared.frames.try_offer(tick.sim(), tick.outputs());
    }
    if let Ok(mut shared_report) = shared.report.lock() {
        shared_report.copy_from(&local);
    }
    if let Some(tap) = recorder {
        let sim = tick.sim();
        tap.finish(FinalState {
            ticks: local.ticks,
            positions_mm: sim
                .objects
                .iter()
                .map(|o| {
                    o.state
                        .positions_mm
                        .iter()
                        .map(|p| [p.x, p.y, p.z])
                        .collect()
                })
                .collect(),
        });
    }
}

/// Microseconds from a pose's arrival to the tick that takes it (saturating: a pose stamped after the tick's
/// start, by a callback racing it, waited 0).
fn wait_us(tick_start: Instant, received: Instant) -> u32 {
    u32::try_from(tick_start.saturating_duration_since(received).as_micros()).unwrap_or(u32::MAX)
}

/// Copy the training layer's live view into the report (no allocation).
fn live_training(observer: &SessionObserver, local: &mut SimReport) {
    for (t, device) in local.devices.iter_mut().enumerate() {
        if let Some(live) = observer.live(t) {
            device.training = live;
        }
    }
    local.exercise = observer.exercise().map(ExerciseRun::live);
}
