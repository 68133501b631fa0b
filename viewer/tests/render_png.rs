//! Offscreen rendering of a hand-made replica (no zenoh): the image shows the sheet, and deforming the sheet
//! changes the image. Needs a Vulkan adapter (Mesa lavapipe is enough: `apt-get install libvulkan1
//! mesa-vulkan-drivers`); without one this test fails on purpose.

// This whole file is test code: a panic is a test failure (clippy's allow-unwrap-in-tests only covers #[test] fns).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{diff_delta, quantize_all, sheet_positions_mm, sheet_snapshot};
use image::RgbImage;
use sinew_viewer::render::{render_image_framed, render_sequence};
use sinew_viewer::scene_view::BACKGROUND_RGB;
use sinew_viewer::{
    CameraFraming, DeltaOutcome, SceneReplica, ViewerError, frame_replica, render_image, render_png,
};

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

fn render(replica: &SceneReplica, framing: &CameraFraming) -> RgbImage {
    match render_image_framed(replica, framing, WIDTH, HEIGHT) {
        Ok((image, stats)) => {
            assert_eq!((stats.width, stats.height), (WIDTH, HEIGHT));
            image
        }
        Err(err @ ViewerError::NoGpuAdapter { .. }) => panic!(
            "offscreen rendering needs a Vulkan adapter and none was found: {err}. \
             CI must install libvulkan1 and mesa-vulkan-drivers (Mesa lavapipe)."
        ),
        Err(err) => panic!("offscreen rendering failed: {err}"),
    }
}

fn differs_from_background(p: &image::Rgb<u8>) -> bool {
    p.0.iter()
        .zip(BACKGROUND_RGB)
        .any(|(&c, b)| c.abs_diff(b) > 6)
}

/// Pinkish: red clearly above green and blue (tissue under any of the scene's lights).
fn tissue_like(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r > 60 && r > g + 25 && r > b + 15
}

#[test]
fn renders_the_sheet_and_shows_a_deformation() {
    let n = 20;
    let flat_q = quantize_all(&sheet_positions_mm(n));
    let mut replica =
        SceneReplica::from_snapshot(sheet_snapshot(flat_q.clone(), n, 1, [25.0, 10.0, 8.0]));

    // One viewpoint for both frames, so only the deformation changes the image.
    let framing = frame_replica(&replica);
    let flat = render(&replica, &framing);
    assert_eq!(flat.dimensions(), (WIDTH, HEIGHT));

    // The centre region (middle half in each direction) is mostly sheet.
    let (x0, x1, y0, y1) = (WIDTH / 4, 3 * WIDTH / 4, HEIGHT / 4, 3 * HEIGHT / 4);
    let centre_pixels = u64::from((x1 - x0) * (y1 - y0));
    let covered_centre = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .filter(|&(x, y)| differs_from_background(flat.get_pixel(x, y)))
        .count() as u64;
    assert!(
        covered_centre * 2 > centre_pixels,
        "only {covered_centre} of {centre_pixels} centre pixels differ from the background"
    );
    let tissue = flat.pixels().filter(|p| tissue_like(p)).count();
    assert!(
        tissue > (WIDTH * HEIGHT / 10) as usize,
        "only {tissue} tissue-coloured pixels; centre pixel is {:?}",
        flat.get_pixel(WIDTH / 2, HEIGHT / 2)
    );

    // Push the vertices within 15 mm of the centre down by 10 mm.
    let mut pushed_mm = sheet_positions_mm(n);
    let mut moved = 0;
    for p in &mut pushed_mm {
        if (p[0] * p[0] + p[1] * p[1]).sqrt() < 15.0 {
            p[2] -= 10.0;
            moved += 1;
        }
    }
    assert!(moved > 10);
    let pushed_q = quantize_all(&pushed_mm);
    let flat_replica = replica.clone();
    let delta = diff_delta(&flat_q, &pushed_q, 1, 2);
    assert_eq!(replica.apply_delta(&delta), Ok(DeltaOutcome::Applied));

    let pushed = render(&replica, &framing);
    // The same two states through one surface: the second frame updates the mesh in place (modify_vertices +
    // recompute_normals, the interactive window's path) and must look like the freshly built one.
    let sequence = render_sequence(&[&flat_replica, &replica], &framing, WIDTH, HEIGHT).unwrap();
    assert_eq!(sequence.len(), 2);
    let mismatched = |a: &RgbImage, b: &RgbImage| {
        a.pixels()
            .zip(b.pixels())
            .filter(|(p, q)| p.0.iter().zip(q.0).any(|(&x, y)| x.abs_diff(y) > 12))
            .count()
    };
    assert!(
        mismatched(&sequence[0].0, &flat) < (WIDTH * HEIGHT / 500) as usize,
        "first sequence frame differs from the single render"
    );
    let in_place = mismatched(&sequence[1].0, &pushed);
    assert!(
        in_place < (WIDTH * HEIGHT / 500) as usize,
        "in-place update differs from a fresh build in {in_place} pixels"
    );

    // Keep the images for a human to look at.
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    flat.save(dir.join("sinew_viewer_flat.png")).unwrap();
    pushed.save(dir.join("sinew_viewer_pushed.png")).unwrap();
    let changed = flat
        .pixels()
        .zip(pushed.pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0).any(|(&x, y)| x.abs_diff(y) > 12))
        .count();
    assert!(
        changed > (WIDTH * HEIGHT / 100) as usize,
        "the deformation changed only {changed} pixels"
    );

    let stats = render_png(
        &replica,
        &dir.join("sinew_viewer_render_png.png"),
        WIDTH,
        HEIGHT,
    )
    .unwrap();
    assert_eq!(stats.objects, 1);
    assert_eq!(stats.tools, 1);
    assert_eq!(stats.triangles, 2 * (n - 1) * (n - 1));
    assert!(stats.covered_pixels > 0);
}

