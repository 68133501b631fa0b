//! Latency-moderated mode against its acceptance criteria, on virtual time: the real server tick and device
//! loops, joined by seeded emulated links (tests/src/drill.rs). Deterministic: no wall-clock assertion.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use hapticserver::{HandPreset, HandScript, ModePolicy};
use sinew_testkit::drill::{
    DrillDevice, Link, drift_mm, energy_output_mj, force_amplitude_at, hold_metrics,
    max_force_step, run_drill,
};
use sinew_testkit::harness::load_shipped_world;
use sinew_testkit::scenarios::{
    felt_stiffness_n_per_mm, hold, lossy_link, one_device, press, stroke_error, taps,
};

/// Press, then hold; measure the last 2 s of a 5 s run (the hold starts at 1 s), at +-20 ms jitter and 5% loss.
fn stability_row(world: &str, hand: HandPreset, rtt_ms: f64, mode: ModePolicy) -> String {
    let link = lossy_link(rtt_ms);
    hold(world, hand, link, mode)
        .unwrap()
        .row(world, hand, &link, mode)
}

fn assert_all_stable(cases: &[(&str, HandPreset)]) {
    let mut rows = Vec::new();
    for &(world, hand) in cases {
        for rtt_ms in [10.0, 50.0, 100.0, 200.0] {
            rows.push(stability_row(world, hand, rtt_ms, ModePolicy::Moderated));
        }
    }
    let failures: Vec<&String> = rows.iter().filter(|r| r.ends_with("UNSTABLE")).collect();
    assert!(failures.is_empty(), "unstable:\n{}", rows.join("\n"));
}

#[test]
fn moderated_mode_holds_still_on_both_pads_with_every_hand_up_to_200_ms_with_jitter_and_loss() {
    assert_all_stable(&[
        ("pad.toml", HandPreset::Light),
        ("pad.toml", HandPreset::Nominal),
        ("pad_stiff.toml", HandPreset::Light),
        ("pad_stiff.toml", HandPreset::Nominal),
        ("pad_stiff.toml", HandPreset::Firm),
    ]);
}

#[test]
fn the_firm_hand_holds_still_on_the_soft_pad() {
    assert_all_stable(&[("pad.toml", HandPreset::Firm)]);
}

#[test]
fn direct_mode_at_the_same_settings_fails_where_theory_says() {
    // A streamed force is passive only while hand damping b > K (T/2 + d): the light hand (1.5 N s/m) on
    // the pad's ~200 N/m contact at 100 ms round trip is far outside that.
    let row = stability_row("pad.toml", HandPreset::Light, 100.0, ModePolicy::Direct);
    assert!(row.ends_with("UNSTABLE"), "{row}");
    // ... while moderated mode holds the same hand still at the same delay, jitter and loss.
    let row = stability_row("pad.toml", HandPreset::Light, 100.0, ModePolicy::Moderated);
    assert!(row.ends_with("stable"), "{row}");
}

/// A slow press, 1-5 mm into the pad over 6 s: the felt stiffness at each round trip against zero delay.
#[test]
fn felt_stiffness_stays_within_ten_percent_of_zero_delay_up_to_200_ms() {
    let run = |rtt_ms: f64| {
        // The firm hand follows its target closely: 18 mm of travel over 6 s, 8 mm below the surface.
        felt_stiffness_n_per_mm(HandPreset::Firm, Link::rtt(rtt_ms), ModePolicy::Moderated)
            .unwrap()
            .expect("the press reached 5 mm")
    };
    let reference = run(0.0);
    assert!(reference > 0.05, "zero-delay stiffness {reference} N/mm");
    for rtt_ms in [50.0, 100.0, 200.0] {
        let ratio = run(rtt_ms) / reference;
        assert!(
            (0.9..=1.1).contains(&ratio),
            "felt stiffness ratio {ratio:.3} at {rtt_ms} ms (zero delay {reference:.3} N/mm)"
        );
    }
}

