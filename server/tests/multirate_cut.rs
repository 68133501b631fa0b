//! Cutting a multi-rate organ (issue 33): `worlds/liver_incision.toml`, the shipped liver (13,224 corotational
//! tetrahedra stepped at 25 Hz on a thread of its own) with a scalpel and the grasper. The grasper retracts the
//! lobe, the scalpel draws an incision across it; the cut follows the blade on the organ's latest finished step,
//! the organ's own step takes the cut model at its next hand-off, and the incision gapes under the retraction.
//! A run with the steps on a thread gives the same bits as one run inline. The same organ tears where the jaws
//! pull it past its limit, and burns where a cautery tip touches it.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;
#[path = "common/counting_allocator.rs"]
mod counting_allocator;

use counting_allocator::{Counting, assert_counting_works, count_all_threads, serial};

// The tests of this binary run one at a time (`serial`): the allocation count sees every thread's allocations.

#[global_allocator]
static GLOBAL: Counting = Counting;

use nalgebra::{Vector2, Vector3};
use sinew_server::interaction::CauterySpec;
use sinew_server::node::step_threads::ThreadRunner;
use sinew_server::sim::{Sim, SimObject, StepReport, ToolCommand, ToolOutput};
use sinew_server::tissue::Vec3;
use sinew_server::world::{InstrumentSpec, World, load_world};

use common::worst_kept_quality;

fn world() -> World {
    load_world(&common::worlds().join("liver_incision.toml"))
        .expect("the liver incision world loads")
}

/// The scalpel's device origin (tool 0), world mm.
const SCALPEL_X_MM: f32 = 25.0;
/// The grasper's (tool 1).
const GRASPER_X_MM: f32 = 40.0;
/// How deep the jaws bite, mm.
const BITE_DEPTH_MM: f32 = 3.0;
/// The grasper's sphere radius, mm.
const GRASPER_RADIUS_MM: f32 = 4.0;
/// The scalpel's blunt back (a sphere at its origin), mm.
const SCALPEL_BACK_MM: f32 = 1.0;
/// Where the incision runs: along y at the scalpel's x, from here to there, mm (world).
const INCISION_Y_MM: (f32, f32) = (-20.0, 15.0);
/// How far the grasper retracts the lobe away from the incision (+x) and up, mm.
const RETRACT_MM: (f32, f32) = (4.0, 3.0);

fn scalpel_at(y_mm: f32, z_mm: f32) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [0.0, y_mm, z_mm],
        ..ToolCommand::default()
    }
}

fn grasper_at(offset_mm: Vec3, bottom_z_mm: f32, closed: bool) -> ToolCommand {
    common::jaws_at(
        [offset_mm.x, offset_mm.y, bottom_z_mm + GRASPER_RADIUS_MM],
        closed,
    )
}

/// What one run of the script saw.
#[derive(Default)]
struct Run {
    /// Both tools' forces every tick, N.
    forces: Vec<[Vector3<f32>; 2]>,
    report: StepReport,
    /// The organ's vertex count before and after the cut.
    vertices: (usize, usize),
    /// The mean and largest gap between the incision's faces, mm, just after the cut and a second later.
    gap_after_cut_mm: (f32, f32),
    gap_settled_mm: (f32, f32),
    /// The vertices the cut made by splitting edges: their largest distance from the blade's plane as the draw
    /// ended, mm.
    off_plane_mm: f32,
}

/// The largest distance from the plane x = `SCALPEL_X_MM` of the vertices a subdivision made (those past
/// `first_new` whose rest position is not their parent's), mm (world, now).
fn off_plane_mm(object: &SimObject, first_new: usize) -> f32 {
    let (first, parents) = object.split_parents();
    let rest = object.model.rest_positions_mm();
    parents
        .iter()
        .enumerate()
        .map(|(k, &p)| (first as usize + k, p as usize))
        .filter(|&(c, p)| c >= first_new && rest[c] != rest[p])
        .map(|(c, _)| (object.state.positions_mm[c].x - SCALPEL_X_MM).abs())
        .fold(0.0, f32::max)
}

