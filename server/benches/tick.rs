//! Server tick time for worlds/pad.toml with two tools pressing and stroking, on one core, no network:
//! p50/p99/max of the whole `Sim::step`, plus a breakdown of its stages (integration substeps, collider
//! refit) measured separately on the same state.
//!
//! Run: `cargo bench -p sinew-server --bench tick` (add `-- --ticks N` to change the count). With
//! `-- --world worlds/liver.toml` (relative to the repository) the same two presses and strokes run on that
//! world's first two tools, and only the full tick is reported (the stage breakdown is the pad's). A world with
//! multi-rate objects (`step_hz`) runs as the server runs it: their steps on threads of their own, the ticks
//! paced at the tick rate (a flat-out tick would hand off faster than real time); it also prints each object's
//! step time against its period and how many hand-offs had to wait for the step. `-- --step-hz H` makes the
//! world's first object multi-rate at `H` Hz (one step a period). `-- --tools N` lets only the first `N` (0, 1
//! or 2) of the two tools act; `-- --grasp` closes the second tool's jaws once it has pressed (0.5 s in): a
//! grasper holds what it pressed as it strokes.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::time::Instant;

use sinew_parallel::ChunkRunner;
use sinew_parallel::WorkerPool;
use sinew_protocol::rt::LatencyHistogram;
use sinew_protocol::rt::Pacer;
use sinew_server::collision::SurfaceCollider;
use sinew_server::node::step_threads::ThreadRunner;
use sinew_server::node::tick_cost::press_and_stroke_commands;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::tissue::{Integrator, SymplecticEuler};
use sinew_server::world::load_world;
use std::sync::Arc;
use std::sync::atomic::Ordering;

