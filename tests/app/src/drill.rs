//! Latency drills on virtual time: the real server tick and the real device loops, joined by emulated links.
//!
//! Owns: [`run_drill`], which steps, in lockstep at 1 kHz of virtual time, every device's
//! [`hapticserver::haptic_loop::HapticLoop`] (a simulated hand with a preset impedance, the local-model
//! renderer, the mode switch, force safety, passivity) and the server's [`ServerTick`] (simulation, virtual
//! coupling, contact stiffness, planes, energy budget, deadband), passing every pose and force command as
//! encoded bytes through a seeded [`DelayLine`] per direction (delay, jitter, loss); and the measurements the
//! acceptance criteria are written in ([`hold_metrics`], [`felt_stiffness`], [`rms_error_fraction`],
//! [`max_force_step`]). Nothing here is a model of the roles: the same code runs in the processes; only the
//! network is replaced, which makes every run deterministic and faster than real time.
//!
//! Must not: open zenoh sessions or read the wall clock.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use hapticserver::force_inbox::ForceInbox;
use hapticserver::haptic_loop::HapticLoop;
use hapticserver::sim_device::sim_device_model;
use hapticserver::{
    ForceSafety, HandPreset, HandScript, ModePolicy, SafetyConfig, SimDevice, TraceSample,
};
use sinew_protocol::rt::{DelayLine, EmulationConfig};
use sinew_protocol::{DevicePose, ForceCommand, InstanceId, decode, encode};

/// The instance id of the drill's in-process server.
const DRILL_SERVER: InstanceId = InstanceId(0x5e);
use sinew_server::server_tick::DeadbandParams;
use sinew_server::server_tick::{PoseInput, ServerTick};
use sinew_server::sim::Sim;
use sinew_server::world::World;

/// One emulated network path between a device and the server.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    /// Round trip added by the network, ms (half each way).
    pub rtt_ms: f64,
    /// Each one-way delay varies by up to this much either way, ms.
    pub jitter_ms: f64,
    /// Fraction of messages lost, each way.
    pub loss: f64,
    /// Seed of the draws.
    pub seed: u64,
}

impl Link {
    /// A link with this round trip and nothing else.
    pub fn rtt(rtt_ms: f64) -> Self {
        Self {
            rtt_ms,
            jitter_ms: 0.0,
            loss: 0.0,
            seed: 1,
        }
    }

    fn one_way(&self, direction: u64) -> EmulationConfig {
        EmulationConfig {
            delay_ms: self.rtt_ms / 2.0,
            jitter_ms: self.jitter_ms,
            loss: self.loss,
            seed: self.seed.wrapping_mul(2).wrapping_add(direction),
        }
    }
}

/// One device in a drill.
#[derive(Debug, Clone)]
pub struct DrillDevice {
    /// Device id (the world binds it to a tool).
    pub id: String,
    /// The simulated operator.
    pub hand: HandPreset,
    /// What the hand does.
    pub script: HandScript,
    /// The network between it and the server.
    pub link: Link,
    /// Direct, moderated or auto.
    pub mode: ModePolicy,
}

/// The server tool's position and the device position that drove it, device frame, mm (None before the
/// first pose).
pub type DriftPair = Option<([f32; 3], [f32; 3])>;

/// What a drill recorded.
#[derive(Debug, Clone)]
pub struct DrillResult {
    /// Per device, every tick.
    pub traces: Vec<Vec<TraceSample>>,
    /// Per device, per tick: the server tool's position (device frame, mm), and the device position at the
    /// time of the pose that drove it (None before the first pose) — equal timestamps, for drift.
    pub tool_vs_device_mm: Vec<Vec<DriftPair>>,
    /// Per device: force commands the server sent.
    pub commands_sent: Vec<u64>,
    /// Per device: force commands the server sent in each whole second of the run (index = second).
    pub commands_per_second: Vec<Vec<u64>>,
    /// Per device: times the silence rule started a ramp to zero.
    pub stale_events: Vec<u64>,
    /// Per device: the passivity controller's active ticks and withheld energy, mJ.
    pub passivity_withheld_mj: Vec<f64>,
    /// Per device: needle punctures its local model popped at the device.
    pub needle_pops: Vec<u32>,
    /// Per device: the largest force rendered, N.
    pub max_force_n: Vec<f32>,
    /// Per device: force payloads the device refused (a valid server sends none).
    pub rejected: Vec<u64>,
    /// Deepest point of object 0 below its rest plane at the end, mm.
    pub final_positions_mm: Vec<[f32; 3]>,
}

