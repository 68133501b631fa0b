//! What the suture thread costs the server tick, on worlds/suture_block.toml (the skin block, a needle driver with its
//! thread, a grasper), one core, no network. Two sims of the same world run the same script tick by tick,
//! interleaved, one as shipped and one whose needle carries no thread (`thread_length_mm = 0`): the difference
//! is the thread's share of the tick. In both the grasper presses the skin 1.5 mm and strokes +-4 mm (the
//! tissue is touched and stepped as in any probing tick). Phases, each the same number of ticks:
//! - air: the needle driver held 60 mm up beside the block, the thread hanging free past its side;
//! - skin: the needle driver circling 10 mm round over the block's middle at 0.5 Hz, 30 mm up, the thread lying
//!   on the skin and dragged over it (most of it hangs down a side).
//!
//! Figures are ratios to the threadless sim of the same run, so they travel between machines; the thread's
//! segment steps per tick (segments times its substeps) give its cost per segment step.
//!
//! Run: `cargo bench -p sinew-server --bench suture` (add `-- --ticks N` to change the count per phase).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Instant;

use nalgebra::{UnitQuaternion, Vector3};
use sinew_protocol::rt::LatencyHistogram;
use sinew_server::interaction::suture::ThreadSpec;
use sinew_server::sim::{Sim, ToolOutput};
use sinew_server::world::{InstrumentSpec, load_world};

#[path = "support/bench_args.rs"]
mod bench_args;
#[path = "../tests/common/tool_pose.rs"]
mod tool_pose;

use tool_pose::pose_command;

/// The thread's substeps per tick (`interaction/suture/thread.rs`).
const THREAD_SUBSTEPS: usize = 4;

fn main() {
    let ticks = bench_args::count_arg("ticks", 10_000).expect("--ticks takes a count");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/suture_block.toml");
    let world = load_world(&path).unwrap();
    let mut bare = load_world(&path).unwrap();
    let InstrumentSpec::NeedleDriver(mut spec) = bare.tools[0].instrument else {
        panic!("tool 0 of the suture block is not a needle driver");
    };
    let segments = usize::from(spec.thread.segments);
    spec.thread = ThreadSpec::NONE;
    bare.tools[0].instrument = InstrumentSpec::NeedleDriver(spec);
    let origins = [
        Vector3::from(world.tools[0].device_origin_in_world_mm),
        Vector3::from(world.tools[1].device_origin_in_world_mm),
    ];
    let mut sims = [Sim::new(&world).unwrap(), Sim::new(&bare).unwrap()];
    assert!(sims[0].tools[0].thread().is_some() && sims[1].tools[0].thread().is_none());
    let level = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2);
    let upright = UnitQuaternion::identity();
    let dt_s = 0.001f32;
    println!(
        "suture thread bench: {ticks} ticks per phase, {segments} segments x {THREAD_SUBSTEPS} substeps = {} segment steps a tick",
        segments * THREAD_SUBSTEPS
    );
    println!(
        "| phase | no thread p50 / p99 | thread p50 / p99 | ratio p50 / p99 | thread's cost at p50, per segment step |"
    );
    println!("|---|---|---|---|---|");
    let mut k = 0usize;
    for phase in ["air", "skin"] {
        let mut histograms = [LatencyHistogram::new(), LatencyHistogram::new()];
        // A settling second first, untimed.
        for step in 0..ticks + 1000 {
            let t = k as f32 * dt_s;
            k += 1;
            let needle = match phase {
                "air" => Vector3::new(-60.0, 0.0, 60.0),
                _ => {
                    let a = std::f32::consts::PI * t;
                    Vector3::new(10.0 * a.cos(), 10.0 * a.sin(), 30.0)
                }
            };
            // The grasper's capsule (3 mm half length, 1.5 mm radius, upright): its bottom 1.5 mm into the skin.
            let stroke = 4.0 * (std::f32::consts::TAU * 0.5 * t).sin();
            let grasper = Vector3::new(10.0 + stroke, 0.0, 3.0);
            let commands = [
                pose_command(&needle, &origins[0], &level),
                pose_command(&grasper, &origins[1], &upright),
            ];
            for (sim, histogram) in sims.iter_mut().zip(&mut histograms) {
                let mut outputs = [ToolOutput::default(); 2];
                let start = Instant::now();
                sim.step(dt_s, &commands, &mut outputs);
                sim.finish_tick();
                if step >= 1000 {
                    histogram.record(start.elapsed());
                }
            }
        }
        let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
        let [with, without] = &histograms;
        let cost_ns =
            (with.percentile_ns(50.0) as f64 - without.percentile_ns(50.0) as f64).max(0.0);
        println!(
            "| {phase} | {:.0} / {:.0} us | {:.0} / {:.0} us | x{:.2} / x{:.2} | {:.0} us, {:.0} ns |",
            us(without, 50.0),
            us(without, 99.0),
            us(with, 50.0),
            us(with, 99.0),
            us(with, 50.0) / us(without, 50.0),
            us(with, 99.0) / us(without, 99.0),
            cost_ns / 1000.0,
            cost_ns / (segments * THREAD_SUBSTEPS) as f64,
        );
        let thread = sims[0].tools[0].thread().unwrap();
        println!(
            "  (end of the {phase} phase: {} nodes resting on the skin, length {:.2} mm)",
            thread.resting_nodes(),
            thread.chain().length_mm()
        );
    }
}
