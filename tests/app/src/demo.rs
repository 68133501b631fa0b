//! The demo: one server, two simulated surgeons, one viewer, all over zenoh on loopback.
//!
//! Left presses 5 mm into the pad and strokes +-8 mm; right presses 4 mm and holds. One line per second,
//! then a summary: server ticks and tick time, per-device round trip and force, mesh-delta traffic against
//! whole-mesh traffic, and the viewer replica's error against its quantization bound.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use hapticserver::{HapticHandle, HapticReport};
use sinew_server::node::ServerHandle;
use sinew_server::world::load_world;
use sinew_viewer::ViewerHandle;

use crate::loopback::{
    Pacing, SimDeviceSetup, replica_error, start_server_recording, start_sim_device_emulated,
    start_viewer, surgeon_scripts_for,
};
use crate::stitch_script::{STITCH_HAND, StitchLink, stitch_scripts_over};
use sinew_server::tissue::Vec3;
use sinew_server::training::wound_gap_between_mm;

/// Demo options.
#[derive(Debug, Clone)]
pub struct DemoOptions {
    /// World file.
    pub world: PathBuf,
    /// Endpoint the server listens on and the others connect to.
    pub endpoint: String,
    /// How long to run.
    pub duration: Duration,
    /// Open the viewer window (needs a display).
    pub window: bool,
    /// Write a PNG of the viewer's replica at the end.
    pub png: Option<PathBuf>,
    /// Emulated round trip between the devices and the server, ms (half on the poses, half on the forces).
    pub rtt_ms: f64,
    /// How the devices render forces.
    pub mode: hapticserver::ModePolicy,
    /// The simulated operators' hand.
    pub hand: hapticserver::HandPreset,
    /// Record the session into this MCAP file (`sinew replay`, `sinew report` read it).
    pub record: Option<PathBuf>,
    /// Real-time scheduling for the 1 kHz loops, where the process may have it.
    pub realtime: bool,
    /// Threads for the server's tissue passes (`None`: the world's `[sim] threads`, or the machine's share).
    pub tissue_threads: Option<usize>,
}

/// The demo's final figures.
#[derive(Debug, Clone)]
pub struct DemoSummary {
    /// Server ticks run.
    pub ticks: u64,
    /// Tick time p50 / p99, us.
    pub tick_p50_us: f32,
    /// Tick time p99, us.
    pub tick_p99_us: f32,
    /// The one-core bench tick's p99 in the same run, us.
    pub bench_tick_p99_us: f32,
    /// Per device: id, round trip p50 / p99 us, max rendered force N.
    pub devices: Vec<(String, f64, f64, f32)>,
    /// Mesh delta bytes per second.
    pub delta_bytes_per_s: f64,
    /// Viewer replica error and its bound, mm.
    pub replica_error_mm: Option<(f32, f32)>,
}

/// The world has what a stitch needs: a needle driver and a grasper.
fn stitch_tools(world: &sinew_server::world::World) -> bool {
    use sinew_server::world::InstrumentSpec;
    let has = |pick: fn(&InstrumentSpec) -> bool| world.tools.iter().any(|t| pick(&t.instrument));
    has(|i| matches!(i, InstrumentSpec::NeedleDriver(_)))
        && has(|i| matches!(i, InstrumentSpec::Grasper(_)))
}

struct Running {
    server: ServerHandle,
    devices: Vec<HapticHandle>,
    viewer: ViewerHandle,
}

