//! Grasping the shipped pad on virtual time: closed jaws take hold only of tissue touching both of them; a
//! grasped pull feels like a pull (the force points back toward the tissue and grows with it); opening the jaws
//! lets go and the tissue relaxes; a pull past the slip force slips the tissue out of the jaws.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use nalgebra::UnitQuaternion;
use sinew_server::interaction::JawInput;
use sinew_server::sim::{Sim, StepReport, ToolCommand, ToolOutput};
use sinew_server::world::{GraspSpec, InstrumentSpec, ToolShapeSpec, load_world};

/// The pad world with both probes (4 mm spheres) turned into graspers: `grasp` is what a world file's
/// `instrument = { kind = "grasper", ... }` gives (`GraspSpec::DEFAULT` for no keys beyond the kind).
fn pad_with_graspers(grasp: GraspSpec) -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let mut world = load_world(&path).expect("pad loads");
    let sphere = ToolShapeSpec::Sphere { radius_mm: 4.0 };
    assert_eq!(world.tools.iter().filter(|t| t.shape == sphere).count(), 2);
    for tool in &mut world.tools {
        tool.instrument = InstrumentSpec::Grasper(grasp);
    }
    Sim::new(&world).expect("builds")
}

/// Tool 0 (device origin at world x = -18) with its sphere's bottom `depth_mm` below the rest surface.
fn at(depth_mm: f32, closed: bool) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [0.0, 0.0, 4.0 - depth_mm],
        jaws: JawInput {
            buttons: u32::from(closed),
            jaw_angle_rad: 0.0,
        },
        ..ToolCommand::default()
    }
}

/// Run `ticks` ticks with tool 0 at `command` (tool 1 absent); the last output and the summed reports.
fn run(sim: &mut Sim, command: ToolCommand, ticks: usize) -> (ToolOutput, StepReport) {
    let mut out = [ToolOutput::default(); 2];
    let mut total = StepReport::default();
    for _ in 0..ticks {
        let report = sim.step(0.001, &[command], &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
        total.grasps_taken += report.grasps_taken;
        total.grasps_missed += report.grasps_missed;
        total.attachments_released += report.attachments_released;
        total.attachments_slipped += report.attachments_slipped;
    }
    (out[0], total)
}

/// Lower tool 0 from 10 mm above to `depth_mm` over 0.5 s and let it settle, jaws open.
fn press(sim: &mut Sim, depth_mm: f32) {
    for k in 0..500 {
        let d = -10.0 + (depth_mm + 10.0) * (k + 1) as f32 / 500.0;
        run(sim, at(d, false), 1);
    }
    run(sim, at(depth_mm, false), 300);
}

/// Largest distance of any pad node from its rest position, mm.
fn max_displacement_mm(sim: &Sim) -> f32 {
    let pad = &sim.objects[0];
    pad.state
        .positions_mm
        .iter()
        .zip(pad.model.rest_positions_mm())
        .map(|(x, r)| (x - r).norm())
        .fold(0.0, f32::max)
}

#[test]
fn grasp_then_pull_feels_like_a_pull_and_release_lets_the_tissue_relax() {
    let mut sim = pad_with_graspers(GraspSpec::DEFAULT);
    press(&mut sim, 1.5);
    let (pressed, _) = run(&mut sim, at(1.5, false), 1);
    assert!(pressed.force_world_n.z > 0.0, "pressing pushes the tool up");
    // Close: the tissue is taken at once, and the force passes from the body's push to the grasp's pull as
    // the jaws close, never stepping by more than 0.05 N a tick (counting the taken points' push twice on the
    // take's tick stepped it by 0.2 N here).
    let mut previous_n = pressed.force_world_n;
    let mut taken = 0;
    for tick in 1..=50 {
        let (out, report) = run(&mut sim, at(1.5, true), 1);
        taken += report.grasps_taken;
        let step_n = (out.force_world_n - previous_n).norm();
        assert!(
            step_n <= 0.05,
            "tick {tick} of the take: stepped {step_n} N"
        );
        previous_n = out.force_world_n;
    }
    assert_eq!(taken, 1);
    let (closed, _) = run(&mut sim, at(1.5, true), 1);
    assert!(closed.jaws_closed && closed.attachments > 0);
    let held = closed.attachments;
    // Pull up 5 mm over 1 s, 1 mm at a time, holding 0.2 s at each.
    let mut forces = Vec::new();
    for pull_mm in 1..=5 {
        let target = 1.5 - pull_mm as f32;
        for k in 0..200 {
            let d = target + 1.0 - (k + 1) as f32 / 200.0;
            run(&mut sim, at(d, true), 1);
        }
        let (out, report) = run(&mut sim, at(target, true), 200);
        assert_eq!(report.attachments_slipped, 0, "no slip at {pull_mm} mm");
        assert_eq!(out.attachments, held);
        forces.push(out.force_world_n);
    }
    eprintln!("held {held}, forces {forces:?}");
    for (k, f) in forces.iter().enumerate() {
        // The force points back toward the tissue (down, into the pad) ...
        assert!(
            f.z < 0.0 && f.z.abs() > 2.0 * f.xy().norm(),
            "pull {} mm: force {f:?} does not point back at the tissue",
            k + 1
        );
    }
    // ... and grows with the pull.
    for pair in forces.windows(2) {
        assert!(
            pair[1].z < pair[0].z - 0.01,
            "force does not grow with the pull: {forces:?}"
        );
    }
    assert!(
        max_displacement_mm(&sim) > 4.0,
        "the grasped tissue follows the jaws up"
    );
    // Open: the jaws let go as they open (40 degrees at 8 rad/s, about 87 ms), the pull falling with them,
    // never by more than 0.1 N a tick; then the tissue is let go and relaxes.
    let pulled_n = forces[4].norm();
    let mut previous_n = pulled_n;
    let mut released = 0;
    let mut let_go_after = None;
    for tick in 1..=150 {
        let (open, report) = run(&mut sim, at(-3.5, false), 1);
        let force_n = open.force_world_n.norm();
        assert!(
            (force_n - previous_n).abs() <= 0.1,
            "tick {tick} of the opening: {previous_n} -> {force_n} N"
        );
        if tick == 10 {
            assert_eq!(
                open.attachments, held,
                "still holding 10 ms into the opening"
            );
            assert!(
                force_n < pulled_n && force_n > 0.5 * pulled_n,
                "10 ms in: {force_n} N of {pulled_n}"
            );
        }
        released += report.attachments_released;
        if open.attachments == 0 && let_go_after.is_none() {
            let_go_after = Some(tick);
        }
        previous_n = force_n;
    }
    assert_eq!(released, u32::from(held));
    let ticks = let_go_after.expect("the jaws never let go");
    assert!((80..=95).contains(&ticks), "let go after {ticks} ticks");
    run(&mut sim, at(-3.5, false), 2000);
    assert!(
        max_displacement_mm(&sim) < 0.1,
        "the tissue has not relaxed: {} mm",
        max_displacement_mm(&sim)
    );
}

#[test]
fn jaws_touching_tissue_with_one_side_only_take_nothing() {
    let mut sim = pad_with_graspers(GraspSpec::DEFAULT);
    // Turn the tool a quarter about x: its jaw plane lies flat, so only the lower jaw meets the pad.
    let q =
        UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), std::f32::consts::FRAC_PI_2);
    let turned = |depth_mm: f32, closed: bool| ToolCommand {
        orientation_xyzw: [q.i, q.j, q.k, q.w],
        ..at(depth_mm, closed)
    };
    for k in 0..500 {
        let d = -10.0 + 11.5 * (k + 1) as f32 / 500.0;
        run(&mut sim, turned(d, false), 1);
    }
    let (pressed, _) = run(&mut sim, turned(1.5, false), 300);
    assert!(pressed.in_contact);
    let (closed, report) = run(&mut sim, turned(1.5, true), 50);
    assert_eq!((report.grasps_taken, report.grasps_missed), (0, 1));
    assert!(closed.jaws_closed && closed.attachments == 0);
    // Lifting the closed jaws pulls nothing up.
    let (lifted, _) = run(&mut sim, turned(-5.0, true), 500);
    assert!(!lifted.in_contact && lifted.force_world_n.norm() < 1e-3);
}

