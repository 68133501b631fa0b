//! A needle let go in free space falls and comes to rest on the tissue (`interaction/suture/needle_fall.rs`),
//! on the suture block, on virtual time: let go over the skin it lands on it and lies still, never inside it;
//! let go beside the block it falls past it; the viewers are sent where it lies; a needle lying on the skin
//! is taken again by the driver's jaws and lifted with them, and pushed along by a grasper swept across it; a
//! needle passes from the driver's jaws to a grasper's and back in the air.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

#[path = "common/skin_block.rs"]
mod skin_block;
#[path = "common/tool_pose.rs"]
mod tool_pose;

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use sinew_protocol::needle_point_in_tool_mm;
use sinew_server::interaction::JawInput;
use sinew_server::interaction::suture::NeedleHolder;
use sinew_server::replication::FrameExchange;
use sinew_server::sim::{Sim, ToolOutput};
use sinew_server::world::InstrumentSpec;
use skin_block::{depth_in_block_mm, suture_block};
use tool_pose::pose_command;

const DT_S: f32 = 0.001;
/// The wire's radius, mm (the suture block's needle is 0.5 mm thick).
const RADIUS_MM: f32 = 0.25;

/// The suture block's needle driver (tool 0), its shaft level, the needle's curve down.
struct Dropper {
    sim: Sim,
    device_origin_mm: Vector3<f32>,
    grasper_origin_mm: Vector3<f32>,
    tool_from_needle: Isometry3<f32>,
}

impl Dropper {
    fn new() -> Self {
        let (world, spec) = suture_block();
        Self {
            device_origin_mm: Vector3::from(world.tools[0].device_origin_in_world_mm),
            grasper_origin_mm: Vector3::from(world.tools[1].device_origin_in_world_mm),
            tool_from_needle: spec.tool_from_needle(),
            sim: Sim::new(&world).unwrap(),
        }
    }

    fn level() -> UnitQuaternion<f32> {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2)
    }

    /// One tick with the driver at `origin_mm`, `rotation`, its ratchet's release button `open` (held: the
    /// jaws open), the grasper away.
    fn step(&mut self, origin_mm: &Vector3<f32>, rotation: &UnitQuaternion<f32>, open: bool) {
        self.step_with_grasper(origin_mm, rotation, open, None);
    }

    /// [`Self::step`] with the grasper (upright, its jaws closed) at `grasper_mm`, or away.
    fn step_with_grasper(
        &mut self,
        origin_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        open: bool,
        grasper_mm: Option<&Vector3<f32>>,
    ) {
        self.step_with_grasper_jaws(origin_mm, rotation, open, grasper_mm, true);
    }

    /// [`Self::step_with_grasper`] with the grasper's jaws `grasper_closed` (or open).
    fn step_with_grasper_jaws(
        &mut self,
        origin_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        open: bool,
        grasper_mm: Option<&Vector3<f32>>,
        grasper_closed: bool,
    ) {
        let mut command = pose_command(origin_mm, &self.device_origin_mm, rotation);
        command.jaws = JawInput {
            buttons: u32::from(open),
            jaw_angle_rad: 0.0,
        };
        let grasper = grasper_mm.map_or(Default::default(), |at| {
            let mut command =
                pose_command(at, &self.grasper_origin_mm, &UnitQuaternion::identity());
            command.jaws = JawInput {
                buttons: u32::from(grasper_closed),
                jaw_angle_rad: 0.0,
            };
            command
        });
        let mut out = [ToolOutput::default(); 2];
        let report = self.sim.step(DT_S, &[command, grasper], &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
    }

    fn world_from_needle(&self) -> Isometry3<f32> {
        *self.sim.tools[0].needle_hold().unwrap().world_from_needle()
    }

    fn holder(&self) -> NeedleHolder {
        *self.sim.tools[0].needle_hold().unwrap().holder()
    }

    /// 49 points along the needle's arc, world.
    fn arc_points(&self) -> Vec<Vector3<f32>> {
        let arc = *self.sim.tools[0].needle().unwrap().arc();
        let pose = self.world_from_needle();
        (0..=48)
            .map(|k| {
                (pose * Point3::from(arc.at(arc.sweep_rad() * k as f32 / 48.0).point_mm)).coords
            })
            .collect()
    }

    /// Let the needle go with the driver at `origin_mm` (brought there closed, the jaws opened there, the
    /// driver then drawn 40 mm up out of the way), and run `ticks` ticks.
    fn drop_at(&mut self, origin_mm: &Vector3<f32>, ticks: usize) {
        let level = Self::level();
        for _ in 0..20_000 {
            self.step(origin_mm, &level, false);
            if (self.sim.tools[0].position_mm - origin_mm).norm() < 0.01 {
                break;
            }
        }
        assert!(
            (self.sim.tools[0].position_mm - origin_mm).norm() < 0.01,
            "the driver did not reach {origin_mm:?}"
        );
        for _ in 0..50 {
            self.step(origin_mm, &level, true);
        }
        assert_eq!(
            self.holder(),
            NeedleHolder::Loose,
            "the jaws did not let go"
        );
        let away = origin_mm + Vector3::new(0.0, 0.0, 40.0);
        for k in 0..ticks {
            let to = origin_mm + (away - origin_mm) * (k as f32 / 200.0).min(1.0);
            self.step(&to, &level, true);
        }
    }
}

