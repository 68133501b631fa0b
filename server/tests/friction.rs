//! Coulomb friction between a probe and the shipped pad, on virtual time: with the material's
//! `friction_coefficient` the probe drags the surface along before it slides, the hand feels the drag against
//! its stroke (more than the dent's walls alone give), and a still press stays free of ripple.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::sim::{Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

/// The pad with `friction_coefficient = mu` (none for 0).
fn pad(mu: f32) -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let mut world = load_world(&path).unwrap();
    if mu > 0.0 {
        // The shipped pad is frictionless: the coefficient is the only change.
        assert_eq!(world.objects[0].material.friction_coefficient, 0.0);
        world.objects[0].material.friction_coefficient = mu;
    }
    Sim::new(&world).unwrap()
}

/// Tool 0 (sphere radius 4, device origin at world x = -18) with its bottom `depth_mm` below the rest surface.
fn at(x_mm: f32, depth_mm: f32) -> [ToolCommand; 1] {
    [ToolCommand {
        active: true,
        position_device_mm: [x_mm, 0.0, 4.0 - depth_mm],
        ..ToolCommand::default()
    }]
}

struct Stroke {
    /// Mean force against the stroke (-x) over its second half, N.
    drag_n: f32,
    /// How far the surface node first under the probe moved along x by the stroke's first millimetre, mm.
    dragged_mm: f32,
    /// Its x displacement at the end of the stroke, mm.
    carried_mm: f32,
    /// Force at the end of the press (before the stroke), N.
    press_n: f32,
    faults: u32,
}

/// Press 3 mm, settle, then stroke 6 mm along +x over 1.2 s.
fn stroke(mu: f32) -> Stroke {
    let mut sim = pad(mu);
    let mut out = [ToolOutput::default(); 2];
    let mut faults = 0;
    for k in 0..800 {
        let depth = -3.0 + 6.0 * ((k + 1) as f32 / 500.0).min(1.0);
        faults += sim.step(0.001, &at(0.0, depth), &mut out).faults;
    }
    let press_n = out[0].force_world_n.z;
    let rest = sim.objects[0].model.rest_positions_mm();
    let under = rest
        .iter()
        .position(|p| (p.x + 18.0).abs() < 1e-3 && p.y.abs() < 1e-3)
        .unwrap();
    let x0 = sim.objects[0].state.positions_mm[under].x;
    let (mut drag, mut samples, mut dragged_mm) = (0.0, 0, 0.0);
    for k in 0..1200 {
        let x = 6.0 * (k + 1) as f32 / 1200.0;
        faults += sim.step(0.001, &at(x, 3.0), &mut out).faults;
        assert!(out[0].force_world_n.iter().all(|c| c.is_finite()));
        if k == 199 {
            dragged_mm = sim.objects[0].state.positions_mm[under].x - x0;
        }
        if k >= 600 {
            drag += -out[0].force_world_n.x;
            samples += 1;
        }
    }
    Stroke {
        drag_n: drag / samples as f32,
        dragged_mm,
        carried_mm: sim.objects[0].state.positions_mm[under].x - x0,
        press_n,
        faults,
    }
}

#[test]
fn with_friction_a_stroking_probe_drags_the_surface_before_it_slides_and_feels_more_drag() {
    let smooth = stroke(0.0);
    let rough = stroke(0.5);
    for (name, s) in [("frictionless", &smooth), ("mu 0.5", &rough)] {
        println!(
            "{name}: press {:.3} N; stroke drag {:.3} N; surface under the probe moved {:.2} mm in the first 1 mm, \
             {:.2} mm by the end of 6 mm",
            s.press_n, s.drag_n, s.dragged_mm, s.carried_mm
        );
        assert_eq!(s.faults, 0, "{name}: the guard reset the tissue");
    }
    // Friction stiffens the press (the sheet's pull along the ball's flanks now carries load, measured +30% at
    // mu 0.5), within reason.
    assert!(rough.press_n >= smooth.press_n && rough.press_n < 1.5 * smooth.press_n);
    // It sticks: the surface rides with the probe into the first millimetre (0.41 mm measured), where the
    // frictionless probe slides over it (-0.10 mm: the dent's front wall pushes it back).
    assert!(
        rough.dragged_mm > 0.3,
        "mu 0.5 dragged the surface {} mm of 1",
        rough.dragged_mm
    );
    assert!(rough.dragged_mm > 2.0 * smooth.dragged_mm.max(0.05));
    // Then it slides: the surface is not carried the whole 6 mm.
    assert!(
        rough.carried_mm < 5.0,
        "the surface never slipped: {} mm",
        rough.carried_mm
    );
    // And the hand feels it: more drag against the stroke, within mu times the press on top of the walls'.
    assert!(
        rough.drag_n > smooth.drag_n + 0.05,
        "drag {} vs {}",
        rough.drag_n,
        smooth.drag_n
    );
    assert!(rough.drag_n < smooth.drag_n + 0.5 * rough.press_n * 1.2);
}

#[test]
fn with_friction_a_still_deep_press_holds_without_ripple() {
    for depth in [2.0f32, 5.0, 7.0] {
        let mut sim = pad(0.5);
        let mut out = [ToolOutput::default(); 2];
        for k in 0..1300 {
            let d = -3.0 + (depth + 3.0) * ((k + 1) as f32 / 300.0).min(1.0);
            sim.step(0.001, &at(0.0, d), &mut out);
        }
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut jitter = 0x9E37_79B9u32;
        for _ in 0..3000 {
            jitter ^= jitter << 13;
            jitter ^= jitter >> 17;
            jitter ^= jitter << 5;
            let dz = (jitter % 2001) as f32 * 1e-6 - 1e-3;
            let mut command = at(0.0, depth);
            command[0].position_device_mm[2] += dz;
            sim.step(0.001, &command, &mut out);
            lo = lo.min(out[0].force_world_n.z);
            hi = hi.max(out[0].force_world_n.z);
        }
        println!("mu 0.5, {depth} mm deep: force {lo:.4}..{hi:.4} N");
        assert!(lo > 0.05);
        assert!(hi - lo < 0.02 * hi, "ripple {:.4} N at {depth} mm", hi - lo);
    }
}
