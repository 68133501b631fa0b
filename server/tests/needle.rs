//! A needle driver's curved needle against the shipped suture block's skin, on virtual time: the tip tents the
//! surface and punctures it past the material's force and within its angle, not below the force and not at a
//! glancing angle; the pop drops the force at once; a needle driven on through the block tents its floor from
//! inside and punctures it too (a through-bite's second peak), allocating nothing between; in the skin it slides
//! along its own curve with friction and meets a wall across it.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
#[path = "common/skin_block.rs"]
mod skin_block;
#[path = "common/tool_pose.rs"]
mod tool_pose;

use skin_block::{depth_in_block_mm, suture_block};
use tool_pose::pose_command;

use counting_allocator::{Counting, assert_counting_works, count_this_thread};

#[global_allocator]
static GLOBAL: Counting = Counting;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sinew_server::interaction::suture::{HolePoint, NeedleArc, TipPhase};
use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::InstrumentSpec;

const DT_S: f32 = 0.001;

fn suture_world() -> sinew_server::scene::World {
    suture_block().0
}

/// The suture block's needle driver (tool 0) held with its shaft along world +y and the needle's curve turned
/// down, tilted `tilt_rad` about the world's x axis from that (0: the tip 14 degrees off straight down, in the
/// x-z plane). Tool 1 (the grasper) stays away.
struct Driver {
    sim: Sim,
    rotation: UnitQuaternion<f32>,
    /// The tip and its direction in the tool frame.
    tip_tool_mm: Vector3<f32>,
    tip_dir_tool: Vector3<f32>,
    device_origin_mm: Vector3<f32>,
    puncture_force_n: f32,
}

impl Driver {
    fn new(tilt_about_y_rad: f32) -> Self {
        Self::with(suture_world(), tilt_about_y_rad)
    }

    fn with(world: sinew_server::scene::World, tilt_about_y_rad: f32) -> Self {
        let InstrumentSpec::NeedleDriver(spec) = world.tools[0].instrument else {
            panic!("tool 0 of the suture block is not a needle driver");
        };
        let tool_from_needle = spec.tool_from_needle();
        let tip = spec.arc.tip();
        let level =
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f32::consts::FRAC_PI_2);
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), tilt_about_y_rad);
        Self {
            puncture_force_n: world.objects[0].material.puncture.force_n,
            device_origin_mm: Vector3::from(world.tools[0].device_origin_in_world_mm),
            sim: Sim::new(&world).unwrap(),
            rotation: tilt * level,
            tip_tool_mm: (tool_from_needle * Point3::from(tip.point_mm)).coords,
            tip_dir_tool: tool_from_needle * tip.tangent,
        }
    }

    /// The tip's direction in the world.
    fn tip_dir(&self) -> Vector3<f32> {
        self.rotation * self.tip_dir_tool
    }

    /// The device pose that puts the tip at `tip_mm` (world).
    fn command(&self, tip_mm: &Vector3<f32>) -> [ToolCommand; 2] {
        let origin = tip_mm - self.rotation * self.tip_tool_mm;
        self.pose_command(&self.rotation, &origin)
    }

    /// The device pose that puts the tool at `rotation`, its origin at `origin_mm` (world).
    fn pose_command(
        &self,
        rotation: &UnitQuaternion<f32>,
        origin_mm: &Vector3<f32>,
    ) -> [ToolCommand; 2] {
        [
            pose_command(origin_mm, &self.device_origin_mm, rotation),
            ToolCommand::default(),
        ]
    }

    /// Where the tool's tip is now (world).
    fn tip_now(&self) -> Vector3<f32> {
        let tool = &self.sim.tools[0];
        let pose = Isometry3::from_parts(Translation3::from(tool.position_mm), tool.rotation);
        (pose * Point3::from(self.tip_tool_mm)).coords
    }

    /// One tick with the device's tip aimed at `tip_mm`.
    fn step(&mut self, tip_mm: &Vector3<f32>) -> ToolOutput {
        let mut out = [ToolOutput::default(); 2];
        let command = self.command(tip_mm);
        let report = self.sim.step(DT_S, &command, &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
        out[0]
    }

    /// The force the tissue presses the tip back with, along the tip's direction, N.
    fn along_tip_n(&self, out: &ToolOutput) -> f32 {
        -out.force_world_n.dot(&self.tip_dir())
    }

    fn punctures(&self) -> u32 {
        self.sim.tools[0].needle().unwrap().punctures()
    }

    fn phase(&self) -> TipPhase {
        *self.sim.tools[0].needle().unwrap().phase()
    }

    /// Bring the tip from 6 mm above `at_mm` (on the rest surface) down its own direction until it presses
    /// with `target_n` along it, then hold that force for `hold_s`: a slow integral controller on the device's
    /// depth. Returns the outputs of the hold.
    fn press_to(&mut self, at_mm: &Vector3<f32>, target_n: f32, hold_s: f32) -> Vec<ToolOutput> {
        let dir = self.tip_dir();
        let mut depth_mm = -6.0f32;
        // Settle the tool at the start (a taken tool enters from its entry point).
        for _ in 0..1500 {
            self.step(&(at_mm + dir * depth_mm));
        }
        let mut held = Vec::new();
        let mut reached_at = None;
        for k in 0..20_000 {
            let out = self.step(&(at_mm + dir * depth_mm));
            let f = self.along_tip_n(&out);
            // 4 mm/s at most, slower as the force nears its target.
            depth_mm += ((target_n - f) * 0.004).clamp(-0.004, 0.004);
            if reached_at.is_none() && (f - target_n).abs() < 0.02 * target_n {
                reached_at = Some(k);
            }
            if let Some(start) = reached_at {
                held.push(out);
                if (k - start) as f32 * DT_S >= hold_s {
                    return held;
                }
            }
            if self.punctures() > 0 {
                return held;
            }
        }
        panic!("the tip never pressed with {target_n} N");
    }
}

