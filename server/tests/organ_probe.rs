//! A probe on the coarse organ (issue 33): `worlds/liver.toml`, the shipped liver (corotational tetrahedra with
//! 3-5 mm surface edges, stepped at 25 Hz) under the left probe, a 4 mm sphere. Pressed 5 mm into the lobe
//! and stroked +-8 mm, the probe stays on the surface it dents: the lobe keeps pushing it up through the stroke
//! as it did while it held still, and no surface triangle lets the sphere through between its corners.
//!
//! Until 2026-12-07 the contact held nodes only: a sphere wider than the gaps between the organ's surface
//! nodes slipped between them on the stroke, the nodes ended on its sides and the lobe closed over it (the
//! force went sideways and nothing pushed up; BENCHMARKS.md, "The multi-rate liver at a distance").
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use nalgebra::Vector3;
use sinew_server::collision::closest_point_on_triangle;
use sinew_server::sim::{Sim, SimObject, ToolCommand, ToolOutput};

const PROBE_RADIUS_MM: f32 = 4.0;
/// How far the sphere's bottom goes below the rest surface, mm.
const PRESS_MM: f32 = 5.0;
const STROKE_MM: f32 = 8.0;
const STROKE_PERIOD_S: f32 = 2.0;

fn liver() -> Sim {
    let world = sinew_server::world::load_world(&common::worlds().join("liver.toml"))
        .expect("the liver world loads");
    Sim::new(&world).expect("the liver builds")
}

fn probe_at(centre_mm: Vector3<f32>) -> [ToolCommand; 2] {
    [
        ToolCommand {
            active: true,
            position_device_mm: centre_mm.into(),
            ..ToolCommand::default()
        },
        ToolCommand::default(),
    ]
}

/// How deep the sphere (centre `centre_mm`) reaches into the organ's surface between corners: over every
/// surface triangle, how far the triangle comes inside the sphere beyond what a triangle whose corners lie on
/// the sphere would (its sagitta), mm; 0 when none does.
fn sunk_between_corners_mm(object: &SimObject, centre_mm: &Vector3<f32>) -> f32 {
    let x = &object.state.positions_mm;
    let mut worst = 0.0f32;
    for t in object.model.triangles() {
        let [a, b, c] = t.map(|i| x[i as usize]);
        if [a, b, c]
            .iter()
            .all(|p| (p - centre_mm).norm() > PROBE_RADIUS_MM + 6.0)
        {
            continue;
        }
        let q = closest_point_on_triangle(centre_mm, &a, &b, &c);
        let longest = (a - b).norm().max((b - c).norm()).max((c - a).norm());
        let sagitta = longest * longest / (8.0 * PROBE_RADIUS_MM);
        let sunk = PROBE_RADIUS_MM - (q - centre_mm).norm() - sagitta;
        worst = worst.max(sunk);
    }
    worst
}

#[test]
fn a_probe_stroked_across_the_liver_stays_on_the_surface_it_dents() {
    let mut sim = liver();
    let top = common::rest_surface_z_mm(&sim.objects[0], 0.0, 0.0);
    let press_centre = top + PROBE_RADIUS_MM - PRESS_MM;
    let mut out = [ToolOutput::default(); 2];
    let mut step = |sim: &mut Sim, centre: Vector3<f32>| {
        let report = sim.step(0.001, &probe_at(centre), &mut out);
        assert_eq!(report.faults, 0, "the organ was reset");
        let f = out[0].force_world_n;
        assert!(
            f.iter().all(|c| c.is_finite()) && f.norm() <= 3.3 + 1e-4,
            "{f:?}"
        );
        f
    };
    // Down from 10 mm above over 1 s, then hold 1 s.
    for k in 0..1000 {
        let z = top + PROBE_RADIUS_MM + 10.0 - (10.0 + PRESS_MM) * (k + 1) as f32 / 1000.0;
        step(&mut sim, Vector3::new(0.0, 0.0, z));
    }
    let centre = Vector3::new(0.0, 0.0, press_centre);
    let held: Vec<f32> = (0..1000).map(|_| step(&mut sim, centre).z).collect();
    let held_n = held[500..].iter().sum::<f32>() / 500.0;
    // Two strokes.
    let (mut stroke_z, mut lowest_z) = (Vec::new(), f32::MAX);
    for k in 0..(2.0 * STROKE_PERIOD_S * 1000.0) as usize {
        let t = (k + 1) as f32 * 0.001;
        let x = STROKE_MM * (std::f32::consts::TAU * t / STROKE_PERIOD_S).sin();
        let f = step(&mut sim, Vector3::new(x, 0.0, press_centre));
        stroke_z.push(f.z);
        lowest_z = lowest_z.min(f.z);
    }
    // The strokes end in the middle: the probe stays there 0.4 s, moves to the stroke's end over 0.2 s and stays
    // 0.4 s. Each time it has stood still, the organ's latest step held it where it is: no triangle may let it in
    // between its corners.
    let mut worst_sunk_mm = 0.0f32;
    for k in 0..1000 {
        let s = (k.max(400) - 400) as f32 / 200.0;
        step(
            &mut sim,
            Vector3::new(STROKE_MM * s.min(1.0), 0.0, press_centre),
        );
        if k == 399 || k == 999 {
            let tool_mm = sim.tools[0].position_mm;
            worst_sunk_mm = worst_sunk_mm.max(sunk_between_corners_mm(&sim.objects[0], &tool_mm));
        }
    }
    let stroke_n = stroke_z.iter().sum::<f32>() / stroke_z.len() as f32;
    let weakest_n = {
        // The weakest 100 ms of the stroke, mean.
        stroke_z
            .windows(100)
            .step_by(20)
            .map(|w| w.iter().sum::<f32>() / 100.0)
            .fold(f32::MAX, f32::min)
    };
    println!(
        "liver probe: press {held_n:.3} N up; stroke mean {stroke_n:.3} N, weakest 100 ms {weakest_n:.3} N, \
         lowest {lowest_z:.3} N; deepest between corners {worst_sunk_mm:.2} mm"
    );
    assert!(
        held_n > 0.1,
        "the pressed lobe pushes up only {held_n:.3} N"
    );
    assert!(
        stroke_n > 0.6 * held_n,
        "stroking, the lobe pushes up {stroke_n:.3} N on average against {held_n:.3} N held: the probe sank"
    );
    assert!(
        weakest_n > 0.1 * held_n,
        "for 100 ms of the stroke the lobe pushed up only {weakest_n:.3} N (held {held_n:.3} N)"
    );
    assert!(
        worst_sunk_mm < 0.5,
        "a surface triangle let the sphere {worst_sunk_mm:.2} mm in between its corners"
    );
}

