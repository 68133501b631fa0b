//! An instrument's shaft pushes tissue as its tip does, on virtual time on the shipped pad: a tool laid almost
//! flat presses the pad with its shaft, and a sheet that only the shaft touches is never passed through.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::{ShaftSpec, ToolShapeSpec, load_world};

/// The pad with tool 0 a 1 mm tip, with or without a 40 mm shaft of radius 3 mm.
fn pad(shaft: bool) -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let mut world = load_world(&path).unwrap();
    // Tool 0 is the left probe: a 4 mm sphere at world x = -18, with no shaft.
    let tool = &mut world.tools[0];
    assert!(
        tool.shape == ToolShapeSpec::Sphere { radius_mm: 4.0 }
            && tool.device_origin_in_world_mm[0] == -18.0
            && tool.shaft.is_none()
    );
    tool.shape = ToolShapeSpec::Sphere { radius_mm: 1.0 };
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
