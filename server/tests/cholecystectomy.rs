//! A cholecystectomy's dissection (issue 33): `worlds/cholecystectomy.toml`, a liver (multi-rate, 25 Hz) with the
//! gallbladder in its bed, held to the bed's floor by a plate of connective tissue. The grasper takes the fundus
//! and retracts it; the plate pulls back. The hook is lowered into the bed beside the plate and drawn across the
//! floor through the plate: the cut follows its edge, the gallbladder comes free (no element path joins the
//! fundus to the fixed floor any more), the same retraction's pull falls away, and the liver is untouched.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use nalgebra::Vector3;
use sinew_server::sim::{Sim, SimObject, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

/// Object indices in the world file.
const LIVER: usize = 0;
const GALLBLADDER: usize = 1;
/// The grasper is tool 1 in the world file (the hook tool 0); the tools' device origins, world mm.
const GRASPER: usize = 1;
const HOOK_ORIGIN_MM: [f32; 3] = [24.0, 0.0, 25.2];
const GRASPER_ORIGIN_MM: [f32; 3] = [38.0, 0.0, 10.8];
/// The hook's edge, below its body, mm (the world file's `edge_from_mm`/`edge_to_mm` z).
const HOOK_EDGE_BELOW_MM: f32 = 30.0;
/// The grasper's sphere, mm, and how deep its jaws bite into the fundus, mm.
const GRASPER_RADIUS_MM: f32 = 4.0;
const BITE_DEPTH_MM: f32 = 3.0;
/// The retraction: up and toward the fundus's end, mm.
const RETRACT_UP_MM: f32 = 8.0;
const RETRACT_OUT_MM: f32 = 4.0;
/// Where the hook's edge divides the plate (the floor is at z = -4, the plate's top at -1), world mm.
const DISSECT_Z_MM: f32 = -3.3;
/// The dissection runs across the bed from beside the plate to beside it on the other side, world y mm.
const DISSECT_Y_MM: (f32, f32) = (-20.0, 20.0);

fn idle() -> ToolCommand {
    ToolCommand::default()
}

/// The grasper with its sphere's bottom at `bottom_z_mm`, moved `out_mm` along x from its origin.
fn grasper(out_mm: f32, bottom_z_mm: f32, closed: bool) -> ToolCommand {
    common::jaws_at(
        [
            out_mm,
            0.0,
            bottom_z_mm + GRASPER_RADIUS_MM - GRASPER_ORIGIN_MM[2],
        ],
        closed,
    )
}

/// The hook with its edge at world (`y_mm`, `edge_z_mm`).
fn hook(y_mm: f32, edge_z_mm: f32) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [
            0.0,
            y_mm - HOOK_ORIGIN_MM[1],
            edge_z_mm + HOOK_EDGE_BELOW_MM - HOOK_ORIGIN_MM[2],
        ],
        ..ToolCommand::default()
    }
}

/// Step through `commands`; every force finite and within the limit, no fault. The grasper's force each tick.
/// Step through `commands`; every force finite and within the limit, no fault. The grasper's force each tick.
fn drive(sim: &mut Sim, commands: impl Iterator<Item = [ToolCommand; 2]>) -> Vec<Vector3<f32>> {
    let mut out = [ToolOutput::default(); 2];
    let mut grasper_n = Vec::new();
    for command in commands {
        let report = sim.step(0.001, &command, &mut out);
        assert_eq!(report.faults, 0, "an object was reset");
        for o in &out {
            let f = o.force_world_n;
            assert!(
                f.iter().all(|c| c.is_finite()) && f.norm() <= 3.3 + 1e-4,
                "{f:?}"
            );
        }
        grasper_n.push(out[GRASPER].force_world_n);
    }
    grasper_n
}

fn mean(forces: &[Vector3<f32>]) -> Vector3<f32> {
    forces.iter().sum::<Vector3<f32>>() / forces.len().max(1) as f32
}

/// Whether some chain of tetrahedra sharing vertices joins `node` to a fixed node.
fn joined_to_the_floor(object: &SimObject, node: usize) -> bool {
    let n = object.model.node_count();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for tet in &object.model.tets().tets {
        let a = root(&mut parent, tet[0] as usize);
        for &v in &tet[1..] {
            let b = root(&mut parent, v as usize);
            parent[b] = a;
        }
    }
    let mine = root(&mut parent, node);
    (0..n).any(|i| object.model.is_fixed(i) && root(&mut parent, i) == mine)
}

