//! The shipped exercises (`worlds/exercise_*.toml`) under scripted devices through the real server tick: one
//! trainee does each exercise right, one makes known errors, and each is scored as the rules say
//! (`training::exercise`).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use sinew_server::training::{ExerciseRun, ExerciseScore, MetricsConfig, SessionObserver};
use sinew_server::world::{World, load_world};

/// Centre height of a hovering probe (radius 4 mm: 6 mm clear of the pad), mm.
const HOVER_Z: f32 = 10.0;
/// Centre height at which a probe first touches the pad at rest, mm.
const TOUCH_Z: f32 = 4.0;

/// A scripted hand: straight moves at a speed, holds, in the world frame.
struct Hand {
    points: Vec<(f64, [f32; 3])>,
}

impl Hand {
    fn at(start: [f32; 3]) -> Self {
        Self {
            points: vec![(0.0, start)],
        }
    }

    fn end(&self) -> (f64, [f32; 3]) {
        *self.points.last().unwrap()
    }

    fn go(mut self, to: [f32; 3], speed_mm_s: f32) -> Self {
        let (t, from) = self.end();
        let d = ((to[0] - from[0]).powi(2) + (to[1] - from[1]).powi(2) + (to[2] - from[2]).powi(2))
            .sqrt();
        self.points.push((t + f64::from(d / speed_mm_s), to));
        self
    }

    fn until(mut self, t_s: f64) -> Self {
        let (t, p) = self.end();
        self.points.push((t_s.max(t), p));
        self
    }

    fn hold(self, seconds: f64) -> Self {
        let t = self.end().0;
        self.until(t + seconds)
    }

    /// Over (x, y), down to `depth_mm` past first touch, hold, back up.
    fn touch(self, x: f32, y: f32, depth_mm: f32) -> Self {
        self.go([x, y, HOVER_Z], 150.0)
            .go([x, y, TOUCH_Z - depth_mm], 30.0)
            .hold(0.2)
            .go([x, y, HOVER_Z], 60.0)
    }

    fn position(&self, t_s: f64) -> [f32; 3] {
        let i = self.points.partition_point(|(t, _)| *t <= t_s);
        if i == 0 {
            return self.points[0].1;
        }
        if i == self.points.len() {
            return self.end().1;
        }
        let ((t0, a), (t1, b)) = (self.points[i - 1], self.points[i]);
        let f = ((t_s - t0) / (t1 - t0).max(1e-9)) as f32;
        [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * f)
    }
}

fn shipped(name: &str) -> World {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../worlds")
        .join(name);
    load_world(&path).expect("the exercise world loads")
}

/// Run `world`'s exercise with the two hands (world frame) until both are done, plus half a second.
fn run(world: &World, left: &Hand, right: &Hand) -> ExerciseScore {
    let dt_s = 1.0 / world.tick_hz;
    let mut tick = common::server_tick(world);
    let spec = world.exercise.clone().expect("an exercise world");
    let mut observer = SessionObserver::new(2, MetricsConfig::new(dt_s))
        .with_exercise(ExerciseRun::new(spec, 2, dt_s));
    let origins: Vec<[f32; 3]> = world
        .tools
        .iter()
        .map(|t| t.device_origin_in_world_mm)
        .collect();
    let seconds = left.end().0.max(right.end().0) + 0.5;
    let mut out = [None; 2];
    for k in 0..(seconds / dt_s) as u64 {
        let t_s = k as f64 * dt_s;
        let pose = |hand: &Hand, origin: [f32; 3]| {
            let p = hand.position(t_s);
            common::pose_at(k + 1, [0, 1, 2].map(|i| p[i] - origin[i]))
        };
        let inputs = [pose(left, origins[0]), pose(right, origins[1])];
        let step = tick.step(&inputs, &[None, None], &mut out);
        assert_eq!(step.faults, 0);
        common::observe_tick(&mut observer, &tick, k, &step);
    }
    let score = observer.exercise().unwrap().score();
    println!("{score:?}");
    score
}

/// (wrong tool, off target, too deep).
fn errors(score: &ExerciseScore) -> (u32, u32, u32) {
    let e = score.errors;
    (e.wrong_tool, e.off_target, e.too_deep)
}

fn hover(x: f32) -> [f32; 3] {
    [x, 0.0, HOVER_Z]
}