#[path = "support/bench_args.rs"]
mod bench_args;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ticks = bench_args::count_arg("ticks", 20_000)?;
    let acting = bench_args::count_arg("tools", 2)?.min(2);
    let grasp = std::env::args().any(|a| a == "--grasp");
    let other_world = bench_args::text_arg("world");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(other_world.as_deref().unwrap_or("worlds/pad.toml"));
    let mut world = load_world(&path)?;
    // `--step-hz H`: the world's first object as a multi-rate object at H Hz, one step a period.
    if let Some(step_hz) = bench_args::text_arg("step-hz") {
        let step_hz: f64 = step_hz.parse()?;
        let ticks = (world.tick_hz / step_hz).round().max(1.0) as u32;
        world.objects[0].ticks_per_step = ticks;
        world.objects[0].dt_s = (f64::from(ticks) / world.tick_hz) as f32;
    }
    let mut sim = Sim::new(&world)?;
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut counters = Vec::new();
    sim.set_step_runners(|object| {
        let runner = ThreadRunner::spawn(object).expect("a step thread");
        counters.push((object.to_owned(), runner.counters()));
        Box::new(runner)
    });
    let mut pacer = (!counters.is_empty()).then(|| {
        Pacer::new(
            std::time::Duration::from_secs_f64(1.0 / world.tick_hz),
            100_000,
        )
    });
    let model = &sim.objects[0].model;
    println!(
        "{}: {} nodes, {} edges, {} triangles, {} tetrahedra, integrator {}, dt {} s, tick {} s",
        world.scene,
        model.node_count(),
        model.edge_count(),
        model.triangles().len(),
        model.tets().len(),
        sim.objects[0].integrator_name(),
        world.objects[0].dt_s,
        dt_s
    );

    let mut outputs = [ToolOutput::default(); 2];
    let mut tick = LatencyHistogram::new();
    let mut held = 0u64;
    let mut retries = 0u64;
    let mut grasped_ticks = 0u64;
    for k in 0..ticks {
        // Both probes press 5 mm and stroke +-8 mm along x with a 2 s period (after a 0.5 s descent).
        let mut commands = [ToolCommand::default(); 2];
        press_and_stroke_commands(k as f32 * dt_s, &mut commands);
        for command in &mut commands[acting..] {
            command.active = false;
        }
        if grasp && k as f32 * dt_s > 0.5 {
            commands[1].jaws.buttons = 1;
        }
        if let Some(pacer) = &mut pacer {
            pacer.wait();
        }
        let start = Instant::now();
        let report = sim.step(dt_s, &commands, &mut outputs);
        tick.record(start.elapsed());
        held += u64::from(report.held_nodes);
        retries += u64::from(report.retries);
        grasped_ticks += u64::from(outputs[1].attachments > 0);
    }
    let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
    println!(
        "full tick ({acting} tool(s) pressing+stroking{}): p50 {:.0} us  p99 {:.0} us  max {:.0} us  over {ticks} ticks, mean held nodes {:.0}, guard retries {retries}",
        if grasp {
            format!(
                ", the second grasping (holding {:.0}% of ticks)",
                100.0 * grasped_ticks as f64 / ticks as f64
            )
        } else {
            String::new()
        },
        us(&tick, 50.0),
        us(&tick, 99.0),
        tick.max_ns() as f64 / 1000.0,
        held as f64 / ticks as f64
    );
    for (object, counters) in &counters {
        let steps = counters.steps.load(Ordering::Relaxed).max(1);
        let ticks_per_step = world
            .objects
            .iter()
            .find(|o| &o.name == object)
            .map_or(1, |o| o.ticks_per_step);
        let period_us = f64::from(ticks_per_step) * f64::from(dt_s) * 1e6;
        let mean_us = counters.busy_ns.load(Ordering::Relaxed) as f64 / steps as f64 / 1000.0;
        println!(
            "object `{object}` at {:.0} Hz on its own thread: step mean {mean_us:.0} us, longest {:.0} us, \
             {:.0}% of its {period_us:.0} us period; the tick waited for {} of {steps} steps; paced tick overruns {}",
            1e6 / period_us,
            counters.longest_ns.load(Ordering::Relaxed) as f64 / 1000.0,
            100.0 * mean_us / period_us,
            counters.late.load(Ordering::Relaxed),
            pacer.as_ref().map_or(0, |p| p.overruns()),
        );
    }
    if other_world.is_some() {
        return Ok(());
    }

    // Stage breakdown on the deformed state.
    let object = &mut sim.objects[0];
    let mut integrate = LatencyHistogram::new();
    let mut refit = LatencyHistogram::new();
    let mut integrator = SymplecticEuler;
    let mut collider = SurfaceCollider::new(&object.state.positions_mm, object.model.triangles())
        .map_err(|e| format!("{e:?}"))?
        .with_refit_margin(sinew_server::sim::REFIT_MARGIN_MM);
    let h = world.objects[0].dt_s;
    for _ in 0..5_000 {
        let start = Instant::now();
        integrator.step(&object.model, &mut object.state, h);
        integrate.record(start.elapsed());
        let start = Instant::now();
        collider.refit(&object.state.positions_mm);
        refit.record(start.elapsed());
    }
    // The guard's checks alone (absolute tests, then the energy pass).
    let mut guard_check = LatencyHistogram::new();
    let check = sinew_server::tissue::DivergenceGuard::new(&object.model);
    for _ in 0..2_000 {
        let start = Instant::now();
        let assessment = check.assess(&object.model, &object.state);
        guard_check.record(start.elapsed());
        assert!(!assessment.broken && assessment.energy_n_mm.is_finite());
    }
    println!(
        "anti-divergence checks (one assess: absolute tests + energy) p50 {:.0} us p99 {:.0} us",
        us(&guard_check, 50.0),
        us(&guard_check, 99.0)
    );
    // The force kernel alone, warm caches.
    let mut forces = LatencyHistogram::new();
    let mut scratch = object.state.forces_n.clone();
    for _ in 0..5_000 {
        let start = Instant::now();
        object.model.compute_forces(
            &object.state.positions_mm,
            &object.state.velocities_mm_s,
            None,
            &mut scratch,
        );
        forces.record(start.elapsed());
    }
    let mut warm_step = LatencyHistogram::new();
    for _ in 0..5_000 {
        let start = Instant::now();
        integrator.step(&object.model, &mut object.state, h);
        warm_step.record(start.elapsed());
    }
    println!(
        "warm caches: spring+anchor forces p50 {:.0} us ({:.1} ns/spring); whole symplectic-Euler step p50 {:.0} us p99 {:.0} us",
        us(&forces, 50.0),
        forces.percentile_ns(50.0) as f64 / object.model.edge_count() as f64,
        us(&warm_step, 50.0),
        us(&warm_step, 99.0)
    );
    println!(
        "stages (interleaved, as in a tick): one symplectic-Euler substep p50 {:.0} us p99 {:.0} us; BVH refit (fat leaves, sim::REFIT_MARGIN_MM) p50 {:.0} us p99 {:.0} us",
        us(&integrate, 50.0),
        us(&integrate, 99.0),
        us(&refit, 50.0),
        us(&refit, 99.0)
    );
    thread_scaling(&world, ticks)
}

