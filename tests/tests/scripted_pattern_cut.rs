//! FLS's pattern cutting (`worlds/exercise_pattern_cutting.toml`) through the real device loops, on virtual
//! time: a simulated surgeon's hand (compliant, the drill's firm grip) carries the scalpel down through the gauze
//! and once round the marked circle at 20 mm/s, over a LAN-like link with forces streamed; the server's tick
//! cuts where the blade goes, and the exercise is scored from each tick as the server scores it live. The circle
//! comes free, the cut stays in the 1 mm band while the hand feels the cut's drag, and the points are what
//! MISTELS's rule gives.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::sync::Arc;

use hapticserver::hand_script::{PoseKey, PosePath};
use hapticserver::{HandPreset, HandScript, ModePolicy};
use sinew_server::server_tick::ServerTick;
use sinew_server::training::{ExerciseRun, MetricsConfig, SessionObserver, TickView};
use sinew_testkit::drill::{DrillDevice, Link, run_drill_observed};

/// The scalpel's origin above the gauze while it cuts, mm (its edge reaches 9 mm below the origin).
const CUT_Z_MM: f32 = 1.5;
/// Where the hand carries it before and after, mm.
const HOVER_Z_MM: f32 = 12.0;

#[test]
fn a_scripted_hand_cuts_the_pattern_free_through_the_device_loops_inside_the_band() {
    let world =
        sinew_testkit::harness::load_shipped_world("exercise_pattern_cutting.toml").unwrap();
    let pattern = world.exercise.as_ref().unwrap().pattern.unwrap();
    let radius = 0.5 * (pattern.inner_radius_mm + pattern.outer_radius_mm);
    let scalpel = world
        .tools
        .iter()
        .find(|t| t.name == "right-scalpel")
        .unwrap();
    let origin = scalpel.device_origin_in_world_mm;
    // Keyframes, device frame: hover over the circle's +x point, down in 0.5 s, round it (and 20 degrees on)
    // at 20 mm/s, a key every 2 degrees, then up.
    let key = |t_s: f64, x: f32, y: f32, z: f32| PoseKey {
        t_s,
        position_mm: [x - origin[0], y - origin[1], z - origin[2]],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        buttons: 0,
    };
    let c = pattern.centre_mm;
    let mut keys = vec![
        key(0.0, c[0] + radius, c[1], HOVER_Z_MM),
        key(0.5, c[0] + radius, c[1], HOVER_Z_MM),
        key(1.0, c[0] + radius, c[1], CUT_Z_MM),
    ];
    let sweep_deg = 380;
    let speed_mm_s = 20.0;
    let per_deg_s = f64::from(radius) * std::f64::consts::PI / 180.0 / speed_mm_s;
    for deg in (2..=sweep_deg).step_by(2) {
        let a = (deg as f32).to_radians();
        keys.push(key(
            1.0 + f64::from(deg) * per_deg_s,
            c[0] + radius * a.cos(),
            c[1] + radius * a.sin(),
            CUT_Z_MM,
        ));
    }
    let around_s = 1.0 + f64::from(sweep_deg) * per_deg_s;
    let last = (sweep_deg as f32).to_radians();
    keys.push(key(
        around_s + 0.5,
        c[0] + radius * last.cos(),
        c[1] + radius * last.sin(),
        HOVER_Z_MM,
    ));
    let end_s = around_s + 1.0;
    let devices = [DrillDevice {
        id: scalpel.device_id.clone(),
        hand: HandPreset::Firm,
        script: HandScript::Path(Arc::new(PosePath::new(keys).unwrap())),
        link: Link::rtt(0.0),
        mode: ModePolicy::Direct,
    }];
    let exercise = world.exercise.clone().unwrap();
    let tools = world.tools.len();
    let mut observer = SessionObserver::new(tools, MetricsConfig::new(0.001))
        .with_exercise(ExerciseRun::new(exercise, tools, 0.001));
    let mut faults = 0;
    let result = run_drill_observed(&world, &devices, end_s, |server: &ServerTick, _| {
        let sim = server.sim();
        faults += server.last_step().faults;
        let view = TickView {
            tick: sim.steps() - 1,
            active: server.tools_active(),
            outputs: server.outputs(),
            step: server.last_step(),
        };
        observer.observe(&view, |_| {}, |_, _| {});
    })
    .unwrap();
    let score = observer.exercise().unwrap().score();
    let cut = score.pattern.unwrap();
    println!(
        "pattern cut through the device loops: freed {} at {:.2} s of the exercise's clock, {:.1} mm^2 outside the \
         band and {:.1} inside it ({:.2}%), {:.1} MISTELS points, score {:.1}, passed {}; the hand's largest force \
         {:.2?} N",
        cut.freed,
        score.time_s,
        cut.outside_band_mm2,
        cut.inside_band_mm2,
        cut.deviation_pct,
        cut.mistels_points,
        score.score,
        score.passed,
        result.max_force_n
    );
    assert_eq!(faults, 0, "the guard reset the gauze");
    assert!(
        score.completed && cut.freed,
        "the circle did not come free: {score:?}"
    );
    assert_eq!(
        cut.deviation_pct, 0.0,
        "the hand's cut left the band: {cut:?}"
    );
    assert!(score.passed, "{score:?}");
    assert_eq!(cut.mistels_points, 300.0 - score.time_s);
    // The clock starts when the device joins (the first pose): freed once the blade is round the circle.
    let round_s = 1.0 + 360.0 * per_deg_s;
    assert!(
        score.time_s > round_s - 0.5 && score.time_s < around_s,
        "freed at {:.2} s; the blade is round at {round_s:.2} s",
        score.time_s
    );
}
