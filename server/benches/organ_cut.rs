//! What cutting a multi-rate organ costs the server tick: worlds/liver_incision.toml (the liver, 13,224
//! corotational tetrahedra stepped at 25 Hz on a thread of its own, as the server runs it; the ticks paced at
//! the tick rate), its scalpel drawn +-20 mm along y at 20 mm/s across the right lobe, a fresh line 4 mm further
//! along x each pass; first with its edge 2 mm above the surface, then with its blunt back riding the surface
//! (the edge 12 mm deep). One core's worth of tick: the step runs on its own thread.
//!
//! Reported, each as a ratio to the edge-above tick of the same run: the tick p50 / p99 between hand-offs, the
//! ticks that changed the topology (p50 / p99 / worst), the hand-off ticks (p50 / worst) and the hand-offs
//! that gave the step the cut model (worst); then the organ's step on its thread before and after the cuts, and
//! the tetrahedra made per mm of cut, and the mesh deltas a viewer gets (one per 60 Hz publish frame, encoded and
//! weighed) while the scalpel cuts.
//!
//! Run: `cargo bench -p sinew-server --bench organ_cut` (add `-- --ticks N` to change the count per phase).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use nalgebra::Vector2;
use sinew_protocol::rt::{LatencyHistogram, Pacer};
use sinew_server::node::step_threads::ThreadRunner;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

#[path = "support/bench_args.rs"]
mod bench_args;
#[path = "support/delta_scale.rs"]
mod delta_scale;

use delta_scale::DeltaScale;

/// The scalpel's device origin in the world, mm.
const SCALPEL_ORIGIN_MM: (f32, f32) = (25.0, 0.0);
/// Each pass draws this far either side of the origin along y, mm, at `SPEED_MM_S`.
const HALF_LINE_MM: f32 = 20.0;
const SPEED_MM_S: f32 = 20.0;
/// The passes' lines along x, device frame, mm.
const LINES_X_MM: [f32; 6] = [-10.0, -6.0, -2.0, 2.0, 6.0, 10.0];

/// Where the scalpel's device is at tick `k` of a phase, its origin `lift_mm` above the rest surface.
fn scalpel_at(sim_surface: &impl Fn(f32, f32) -> f32, k: usize, lift_mm: f32) -> ToolCommand {
    let pass_ticks = (2.0 * HALF_LINE_MM / SPEED_MM_S * 1000.0) as usize;
    let pass = k / pass_ticks;
    let along = (k % pass_ticks) as f32 / pass_ticks as f32;
    let y = if pass.is_multiple_of(2) {
        -HALF_LINE_MM + 2.0 * HALF_LINE_MM * along
    } else {
        HALF_LINE_MM - 2.0 * HALF_LINE_MM * along
    };
    let x = LINES_X_MM[pass % LINES_X_MM.len()];
    let z = sim_surface(SCALPEL_ORIGIN_MM.0 + x, SCALPEL_ORIGIN_MM.1 + y) + lift_mm;
    ToolCommand {
        active: true,
        position_device_mm: [x, y, z],
        ..ToolCommand::default()
    }
}