#[test]
fn bad_image_size_is_an_error_not_a_panic() {
    let replica = SceneReplica::new();
    assert!(matches!(
        render_image(&replica, 0, 10),
        Err(ViewerError::BadImageSize { .. })
    ));
}

/// Grey (steel or inactive tool), not the background.
fn tool_like(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    differs_from_background(p) && (r - g).abs() < 20 && (g - b).abs() < 20 && r > 40
}

#[test]
fn draws_a_mesh_tool_where_the_server_says_it_is() {
    let n = 20;
    let flat_q = quantize_all(&sheet_positions_mm(n));
    let cube = |h: f32| -> Vec<[f32; 3]> {
        (0..8)
            .map(|i| {
                [
                    if i & 1 == 0 { -h } else { h },
                    if i & 2 == 0 { -h } else { h },
                    if i & 4 == 0 { -h } else { h },
                ]
            })
            .collect()
    };
    // Vertex i has bits (x, y, z); faces counter-clockwise from outside.
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    let mut snapshot = sheet_snapshot(flat_q, n, 1, [-20.0, 0.0, 8.0]);
    snapshot.tools[0].shape = sinew_protocol::ToolShape::Mesh {
        positions_mm: cube(6.0),
        triangles,
    };
    let mut replica = SceneReplica::from_snapshot(snapshot);
    let framing = frame_replica(&replica);
    let left = render(&replica, &framing);
    let grey = left.pixels().filter(|p| tool_like(p)).count();
    assert!(
        grey > 100,
        "only {grey} tool pixels: the mesh tool is not drawn"
    );

    let mut moved = replica.tool_states().clone();
    moved.frame += 1;
    moved.tools[0].position_mm = [20.0, 0.0, 8.0];
    assert!(replica.apply_tools(moved));
    let right = render(&replica, &framing);
    let changed = left
        .pixels()
        .zip(right.pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0).any(|(x, y)| x.abs_diff(y) > 10))
        .count();
    assert!(
        changed > (WIDTH * HEIGHT / 100) as usize,
        "moving the mesh tool 40 mm changed only {changed} pixels"
    );
}

#[test]
fn draws_a_needle_drivers_needle_in_its_jaws() {
    let n = 20;
    let flat_q = quantize_all(&sheet_positions_mm(n));
    let mut probe = sheet_snapshot(flat_q, n, 1, [0.0, 0.0, 6.0]);
    probe.tools[0].shape = sinew_protocol::ToolShape::Sphere { radius_mm: 0.5 };
    let mut driver = probe.clone();
    driver.tools[0].instrument = sinew_protocol::InstrumentInfo::NeedleDriver {
        jaw_length_mm: 10.0,
        needle_radius_mm: 10.7,
        needle_sweep_rad: 116f32.to_radians(),
        needle_diameter_mm: 1.0,
        grasp_at_rad: 40f32.to_radians(),
    };
    // One viewpoint (the sheet's) for both: only the instrument differs.
    let framing = frame_replica(&SceneReplica::from_snapshot(probe.clone()));
    let without = render(&SceneReplica::from_snapshot(probe), &framing);
    let with = render(&SceneReplica::from_snapshot(driver), &framing);
    let steel = |image: &RgbImage| image.pixels().filter(|p| tool_like(p)).count();
    let (before, after) = (steel(&without), steel(&with));
    println!("tool pixels: {before} as a probe, {after} holding a needle");
    assert!(
        after > before + 150,
        "the needle and jaws added only {} tool pixels",
        after - before
    );
}

/// Violet, as a suture thread is drawn: blue well above green, and above red.
fn thread_like(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    b > 50 && b > g + 40 && b > r + 10
}

