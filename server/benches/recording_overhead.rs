//! What recording costs the tick: two server ticks on worlds/pad.toml, each with both probes pressing and
//! stroking (the demo's load, every device rendering directly so every tick carries two commands), paced at
//! 1 kHz like the sim thread, alternating in blocks of 500 ticks; one hands every tick to a live recorder
//! (`Recorder`, its writer thread compressing into an MCAP file), the other does not. Reports tick p50/p99
//! of each in the same run, their ratio, the ticks the queue dropped and the file's size.
//!
//! Run: `cargo bench -p sinew-server --bench recording_overhead` (add `-- --seconds N`, default 10 per side).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::{Duration, Instant};

use sinew_protocol::rt::LatencyHistogram;
use sinew_protocol::{DevicePose, RenderMode};
use sinew_server::recording::{FinalState, Recorder, TickRecord};
use sinew_server::server_tick::DeadbandParams;
use sinew_server::server_tick::{PoseInput, ServerTick};
use sinew_server::sim::Sim;
use sinew_server::world::{World, load_world};

const BLOCK: u64 = 500;

struct Side {
    tick: ServerTick,
    k: u64,
    out: [Option<sinew_protocol::ForceCommand>; 2],
    time: LatencyHistogram,
}

impl Side {
    fn new(world: &World) -> Self {
        Self {
            tick: ServerTick::new(
                Sim::new(world).unwrap(),
                (1.0 / world.tick_hz) as f32,
                world.pose_timeout_s,
                DeadbandParams::default(),
            ),
            k: 0,
            out: [None; 2],
            time: LatencyHistogram::new(),
        }
    }
}

/// Both probes press 5 mm and stroke +-8 mm along x with a 2 s period (after a 0.5 s descent).
fn poses(k: u64) -> [Option<PoseInput>; 2] {
    let t = k as f32 * 0.001;
    let depth = (t / 0.5).min(1.0) * 5.0;
    let stroke = if t > 0.5 {
        8.0 * (std::f32::consts::TAU * (t - 0.5) / 2.0).sin()
    } else {
        0.0
    };
    let pose = |x: f32, y: f32| {
        Some(PoseInput {
            pose: DevicePose {
                seq: k + 1,
                position_mm: [x, y, 4.0 - depth],
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                render_mode: RenderMode::Direct,
                ..DevicePose::default()
            },
            age_s: 0.0005,
            usable: true,
        })
    };
    [pose(stroke, 0.0), pose(-stroke, 5.0)]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seconds: f64 = args
        .iter()
        .position(|a| a == "--seconds")
        .and_then(|i| args.get(i + 1))
        .map_or(Ok(10.0), |s| s.parse())?;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let world = load_world(&path)?;
    let file = std::env::temp_dir().join(format!("sinew-overhead-{}.mcap", std::process::id()));
    let (recorder, mut tap) = Recorder::start(&file, &world)?;
    let mut plain = Side::new(&world);
    let mut recorded = Side::new(&world);
    let limits = [None, None];
    let ticks_per_side = (seconds * 1000.0) as u64;
    let period = Duration::from_millis(1);
    let mut next = Instant::now();
    while recorded.k < ticks_per_side {
        for with_recording in [false, true] {
            let side = if with_recording {
                &mut recorded
            } else {
                &mut plain
            };
            for _ in 0..BLOCK {
                let inputs = poses(side.k);
                let start = Instant::now();
                side.tick.step(&inputs, &limits, &mut side.out);
                if with_recording {
                    tap.offer(&TickRecord::new(side.k, &inputs, &limits, &side.out));
                }
                side.time.record(start.elapsed());
                side.k += 1;
                next += period;
                let now = Instant::now();
                if next > now {
                    std::thread::sleep(next - now);
                } else {
                    next = now;
                }
            }
        }
    }
    let dropped = recorder.dropped();
    let positions_mm = (0..recorded.tick.sim().objects.len())
        .map(|o| {
            recorded
                .tick
                .positions_mm(o)
                .unwrap_or_default()
                .iter()
                .map(|p| [p.x, p.y, p.z])
                .collect()
        })
        .collect();
    tap.finish(FinalState {
        ticks: recorded.k,
        positions_mm,
    });
    let summary = recorder.join();
    let size = std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0);
    let _ = std::fs::remove_file(&file);
    let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
    println!(
        "tick without recording: p50 {:.0} us p99 {:.0} us max {:.0} us ({} ticks)",
        us(&plain.time, 50.0),
        us(&plain.time, 99.0),
        plain.time.max_ns() as f64 / 1000.0,
        plain.k
    );
    println!(
        "tick with recording:    p50 {:.0} us p99 {:.0} us max {:.0} us ({} ticks)",
        us(&recorded.time, 50.0),
        us(&recorded.time, 99.0),
        recorded.time.max_ns() as f64 / 1000.0,
        recorded.k
    );
    println!(
        "ratio with/without: p50 {:.3}, p99 {:.3}; recorder wrote {} ticks, dropped {dropped}, {:.1} MB/min ({} bytes){}",
        us(&recorded.time, 50.0) / us(&plain.time, 50.0).max(1e-9),
        us(&recorded.time, 99.0) / us(&plain.time, 99.0).max(1e-9),
        summary.ticks,
        size as f64 / 1e6 / (recorded.k as f64 / 60_000.0),
        size,
        summary
            .error
            .map_or(String::new(), |e| format!("; error: {e}"))
    );
    Ok(())
}