#[test]
fn the_tip_tents_the_skin_below_the_puncture_force_and_punctures_past_it() {
    let mut driver = Driver::new(0.0);
    let threshold = driver.puncture_force_n;
    let at = Vector3::new(1.0, 1.0, 0.0);
    // 0.9 of the threshold along the tip, held 2 s: the skin tents, nothing punctures.
    let held = driver.press_to(&at, 0.9 * threshold, 2.0);
    assert_eq!(driver.punctures(), 0, "punctured below the threshold");
    assert!(matches!(
        driver.phase(),
        TipPhase::Pressing { exit: false, .. }
    ));
    let tent_mm = -driver.tip_now().z;
    let last = held.last().unwrap();
    println!(
        "held {:.3} N along the tip for 2 s, tip {tent_mm:.2} mm below the rest surface",
        driver.along_tip_n(last)
    );
    assert!(tent_mm > 0.5, "the skin did not tent: {tent_mm} mm");
    for out in &held {
        assert!((driver.along_tip_n(out) - 0.9 * threshold).abs() < 0.1 * threshold);
        // The model a distant device gets carries the pop (sim/needle_model.rs): at the tip's threshold (only
        // the tip loads the tool), along the tip, and after it free along the tip.
        let pop = &out.needle_pop;
        assert_eq!(pop.press, 1, "{pop:?}");
        assert!(
            (pop.pop_at_n - threshold).abs() < 0.05 * threshold,
            "{pop:?}"
        );
        assert!((pop.tip_axis - driver.tip_dir()).norm() < 1e-3, "{pop:?}");
        let along = (pop.stiffness_after_n_per_mm * pop.tip_axis).norm();
        assert!(
            along < 1e-4,
            "the needle is held along its path after the pop: {pop:?}"
        );
        assert!(
            pop.drag_after_n > 0.0 && pop.drag_after_n < threshold,
            "{pop:?}"
        );
    }
    // Past the threshold: it punctures, and the force drops at once.
    let before = driver.punctures();
    let mut peak = 0.0f32;
    let mut after = None;
    let dir = driver.tip_dir();
    let mut depth = driver.tip_now().dot(&dir) - at.dot(&dir);
    for _ in 0..3000 {
        depth += 0.002;
        let out = driver.step(&(at + dir * depth));
        if driver.punctures() > before {
            after = Some(out);
            break;
        }
        peak = peak.max(driver.along_tip_n(&out));
    }
    let after = after.expect("pressed past the threshold, the tip never punctured");
    println!(
        "punctured at {peak:.3} N along the tip; the tick after, {:.3} N",
        driver.along_tip_n(&after)
    );
    assert!(
        peak >= threshold * 0.98 && peak < threshold * 1.15,
        "{peak}"
    );
    assert!(
        driver.along_tip_n(&after) < 0.1 * threshold,
        "the pop did not drop the force"
    );
    assert!(matches!(driver.phase(), TipPhase::Inside { object: 0 }));
    assert_eq!(after.needle_pop.press, 0, "the press is over");
    assert!(after.in_contact, "the needle in the skin loads the tool");
    let needle = driver.sim.tools[0].needle().unwrap();
    assert_eq!(needle.holes().len(), 1);
    assert!(!needle.holes()[0].exit);
}