#[test]
fn coordination_done_right_passes_with_full_marks_in_known_time() {
    let world = shipped("exercise_coordination.toml");
    let t = &world.exercise.as_ref().unwrap().targets;
    let xy = |i: usize| (t[i].at_mm[0], t[i].at_mm[1]);
    // Left hits 0 and 2, right 1 and 3, alternating (each waits for the other to lift).
    let left = Hand::at(hover(-18.0))
        .hold(0.3)
        .touch(xy(0).0, xy(0).1, 1.5)
        .until(2.2)
        .touch(xy(2).0, xy(2).1, 1.5);
    let right = Hand::at(hover(18.0))
        .until(1.1)
        .touch(xy(1).0, xy(1).1, 1.5)
        .until(3.3)
        .touch(xy(3).0, xy(3).1, 1.5);
    let score = run(&world, &left, &right);
    assert!(score.completed && score.passed, "{score:?}");
    assert_eq!(score.score, 100.0);
    assert_eq!(score.errors.total(), 0);
    assert_eq!(
        score
            .hits
            .iter()
            .map(|h| (h.target, h.tool))
            .collect::<Vec<_>>(),
        [(0, 0), (1, 1), (2, 0), (3, 1)]
    );
    // The last hit is right's descent onto target 3: at 3.3 s it leaves its hover over target 1, moves over
    // target 3 and down to the touch height (the clock starts at the first tick; the coupling lags a few ms).
    let ((x1, y1), (x3, y3)) = (xy(1), xy(3));
    let over = ((x3 - x1).powi(2) + (y3 - y1).powi(2)).sqrt() / 150.0 + (HOVER_Z - TOUCH_Z) / 30.0;
    let expected = 3.3 + f64::from(over);
    assert!(
        (score.time_s - expected).abs() < 0.02,
        "time {:.3} s, expected about {expected:.3} s",
        score.time_s
    );
    assert!(score.mean_distance_mm < 1.0, "{score:?}");
}

#[test]
fn coordination_with_a_wrong_tool_and_an_off_target_touch_completes_but_fails_with_80_points() {
    let world = shipped("exercise_coordination.toml");
    let t = &world.exercise.as_ref().unwrap().targets;
    let xy = |i: usize| (t[i].at_mm[0], t[i].at_mm[1]);
    // Right touches target 0 first (it is left's): wrong tool. Left then hits 0, and touches the pad at
    // (0, 20), away from target 1: off target. Then the rest, right.
    let right = Hand::at(hover(18.0))
        .hold(0.2)
        .touch(xy(0).0, xy(0).1, 1.5)
        .go(hover(18.0), 150.0)
        .until(3.3)
        .touch(xy(1).0, xy(1).1, 1.5)
        .until(5.5)
        .touch(xy(3).0, xy(3).1, 1.5);
    let left = Hand::at(hover(-18.0))
        .until(1.4)
        .touch(xy(0).0, xy(0).1, 1.5)
        .touch(0.0, 20.0, 1.5)
        .go(hover(-18.0), 150.0)
        .until(4.4)
        .touch(xy(2).0, xy(2).1, 1.5);
    let score = run(&world, &left, &right);
    assert!(score.completed && !score.passed, "{score:?}");
    assert_eq!(errors(&score), (1, 1, 0), "{score:?}");
    assert_eq!(score.score, 80.0);
}

#[test]
fn accurate_touch_gentle_passes_and_a_deep_press_and_a_stray_touch_cost_20_points() {
    let world = shipped("exercise_accurate_touch.toml");
    let limit = world.exercise.as_ref().unwrap().depth_limit_mm.unwrap();
    let t = &world.exercise.as_ref().unwrap().targets;
    let xy = |i: usize| (t[i].at_mm[0], t[i].at_mm[1]);
    // Left does marks 0-2, right 3-4, 1.5 mm deep.
    let gentle = |first_depth: f32, stray: bool| {
        let mut left = Hand::at(hover(-18.0))
            .hold(0.2)
            .touch(xy(0).0, xy(0).1, first_depth);
        if stray {
            left = left.touch(-25.0, -20.0, 1.5);
        }
        let left = left
            .touch(xy(1).0, xy(1).1, 1.5)
            .touch(xy(2).0, xy(2).1, 1.5)
            .go(hover(-25.0), 150.0);
        let start_right = left.end().0 - 0.4;
        let right = Hand::at(hover(18.0))
            .until(start_right)
            .touch(xy(3).0, xy(3).1, 1.5)
            .touch(xy(4).0, xy(4).1, 1.5);
        (left, right)
    };
    let (left, right) = gentle(1.5, false);
    let good = run(&world, &left, &right);
    assert!(good.completed && good.passed, "{good:?}");
    assert_eq!(good.score, 100.0);
    assert!(
        good.max_depth_mm > 1.0 && good.max_depth_mm < limit as f64,
        "{good:?}"
    );
    assert!(good.mean_distance_mm < 1.0, "{good:?}");

    let (left, right) = gentle(6.0, true);
    let bad = run(&world, &left, &right);
    assert!(bad.completed && !bad.passed, "{bad:?}");
    assert_eq!(errors(&bad), (0, 1, 1), "{bad:?}");
    assert_eq!(bad.score, 80.0);
    // The deep press went about 6 mm below its first touch (the coupling lags a little under the load).
    assert!(
        bad.hits[0].max_depth_mm > 5.0 && bad.hits[0].max_depth_mm <= 6.05,
        "{:?}",
        bad.hits[0]
    );
}