#[test]
fn draws_a_suture_thread_where_the_tool_states_lay_it_and_follows_it() {
    let n = 20;
    let flat_q = quantize_all(&sheet_positions_mm(n));
    let snapshot = sheet_snapshot(flat_q, n, 1, [30.0, 30.0, 20.0]);
    let mut replica = SceneReplica::from_snapshot(snapshot);
    let framing = frame_replica(&replica);
    let bare = render(&replica, &framing);
    // A thread lying across the sheet from (-20, -5) to (20, -5), 1 mm above it, 41 nodes.
    let lie = |y_mm: f32| -> Vec<[f32; 3]> {
        (0..=40)
            .map(|i| [-20.0 + i as f32, y_mm, 1.0 + 0.5 * (i as f32 * 0.3).sin()])
            .collect()
    };
    let mut states = replica.tool_states().clone();
    states.frame += 1;
    states.threads = vec![sinew_protocol::ThreadState::from_nodes_mm(0, &lie(-5.0))];
    assert!(replica.apply_tools(states.clone()));
    let laid = render(&replica, &framing);
    let violet = |image: &RgbImage| image.pixels().filter(|p| thread_like(p)).count();
    let (before, after) = (violet(&bare), violet(&laid));
    // Moved 10 mm across the sheet: the drawn thread follows.
    states.frame += 1;
    states.threads[0] = sinew_protocol::ThreadState::from_nodes_mm(0, &lie(5.0));
    assert!(replica.apply_tools(states));
    let moved = render(&replica, &framing);
    let changed = laid
        .pixels()
        .zip(moved.pixels())
        .filter(|(a, b)| thread_like(a) != thread_like(b))
        .count();
    println!(
        "thread pixels: {before} without, {after} with; {changed} changed when it moved 10 mm"
    );
    assert_eq!(before, 0, "violet pixels with no thread");
    assert!(
        after > 80,
        "only {after} thread pixels: the thread is not drawn"
    );
    assert!(
        changed > after,
        "moving the thread changed only {changed} pixels"
    );
}

/// Amber, as a hole pulled tight is drawn: red and green high, blue well below green (tissue pink has blue
/// near green).
fn amber(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r > 150 && g > 100 && r >= g && b + 50 < g
}

#[test]
fn marks_a_threads_holes_dark_when_slack_and_amber_when_drawn_tight() {
    use sinew_protocol::{HoleMark, ThreadState};
    let n = 20;
    let flat_q = quantize_all(&sheet_positions_mm(n));
    let snapshot = sheet_snapshot(flat_q, n, 1, [30.0, 30.0, 20.0]);
    let mut replica = SceneReplica::from_snapshot(snapshot);
    let framing = frame_replica(&replica);
    // A thread lying on the sheet from (-20, -5) to (20, -5), 0.3 mm above it; four holes along it, 10 mm apart.
    let nodes: Vec<[f32; 3]> = (0..=40).map(|i| [-20.0 + i as f32, -5.0, 0.3]).collect();
    let with_holes = |pull_n: f32| {
        let mut thread = ThreadState::from_nodes_mm(0, &nodes);
        thread.holes = (0..4)
            .map(|k| HoleMark {
                position_mm: [-15.0 + 10.0 * k as f32, -5.0, 0.0],
                pull_n,
                on_needle: k == 3,
            })
            .collect();
        thread
    };
    let mut frames = Vec::new();
    for holes in [None, Some(0.0), Some(3.3)] {
        let mut states = replica.tool_states().clone();
        states.frame += 1;
        states.threads = vec![match holes {
            None => ThreadState::from_nodes_mm(0, &nodes),
            Some(pull_n) => with_holes(pull_n),
        }];
        assert!(replica.apply_tools(states));
        frames.push(replica.clone());
    }
    let images = render_sequence(&frames.iter().collect::<Vec<_>>(), &framing, WIDTH, HEIGHT)
        .unwrap_or_else(|err| panic!("offscreen rendering failed: {err}"));
    let (bare, slack, tight) = (&images[0].0, &images[1].0, &images[2].0);
    let changed = |a: &RgbImage, b: &RgbImage| {
        a.pixels()
            .zip(b.pixels())
            .filter(|(p, q)| p.0.iter().zip(q.0).any(|(&x, y)| x.abs_diff(y) > 20))
            .count()
    };
    // The slack holes are darker than what they cover.
    let darker = bare
        .pixels()
        .zip(slack.pixels())
        .filter(|(p, q)| {
            p.0.iter().map(|&c| u32::from(c)).sum::<u32>()
                > q.0.iter().map(|&c| u32::from(c)).sum::<u32>() + 60
        })
        .count();
    let ambers = |img: &RgbImage| img.pixels().filter(|p| amber(p)).count();
    println!(
        "holes: {} pixels changed marking them ({darker} darker), {} amber drawn tight ({} slack)",
        changed(bare, slack),
        ambers(tight),
        ambers(slack)
    );
    assert!(darker >= 30, "only {darker} pixels darkened by four holes");
    assert_eq!(ambers(slack), 0, "amber pixels with no pull");
    assert!(
        ambers(tight) >= 25,
        "drawn tight, the holes show {} amber pixels",
        ambers(tight)
    );
}
