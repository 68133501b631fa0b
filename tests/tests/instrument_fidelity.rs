//! Every interaction at a distance, on virtual time: the shipped instrument worlds with the demo's scripts,
//! in `--mode auto`, at 50-200 ms round trips, against the same trajectories at zero delay
//! (`tests/src/fidelity.rs`). Deterministic: no wall-clock assertion.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use hapticserver::HandPreset;
use sinew_testkit::drill::Link;
use sinew_testkit::fidelity::{
    FIDELITY_RUN_S, TUG_HOLD_S, fidelity, mean_force_n, sheet_difference_mm, tug_of_war,
};
use sinew_testkit::harness::load_shipped_world;

const ROUND_TRIPS_MS: [f64; 3] = [50.0, 100.0, 200.0];

// The runs cover the release (the demo's jaws open at 4.5 s), and the tug's hold ends before left opens (5 s).
const _: () = assert!(FIDELITY_RUN_S > 4.6 && TUG_HOLD_S.1 < 5.0);

/// Two graspers pull one sheet apart (grasp_pull's demo): peak and RMS force felt within 10% of zero delay,
/// the passivity controller quiet, no clamp, no silence; `--mode auto` renders the local model at a
/// distance (10 ms included: streamed there, a grasp drove these hands to the clamp) and streams at zero
/// delay. Before the grasp had a bilateral term of its own, the nominal hand felt +130% at 200 ms with
/// 115 mJ withheld; before it was rendered from the device through the coupling, the firm hand reached the
/// clamp at every round trip.
#[test]
fn a_grasped_pull_is_felt_at_a_distance_as_at_zero_delay() {
    let world = load_shipped_world("grasp_pull.toml").unwrap();
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    for hand in [HandPreset::Light, HandPreset::Nominal, HandPreset::Firm] {
        for rtt_ms in [10.0].into_iter().chain(ROUND_TRIPS_MS) {
            let f = fidelity(&world, hand, Link::rtt(rtt_ms), Link::rtt(rtt_ms)).unwrap();
            for (d, row) in f.devices.iter().zip(f.rows("grasp_pull", hand, rtt_ms)) {
                if !d.faithful_within(0.10) {
                    failures.push(row.clone());
                }
                rows.push(row);
            }
            for (delayed, reference) in f.delayed.traces.iter().zip(&f.reference.traces) {
                let weight = |t: &[hapticserver::TraceSample]| t.last().unwrap().model_weight;
                assert_eq!(weight(reference), 0.0, "auto streams at zero delay");
                assert_eq!(
                    weight(delayed),
                    1.0,
                    "auto renders the model at {rtt_ms} ms"
                );
            }
        }
    }
    println!("{}", rows.join("\n"));
    assert!(failures.is_empty(), "outside 10%:\n{}", failures.join("\n"));
}

/// The scalpel's drag, felt while it cuts (cut.toml's demo: 40 mm along +y at 20 mm/s), within 10% of zero
/// delay for the nominal and firm hands, and the whole run's peak and RMS within 10%: the peak is the drag as
/// a facet is cut, which the device's own sawtooth reproduces (with the model's mean drag it was 20% low).
/// Before the model carried the drag of cutting, nothing was felt at 200 ms. (The light hand: BENCHMARKS.md.)
#[test]
fn the_drag_of_cutting_is_felt_at_a_distance_as_at_zero_delay() {
    let world = load_shipped_world("cut.toml").unwrap();
    let mut rows = Vec::new();
    for hand in [HandPreset::Nominal, HandPreset::Firm] {
        for rtt_ms in ROUND_TRIPS_MS {
            let f = fidelity(&world, hand, Link::rtt(rtt_ms), Link::rtt(rtt_ms)).unwrap();
            // The edge cuts from about 1.2 s to 3 s at zero delay: the steady part.
            let (from_s, to_s) = (1.4, 2.9);
            let reference = mean_force_n(&f.reference.traces[0], from_s, to_s);
            let felt = mean_force_n(&f.delayed.traces[0], from_s, to_s);
            rows.push(format!(
                "{} {rtt_ms} ms: drag {felt:.4} N against {reference:.4} N",
                hand.name()
            ));
            assert!(reference > 0.05, "no drag at zero delay: {rows:?}");
            assert!(
                (felt / reference - 1.0).abs() <= 0.10,
                "drag outside 10%: {rows:?}"
            );
            let d = &f.devices[0];
            rows.push(format!(
                "  peak {:+.1}%, RMS {:+.1}%",
                100.0 * d.peak_error(),
                100.0 * d.rms_error()
            ));
            assert!(d.faithful_within(0.10), "{rows:?}");
        }
    }
    println!("{}", rows.join("\n"));
}

