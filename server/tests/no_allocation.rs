//! The real-time contract of `Sim::step`: after warm-up, a tick allocates nothing. A counting global allocator
//! wraps the system one; the test warms the pad up under two probes (contacts grow their buffers, integrator
//! scratch is sized), then counts allocations over a second of pressing and stroking ticks.
#![allow(clippy::unwrap_used, clippy::expect_used)]
// test code: a failed setup should panic loudly

mod common;
#[path = "common/counting_allocator.rs"]
mod counting_allocator;

use common::scene_edits::{with_integrator, with_region, with_step_hz};
use counting_allocator::{Counting, assert_counting_works, count_all_threads};
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::{InstrumentSpec, IntegratorName, load_world};

#[global_allocator]
static GLOBAL: Counting = Counting;

fn commands(k: usize) -> [ToolCommand; 2] {
    let t = k as f32 * 0.001;
    let depth = (t / 0.3).min(1.0) * 4.0;
    let stroke = 6.0 * (std::f32::consts::TAU * t).sin();
    let at = |x: f32, y: f32| ToolCommand {
        active: true,
        position_device_mm: [x, y, 4.0 - depth],
        velocity_device_mm_s: [0.0; 3],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    };
    [at(stroke, 0.0), at(-stroke, 4.0)]
}

/// Step ticks `ticks` of the two-probe press-and-stroke.
fn step_ticks(sim: &mut Sim, ticks: std::ops::Range<usize>) {
    let mut out = [ToolOutput::default(); 2];
    for k in ticks {
        sim.step(0.001, &commands(k), &mut out);
    }
}

/// Allocations over ticks `warm..warm + counted` of the two-probe press-and-stroke, after ticks `0..warm`.
fn allocations_while_stepping(sim: &mut Sim, warm: usize, counted: usize) -> u64 {
    step_ticks(sim, 0..warm);
    count_allocations(sim, warm..warm + counted)
}

/// Allocations (on any thread) while stepping `ticks`.
fn count_allocations(sim: &mut Sim, ticks: std::ops::Range<usize>) -> u64 {
    count_all_threads(|| step_ticks(sim, ticks))
}