impl DrillResult {
    /// Force commands the server sent `device` per second from whole second `from_s` to the end of the run.
    pub fn messages_per_s_from(&self, device: usize, from_s: usize) -> f64 {
        let seconds = &self.commands_per_second[device];
        let window = seconds.get(from_s..).unwrap_or_default();
        window.iter().sum::<u64>() as f64 / window.len().max(1) as f64
    }
}

struct DeviceRig {
    haptic: HapticLoop,
    inbox: Arc<ForceInbox>,
    tool: usize,
    up: DelayLine,
    down: DelayLine,
    poses_in_flight: VecDeque<(u64, Vec<u8>)>,
    forces_in_flight: VecDeque<(u64, Vec<u8>)>,
    latest_pose: Option<(DevicePose, u64)>,
    positions_by_seq: VecDeque<(u64, [f32; 3])>,
    sent: u64,
    sent_per_s: Vec<u64>,
}

/// Run `devices` against `world` for `duration_s` of virtual time. Deterministic.
pub fn run_drill(
    world: &World,
    devices: &[DrillDevice],
    duration_s: f64,
) -> anyhow::Result<DrillResult> {
    run_drill_observed(world, devices, duration_s, |_, _| {})
}

/// [`run_drill`], showing `observe` the server after each tick with the force commands that tick produced
/// (before the link delays them): the golden traces hash what it sees.
pub fn run_drill_observed(
    world: &World,
    devices: &[DrillDevice],
    duration_s: f64,
    mut observe: impl FnMut(&ServerTick, &[Option<ForceCommand>]),
) -> anyhow::Result<DrillResult> {
    let sim = Sim::new(world).context("building the drill's simulation")?;
    let tools: Vec<String> = sim.tools.iter().map(|t| t.device_id.clone()).collect();
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut server = ServerTick::new(sim, dt_s, world.pose_timeout_s, DeadbandParams::default());
    let ticks = (duration_s * 1000.0).round() as usize;
    let model = sim_device_model();
    let mut rigs = Vec::with_capacity(devices.len());
    for device in devices {
        let tool = tools
            .iter()
            .position(|id| *id == device.id)
            .with_context(|| format!("no tool in the world is bound to device `{}`", device.id))?;
        let sim_device =
            SimDevice::with_params(device.script.clone(), device.hand.params(), model.clone());
        let safety = ForceSafety::new(SafetyConfig::for_device(&model))?;
        // Each device is its own instance; the drill's server is DRILL_SERVER.
        let inbox = Arc::new(ForceInbox::new(InstanceId(rigs.len() as u64 + 1)));
        let mut haptic = HapticLoop::new(
            Box::new(sim_device),
            safety,
            inbox.clone(),
            Duration::from_millis(1),
        );
        haptic.set_mode_policy(device.mode);
        haptic.record_trace(ticks + 1);
        rigs.push(DeviceRig {
            haptic,
            inbox,
            tool,
            up: DelayLine::new(device.link.one_way(0)),
            down: DelayLine::new(device.link.one_way(1)),
            poses_in_flight: VecDeque::new(),
            forces_in_flight: VecDeque::new(),
            latest_pose: None,
            positions_by_seq: VecDeque::new(),
            sent: 0,
            sent_per_s: vec![0; ticks.div_ceil(1000)],
        });
    }
    let n_tools = tools.len();
    let mut inputs: Vec<Option<PoseInput>> = vec![None; n_tools];
    let limits: Vec<Option<f32>> = vec![Some(model.max_force_n); n_tools];
    let mut commands: Vec<Option<ForceCommand>> = vec![None; n_tools];
    let mut drift: Vec<Vec<DriftPair>> =
        (0..rigs.len()).map(|_| Vec::with_capacity(ticks)).collect();
    let mut bytes = Vec::with_capacity(512);

    for tick in 1..=ticks {
        let now_ns = tick as u64 * 1_000_000;
        // Devices: read, publish the pose into the uplink.
        for rig in &mut rigs {
            let up = &mut rig.up;
            let queue = &mut rig.poses_in_flight;
            rig.haptic.tick(
                now_ns,
                Some(Duration::from_millis(1)),
                &mut |pose: &[u8]| {
                    if let Some(due) = up.schedule(now_ns) {
                        queue.push_back((due, pose.to_vec()));
                    }
                    true
                },
            );
            if let Some(last) = rig.haptic.trace().samples().last() {
                // The pose just published carries this position; remember it by its sequence number.
                let seq = rig.positions_by_seq.back().map_or(1, |(s, _)| s + 1);
                rig.positions_by_seq.push_back((seq, last.position_mm));
                if rig.positions_by_seq.len() > 2000 {
                    rig.positions_by_seq.pop_front();
                }
            }
            while rig
                .poses_in_flight
                .front()
                .is_some_and(|(due, _)| *due <= now_ns)
            {
                if let Some((_, payload)) = rig.poses_in_flight.pop_front()
                    && let Ok(pose) = decode::<DevicePose>(&payload)
                {
                    rig.latest_pose = Some((pose, now_ns));
                }
            }
        }
        // Server tick.
        for input in inputs.iter_mut() {
            *input = None;
        }
        for rig in &rigs {
            inputs[rig.tool] = rig.latest_pose.map(|(pose, arrived_ns)| PoseInput {
                pose,
                age_s: (now_ns - arrived_ns) as f64 * 1e-9,
                usable: true,
            });
        }
        server.step(&inputs, &limits, &mut commands);
        observe(&server, &commands);
        for (r, rig) in rigs.iter_mut().enumerate() {
            if let Some(command) = &mut commands[rig.tool] {
                rig.sent += 1;
                rig.sent_per_s[(tick - 1) / 1000] += 1;
                command.device_instance = rig.inbox.own_instance().0;
                encode(DRILL_SERVER, command, &mut bytes);
                if let Some(due) = rig.down.schedule(now_ns) {
                    rig.forces_in_flight.push_back((due, bytes.clone()));
                }
            }
            let out = &server.outputs()[rig.tool];
            let origin = server.sim().tools[rig.tool].device_origin_in_world_mm;
            let tool_mm: [f32; 3] = (out.position_world_mm - origin).into();
            let driven_by = rig.latest_pose.and_then(|(pose, _)| {
                rig.positions_by_seq
                    .iter()
                    .find(|(seq, _)| *seq == pose.seq)
                    .map(|(_, p)| *p)
            });
            drift[r].push(driven_by.map(|device_mm| (tool_mm, device_mm)));
            // Downlink: deliver what is due (read by the device on its next tick).
            while rig
                .forces_in_flight
                .front()
                .is_some_and(|(due, _)| *due <= now_ns)
            {
                if let Some((_, payload)) = rig.forces_in_flight.pop_front() {
                    // A refused payload is counted by the inbox (DrillResult::rejected).
                    if let Err(e) = rig.inbox.accept(&payload, now_ns) {
                        eprintln!("drill: refused force payload at {now_ns} ns: {e:?}");
                    }
                }
            }
        }
    }

    let mut result = DrillResult {
        traces: Vec::new(),
        tool_vs_device_mm: drift,
        commands_sent: Vec::new(),
        commands_per_second: Vec::new(),
        stale_events: Vec::new(),
        passivity_withheld_mj: Vec::new(),
        needle_pops: Vec::new(),
        max_force_n: Vec::new(),
        rejected: Vec::new(),
        final_positions_mm: server
            .positions_mm(0)
            .map(|p| p.iter().map(|v| (*v).into()).collect())
            .unwrap_or_default(),
    };
    for mut rig in rigs {
        let mut report = hapticserver::HapticReport::new("drill");
        rig.haptic.write_report(&mut report);
        result.commands_sent.push(rig.sent);
        result.commands_per_second.push(rig.sent_per_s);
        result.stale_events.push(report.safety.stale_events);
        result
            .passivity_withheld_mj
            .push(report.passivity.withheld_mj);
        result.needle_pops.push(report.needle_pops);
        result.max_force_n.push(report.max_rendered_force_n);
        result.rejected.push(rig.inbox.rejects().total());
        result
            .traces
            .push(rig.haptic.take_trace().samples().to_vec());
    }
    Ok(result)
}

