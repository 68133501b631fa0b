//! The exercise rules of `exercise.rs`, run on hand-made events.

use super::*;
use crate::scene::TargetSpec;

fn spec(limit_s: f64) -> ExerciseSpec {
    let target = |x: f32| TargetSpec {
        at_mm: [x, 0.0, 0.0],
        radius_mm: 2.0,
        tool: Some(0),
    };
    ExerciseSpec {
        name: "two".into(),
        kind: ExerciseKind::Coordination,
        time_limit_s: limit_s,
        depth_limit_mm: None,
        targets: vec![target(0.0), target(10.0)],
        samples: Vec::new(),
        wound: None,
        knot: false,
        pattern: None,
    }
}

fn at(x: f32) -> ToolActivity {
    ToolActivity {
        active: true,
        in_contact: true,
        tool_world_mm: [x, 0.5, 4.0],
        ..ToolActivity::default()
    }
}

fn event(tick: u64, kind: EventKind) -> SessionEvent {
    SessionEvent {
        tick,
        tool: 0,
        kind,
    }
}

#[test]
fn out_of_time_misses_the_rest_and_scores_what_was_hit() {
    let mut run = ExerciseRun::new(spec(0.010), 1, 0.001);
    run.on_event(&event(0, EventKind::Joined), &at(0.0));
    run.on_event(&event(3, EventKind::ContactBegin), &at(0.0));
    assert_eq!(run.next_target(), Some(1));
    for tick in 0..20 {
        run.on_tick(tick, &[at(0.0)]);
    }
    // Too late: the clock ran out at tick 10.
    run.on_event(&event(15, EventKind::ContactBegin), &at(10.0));
    let score = run.score();
    assert!(
        !score.completed && score.timed_out && !score.passed,
        "{score:?}"
    );
    assert_eq!(
        (score.targets_hit, score.score, score.time_s),
        (1, 50.0, 0.010)
    );
    assert!((score.hits[0].at_s - 0.004).abs() < 1e-12);
    assert!((score.hits[0].distance_mm - 0.5).abs() < 1e-6);
}

#[test]
fn errors_cost_ten_points_each_and_never_below_zero() {
    let mut run = ExerciseRun::new(spec(10.0), 2, 0.001);
    run.on_event(&event(0, EventKind::Joined), &at(0.0));
    for k in 0..12 {
        // Tool 1 on tool 0's target: wrong tool, twelve times.
        let e = SessionEvent {
            tick: k + 1,
            tool: 1,
            kind: EventKind::ContactBegin,
        };
        run.on_event(&e, &at(0.0));
    }
    let score = run.score();
    assert_eq!(score.errors.wrong_tool, 12);
    assert_eq!(score.score, 0.0);
}

#[test]
fn a_suture_exercise_judges_punctures_at_the_marks_not_touches() {
    // Entry mark at the origin, exit mark 10 mm along x, each 2 mm across; the driver (tool 0) named.
    let suture = || ExerciseSpec {
        kind: ExerciseKind::Suture,
        ..spec(60.0)
    };
    let mut run = ExerciseRun::new(suture(), 2, 0.001);
    let puncture = |hole_mm: [f32; 3]| ToolActivity {
        newest_hole_rest_mm: Some(hole_mm),
        ..at(0.0)
    };
    run.on_event(&event(0, EventKind::Joined), &at(0.0));
    // Touches anywhere are not judged.
    run.on_event(&event(5, EventKind::ContactBegin), &at(30.0));
    // In 1.5 mm from the entry mark (a 3-D distance: 0.9 across, 1.2 down a face).
    run.on_event(
        &event(100, EventKind::Puncture),
        &puncture([0.9, 0.0, -1.2]),
    );
    assert_eq!(run.next_target(), Some(1));
    // The bites through the wound's faces, off both marks: not judged.
    run.on_event(
        &event(200, EventKind::Puncture),
        &puncture([4.0, 0.0, -5.0]),
    );
    run.on_event(
        &event(300, EventKind::Puncture),
        &puncture([6.0, 0.0, -5.0]),
    );
    // Tool 1 comes out at the exit mark: the wrong tool.
    let by_grasper = SessionEvent {
        tick: 350,
        tool: 1,
        kind: EventKind::Puncture,
    };
    run.on_event(&by_grasper, &puncture([10.0, 0.0, 0.0]));
    // The driver's needle out 0.5 mm from it.
    run.on_event(
        &event(400, EventKind::Puncture),
        &puncture([10.0, 0.5, 0.0]),
    );
    let score = run.score();
    assert!(score.completed && !score.passed, "{score:?}");
    assert_eq!((score.targets_hit, score.errors.total()), (2, 1));
    assert_eq!(score.errors.wrong_tool, 1);
    assert!((score.hits[0].distance_mm - 1.5).abs() < 1e-6);
    assert!((score.mean_distance_mm - 1.0).abs() < 1e-6);
    assert!((score.time_s - 0.401).abs() < 1e-9);
    // A puncture with no place (no hole) is not judged either.
    let mut run = ExerciseRun::new(suture(), 1, 0.001);
    run.on_event(&event(1, EventKind::Puncture), &at(0.0));
    assert_eq!(run.next_target(), Some(0));
    // Named, its wound must close: both marks hit cleanly, the gap left at 1.4 mm, then closed to 0.6.
    let mut run = ExerciseRun::new(
        ExerciseSpec {
            wound: Some([0, 1]),
            ..suture()
        },
        1,
        0.001,
    );
    run.on_event(&event(0, EventKind::Joined), &at(0.0));
    run.on_event(&event(10, EventKind::Puncture), &puncture([0.0, 0.0, 0.0]));
    run.on_event(&event(20, EventKind::Puncture), &puncture([10.0, 0.0, 0.0]));
    run.on_wound_gap(Some(1.4));
    run.on_wound_gap(None);
    run.on_wound_gap(Some(f32::NAN));
    let score = run.score();
    assert!(score.completed && !score.passed, "{score:?}");
    assert_eq!(score.wound_gap_mm, Some(f64::from(1.4f32)));
    run.on_wound_gap(Some(0.6));
    assert!(run.score().passed);
    // Not kept for an exercise that names no wound.
    let mut run = ExerciseRun::new(suture(), 1, 0.001);
    run.on_wound_gap(Some(0.6));
    assert_eq!(run.score().wound_gap_mm, None);
}