/// Run the demo. Prints as it goes; returns the summary.
pub fn run_demo(options: &DemoOptions) -> anyhow::Result<DemoSummary> {
    let mut world = load_world(&options.world).context("the demo's world")?;
    if let Some(threads) = options.tissue_threads {
        world.tissue_threads = Some(threads);
    }
    let (mut left, mut right) = surgeon_scripts_for(&world);
    let (mut hand, mut duration) = (options.hand, options.duration);
    // A stitched wound's two edges at rest, to say how far the stitch closed it.
    let mut wound_rest: Option<[Vec<Vec3>; 2]> = None;
    // A world with a needle driver and a grasper gets the scripted stitch, its pass rehearsed first.
    if stitch_tools(&world) {
        let started = Instant::now();
        println!(
            "scripted stitch: rehearsing the pass, the hand-off and the draw on virtual time (about a minute of \
             one core) before the live run"
        );
        // Planned over the demo's own link: each stage reaches for where the last left things under its delay.
        let link = StitchLink {
            link: crate::drill::Link::rtt(options.rtt_ms),
            mode: options.mode,
        };
        match stitch_scripts_over(&world, &link) {
            Ok(stitch) => {
                println!(
                    "scripted stitch: rehearsed stage by stage on virtual time in {:.1} s; the grasper takes the \
                     needle's tip at {:.1?} mm, the driver the thread's free end at {:.1?} mm; drawn tight and held \
                     by {:.1} s (hands: {})",
                    started.elapsed().as_secs_f64(),
                    stitch.tip_mm,
                    stitch.free_end_mm,
                    stitch.end_s,
                    STITCH_HAND.name()
                );
                for (id, script) in [stitch.driver, stitch.grasper] {
                    match id.as_str() {
                        "left" => left = script,
                        "right" => right = script,
                        _ => {}
                    }
                }
                hand = STITCH_HAND;
                duration = duration.max(Duration::from_secs_f64(stitch.end_s + 1.0));
                if let [a, b] = &world.objects[..] {
                    let rest = |o: &sinew_server::tissue::ObjectSpec| -> Vec<Vec3> {
                        o.mesh.positions_mm.iter().map(|p| Vec3::from(*p)).collect()
                    };
                    wound_rest = Some([rest(a), rest(b)]);
                }
            }
            Err(e) => println!(
                "no scripted stitch in this world ({e:#}): the needle driver presses as a probe does"
            ),
        }
    }
    let scene = world.scene.clone();
    // The one-core bench tick of this world, in this run: the live tick is read against it.
    let bench_tick = sinew_server::node::tick_cost::press_and_stroke(&world, BENCH_TICKS)
        .context("timing the bench tick")?;
    println!(
        "bench tick (one core, no network, two tools pressing and stroking, {BENCH_TICKS} ticks): p50 {:.0} us, p99 {:.0} us",
        bench_tick.percentile_us(50.0),
        bench_tick.percentile_us(99.0)
    );
    let pacing = if options.realtime {
        Pacing::Realtime
    } else {
        Pacing::Spin
    };
    let one_way = sinew_protocol::rt::EmulationConfig {
        delay_ms: options.rtt_ms / 2.0,
        ..Default::default()
    };
    one_way.validate().map_err(anyhow::Error::msg)?;
    let server = start_server_recording(
        world,
        &options.endpoint,
        pacing,
        one_way,
        options.record.clone(),
    )?;
    let device = |id: &str, script| {
        start_sim_device_emulated(
            &scene,
            id,
            script,
            &options.endpoint,
            pacing,
            SimDeviceSetup {
                mode: options.mode,
                emulation: one_way,
                hand,
                phase_align: true,
            },
        )
    };
    let devices = vec![device("left", left)?, device("right", right)?];
    let viewer = start_viewer(&scene, "demo-viewer", &options.endpoint)?;
    if !viewer.wait_for_snapshot(Duration::from_secs(5)) {
        anyhow::bail!("the viewer got no snapshot from the server within 5 s");
    }
    println!(
        "sinew demo: scene `{scene}` on {} (zenoh peer, loopback), devices left + right (mode {}, hand {}, emulated round trip {} ms), viewer headless{}",
        options.endpoint,
        options.mode.name(),
        hand.name(),
        options.rtt_ms,
        if options.window { " + window" } else { "" }
    );
    let mut running = Running {
        server,
        devices,
        viewer,
    };
    if options.window {
        run_with_window(&running, duration)?;
    } else {
        live_lines(&running, duration);
    }
    let summary = summarize(&running, &bench_tick);
    if let Some([a_rest, b_rest]) = &wound_rest {
        let now = |o| -> Vec<Vec3> {
            running
                .server
                .latest_positions(o)
                .unwrap_or_default()
                .into_iter()
                .map(Vec3::from)
                .collect()
        };
        let (a_now, b_now) = (now(0), now(1));
        let gap = |a: &[Vec3], b: &[Vec3]| wound_gap_between_mm((a_rest, a), (b_rest, b));
        match (gap(a_rest, b_rest), gap(&a_now, &b_now)) {
            (Some(before), Some(after)) => {
                println!("stitch: the wound's gap {before:.2} mm at rest, {after:.2} mm now")
            }
            _ => println!("stitch: the wound's gap could not be measured"),
        }
    }
    if let Some(path) = &options.png {
        let replica = running.viewer.replica();
        let overlay = sinew_viewer::InstructorOverlay::build(
            &replica,
            running.viewer.server_stats().as_ref(),
        );
        let stats =
            sinew_viewer::render_png_with_overlay(&replica, Some(&overlay), path, 1024, 768)
                .with_context(|| format!("rendering {}", path.display()))?;
        println!(
            "viewer replica rendered to {} ({:.0} ms)",
            path.display(),
            stats.render_ms
        );
    }
    for device in &mut running.devices {
        device.stop().context("stopping a hapticserver")?;
    }
    running.viewer.stop();
    running.server.stop();
    if let Some(record) = running.server.record_summary() {
        match &record.error {
            None => println!(
                "recorded {} ticks ({} dropped) into {}: `sinew replay` or `sinew report` it",
                record.ticks,
                record.dropped,
                record.path.display()
            ),
            Some(error) => println!("the recording stopped early: {error}"),
        }
    }
    Ok(summary)
}