#[test]
fn a_tip_meeting_the_skin_at_a_glancing_angle_slides_instead_of_puncturing() {
    // Tilted 50 degrees further about y: the tip meets the surface 64 degrees off its normal.
    let mut driver = Driver::new(-50f32.to_radians());
    let dir = driver.tip_dir();
    let square = dir.dot(&-Vector3::z());
    assert!(square < 37f32.to_radians().cos(), "{square}");
    let threshold = driver.puncture_force_n;
    // Driven along its own direction from 6 mm before the surface to 14 mm past it, at 5 mm/s.
    let at = Vector3::new(-4.0, 1.0, 0.0);
    for _ in 0..1500 {
        driver.step(&(at - dir * 6.0));
    }
    let mut most_along_n = 0.0f32;
    for k in 0..4000 {
        let out = driver.step(&(at + dir * (-6.0 + 0.005 * k as f32)));
        assert_eq!(out.needle_pop.press, 0, "a glancing tip has no pop to make");
        if let TipPhase::Pressing { contact, .. } = driver.phase() {
            most_along_n = most_along_n.max(-contact.force_n.dot(&dir));
        }
    }
    println!("the glancing tip pressed with up to {most_along_n:.3} N along itself");
    assert!(
        most_along_n > threshold,
        "the tip never pressed past the threshold: the test proves nothing"
    );
    assert_eq!(driver.punctures(), 0, "punctured at a glancing angle");
}

/// The suture block with a half-circle needle held 10 degrees from its tail (170 degrees of it ahead of the
/// jaws), and the pose of the driver turned `turn_rad` about the needle's own axis, its centre 3 mm over the
/// skin at x = 0 (world y runs along the axis): the arc dips 7.7 mm into the skin, entering and leaving 10.3
/// mm either side, its tangent 16 degrees off the normal there. Returns the driver, the pose at a turn, and
/// the turn (and its sign) that brings the tip to the skin 8 degrees later, going down.
struct Bite {
    driver: Driver,
    centre: Vector3<f32>,
    centre_tool: Vector3<f32>,
    base: UnitQuaternion<f32>,
    start: f32,
    sign: f32,
}

impl Bite {
    fn new() -> Self {
        Self::gripped(10.0, None)
    }

