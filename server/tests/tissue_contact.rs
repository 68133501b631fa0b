//! One tissue kept out of another (interaction/tissue_pair.rs), on virtual time: a free block of the wound's
//! skin dropped under gravity onto another fixed at its floor rests on it, and pressed down onto it by a probe
//! at 3 N the two stay apart to 0.2 mm; the contact's forces are equal and opposite, and at rest carry the
//! top block's weight, and watching them allocates nothing once warm; worlds with objects that never meet watch
//! no contact.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
#[path = "common/tool_pose.rs"]
mod tool_pose;

use counting_allocator::{Counting, assert_counting_works, count_this_thread};

use nalgebra::{UnitQuaternion, Vector3};
use sinew_server::sim::{Sim, SimObject, StepReport, ToolCommand, ToolOutput};
use sinew_server::world::{load_world, parse_world};
use tool_pose::pose_command;

#[global_allocator]
static GLOBAL: Counting = Counting;

const DT_S: f32 = 0.001;
/// The gap the top block is dropped across, mm.
const DROP_MM: f32 = 1.0;
/// The deepest either block may go into the other, mm.
const MOST_OVERLAP_MM: f32 = 0.2;

const MATERIAL: &str = r#"
mass_kg = 0.3
stiffness_n_per_mm = 0.12
damping_n_s_per_mm = 0.00002
drag_per_s = 150.0
tet_bulk_modulus_kpa = 400.0
"#;

/// Two 17.5 x 30 x 10 mm blocks of the wound's skin (worlds/meshes/wound_half.msh, x 0 to 17.5, y -15 to 15,
/// z -10 to 0 as meshed), the bottom one fixed at its floor, the top one free and `DROP_MM` above it; a 4 mm
/// sphere probe above the top block's centre.
fn stacked_world() -> sinew_server::scene::World {
    let text = format!(
        r#"
scene = "stacked-blocks"
[sim]
tick_hz = 1000
publish_hz = 60
pose_timeout_s = 0.1
gravity_mm_per_s2 = [0.0, 0.0, -9810.0]
[collision]
margin_mm = 2.0

[[objects]]
name = "bottom"
mesh = "meshes/wound_half.msh"
units = "mm"
integrator = "symplectic-euler"
dt_s = 0.000125
[objects.material]
{MATERIAL}
[[objects.fixed]]
kind = "plane"
point_mm = [0.0, 0.0, -10.0]
normal = [0.0, 0.0, -1.0]
tolerance_mm = 0.01

[[objects]]
name = "top"
mesh = "meshes/wound_half.msh"
units = "mm"
offset_mm = [0.0, 0.0, {top}]
integrator = "symplectic-euler"
dt_s = 0.000125
[objects.material]
{MATERIAL}

[[tools]]
name = "probe"
device = "left"
shape = {{ kind = "sphere", radius_mm = 4.0 }}
device_origin_in_world_mm = [8.75, 0.0, 20.0]
max_force_n = 10.0
"#,
        top = 10.0 + DROP_MM
    );
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/stacked_blocks.toml");
    parse_world(&path, &text).unwrap()
}

/// How far the two blocks overlap, mm (positive: one is inside the other): the deepest any node of the top
/// block's bottom face lies under the bottom block's top face, or any node of the bottom's top face lies above
/// the top's bottom face, read from the faces' triangles (by height over the point's place in x and y).
fn deepest_overlap_mm(sim: &Sim) -> f32 {
    overlap_range_mm(sim).1
}

/// The least and the most the blocks overlap over the top block's bottom face and the bottom block's top face,
/// mm (the least negative: a gap).
fn overlap_range_mm(sim: &Sim) -> (f32, f32) {
    let (bottom, top) = (&sim.objects[0], &sim.objects[1]);
    fn facing(object: &SimObject, up: bool) -> Vec<[Vector3<f32>; 3]> {
        let p = &object.state.positions_mm;
        object
            .model
            .triangles()
            .iter()
            .map(|t| t.map(|i| p[i as usize]))
            .filter(|[a, b, c]| {
                let n = (b - a).cross(&(c - a)).normalize();
                if up { n.z > 0.7 } else { n.z < -0.7 }
            })
            .collect()
    }
    // The height of a triangle over (x, y), when (x, y) lies over it.
    let height = |tri: [Vector3<f32>; 3], x: f32, y: f32| {
        let [a, b, c] = tri;
        let det = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        let u = ((x - a.x) * (c.y - a.y) - (c.x - a.x) * (y - a.y)) / det;
        let v = ((b.x - a.x) * (y - a.y) - (x - a.x) * (b.y - a.y)) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then(|| a.z + u * (b.z - a.z) + v * (c.z - a.z))
    };
    let face_nodes = |object: &SimObject, up: bool| {
        let mut nodes: Vec<[f32; 3]> = facing(object, up)
            .iter()
            .flatten()
            .map(|p| [p.x, p.y, p.z])
            .collect();
        nodes.sort_by(|a, b| a.partial_cmp(b).unwrap());
        nodes.dedup();
        nodes.into_iter().map(Vector3::from).collect::<Vec<_>>()
    };
    let (mut least, mut deepest) = (f32::INFINITY, f32::NEG_INFINITY);
    for node in face_nodes(top, false) {
        for &tri in &facing(bottom, true) {
            if let Some(z) = height(tri, node.x, node.y) {
                deepest = deepest.max(z - node.z);
                least = least.min(z - node.z);
            }
        }
    }
    for node in face_nodes(bottom, true) {
        for &tri in &facing(top, false) {
            if let Some(z) = height(tri, node.x, node.y) {
                deepest = deepest.max(node.z - z);
                least = least.min(node.z - z);
            }
        }
    }
    (least, deepest)
}

