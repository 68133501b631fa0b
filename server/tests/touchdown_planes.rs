//! Before a tool's first contact, the plane of the surface it approaches carries the stiffness of a touch-down
//! there (the contact-stiffness solve of the tool's footprint around the plane's node), not a fixed prior:
//! on a loosely held sheet it is a fraction of the pad's, as the contact then shows; a small tip's is a
//! fraction of a large probe's on the same pad, as its contact then shows; and after a contact the planes
//! carry that contact's measured stiffness.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_server::sim::{PLANE_STIFFNESS_PRIOR_N_PER_MM, Sim, ToolCommand, ToolOutput};
use sinew_server::world::load_world;

fn shipped(name: &str) -> Sim {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../worlds")
        .join(format!("{name}.toml"));
    Sim::new(&load_world(&path).unwrap()).unwrap()
}

/// Tool 0's sphere of `radius_mm` with its bottom `depth_mm` below the rest surface at its device origin.
fn at_depth(radius_mm: f32, depth_mm: f32) -> ToolCommand {
    ToolCommand {
        active: true,
        position_device_mm: [0.0, 0.0, radius_mm - depth_mm],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    }
}

fn idle() -> ToolCommand {
    ToolCommand {
        position_device_mm: [0.0, 0.0, 40.0],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..ToolCommand::default()
    }
}

/// Hover 3 mm above the surface for 0.1 s: the plane's stiffness. Then press `press_mm` in over 0.4 s and
/// hold 0.2 s: the contact's stiffness. Then lift back: the plane's stiffness after the contact.
fn approach_press_lift(sim: &mut Sim, radius_mm: f32, press_mm: f32) -> (f32, f32, f32) {
    let at_depth = |depth_mm| at_depth(radius_mm, depth_mm);
    let mut out = [ToolOutput::default(); 2];
    let mut step = |sim: &mut Sim, command: ToolCommand| {
        sim.step(0.001, &[command, idle()], &mut out);
        out[0]
    };
    let mut hover = ToolOutput::default();
    for _ in 0..100 {
        hover = step(sim, at_depth(-3.0));
    }
    assert!(!hover.in_contact && hover.plane_count >= 1, "{hover:?}");
    let mut pressed = ToolOutput::default();
    for k in 0..600 {
        pressed = step(
            sim,
            at_depth(-3.0 + (3.0 + press_mm) * ((k + 1) as f32 / 400.0).min(1.0)),
        );
    }
    assert!(pressed.in_contact);
    let contact_k = pressed.stiffness_n_per_mm[(2, 2)];
    let mut lifted = ToolOutput::default();
    for _ in 0..600 {
        lifted = step(sim, at_depth(-3.0));
    }
    assert!(!lifted.in_contact && lifted.plane_count >= 1);
    (
        hover.planes[0].stiffness_n_per_mm,
        contact_k,
        lifted.planes[0].stiffness_n_per_mm,
    )
}

#[test]
fn a_first_touch_meets_the_stiffness_of_the_tissue_it_will_touch() {
    let (pad_plane, pad_contact, pad_after) = approach_press_lift(&mut shipped("pad"), 4.0, 4.0);
    let (sheet_plane, sheet_contact, sheet_after) =
        approach_press_lift(&mut shipped("tug_of_war"), 4.0, 4.0);
    // The cautery's 1.5 mm tip on the same pad, pressed 1 mm (its demo goes 0.5 mm in).
    let (tip_plane, tip_contact, _) = approach_press_lift(&mut shipped("cautery"), 1.5, 1.0);
    println!(
        "pad: plane before {pad_plane:.4} N/mm, contact {pad_contact:.4}, plane after {pad_after:.4}; \
         loose sheet: {sheet_plane:.4}, {sheet_contact:.4}, {sheet_after:.4}; \
         1.5 mm tip on the pad: {tip_plane:.4}, {tip_contact:.4}"
    );
    for (plane, contact) in [(pad_plane, pad_contact), (sheet_plane, sheet_contact)] {
        assert!(
            plane > 0.0 && plane < PLANE_STIFFNESS_PRIOR_N_PER_MM,
            "{plane}"
        );
        // Within a factor of two of what the contact then shows.
        assert!(
            (0.5..=2.0).contains(&(plane / contact)),
            "plane {plane} N/mm against the contact's {contact} N/mm"
        );
    }
    assert!(
        sheet_plane < 0.5 * pad_plane,
        "{sheet_plane} vs {pad_plane}"
    );
    // A fixed 2.5 mm footprint gave the tip the probe's plane (0.17 N/mm), six times what its contact
    // shows. Its footprint now holds one node: softer than the contact (0.008 against 0.029 N/mm), never
    // stiffer.
    assert!(tip_plane < 0.5 * pad_plane, "{tip_plane} vs {pad_plane}");
    assert!(
        tip_plane > 0.0 && tip_plane <= tip_contact,
        "tip: plane {tip_plane} N/mm against the contact's {tip_contact} N/mm"
    );
    // After a contact: that contact's measured stiffness.
    assert!((pad_after - pad_contact).abs() <= 0.5 * pad_contact);
    assert!(sheet_after > 0.0);
}