/// One phase's ticks.
#[derive(Default)]
struct Phase {
    between: LatencyHistogram,
    hand_offs: LatencyHistogram,
    changing: LatencyHistogram,
    taking: LatencyHistogram,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ticks = bench_args::count_arg("ticks", 8_000)?;
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/liver_incision.toml");
    let world = load_world(&path)?;
    let mut sim = Sim::new(&world)?;
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut counters = Vec::new();
    sim.set_step_runners(|object| {
        let runner = ThreadRunner::spawn(object).expect("a step thread");
        counters.push(runner.counters());
        Box::new(runner)
    });
    let ticks_per_step = sim.objects[0].step_lane().unwrap().ticks_per_step() as u64;
    // The rest surface's height at world (x, y): the highest rest node within 2.5 mm.
    let rest: Vec<_> = sim.objects[0].model.rest_positions_mm().to_vec();
    let surface = move |x: f32, y: f32| {
        rest.iter()
            .filter(|p| (p.xy() - Vector2::new(x, y)).norm() < 2.5)
            .map(|p| p.z)
            .fold(f32::MIN, f32::max)
    };
    let tets_before = sim.objects[0].model.tets().len();
    let mut pacer = Pacer::new(Duration::from_secs_f64(1.0 / world.tick_hz), 100_000);
    let mut out = [ToolOutput::default(); 2];
    let idle = ToolCommand::default();
    let mut deltas = DeltaScale::new(&sim.objects[0], world.objects[0].quant_margin_mm);
    let mut run = |sim: &mut Sim,
                   deltas: &mut DeltaScale,
                   ticks: usize,
                   timed: bool,
                   scalpel: &dyn Fn(usize) -> ToolCommand| {
        let mut phase = Phase::default();
        let mut taking = false;
        for k in 0..ticks {
            let command = [scalpel(k), idle];
            pacer.wait();
            let version = sim.objects[0].topology_version();
            let hand_off = sim.steps().is_multiple_of(ticks_per_step);
            let started = Instant::now();
            sim.step(dt_s, &command, &mut out);
            let elapsed = started.elapsed();
            if !timed {
                continue;
            }
            if hand_off {
                phase.hand_offs.record(elapsed);
                if std::mem::take(&mut taking) {
                    phase.taking.record(elapsed);
                }
            } else {
                phase.between.record(elapsed);
            }
            if sim.objects[0].topology_version() != version {
                phase.changing.record(elapsed);
                taking = true;
            }
            // A 60 Hz publish frame: the delta a viewer would get, weighed.
            if k % 16 == 15 {
                deltas.frame(&sim.objects[0]);
            }
        }
        phase
    };
    // Join 14 mm above the first line's start (not timed).
    run(&mut sim, &mut deltas, 500, false, &|_| {
        scalpel_at(&surface, 0, 14.0)
    });
    let air = run(&mut sim, &mut deltas, ticks, true, &|k| {
        scalpel_at(&surface, k, 14.0)
    });
    let step_ns = |c: &sinew_server::node::step_threads::StepCounters| {
        (
            c.busy_ns.load(Ordering::Relaxed),
            c.steps.load(Ordering::Relaxed).max(1),
        )
    };
    let (busy_air, steps_air) = step_ns(&counters[0]);
    // Down onto the surface at the first line's start (not timed), then cut.
    run(&mut sim, &mut deltas, 300, false, &|j| {
        scalpel_at(&surface, 0, 14.0 - 13.2 * (j + 1) as f32 / 300.0)
    });
    let (busy_down, steps_down) = step_ns(&counters[0]);
    // The deltas weighed are the cutting phase's.
    (deltas.with_topology, deltas.plain) = Default::default();
    let through = run(&mut sim, &mut deltas, ticks, true, &|k| {
        scalpel_at(&surface, k, 0.8)
    });
    let (busy_cut, steps_cut) = step_ns(&counters[0]);
    let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
    let max_us = |h: &LatencyHistogram| h.max_ns() as f64 / 1000.0;
    let (a50, a99) = (us(&air.between, 50.0), us(&air.between, 99.0));
    let model = &sim.objects[0].model;
    let drawn_mm = ticks as f64 * f64::from(SPEED_MM_S) * f64::from(dt_s);
    println!(
        "organ cut bench: worlds/liver_incision.toml, the liver at 25 Hz on its own thread, the scalpel +-{HALF_LINE_MM} mm \
         along y at {SPEED_MM_S} mm/s, {ticks} paced ticks a phase"
    );
    println!(
        "edge above the surface: tick between hand-offs p50 {a50:.0} us / p99 {a99:.0} us; hand-off p50 {:.0} / max {:.0} us",
        us(&air.hand_offs, 50.0),
        max_us(&air.hand_offs)
    );
    println!(
        "edge through the lobe: between hand-offs p50 {:.0} us (x{:.2}) / p99 {:.0} us (x{:.2}); hand-off p50 {:.0} / max {:.0} us",
        us(&through.between, 50.0),
        us(&through.between, 50.0) / a50,
        us(&through.between, 99.0),
        us(&through.between, 99.0) / a99,
        us(&through.hand_offs, 50.0),
        max_us(&through.hand_offs)
    );
    println!(
        "ticks that changed the topology: {}, p50 {:.0} us (x{:.2} the edge-above p50) / p99 {:.0} us / worst {:.0} us (x{:.2}); \
         hand-offs that gave the step the cut model: {}, worst {:.0} us (x{:.2})",
        through.changing.count(),
        us(&through.changing, 50.0),
        us(&through.changing, 50.0) / a50,
        us(&through.changing, 99.0),
        max_us(&through.changing),
        max_us(&through.changing) / a50,
        through.taking.count(),
        max_us(&through.taking),
        max_us(&through.taking) / a50,
    );
    let (topo, plain) = (deltas.with_topology, deltas.plain);
    println!(
        "mesh deltas at 60 Hz while cutting: {} with a topology change, mean {:.0} B, max {} B; {} without, mean {:.0} B, max {} B",
        topo.count,
        topo.mean(),
        topo.max,
        plain.count,
        plain.mean(),
        plain.max,
    );
    let mean_ms = |busy: u64, steps: u64| busy as f64 / steps as f64 / 1e6;
    println!(
        "the organ's step on its thread: mean {:.1} ms edge above, {:.1} ms cutting (x{:.2}); tetrahedra {tets_before} -> {} \
         ({:.1} per mm of the {drawn_mm:.0} mm drawn), nodes {}",
        mean_ms(busy_air, steps_air),
        mean_ms(busy_cut - busy_down, steps_cut - steps_down),
        mean_ms(busy_cut - busy_down, steps_cut - steps_down) / mean_ms(busy_air, steps_air),
        model.tets().len(),
        (model.tets().len() - tets_before) as f64 / drawn_mm,
        model.node_count(),
    );
    Ok(())
}