    /// A half-circle needle held `grasp_deg` from its tail, by jaws of radius `jaws_mm` (None: the world's).
    fn gripped(grasp_deg: f32, jaws_mm: Option<f32>) -> Self {
        let mut world = suture_world();
        if let Some(radius_mm) = jaws_mm {
            world.tools[0].shape = sinew_server::collision::ToolShapeSpec::Sphere { radius_mm };
        }
        let InstrumentSpec::NeedleDriver(spec) = &mut world.tools[0].instrument else {
            panic!("tool 0 is not a needle driver");
        };
        spec.arc = NeedleArc::new(10.7, 180.0).unwrap();
        spec.grasp_at_rad = grasp_deg.to_radians();
        let spec = *spec;
        let driver = Driver::with(world, 0.0);
        let mut bite = Self {
            centre_tool: (spec.tool_from_needle() * Point3::origin()).coords,
            base: driver.rotation,
            driver,
            centre: Vector3::new(0.0, 1.0, 3.0),
            start: 0.0,
            sign: 1.0,
        };
        let entry_turn = (0..7200)
            .map(|k| -180f32.to_radians() + k as f32 * 0.05f32.to_radians())
            .find(|&turn| {
                let (rotation, _) = bite.pose_at(turn);
                bite.tip_at(turn).z.abs() < 0.05 && (rotation * bite.driver.tip_dir_tool).z < 0.0
            })
            .expect("the tip never reaches the skin going down");
        bite.start = entry_turn - 8f32.to_radians();
        let (r0, _) = bite.pose_at(bite.start);
        let ahead = bite.tip_at(bite.start + 0.01) - bite.tip_at(bite.start);
        bite.sign = if ahead.dot(&(r0 * bite.driver.tip_dir_tool)) > 0.0 {
            1.0
        } else {
            -1.0
        };
        bite
    }

    /// The tool's pose turned `turn_rad` about the needle's axis.
    fn pose_at(&self, turn_rad: f32) -> (UnitQuaternion<f32>, Vector3<f32>) {
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), turn_rad) * self.base;
        (rotation, self.centre - rotation * self.centre_tool)
    }

    fn tip_at(&self, turn_rad: f32) -> Vector3<f32> {
        let (rotation, origin) = self.pose_at(turn_rad);
        origin + rotation * self.driver.tip_tool_mm
    }

    /// One tick with the tool turned `turn_rad` along the needle's curve from the start and shifted by
    /// `shift_mm` (world). Returns the output.
    fn step(&mut self, turn_rad: f32, shift_mm: &Vector3<f32>) -> ToolOutput {
        let (rotation, origin) = self.pose_at(self.start + self.sign * turn_rad);
        let command = self.driver.pose_command(&rotation, &(origin + shift_mm));
        let mut out = [ToolOutput::default(); 2];
        let report = self.driver.sim.step(DT_S, &command, &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
        out[0]
    }
}

#[test]
fn a_needle_driven_along_its_curve_through_a_bite_pops_in_and_pops_out() {
    assert_counting_works();
    let mut bite = Bite::new();
    for _ in 0..1500 {
        bite.step(0.0, &Vector3::zeros());
    }
    let mut pops = Vec::with_capacity(2);
    let mut last_force = 0.0;
    let mut k = 0;
    let mut drive = |bite: &mut Bite, pops: &mut Vec<(usize, f32, f32)>, until: usize| {
        while pops.len() < until && k < 10_000 {
            let before = bite.driver.punctures();
            let out = bite.step(k as f32 * DT_S * 20f32.to_radians(), &Vector3::zeros());
            let force = out.force_world_n.norm();
            if bite.driver.punctures() > before {
                pops.push((k, last_force, force));
            }
            last_force = force;
            k += 1;
        }
    };
    drive(&mut bite, &mut pops, 1);
    // From the tick after the way in to the way out (tissue pressed and let go, a hole made), a tick
    // allocates nothing.
    let allocations = count_this_thread(|| drive(&mut bite, &mut pops, 2));
    println!(
        "pops (tick, force before, force after): {pops:?}; {allocations} allocations in between"
    );
    assert_eq!(allocations, 0, "the needle's ticks allocated");
    assert_eq!(pops.len(), 2, "a through-bite punctures twice");
    let needle = bite.driver.sim.tools[0].needle().unwrap();
    assert_eq!(needle.holes().len(), 2);
    assert!(!needle.holes()[0].exit && needle.holes()[1].exit);
    assert!(matches!(needle.phase(), TipPhase::Free));
    for (_, before, after) in pops {
        assert!(before > 1.0, "no peak before a pop: {before} N");
        assert!(
            after < 0.5 * before,
            "the pop did not drop the force: {before} -> {after} N"
        );
    }
}