/// The top block's lowest node, mm.
fn top_floor_mm(sim: &Sim) -> f32 {
    sim.objects[1]
        .state
        .positions_mm
        .iter()
        .map(|p| p.z)
        .fold(f32::INFINITY, f32::min)
}

fn step(sim: &mut Sim, command: &ToolCommand) -> (StepReport, ToolOutput) {
    let mut out = [ToolOutput::default()];
    let report = sim.step(DT_S, std::slice::from_ref(command), &mut out);
    assert!(sim.objects.iter().all(|o| o.state.is_finite()));
    assert_eq!(report.faults, 0, "no object is reset");
    (report, out[0])
}

#[test]
fn a_block_dropped_on_another_rests_on_it_and_pressed_at_3_n_stays_out_of_it_to_0_2_mm() {
    let world = stacked_world();
    let origin = Vector3::from(world.tools[0].device_origin_in_world_mm);
    let mut sim = Sim::new(&world).unwrap();
    let level = UnitQuaternion::identity();
    let mut at = Vector3::new(8.75, 0.0, 16.0);
    let mut contacts = 0;
    // The drop: half a second with the probe well clear.
    for _ in 0..500 {
        let (report, _) = step(&mut sim, &pose_command(&at, &origin, &level));
        contacts = contacts.max(report.tissue_contacts);
    }
    let (widest_gap, rested_overlap) = overlap_range_mm(&sim);
    let widest_gap = -widest_gap;
    // The contact's forces (the only external forces here: gravity is the model's) are equal and opposite,
    // and at rest they carry the top block's weight.
    let sum = |o: usize| -> Vector3<f32> { sim.objects[o].state.external_forces_n.iter().sum() };
    let (on_bottom, on_top) = (sum(0), sum(1));
    let weight_n = 0.3 * 9.81;
    println!(
        "the contact pushes the top block {:.3?} N and the bottom one {:.3?} N (the top's weight {weight_n:.3} N)",
        on_top.as_slice(),
        on_bottom.as_slice()
    );
    assert!((on_top + on_bottom).norm() < 1e-3, "not equal and opposite");
    assert!(
        (on_top.z - weight_n).abs() < 0.05 * weight_n && on_top.xy().norm() < 0.05 * weight_n,
        "at rest the contact carries the top block's weight"
    );
    println!(
        "dropped: {contacts} contacts watched, overlap {rested_overlap:.3} mm, widest gap {widest_gap:.3} mm, \
         top's floor {:.3} mm",
        top_floor_mm(&sim)
    );
    assert!(contacts > 0, "the blocks' faces are watched once they meet");
    assert!(
        rested_overlap <= MOST_OVERLAP_MM,
        "resting, the top block sinks {rested_overlap:.3} mm into the bottom one"
    );
    assert!(
        widest_gap <= MOST_OVERLAP_MM,
        "the top block rests on the bottom one all over, not above it: a gap of {widest_gap:.3} mm"
    );

    // The press: the probe comes down on the top block's centre until it feels 3 N, then holds.
    let mut force_n = 0.0;
    let mut deepest: f32 = rested_overlap;
    for tick in 0..1500 {
        if force_n < 3.0 {
            at.z -= 0.01;
        }
        let (_, out) = step(&mut sim, &pose_command(&at, &origin, &level));
        force_n = out.force_world_n.norm();
        if tick % 500 == 0 {
            println!(
                "t {tick} ms: probe at z {:.2}, {force_n:.2} N, overlap {:.3} mm",
                at.z,
                deepest_overlap_mm(&sim)
            );
        }
        if force_n >= 2.9 {
            deepest = deepest.max(deepest_overlap_mm(&sim));
        }
    }
    // Held pressed, the contact watched every tick: no allocation.
    assert_counting_works();
    let mut watched = usize::MAX;
    let command = pose_command(&at, &origin, &level);
    let allocations = count_this_thread(|| {
        for _ in 0..500 {
            let (report, _) = step(&mut sim, &command);
            watched = watched.min(report.tissue_contacts as usize);
        }
    });
    println!(
        "pressed at {force_n:.2} N: deepest overlap {deepest:.3} mm; 500 more ticks with at least {watched} \
         contacts watched: {allocations} allocations"
    );
    assert!(watched > 0);
    assert_eq!(allocations, 0, "a tick watching tissue contacts allocated");
    assert!(force_n >= 2.9, "the probe presses at 3 N: {force_n:.2} N");
    assert!(
        deepest <= MOST_OVERLAP_MM,
        "pressed at 3 N the blocks overlap by {deepest:.3} mm"
    );
}

#[test]
fn objects_that_never_meet_watch_no_contact() {
    for file in ["cut.toml", "exercise_stiffness_ranking.toml"] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../worlds")
            .join(file);
        let world = load_world(&path).unwrap();
        let mut sim = Sim::new(&world).unwrap();
        let mut out = vec![ToolOutput::default(); world.tools.len()];
        for _ in 0..50 {
            let report = sim.step(DT_S, &[], &mut out);
            assert_eq!(report.tissue_contacts, 0, "{file}");
        }
    }
}