/// Step `sim` through `commands`; every output finite and within its limit, no fault.
fn drive(sim: &mut Sim, run: &mut Run, commands: impl Iterator<Item = [ToolCommand; 2]>) {
    let mut out = [ToolOutput::default(); 2];
    for command in commands {
        let report = sim.step(0.001, &command, &mut out);
        assert_eq!(report.faults, 0, "the organ was reset");
        for o in &out {
            let f = o.force_world_n;
            assert!(
                f.iter().all(|c| c.is_finite()) && f.norm() <= 3.3 + 1e-4,
                "{f:?}"
            );
        }
        run.forces
            .push([out[0].force_world_n, out[1].force_world_n]);
        let r = &mut run.report;
        r.grasps_taken += report.grasps_taken;
        r.attachments_slipped += report.attachments_slipped;
        r.vertices_split += report.vertices_split;
        r.seams_cut += report.seams_cut;
        r.seams_torn += report.seams_torn;
        r.retries += report.retries;
    }
}

/// The incision's gap: over every vertex an opening copied (a split-off vertex with its parent's rest
/// position: the two faces of the cut), the distance between the copy and its parent now; mean and largest,
/// mm.
fn gap_mm(object: &SimObject) -> (f32, f32) {
    let (first, parents) = object.split_parents();
    let rest = object.model.rest_positions_mm();
    let x = &object.state.positions_mm;
    let gaps: Vec<f32> = parents
        .iter()
        .enumerate()
        .map(|(k, &p)| (first as usize + k, p as usize))
        .filter(|&(c, p)| rest[c] == rest[p])
        .map(|(c, p)| (x[c] - x[p]).norm())
        .collect();
    assert!(!gaps.is_empty(), "nothing opened");
    let mean = gaps.iter().sum::<f32>() / gaps.len() as f32;
    (mean, gaps.iter().copied().fold(0.0, f32::max))
}

/// The script: the grasper takes the lobe right of the incision and retracts it (1.6 s); the scalpel comes
/// down onto the surface and draws the incision along y at 20 mm/s, its back riding 0.2 mm into the rest
/// surface (the edge 12 mm deep), then lifts out (2.3 s); everything holds 1 s.
fn incise(sim: &mut Sim, retract: bool) -> Run {
    let mut run = Run::default();
    let o = &sim.objects[0];
    let grasp_top = common::rest_surface_z_mm(o, GRASPER_X_MM, 0.0);
    let bite = grasp_top - BITE_DEPTH_MM;
    let back_z = |y: f32| common::rest_surface_z_mm(o, SCALPEL_X_MM, y) + SCALPEL_BACK_MM - 0.2;
    let (y0, y1) = INCISION_Y_MM;
    let path: Vec<f32> = (0..=200)
        .map(|k| back_z(y0 + (y1 - y0) * k as f32 / 200.0))
        .collect();
    let back_at = |y: f32| {
        let s = ((y - y0) / (y1 - y0)).clamp(0.0, 1.0) * 200.0;
        let k = (s as usize).min(199);
        path[k] + (path[k + 1] - path[k]) * (s - k as f32)
    };
    run.vertices.0 = o.model.node_count();
    let idle = ToolCommand::default();
    let (dx, dz) = if retract { RETRACT_MM } else { (0.0, 0.0) };
    let retracted = Vec3::new(dx, 0.0, 0.0);
    // The grasper: down 0.5 s, settle 0.4 s, close 0.2 s, retract over 0.5 s.
    drive(
        sim,
        &mut run,
        (0..500).map(|k| {
            let z = grasp_top + 10.0 - (10.0 + BITE_DEPTH_MM) * (k + 1) as f32 / 500.0;
            [idle, grasper_at(Vec3::zeros(), z, false)]
        }),
    );
    drive(
        sim,
        &mut run,
        (0..400).map(|_| [idle, grasper_at(Vec3::zeros(), bite, false)]),
    );
    drive(
        sim,
        &mut run,
        (0..200).map(|_| [idle, grasper_at(Vec3::zeros(), bite, true)]),
    );
    drive(
        sim,
        &mut run,
        (0..500).map(|k| {
            let s = (k + 1) as f32 / 500.0;
            [idle, grasper_at(retracted * s, bite + dz * s, true)]
        }),
    );
    let held = grasper_at(retracted, bite + dz, true);
    // The scalpel: down from 8 mm above the incision's start over 0.3 s, draw it at 20 mm/s, lift out 0.25 s.
    let start = back_at(y0);
    drive(
        sim,
        &mut run,
        (0..300).map(|k| {
            [
                scalpel_at(y0, start + 8.0 * (1.0 - (k + 1) as f32 / 300.0)),
                held,
            ]
        }),
    );
    let draw_ticks = ((y1 - y0) / 0.02) as usize;
    drive(
        sim,
        &mut run,
        (0..draw_ticks).map(|k| {
            let y = y0 + 0.02 * (k + 1) as f32;
            [scalpel_at(y, back_at(y)), held]
        }),
    );
    let end = back_at(y1);
    drive(
        sim,
        &mut run,
        (0..250).map(|k| [scalpel_at(y1, end + 15.0 * (k + 1) as f32 / 250.0), held]),
    );
    run.vertices.1 = sim.objects[0].model.node_count();
    run.off_plane_mm = off_plane_mm(&sim.objects[0], run.vertices.0);
    // Two hand-offs: the organ's step has taken the cut model and stepped once with it.
    drive(sim, &mut run, (0..80).map(|_| [idle, held]));
    run.gap_after_cut_mm = gap_mm(&sim.objects[0]);
    drive(sim, &mut run, (0..1000).map(|_| [idle, held]));
    run.gap_settled_mm = gap_mm(&sim.objects[0]);
    run
}

