//! The needle's hand-off on the wound of worlds/suture.toml, on virtual time: the driver drives the
//! needle through both edges until its tip stands out of the far edge, opens its ratchet and leaves; the
//! needle stays where it is, held by its holes; the grasper comes down on its tip, takes it, and draws it on
//! along its own curve until its tail has left all four holes and the thread runs through them.
//!
//! What the surgeon feels and what the training layer sees are checked with it: after the release the driver
//! feels nothing of the needle and the grasper feels its drag; the driver is releasing, the grasper
//! regrasping, then pulling the thread through; no puncture is counted twice.

#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
#[path = "common/tool_pose.rs"]
mod tool_pose;
#[path = "common/wound.rs"]
mod wound;

use nalgebra::{Point3, UnitQuaternion, Vector3};
use sinew_protocol::needle_point_in_tool_mm;
use sinew_server::interaction::suture::NeedleHolder;
use sinew_server::replication::FrameExchange;
use sinew_server::sim::ToolOutput;
use sinew_server::training::{EventKind, SkillState};
use sinew_server::world::InstrumentSpec;
use wound::{DT_S, Wound};

use counting_allocator::{Counting, assert_counting_works, count_this_thread};

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Where each of the needle's holes lies now, world, mm.
fn hole_places(wound: &Wound) -> Vec<Vector3<f32>> {
    let needle = wound.sim.tools[0].needle().unwrap();
    needle
        .holes()
        .iter()
        .map(|h| {
            let object = &wound.sim.objects[usize::from(h.point.object)];
            h.point.position_mm(&object.model, &object.state).unwrap()
        })
        .collect()
}

/// The wound with the grasper parked aside and the driver held 1.5 s 8 degrees before the skin: the wound, the
/// driver's turn there and the way to turn on.
fn ready() -> (Wound, f32, f32) {
    let mut wound = Wound::new();
    wound.aim_grasper(&Vector3::new(30.0, 0.0, 30.0), false);
    let (start, sign) = wound.start();
    let (rotation, origin) = wound.pose_at(start);
    for _ in 0..1500 {
        wound.step_at(&rotation, &origin);
    }
    (wound, start, sign)
}

