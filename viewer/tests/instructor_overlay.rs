//! The instructor's overlay: what it says for given stats (no GPU), and that it reaches the pixels (offscreen,
//! Mesa lavapipe): text in the top-left corner, a force arrow at the tool in its limit colour, rings round the
//! exercise's targets in their state's colour.

// This whole file is test code: a panic is a test failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{quantize_all, sheet_positions_mm, sheet_snapshot};
use image::RgbImage;
use sinew_protocol::{DeviceStats, ExerciseStats, ServerStats, TargetMark, TrainingStats};
use sinew_viewer::instructor_overlay::{
    ARROW_MM_PER_N, HIT_RGB, NEXT_RGB, TEXT_RGB, UNKNOWN_LIMIT_RGB, limit_rgb,
};
use sinew_viewer::render::{SceneFrame, render_frames};
use sinew_viewer::scene_view::BACKGROUND_RGB;
use sinew_viewer::{InstructorOverlay, SceneReplica, frame_replica};

const WIDTH: u32 = 480;
const HEIGHT: u32 = 360;

fn stats(force_limit_n: f32) -> ServerStats {
    ServerStats {
        sim_time_s: 12.5,
        tick_p99_us: 900.0,
        devices: vec![DeviceStats {
            device_id: "left".into(),
            tool: "probe".into(),
            active: true,
            moderated: true,
            last_round_trip_us: 2100,
            force_limit_n,
            training: TrainingStats {
                skill_state: "contact".into(),
                contacts: 3,
                ..TrainingStats::default()
            },
            ..DeviceStats::default()
        }],
        exercise: Some(ExerciseStats {
            kind: "coordination".into(),
            score: 75.0,
            hits: 2,
            total: 4,
            errors: 1,
            time_s: 9.5,
            completed: false,
            timed_out: false,
            targets: Vec::new(),
        }),
        ..ServerStats::default()
    }
}

/// The sheet with the probe 8 mm above its centre, pushed up by `force_n` (z).
fn replica_with_force(force_n: f32) -> SceneReplica {
    let n = 20;
    let mut replica = SceneReplica::from_snapshot(sheet_snapshot(
        quantize_all(&sheet_positions_mm(n)),
        n,
        1,
        [0.0, 0.0, 8.0],
    ));
    let mut tools = replica.tool_states().clone();
    tools.frame += 1;
    tools.sim_time_s = 12.5;
    tools.tools[0].force_n = [force_n, 0.0, force_n];
    tools.tools[0].in_contact = true;
    assert!(replica.apply_tools(tools));
    replica
}

#[test]
fn says_who_is_where_and_scales_and_colours_the_force() {
    let force = 2.0_f32;
    let replica = replica_with_force(force);
    let overlay = InstructorOverlay::build(&replica, Some(&stats(3.3)));
    let text: Vec<&str> = overlay.lines.iter().map(|l| l.text.as_str()).collect();
    assert!(text[0].starts_with("pad  t 12.5 s"), "{text:?}");
    let magnitude = force * 2f32.sqrt();
    assert_eq!(
        text[1],
        format!(
            "left (surgeon, probe): moderated  rtt 2.1 ms  {magnitude:.2}/3.30 N  contact  touches 3"
        )
    );
    assert_eq!(
        text[2],
        "exercise coordination: score 75  2/4  errors 1  9.5 s"
    );
    assert_eq!(overlay.arrows.len(), 1);
    let arrow = overlay.arrows[0];
    assert_eq!(arrow.from_mm, [0.0, 0.0, 8.0]);
    assert_eq!(
        arrow.to_mm,
        [force * ARROW_MM_PER_N, 0.0, 8.0 + force * ARROW_MM_PER_N]
    );
    let fraction = arrow.fraction_of_limit.unwrap();
    assert!((fraction - magnitude / 3.3).abs() < 1e-6);
    // 0.86 of the limit: nearly red. Half: yellow. A tenth: mostly green. Unknown: its own colour.
    assert_eq!(arrow.rgb, limit_rgb(Some(fraction)));
    let [r, g, _] = arrow.rgb;
    assert!(r > 0.9 && g < 0.4, "{:?}", arrow.rgb);
    assert_eq!(limit_rgb(Some(0.5)), [0.95, 0.85, 0.15]);
    let [r, g, _] = limit_rgb(Some(0.1));
    assert!(g > 0.8 && r < 0.4);
    assert_eq!(limit_rgb(Some(f32::NAN)), limit_rgb(Some(1.0)));
    assert_eq!(limit_rgb(None), UNKNOWN_LIMIT_RGB);

    // No stats yet: the scene and the force are still shown, nothing is made up.
    let bare = InstructorOverlay::build(&replica, None);
    assert!(bare.lines[0].text.contains("no server stats yet"));
    assert_eq!(
        bare.lines[1].text,
        format!("left (surgeon, probe): {magnitude:.2} N")
    );
    assert_eq!(bare.lines.len(), 2);
    assert_eq!(bare.arrows[0].fraction_of_limit, None);

    // A released tool draws no arrow and says it is not connected.
    let mut idle = replica.clone();
    let mut tools = idle.tool_states().clone();
    tools.frame += 1;
    tools.tools[0].active = false;
    assert!(idle.apply_tools(tools));
    let overlay = InstructorOverlay::build(&idle, Some(&stats(3.3)));
    assert!(overlay.arrows.is_empty());
    assert_eq!(
        overlay.lines[1].text,
        "left (surgeon, probe): not connected"
    );
}

fn differs(a: &image::Rgb<u8>, b: &image::Rgb<u8>) -> bool {
    a.0.iter().zip(b.0).any(|(&x, y)| x.abs_diff(y) > 12)
}

/// Red-dominant: the arrow near the limit.
fn arrow_red(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r > 150 && g < 110 && b < 110
}

