//! The server tick during a stitch, beside the probe-only pad tick in the same run (issue 32's measure), one
//! core, no network, virtual time. The stitch is the wound of `worlds/suture.toml` as its tests drive it
//! (`tests/common/wound.rs`): the needle turned through both edges and the grasper's take of the thread
//! (untimed), then both ends drawn crossed by hands that stop drawing at 3 N, timed in two phases:
//! - drawing (its first 3 s): the thread sliding through its four holes (the chain's 4x4 blocks), the edges
//!   coming together;
//! - tight (the next 3 s): the tension held at 3 N, the edges touching (tissue-tissue contact watched).
//!
//! Each stitch tick is interleaved with one tick of `worlds/pad.toml` under the tick bench's workload (two
//! probes pressing 5 mm and stroking), so the ratio travels between machines.
//!
//! Run: `cargo bench -p sinew-server --bench stitch`.
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Instant;

use sinew_protocol::rt::LatencyHistogram;
use sinew_server::node::tick_cost::press_and_stroke_commands;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

#[path = "../tests/common/tool_pose.rs"]
mod tool_pose;
#[path = "../tests/common/wound.rs"]
mod wound;

use wound::{CrossedDraw, DT_S};

/// The thread's substeps per tick (`interaction/suture/thread.rs`).
const THREAD_SUBSTEPS: usize = 4;
/// Ticks per phase.
const PHASE_TICKS: usize = 3000;

fn main() {
    let (mut wound, _, mut draw) = CrossedDraw::after_the_pass(3.0);
    // The tick alone: the training layer's watch is not the server's.
    wound.observer = None;

    let pad_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let mut pad = Sim::new(&load_world(&pad_path).unwrap()).unwrap();
    let mut pad_commands = vec![ToolCommand::default(); pad.tools.len()];
    let mut pad_outputs = vec![ToolOutput::default(); pad.tools.len()];
    // The pad's probes pressed in first, untimed.
    let mut pad_tick = 0usize;
    for _ in 0..1000 {
        press_and_stroke_commands(pad_tick as f32 * DT_S, &mut pad_commands);
        pad.step(DT_S, &pad_commands, &mut pad_outputs);
        pad_tick += 1;
    }
    let segments = wound.thread().chain().node_u_mm().len() - 1;
    println!(
        "stitch bench: {PHASE_TICKS} ticks a phase; the thread {segments} segments x {THREAD_SUBSTEPS} substeps = {} segment steps a tick, through {} holes and {} track rings",
        segments * THREAD_SUBSTEPS,
        wound.thread().holes().len(),
        wound.thread().tracks().len()
    );
    println!(
        "| phase | pad (two probes) p50 / p99 | stitch p50 / p99 | ratio p50 / p99 | pull felt at the end | gap at the end | node-face contacts watched a tick |"
    );
    println!("|---|---|---|---|---|---|---|");
    for phase in ["drawing", "tight"] {
        let mut histograms = [LatencyHistogram::new(), LatencyHistogram::new()];
        let mut contacts = 0u64;
        for _ in 0..PHASE_TICKS {
            let start = Instant::now();
            let (_, report) = draw.step(&mut wound);
            wound.sim.finish_tick();
            histograms[1].record(start.elapsed());
            contacts += u64::from(report.tissue_contacts);

            press_and_stroke_commands(pad_tick as f32 * DT_S, &mut pad_commands);
            pad_tick += 1;
            let start = Instant::now();
            pad.step(DT_S, &pad_commands, &mut pad_outputs);
            pad.finish_tick();
            histograms[0].record(start.elapsed());
        }
        let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
        let [probe, stitch] = &histograms;
        println!(
            "| {phase} | {:.0} / {:.0} us | {:.0} / {:.0} us | x{:.2} / x{:.2} | {:.2} and {:.2} N | {:.2} mm | {:.0} |",
            us(probe, 50.0),
            us(probe, 99.0),
            us(stitch, 50.0),
            us(stitch, 99.0),
            us(stitch, 50.0) / us(probe, 50.0),
            us(stitch, 99.0) / us(probe, 99.0),
            draw.felt[0],
            draw.felt[1],
            wound.gap_mm(),
            contacts as f64 / PHASE_TICKS as f64,
        );
    }
}