#[test]
fn the_driver_lets_the_needle_go_in_the_tissue_and_the_grasper_takes_it_at_the_tip_and_draws_it_through()
 {
    let (mut wound, start, sign) = ready();

    // Drive the needle through both edges: four punctures, then 20 degrees more (the tip ~3.7 mm out).
    let mut turn = 0.0f32;
    let mut punctures = 0;
    let mut past = 0.0f32;
    let mut pass_pull_n = 0.0f32;
    while past < 20f32.to_radians() {
        turn += DT_S * 40f32.to_radians();
        if punctures == 4 {
            past += DT_S * 40f32.to_radians();
        }
        let (rotation, origin) = wound.pose_at(start + sign * turn);
        let (out, report) = wound.step_at(&rotation, &origin);
        punctures += report.punctures;
        pass_pull_n = pass_pull_n.max(out[0].suture.thread_pull_n);
        assert!(turn < 2.0 * std::f32::consts::PI, "{punctures} punctures");
    }
    // The thread's pull on the tail while it was driven: the rings laid in the track as the tail runs inside
    // an edge take the thread without a jolt (one laid at the tail jolted it to 3.6-4.7 N for a tick).
    println!("the pass: the thread pulled the tail {pass_pull_n:.2} N at most");
    assert!(
        pass_pull_n < 1.0,
        "the thread jolted the tail at {pass_pull_n} N"
    );
    let (rotation, driver_at) = wound.pose_at(start + sign * turn);
    for _ in 0..300 {
        wound.step_at(&rotation, &driver_at);
    }
    // (The half-circle needle's tail has left the first hole by now: the thread runs through it.)
    let in_needle = wound.sim.tools[0].needle().unwrap().holes().len();
    println!(
        "at the release: {in_needle} holes on the needle, {} on the thread",
        wound.thread().holes().len()
    );
    assert!(in_needle >= 2);
    assert_eq!(in_needle + wound.thread().holes().len(), 4);
    let places_before = hole_places(&wound);
    // What the viewers are sent of the holes (protocol 18): the thread's, then the needle's, each where it is.
    let frames = FrameExchange::new(&wound.sim);
    assert!(frames.try_offer(&wound.sim, &[ToolOutput::default(); 2]));
    let marks = frames
        .with_frame(|f| f.threads.first().map(|t| t.holes.clone()))
        .unwrap()
        .expect("no thread sent");
    let on_thread: Vec<_> = wound
        .thread()
        .holes()
        .iter()
        .map(|h| h.place_mm())
        .collect();
    let expected: Vec<_> = on_thread
        .iter()
        .map(|p| (*p, false))
        .chain(places_before.iter().map(|p| (*p, true)))
        .collect();
    assert_eq!(marks.len(), 4);
    for (mark, (at, on_needle)) in marks.iter().zip(&expected) {
        assert_eq!(mark.on_needle, *on_needle, "{marks:?}");
        assert!(
            (Vector3::from(mark.position_mm) - at).norm() < 1e-4,
            "{mark:?} sent for a hole at {at:?}"
        );
        assert!(mark.pull_n.is_finite() && mark.pull_n >= 0.0);
    }

    // The driver opens its ratchet (its first button held) and rises 15 mm away; then lets the button go,
    // its jaws closing on nothing there.
    wound.driver_buttons = 1;
    let mut driver_felt_n = 0.0f32;
    let mut released = false;
    for k in 0..700 {
        let up = Vector3::new(
            0.0,
            0.0,
            15.0 * ((k as f32 - 200.0) / 500.0).clamp(0.0, 1.0),
        );
        let (out, _) = wound.step_at(&rotation, &(driver_at + up));
        released |= out[0].suture.needle_released && !out[0].suture.needle_held;
        if k > 50 {
            driver_felt_n = driver_felt_n.max(out[0].force_world_n.norm());
        }
    }
    wound.driver_buttons = 0;
    let pose_let_go = *wound.sim.tools[0]
        .needle_hold()
        .unwrap()
        .world_from_needle();
    let up = driver_at + Vector3::new(0.0, 0.0, 15.0);
    for _ in 0..300 {
        let (out, _) = wound.step_at(&rotation, &up);
        driver_felt_n = driver_felt_n.max(out[0].force_world_n.norm());
    }
    let hold = wound.sim.tools[0].needle_hold().unwrap();
    assert_eq!(
        *hold.holder(),
        NeedleHolder::Loose,
        "closing far from it, the jaws took it back"
    );
    assert_eq!(
        *hold.world_from_needle(),
        pose_let_go,
        "a loose needle moved"
    );
    assert!(
        released,
        "the driver's output never said it let the needle go in the tissue"
    );
    let drift_mm = hole_places(&wound)
        .iter()
        .zip(&places_before)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0f32, f32::max);
    println!(
        "let go: the holes drifted {drift_mm:.3} mm at most; the driver felt {driver_felt_n:.3} N"
    );
    assert!(
        drift_mm <= 0.5,
        "the holes drifted {drift_mm} mm with the needle let go"
    );
    assert!(
        driver_felt_n < 0.05,
        "the driver felt {driver_felt_n} N of a needle it let go"
    );

    // The grasper comes down on the tip from 20 mm above to 0.3 mm over it (its capsule is 1.5 mm thick),
    // and closes.
    let needle_pose = pose_let_go;
    let arc = *wound.sim.tools[0].needle().unwrap().arc();
    let tip = (needle_pose * Point3::from(arc.tip().point_mm)).coords;
    let over_tip = tip + Vector3::new(0.0, 0.0, 1.5 + 0.3);
    let mut aim = wound.sim.tools[1].position_mm;
    for lift in [20.0, 0.0] {
        let waypoint = over_tip + Vector3::new(0.0, 0.0, lift);
        for _ in 0..20_000 {
            let to = waypoint - aim;
            aim += to * (0.02 / to.norm().max(0.02));
            wound.aim_grasper(&aim, false);
            wound.step_at(&rotation, &up);
            if (wound.sim.tools[1].position_mm - waypoint).norm() < 0.02 {
                break;
            }
        }
    }
    let mut taken = 0;
    for _ in 0..200 {
        wound.aim_grasper(&aim, true);
        taken += wound.step_at(&rotation, &up).1.grasps_taken;
    }
    assert_eq!(taken, 1);
    let hold = wound.sim.tools[0].needle_hold().unwrap();
    assert!(
        hold.held_by(1) && hold.taken_in_tissue(),
        "{:?}",
        hold.holder()
    );

    // It draws the needle on along its own curve (turning about the needle's centre, at 40 degrees a
    // second) until the tail has left all four holes, and 0.5 s more.
    let centre = (needle_pose * Point3::origin()).coords;
    let axis = needle_pose * Vector3::z_axis();
    let mut drawn = 0.0f32;
    let mut after = None;
    let (mut grasper_felt_n, mut driver_felt_n) = (0.0f32, 0.0f32);
    let mut extra_punctures = 0;
    let mut allocations = 0;
    assert_counting_works();
    while after.is_none_or(|ticks| ticks < 500) {
        drawn += DT_S * 40f32.to_radians();
        // The needle's tip goes on along +tangent: the needle frame's z is the turn's axis.
        let turn = UnitQuaternion::from_axis_angle(&axis, drawn);
        wound.pose_grasper(&(centre + turn * (aim - centre)), &turn, true);
        // (Counted: drawing the needle through, its holes and the thread's, allocates nothing.)
        let mut stepped = None;
        allocations += count_this_thread(|| stepped = Some(wound.step_at(&rotation, &up)));
        let (out, report) = stepped.unwrap();
        extra_punctures += report.punctures;
        grasper_felt_n = grasper_felt_n.max(out[1].force_world_n.norm());
        driver_felt_n = driver_felt_n.max(out[0].force_world_n.norm());
        if wound.thread().holes().len() == 4 {
            after = Some(after.map_or(0, |t| t + 1));
        }
        assert!(
            drawn < 1.5 * std::f32::consts::PI,
            "the tail never left four holes ({} taken)",
            wound.thread().holes().len()
        );
    }
    println!(
        "drawn {:.0} degrees: the grasper felt {grasper_felt_n:.2} N at most, the driver {driver_felt_n:.3} N; \
         gap {:.2} mm, {} inverted",
        drawn.to_degrees(),
        wound.gap_mm(),
        wound.inverted()
    );
    assert_eq!(extra_punctures, 0, "drawing the needle out punctured again");
    assert_eq!(allocations, 0, "a tick of the draw allocated");
    assert!(wound.sim.tools[0].needle().unwrap().holes().is_empty());
    assert!(wound.sim.tools[0].needle_hold().unwrap().held_by(1));
    assert!(
        grasper_felt_n > 0.1 && grasper_felt_n < 1.0,
        "the grasper felt {grasper_felt_n} N drawing the needle"
    );
    assert!(driver_felt_n < 0.05, "the driver felt {driver_felt_n} N");
    assert_eq!(wound.inverted(), 0);

    // What the viewers are sent of it (protocol 15): drawn by the protocol's map in the pose sent, the needle's
    // tip is where the grasper holds it.
    let frames = FrameExchange::new(&wound.sim);
    assert!(frames.try_offer(&wound.sim, &[ToolOutput::default(); 2]));
    let sent = frames.with_frame(|f| f.needles.clone()).unwrap();
    assert_eq!(sent.len(), 1);
    // Offered again, once warm, the frame with its thread and four holes allocates nothing.
    let outputs = [ToolOutput::default(); 2];
    let allocations = count_this_thread(|| {
        assert!(frames.try_offer(&wound.sim, &outputs));
    });
    assert_eq!(allocations, 0, "handing off the holes allocated");
    // All four holes are the thread's now, sent where it runs through them.
    let marks = frames.with_frame(|f| f.threads[0].holes.clone()).unwrap();
    assert_eq!(marks.len(), 4);
    for (mark, hole) in marks.iter().zip(wound.thread().holes()) {
        assert!(!mark.on_needle);
        assert!((Vector3::from(mark.position_mm) - hole.place_mm()).norm() < 1e-4);
        assert!((mark.pull_n - hole.pull_on_tissue_n().norm()).abs() < 1e-6);
    }
    let InstrumentSpec::NeedleDriver(spec) = wound.sim.tools[0].instrument else {
        panic!("tool 0 is not a needle driver");
    };
    let drawn_tip = {
        let [x, y, z, w] = sent[0].orientation_xyzw;
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        let in_tool =
            needle_point_in_tool_mm(spec.arc.radius_mm(), spec.grasp_at_rad, arc.sweep_rad());
        Vector3::from(sent[0].position_mm) + q * Vector3::from(in_tool)
    };
    let hold = wound.sim.tools[0].needle_hold().unwrap();
    let tip_now = (hold.world_from_needle() * Point3::from(arc.tip().point_mm)).coords;
    assert!(
        (drawn_tip - tip_now).norm() < 0.01,
        "viewers would draw the tip at {drawn_tip:?}, it is at {tip_now:?}"
    );
    assert!(
        (tip_now - wound.sim.tools[0].position_mm).norm() > 5.0,
        "the needle is drawn on its driver"
    );

    // What the training layer saw: the driver pushing through then releasing, the grasper regrasping then
    // pulling the thread through; the four punctures counted once, on the driver.
    let states = |tool: u8| -> Vec<SkillState> {
        wound
            .transitions
            .iter()
            .filter(|(t, _)| *t == tool)
            .map(|(_, t)| t.to)
            .collect()
    };
    let (driver, grasper) = (states(0), states(1));
    println!("driver: {driver:?}\ngrasper: {grasper:?}");
    let at = |states: &[SkillState], s: SkillState| states.iter().position(|&x| x == s);
    assert!(at(&driver, SkillState::PushThrough) < at(&driver, SkillState::Release));
    assert!(at(&driver, SkillState::Release).is_some());
    let regrasp = at(&grasper, SkillState::Regrasp).expect("the grasper never regrasped");
    assert!(at(&grasper[regrasp..], SkillState::PullThrough).is_some());
    let count = |tool: u8, kind: EventKind| {
        wound
            .events
            .iter()
            .filter(|e| e.tool == tool && e.kind == kind)
            .count()
    };
    assert_eq!(count(0, EventKind::Puncture), 4);
    assert_eq!(count(1, EventKind::Puncture), 0);
    assert_eq!(count(0, EventKind::NeedleReleaseBegin), 1);
    assert_eq!(count(1, EventKind::NeedleRegraspBegin), 1);

    // Then the driver takes the thread's free end, as a surgeon does to draw the stitch: its jaws open, come
    // down beside the thread 15 mm past the hole nearest that end, and close on it. It then draws 10 mm up
    // and out, the grasper holding the needle, and feels the thread's pull.
    let (free_u, free_hole) = {
        let holes = wound.thread().holes();
        let last = holes
            .iter()
            .map(|h| h.u_mm)
            .fold(f32::NEG_INFINITY, f32::max);
        (last + 15.0, last)
    };
    let node = wound
        .thread()
        .chain()
        .node_u_mm()
        .iter()
        .position(|&u| u >= free_u)
        .expect("the thread is shorter than that");
    wound.driver_buttons = 1;
    let beside = Vector3::new(0.0, 0.2 + 0.3, 0.0);
    let mut driver_aim = wound.sim.tools[0].position_mm;
    for lift in [20.0, 0.0] {
        for _ in 0..20_000 {
            let waypoint = wound.thread().nodes_mm()[node] + beside + Vector3::new(0.0, 0.0, lift);
            let to = waypoint - driver_aim;
            driver_aim += to * (0.02 / to.norm().max(0.02));
            wound.step_at(&rotation, &driver_aim);
            if (wound.sim.tools[0].position_mm - waypoint).norm() < 0.02 {
                break;
            }
        }
    }
    wound.driver_buttons = 0;
    for _ in 0..200 {
        wound.step_at(&rotation, &driver_aim);
    }
    let grip = *wound
        .thread()
        .grip_of(0)
        .expect("the driver's jaws did not take the thread");
    assert!(grip.node as usize >= node.saturating_sub(2) && grip.node as usize <= node + 2);
    assert!(wound.sim.tools[0].needle_hold().unwrap().held_by(1));
    // (The hand draws on only while it feels under 1 N: a surgeon does not yank.)
    let mut driver_pull_n = 0.0f32;
    let mut held = false;
    let mut drawn_mm = 0.0f32;
    for _ in 0..2000 {
        let (out, _) = wound.step_at(
            &rotation,
            &(driver_aim + Vector3::new(0.0, 1.0, 1.0) * drawn_mm),
        );
        driver_pull_n = out[0].force_world_n.norm();
        held = out[0].suture.thread_held;
        if driver_pull_n < 1.0 {
            drawn_mm = (drawn_mm + 0.005).min(7.0);
        }
    }
    println!(
        "the driver took the thread (node {}, {:.1} mm past the hole at u {free_hole:.1}) and drew it {:.1} mm up and \
         out: {driver_pull_n:.2} N",
        grip.node,
        free_u - free_hole,
        drawn_mm * std::f32::consts::SQRT_2
    );
    assert!(held, "the driver's output does not say it holds the thread");
    assert!(
        driver_pull_n > 0.05,
        "the driver felt {driver_pull_n} N drawing the thread"
    );
    let driver_after: Vec<SkillState> = wound
        .transitions
        .iter()
        .filter(|(t, _)| *t == 0)
        .map(|(_, t)| t.to)
        .skip(driver.len())
        .collect();
    println!("driver, after: {driver_after:?}");
    assert!(
        driver_after
            .iter()
            .any(|s| matches!(s, SkillState::PullThrough | SkillState::Tighten)),
        "{driver_after:?}"
    );
}