/// Let go 20 mm over the middle of the skin block, the needle falls onto the skin and lies still on it: after
/// 3 s no point of its arc lies closer to the skin than its radius (less 0.05 mm), its lowest lies within
/// 0.5 mm past the radius of the skin's top (it rests on it, not above it), over the last half second no
/// point moved more than 0.05 mm, and it punctured nothing.
#[test]
fn a_needle_let_go_over_the_skin_falls_onto_it_and_lies_still() {
    let mut d = Dropper::new();
    let origin = Vector3::new(0.0, 0.0, 20.0);
    d.drop_at(&origin, 2500);
    let before = d.arc_points();
    let mut deepest = f32::NEG_INFINITY;
    for _ in 0..500 {
        d.step(
            &(origin + Vector3::new(0.0, 0.0, 40.0)),
            &Dropper::level(),
            true,
        );
        deepest = d
            .arc_points()
            .iter()
            .map(depth_in_block_mm)
            .fold(deepest, f32::max);
    }
    let after = d.arc_points();
    let moved = before
        .iter()
        .zip(&after)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0f32, f32::max);
    let lowest = after.iter().map(|p| p.z).fold(f32::INFINITY, f32::min);
    println!(
        "a needle dropped on the skin: lowest point {lowest:.3} mm over its top, deepest {deepest:.3} mm \
         into it, moved {moved:.4} mm over the last 0.5 s"
    );
    assert!(
        deepest <= -(RADIUS_MM - 0.05),
        "the needle lay {deepest} mm into the skin"
    );
    assert!(
        lowest <= RADIUS_MM + 0.5,
        "the needle hovers {lowest} mm over the skin"
    );
    assert!(moved < 0.05, "the needle still moves: {moved} mm in 0.5 s");
    let needle = d.sim.tools[0].needle().unwrap();
    assert_eq!(
        (needle.punctures(), needle.holes().len()),
        (0, 0),
        "the dropped needle punctured the skin"
    );

    // What the viewers are sent of it (protocol 15): drawn by the protocol's map in the pose sent, the needle's
    // tip is where it lies.
    let frames = FrameExchange::new(&d.sim);
    assert!(frames.try_offer(&d.sim, &[ToolOutput::default(); 2]));
    let sent = frames.with_frame(|f| f.needles.clone()).unwrap();
    let InstrumentSpec::NeedleDriver(spec) = d.sim.tools[0].instrument else {
        panic!("tool 0 is not a needle driver");
    };
    let [x, y, z, w] = sent[0].orientation_xyzw;
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    let in_tool = needle_point_in_tool_mm(
        spec.arc.radius_mm(),
        spec.grasp_at_rad,
        spec.arc.sweep_rad(),
    );
    let drawn_tip = Vector3::from(sent[0].position_mm) + q * Vector3::from(in_tool);
    let tip = *after.last().unwrap();
    assert!(
        (drawn_tip - tip).norm() < 0.01,
        "viewers would draw the tip at {drawn_tip:?}, it lies at {tip:?}"
    );
}