fn norm(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// How still a hold was, over the samples with `from_s <= t < to_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoldMetrics {
    /// Largest peak-to-peak of a force component, N.
    pub force_p2p_n: f32,
    /// RMS of the stylus speed, mm/s.
    pub velocity_rms_mm_s: f32,
    /// Mean force magnitude, N.
    pub mean_force_n: f32,
}

/// [`HoldMetrics`] of a trace window.
pub fn hold_metrics(trace: &[TraceSample], from_s: f64, to_s: f64) -> HoldMetrics {
    let window: Vec<&TraceSample> = trace
        .iter()
        .filter(|s| s.t_s >= from_s && s.t_s < to_s)
        .collect();
    let mut p2p: f32 = 0.0;
    for axis in 0..3 {
        let (lo, hi) = window.iter().fold((f32::MAX, f32::MIN), |(lo, hi), s| {
            (lo.min(s.force_n[axis]), hi.max(s.force_n[axis]))
        });
        if !window.is_empty() {
            p2p = p2p.max(hi - lo);
        }
    }
    let n = window.len().max(1) as f32;
    let speed2: f32 = window.iter().map(|s| norm(s.velocity_mm_s).powi(2)).sum();
    HoldMetrics {
        force_p2p_n: p2p,
        velocity_rms_mm_s: (speed2 / n).sqrt(),
        mean_force_n: window.iter().map(|s| norm(s.force_n)).sum::<f32>() / n,
    }
}

