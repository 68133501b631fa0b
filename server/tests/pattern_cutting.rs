//! FLS's pattern-cutting task (`worlds/exercise_pattern_cutting.toml`) under a scripted scalpel through the real
//! server tick: a clean circle, cut in the band between the marked circles, comes free with no penalty and scores
//! the cutoff less its time; a sloppy one, 3 mm off centre, comes free and loses the percentage area it cut
//! outside the band, as the two circles' overlap says it should (`training::pattern_cutting`).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use std::f64::consts::PI;

use sinew_server::node::exercise_stats;
use sinew_server::training::{
    ExerciseRun, ExerciseScore, LiveScore, MetricsConfig, SessionObserver,
};
use sinew_server::world::{World, load_world};

/// The scalpel's origin above the gauze while it cuts, mm: its edge (2 mm above to 9 mm below the origin)
/// passes through the sheet.
const CUT_Z_MM: f32 = 1.5;
/// Where the hand carries the scalpel between cuts, mm.
const HOVER_Z_MM: f32 = 12.0;
/// How fast the hand draws the blade, mm/s.
const SPEED_MM_S: f64 = 20.0;

fn world() -> World {
    load_world(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../worlds/exercise_pattern_cutting.toml"),
    )
    .expect("the exercise world loads")
}

/// The scalpel's hand in the world at `t_s`: down onto the circle of `radius_mm` about (`cx`, 0) at its +x point,
/// once round and 20 degrees on, then up and held.
fn scalpel_path(cx: f32, radius_mm: f32) -> (impl Fn(f64) -> [f32; 3], f64) {
    let r = f64::from(radius_mm);
    let (descend_s, sweep) = (0.5, 2.0 * PI + 20f64.to_radians());
    let round_s = sweep * r / SPEED_MM_S;
    let end_s = descend_s + round_s + 0.5;
    let path = move |t_s: f64| {
        let on_circle = |angle: f64| [cx + (r * angle.cos()) as f32, (r * angle.sin()) as f32];
        if t_s < descend_s {
            let [x, y] = on_circle(0.0);
            let f = (t_s / descend_s) as f32;
            [x, y, HOVER_Z_MM + (CUT_Z_MM - HOVER_Z_MM) * f]
        } else if t_s < descend_s + round_s {
            let [x, y] = on_circle(sweep * (t_s - descend_s) / round_s);
            [x, y, CUT_Z_MM]
        } else {
            let [x, y] = on_circle(sweep);
            [x, y, HOVER_Z_MM]
        }
    };
    (path, end_s)
}

/// Run the exercise with the grasper idle and the scalpel's hand on `path` until `end_s`: the score, and the
/// live score at the end.
fn run(world: &World, path: impl Fn(f64) -> [f32; 3], end_s: f64) -> (ExerciseScore, LiveScore) {
    let dt_s = 1.0 / world.tick_hz;
    let mut tick = common::server_tick(world);
    let spec = world.exercise.clone().expect("an exercise world");
    let mut observer = SessionObserver::new(2, MetricsConfig::new(dt_s))
        .with_exercise(ExerciseRun::new(spec, 2, dt_s));
    let origin = world.tools[1].device_origin_in_world_mm;
    let mut out = [None; 2];
    for k in 0..(end_s / dt_s) as u64 {
        let p = path(k as f64 * dt_s);
        let inputs = [
            None,
            common::pose_at(k + 1, [0, 1, 2].map(|i| p[i] - origin[i])),
        ];
        let step = tick.step(&inputs, &[None, None], &mut out);
        assert_eq!(step.faults, 0, "the guard reset the gauze");
        common::observe_tick(&mut observer, &tick, k, &step);
    }
    let exercise = observer.exercise().unwrap();
    let score = exercise.score();
    println!("{score:?}");
    (score, exercise.live())
}