/// Lateral strokes of +-8 mm in a 4 mm dent with period `period_s`, firm hand, at 100 ms round trip against
/// zero delay: the RMS force error (fraction of peak) and the drift at equal timestamps.
fn stroke_run(period_s: f32) -> (f32, f32, f32) {
    stroke_error(
        HandPreset::Firm,
        period_s,
        Link::rtt(100.0),
        ModePolicy::Moderated,
    )
    .unwrap()
}

#[test]
fn force_tracks_a_zero_delay_run_at_half_a_hertz_and_the_server_tool_stays_with_the_device() {
    let (error, drift, speed) = stroke_run(2.0);
    assert!(
        error <= 0.10,
        "0.5 Hz strokes: RMS force error {error:.3} of peak"
    );
    assert!(drift < 3.0, "drift {drift:.2} mm at up to {speed:.0} mm/s");
    // At rest: under 1 mm (the coupling's F / k_c).
    let world = load_shipped_world("pad.toml").unwrap();
    let result = run_drill(
        &world,
        &[one_device(
            HandPreset::Nominal,
            press(10.0, 1.0),
            Link::rtt(100.0),
            ModePolicy::Moderated,
        )],
        4.0,
    )
    .unwrap();
    let (drift, _) = drift_mm(&result, 0, 3.0, 4.0);
    assert!(drift < 1.0, "drift at rest {drift:.3} mm");
}

#[test]
fn force_tracks_a_zero_delay_run_at_two_hertz() {
    let (error, drift, speed) = stroke_run(0.5);
    assert!(
        error <= 0.20,
        "2 Hz strokes: RMS force error {error:.3} of peak"
    );
    assert!(drift < 3.0, "drift {drift:.2} mm at up to {speed:.0} mm/s");
}

/// The heartbeat (7 ms) keeps the stream inside the device's 50 ms silence rule through +-10 ms of jitter and
/// 5% loss; the deadband keeps a held contact at about the heartbeat's rate.
#[test]
fn holding_still_costs_at_most_150_messages_a_second_and_no_silence_through_jitter_and_5_percent_loss()
 {
    let world = load_shipped_world("pad.toml").unwrap();
    for loss in [0.01, 0.05] {
        let result = run_drill(
            &world,
            &[one_device(
                HandPreset::Nominal,
                press(10.0, 1.0),
                Link {
                    rtt_ms: 100.0,
                    jitter_ms: 10.0,
                    loss,
                    seed: 5,
                },
                ModePolicy::Moderated,
            )],
            12.0,
        )
        .unwrap();
        // 10 s of holding after the press: the deadband leaves the heartbeat.
        let per_s = result.commands_sent[0] as f64 / 12.0;
        assert!(per_s <= 150.0, "{per_s:.0} messages/s at {loss} loss");
        assert_eq!(
            result.stale_events[0], 0,
            "a silence reached the device's 50 ms rule"
        );
        assert!(
            result.max_force_n[0] < 3.3,
            "the force never reached the clamp"
        );
        assert_eq!(result.rejected[0], 0);
    }
}