/// The liver's surface nodes are 3-5 mm apart: the cut's vertices lie on the blade's plane within 5% of that.
const ON_PLANE_MM: f32 = 0.2;

#[test]
fn an_incision_in_the_retracted_liver_follows_the_blade_and_gapes() {
    let _serial = serial();
    let mut lying = Sim::new(&world()).unwrap();
    let mut retracted = Sim::new(&world()).unwrap();
    assert_eq!(
        retracted.objects[0].step_lane().unwrap().ticks_per_step(),
        40,
        "the liver steps at 25 Hz"
    );
    let tets_before = retracted.objects[0].model.tets().tets.len();
    let still = incise(&mut lying, false);
    let run = incise(&mut retracted, true);
    let o = &retracted.objects[0];
    println!(
        "incision: {} vertices added ({} -> {}), {} of them opened, {} facets cut, tetrahedra {} -> {}",
        run.vertices.1 - run.vertices.0,
        run.vertices.0,
        run.vertices.1,
        run.report.vertices_split,
        run.report.seams_cut,
        tets_before,
        o.model.tets().tets.len(),
    );
    println!(
        "gap between the faces, mean / largest: retracted {:.3} / {:.3} mm two steps after the cut, {:.3} / {:.3} \
         mm a second later; lying still {:.3} / {:.3} mm a second later",
        run.gap_after_cut_mm.0,
        run.gap_after_cut_mm.1,
        run.gap_settled_mm.0,
        run.gap_settled_mm.1,
        still.gap_settled_mm.0,
        still.gap_settled_mm.1,
    );
    println!(
        "the cut's new vertices off the blade's plane as the draw ended: lying still {:.3} mm, retracted {:.3} mm",
        still.off_plane_mm, run.off_plane_mm
    );
    // The hand holding the retractor feels the cut soften the lobe, without a jolt: ticks from the scalpel's
    // descent to a second after the cut (the pad's grasp holds a take to the same 0.05 N a tick).
    let jolt = run.forces[1600..]
        .windows(2)
        .map(|w| (w[1][1] - w[0][1]).norm())
        .fold(0.0f32, f32::max);
    let held_before = run.forces[1599][1];
    let held_after = run.forces.last().unwrap()[1];
    println!(
        "the retractor's pull {held_before:?} N before the cut, {held_after:?} N after; it changed by {jolt:.4} N \
         in a tick at most"
    );
    assert!(
        jolt < 0.05,
        "the retractor's force jumped {jolt} N in a tick"
    );
    for (what, r) in [("retracted", &run), ("lying still", &still)] {
        assert!(
            r.vertices.1 > r.vertices.0,
            "{what}: the scalpel cut nothing"
        );
        assert!(r.report.seams_cut > 0, "{what}: nothing opened");
    }
    assert_eq!(run.report.grasps_taken, 1, "the jaws took the lobe");
    assert_eq!(run.report.attachments_slipped, 0);
    assert!(
        o.model.tets().tets.len() > tets_before,
        "no tetrahedron was split"
    );
    // The cut follows the blade: lying still, its new vertices are where the edge crossed the tissue.
    assert!(
        still.off_plane_mm < ON_PLANE_MM,
        "a vertex of the cut lies {} mm off the blade's plane",
        still.off_plane_mm
    );
    // The incision gapes under the retraction, and stays open.
    assert!(
        run.gap_settled_mm.0 > 2.0 * still.gap_settled_mm.0 && run.gap_settled_mm.0 > 0.2,
        "retracted, the incision's faces are {} mm apart on average; lying still {} mm",
        run.gap_settled_mm.0,
        still.gap_settled_mm.0
    );
    assert!(
        run.gap_settled_mm.0 > 0.8 * run.gap_after_cut_mm.0,
        "the incision closed"
    );
    // The organ stays whole and well shaped: the state is the model's, finite, and no tetrahedron turned
    // over or flattened past a fifth of its rest quality in the second after the cut.
    for sim in [&retracted, &lying] {
        let o = &sim.objects[0];
        assert_eq!(o.state.positions_mm.len(), o.model.node_count());
        assert!(o.state.is_finite());
        let worst = worst_kept_quality(o);
        println!("the worst tetrahedron keeps {worst:.3} of its rest quality");
        assert!(
            worst > 0.2,
            "a tetrahedron flattened or turned over: {worst}"
        );
    }
}