/// The gallbladder's node nearest the fundus's tip (its end at x = 44 mm), by rest position.
fn fundus_node(object: &SimObject) -> usize {
    let tip = Vector3::new(44.0, 0.0, 6.0);
    object
        .model
        .rest_positions_mm()
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - tip).norm().total_cmp(&(b.1 - tip).norm()))
        .map(|(i, _)| i)
        .unwrap()
}

/// What a retraction felt and did.
struct Retraction {
    /// The grasper's mean force over the hold's first 0.2 s, N.
    early_pull_n: Vector3<f32>,
    /// The grasper's mean force over the hold's last 0.2 s, N.
    pull_n: Vector3<f32>,
    /// How far the fundus's tip rose, mm.
    lift_mm: f32,
    /// The grasper's command holding the retraction.
    held: ToolCommand,
}

/// The grasper comes down onto the fundus (0.5 s), settles (0.3 s), closes (0.2 s), retracts up and out over
/// 1 s and holds 2 s.
fn retract_fundus(sim: &mut Sim) -> Retraction {
    let object = &sim.objects[GALLBLADDER];
    let fundus = fundus_node(object);
    let top = common::rest_surface_z_mm(object, GRASPER_ORIGIN_MM[0], 0.0);
    let bite = top - BITE_DEPTH_MM;
    let descend = (0..500).map(|k| {
        let s = (k + 1) as f32 / 500.0;
        [
            idle(),
            grasper(0.0, top + 8.0 - (8.0 + BITE_DEPTH_MM) * s, false),
        ]
    });
    drive(sim, descend);
    drive(sim, (0..300).map(|_| [idle(), grasper(0.0, bite, false)]));
    drive(sim, (0..200).map(|_| [idle(), grasper(0.0, bite, true)]));
    let retracted = |s: f32| {
        [
            idle(),
            grasper(RETRACT_OUT_MM * s, bite + RETRACT_UP_MM * s, true),
        ]
    };
    drive(sim, (0..1000).map(|k| retracted((k + 1) as f32 / 1000.0)));
    let held = drive(sim, (0..2000).map(|_| retracted(1.0)));
    let object = &sim.objects[GALLBLADDER];
    Retraction {
        held: retracted(1.0)[GRASPER],
        early_pull_n: mean(&held[..200]),
        pull_n: mean(&held[1800..]),
        lift_mm: (object.state.positions_mm[fundus] - object.model.rest_positions_mm()[fundus]).z,
    }
}

/// The hook lowered into the bed beside the plate (0.5 s), drawn across the bed through the plate at 20 mm/s,
/// lifted out (0.3 s); then 0.5 s still. The grasper does `grasper` meanwhile. The grasper's force over the
/// last 0.2 s, N.
fn dissect(sim: &mut Sim, grasper: ToolCommand) -> Vector3<f32> {
    let (y0, y1) = DISSECT_Y_MM;
    let lower = (0..500).map(|k| {
        let s = (k + 1) as f32 / 500.0;
        [hook(y0, DISSECT_Z_MM + 20.0 * (1.0 - s)), grasper]
    });
    drive(sim, lower);
    let draw_ticks = ((y1 - y0) / 0.02) as usize;
    drive(
        sim,
        (0..draw_ticks).map(|k| [hook(y0 + 0.02 * (k + 1) as f32, DISSECT_Z_MM), grasper]),
    );
    let lift = (0..300).map(|k| {
        [
            hook(y1, DISSECT_Z_MM + 20.0 * (k + 1) as f32 / 300.0),
            grasper,
        ]
    });
    drive(sim, lift);
    mean(&drive(sim, (0..500).map(|_| [idle(), grasper]))[300..])
}

