//! What instruments cost the server tick, on worlds/grasp_pull.toml (the pad and two graspers), one core, no
//! network. The same sim runs two phases and each is timed over the same number of ticks:
//! - probe: both tools press 1.5 mm and stroke +-4 mm along x with their jaws open (they act as probes);
//! - grasp: both tools press, close their jaws on the sheet, pull it 3 mm up and back (1 s period), open, and
//!   do it again every 2 s; the ticks that take hold (the closing edge) are also reported on their own;
//! - cautery (worlds/cautery.toml): one tip 0.5 mm in, stroking +-8 mm, current off and then on;
//! - cut (worlds/cut_under_tension.toml): the scalpel drawn +-25 mm along y at 20 mm/s, first with its edge above the sheet,
//!   then through it, each pass on a fresh line 3 mm further along x; the ticks that open the mesh are also
//!   reported on their own, and the mesh deltas a viewer would get (one per 60 Hz publish frame) are encoded
//!   and weighed, with and without a topology change in them.
//!
//! Figures are ratios to the probe phase of the same run, so they travel between machines.
//!
//! Run: `cargo bench -p sinew-server --bench instruments` (add `-- --ticks N` to change the count per phase).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Instant;

use sinew_protocol::rt::LatencyHistogram;
use sinew_server::interaction::JawInput;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

#[path = "support/bench_args.rs"]
mod bench_args;
#[path = "support/delta_scale.rs"]
mod delta_scale;

use delta_scale::DeltaScale;

fn command(x_mm: f32, z_mm: f32, closed: bool) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [x_mm, 0.0, z_mm],
        jaws: JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    }
}

struct Phase {
    ticks: LatencyHistogram,
    takes: LatencyHistogram,
    held_max: u16,
    slipped: u32,
}

fn run(sim: &mut Sim, ticks: usize, start: usize, grasp: bool) -> Phase {
    let dt_s = 0.001f32;
    let mut outputs = [ToolOutput::default(); 2];
    let mut phase = Phase {
        ticks: LatencyHistogram::new(),
        takes: LatencyHistogram::new(),
        held_max: 0,
        slipped: 0,
    };
    for k in start..start + ticks {
        let t = k as f32 * dt_s;
        // Sphere radius 4: centre at 2.5 puts its bottom 1.5 mm into the pad.
        let (x, z, closed) = if grasp {
            let cycle = t % 2.0;
            let closed = (0.2..1.6).contains(&cycle);
            let lift = if (0.3..1.3).contains(&cycle) {
                3.0 * (std::f32::consts::PI * (cycle - 0.3)).sin()
            } else {
                0.0
            };
            (0.0, 2.5 + lift, closed)
        } else {
            (4.0 * (std::f32::consts::TAU * t / 2.0).sin(), 2.5, false)
        };
        let commands = [command(x, z, closed), command(-x, z, closed)];
        let started = Instant::now();
        let report = sim.step(dt_s, &commands, &mut outputs);
        let elapsed = started.elapsed();
        phase.ticks.record(elapsed);
        if report.grasps_taken > 0 {
            phase.takes.record(elapsed);
        }
        phase.slipped += report.attachments_slipped;
        phase.held_max = phase.held_max.max(outputs[0].attachments);
        assert_eq!(report.faults, 0);
    }
    phase
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ticks = bench_args::count_arg("ticks", 10_000)?;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/grasp_pull.toml");
    let world = load_world(&path)?;
    let mut sim = Sim::new(&world)?;
    // Settle into the press with the jaws open (not timed).
    for k in 0..500 {
        let z = 2.5 + 10.0 * (1.0 - (k + 1) as f32 / 500.0);
        let mut out = [ToolOutput::default(); 2];
        sim.step(
            0.001,
            &[command(0.0, z, false), command(0.0, z, false)],
            &mut out,
        );
    }
    let probe = run(&mut sim, ticks, 500, false);
    let grasp = run(&mut sim, ticks, 500 + ticks, true);
    let us = |ns: u64| ns as f32 / 1000.0;
    let (p50, p99) = (
        probe.ticks.percentile_us(50.0),
        probe.ticks.percentile_us(99.0),
    );
    println!(
        "instruments bench: worlds/grasp_pull.toml, two tools, {ticks} ticks per phase, one core"
    );
    println!(
        "probe (jaws open, stroking): tick p50 {p50:.0} us, p99 {p99:.0} us, max {:.0} us",
        us(probe.ticks.max_ns())
    );
    let g50 = grasp.ticks.percentile_us(50.0);
    let g99 = grasp.ticks.percentile_us(99.0);
    println!(
        "grasp (close, pull 3 mm, open; every 2 s): tick p50 {g50:.0} us (x{:.2}), p99 {g99:.0} us (x{:.2}), max {:.0} us; up to {} points held per tool, {} slipped",
        g50 / p50,
        g99 / p99,
        us(grasp.ticks.max_ns()),
        grasp.held_max,
        grasp.slipped
    );
    // Cautery: worlds/cautery.toml, the tip 0.5 mm in, stroking +-8 mm; current off, then on.
    let cautery_path = path.with_file_name("cautery.toml");
    let mut cautery = Sim::new(&load_world(&cautery_path)?)?;
    let stroke = |cautery: &mut Sim, ticks: std::ops::Range<usize>, on: bool| {
        let mut histogram = LatencyHistogram::new();
        let mut out = [ToolOutput::default(); 2];
        for k in ticks {
            let t = k as f32 * 0.001;
            let command = command(8.0 * (t * 2.0).sin(), 1.5 - (t / 0.3).min(1.0) * 0.5, on);
            let started = Instant::now();
            cautery.step(0.001, &[command], &mut out);
            histogram.record(started.elapsed());
        }
        histogram
    };
    stroke(&mut cautery, 0..500, false);
    let off = stroke(&mut cautery, 500..500 + ticks, false);
    let on = stroke(&mut cautery, 500 + ticks..500 + 2 * ticks, true);
    let (o50, o99) = (off.percentile_us(50.0), off.percentile_us(99.0));
    let (b50, b99) = (on.percentile_us(50.0), on.percentile_us(99.0));
    println!(
        "cautery (worlds/cautery.toml, one tip stroking +-8 mm): current off p50 {o50:.0} / p99 {o99:.0} us; on p50 {b50:.0} us (x{:.2}) / p99 {b99:.0} us (x{:.2}); {} vertices burnt",
        b50 / o50,
        b99 / o99,
        cautery.objects[0].burn().iter().filter(|&&b| b > 0).count()
    );
    println!(
        "ticks that took hold: {}, worst {:.0} us (x{:.2} the probe p50)",
        grasp.takes.count(),
        us(grasp.takes.max_ns()),
        us(grasp.takes.max_ns()) / p50
    );
    cut_phase(&path.with_file_name("cut_under_tension.toml"), ticks)?;
    Ok(())
}