#[test]
fn in_the_skin_the_needle_slides_along_its_curve_with_friction_and_a_push_out_of_its_plane_meets_a_wall()
 {
    let mut bite = Bite::new();
    for _ in 0..1500 {
        bite.step(0.0, &Vector3::zeros());
    }
    // Turn until the tip is in, then on for 1.3 s (26 degrees, 4.9 mm of needle through the skin).
    let mut turn = 0.0;
    while bite.driver.punctures() == 0 {
        turn += DT_S * 20f32.to_radians();
        bite.step(turn, &Vector3::zeros());
        assert!(turn < 1.0, "the tip never went in");
    }
    // The pop's spring-back settles over the next 0.3 s of driving.
    for _ in 0..300 {
        turn += DT_S * 20f32.to_radians();
        bite.step(turn, &Vector3::zeros());
    }
    let mut along = Vec::new();
    let mut drift_mm = 0.0f32;
    let entry = bite.driver.sim.tools[0].needle().unwrap().holes()[0].point;
    let skin = &bite.driver.sim.objects[0];
    let entry_at = entry.position_mm(&skin.model, &skin.state).unwrap();
    for _ in 0..1000 {
        turn += DT_S * 20f32.to_radians();
        let out = bite.step(turn, &Vector3::zeros());
        along.push(out.force_world_n.norm());
        let skin = &bite.driver.sim.objects[0];
        let now = entry.position_mm(&skin.model, &skin.state).unwrap();
        drift_mm = drift_mm.max((now - entry_at).norm());
    }
    let mean_along = along.iter().sum::<f32>() / along.len() as f32;
    let (least, most) = along
        .iter()
        .fold((f32::MAX, 0.0f32), |(lo, hi), &f| (lo.min(f), hi.max(f)));
    println!("drag along the curve from {least:.3} to {most:.3} N");
    // Then held there and pushed 2 mm out of the needle's plane (world +y) over 0.2 s, held 0.5 s.
    let mut sideways = ToolOutput::default();
    for k in 0..700 {
        let shift = Vector3::y() * (2.0 * (k as f32 / 200.0).min(1.0));
        sideways = bite.step(turn, &shift);
    }
    let f = sideways.force_world_n;
    println!(
        "driven along its curve: {mean_along:.3} N on average (the entry point moved {drift_mm:.2} mm); \
         pushed 2 mm out of its plane: {f:?} N"
    );
    assert_eq!(
        bite.driver.punctures(),
        1,
        "the needle tore out or punctured again"
    );
    assert!(mean_along > 0.05, "no drag along the curve: {mean_along} N");
    assert!(
        mean_along < 1.0,
        "more than friction along the curve: {mean_along} N"
    );
    assert!(
        drift_mm <= 0.5,
        "the entry point moved {drift_mm} mm on the skin"
    );
    assert!(f.y < -2.0 * mean_along, "no wall across the path: {f:?} N");
    assert!(
        -f.y > 0.8 * f.norm(),
        "the wall does not push back across the path: {f:?}"
    );
}

