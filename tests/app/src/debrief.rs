//! The instructor's debrief of a recording: `sinew replay FILE --publish` republishes the session on zenoh
//! for any viewer to watch, and `sinew replay FILE --png-every N` writes frames with the instructor's overlay.
//!
//! Both re-run the recorded inputs through the server's deterministic tick, so the scene is the session's
//! own, bit for bit, and both say whether every force command came out as recorded. The published replay runs
//! inside a real server node ([`sinew_server::node::ReplayFeed`]): viewers join it as they join a live
//! session (snapshot, deltas, tool states, stats with the live score); it sends no force to anyone. The
//! frames go through the viewer's own replica and renderer.
//!
//! Must not: write to the recording, or send a force command.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_protocol::{DeviceStats, RenderMode, ServerStats};
use sinew_server::node::{
    MAX_REPLAY_SPEED, ReplayFeed, ReplayProgress, ServerConfig, ServerNode, exercise_stats,
    training_stats,
};
use sinew_server::recording::{DebriefFrames, Recording, ReplayOutcome, replay_inspected};
use sinew_server::sim::Sim;
use sinew_server::training::{ExerciseRun, MetricsConfig, SessionObserver};
use sinew_server::world::World;
use sinew_viewer::render::{SceneFrame, render_frames};
use sinew_viewer::{InstructorOverlay, SceneReplica, frame_replica};

/// Frames rendered through one offscreen surface before it is rebuilt (bounds the replicas held at once).
const FRAMES_PER_SURFACE: usize = 24;