/// Net energy the rendered force put into the hand over the whole trace, mJ (`sum F . v dt`; a passive
/// contact gives back at most what the hand stored, so this stays <= 0 up to rounding).
pub fn energy_output_mj(trace: &[TraceSample]) -> f64 {
    trace
        .windows(2)
        .map(|w| {
            let dt = w[1].t_s - w[0].t_s;
            let f = w[1].force_n;
            let v = w[1].velocity_mm_s;
            (0..3)
                .map(|i| f64::from(f[i]) * f64::from(v[i]))
                .sum::<f64>()
                * dt
        })
        .sum()
}

/// The stiffness felt along z during a slow press: the least-squares slope of the z force against the
/// indentation, over the samples where the indentation (below the height at which the force first exceeded
/// 20 mN) lies in `[from_mm, to_mm]` and the hand still moves down. N/mm; None with too few samples.
pub fn felt_stiffness(trace: &[TraceSample], from_mm: f32, to_mm: f32) -> Option<f32> {
    let contact = trace.iter().find(|s| s.force_n[2] > 0.02)?;
    let z_contact = contact.position_mm[2];
    let points: Vec<(f32, f32)> = trace
        .iter()
        .filter(|s| s.t_s > contact.t_s)
        .map(|s| (z_contact - s.position_mm[2], s.force_n[2]))
        .filter(|(d, _)| *d >= from_mm && *d <= to_mm)
        .collect();
    if points.len() < 50 {
        return None;
    }
    let n = points.len() as f32;
    let mx = points.iter().map(|p| p.0).sum::<f32>() / n;
    let my = points.iter().map(|p| p.1).sum::<f32>() / n;
    let sxy: f32 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f32 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    (sxx > 1e-9).then_some(sxy / sxx)
}

