//! The real-time contract of the sim thread's whole tick, beyond `Sim::step`: `ServerTick::step` (the model
//! streams and their deadband, for one device rendering directly and one rendering the local model), the
//! recorder hand-off (`TickRecord::new` + `RecorderTap::offer`) and the frame hand-off to the publisher
//! (`FrameExchange::try_offer`) allocate nothing on the sim thread once warm. Counted on the calling thread
//! alone: the recorder's writer thread allocates by design, off the tick.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;
#[path = "common/counting_allocator.rs"]
mod counting_allocator;

use counting_allocator::{Counting, assert_counting_works, count_this_thread};
use sinew_protocol::{ForceCommand, RenderMode};
use sinew_server::recording::{Recorder, TickRecord};
use sinew_server::replication::FrameExchange;
use sinew_server::server_tick::PoseInput;
use sinew_server::world::load_world;

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Tick `k`'s poses: left presses and strokes rendering directly, right presses and holds rendering the local
/// model (so its stream sends on change and on the heartbeat).
fn poses(k: u64) -> [Option<PoseInput>; 2] {
    let t = k as f32 * 0.001;
    let depth = (t / 0.3).min(1.0) * 4.0;
    let stroke = 6.0 * (std::f32::consts::TAU * t).sin();
    let pose = |x: f32, y: f32, mode| {
        let mut input = common::pose_at(k + 1, [x, y, 4.0 - depth]).unwrap();
        input.pose.render_mode = mode;
        input.pose.device_time_ns = k * 1_000_000;
        Some(input)
    };
    [
        pose(stroke, 0.0, RenderMode::Direct),
        pose(0.0, 4.0, RenderMode::Moderated),
    ]
}

#[test]
fn the_sim_threads_whole_tick_allocates_nothing_once_warm() {
    assert_counting_works();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let world = load_world(&path).unwrap();
    let mut tick = common::server_tick(&world);
    let frames = FrameExchange::new(tick.sim());
    let dir = common::scratch_dir("sinew-no-alloc-tick");
    let (recorder, mut tap) = Recorder::start(&dir.join("session.mcap"), &world).unwrap();
    let limits = [Some(3.3f32), None];
    let mut commands: [Option<ForceCommand>; 2] = [None; 2];
    let (mut sent, mut frames_offered) = (0u64, 0u64);
    let mut run = |ticks: std::ops::Range<u64>, sent: &mut u64, frames_offered: &mut u64| {
        for k in ticks {
            let inputs = poses(k);
            tick.step(&inputs, &limits, &mut commands);
            *sent += commands.iter().flatten().count() as u64;
            tap.offer(&TickRecord::new(k, &inputs, &limits, &commands));
            if k % 16 == 0 && frames.try_offer(tick.sim(), tick.outputs()) {
                *frames_offered += 1;
            }
            tick.finish_tick();
        }
    };
    run(0..800, &mut sent, &mut frames_offered);
    let (warm_sent, warm_frames) = (sent, frames_offered);
    let allocations = count_this_thread(|| run(800..2800, &mut sent, &mut frames_offered));
    let (sent, frames_offered) = (sent - warm_sent, frames_offered - warm_frames);
    println!(
        "sim thread: {allocations} allocations in 2000 warm ticks ({sent} force commands, {frames_offered} frames offered)"
    );
    // What the counted ticks really did: both streams sent (direct every tick, moderated on change and at least
    // on the 7 ms heartbeat), and frames went to the publisher.
    assert!(sent >= 2000 + 2000 / 7, "{sent} commands in 2000 ticks");
    assert!(frames_offered > 100, "{frames_offered} frames offered");
    assert_eq!(allocations, 0, "the sim thread allocated in a warm tick");
    drop(tap);
    let summary = recorder.join();
    assert!(summary.ticks > 0, "the recorder wrote no tick");
}

/// The frame hand-off copies a suture thread's polyline too (wire v14) without allocating once warm:
/// `worlds/suture_block.toml`'s needle driver held above the skin, its thread laid out and hanging.
#[test]
fn handing_off_a_frame_with_a_thread_and_its_needle_allocates_nothing_once_warm() {
    assert_counting_works();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/suture_block.toml");
    let world = load_world(&path).unwrap();
    let mut tick = common::server_tick(&world);
    let frames = FrameExchange::new(tick.sim());
    let limits = [Some(3.3f32), Some(3.3)];
    let mut commands: [Option<ForceCommand>; 2] = [None; 2];
    let mut frames_offered = 0u64;
    let mut run = |ticks: std::ops::Range<u64>, frames_offered: &mut u64| {
        for k in ticks {
            let inputs = [common::pose_at(k + 1, [0.0, 0.0, 20.0]), None];
            tick.step(&inputs, &limits, &mut commands);
            if k % 16 == 0 && frames.try_offer(tick.sim(), tick.outputs()) {
                *frames_offered += 1;
            }
            tick.finish_tick();
        }
    };
    run(0..200, &mut frames_offered);
    let warm = frames_offered;
    let allocations = count_this_thread(|| run(200..1200, &mut frames_offered));
    let nodes = frames.with_frame(|f| {
        f.threads
            .iter()
            .map(|t| t.nodes_q.len())
            .collect::<Vec<_>>()
    });
    let needles = frames.with_frame(|f| f.needles.len());
    println!(
        "{allocations} allocations in 1000 warm ticks ({} frames offered), threads' nodes {nodes:?}",
        frames_offered - warm
    );
    assert_eq!(nodes, Some(vec![65]), "the frame does not hold the thread");
    assert_eq!(
        needles,
        Some(1),
        "the frame does not say where the needle lies"
    );
    assert!(
        frames_offered - warm > 50,
        "{} frames offered",
        frames_offered - warm
    );
    assert_eq!(allocations, 0, "the sim thread allocated in a warm tick");
}