/// The other instrument worlds at 200 ms, nominal hands: the cautery and the graspers' RMS force within 10%
/// of zero delay, cut_under_tension's scalpel's drag while it cuts within 10%, the controller quiet, no
/// clamp. The cautery's peaks: see [`the_cautery_tip_touches_down_at_a_distance_as_at_zero_delay`].
#[test]
fn cautery_and_a_cut_under_tension_are_felt_at_200_ms_as_at_zero_delay() {
    for world_name in ["cautery.toml", "cut_under_tension.toml"] {
        let world = load_shipped_world(world_name).unwrap();
        let f = fidelity(
            &world,
            HandPreset::Nominal,
            Link::rtt(200.0),
            Link::rtt(200.0),
        )
        .unwrap();
        let rows = f.rows(world_name, HandPreset::Nominal, 200.0);
        println!("{}", rows.join("\n"));
        for (device, d) in f.devices.iter().enumerate() {
            assert!(d.withheld_mj < 1.0 && !d.clamped, "{}", rows.join("\n"));
            let scalpel = world_name == "cut_under_tension.toml" && device == 0;
            if scalpel {
                let (from_s, to_s) = (1.4, 2.9);
                let reference = mean_force_n(&f.reference.traces[0], from_s, to_s);
                let felt = mean_force_n(&f.delayed.traces[0], from_s, to_s);
                assert!(
                    (felt / reference - 1.0).abs() <= 0.10,
                    "drag while cutting {felt:.4} N against {reference:.4} N"
                );
            } else {
                assert!(d.rms_error().abs() <= 0.10, "{}", rows.join("\n"));
            }
        }
    }
}

/// The cautery's 1.5 mm tip touching the pad down at 100 and 200 ms, nominal and firm hands: its peak no more
/// than 10% above zero delay (it was +65-318% while a touch-down's plane carried a fixed 2.5 mm footprint, four
/// times stiffer than what the tip holds) and at most 12% below (measured -10.9% for the nominal hand at
/// 200 ms: the footprint a quarter of the tip's radius deep holds one node, where the contact soon holds
/// several), RMS within 10%, the controller quiet, no clamp. The probe holding the tissue: within 10%.
#[test]
fn the_cautery_tip_touches_down_at_a_distance_as_at_zero_delay() {
    let world = load_shipped_world("cautery.toml").unwrap();
    for hand in [HandPreset::Nominal, HandPreset::Firm] {
        for rtt_ms in [100.0, 200.0] {
            let f = fidelity(&world, hand, Link::rtt(rtt_ms), Link::rtt(rtt_ms)).unwrap();
            let rows = f.rows("cautery", hand, rtt_ms);
            println!("{}", rows.join("\n"));
            let (tip, probe) = (&f.devices[0], &f.devices[1]);
            assert!(
                (-0.12..=0.10).contains(&tip.peak_error())
                    && tip.rms_error().abs() <= 0.10
                    && tip.withheld_mj < 1.0
                    && !tip.clamped
                    && tip.stale_events == 0,
                "{}",
                rows.join("\n")
            );
            assert!(probe.faithful_within(0.10), "{}", rows.join("\n"));
        }
    }
}

/// The cautery's 1.5 mm tip stroked across the pad by a light hand (1.5-3.0 s of the demo, after the touch-down has settled) holds steady at a
/// distance: the slide's peak force within 10% of zero delay's and its height wandering at most 0.15 mm more.
/// The model's normal stiffness is fitted from the server tool's force on its depth; measured along the
/// push, which tilts 0.05 rad as the small tip rides the mesh, the depth was read 20 mm from the world's
/// origin, moved a millimetre while the force held, and the fit fell to zero: the device rendered a
/// constant force and the light hand bobbed 0.8 mm at 3 Hz, a round trip behind the server (+36% at 50 ms).
#[test]
fn the_cautery_tip_stroked_by_a_light_hand_holds_steady_at_a_distance() {
    let world = load_shipped_world("cautery.toml").unwrap();
    let slide = |trace: &[hapticserver::TraceSample]| {
        let window: Vec<_> = trace
            .iter()
            .filter(|s| (1.5..3.0).contains(&s.t_s))
            .collect();
        let peak = window
            .iter()
            .map(|s| s.force_n.iter().map(|c| c * c).sum::<f32>().sqrt())
            .fold(0.0f32, f32::max);
        let (lo, hi) = window.iter().fold((f32::MAX, f32::MIN), |(lo, hi), s| {
            (lo.min(s.position_mm[2]), hi.max(s.position_mm[2]))
        });
        (peak, hi - lo)
    };
    for rtt_ms in [50.0, 100.0] {
        let f = fidelity(
            &world,
            HandPreset::Light,
            Link::rtt(rtt_ms),
            Link::rtt(rtt_ms),
        )
        .unwrap();
        let (peak, wander) = slide(&f.delayed.traces[0]);
        let (zero_peak, zero_wander) = slide(&f.reference.traces[0]);
        println!(
            "{rtt_ms} ms: slide peak {peak:.4} N (zero delay {zero_peak:.4}), height wanders {wander:.3} mm \
             ({zero_wander:.3})"
        );
        assert!(
            (peak / zero_peak - 1.0).abs() <= 0.10,
            "{rtt_ms} ms: {peak} against {zero_peak} N"
        );
        assert!(
            wander <= zero_wander + 0.15,
            "{rtt_ms} ms: the hand wandered {wander} mm ({zero_wander} at zero delay)"
        );
    }
}

