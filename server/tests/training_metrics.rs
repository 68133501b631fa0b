//! The training layer's metrics and skill states on scripted sessions through the real server tick (pad world,
//! left probe), whose answers are known: a straight path of known length in free air, a press of known
//! duration, and a press deep enough that the force sits at the tool's 3.3 N limit (a known peak, and a known
//! harm rate above the threshold).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use sinew_server::training::{
    EventKind, MetricsConfig, MetricsSummary, SessionEvent, SessionObserver, SkillState, TickView,
};
use sinew_server::world::load_world;

/// A session on the pad: the left device follows `script(t_s)` (device frame, mm; None: not driving) for
/// `seconds`. Returns the left tool's metrics, its events and its state path (without repeats).
fn session(
    seconds: f64,
    script: impl Fn(f64) -> Option<[f32; 3]>,
) -> (MetricsSummary, Vec<SessionEvent>, Vec<SkillState>) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let world = load_world(&path).expect("pad world loads");
    let dt_s = 1.0 / world.tick_hz;
    let mut tick = common::server_tick(&world);
    let mut observer = SessionObserver::new(2, MetricsConfig::new(dt_s));
    let mut out = [None; 2];
    let mut events = Vec::new();
    let mut states = vec![SkillState::Idle];
    let ticks = (seconds / dt_s).round() as u64;
    for k in 0..ticks {
        let t_s = k as f64 * dt_s;
        let left = script(t_s).and_then(|position_mm| common::pose_at(k + 1, position_mm));
        let step = tick.step(&[left, None], &[None, None], &mut out);
        let view = TickView {
            tick: k,
            active: tick.tools_active(),
            outputs: tick.outputs(),
            step: &step,
        };
        observer.observe(
            &view,
            |e| {
                if e.tool == 0 {
                    events.push(*e);
                }
            },
            |tool, tr| {
                if tool == 0 {
                    states.push(tr.to);
                }
            },
        );
        assert_eq!(step.faults, 0);
    }
    (observer.metrics(0).unwrap().summary(), events, states)
}

fn count(events: &[SessionEvent], kind: EventKind) -> usize {
    events.iter().filter(|e| e.kind == kind).count()
}

#[test]
fn a_straight_40_mm_stroke_in_free_air_measures_40_mm_economy_1_and_no_contact() {
    // 40 mm above the pad (beyond the 20 mm look-ahead): 0.5 s still, 40 mm along x in 1 s, 0.5 s still.
    let (m, events, states) = session(2.0, |t| {
        let x = (40.0 * (t - 0.5)).clamp(0.0, 40.0) as f32 - 20.0;
        Some([x, 0.0, 40.0])
    });
    println!("{m:?}");
    assert!(
        (m.path_length_mm - 40.0).abs() < 0.4,
        "path {:.3} mm for a 40 mm stroke",
        m.path_length_mm
    );
    assert!((m.straight_line_mm - 40.0).abs() < 0.1, "{m:?}");
    let economy = m.economy.unwrap();
    assert!((1.0..1.01).contains(&economy), "economy {economy:.4}");
    assert!((m.task_time_s - 2.0).abs() < 1e-9, "{m:?}");
    assert_eq!(
        (m.contact_time_s, m.contacts, m.peak_force_n),
        (0.0, 0, 0.0)
    );
    assert_eq!(count(&events, EventKind::Joined), 1);
    // The tool starts parked at the device origin, on the pad, and is dragged up to the hand in its first
    // ticks: near the tissue only then.
    assert!(
        events
            .iter()
            .all(|e| e.kind == EventKind::Joined || e.tick < 100),
        "{events:?}"
    );
    assert_eq!(states.last(), Some(&SkillState::Idle), "{states:?}");
}

#[test]
fn a_one_second_press_measures_one_second_of_contact_and_the_states_of_a_probe() {
    // Hover 10 mm above (probe radius 4: 6 mm clear), press to 1 mm below the surface for 1.000 s, lift.
    let (m, events, states) = session(2.5, |t| {
        let z = if (0.5..1.5).contains(&t) { -1.0 } else { 10.0 };
        Some([0.0, 0.0, z])
    });
    println!("{m:?}\n{events:?}");
    // The coupling crosses the 6 mm gap in about 15 ms each way (at most 500 mm/s): contact starts that much
    // after the pose and ends that much after it leaves, give or take the dent following the probe up.
    assert_eq!(m.contacts, 1, "{events:?}");
    assert!(
        (m.contact_time_s - 1.0).abs() < 0.03,
        "contact {:.3} s for a 1.000 s press",
        m.contact_time_s
    );
    assert!(
        m.mean_contact_force_n > 0.3 && m.peak_force_n < 3.3,
        "{m:?}"
    );
    assert_eq!(m.harm_n_s, 0.0, "a 5 mm press is not harmful");
    assert_eq!(
        states,
        [
            SkillState::Idle,
            SkillState::Approach,
            SkillState::Contact,
            SkillState::Approach
        ]
    );
    let begin = events
        .iter()
        .find(|e| e.kind == EventKind::ContactBegin)
        .unwrap();
    assert!((500..530).contains(&begin.tick), "{begin:?}");
}

#[test]
fn a_press_into_the_force_limit_peaks_at_exactly_the_limit_and_integrates_the_excess_as_harm() {
    // Hover, then 20 mm into the pad (far past what 3.3 N holds) for 1 s, then lift and leave.
    let (m, events, _) = session(2.5, |t| {
        if t >= 2.2 {
            None
        } else if (0.5..1.5).contains(&t) {
            Some([0.0, 0.0, -20.0])
        } else {
            Some([0.0, 0.0, 10.0])
        }
    });
    println!("{m:?}");
    assert!(
        (m.peak_force_n - 3.3).abs() < 1e-5,
        "peak {:.6} N: the tool's limit is 3.3 N",
        m.peak_force_n
    );
    // At the limit the excess is 3.3 - 2.2 = 1.1 N: harm is 1.1 N times the time at the limit, which is the
    // contact time less the rise and fall.
    let at_limit_s = m.harm_n_s / 1.1;
    assert!(
        at_limit_s > m.contact_time_s - 0.2 && at_limit_s <= m.contact_time_s,
        "harm {:.4} N s over {:.3} s of contact",
        m.harm_n_s,
        m.contact_time_s
    );
    assert_eq!(count(&events, EventKind::HarmBegin), 1);
    assert_eq!(count(&events, EventKind::HarmEnd), 1);
    assert_eq!(count(&events, EventKind::Left), 1);
    assert!((m.task_time_s - 2.2).abs() < 1e-9, "{m:?}");
}