fn run_with_window(running: &Running, duration: Duration) -> anyhow::Result<()> {
    let server = &running.server;
    let devices = &running.devices;
    let viewer = &running.viewer;
    let stop = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        let printer = scope.spawn(|| {
            let start = Instant::now();
            while !stop.load(std::sync::atomic::Ordering::Acquire) && start.elapsed() < duration {
                std::thread::sleep(Duration::from_secs(1));
                print_line(server, devices, viewer, start.elapsed());
            }
        });
        let start = Instant::now();
        let result = sinew_viewer::run_window_until(viewer, "Sinew demo", 1280, 800, &|| {
            start.elapsed() >= duration
        });
        stop.store(true, std::sync::atomic::Ordering::Release);
        let _ = printer.join();
        result.context("viewer window")
    })
}

fn live_lines(running: &Running, duration: Duration) {
    let start = Instant::now();
    let mut next = Duration::from_secs(1);
    while start.elapsed() < duration {
        std::thread::sleep(
            next.saturating_sub(start.elapsed())
                .min(Duration::from_millis(100)),
        );
        if start.elapsed() >= next {
            print_line(
                &running.server,
                &running.devices,
                &running.viewer,
                start.elapsed(),
            );
            next += Duration::from_secs(1);
        }
    }
}

fn device_text(report: &HapticReport) -> String {
    let f = report.last_rendered_force_n;
    format!(
        "{} rtt {:.0}/{:.0} us F ({:+.2} {:+.2} {:+.2}) N",
        report.device_id,
        report.round_trip.percentile_ns(50.0) as f64 / 1000.0,
        report.round_trip.percentile_ns(99.0) as f64 / 1000.0,
        f[0],
        f[1],
        f[2]
    )
}

fn print_line(
    server: &ServerHandle,
    devices: &[HapticHandle],
    viewer: &ViewerHandle,
    elapsed: Duration,
) {
    let s = server.stats();
    let v = viewer.stats();
    let devices: Vec<String> = devices.iter().map(|d| device_text(&d.report())).collect();
    println!(
        "t {:4.1} s | server ticks {:6} tick p50 {:3.0} p99 {:3.0} us | {} | deltas {} ({:.0} kB/s at viewer, {:.0} frames/s)",
        elapsed.as_secs_f64(),
        s.ticks,
        s.tick_p50_us,
        s.tick_p99_us,
        devices.join(" | "),
        s.deltas_sent,
        v.bytes_per_s / 1000.0,
        v.frames_per_s
    );
}

/// Ticks of the bench run before the live system.
const BENCH_TICKS: usize = 3000;