/// Let go beside the skin block (30 mm past its side), the needle falls past it: 0.3 s on from the jaws'
/// opening it is more than 200 mm lower (free fall from rest takes it 441 mm in 0.3 s; it was falling as the
/// jaws opened), its shape (its ends' distance) unchanged.
#[test]
fn a_needle_let_go_beside_the_skin_falls_past_it() {
    let mut d = Dropper::new();
    let origin = Vector3::new(50.0, 0.0, 20.0);
    d.drop_at(&origin, 0);
    let before = d.arc_points();
    for _ in 0..300 {
        d.step(
            &(origin + Vector3::new(0.0, 0.0, 40.0)),
            &Dropper::level(),
            true,
        );
    }
    let after = d.arc_points();
    let fell_mm = before[24].z - after[24].z;
    let chord = |p: &[Vector3<f32>]| (p[0] - p[48]).norm();
    println!("a needle dropped beside the skin fell {fell_mm:.1} mm in 0.3 s");
    assert!(fell_mm > 200.0, "it fell only {fell_mm} mm");
    assert!((chord(&before) - chord(&after)).abs() < 1e-3);
}

/// A needle lying on the skin is taken again: the driver comes to where it held the needle, open, closes its
/// jaws, and the needle is in them again; drawn 20 mm up, the needle rises with them.
#[test]
fn a_needle_lying_on_the_skin_is_taken_again_by_the_drivers_jaws() {
    let mut d = Dropper::new();
    let origin = Vector3::new(0.0, 0.0, 20.0);
    d.drop_at(&origin, 1500);
    let target = d.world_from_needle() * d.tool_from_needle.inverse();
    let (to, rotation) = (target.translation.vector, target.rotation);
    let mut at = origin + Vector3::new(0.0, 0.0, 40.0);
    for _ in 0..20_000 {
        let step = to - at;
        at += step * (0.1 / step.norm().max(0.1));
        d.step(&at, &rotation, true);
        if (d.sim.tools[0].position_mm - to).norm() < 0.05 {
            break;
        }
    }
    assert!(
        (d.sim.tools[0].position_mm - to).norm() < 0.05,
        "the driver did not reach the needle"
    );
    for _ in 0..100 {
        d.step(&at, &rotation, false);
    }
    assert!(
        matches!(d.holder(), NeedleHolder::Driver { .. }),
        "the jaws did not take the needle: {:?}",
        d.holder()
    );
    let lying = d.arc_points();
    for k in 1..=200 {
        d.step(
            &(at + Vector3::new(0.0, 0.0, 0.1 * k as f32)),
            &rotation,
            false,
        );
    }
    let lifted = d.arc_points();
    let rose = lifted[24].z - lying[24].z;
    assert!(
        (rose - 20.0).abs() < 0.5,
        "the needle rose {rose} mm with jaws drawn 20 mm up"
    );
}