#[test]
fn opening_the_ratchet_on_a_loaded_needle_fades_its_load_from_the_hand_over_the_jaws_opening() {
    let (mut wound, start, sign) = ready();
    // Drive the needle through the near edge until its tip tents the far edge's face at over 1 N.
    let (mut turn, mut punctures, mut load_n) = (0.0f32, 0, 0.0f32);
    while punctures < 2 || load_n < 1.0 {
        turn += DT_S * 40f32.to_radians();
        let (rotation, origin) = wound.pose_at(start + sign * turn);
        let (out, report) = wound.step_at(&rotation, &origin);
        punctures += report.punctures;
        load_n = out[0].force_world_n.norm();
        assert!(
            turn < 2.0 * std::f32::consts::PI && punctures < 3,
            "{punctures} punctures"
        );
    }
    // Still pushing on, the hand opens the ratchet and holds where it is (the tip, let go tenting the face, stays
    // where it is: the needle does not move).
    let (rotation, at) = wound.pose_at(start + sign * (turn + DT_S * 40f32.to_radians()));
    let loaded_n = wound.step_at(&rotation, &at).0[0].force_world_n.norm();
    wound.driver_buttons = 1;
    let mut trace = Vec::new();
    for _ in 0..150 {
        trace.push(wound.step_at(&rotation, &at).0[0].force_world_n.norm());
    }
    let steepest = trace
        .windows(2)
        .map(|w| w[0] - w[1])
        .chain(std::iter::once(loaded_n - trace[0]))
        .fold(0.0f32, f32::max);
    println!(
        "loaded {loaded_n:.3} N; after opening: {:.3} N at 1 ms, {:.3} at 20, {:.3} at 50, {:.3} at 150; steepest fall {steepest:.3} N a tick",
        trace[0], trace[19], trace[49], trace[149]
    );
    assert!(loaded_n > 0.9, "the needle was not loaded: {loaded_n} N");
    assert!(
        steepest <= 0.05 * loaded_n + 0.01,
        "the load fell {steepest} N in one tick of {loaded_n} N"
    );
    assert!(trace[149] < 0.1 * loaded_n + 0.01, "{} N left", trace[149]);
    assert_eq!(
        *wound.sim.tools[0].needle_hold().unwrap().holder(),
        NeedleHolder::Loose
    );
}
