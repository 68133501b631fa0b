//! The tissue step spread over worker threads gives the same bits as on one thread: positions, velocities and
//! the forces sent to the tools, tick by tick, through the real `Sim`, the real world loader and the real
//! worker pool (`sinew_parallel::WorkerPool`): on the shipped pad, on a sheet with a stiffening law under
//! every integrator (with and without a region of deformation), and on the shipped volumetric blocks.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use std::sync::Arc;

use common::{sheet_world_text, write_sheet_world};
use sinew_parallel::ChunkRunner;
use sinew_parallel::WorkerPool;
use sinew_server::node::tick_cost::press_and_stroke_commands;
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::tissue::SpringLaw;
use sinew_server::world::{World, load_world};

/// A sim of `world` whose tissue passes run on `threads` threads (1: the tick's own thread, no pool).
fn sim_on(world: &World, threads: usize) -> Sim {
    let mut sim = Sim::new(world).unwrap();
    if threads > 1 {
        let pool = WorkerPool::new(threads, None).unwrap();
        assert_eq!(pool.threads(), threads);
        sim.set_chunk_runner(Some(Arc::new(pool)));
    }
    sim
}

/// Every object's positions and velocities, and every tool output, as bits.
fn fingerprint(sim: &Sim, outputs: &[ToolOutput]) -> (Vec<u32>, String) {
    let mut bits = Vec::new();
    for object in &sim.objects {
        for v in object
            .state
            .positions_mm
            .iter()
            .chain(&object.state.velocities_mm_s)
        {
            bits.extend([v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]);
        }
    }
    // Debug prints each float's shortest exact form: equal text, equal bits.
    (bits, format!("{outputs:?}"))
}

/// Step one sim per thread count through the same commands, comparing every tick with the first.
fn assert_same_bits(
    world: &World,
    thread_counts: &[usize],
    ticks: usize,
    commands_at: impl Fn(usize, &mut [ToolCommand]),
) {
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut sims: Vec<Sim> = thread_counts.iter().map(|&t| sim_on(world, t)).collect();
    let tools = sims[0].tools.len();
    let mut commands = vec![ToolCommand::default(); tools];
    let mut moved = false;
    for k in 0..ticks {
        commands_at(k, &mut commands);
        let mut reference = None;
        for (sim, &threads) in sims.iter_mut().zip(thread_counts) {
            let mut outputs = vec![ToolOutput::default(); tools];
            sim.step(dt_s, &commands, &mut outputs);
            let print = fingerprint(sim, &outputs);
            match &reference {
                None => reference = Some(print),
                Some(first) => assert!(
                    *first == print,
                    "tick {k}: {threads} threads differ from {} thread(s)",
                    thread_counts[0]
                ),
            }
        }
        moved |= sims[0].objects[0]
            .state
            .velocities_mm_s
            .iter()
            .any(|v| v.norm() > 1.0);
    }
    assert!(
        moved,
        "the tissue never moved: the comparison proved nothing"
    );
}

#[test]
fn the_pad_pressed_and_stroked_is_the_same_to_the_bit_on_1_2_and_3_threads() {
    let world = load_world(&common::worlds().join("pad.toml")).unwrap();
    assert!(world.objects[0].region.is_none());
    let dt_s = (1.0 / world.tick_hz) as f32;
    // 0.8 s: the press and the start of the stroke, with contact throughout.
    assert_same_bits(&world, &[1, 2, 3], 800, |k, commands| {
        press_and_stroke_commands(k as f32 * dt_s, commands)
    });
}

#[test]
fn every_integrator_with_a_stiffening_law_with_and_without_a_region_is_the_same_to_the_bit_on_1_and_3_threads()
 {
    for integrator in [
        "explicit-euler",
        "symplectic-euler",
        "rk2",
        "rk4",
        "quasi-static",
        "implicit-euler",
        "xpbd",
    ] {
        // A sheet big enough for several chunks of springs and nodes (40 x 40 cells: 1681 nodes, 4840
        // springs), a stiffening law, and region tracking (the sub-model steps on the threads too).
        let (nx, ny) = (40, 40);
        // Within each explicit method's stability bound under the stiffening law (the loader checks it).
        let dt_s = match integrator {
            "explicit-euler" => 0.00005,
            "symplectic-euler" | "rk4" => 0.0005,
            "rk2" => 0.00025,
            _ => 0.001,
        };
        for extra in ["", "region = { threshold_mm = 0.001 }"] {
            let text = sheet_world_text(nx, ny, integrator, dt_s, extra);
            let mut world =
                load_world(&write_sheet_world("sinew-parallel-step", &text, nx, ny)).unwrap();
            assert_eq!(
                world.objects[0].material.law,
                SpringLaw::Linear,
                "the sheet's law was set before the edit"
            );
            world.objects[0].material.law = SpringLaw::Exponential { stiffening: 5.0 };
            // The world loader checks dt_s against the stability bound under the object's law; so does this.
            assert!(
                common::scene_edits::dt_accepted(&world, &world.objects[0], dt_s),
                "{integrator} is unstable at {dt_s} s under the stiffening law"
            );
            assert_eq!(world.objects[0].region.is_some(), !extra.is_empty());
            assert_same_bits(&world, &[1, 3], 150, |k, commands| {
                let depth = 3.0 * (k as f32 / 100.0).min(1.0);
                commands[0] = ToolCommand {
                    active: true,
                    position_device_mm: [0.3, 0.2, 4.0 - depth],
                    orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                    ..ToolCommand::default()
                };
            });
        }
    }
}

#[test]
fn volumetric_worlds_are_the_same_to_the_bit_on_1_and_3_threads() {
    // Corotational finite elements under implicit Euler, and springs with per-tetrahedron volume terms.
    for name in ["fem_block.toml", "tet_block.toml"] {
        let world = load_world(&common::worlds().join(name)).unwrap();
        assert_same_bits(&world, &[1, 3], 200, |k, commands| {
            commands[0] = common::fem_block_press(4.0 * (k as f32 / 150.0).min(1.0) - 0.5);
        });
    }
}