/// RMS of the force difference between two traces over `from_s..to_s`, as a fraction of the reference's
/// peak force magnitude there.
pub fn rms_error_fraction(
    trace: &[TraceSample],
    reference: &[TraceSample],
    from_s: f64,
    to_s: f64,
) -> f32 {
    let mut sum2 = 0.0f64;
    let mut count = 0usize;
    let mut peak: f32 = 0.0;
    for (a, b) in trace.iter().zip(reference) {
        if a.t_s < from_s || a.t_s >= to_s {
            continue;
        }
        let d = [
            a.force_n[0] - b.force_n[0],
            a.force_n[1] - b.force_n[1],
            a.force_n[2] - b.force_n[2],
        ];
        sum2 += f64::from(norm(d)).powi(2);
        count += 1;
        peak = peak.max(norm(b.force_n));
    }
    if count == 0 || peak <= 0.0 {
        return f32::NAN;
    }
    ((sum2 / count as f64).sqrt() as f32) / peak
}

/// Amplitude of the rendered force's z component at `frequency_hz` over `from_s..to_s`, N (a lock-in: twice
/// the magnitude of the force's Fourier coefficient there; over a whole number of periods a steady offset and
/// the other harmonics of the window cancel). What a hand feels of a periodic push, without the tick-level
/// noise a peak-to-peak reading would add.
pub fn force_amplitude_at(trace: &[TraceSample], frequency_hz: f64, from_s: f64, to_s: f64) -> f32 {
    let (mut re, mut im, mut count) = (0.0f64, 0.0f64, 0usize);
    for s in trace.iter().filter(|s| s.t_s >= from_s && s.t_s < to_s) {
        let phase = std::f64::consts::TAU * frequency_hz * s.t_s;
        re += f64::from(s.force_n[2]) * phase.cos();
        im += f64::from(s.force_n[2]) * phase.sin();
        count += 1;
    }
    if count == 0 {
        return f32::NAN;
    }
    (2.0 * re.hypot(im) / count as f64) as f32
}

/// The largest change of the rendered force between two consecutive ticks over `from_s..to_s`, N.
pub fn max_force_step(trace: &[TraceSample], from_s: f64, to_s: f64) -> f32 {
    trace
        .windows(2)
        .filter(|w| w[1].t_s >= from_s && w[1].t_s < to_s)
        .map(|w| {
            norm([
                w[1].force_n[0] - w[0].force_n[0],
                w[1].force_n[1] - w[0].force_n[1],
                w[1].force_n[2] - w[0].force_n[2],
            ])
        })
        .fold(0.0, f32::max)
}

/// Largest distance between the server's tool and the device at equal timestamps over `from_s..to_s`, mm,
/// and the largest device speed there, mm/s.
pub fn drift_mm(result: &DrillResult, device: usize, from_s: f64, to_s: f64) -> (f32, f32) {
    let trace = &result.traces[device];
    let mut worst: f32 = 0.0;
    let mut fastest: f32 = 0.0;
    for (tick, pair) in result.tool_vs_device_mm[device].iter().enumerate() {
        let t_s = (tick + 1) as f64 * 1e-3;
        if t_s < from_s || t_s >= to_s {
            continue;
        }
        if let Some((tool, dev)) = pair {
            worst = worst.max(norm([tool[0] - dev[0], tool[1] - dev[1], tool[2] - dev[2]]));
        }
        if let Some(s) = trace.get(tick) {
            fastest = fastest.max(norm(s.velocity_mm_s));
        }
    }
    (worst, fastest)
}