/// The full tick at each thread count of `--threads` (default 1, 2 and the machine's cores), the sims stepped
/// in turn tick by tick so the machine's noise falls on all of them alike; then each sim's final state against
/// the one-thread sim's, bit for bit.
fn thread_scaling(
    world: &sinew_server::world::World,
    ticks: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let counts: Vec<usize> = match bench_args::text_arg("threads") {
        Some(list) => list
            .split(',')
            .map(|t| t.trim().parse())
            .collect::<Result<_, _>>()?,
        None => {
            let mut counts = vec![1, 2, cores];
            counts.dedup();
            counts
        }
    };
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut runs = Vec::new();
    for &threads in &counts {
        let mut sim = Sim::new(world)?;
        let pool = (threads > 1)
            .then(|| WorkerPool::new(threads, Some(sinew_protocol::rt::realtime::pin_this_thread)))
            .transpose()?;
        if let Some(pool) = &pool {
            println!("  {}", pool.report());
        }
        sim.set_chunk_runner(pool.map(|p| Arc::new(p) as Arc<dyn ChunkRunner>));
        runs.push((threads, sim, LatencyHistogram::new()));
    }
    let mut outputs = [ToolOutput::default(); 2];
    for k in 0..ticks {
        let mut commands = [ToolCommand::default(); 2];
        press_and_stroke_commands(k as f32 * dt_s, &mut commands);
        for (_, sim, histogram) in &mut runs {
            let start = Instant::now();
            sim.step(dt_s, &commands, &mut outputs);
            histogram.record(start.elapsed());
        }
    }
    let us = |h: &LatencyHistogram, p: f64| h.percentile_ns(p) as f64 / 1000.0;
    // The passes alone, back to back (workers spinning, caches warm): forces, and a whole step.
    for (threads, sim, _) in &mut runs {
        let object = &mut sim.objects[0];
        let (mut forces, mut step) = (LatencyHistogram::new(), LatencyHistogram::new());
        let mut out = object.state.forces_n.clone();
        let mut integrator = SymplecticEuler;
        let mut state = object.state.clone();
        for _ in 0..3_000 {
            let start = Instant::now();
            object.model.compute_forces(
                &state.positions_mm,
                &state.velocities_mm_s,
                None,
                &mut out,
            );
            forces.record(start.elapsed());
            let start = Instant::now();
            integrator.step(&object.model, &mut state, world.objects[0].dt_s);
            step.record(start.elapsed());
        }
        println!(
            "  warm, {threads} thread(s): spring+anchor forces p50 {:.0} us, whole symplectic-Euler step p50 {:.0} us p99 {:.0} us",
            us(&forces, 50.0),
            us(&step, 50.0),
            us(&step, 99.0)
        );
    }
    let bits = |sim: &Sim| -> Vec<u32> {
        sim.objects[0]
            .state
            .positions_mm
            .iter()
            .chain(&sim.objects[0].state.velocities_mm_s)
            .flat_map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect()
    };
    let reference = bits(&runs[0].1);
    let (base_p50, base_p99) = (us(&runs[0].2, 50.0), us(&runs[0].2, 99.0));
    println!(
        "thread scaling, full tick, {ticks} ticks interleaved on {cores} cores (ratio to {} thread(s) in the same run):",
        runs[0].0
    );
    for (threads, sim, histogram) in &runs {
        println!(
            "  {threads} thread(s): p50 {:.0} us ({:.2}x)  p99 {:.0} us ({:.2}x)  state after {ticks} ticks {} the first run's",
            us(histogram, 50.0),
            us(histogram, 50.0) / base_p50,
            us(histogram, 99.0),
            us(histogram, 99.0) / base_p99,
            if bits(sim) == reference {
                "bit-identical to"
            } else {
                "DIFFERS from"
            }
        );
    }
    Ok(())
}