/// The scalpel of worlds/cut_under_tension.toml drawn along y, its edge above the sheet (`height_mm` 12) or through it (1.5),
/// a fresh line each pass; timed ticks, the ticks that split vertices, and the weight of the mesh deltas.
fn cut_phase(path: &std::path::Path, ticks: usize) -> Result<(), Box<dyn std::error::Error>> {
    let mut sim = Sim::new(&load_world(path)?)?;
    let mut deltas = DeltaScale::new(&sim.objects[0], 40.0);
    let mut out = [ToolOutput::default(); 2];
    // Pass k runs at device x = -21 + 3k mm, from y = -25 to +25 (k even) or back (k odd), 2.5 s a pass.
    let at = |k: usize, height_mm: f32| {
        let t = k as f32 * 0.001;
        let pass = (t / 2.5) as usize;
        let along = (t % 2.5) / 2.5;
        let y = if pass.is_multiple_of(2) {
            -25.0 + 50.0 * along
        } else {
            25.0 - 50.0 * along
        };
        ToolCommand {
            active: true,
            position_device_mm: [-21.0 + 3.0 * pass as f32, y, height_mm],
            ..ToolCommand::default()
        }
    };
    // Join above the sheet at the first line's start (not timed).
    for _ in 0..500 {
        sim.step(0.001, &[at(0, 12.0)], &mut out);
    }
    let mut air = LatencyHistogram::new();
    for k in 0..ticks {
        let started = Instant::now();
        sim.step(0.001, &[at(k, 12.0)], &mut out);
        air.record(started.elapsed());
    }
    // Down through the sheet at the start of the first line (not timed), then cut.
    for j in 0..300 {
        let h = 12.0 - 10.5 * (j + 1) as f32 / 300.0;
        sim.step(0.001, &[at(0, h)], &mut out);
    }
    let (mut cutting, mut splitting) = (LatencyHistogram::new(), LatencyHistogram::new());
    // Every tick that changed the topology (a subdivision that opened nothing too).
    let mut changing = LatencyHistogram::new();
    let (mut split, mut changes) = (0u32, 0u32);
    for k in 0..ticks {
        let version = sim.objects[0].topology_version();
        let started = Instant::now();
        let report = sim.step(0.001, &[at(k, 1.5)], &mut out);
        let elapsed = started.elapsed();
        cutting.record(elapsed);
        if sim.objects[0].topology_version() != version {
            changing.record(elapsed);
        }
        if report.vertices_split > 0 {
            splitting.record(elapsed);
            changes += 1;
        }
        split += report.vertices_split;
        if k % 16 == 15 {
            deltas.frame(&sim.objects[0]);
        }
    }
    let (a50, a99) = (air.percentile_us(50.0), air.percentile_us(99.0));
    let (c50, c99) = (cutting.percentile_us(50.0), cutting.percentile_us(99.0));
    println!(
        "cut (worlds/cut_under_tension.toml, scalpel +-25 mm along y at 20 mm/s): edge above the sheet p50 {a50:.0} / p99 {a99:.0} us; through it p50 {c50:.0} us (x{:.2}) / p99 {c99:.0} us (x{:.2}); {split} vertices split in {changes} ticks, worst of them {:.0} us (x{:.2} the edge-above p50)",
        c50 / a50,
        c99 / a99,
        splitting.max_ns() as f32 / 1000.0,
        splitting.max_ns() as f32 / 1000.0 / a50,
    );
    println!(
        "cut ticks that changed the topology: {} (p50 {:.0} us, x{:.2} the edge-above p50; p99 {:.0} us, x{:.2}; worst {:.0} us, x{:.2})",
        changing.count(),
        changing.percentile_us(50.0),
        changing.percentile_us(50.0) / a50,
        changing.percentile_us(99.0),
        changing.percentile_us(99.0) / a50,
        changing.max_ns() as f32 / 1000.0,
        changing.max_ns() as f32 / 1000.0 / a50,
    );
    let (topo, plain) = (deltas.with_topology, deltas.plain);
    println!(
        "cut mesh deltas (60 Hz): {} with a topology change, mean {:.0} B, max {} B; {} without, mean {:.0} B; {} vertices and {} triangles in the mesh",
        topo.count,
        topo.mean(),
        topo.max,
        plain.count,
        plain.mean(),
        sim.objects[0].model.node_count(),
        sim.objects[0].model.triangles().len()
    );
    Ok(())
}