/// The pad with Coulomb friction 0.5 (as the golden traces make it), stroked by the demo's nominal hands: peak
/// and RMS force within 10% of zero delay at 50-200 ms, the controller quiet, no clamp. The friction is
/// rendered about the device's own stick point with the sliding coefficient the server measures; carried in
/// `f0` it was a round trip late and tilted the contact normal: +37-108% peaks and up to 24 mJ withheld.
/// (The light hand's touch-down overshoots as on the frictionless pad, +8-14% at 100-200 ms; the firm hand
/// ploughs a dent whose wall drag still travels in `f0`: BENCHMARKS.md.)
#[test]
fn friction_on_the_pad_is_felt_at_a_distance_as_at_zero_delay() {
    let mut world = load_shipped_world("pad.toml").unwrap();
    world.objects[0].material.friction_coefficient = 0.5;
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    for rtt_ms in ROUND_TRIPS_MS {
        let f = fidelity(
            &world,
            HandPreset::Nominal,
            Link::rtt(rtt_ms),
            Link::rtt(rtt_ms),
        )
        .unwrap();
        for (d, row) in f
            .devices
            .iter()
            .zip(f.rows("pad_friction", HandPreset::Nominal, rtt_ms))
        {
            if !d.faithful_within(0.10) {
                failures.push(row.clone());
            }
            rows.push(row);
        }
    }
    println!("{}", rows.join("\n"));
    assert!(failures.is_empty(), "outside 10%:\n{}", failures.join("\n"));
}

/// A tug of war on tug_of_war.toml's membrane: right holds the sheet while left takes hold 12 mm from it and
/// pulls 6 mm outward and 8 mm up. With left at 10 or 200 ms and right at 200 or 10 ms (and both at 200 ms):
/// each feels the other's pull within 15% of zero delay (right: the change left's pull makes to its force;
/// left: its pull against the sheet and right's grip), both hold still afterwards (the stability rule of the
/// remote-surgeons issue), the controller withholds under 1 mJ, nothing reaches the clamp or the silence rule,
/// and the sheet in the middle of the hold is where it is at zero delay to 0.5 mm. (On grasp_pull's sheet,
/// anchored eight times more firmly, right felt 2 mN of the pull: too little to hold to anything.)
#[test]
fn a_tug_of_war_at_200_ms_is_felt_and_held_as_at_zero_delay() {
    let world = load_shipped_world("tug_of_war.toml").unwrap();
    let hand = HandPreset::Nominal;
    let reference = tug_of_war(&world, hand, Link::rtt(0.0), Link::rtt(0.0)).unwrap();
    assert!(
        reference.left_feels_n > 0.5 && reference.right_feels_n > 0.04,
        "each must feel the pull: left {} N, right {} N",
        reference.left_feels_n,
        reference.right_feels_n
    );
    let mut rows = Vec::new();
    for (left_ms, right_ms) in [(10.0, 200.0), (200.0, 10.0), (200.0, 200.0)] {
        let tug = tug_of_war(&world, hand, Link::rtt(left_ms), Link::rtt(right_ms)).unwrap();
        let right_ratio = tug.right_feels_n / reference.right_feels_n;
        let left_ratio = tug.left_feels_n / reference.left_feels_n;
        let sheet_mm = sheet_difference_mm(&tug.sheet_mm, &reference.sheet_mm);
        let row = format!(
            "left {left_ms} / right {right_ms} ms: left feels {:.3} N ({left_ratio:.3} of zero delay), right {:.4} N \
             ({right_ratio:.3}); hold {:?}; energy out {:?} mJ; withheld {:?} mJ; clamped {:?}; sheet {sheet_mm:.3} mm",
            tug.left_feels_n,
            tug.right_feels_n,
            tug.hold,
            tug.energy_out_mj,
            tug.withheld_mj,
            tug.clamped
        );
        let stable = tug
            .hold
            .iter()
            .all(|h| h.force_p2p_n < 0.05 && h.velocity_rms_mm_s < 1.0)
            && tug.energy_out_mj.iter().all(|&e| e <= 1.0);
        assert!(
            (0.85..=1.15).contains(&left_ratio)
                && (0.85..=1.15).contains(&right_ratio)
                && stable
                && tug.withheld_mj.iter().all(|&w| w < 1.0)
                && !tug.clamped.iter().any(|&c| c)
                && tug.stale_events.iter().all(|&s| s == 0)
                && sheet_mm <= 0.5,
            "{row}"
        );
        rows.push(row);
    }
    println!("{}", rows.join("\n"));
}