/// How to write debrief frames.
#[derive(Debug, Clone)]
pub struct FrameOptions {
    /// A frame every this many ticks (tick N, 2N, ...), at least 1.
    pub every_ticks: u64,
    /// The directory the PNGs go into (created).
    pub out: PathBuf,
    /// Image size, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

/// What writing the frames did.
#[derive(Debug, Clone)]
pub struct FramesSummary {
    /// The PNGs written, in tick order.
    pub files: Vec<PathBuf>,
    /// The replay's comparison with the recording.
    pub outcome: ReplayOutcome,
}

/// The stats a live server would have published at this tick of the replay: what the overlay reads.
fn replay_stats(
    world: &World,
    recording: &Recording,
    observer: &SessionObserver,
    tick: u64,
    active: &[bool],
    sim_time_s: f64,
) -> ServerStats {
    let record = recording.ticks.get(tick as usize);
    let devices = world
        .tools
        .iter()
        .enumerate()
        .map(|(t, tool)| {
            let device = record.and_then(|r| r.devices.get(t));
            let pose = device.and_then(|d| d.pose);
            DeviceStats {
                device_id: tool.device_id.clone(),
                tool: tool.name.clone(),
                active: active.get(t).copied().unwrap_or(false),
                moderated: pose.is_some_and(|p| p.render_mode == RenderMode::Moderated),
                last_round_trip_us: pose.map_or(0, |p| p.round_trip_us),
                force_limit_n: device.and_then(|d| d.max_force_n).unwrap_or(0.0),
                training: observer
                    .live(t)
                    .map(|live| training_stats(&live))
                    .unwrap_or_default(),
                ..DeviceStats::default()
            }
        })
        .collect();
    ServerStats {
        sim_time_s,
        ticks: tick + 1,
        devices,
        server_id: "replay".to_owned(),
        exercise: world
            .exercise
            .as_ref()
            .zip(observer.exercise())
            .map(|(spec, run)| exercise_stats(spec, &run.live())),
        ..ServerStats::default()
    }
}

/// Re-run `recording` and write a PNG with the instructor's overlay every `every_ticks` ticks, from one
/// viewpoint framed on the scene at rest.
pub fn write_frames(
    recording: &Recording,
    world: &World,
    options: &FrameOptions,
) -> anyhow::Result<FramesSummary> {
    anyhow::ensure!(options.every_ticks >= 1, "--png-every must be at least 1");
    std::fs::create_dir_all(&options.out)
        .with_context(|| format!("creating {}", options.out.display()))?;
    let sim = Sim::new(world).context("building the recorded world")?;
    let n = sim.tools.len();
    let mut frames = DebriefFrames::new(world, &sim);
    let framing = frame_replica(&SceneReplica::from_snapshot(frames.capture(&sim, &[])));
    drop(sim);
    let dt_s = 1.0 / world.tick_hz;
    let mut observer = SessionObserver::new(n, MetricsConfig::new(dt_s));
    if let Some(spec) = &world.exercise {
        observer = observer.with_exercise(ExerciseRun::new(spec.clone(), n, dt_s));
    }
    let mut pending: Vec<(u64, SceneReplica, InstructorOverlay)> = Vec::new();
    let mut files = Vec::new();
    let mut failure: Option<anyhow::Error> = None;
    let outcome = replay_inspected(recording, world, |view, tick| {
        observer.observe(view, |_| {}, |_, _| {});
        if failure.is_some() || !(view.tick + 1).is_multiple_of(options.every_ticks) {
            return;
        }
        let replica = SceneReplica::from_snapshot(frames.capture(tick.sim(), tick.outputs()));
        let stats = replay_stats(
            world,
            recording,
            &observer,
            view.tick,
            view.active,
            tick.sim().time_s(),
        );
        let overlay = InstructorOverlay::build(&replica, Some(&stats));
        pending.push((view.tick + 1, replica, overlay));
        if pending.len() == FRAMES_PER_SURFACE
            && let Err(e) = flush(&mut pending, &framing, options, &mut files)
        {
            failure = Some(e);
        }
    })
    .context("building the recorded world")?;
    if let Some(e) = failure {
        return Err(e);
    }
    flush(&mut pending, &framing, options, &mut files)?;
    Ok(FramesSummary { files, outcome })
}

fn flush(
    pending: &mut Vec<(u64, SceneReplica, InstructorOverlay)>,
    framing: &sinew_viewer::CameraFraming,
    options: &FrameOptions,
    files: &mut Vec<PathBuf>,
) -> anyhow::Result<()> {
    if pending.is_empty() {
        return Ok(());
    }
    let scene_frames: Vec<SceneFrame<'_>> = pending
        .iter()
        .map(|(_, replica, overlay)| SceneFrame {
            replica,
            overlay: Some(overlay),
        })
        .collect();
    let images = render_frames(&scene_frames, framing, options.width, options.height)
        .context("rendering the debrief frames")?;
    for ((tick, _, _), (image, _)) in pending.iter().zip(images) {
        let path = options.out.join(format!("frame_{tick:07}.png"));
        image
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        files.push(path);
    }
    pending.clear();
    Ok(())
}

/// How to publish a replay.
#[derive(Debug, Clone)]
pub struct PublishOptions {
    /// The endpoint the replaying server listens on (TCP, and UDP on the same port).
    pub endpoint: String,
    /// Simulated seconds per wall second.
    pub speed: f64,
    /// Keep publishing the last state this long after the replay ends (viewers see how it finished).
    pub linger: Duration,
}

/// Republish `recording` on zenoh as its scene, paced at `speed`, until its last tick (then linger). Calls
/// `progress` about once a second. Returns the replay's comparison with the recording.
pub fn publish(
    recording: &Recording,
    world: World,
    options: &PublishOptions,
    mut progress: impl FnMut(&ReplayProgress, Option<&ServerStats>),
) -> anyhow::Result<ReplayProgress> {
    anyhow::ensure!(
        options.speed.is_finite() && options.speed > 0.0 && options.speed <= MAX_REPLAY_SPEED,
        "--speed must be in (0, {MAX_REPLAY_SPEED}], got {}",
        options.speed
    );
    let scene = world.scene.clone();
    let config = ServerConfig {
        network: NetworkOptions {
            listen: with_udp_twin(&options.endpoint),
            ..NetworkOptions::default()
        },
        server_id: "replay".into(),
        replay: Some(ReplayFeed {
            ticks: recording.ticks.clone(),
            speed: options.speed,
        }),
        ..ServerConfig::default()
    };
    let mut server = ServerNode::start(world, config)
        .with_context(|| format!("starting the replay of scene `{scene}`"))?;
    let mut last_line = Instant::now();
    let finished = loop {
        std::thread::sleep(Duration::from_millis(20));
        if let Some(failure) = server.failure() {
            anyhow::bail!("the replay stopped: {failure}");
        }
        let Some(now) = server.replay_progress() else {
            continue;
        };
        if now.finished {
            break now;
        }
        if last_line.elapsed() >= Duration::from_secs(1) {
            last_line = Instant::now();
            progress(&now, Some(&server.stats()));
        }
    };
    progress(&finished, Some(&server.stats()));
    std::thread::sleep(options.linger);
    server.stop();
    Ok(finished)
}

/// Where the frames of `file` go by default: beside it, `<stem>-frames`.
pub fn default_frames_dir(file: &Path) -> PathBuf {
    let stem = file
        .file_stem()
        .map_or("session".into(), |s| s.to_string_lossy().into_owned());
    file.with_file_name(format!("{stem}-frames"))
}