/// A suture exercise tied off passes only with a secure knot read at the end: a half knot, then a granny, do
/// not pass; a square knot does. A knot that comes undone is an error. Untied, the knot is reported and
/// asks nothing.
#[test]
fn a_stitch_tied_off_passes_only_with_a_secure_knot_and_a_knot_undone_is_an_error() {
    use crate::interaction::suture::Throws;
    let tied_off = |knot: bool| ExerciseSpec {
        kind: ExerciseKind::Suture,
        knot,
        ..spec(60.0)
    };
    let puncture = |hole_mm: [f32; 3]| ToolActivity {
        newest_hole_rest_mm: Some(hole_mm),
        ..at(0.0)
    };
    let knotted = |throws: Option<Throws>| ToolActivity {
        knot_tied: throws.is_some(),
        knot: throws,
        ..at(0.0)
    };
    let half = Throws {
        single_right: 1,
        ..Throws::default()
    };
    let granny = Throws {
        single_right: 2,
        ..Throws::default()
    };
    let square = Throws {
        single_right: 1,
        single_left: 1,
        ..Throws::default()
    };
    let run_with = |knot: bool, readings: &[Option<Throws>]| {
        let mut run = ExerciseRun::new(tied_off(knot), 2, 0.001);
        run.on_event(&event(0, EventKind::Joined), &at(0.0));
        run.on_event(&event(10, EventKind::Puncture), &puncture([0.0, 0.0, 0.0]));
        run.on_event(&event(20, EventKind::Puncture), &puncture([10.0, 0.0, 0.0]));
        for (k, reading) in readings.iter().enumerate() {
            // The grasper (tool 1) draws the thread; the driver reads nothing.
            run.on_tick(30 + k as u64, &[at(0.0), knotted(*reading)]);
        }
        run.score()
    };
    let score = run_with(true, &[None, Some(half)]);
    let knot = score.knot.clone().unwrap();
    assert_eq!(knot.name.as_deref(), Some("half knot"));
    assert!(
        score.completed && !knot.secure && !score.passed,
        "{score:?}"
    );
    let score = run_with(true, &[Some(half), Some(granny)]);
    assert!(!score.knot.unwrap().secure && !score.passed);
    let score = run_with(true, &[Some(half), Some(square)]);
    let knot = score.knot.clone().unwrap();
    assert_eq!(
        (knot.name.as_deref(), knot.throws, knot.secure, knot.undone),
        (Some("square knot"), [1, 1, 0, 0], true, 0)
    );
    assert!(score.passed && score.score == 100.0, "{score:?}");
    // Tied, undone, tied again: one error, ten points, not passed.
    let score = run_with(true, &[Some(square), None, Some(square)]);
    assert_eq!((score.errors.knot_undone, score.score), (1, 90.0));
    assert!(score.knot.unwrap().secure && !score.passed);
    // Not tied off: the knot is reported, and neither asked nor counted against the stitch.
    let score = run_with(false, &[Some(half), None]);
    let knot = score.knot.unwrap();
    assert_eq!((knot.name, knot.undone), (None, 1));
    assert!(score.passed && score.errors.total() == 0);
    // Another kind has no knot in its score.
    assert!(
        ExerciseRun::new(spec(10.0), 1, 0.001)
            .score()
            .knot
            .is_none()
    );
}
