//! What a loose needle lying on the skin costs the server tick (`interaction/suture/needle_fall.rs`), on
//! worlds/suture_block.toml without its thread, one core, no network. Two sims of the same world run the same
//! script tick by tick, interleaved: in one the driver has let its needle go over the block's middle and it
//! lies on the skin (the fall's tick runs every tick: each of its 17 masses meets the skin and the tools); in
//! the other the driver holds its needle 30 mm over the block. In both the grasper presses the skin 1.5 mm and
//! strokes +-4 mm (the tissue is touched and stepped as in any probing tick), and the driver stays 60 mm up.
//! The difference is the loose needle's share of the tick.
//!
//! Figures are ratios to the held needle's sim of the same run, so they travel between machines.
//!
//! Run: `cargo bench -p sinew-server --bench needle_fall` (add `-- --ticks N` to change the count).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Instant;

use nalgebra::{UnitQuaternion, Vector3};
use sinew_protocol::rt::LatencyHistogram;
use sinew_server::interaction::JawInput;
use sinew_server::interaction::suture::{NeedleHolder, ThreadSpec};
use sinew_server::sim::{Sim, ToolOutput};
use sinew_server::world::{InstrumentSpec, load_world};

#[path = "support/bench_args.rs"]
mod bench_args;
#[path = "../tests/common/tool_pose.rs"]
mod tool_pose;

use tool_pose::pose_command;

fn main() {
    let ticks = bench_args::count_arg("ticks", 10_000).expect("--ticks takes a count");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/suture_block.toml");
    let mut world = load_world(&path).unwrap();
    let InstrumentSpec::NeedleDriver(mut spec) = world.tools[0].instrument else {
        panic!("tool 0 of the suture block is not a needle driver");
    };
    spec.thread = ThreadSpec::NONE;
    world.tools[0].instrument = InstrumentSpec::NeedleDriver(spec);
    let origins = [
        Vector3::from(world.tools[0].device_origin_in_world_mm),
        Vector3::from(world.tools[1].device_origin_in_world_mm),
    ];
    let mut sims = [Sim::new(&world).unwrap(), Sim::new(&world).unwrap()];
    let level = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2);
    let upright = UnitQuaternion::identity();
    let dt_s = 0.001f32;
    let (over, up) = (Vector3::new(0.0, 0.0, 30.0), Vector3::new(0.0, 0.0, 60.0));
    // Setting up, untimed: the driver to 30 mm over the block (4 s), the first sim's opens its jaws there and
    // goes up to 60 mm (the second's goes up holding its needle), and the needle falls and settles (2 s).
    for k in 0..6000 {
        for (s, sim) in sims.iter_mut().enumerate() {
            let letting_go = s == 0 && k >= 4000;
            let at = if k < 4200 { over } else { up };
            let mut driver = pose_command(&at, &origins[0], &level);
            driver.jaws = JawInput {
                buttons: u32::from(letting_go),
                jaw_angle_rad: 0.0,
            };
            let grasper = pose_command(&Vector3::new(10.0, 0.0, 3.0), &origins[1], &upright);
            sim.step(dt_s, &[driver, grasper], &mut [ToolOutput::default(); 2]);
            sim.finish_tick();
        }
    }
    let hold = |sim: &Sim| *sim.tools[0].needle_hold().unwrap().holder();
    assert_eq!(
        hold(&sims[0]),
        NeedleHolder::Loose,
        "the needle was not let go"
    );
    assert!(matches!(hold(&sims[1]), NeedleHolder::Driver { .. }));
    let lowest = |sim: &Sim| {
        let pose = *sim.tools[0].needle_hold().unwrap().world_from_needle();
        let arc = *sim.tools[0].needle().unwrap().arc();
        (0..=16)
            .map(|k| {
                (pose * nalgebra::Point3::from(arc.at(arc.sweep_rad() * k as f32 / 16.0).point_mm))
                    .z
            })
            .fold(f32::INFINITY, f32::min)
    };
    let lying_z = lowest(&sims[0]);
    assert!(
        lying_z.abs() < 1.0,
        "the needle is not lying on the skin: {lying_z} mm up"
    );
    let mut histograms = [LatencyHistogram::new(), LatencyHistogram::new()];
    for k in 0..ticks {
        let t = k as f32 * dt_s;
        let stroke = 4.0 * (std::f32::consts::TAU * 0.5 * t).sin();
        let grasper = Vector3::new(10.0 + stroke, 0.0, 3.0);
        for (s, (sim, histogram)) in sims.iter_mut().zip(&mut histograms).enumerate() {
            let mut driver = pose_command(&up, &origins[0], &level);
            driver.jaws = JawInput {
                buttons: u32::from(s == 0),
                jaw_angle_rad: 0.0,
            };
            let commands = [driver, pose_command(&grasper, &origins[1], &upright)];
            let mut outputs = [ToolOutput::default(); 2];
            let start = Instant::now();
            sim.step(dt_s, &commands, &mut outputs);
            sim.finish_tick();
            histogram.record(start.elapsed());
        }
    }
    let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
    let [loose, held] = &histograms;
    println!(
        "needle fall bench: {ticks} ticks, the loose needle's lowest point {lying_z:.3} mm over the skin's top"
    );
    println!("| needle | p50 | p99 | x the held needle's p50 / p99 |");
    println!("|---|---|---|---|");
    println!(
        "| held 30 mm up (baseline) | {:.1} us | {:.1} us | 1 / 1 |",
        us(held, 50.0),
        us(held, 99.0)
    );
    println!(
        "| loose, lying on the skin | {:.1} us | {:.1} us | x{:.3} / x{:.3} |",
        us(loose, 50.0),
        us(loose, 99.0),
        us(loose, 50.0) / us(held, 50.0),
        us(loose, 99.0) / us(held, 99.0)
    );
}