#[test]
fn cutting_the_organ_on_its_own_thread_gives_the_same_bits_as_inline() {
    let _serial = serial();
    let mut inline = Sim::new(&world()).unwrap();
    let mut threaded = Sim::new(&world()).unwrap();
    threaded.set_step_runners(|object| Box::new(ThreadRunner::spawn(object).unwrap()));
    let a = incise(&mut inline, true);
    let b = incise(&mut threaded, true);
    assert!(a.vertices.1 > a.vertices.0);
    assert_eq!(a.vertices, b.vertices);
    common::assert_same_bits(&a.forces, &b.forces, &inline, &threaded);
}

#[test]
fn after_the_cut_the_organs_ticks_allocate_nothing() {
    let _serial = serial();
    for threaded in [false, true] {
        let mut sim = Sim::new(&world()).unwrap();
        if threaded {
            sim.set_step_runners(|object| Box::new(ThreadRunner::spawn(object).unwrap()));
        }
        let run = incise(&mut sim, true);
        assert!(run.vertices.1 > run.vertices.0);
        let version = sim.objects[0].topology_version();
        let o = &sim.objects[0];
        let held_z = common::rest_surface_z_mm(o, GRASPER_X_MM, 0.0) - BITE_DEPTH_MM + RETRACT_MM.1;
        let lifted = scalpel_at(
            INCISION_Y_MM.1,
            common::rest_surface_z_mm(o, SCALPEL_X_MM, INCISION_Y_MM.1) + 20.0,
        );
        let mut out = [ToolOutput::default(); 2];
        assert_counting_works();
        // Ten steps of the retracted lobe swaying 1 mm either way (hand-offs, holds, settles and solves on the
        // cut model), the scalpel lifted out.
        let allocations = count_all_threads(|| {
            for k in 0..400 {
                let sway = (k as f32 * 0.0157).sin();
                let command = [
                    lifted,
                    grasper_at(Vec3::new(RETRACT_MM.0 + sway, 0.0, 0.0), held_z, true),
                ];
                sim.step(0.001, &command, &mut out);
            }
        });
        assert_eq!(
            sim.objects[0].topology_version(),
            version,
            "the scalpel cut again"
        );
        assert_eq!(
            allocations, 0,
            "threaded {threaded}: {allocations} allocations"
        );
    }
}

/// The liver made to tear at 30% strain, its grasper holding on up to 5 N a point.
fn tearing_world() -> World {
    let mut world = world();
    world.objects[0].material.tear_strain = Some(0.3);
    let InstrumentSpec::Grasper(spec) = &mut world.tools[1].instrument else {
        panic!("tool 1 is the grasper");
    };
    spec.slip_force_n = 5.0;
    world
}

/// The grasper takes the lobe and lifts it `lift_mm` over 1 s, then holds 1 s; the scalpel stays away.
fn take_and_tear(sim: &mut Sim, lift_mm: f32) -> Run {
    let mut run = Run::default();
    let top = common::rest_surface_z_mm(&sim.objects[0], GRASPER_X_MM, 0.0);
    let bite = top - BITE_DEPTH_MM;
    run.vertices.0 = sim.objects[0].model.node_count();
    let idle = ToolCommand::default();
    let at = |z: f32, closed: bool| [idle, grasper_at(Vec3::zeros(), z, closed)];
    drive(
        sim,
        &mut run,
        (0..500).map(|k| {
            at(
                top + 10.0 - (10.0 + BITE_DEPTH_MM) * (k + 1) as f32 / 500.0,
                false,
            )
        }),
    );
    drive(sim, &mut run, (0..400).map(|_| at(bite, false)));
    drive(sim, &mut run, (0..200).map(|_| at(bite, true)));
    drive(
        sim,
        &mut run,
        (0..1000).map(|k| at(bite + lift_mm * (k + 1) as f32 / 1000.0, true)),
    );
    drive(sim, &mut run, (0..1000).map(|_| at(bite + lift_mm, true)));
    run.vertices.1 = sim.objects[0].model.node_count();
    run
}