/// Hand to hand in the air: the driver holds the needle 30 mm over the skin; the grasper (upright, its jaws
/// open) comes to the middle of its arc and closes: it takes the needle there, as it lies (no jump); the driver
/// opens and leaves, and the needle stays in the grasper's jaws and follows them 10 mm along; the driver comes
/// back to its tail and closes: it takes the needle back; the grasper opens, and the needle stays with the
/// driver. Never loose, it never falls.
#[test]
fn a_needle_passes_from_hand_to_hand_in_the_air_and_back() {
    let mut d = Dropper::new();
    let level = Dropper::level();
    let origin = Vector3::new(0.0, 0.0, 30.0);
    let park = Vector3::new(30.0, 0.0, 40.0);
    // The driver to its place, the grasper parked open.
    for _ in 0..20_000 {
        d.step_with_grasper_jaws(&origin, &level, false, Some(&park), false);
        if (d.sim.tools[0].position_mm - origin).norm() < 0.01 {
            break;
        }
    }
    let middle = d.arc_points()[24];
    // The open grasper to the middle of the arc, from 20 mm aside (0.1 mm a tick), held there.
    let mut grasper = park;
    for waypoint in [middle + Vector3::new(20.0, 0.0, 0.0), middle] {
        for _ in 0..20_000 {
            let to = waypoint - grasper;
            grasper += to * (0.1 / to.norm().max(0.1));
            d.step_with_grasper_jaws(&origin, &level, false, Some(&grasper), false);
            if (d.sim.tools[1].position_mm - waypoint).norm() < 0.02 {
                break;
            }
        }
    }
    assert!(matches!(d.holder(), NeedleHolder::Driver { .. }));
    let before = d.world_from_needle();
    for _ in 0..50 {
        d.step_with_grasper_jaws(&origin, &level, false, Some(&grasper), true);
    }
    assert!(
        matches!(d.holder(), NeedleHolder::Tool { tool: 1, .. }),
        "the grasper did not take the needle from the driver: {:?}",
        d.holder()
    );
    let jumped = (d.world_from_needle().translation.vector - before.translation.vector).norm();
    assert!(jumped < 0.05, "the needle jumped {jumped} mm as it passed");
    // The driver opens and draws 40 mm up: the needle stays in the grasper's jaws.
    for k in 0..400 {
        let up = origin + Vector3::new(0.0, 0.0, 40.0 * (k as f32 / 200.0).min(1.0));
        d.step_with_grasper_jaws(&up, &level, true, Some(&grasper), true);
    }
    assert!(matches!(d.holder(), NeedleHolder::Tool { tool: 1, .. }));
    let held = d.arc_points()[24];
    assert!((held - middle).norm() < 0.1, "{held:?} for {middle:?}");
    // The grasper carries it 10 mm along x.
    let along = Vector3::new(10.0, 0.0, 0.0);
    let from = grasper;
    for k in 1..=500 {
        grasper = from + along * (k as f32 / 500.0);
        d.step_with_grasper_jaws(
            &(origin + Vector3::new(0.0, 0.0, 40.0)),
            &level,
            true,
            Some(&grasper),
            true,
        );
    }
    for _ in 0..200 {
        d.step_with_grasper_jaws(
            &(origin + Vector3::new(0.0, 0.0, 40.0)),
            &level,
            true,
            Some(&grasper),
            true,
        );
    }
    let carried = d.arc_points()[24] - middle;
    assert!(
        (carried - along).norm() < 0.3,
        "carried {carried:?} for {along:?}"
    );
    // The driver comes back, open, to where its jaws held the tail, and closes: it takes the needle back.
    let target = d.world_from_needle() * d.tool_from_needle.inverse();
    let (to, rotation) = (target.translation.vector, target.rotation);
    let mut at = origin + Vector3::new(0.0, 0.0, 40.0);
    for _ in 0..20_000 {
        let step = to - at;
        at += step * (0.1 / step.norm().max(0.1));
        d.step_with_grasper_jaws(&at, &rotation, true, Some(&grasper), true);
        if (d.sim.tools[0].position_mm - to).norm() < 0.05 {
            break;
        }
    }
    let before = d.world_from_needle();
    for _ in 0..100 {
        d.step_with_grasper_jaws(&at, &rotation, false, Some(&grasper), true);
    }
    assert!(
        matches!(d.holder(), NeedleHolder::Driver { .. }),
        "the driver did not take the needle back: {:?}",
        d.holder()
    );
    let jumped = (d.world_from_needle().translation.vector - before.translation.vector).norm();
    assert!(
        jumped < 0.1,
        "the needle jumped {jumped} mm as it passed back"
    );
    // The grasper opens: the needle stays with the driver.
    for _ in 0..300 {
        d.step_with_grasper_jaws(&at, &rotation, false, Some(&grasper), false);
    }
    assert!(matches!(d.holder(), NeedleHolder::Driver { .. }));
}

