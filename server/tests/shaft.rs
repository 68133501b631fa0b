//! An instrument's shaft pushes tissue as its tip does, on virtual time on the shipped pad: a tool laid almost
//! flat presses the pad with its shaft, and a sheet that only the shaft touches is never passed through.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::sim::{PLANE_STIFFNESS_PRIOR_N_PER_MM, Sim, ToolCommand, ToolOutput};
use sinew_server::world::{ShaftSpec, ToolShapeSpec, load_world};

/// The pad with tool 0 a 1 mm tip, with or without a 40 mm shaft of radius 3 mm.
fn pad(shaft: bool) -> Sim {
    pad_with(1.0, shaft)
}

/// The pad with tool 0 a tip of `tip_radius_mm`, with or without a 40 mm shaft of radius 3 mm.
fn pad_with(tip_radius_mm: f32, shaft: bool) -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let mut world = load_world(&path).unwrap();
    // Tool 0 is the left probe: a 4 mm sphere at world x = -18, with no shaft.
    let tool = &mut world.tools[0];
    assert!(
        tool.shape == ToolShapeSpec::Sphere { radius_mm: 4.0 }
            && tool.device_origin_in_world_mm[0] == -18.0
            && tool.shaft.is_none()
    );
    tool.shape = ToolShapeSpec::Sphere {
        radius_mm: tip_radius_mm,
    };
    if shaft {
        tool.shaft = Some(ShaftSpec {
            radius_mm: 3.0,
            length_mm: 40.0,
        });
    }
    Sim::new(&world).unwrap()
}

/// Tool 0 turned 90 degrees about y (its shaft along world +x from the tip), the tip at device x = -10 and its
/// origin `height_mm` above the rest surface: the shaft runs over world x -28 to +12.
fn laid_flat(height_mm: f32) -> [ToolCommand; 1] {
    let half = std::f32::consts::FRAC_PI_4;
    [ToolCommand {
        active: true,
        position_device_mm: [-10.0, 0.0, height_mm],
        orientation_xyzw: [0.0, half.sin(), 0.0, half.cos()],
        ..ToolCommand::default()
    }]
}

/// Lower the laid-flat tool from 10 mm to `height_mm` over 0.6 s and hold 0.6 s; the last output and how far
/// the highest pad node right under the shaft (world x -24 to +10, y = 0) lies below the shaft's underside
/// where the tool is (the coupling holds it above the hand when the tissue pushes back hard), mm.
fn press(sim: &mut Sim, height_mm: f32) -> (ToolOutput, f32) {
    let mut out = [ToolOutput::default(); 2];
    for k in 0..1200 {
        let h = 10.0 + (height_mm - 10.0) * ((k + 1) as f32 / 600.0).min(1.0);
        let report = sim.step(0.001, &laid_flat(h), &mut out);
        assert_eq!(report.faults, 0, "the guard reset the tissue");
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
    }
    let pad = &sim.objects[0];
    let rest = pad.model.rest_positions_mm();
    let highest = rest
        .iter()
        .zip(&pad.state.positions_mm)
        .filter(|(r, _)| (-24.0..=10.0).contains(&r.x) && r.y.abs() < 0.5)
        .map(|(_, x)| x.z)
        .fold(f32::MIN, f32::max);
    let underside_mm = sim.tools[0].position_mm.z - 3.0;
    (out[0], highest - underside_mm)
}

#[test]
fn a_shaft_laid_on_the_pad_pushes_it_and_is_never_passed_through() {
    // Shaft axis 1 mm above the surface: its underside 2 mm into the pad, the 1 mm tip just touching.
    let (with, _) = press(&mut pad(true), 1.0);
    let (without, _) = press(&mut pad(false), 1.0);
    println!(
        "shaft 2 mm in: {:.3} N over {} nodes; tip alone {:.3} N over {} nodes",
        with.force_world_n.z, with.held_nodes, without.force_world_n.z, without.held_nodes
    );
    assert!(
        with.force_world_n.z > 0.2,
        "the shaft pushed {} N",
        with.force_world_n.z
    );
    assert!(with.held_nodes > 20);
    assert!(without.force_world_n.z < 0.05 * with.force_world_n.z);
    // Pressed so that the shaft's axis is 4 mm below the rest surface: the sheet under the shaft stays under
    // it (below its underside, give or take a node's rounding), where without a shaft it goes right through.
    let (deep, above) = press(&mut pad(true), -4.0);
    let (_, through) = press(&mut pad(false), -4.0);
    println!(
        "shaft axis 4 mm down: {:.3} N, highest node under it {above:.3} mm from its underside; without a \
         shaft {through:.2} mm (3 mm is its axis)",
        deep.force_world_n.z
    );
    assert!(
        above < 0.1,
        "the sheet passed into the shaft: {above} mm above its underside"
    );
    assert!(
        through > 3.0,
        "without a shaft the sheet should stay where it was: {through} mm"
    );
    assert!(deep.force_world_n.z > with.force_world_n.z);
}

