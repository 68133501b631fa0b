//! Finite-element tissue in the simulation (issue 13): the shipped `fem_block` world loads from material data,
//! pushes back on a probe with a force that grows with depth, relaxes when the probe leaves, and agrees with
//! the same world's elements solved without corotation at small depth.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use common::{fem_block_press as press, worlds};
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::{World, load_world};

/// Move the left probe to `depth_mm` over `ticks` and hold it `hold` more; returns the last output.
fn move_to(sim: &mut Sim, from_mm: f32, depth_mm: f32, ticks: usize, hold: usize) -> ToolOutput {
    let mut outputs = common::fem_block_move(sim, from_mm, depth_mm, ticks, hold);
    outputs.pop().expect("at least one tick")
}

fn fem_block_world() -> World {
    load_world(&worlds().join("fem_block.toml")).expect("fem_block world loads")
}

#[test]
fn the_fem_block_presses_back_harder_the_deeper_it_goes_and_relaxes_after() {
    let world = fem_block_world();
    let material = world.objects[0].material.fem.expect("finite elements");
    assert!((material.youngs_modulus_n_per_mm2 - 5e-3).abs() < 1e-9);
    assert!(material.corotated);
    let mut sim = Sim::new(&world).unwrap();
    assert_eq!(sim.objects[0].model.fem().material(), Some(material));
    // The springs carry no stiffness: every bit of the push comes from the elements.
    assert!(
        sim.objects[0]
            .model
            .springs()
            .stiffness_n_per_mm
            .iter()
            .all(|&k| k == 0.0)
    );

    let mut forces = Vec::new();
    let mut from = 0.0;
    for depth in [1.0f32, 2.0, 3.0] {
        let out = move_to(&mut sim, from, depth, 200, 200);
        let f = out.force_world_n;
        println!(
            "{depth} mm deep: force {f:?} N, {} held nodes",
            out.held_nodes
        );
        assert!(out.in_contact && out.held_nodes > 0);
        assert!(
            f.z > 0.0 && f.z > 0.95 * f.norm(),
            "force {f:?} not along +z"
        );
        forces.push(f.z);
        from = depth;
    }
    assert!(forces.windows(2).all(|w| w[1] > 1.5 * w[0]), "{forces:?}");
    // Hertz for a 4 mm sphere on a half-space of E = 5 kPa, nu = 0.45 at 3 mm is 0.087 N. This block is only
    // 10 mm thick on a fixed floor, which stiffens it, and its elements (about 2 mm) resolve a 3.5 mm contact
    // radius coarsely, which softens it; on a fine mesh the same simulation path is within 1-5% of Hertz
    // (tests/tests/hertz.rs). So near Hertz, within -20% / +100%. (Before the held nodes were pinned in the
    // implicit solve, this read 0.18 N: the bound here was then "above 0.087 N".)
    assert!(forces[2] > 0.07 && forces[2] < 0.174, "{forces:?}");

    // Lift off: the surface comes back to rest.
    let out = move_to(&mut sim, 3.0, -5.0, 200, 800);
    assert!(!out.in_contact);
    let object = &sim.objects[0];
    let furthest = common::furthest_from_rest_mm(object);
    assert!(furthest < 0.05, "{furthest} mm from rest after release");
}

#[test]
fn a_region_tracked_fem_block_feels_like_the_whole_one() {
    // The region of deformation keeps the finite elements in its sub-model, and the force at the hand agrees
    // with the whole block's. (On this block it saves nothing: with no anchors to the tissue beneath, an
    // elastic dent's displacement decays like 1 / distance, so a 3 mm dent moves every node of a 40 mm block
    // by more than the 1 um threshold and the region grows to the whole block.)
    let whole_world = fem_block_world();
    let region_world = common::scene_edits::with_region(fem_block_world(), 0, 0.001);
    let mut whole = Sim::new(&whole_world).unwrap();
    let mut region = Sim::new(&region_world).unwrap();
    let (a, b) = (
        move_to(&mut whole, 0.0, 3.0, 300, 300).force_world_n,
        move_to(&mut region, 0.0, 3.0, 300, 300).force_world_n,
    );
    let active = region.objects[0].region().unwrap().active_nodes().len();
    println!(
        "3 mm: whole {a:?} N, region {b:?} N ({active} of {} nodes active)",
        region.objects[0].model.node_count()
    );
    assert!(active > 0);
    assert!(
        (a - b).norm() < 0.03 * a.norm(),
        "whole {a:?}, region {b:?}"
    );
}