#[test]
fn overlay_reaches_the_pixels() {
    let replica = replica_with_force(2.0);
    let stats = stats(3.3);
    let overlay = InstructorOverlay::build(&replica, Some(&stats));
    let framing = frame_replica(&replica);
    let frames = [
        SceneFrame {
            replica: &replica,
            overlay: None,
        },
        SceneFrame {
            replica: &replica,
            overlay: Some(&overlay),
        },
    ];
    let images = render_frames(&frames, &framing, WIDTH, HEIGHT).unwrap_or_else(|err| {
        panic!("offscreen rendering failed (needs Mesa lavapipe, see render_png.rs): {err}")
    });
    let (plain, over): (&RgbImage, &RgbImage) = (&images[0].0, &images[1].0);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    over.save(dir.join("sinew_viewer_overlay.png")).unwrap();

    // Text: the top-left band (three lines) changes; the plain frame has background there.
    let band = |img: &RgbImage| {
        (10..80)
            .flat_map(|y| (10..300).map(move |x| (x, y)))
            .filter(|&(x, y)| differs(img.get_pixel(x, y), &image::Rgb(BACKGROUND_RGB)))
            .count()
    };
    let (plain_band, over_band) = (band(plain), band(over));
    assert!(
        over_band > plain_band + 400,
        "the text band has {over_band} non-background pixels with the overlay, {plain_band} without"
    );
    // The arrow: red pixels appear that the plain frame has not (tissue pink is not this red).
    let red_plain = plain.pixels().filter(|p| arrow_red(p)).count();
    let red_over = over.pixels().filter(|p| arrow_red(p)).count();
    assert!(
        red_over > red_plain + 40,
        "the force arrow drew {red_over} red pixels against {red_plain} without it"
    );
}

/// Green, as a hit target's ring: green well above red and blue (tissue pink is red-dominant).
fn ring_green(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    g > 120 && g > r + 50 && g > b + 50
}

/// Yellow, as the next target's ring: red and green both high, blue well below them (0.15 linear is about 108
/// in sRGB).
fn ring_yellow(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r > 180 && g > 170 && b + 60 < g
}

#[test]
fn rings_each_target_where_the_world_marks_it_green_once_hit_and_yellow_next() {
    // No force: no arrow, so only the rings differ between the two frames. The targets lie in front of the
    // probe (which stands over the sheet's centre), below the text (the participant's line is green too).
    let replica = replica_with_force(0.0);
    let mut stats = stats(3.3);
    let exercise = stats.exercise.as_mut().unwrap();
    exercise.targets = [(-20.0, true), (0.0, false), (20.0, false)]
        .map(|(x, hit)| TargetMark {
            at_mm: [x, -15.0, 0.0],
            radius_mm: 5.0,
            hit,
        })
        .to_vec();
    let overlay = InstructorOverlay::build(&replica, Some(&stats));
    assert!(overlay.arrows.is_empty());
    let rgbs: Vec<_> = overlay.targets.iter().map(|t| t.rgb).collect();
    assert_eq!(rgbs, [HIT_RGB, NEXT_RGB, TEXT_RGB]);
    assert_eq!(overlay.targets[1].centre_mm, [0.0, -15.0, 0.0]);
    assert_eq!(overlay.targets[1].radius_mm, 5.0);
    // Without the exercise's targets (an older server, or none): no ring.
    let no_targets = InstructorOverlay::build(&replica, Some(&self::stats(3.3)));
    assert!(no_targets.targets.is_empty());

    let framing = frame_replica(&replica);
    let frames = [
        SceneFrame {
            replica: &replica,
            overlay: Some(&no_targets),
        },
        SceneFrame {
            replica: &replica,
            overlay: Some(&overlay),
        },
    ];
    let images = render_frames(&frames, &framing, WIDTH, HEIGHT).unwrap_or_else(|err| {
        panic!("offscreen rendering failed (needs Mesa lavapipe, see render_png.rs): {err}")
    });
    let (plain, ringed): (&RgbImage, &RgbImage) = (&images[0].0, &images[1].0);
    ringed
        .save(std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("sinew_viewer_targets.png"))
        .unwrap();
    // Below the text lines.
    let scene_pixels = |img: &RgbImage| {
        img.enumerate_pixels()
            .filter(|(_, y, _)| *y > 100)
            .map(|(x, _, p)| (x, *p))
            .collect::<Vec<_>>()
    };
    let count = |img: &RgbImage, f: fn(&image::Rgb<u8>) -> bool| {
        scene_pixels(img).iter().filter(|(_, p)| f(p)).count()
    };
    let (green, yellow) = (
        count(ringed, ring_green) - count(plain, ring_green).min(count(ringed, ring_green)),
        count(ringed, ring_yellow) - count(plain, ring_yellow).min(count(ringed, ring_yellow)),
    );
    println!("target rings: {green} green pixels (hit), {yellow} yellow (next)");
    assert!(
        green > 60,
        "the hit target's ring drew {green} green pixels"
    );
    assert!(
        yellow > 60,
        "the next target's ring drew {yellow} yellow pixels"
    );
    // The hit ring is left of the next one, as the targets lie along x.
    let mean_x = |f: fn(&image::Rgb<u8>) -> bool| {
        let xs: Vec<u32> = scene_pixels(ringed)
            .iter()
            .filter(|(_, p)| f(p))
            .map(|(x, _)| *x)
            .collect();
        xs.iter().map(|&x| f64::from(x)).sum::<f64>() / xs.len().max(1) as f64
    };
    assert!(
        mean_x(ring_green) < mean_x(ring_yellow),
        "green ring at x {} px, yellow at {} px",
        mean_x(ring_green),
        mean_x(ring_yellow)
    );
}