/// The most restrictive plane along world +z among the output's planes: the height (mm) below which the
/// tool's origin would be pushed back, or None without an upward plane.
fn floor_mm(out: &ToolOutput) -> Option<f32> {
    out.planes[..usize::from(out.plane_count)]
        .iter()
        .filter(|p| p.normal.z > 0.999)
        .map(|p| p.offset_mm / p.normal.z)
        .reduce(f32::max)
}

#[test]
fn a_shaft_over_the_tissue_sends_its_own_plane_so_a_distant_hand_meets_it_in_time() {
    // Laid flat 4 mm over the pad and held there, out of contact: the shaft (radius 3 mm) is 1 mm clear of the
    // surface, the 1 mm tip 3 mm clear. A distant device renders the planes against its hand before the
    // server sees a contact: the tip's alone would let the shaft sink 2 mm into the pad first.
    let hover = |shaft| {
        let mut sim = pad(shaft);
        let mut out = [ToolOutput::default(); 2];
        for _ in 0..300 {
            sim.step(0.001, &laid_flat(4.0), &mut out);
        }
        assert!(!out[0].in_contact, "{:?}", out[0]);
        out[0]
    };
    let (with, without) = (hover(true), hover(false));
    let (with_floor, without_floor) = (floor_mm(&with).unwrap(), floor_mm(&without).unwrap());
    println!(
        "origin's floor with the shaft {with_floor:.3} mm ({} planes), tip alone {without_floor:.3} mm",
        with.plane_count
    );
    // The pad's rest surface is z = 0 (a hovering tool does not move it).
    assert!((with_floor - 3.0).abs() < 0.05, "{with_floor}");
    assert!((without_floor - 1.0).abs() < 0.05, "{without_floor}");
    // Every plane is finite and unit; the shaft's carries the tip's touch-down stiffness (the same tissue,
    // not the fixed prior, which is several times a loose sheet's).
    assert_eq!(with.plane_count, 2, "{:?}", with.planes);
    for p in &with.planes[..usize::from(with.plane_count)] {
        assert!(p.offset_mm.is_finite() && (p.normal.norm() - 1.0).abs() < 1e-4);
        assert!(p.stiffness_n_per_mm > 0.0 && p.stiffness_n_per_mm.is_finite());
        assert_eq!(p.stiffness_n_per_mm, with.planes[0].stiffness_n_per_mm);
    }
    assert!(with.planes[1].stiffness_n_per_mm < PLANE_STIFFNESS_PRIOR_N_PER_MM);
    // Upright: the shaft's lower end sits at the origin, its 3 mm radius past the 1 mm tip, so the floor is
    // the shaft's there too; under a 4 mm tip it adds nothing the tip's plane does not already keep out.
    let upright = |tip_radius_mm| {
        let mut sim = pad_with(tip_radius_mm, true);
        let mut out = [ToolOutput::default(); 2];
        let command = ToolCommand {
            active: true,
            position_device_mm: [-10.0, 0.0, 8.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..ToolCommand::default()
        };
        for _ in 0..300 {
            sim.step(0.001, &[command], &mut out);
        }
        assert!(!out[0].in_contact);
        out[0]
    };
    let thin_tip = upright(1.0);
    assert!((floor_mm(&thin_tip).unwrap() - 3.0).abs() < 0.05);
    let probe = upright(4.0);
    assert!((floor_mm(&probe).unwrap() - 4.0).abs() < 0.05);
    assert_eq!(probe.plane_count, 1, "{:?}", probe.planes);
}
