//! A cut beside a stitch keeps the stitch (issue 32: "a cut beside an existing stitch keeps the stitch (stable
//! ids)"). The wound of worlds/suture.toml stitched as `suture_stitch.rs` draws it (the pass, the grasper
//! on the thread, both ends drawn crossed by hands that stop at 3 N), then a scalpel's sweep opens a slit in
//! the right edge beside the stitch: 10 mm long across the edge, 4 mm deep, 7 mm along the wound from the
//! stitch. The edge's topology changes (vertices split, springs and the collider rebuilt; elements keep their
//! ids), and the stitch holds: the thread's four holes stay where they were on the tissue and hold it, the
//! gap stays closed, nothing turns inside out, and the hands feel the same pull.

#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "common/tool_pose.rs"]
mod tool_pose;
#[path = "common/wound.rs"]
mod wound;

use sinew_server::interaction::suture::HolePoint;
use sinew_server::interaction::{BladeSweep, CutScratch};
use sinew_server::tissue::Vec3;
use wound::{CrossedDraw, Wound};

/// Where each of the thread's holes lies on its tissue now, world, mm.
fn hole_places(wound: &Wound) -> Vec<Vec3> {
    wound
        .thread()
        .holes()
        .iter()
        .map(|h| h.place_mm())
        .collect()
}

#[test]
fn a_slit_cut_beside_a_drawn_stitch_leaves_its_holes_its_closure_and_its_pull() {
    let (mut wound, _, mut draw) = CrossedDraw::after_the_pass(3.0);
    for _ in 0..6000 {
        draw.step(&mut wound);
    }
    let (gap_before, places_before, felt_before) = (wound.gap_mm(), hole_places(&wound), draw.felt);
    let nodes_before = wound.sim.objects[1].state.positions_mm.len();
    let version_before = wound.sim.objects[1].topology_version();
    assert_eq!(places_before.len(), 4);

    // The slit: the blade's edge from x = 4 to 14 mm at y = 7 mm, swept from 1 mm above the skin to 4 mm into it.
    let (y, x0, x1) = (7.0, 4.0, 14.0);
    let sweep = BladeSweep {
        from_mm: [Vec3::new(x0, y, 1.0), Vec3::new(x1, y, 1.0)],
        to_mm: [Vec3::new(x0, y, -4.0), Vec3::new(x1, y, -4.0)],
    };
    let mut scratch = CutScratch::default();
    let opening = wound.sim.cut(1, &sweep, &mut scratch);
    println!(
        "the slit split {} vertices ({} -> {} nodes)",
        opening.new_vertices(),
        nodes_before,
        wound.sim.objects[1].state.positions_mm.len()
    );
    assert!(opening.new_vertices() > 0, "the blade opened nothing");
    assert!(wound.sim.objects[1].topology_version() > version_before);

    // The hands hold where they are for a second.
    let mut inverted = 0;
    for k in 0..1000 {
        draw.step(&mut wound);
        if k % 250 == 0 {
            inverted = inverted.max(wound.inverted());
        }
    }
    let (gap_after, places_after, felt_after) = (wound.gap_mm(), hole_places(&wound), draw.felt);
    let drift_mm = places_after
        .iter()
        .zip(&places_before)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0f32, f32::max);
    println!(
        "after the slit: the gap {gap_before:.2} -> {gap_after:.2} mm; the holes moved {drift_mm:.3} mm at most; the \
         pull felt {felt_before:.2?} -> {felt_after:.2?} N; {inverted} inverted tetrahedra"
    );
    assert_eq!(
        places_after.len(),
        4,
        "the stitch lost a hole to a cut beside it"
    );
    assert!(
        drift_mm < 0.5,
        "a hole moved {drift_mm} mm with a cut beside it"
    );
    assert!(
        (gap_after - gap_before).abs() < 0.3 && gap_after <= 1.0,
        "the gap went {gap_before} -> {gap_after} mm"
    );
    for (a, b) in felt_after.iter().zip(felt_before) {
        assert!(
            a.is_finite() && (a - b).abs() < 0.3 * b.max(0.5),
            "the pull went {felt_before:?} -> {felt_after:?} N"
        );
    }
    assert_eq!(inverted, 0);
}