#[test]
fn a_liver_lobe_pulled_past_its_limit_tears_on_its_own_thread_as_inline() {
    let _serial = serial();
    let mut inline = Sim::new(&tearing_world()).unwrap();
    let mut threaded = Sim::new(&tearing_world()).unwrap();
    threaded.set_step_runners(|object| Box::new(ThreadRunner::spawn(object).unwrap()));
    let a = take_and_tear(&mut inline, 25.0);
    let b = take_and_tear(&mut threaded, 25.0);
    let o = &inline.objects[0];
    println!(
        "lifted 25 mm: {} facets torn, {} vertices added ({} -> {}), {} points slipped; the pull peaked at {:.3} N",
        a.report.seams_torn,
        a.vertices.1 - a.vertices.0,
        a.vertices.0,
        a.vertices.1,
        a.report.attachments_slipped,
        a.forces.iter().map(|f| f[1].norm()).fold(0.0f32, f32::max),
    );
    assert_eq!(a.report.grasps_taken, 1, "the jaws took the lobe");
    assert!(a.report.seams_torn > 0, "a 25 mm lift tore nothing");
    assert!(a.vertices.1 > a.vertices.0, "the tear opened nothing");
    assert_eq!(o.state.positions_mm.len(), o.model.node_count());
    assert!(o.state.is_finite());
    common::assert_same_bits(&a.forces, &b.forces, &inline, &threaded);
}

#[test]
fn a_cautery_tip_burns_the_multi_rate_liver_where_it_touches_and_the_burn_survives_the_hand_offs() {
    let _serial = serial();
    let mut world = world();
    world.tools[0].instrument = InstrumentSpec::Cautery(CauterySpec::DEFAULT);
    let mut sim = Sim::new(&world).unwrap();
    // The surface node nearest the scalpel's device origin (the tool is tool 0): the tip (a 1 mm sphere at the
    // tool's origin) rests 0.5 mm into it with the current on for 1 s, then lifts away for 0.5 s. (The burn is
    // per vertex: on the liver's 3-5 mm surface a 1 mm tip burns the vertices it touches, not the triangles
    // between them.)
    let rest = sim.objects[0].model.rest_positions_mm().to_vec();
    let target = (0..rest.len())
        .filter(|&i| (rest[i].xy() - Vector2::new(SCALPEL_X_MM, 0.0)).norm() < 3.0)
        .max_by(|&a, &b| rest[a].z.total_cmp(&rest[b].z))
        .unwrap();
    let p = rest[target];
    let at = |lift_mm: f32, on: bool| ToolCommand {
        active: true,
        position_device_mm: [p.x - SCALPEL_X_MM, p.y, p.z + SCALPEL_BACK_MM + lift_mm],
        jaws: sinew_server::interaction::JawInput {
            buttons: u32::from(on),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    };
    let idle = ToolCommand::default();
    let mut run = Run::default();
    drive(
        &mut sim,
        &mut run,
        (0..300).map(|k| [at(5.0 - 5.5 * (k + 1) as f32 / 300.0, false), idle]),
    );
    let mut burnt_ticks = 0;
    let mut out = [ToolOutput::default(); 2];
    for _ in 0..1000 {
        let report = sim.step(0.001, &[at(-0.5, true), idle], &mut out);
        assert_eq!(report.faults, 0);
        burnt_ticks += u32::from(report.nodes_burnt > 0);
    }
    let burnt_then: Vec<u16> = sim.objects[0].burn().to_vec();
    drive(
        &mut sim,
        &mut run,
        (0..500).map(|_| [at(20.0, false), idle]),
    );
    let burn = sim.objects[0].burn();
    let touched = burn.iter().filter(|&&b| b > 0).count();
    println!(
        "the tip burnt on {burnt_ticks} of 1000 ticks: {touched} vertices burnt, the one under it to level {}",
        burn[target] >> 8
    );
    assert!(burnt_ticks > 900, "the tip burnt on {burnt_ticks} ticks");
    assert_eq!(
        burn[target] >> 8,
        255,
        "the vertex under the tip is not charred"
    );
    // Burns are the object's own record, not the step's state: twelve hand-offs later they are as they were.
    assert_eq!(burn, burnt_then.as_slice());
    // Nothing burnt away from the tip.
    for (i, _) in burn.iter().enumerate().filter(|(_, b)| **b > 0) {
        assert!(
            (rest[i] - p).norm() < 3.0,
            "vertex {i} at {:?} burnt, away from the tip at {p:?}",
            rest[i]
        );
    }
}