#[test]
fn the_local_model_of_an_fem_block_has_the_stiffness_the_hand_feels() {
    // The latency-moderated mode renders the local model's K at 1 kHz between server updates. An FEM object's
    // springs carry no stiffness, so the contact solve must see the elements: its K is the ceiling of the
    // fitted slope, and was zero before it did.
    let world = fem_block_world();
    let mut sim = Sim::new(&world).unwrap();
    let f2 = move_to(&mut sim, 0.0, 2.0, 300, 300).force_world_n.z;
    let out = move_to(&mut sim, 2.0, 2.5, 100, 300);
    let slope_n_per_mm = (out.force_world_n.z - f2) / 0.5;
    let solved = sim.tools[0]
        .contact_response(0)
        .expect("a finished contact solve")
        .stiffness_n_per_mm[(2, 2)];
    let rendered = out.stiffness_n_per_mm[(2, 2)];
    println!(
        "2-2.5 mm: measured slope {slope_n_per_mm:.4} N/mm, solved K {solved:.4} N/mm, local model K {rendered:.4} N/mm"
    );
    assert!(slope_n_per_mm > 0.0);
    // The frozen-contact solve is the static slope of its held set: a little under the slope measured between
    // two holds (the real contact is a little wider than the nodes held), and not wildly off either way.
    assert!(
        solved > 0.6 * slope_n_per_mm && solved < 4.0 * slope_n_per_mm,
        "solved {solved} N/mm against a slope of {slope_n_per_mm} N/mm"
    );
    // What the hand gets is the slope fitted during the motion (the tissue lags a 5 mm/s press, so it is
    // softer than the static one), capped by the solve: not zero.
    assert!(
        rendered > 0.1 * slope_n_per_mm && rendered <= solved + 1e-6,
        "local model K {rendered} N/mm against a slope of {slope_n_per_mm} N/mm (solved {solved})"
    );
}

#[test]
fn the_shipped_liver_is_a_gmsh_organ_of_finite_elements_with_the_liver_preset() {
    let world = load_world(&worlds().join("liver.toml")).expect("liver world loads");
    let object = &world.objects[0];
    assert!(
        object.tets.len() >= 10_000,
        "{} tetrahedra",
        object.tets.len()
    );
    let material = object.material.fem.expect("finite elements");
    let presets = sinew_server::world::material_presets().unwrap();
    let liver = &presets["liver"];
    assert!((material.youngs_modulus_n_per_mm2 - liver.youngs_modulus_kpa * 1e-3).abs() < 1e-9);
    assert_eq!(material.poisson_ratio, liver.poisson_ratio);
    let kinds: Vec<&str> = world
        .tools
        .iter()
        .map(|t| t.instrument.kind_name())
        .collect();
    assert_eq!(kinds, ["probe", "grasper"]);
    // A multi-rate object: 25 Hz, one step every 40 ticks.
    assert_eq!(object.ticks_per_step, 40);
    // A few ticks of a probe pressing the right lobe: it pushes back, up.
    let mut sim = Sim::new(&world).unwrap();
    assert_eq!(sim.objects[0].step_lane().unwrap().ticks_per_step(), 40);
    let mut out = [ToolOutput::default(); 2];
    // Down 6 mm in 100 ticks, then held: the organ answers the pose of each hand-off 40 ticks later.
    for k in 0..200 {
        let z = (4.0 - 0.06 * k as f32).max(-2.0);
        let command = ToolCommand {
            position_device_mm: [0.0, 0.0, z],
            ..press(0.0)
        };
        sim.step(0.001, &[command, ToolCommand::default()], &mut out);
    }
    assert!(
        out[0].in_contact && out[0].force_world_n.z > 0.0,
        "{:?}",
        out[0]
    );
}