/// A grasper (upright, its jaws closed far off, its capsule's bottom 0.1 mm over the skin) swept 30 mm across a needle lying
/// on the skin, at 20 mm/s, pushes it along: the needle ends more than 5 mm further along the sweep, no point
/// of its arc ever lies deeper than 0.2 mm inside the grasper's capsule (1.5 mm radius, 3 mm half length) or
/// closer to the skin than its radius (less 0.05 mm); the grasper lifted off, it stops (friction).
#[test]
fn a_grasper_swept_across_a_needle_lying_on_the_skin_pushes_it_along() {
    let mut d = Dropper::new();
    let origin = Vector3::new(0.0, 0.0, 20.0);
    let away = origin + Vector3::new(0.0, 0.0, 40.0);
    d.drop_at(&origin, 1500);
    let lying = d.arc_points();
    let middle = lying.iter().sum::<Vector3<f32>>() / lying.len() as f32;
    let start = Vector3::new(middle.x - 15.0, middle.y, 4.6);
    // The grasper to 20 mm over its start, then down to it.
    let mut at = d.sim.tools[1].position_mm;
    for waypoint in [start + Vector3::new(0.0, 0.0, 20.0), start] {
        for _ in 0..20_000 {
            let to = waypoint - at;
            at += to * (0.1 / to.norm().max(0.1));
            d.step_with_grasper(&away, &Dropper::level(), true, Some(&at));
            if (d.sim.tools[1].position_mm - waypoint).norm() < 0.02 {
                break;
            }
        }
    }
    let depth_in_grasper = |d: &Dropper, p: &Vector3<f32>| {
        let tool = &d.sim.tools[1];
        let axis = tool.rotation * Vector3::z();
        let along = (p - tool.position_mm).dot(&axis).clamp(-3.0, 3.0);
        1.5 - (p - (tool.position_mm + axis * along)).norm()
    };
    let (mut in_grasper, mut in_skin) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
    for _ in 0..1500 {
        at += Vector3::new(0.02, 0.0, 0.0);
        d.step_with_grasper(&away, &Dropper::level(), true, Some(&at));
        for p in d.arc_points() {
            in_grasper = in_grasper.max(depth_in_grasper(&d, &p));
            in_skin = in_skin.max(depth_in_block_mm(&p));
        }
    }
    let pushed = d.arc_points().iter().sum::<Vector3<f32>>() / lying.len() as f32 - middle;
    println!(
        "a grasper swept across the needle: pushed {pushed:?} mm, deepest in the grasper {in_grasper:.3} mm, \
         in the skin {in_skin:.3} mm"
    );
    // The grasper lifted off, the needle stops where it was pushed (it slides on the skin with friction):
    // after 0.8 s it moves less than 0.05 mm in 0.5 s.
    for k in 0..800 {
        let lifted = at + Vector3::new(0.0, 0.0, 0.1 * k.min(200) as f32);
        d.step_with_grasper(&away, &Dropper::level(), true, Some(&lifted));
    }
    let settled = d.arc_points();
    for _ in 0..500 {
        let lifted = at + Vector3::new(0.0, 0.0, 20.0);
        d.step_with_grasper(&away, &Dropper::level(), true, Some(&lifted));
    }
    let drift = settled
        .iter()
        .zip(d.arc_points())
        .map(|(a, b)| (a - b).norm())
        .fold(0.0f32, f32::max);
    println!("  then it moved {drift:.4} mm in 0.5 s");
    assert_eq!(
        d.holder(),
        NeedleHolder::Loose,
        "the grasper took the needle"
    );
    assert!(
        pushed.x > 5.0,
        "the needle was pushed {} mm along",
        pushed.x
    );
    assert!(
        drift < 0.05,
        "the pushed needle slides on: {drift} mm in 0.5 s"
    );
    assert!(
        in_grasper <= 0.2,
        "the needle lay {in_grasper} mm inside the grasper"
    );
    assert!(
        in_skin <= -(RADIUS_MM - 0.05),
        "the needle was pressed {in_skin} mm into the skin"
    );
}