#[test]
fn the_hook_divides_the_plate_and_the_gallbladder_lifts_free() {
    let world = load_world(&common::worlds().join("cholecystectomy.toml")).unwrap();
    let mut intact = Sim::new(&world).unwrap();
    let mut dissected = Sim::new(&world).unwrap();
    assert_eq!(
        intact.objects[LIVER].step_lane().unwrap().ticks_per_step(),
        40,
        "the liver steps at 25 Hz"
    );
    assert!(
        intact.objects[GALLBLADDER].step_lane().is_none(),
        "the gallbladder steps every tick"
    );
    let object = &intact.objects[GALLBLADDER];
    let (nodes, tets) = (object.model.node_count(), object.model.tets().tets.len());
    let fixed = (0..nodes).filter(|&i| object.model.is_fixed(i)).count();
    let fundus = fundus_node(object);
    assert!(fixed > 50, "the plate's floor holds {fixed} nodes");
    assert!(joined_to_the_floor(object, fundus));
    let liver_nodes = intact.objects[LIVER].model.node_count();

    dissect(&mut dissected, idle());
    let object = &dissected.objects[GALLBLADDER];
    let cut = (object.model.node_count(), object.model.tets().tets.len());
    assert!(
        !joined_to_the_floor(object, fundus),
        "the fundus is still joined to the bed's floor"
    );
    let held = retract_fundus(&mut intact);
    let free = retract_fundus(&mut dissected);
    println!(
        "cholecystectomy: the plate's floor {fixed} nodes; the dissection took the gallbladder from {nodes} nodes and \
         {tets} tetrahedra to {} and {}; retracted {RETRACT_UP_MM} mm up and {RETRACT_OUT_MM} mm out: attached, \
         the grasper feels {:.3} N at the hold's start and {:.3} N 2 s on (fundus up {:.2} mm); dissected, {:.3} N \
         and {:.3} N (fundus up {:.2} mm)",
        cut.0,
        cut.1,
        held.early_pull_n.norm(),
        held.pull_n.norm(),
        held.lift_mm,
        free.early_pull_n.norm(),
        free.pull_n.norm(),
        free.lift_mm,
    );
    assert!(
        held.pull_n.z < -0.1,
        "the attached gallbladder does not pull the retraction back: {:?}",
        held.pull_n
    );
    assert!(
        free.pull_n.norm() < 0.25 * held.pull_n.norm(),
        "dissected, it still pulls {:?} (attached {:?})",
        free.pull_n,
        held.pull_n
    );
    assert!(
        free.lift_mm > held.lift_mm + 1.0,
        "the dissected fundus did not rise more ({} vs {} mm)",
        free.lift_mm,
        held.lift_mm
    );
    // The hook stayed in the bed: the liver was not cut.
    for sim in [&intact, &dissected] {
        assert_eq!(sim.objects[LIVER].model.node_count(), liver_nodes);
        assert!(common::worst_kept_quality(&sim.objects[GALLBLADDER]) > 0.05);
    }
}

/// The order: the grasper holds the fundus retracted while the hook divides the plate under it. As the
/// plate parts it lifts, and its edges' crossings move with it as the hook moves: the gallbladder still comes
/// free, and the grasper's pull falls away.
#[test]
fn the_hook_frees_the_gallbladder_while_the_grasper_holds_it_retracted() {
    let world = load_world(&common::worlds().join("cholecystectomy.toml")).unwrap();
    let mut sim = Sim::new(&world).unwrap();
    let fundus = fundus_node(&sim.objects[GALLBLADDER]);
    let held = retract_fundus(&mut sim);
    let after_n = dissect(&mut sim, held.held);
    // The lifted gallbladder settles on the grasper: 2 s more.
    let settled_n = mean(&drive(&mut sim, (0..2000).map(|_| [idle(), held.held]))[1800..]);
    let object = &sim.objects[GALLBLADDER];
    println!(
        "cholecystectomy, dissected under retraction: the grasper felt {:.3} N before, {:.3} N just after and \
         {:.3} N 2 s on; the gallbladder has {} nodes and {} tetrahedra",
        held.pull_n.norm(),
        after_n.norm(),
        settled_n.norm(),
        object.model.node_count(),
        object.model.tets().tets.len(),
    );
    assert!(
        !joined_to_the_floor(object, fundus),
        "the fundus is still joined to the bed's floor"
    );
    assert!(
        settled_n.norm() < 0.25 * held.pull_n.norm(),
        "dissected, it still pulls {settled_n:?} (attached {:?})",
        held.pull_n
    );
    assert!(common::worst_kept_quality(object) > 0.05);
}