#[test]
fn a_needle_driven_through_a_bite_leaves_its_thread_in_both_holes_and_the_thread_drags_through_them()
 {
    // Held at its tail by small jaws (the hand-off to a grasper is not built: the driver follows the needle
    // through), turned along its curve until its tail has left both holes.
    let mut bite = Bite::gripped(0.0, Some(0.2));
    for _ in 0..1500 {
        bite.step(0.0, &Vector3::zeros());
    }
    let mut turn = 0.0;
    let thread_holes = |bite: &Bite| bite.driver.sim.tools[0].thread().unwrap().holes().len();
    while thread_holes(&bite) < 2 {
        turn += DT_S * 40f32.to_radians();
        bite.step(turn, &Vector3::zeros());
        assert!(
            turn < 2.0 * std::f32::consts::PI,
            "the tail never left both holes ({} taken)",
            thread_holes(&bite)
        );
    }
    // On a little, clear of the skin.
    for _ in 0..500 {
        turn += DT_S * 40f32.to_radians();
        bite.step(turn, &Vector3::zeros());
    }
    let inside_between = |bite: &Bite| {
        let thread = bite.driver.sim.tools[0].thread().unwrap();
        let holes = thread.holes();
        let (lo, hi) = (
            holes[0].u_mm.min(holes[1].u_mm),
            holes[0].u_mm.max(holes[1].u_mm),
        );
        let l = thread.chain().rest_length_mm() / (thread.nodes_mm().len() - 1) as f32;
        let mut wrong = 0;
        for (p, &u) in thread.nodes_mm().iter().zip(thread.chain().node_u_mm()) {
            let inside = depth_in_block_mm(p) > 0.0;
            let between = u > lo + l && u < hi - l;
            let beside = u < lo - l || u > hi + l;
            if (between && !inside) || (beside && inside) {
                wrong += 1;
            }
        }
        (lo, hi, wrong)
    };
    let (lo, hi, wrong) = inside_between(&bite);
    println!(
        "through: the holes hold the thread at {lo:.1} and {hi:.1} mm from its tail; {wrong} nodes on the wrong side"
    );
    assert_eq!(wrong, 0);
    // Then the driver drawn up 30 mm over 1.5 s: the thread runs through both holes, dragging, and pulls the
    // exit hole's skin up.
    let exit_z = |bite: &Bite| {
        let skin = &bite.driver.sim.objects[0];
        let thread = bite.driver.sim.tools[0].thread().unwrap();
        let exit = thread.holes()[1].point;
        exit.position_mm(&skin.model, &skin.state).unwrap().z
    };
    // Where the exit hole's material point lies on the skin at rest.
    let before = {
        let skin = &bite.driver.sim.objects[0];
        let thread = bite.driver.sim.tools[0].thread().unwrap();
        let HolePoint::Surface(exit) = thread.holes()[1].point else {
            panic!("the exit is not a surface hole");
        };
        let rest = skin.model.rest_positions_mm();
        let corners = exit.corners(&skin.model).unwrap();
        (0..3)
            .map(|k| rest[corners[k] as usize].z * exit.barycentric[k])
            .sum::<f32>()
    };
    let (mut lift_mm, mut exit_pull_z_n, mut tension_n) = (0.0f32, 0.0f32, 0.0f32);
    let mut slid_through = 0;
    let allocations = count_this_thread(|| {
        for k in 0..1500 {
            let up = Vector3::z() * (30.0 * k as f32 / 1500.0);
            bite.step(turn, &up);
            let thread = bite.driver.sim.tools[0].thread().unwrap();
            tension_n = tension_n.max(thread.chain().tension_n()[0]);
            exit_pull_z_n += thread.holes()[1].pull_on_tissue_n().z / 1500.0;
            slid_through += usize::from(thread.holes().iter().all(|h| h.slip != 0.0));
            lift_mm = lift_mm.max(exit_z(&bite) - before);
        }
    });
    let (lo2, hi2, wrong2) = inside_between(&bite);
    println!(
        "drawn up 30 mm: the holes at {lo2:.1} and {hi2:.1} mm, both sliding {slid_through} ticks, tension at the tail \
         up to {tension_n:.3} N, the exit pulled up {exit_pull_z_n:.3} N on average and up to {lift_mm:.3} mm above its place at rest, \
         {wrong2} nodes on the wrong side, {allocations} allocations"
    );
    assert_eq!(allocations, 0, "drawing the thread through allocated");
    assert_eq!(bite.driver.sim.tools[0].thread().unwrap().holes().len(), 2);
    assert!(
        lo2 > lo + 5.0 && hi2 > hi + 5.0,
        "the thread did not run through the holes"
    );
    assert!(slid_through > 50, "the holes never slid together");
    assert!(tension_n > 0.05, "no drag through the holes");
    assert!(
        exit_pull_z_n > 0.0 && lift_mm > 0.005,
        "the thread did not pull the skin up at the exit"
    );
    assert_eq!(wrong2, 0);
}