/// Two surgeons: left at 100 ms pushes 1 Hz pulses into the pad between them; right at 10 ms holds its tool in
/// the tissue and must feel the push as it would at zero delay. The passivity controller is on in moderated
/// mode; the server's energy budget is what lets left's energy reach right's hand.
#[test]
fn right_feels_lefts_push_through_the_tissue_as_at_zero_delay() {
    let world = load_shipped_world("pad.toml").unwrap();
    let run = |left_rtt_ms: f64, right_rtt_ms: f64| {
        let left = DrillDevice {
            id: "left".into(),
            hand: HandPreset::Firm,
            script: HandScript::PressAndPulse {
                at_mm: [14.0, 0.0, 0.0],
                depth_mm: 3.0,
                approach_mm: 10.0,
                descend_s: 1.0,
                pulse_mm: 4.0,
                pulse_period_s: 1.0,
            },
            link: Link::rtt(left_rtt_ms),
            mode: ModePolicy::Moderated,
        };
        let right = DrillDevice {
            id: "right".into(),
            hand: HandPreset::Nominal,
            script: HandScript::Press {
                at_mm: [-14.0, 0.0, 0.0],
                depth_mm: 10.0,
                approach_mm: 10.0,
                descend_s: 1.0,
            },
            link: Link::rtt(right_rtt_ms),
            mode: ModePolicy::Moderated,
        };
        run_drill(&world, &[left, right], 6.0).unwrap()
    };
    // Three whole periods of the 1 Hz push; 4/3 and 5/3 Hz are orthogonal to it over that window and measure
    // what is not the push (tissue noise, contact chatter).
    let amplitude = |result: &sinew_testkit::drill::DrillResult, hz: f64| {
        force_amplitude_at(&result.traces[1], hz, 3.0, 6.0)
    };
    let reference = run(0.0, 0.0);
    let delayed = run(100.0, 10.0);
    let felt_reference = amplitude(&reference, 1.0);
    let felt = amplitude(&delayed, 1.0);
    let noise = amplitude(&reference, 4.0 / 3.0).max(amplitude(&reference, 5.0 / 3.0));
    assert!(
        felt_reference > 0.01 && felt_reference > 10.0 * noise,
        "right must feel the push at all: {felt_reference} N at 1 Hz, {noise} N beside it"
    );
    let ratio = felt / felt_reference;
    println!(
        "right feels {felt:.4} N at 1 Hz at 100/10 ms, {felt_reference:.4} N at zero delay (noise {noise:.5} N)"
    );
    assert!(
        (0.85..=1.15).contains(&ratio),
        "right feels {felt:.3} N against {felt_reference:.3} N at zero delay (ratio {ratio:.2})"
    );
    // A tug of war with both at 200 ms stays stable.
    let tug = run(200.0, 200.0);
    for device in 0..2 {
        let hold = hold_metrics(&tug.traces[device], 4.0, 6.0);
        assert!(
            hold.velocity_rms_mm_s < 20.0 && energy_output_mj(&tug.traces[device]) <= 1.0,
            "device {device}: {hold:?}"
        );
        assert_eq!(tug.rejected[device], 0);
    }
}

/// A hand that taps: its probe's bottom aims from 2 mm above the surface to 8 mm into it, once a second, so every
/// second brings a contact onset, a stream of model updates while pressing, and an offset. At 100 ms round trip with jitter
/// and loss the rendered force never steps by more than 0.1 N from one tick to the next.
#[test]
fn the_force_never_steps_more_than_a_tenth_of_a_newton_at_onset_offset_and_model_updates() {
    let world = load_shipped_world("pad.toml").unwrap();
    let tap = taps();
    let link = Link {
        rtt_ms: 100.0,
        jitter_ms: 20.0,
        loss: 0.05,
        seed: 5,
    };
    let mut rows = Vec::new();
    for hand in [HandPreset::Light, HandPreset::Nominal, HandPreset::Firm] {
        let result = run_drill(
            &world,
            &[one_device(hand, tap.clone(), link, ModePolicy::Moderated)],
            6.0,
        )
        .unwrap();
        let trace = &result.traces[0];
        let onsets = trace
            .windows(2)
            .filter(|w| w[0].force_n[2] <= 0.0 && w[1].force_n[2] > 0.0)
            .count();
        let peak = trace.iter().map(|s| s.force_n[2]).fold(0.0f32, f32::max);
        let step = max_force_step(trace, 0.0, 6.0);
        rows.push(format!(
            "{}: {onsets} onsets, peak {peak:.2} N, largest step {step:.4} N",
            hand.name()
        ));
        assert!(onsets >= 4, "the taps did not touch and leave: {rows:?}");
        assert!(peak > 0.15, "the taps pressed only {peak} N: {rows:?}");
        assert!(step <= 0.1, "force stepped: {rows:?}");
    }
    println!("{}", rows.join("\n"));
}