fn summarize(running: &Running, bench_tick: &sinew_protocol::rt::LatencyHistogram) -> DemoSummary {
    let s = running.server.stats();
    let replica = replica_error(&running.server, &running.viewer, 0, Duration::from_secs(2));
    let devices: Vec<(String, f64, f64, f32)> = running
        .devices
        .iter()
        .map(|d| {
            let r = d.report();
            (
                r.device_id.clone(),
                r.round_trip.percentile_ns(50.0) as f64 / 1000.0,
                r.round_trip.percentile_ns(99.0) as f64 / 1000.0,
                r.max_rendered_force_n,
            )
        })
        .collect();
    let delta_bytes_per_s = s.delta_bytes_sent as f64 / s.sim_time_s.max(1e-9);
    let full_mesh_bytes_per_s = running
        .server
        .published_positions(0)
        .map_or(0.0, |(_, p)| (p.len() * 6) as f64 * 60.0);
    println!("---- summary ----");
    println!(
        "server: {} ticks, tick p50 {:.0} us, p99 {:.0} us, max {:.0} us, overruns {}, sim faults {}, rejected inputs {}",
        s.ticks,
        s.tick_p50_us,
        s.tick_p99_us,
        s.tick_max_us,
        s.overruns,
        s.sim_faults,
        s.rejected.total()
    );
    let bench_p99 = bench_tick.percentile_us(99.0);
    println!(
        "live tick against the bench tick of this run: p50 {:.2}x, p99 {:.2}x (bench p50 {:.0} us, p99 {:.0} us); sim thread: {}; {}",
        s.tick_p50_us / bench_tick.percentile_us(50.0).max(1e-3),
        s.tick_p99_us / bench_p99.max(1e-3),
        bench_tick.percentile_us(50.0),
        bench_p99,
        running
            .server
            .realtime()
            .map_or_else(|| "not started".to_owned(), ToString::to_string),
        running.server.tissue_threads(),
    );
    if let Some(grant) = running.devices.first().and_then(|d| d.report().realtime) {
        println!("device loops: {grant}");
    }
    for ((id, p50, p99, max_force), device) in devices.iter().zip(&running.devices) {
        let report = device.report();
        let server_side = s.devices.iter().find(|d| &d.device_id == id);
        println!(
            "device {id}: mode {} ({}, {} switches); pose->force round trip p50 {p50:.0} us, p99 {p99:.0} us; \
             {:.0} force messages/s ({} suppressed by the deadband); max rendered force {max_force:.2} N; \
             silences {}; port energy {:+.2} mJ (passivity: active on {} of {} ticks, withheld {:.2} mJ); \
             {}; last second: F {:.2} N, peak-to-peak {:.4} N, stylus speed RMS {:.2} mm/s -> {}",
            if report.moderated {
                "moderated"
            } else {
                "direct"
            },
            report.mode_policy,
            report.mode_switches,
            server_side.map_or(0.0, |d| d.forces_sent as f64 / s.sim_time_s.max(1e-9)),
            server_side.map_or(0, |d| d.forces_suppressed),
            report.safety.stale_events,
            report.passivity.energy_mj,
            report.passivity.active_ticks,
            report.ticks,
            report.passivity.withheld_mj,
            if report.safety.clamped == 0 {
                "the clamp was never reached".to_owned()
            } else {
                format!("the clamp was reached on {} ticks", report.safety.clamped)
            },
            report.last_second.mean_force_n,
            report.last_second.force_p2p_n,
            report.last_second.speed_rms_mm_s,
            if report.last_second.still() {
                "still (p2p < 0.05 N, speed < 1 mm/s)"
            } else {
                "moving or unstable"
            }
        );
    }
    let v = running.viewer.stats();
    println!(
        "mesh deltas: {} sent, {:.1} kB/s (whole mesh at 60 Hz would be {:.1} kB/s), {} quantization clamps; viewer: {} snapshots, {} deltas applied, {} gaps",
        s.deltas_sent,
        delta_bytes_per_s / 1000.0,
        full_mesh_bytes_per_s / 1000.0,
        s.quantization_clamps,
        v.snapshots_fetched,
        v.deltas_applied,
        v.gaps
    );
    if let Some(report) = running.server.sim_report() {
        for (id, d) in devices.iter().map(|d| &d.0).zip(&report.devices) {
            let t = d.training;
            println!(
                "training, {id}: now {}, {} touches for {:.1} s, tip path {:.0} mm, peak force {:.2} N, harm {:.3} N s",
                t.state.name(),
                t.contacts,
                t.contact_time_s,
                t.path_length_mm,
                t.peak_force_n,
                t.harm_n_s
            );
        }
        if let Some(e) = report.exercise {
            println!(
                "exercise: score {:.0}/100, {} of {}{}, errors {} (wrong tool {}, off target {}, too deep {}), {:.1} s",
                e.score,
                e.hits,
                e.total,
                if e.completed { ", completed" } else { "" },
                e.errors.total(),
                e.errors.wrong_tool,
                e.errors.off_target,
                e.errors.too_deep,
                e.time_s
            );
        }
    }
    match replica {
        Some(e) => println!(
            "viewer replica error: {:.4} mm at frame {} (bound {:.4} mm: the server's delta tolerance)",
            e.max_error_mm, e.frame, e.bound_mm
        ),
        None => println!(
            "viewer replica error: not measured (viewer never caught up with the server's frame)"
        ),
    }
    DemoSummary {
        ticks: s.ticks,
        tick_p50_us: s.tick_p50_us,
        tick_p99_us: s.tick_p99_us,
        bench_tick_p99_us: bench_p99,
        devices,
        delta_bytes_per_s,
        replica_error_mm: replica.map(|e| (e.max_error_mm, e.bound_mm)),
    }
}