#[test]
fn closed_jaws_pressed_onto_tissue_do_not_grasp_it() {
    let mut sim = pad_with_graspers(GraspSpec::DEFAULT);
    run(&mut sim, at(-10.0, true), 10);
    press_closed(&mut sim);
    let (out, report) = run(&mut sim, at(1.5, true), 200);
    assert_eq!(report.grasps_taken, 0);
    assert!(out.in_contact && out.attachments == 0);
}

fn press_closed(sim: &mut Sim) {
    for k in 0..500 {
        let d = -10.0 + 11.5 * (k + 1) as f32 / 500.0;
        run(sim, at(d, true), 1);
    }
}

#[test]
fn a_pull_past_the_slip_force_slips_the_tissue_out_of_the_jaws() {
    let mut sim = pad_with_graspers(GraspSpec {
        slip_force_n: 0.03,
        ..GraspSpec::DEFAULT
    });
    press(&mut sim, 1.5);
    let (closed, _) = run(&mut sim, at(1.5, true), 50);
    let held = closed.attachments;
    assert!(held > 4);
    let mut slipped = 0;
    let mut peak_n: f32 = 0.0;
    for k in 0..1500 {
        let d = 1.5 - 8.0 * (k + 1) as f32 / 1500.0;
        let (out, report) = run(&mut sim, at(d, true), 1);
        slipped += report.attachments_slipped;
        peak_n = peak_n.max(out.force_world_n.norm());
        // Each point holds at most the slip force (plus the body's push, zero once lifted clear).
        assert!(out.force_world_n.norm() <= 0.03 * f32::from(out.attachments) + 0.5);
    }
    let (out, _) = run(&mut sim, at(-6.5, true), 200);
    eprintln!(
        "slip: held {held} -> {}, slipped {slipped}, peak {peak_n} N",
        out.attachments
    );
    assert!(slipped > 0, "nothing slipped");
    assert!(
        out.attachments < held,
        "still holding {} of {held}",
        out.attachments
    );
    assert!(peak_n > 0.0);
}