/// A cut that follows the blade through the triangles the stitch's holes lie on (the wound's edges with
/// `cut = "follow-blade"`): the pieces the holes end on hold them at the same places (re-expressed, not moved),
/// and the stitch holds as before.
#[test]
fn a_cut_that_follows_the_blade_past_a_hole_keeps_it_where_it_was_and_the_stitch_holds() {
    let wound = Wound::new_with(|world| {
        for object in &mut world.objects {
            object.material.cut_follows_blade = true;
        }
    });
    let (mut wound, _, mut draw) = CrossedDraw::after_the_pass_in(wound, 3.0);
    for _ in 0..6000 {
        draw.step(&mut wound);
    }
    let (gap_before, felt_before) = (wound.gap_mm(), draw.felt);
    let places_before = hole_places(&wound);
    assert_eq!(places_before.len(), 4);
    // Each hole's object, and the hole on the skin's top surface nearest the middle: the blade passes 0.3 mm
    // beside it, from 1 mm above to 1.5 mm below it, 4 mm along the wound (y).
    let objects: Vec<u16> = wound
        .thread()
        .holes()
        .iter()
        .map(|h| h.point.object())
        .collect();
    let (k, hole) = places_before
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
        .unwrap();
    let object = usize::from(objects[k]);
    let beside = |dy: f32| {
        [
            Vec3::new(hole.x + 0.3, hole.y + dy, hole.z + 1.0),
            Vec3::new(hole.x + 0.3, hole.y + dy, hole.z - 1.5),
        ]
    };
    let elements = |wound: &Wound| -> Vec<(u32, [u32; 4])> {
        wound
            .thread()
            .holes()
            .iter()
            .chain(wound.thread().tracks())
            .map(|h| match h.point {
                HolePoint::Surface(p) => (p.triangle, [0; 4]),
                HolePoint::Volume(p) => (p.tet, [1; 4]),
            })
            .collect()
    };
    let elements_before = elements(&wound);
    let mut scratch = CutScratch::default();
    let mut split = 0;
    let mut worst_mm = 0.0f32;
    for step in 0..40 {
        let dy = -2.0 + 0.1 * step as f32;
        let before = hole_places(&wound);
        let sweep = BladeSweep {
            from_mm: beside(dy),
            to_mm: beside(dy + 0.1),
        };
        let version = wound.sim.objects[object].topology_version();
        wound.sim.cut(object, &sweep, &mut scratch);
        if wound.sim.objects[object].topology_version() != version {
            split += 1;
        }
        let after = hole_places(&wound);
        for (a, b) in after.iter().zip(&before) {
            worst_mm = worst_mm.max((a - b).norm());
        }
        draw.step(&mut wound);
    }
    println!(
        "the blade beside hole {k} (object {object}) changed the topology on {split} sweeps; the holes moved at \
         most {worst_mm:.2e} mm across a cut"
    );
    let moved_to_pieces = elements(&wound)
        .iter()
        .zip(&elements_before)
        .filter(|(a, b)| a != b)
        .count();
    println!("{moved_to_pieces} holes and rings now on a new piece of their element");
    assert!(split > 0, "the blade changed nothing");
    assert!(
        moved_to_pieces > 0,
        "the blade split no element a hole or ring lies on"
    );
    assert!(worst_mm <= 1e-5, "a hole moved {worst_mm} mm across a cut");
    let mut inverted = 0;
    for k in 0..1000 {
        draw.step(&mut wound);
        if k % 250 == 0 {
            inverted = inverted.max(wound.inverted());
        }
    }
    let (gap_after, felt_after) = (wound.gap_mm(), draw.felt);
    println!(
        "after: the gap {gap_before:.2} -> {gap_after:.2} mm; the pull felt {felt_before:.2?} -> {felt_after:.2?} \
         N; {inverted} inverted tetrahedra"
    );
    assert_eq!(hole_places(&wound).len(), 4, "the stitch lost a hole");
    assert!(
        (gap_after - gap_before).abs() < 0.3 && gap_after <= 1.0,
        "the gap went {gap_before} -> {gap_after} mm"
    );
    for (a, b) in felt_after.iter().zip(felt_before) {
        assert!(
            a.is_finite() && (a - b).abs() < 0.3 * b.max(0.5),
            "the pull went {felt_before:?} -> {felt_after:?} N"
        );
    }
    assert_eq!(inverted, 0);
}