/// The organ steps at 25 Hz and sees the probe only at each step's launch pose, so a probe coming down at
/// 20 mm/s waited up to two steps for a push: it went 1.6 mm past touching the lobe before it felt anything,
/// then felt it in 0.03 N stairs 40 ms apart. The tick now renders the probe's plane on the organ from the
/// moment it crosses it, with the stiffness of a touch-down solved on the organ's latest step, until the
/// step's contact takes over (`multirate/lane_plane.rs`), and renders that contact with the same stiffness
/// until its own solve finishes.
#[test]
fn a_probe_coming_down_on_the_liver_feels_it_where_it_touches() {
    let mut sim = liver();
    let top = common::rest_surface_z_mm(&sim.objects[0], 0.0, 0.0);
    let touching_centre = top + PROBE_RADIUS_MM;
    let mut out = [ToolOutput::default(); 2];
    let (mut first_touch_mm, mut plane_k, mut at_1_mm_n) = (None, None, 0.0f32);
    let mut climb = Vec::new();
    // From 3 mm above touching to 3 mm past it at 20 mm/s.
    for k in 0..300 {
        let past_mm = -3.0 + 0.02 * (k + 1) as f32;
        let report = sim.step(
            0.001,
            &probe_at(Vector3::new(0.0, 0.0, touching_centre - past_mm)),
            &mut out,
        );
        assert_eq!(report.faults, 0, "the organ was reset");
        let f = out[0].force_world_n;
        assert!(f.iter().all(|c| c.is_finite()) && f.norm() <= 3.3 + 1e-4);
        if past_mm < 0.0 && out[0].plane_count > 0 {
            plane_k = Some(out[0].planes[0].stiffness_n_per_mm);
        }
        if first_touch_mm.is_none() && f.z > 0.005 {
            first_touch_mm = Some(past_mm);
        }
        if (past_mm - 1.0).abs() < 1e-3 {
            at_1_mm_n = f.z;
        }
        if past_mm > 0.0 {
            climb.push(f.z);
        }
    }
    let first_touch_mm = first_touch_mm.expect("the probe never felt the lobe");
    let plane_k = plane_k.expect("no plane ahead of the probe");
    // The largest drop from one tick to the next on the way in (at a hand-off the step's contact takes over
    // from the plane).
    let largest_drop_n = climb.windows(2).map(|w| w[0] - w[1]).fold(0.0f32, f32::max);
    println!(
        "liver touch-down at 20 mm/s: felt {first_touch_mm:.2} mm past touching the topmost node, {at_1_mm_n:.3} N \
         at 1 mm, {:.3} N at 3 mm; the plane ahead {plane_k:.3} N/mm; largest drop {largest_drop_n:.3} N",
        climb.last().unwrap()
    );
    assert!(
        first_touch_mm < 0.5,
        "the probe felt the lobe only {first_touch_mm:.2} mm past touching it"
    );
    assert!(
        at_1_mm_n > 0.02,
        "1 mm into the lobe the probe felt {at_1_mm_n:.3} N"
    );
    // The touch-down's stiffness, not the fixed prior of 0.2 N/mm (4 to 5 times the lobe's own).
    assert!(
        (0.01..0.1).contains(&plane_k),
        "the plane ahead of the probe carries {plane_k:.3} N/mm"
    );
    assert!(
        largest_drop_n < 0.05,
        "on the way in the force dropped {largest_drop_n:.3} N in a tick"
    );
}