/// One test function, so no other test thread allocates while counting.
#[test]
fn a_warm_tick_allocates_nothing_with_every_integrator() {
    assert_counting_works();

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let pad = load_world(&path).unwrap();
    for method in IntegratorName::ALL {
        // Explicit Euler and RK2 need a smaller step on the pad (the loader says so): take the first that passes.
        let world = with_integrator(pad.clone(), 0, method, &[0.001, 0.00025, 0.0001]);
        let mut sim = Sim::new(&world).unwrap();
        let allocations = allocations_while_stepping(&mut sim, 400, 200);
        println!(
            "{}: {allocations} allocations in 200 warm ticks",
            method.as_str()
        );
        assert_eq!(
            allocations,
            0,
            "{} allocated in a warm tick",
            method.as_str()
        );
    }
    // The shipped world as it is.
    let mut sim = Sim::new(&load_world(&path).unwrap()).unwrap();
    assert_eq!(allocations_while_stepping(&mut sim, 600, 1000), 0);
    // ... and with its tissue passes on a pool of workers (the counter sees every thread's allocations).
    let mut sim = Sim::new(&load_world(&path).unwrap()).unwrap();
    let pool = sinew_parallel::WorkerPool::new(3, None).unwrap();
    sim.set_chunk_runner(Some(std::sync::Arc::new(pool)));
    let allocations = allocations_while_stepping(&mut sim, 600, 1000);
    assert_eq!(allocations, 0, "a tick on worker threads allocated");
    // With friction: the nodes stick to the probes and slip as they stroke (each substep's anchors reuse
    // their buffers).
    let mut rough = pad.clone();
    rough.objects[0].material.friction_coefficient = 0.5;
    let mut sim = Sim::new(&rough).unwrap();
    let allocations = allocations_while_stepping(&mut sim, 600, 1000);
    println!("friction: {allocations} allocations in 1000 warm ticks");
    assert_eq!(allocations, 0, "a tick with friction allocated");
    // Finite elements (worlds/fem_block.toml: implicit Euler over corotational tetrahedra), the whole block
    // and region-tracked.
    let fem_block = load_world(&path.with_file_name("fem_block.toml")).unwrap();
    for region in [false, true] {
        let world = if region {
            with_region(fem_block.clone(), 0, 0.001)
        } else {
            fem_block.clone()
        };
        let mut sim = Sim::new(&world).unwrap();
        let allocations = allocations_while_stepping(&mut sim, 600, 400);
        println!("finite elements, region {region}: {allocations} allocations in 400 warm ticks");
        assert_eq!(
            allocations, 0,
            "a finite-element tick allocated (region {region})"
        );
    }
    // The same block as a multi-rate object (200 Hz, every fifth tick hands off), its steps inline and on
    // their own thread (the hand-off's channels allocate nothing once warm).
    for threaded in [false, true] {
        let world = with_step_hz(fem_block.clone(), 0, 200.0, 0.005);
        let mut sim = Sim::new(&world).unwrap();
        if threaded {
            sim.set_step_runners(|object| {
                Box::new(sinew_server::node::step_threads::ThreadRunner::spawn(object).unwrap())
            });
        }
        let allocations = allocations_while_stepping(&mut sim, 600, 400);
        println!(
            "multi-rate finite elements, threaded {threaded}: {allocations} allocations in 400 warm ticks"
        );
        assert_eq!(
            allocations, 0,
            "a multi-rate tick allocated (threaded {threaded})"
        );
    }
    // Region tracking, which rebuilds its sub-model inside ticks as the dent moves: the rebuilds reuse their
    // buffers once a full stroke cycle (1 s) has grown them.
    for method in [IntegratorName::SymplecticEuler, IntegratorName::Xpbd] {
        // At the pad's own step, which the loader accepts for both methods.
        let world = with_region(with_integrator(pad.clone(), 0, method, &[0.001]), 0, 0.001);
        let mut sim = Sim::new(&world).unwrap();
        step_ticks(&mut sim, 0..1200);
        let before = sim.objects[0].region().unwrap().rebuilds();
        let allocations = count_allocations(&mut sim, 1200..2000);
        let rebuilds = sim.objects[0].region().unwrap().rebuilds() - before;
        println!(
            "region, {}: {allocations} allocations in 800 warm ticks with {rebuilds} sub-model rebuilds",
            method.as_str()
        );
        assert!(
            rebuilds > 0,
            "the region never rebuilt while counting: the test proves nothing"
        );
        assert_eq!(
            allocations,
            0,
            "region tracking with {} allocated in a warm tick",
            method.as_str()
        );
    }
    // Graspers: closing on the sheet (taking hold), pulling, letting go, and slipping, cycle after cycle.
    let grasp_pull = load_world(&path.with_file_name("grasp_pull.toml")).unwrap();
    for slip_force_n in [0.3, 0.02] {
        // Both graspers, as shipped (slipping at 0.3 N), at `slip_force_n`.
        let mut world = grasp_pull.clone();
        for tool in &mut world.tools {
            let InstrumentSpec::Grasper(grasp) = &mut tool.instrument else {
                panic!("grasp_pull's `{}` is not a grasper", tool.name);
            };
            assert_eq!(grasp.slip_force_n, 0.3);
            grasp.slip_force_n = slip_force_n;
        }
        let mut sim = Sim::new(&world).unwrap();
        let grasp_ticks = |sim: &mut Sim, ticks: std::ops::Range<usize>| {
            let mut out = [ToolOutput::default(); 2];
            let mut report = sinew_server::sim::StepReport::default();
            for k in ticks {
                let cycle = (k % 2000) as f32 * 0.001;
                let closed = (0.6..1.6).contains(&cycle);
                let lift = if (0.7..1.5).contains(&cycle) {
                    4.0
                } else {
                    0.0
                };
                let descend = (cycle / 0.5).min(1.0);
                let at = |x: f32| ToolCommand {
                    active: true,
                    position_device_mm: [x, 0.0, 12.5 - 10.0 * descend + lift],
                    jaws: sinew_server::interaction::JawInput {
                        buttons: u32::from(closed),
                        jaw_angle_rad: 0.0,
                    },
                    ..ToolCommand::default()
                };
                let r = sim.step(0.001, &[at(0.0), at(0.0)], &mut out);
                report.grasps_taken += r.grasps_taken;
                report.attachments_released += r.attachments_released;
                report.attachments_slipped += r.attachments_slipped;
            }
            report
        };
        grasp_ticks(&mut sim, 0..2000);
        let mut counted = None;
        let allocations = count_all_threads(|| counted = Some(grasp_ticks(&mut sim, 2000..6000)));
        let report = counted.unwrap();
        println!(
            "grasp (slip at {slip_force_n} N): {allocations} allocations in 4000 warm ticks with {} takes, {} points released, {} slipped",
            report.grasps_taken, report.attachments_released, report.attachments_slipped
        );
        assert!(
            report.grasps_taken >= 4,
            "the jaws never took hold while counting"
        );
        if slip_force_n == 0.02 {
            assert!(
                report.attachments_slipped > 0,
                "nothing slipped while counting"
            );
        } else {
            assert!(
                report.attachments_released > 0,
                "nothing was let go while counting"
            );
        }
        assert_eq!(allocations, 0, "a grasp tick allocated");
    }
    // A cautery tip burning a line.
    let cautery_path = path.with_file_name("cautery.toml");
    let mut sim = Sim::new(&load_world(&cautery_path).unwrap()).unwrap();
    let burn_ticks = |sim: &mut Sim, ticks: std::ops::Range<usize>| {
        let mut out = [ToolOutput::default(); 2];
        let mut burnt = 0;
        for k in ticks {
            let t = k as f32 * 0.001;
            let at = ToolCommand {
                active: true,
                position_device_mm: [8.0 * (t * 2.0).sin(), 0.0, 1.5 - (t / 0.3).min(1.0) * 0.5],
                jaws: sinew_server::interaction::JawInput {
                    buttons: 1,
                    jaw_angle_rad: 0.0,
                },
                ..ToolCommand::default()
            };
            burnt += sim.step(0.001, &[at], &mut out).nodes_burnt;
        }
        burnt
    };
    burn_ticks(&mut sim, 0..1000);
    let mut counted = None;
    let allocations = count_all_threads(|| counted = Some(burn_ticks(&mut sim, 1000..2000)));
    let burnt = counted.unwrap();
    println!("cautery: {allocations} allocations in 1000 warm ticks burning {burnt} node-ticks");
    assert!(burnt > 0, "nothing burnt while counting");
    assert_eq!(allocations, 0, "a cautery tick allocated");

    // A scalpel drawn back and forth along its own cut: the first pass cuts (a cut allocates: the topology
    // grows), then the edge keeps sweeping through the tissue along the open slit, which finds nothing new.
    // Along facets (the pad as cut.toml ships it), then following the blade.
    let cut_path = path.with_file_name("cut.toml");
    for follows in [false, true] {
        let mut world = load_world(&cut_path).unwrap();
        world.objects[0].material.cut_follows_blade = follows;
        let mut sim = Sim::new(&world).unwrap();
        let cut_ticks = |sim: &mut Sim, ticks: std::ops::Range<usize>| {
            let mut out = [ToolOutput::default(); 2];
            let (mut cut, mut split) = (0, 0);
            for k in ticks {
                let t = k as f32 * 0.001;
                // Down to 1.5 mm above the surface in 0.3 s, then along y between -10 and +10 mm, 1 s a pass.
                let y = 10.0 * (std::f32::consts::PI * (t - 0.3).max(0.0)).sin();
                let at = ToolCommand {
                    active: true,
                    position_device_mm: [0.0, y, 1.5 + 8.0 * (1.0 - (t / 0.3).min(1.0))],
                    ..ToolCommand::default()
                };
                let r = sim.step(0.001, &[at], &mut out);
                cut += r.seams_cut;
                split += r.vertices_split;
            }
            (cut, split)
        };
        let (cut, split) = cut_ticks(&mut sim, 0..2500);
        assert!(cut > 0 && split > 0, "the first passes cut nothing");
        let mut counted = None;
        let allocations = count_all_threads(|| counted = Some(cut_ticks(&mut sim, 2500..4500)));
        let (cut, split) = counted.unwrap();
        println!(
            "scalpel along its own slit (following the blade: {follows}): {allocations} allocations in 2000 warm ticks ({cut} facets cut, {split} vertices split)"
        );
        assert_eq!(
            split, 0,
            "the slit grew while counting: the test cannot tell"
        );
        assert_eq!(
            allocations, 0,
            "a scalpel tick allocated (following the blade: {follows})"
        );
    }

    // Scissors (tool 1 of cut.toml, over the block) snipping at one spot: the first snips cut, then the blades
    // close again and again through the slit they made (and the crack below it), which opens nothing new.
    let mut sim = Sim::new(&load_world(&cut_path).unwrap()).unwrap();
    let snip_ticks = |sim: &mut Sim, ticks: std::ops::Range<usize>| {
        let mut out = [ToolOutput::default(); 2];
        let (mut cut, mut split) = (0, 0);
        for k in ticks {
            let t = k as f32 * 0.001;
            // Down to the hinge 6 mm above the block in 0.3 s, then a snip every 0.4 s (closed for 0.2 s).
            let closed = t > 0.5 && (t - 0.5) % 0.4 < 0.2;
            let at = ToolCommand {
                active: true,
                position_device_mm: [0.37, 0.0, 6.0 + 14.0 * (1.0 - (t / 0.3).min(1.0))],
                jaws: sinew_server::interaction::JawInput {
                    buttons: u32::from(closed),
                    jaw_angle_rad: 0.0,
                },
                ..ToolCommand::default()
            };
            let r = sim.step(0.001, &[ToolCommand::default(), at], &mut out);
            cut += r.seams_cut;
            split += r.vertices_split;
        }
        (cut, split)
    };
    let (cut, split) = snip_ticks(&mut sim, 0..2500);
    assert!(cut > 0 && split > 0, "the first snips cut nothing");
    let mut counted = None;
    let allocations = count_all_threads(|| counted = Some(snip_ticks(&mut sim, 2500..4500)));
    let (cut, split) = counted.unwrap();
    println!(
        "scissors snipping their own slit: {allocations} allocations in 2000 warm ticks ({cut} facets found again, {split} vertices split)"
    );
    assert_eq!(
        split, 0,
        "the slit grew while counting: the test cannot tell"
    );
    assert_eq!(allocations, 0, "a scissors tick allocated");
}