/// Area of the overlap of two discs of radii `r1`, `r2` whose centres are `d` apart.
fn overlap_mm2(r1: f64, r2: f64, d: f64) -> f64 {
    if d >= r1 + r2 {
        return 0.0;
    }
    if d <= (r1 - r2).abs() {
        return PI * r1.min(r2).powi(2);
    }
    let a1 = ((d * d + r1 * r1 - r2 * r2) / (2.0 * d * r1)).acos();
    let a2 = ((d * d + r2 * r2 - r1 * r1) / (2.0 * d * r2)).acos();
    r1 * r1 * a1 + r2 * r2 * a2
        - 0.5 * ((-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2) * (d + r1 + r2)).sqrt()
}

#[test]
fn a_clean_circle_in_the_band_comes_free_with_no_penalty_and_scores_the_cutoff_less_its_time() {
    let world = world();
    let (path, end_s) = scalpel_path(0.0, 20.0);
    let (score, live) = run(&world, path, end_s);
    let cut = score.pattern.expect("a pattern-cutting score");
    assert!(
        score.completed && cut.freed,
        "the circle did not come free: {score:?}"
    );
    assert_eq!(
        cut.deviation_pct, 0.0,
        "a cut on the band deviated: {cut:?}"
    );
    assert!(score.passed, "{score:?}");
    assert_eq!(cut.mistels_points, 300.0 - score.time_s);
    assert_eq!(score.score, 100.0 * cut.mistels_points / 300.0);
    // Done when the loop closes: once round the 20 mm circle at 20 mm/s after the half-second descent, less
    // the few degrees by which the start of the cut lies ahead of the blade's first crossing.
    let round_s = 0.5 + 2.0 * PI * 20.0 / SPEED_MM_S;
    assert!(
        (score.time_s - round_s).abs() < 0.3,
        "freed at {:.2} s, the loop closes at about {round_s:.2} s",
        score.time_s
    );
    // The live score an instructor sees says the same, and marks the two circles, hit.
    assert!(live.completed && live.hits == 1 && live.total == 1);
    assert_eq!(live.score, score.score);
    let spec = world.exercise.as_ref().unwrap();
    let marks = exercise_stats(spec, &live).targets;
    assert_eq!(
        marks
            .iter()
            .map(|m| (m.at_mm, m.radius_mm, m.hit))
            .collect::<Vec<_>>(),
        [([0.0; 3], 19.5, true), ([0.0; 3], 20.5, true)]
    );
}

#[test]
fn a_sloppy_circle_off_centre_comes_free_and_loses_the_percentage_area_it_cut_outside_the_band() {
    let world = world();
    let pattern = world.exercise.as_ref().unwrap().pattern.unwrap();
    let (inner, outer) = (
        f64::from(pattern.inner_radius_mm),
        f64::from(pattern.outer_radius_mm),
    );
    let (offset, radius) = (3.0_f64, 20.0_f64);
    let (path, end_s) = scalpel_path(offset as f32, radius as f32);
    let (score, _) = run(&world, path, end_s);
    let cut = score.pattern.expect("a pattern-cutting score");
    assert!(
        score.completed && cut.freed,
        "the circle did not come free: {score:?}"
    );
    assert!(!score.passed, "a cut 3 mm off the band passed: {score:?}");
    // What the rule says: the disc cut out beyond the outer circle, and the inner disc not cut out.
    let outside = PI * radius * radius - overlap_mm2(radius, outer, offset);
    let inside = PI * inner * inner - overlap_mm2(radius, inner, offset);
    let pattern_area = PI * (0.5 * (inner + outer)).powi(2);
    let expected_pct = 100.0 * (outside + inside) / pattern_area;
    println!(
        "outside the band {:.1} mm^2 (circles: {outside:.1}), inside {:.1} (circles: {inside:.1}); penalty {:.2}% (circles: {expected_pct:.2}%)",
        cut.outside_band_mm2, cut.inside_band_mm2, cut.deviation_pct
    );
    assert!(
        (cut.deviation_pct - expected_pct).abs() < 0.05 * expected_pct,
        "penalty {:.2}%, the circles' overlap gives {expected_pct:.2}%",
        cut.deviation_pct
    );
    assert_eq!(cut.mistels_points, 300.0 - score.time_s - cut.deviation_pct);
}