#[test]
fn stiffness_ranking_in_the_right_order_passes_and_one_swap_costs_a_pair_and_the_samples_really_differ()
 {
    let world = shipped("exercise_stiffness_ranking.toml");
    let samples = world.exercise.as_ref().unwrap().samples.clone();
    let x_of = |name: &str| {
        let s = samples.iter().find(|s| s.name == name).unwrap();
        (s.min_xy_mm[0] + s.max_xy_mm[0]) / 2.0
    };
    // Explore every sample (2 mm), then tap them in `order`; the right hand stays up.
    let trainee = |order: [&str; 3]| {
        let mut left = Hand::at(hover(-12.0)).hold(0.2);
        for name in ["sample-a", "sample-b", "sample-c"] {
            left = left.touch(x_of(name), 0.0, 2.0);
        }
        for name in order {
            left = left.touch(x_of(name), 0.0, 1.0);
        }
        left
    };
    let right = Hand::at(hover(12.0));
    let good = run(
        &world,
        &trainee(["sample-b", "sample-c", "sample-a"]),
        &right,
    );
    let ranking = good.ranking.clone().unwrap();
    assert_eq!(ranking.truth, ["sample-b", "sample-c", "sample-a"]);
    assert_eq!(ranking.answer, ranking.truth);
    assert_eq!(ranking.touches, [2, 2, 2]);
    assert!(good.completed && good.passed, "{good:?}");
    assert_eq!(
        (good.targets_hit, good.targets_total, good.score),
        (3, 3, 100.0)
    );
    let mut ratios: Vec<f64> = ranking.pairs.iter().map(|p| p.stiffness_ratio).collect();
    ratios.sort_by(f64::total_cmp);
    assert!(
        (ratios[0] - 1.3).abs() < 1e-3 && (ratios[2] - 2.0).abs() < 1e-3,
        "{ratios:?}"
    );

    // c before b: the 1.3x pair is wrong, the others right.
    let swapped = run(
        &world,
        &trainee(["sample-c", "sample-b", "sample-a"]),
        &right,
    );
    let pairs = &swapped.ranking.as_ref().unwrap().pairs;
    let wrong: Vec<_> = pairs.iter().filter(|p| !p.correct).collect();
    assert_eq!(wrong.len(), 1, "{pairs:?}");
    assert!((wrong[0].stiffness_ratio - 1.3).abs() < 1e-3);
    assert!(swapped.completed && !swapped.passed);
    assert!((swapped.score - 200.0 / 3.0).abs() < 1e-9, "{swapped:?}");
}

/// The ranking is learnable: pressing each sample 2 mm, the softest pushes back least and the firmest most.
#[test]
fn the_ranking_samples_push_back_in_their_stiffness_order() {
    let world = shipped("exercise_stiffness_ranking.toml");
    let mut tick = common::server_tick(&world);
    let origin = world.tools[0].device_origin_in_world_mm;
    let mut force_at = std::collections::BTreeMap::new();
    for sample in &world.exercise.as_ref().unwrap().samples {
        let x = (sample.min_xy_mm[0] + sample.max_xy_mm[0]) / 2.0;
        let hand = Hand::at(hover(x))
            .go([x, 0.0, TOUCH_Z - 2.0], 30.0)
            .hold(0.5);
        let mut out = [None; 2];
        let start = 0;
        let mut last = 0.0;
        for k in start..(hand.end().0 * 1000.0) as u64 {
            let p = hand.position(k as f64 * 0.001);
            let input = common::pose_at(k + 1, [0, 1, 2].map(|i| p[i] - origin[i]));
            tick.step(&[input, None], &[None, None], &mut out);
            last = tick.outputs()[0].force_world_n.z;
        }
        force_at.insert(sample.name.clone(), last);
        // Lift off and let the tool leave before the next sample.
        let mut out = [None; 2];
        tick.step(&[None, None], &[None, None], &mut out);
    }
    println!("{force_at:?}");
    let f = |n: &str| force_at[n];
    assert!(
        f("sample-b") < f("sample-c") && f("sample-c") < f("sample-a"),
        "{force_at:?}"
    );
}
