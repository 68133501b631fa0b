//! The latency-moderated mode's acceptance scenarios as drill runs that return their figures.
//!
//! Owns: the simulated operator's scripts for them (press, hold, stroke, tap), how deep each hand presses on
//! each pad, and one function per measured quantity of issue "Remote surgeons": the hold (stable? messages a
//! second), the felt stiffness against zero delay, and the force error of a stroke against zero delay. The
//! acceptance tests (`tests/tests/latency_drills.rs`) assert on them; the `latency_table` bench prints them for
//! every mode x round trip x hand and draws the figure; the `tap_explore` example reuses the scripts.
//!
//! Must not: assert (callers decide), open zenoh sessions or read the wall clock (runs are on the drill's
//! virtual time, so every figure here is deterministic).

use hapticserver::{HandPreset, HandScript, ModePolicy, TraceSample};

use crate::drill::{
    DrillDevice, DrillResult, HoldMetrics, Link, drift_mm, energy_output_mj, felt_stiffness,
    hold_metrics, rms_error_fraction, run_drill,
};
use crate::harness::load_shipped_world;

/// A press at the surface point under the device origin: from 10 mm above to `depth_mm` below the surface
/// (of the probe's centre) over `descend_s`, then hold.
pub fn press(depth_mm: f32, descend_s: f32) -> HandScript {
    HandScript::Press {
        at_mm: [0.0; 3],
        depth_mm,
        approach_mm: 10.0,
        descend_s,
    }
}

/// Lateral strokes of +-8 mm along x in a 4 mm dent, with period `period_s`.
pub fn stroke(period_s: f32) -> HandScript {
    HandScript::PressAndStroke {
        at_mm: [0.0; 3],
        depth_mm: 4.0,
        approach_mm: 10.0,
        descend_s: 1.0,
        stroke_mm: 8.0,
        stroke_period_s: period_s,
    }
}

/// Taps: the probe's bottom aims from 2 mm above the surface to 8 mm into it, once a second, so every second
/// brings a contact onset, model updates while pressing, and an offset.
pub fn taps() -> HandScript {
    HandScript::PressAndPulse {
        at_mm: [0.0; 3],
        // The script places the probe's centre; its bottom is the 4 mm radius lower.
        depth_mm: -6.0,
        approach_mm: 10.0,
        descend_s: 1.0,
        pulse_mm: 10.0,
        pulse_period_s: 1.0,
    }
}

/// One device called `left` on the drill.
pub fn one_device(
    hand: HandPreset,
    script: HandScript,
    link: Link,
    mode: ModePolicy,
) -> DrillDevice {
    DrillDevice {
        id: "left".into(),
        hand,
        script,
        link,
        mode,
    }
}

/// How deep each hand aims (below the surface, mm) for a firm but unclamped hold on each shipped pad.
pub fn hold_depth_mm(world: &str, hand: HandPreset) -> f32 {
    match (world, hand) {
        ("pad.toml", HandPreset::Light) => 30.0,
        ("pad.toml", HandPreset::Nominal) => 10.0,
        // 4 mm: the firm hand follows its target closely, so this is about the depth it holds.
        ("pad.toml", _) => 4.0,
        (_, HandPreset::Light) => 12.0,
        (_, HandPreset::Nominal) => 6.0,
        _ => 2.0,
    }
}

/// The acceptance's hold link: this round trip with +-20 ms jitter (at most half the round trip) and 5% loss
/// each way.
pub fn lossy_link(rtt_ms: f64) -> Link {
    Link {
        rtt_ms,
        jitter_ms: 20.0_f64.min(rtt_ms / 2.0),
        loss: 0.05,
        seed: 11,
    }
}

/// What a press-and-hold run measured over its last 2 s.
#[derive(Debug, Clone)]
pub struct HoldOutcome {
    /// Stillness of the hold window.
    pub hold: HoldMetrics,
    /// Net energy the rendered force put into the hand over the run, mJ.
    pub energy_out_mj: f64,
    /// Force messages the server sent per second over the hold window.
    pub messages_per_s: f64,
    /// Poses the server refused.
    pub rejected: u64,
    /// Silences that reached the device's 50 ms rule.
    pub stale_events: u64,
    /// Every device tick.
    pub trace: Vec<TraceSample>,
}

impl HoldOutcome {
    /// The acceptance's stability rule: force peak-to-peak < 0.05 N, stylus speed RMS < 1 mm/s, net energy
    /// output <= 1 mJ.
    pub fn stable(&self) -> bool {
        self.hold.force_p2p_n < 0.05
            && self.hold.velocity_rms_mm_s < 1.0
            && self.energy_out_mj <= 1.0
    }

    /// One line naming the case and its figures, ending in `stable` or `UNSTABLE`.
    pub fn row(&self, world: &str, hand: HandPreset, link: &Link, mode: ModePolicy) -> String {
        format!(
            "{world} {} {} ms {}: p2p {:.4} N, v_rms {:.3} mm/s, energy out {:.3} mJ, F {:.2} N, {:.0} msg/s, \
             refused {}, stale {} -> {}",
            hand.name(),
            link.rtt_ms,
            mode.name(),
            self.hold.force_p2p_n,
            self.hold.velocity_rms_mm_s,
            self.energy_out_mj,
            self.hold.mean_force_n,
            self.messages_per_s,
            self.rejected,
            self.stale_events,
            if self.stable() { "stable" } else { "UNSTABLE" }
        )
    }
}

/// Length of a hold run, s: the press takes 1 s, the hold is measured over the last 2 s.
pub const HOLD_RUN_S: f64 = 5.0;

/// Press to [`hold_depth_mm`] on `world` (a shipped world file name), hold, and measure the last 2 s.
pub fn hold(
    world: &str,
    hand: HandPreset,
    link: Link,
    mode: ModePolicy,
) -> anyhow::Result<HoldOutcome> {
    let loaded = load_shipped_world(world)?;
    let script = press(hold_depth_mm(world, hand), 1.0);
    let mut result = run_drill(&loaded, &[one_device(hand, script, link, mode)], HOLD_RUN_S)?;
    let trace = std::mem::take(&mut result.traces[0]);
    let from_s = HOLD_RUN_S - 2.0;
    Ok(HoldOutcome {
        hold: hold_metrics(&trace, from_s, HOLD_RUN_S),
        energy_out_mj: energy_output_mj(&trace),
        messages_per_s: result.messages_per_s_from(0, from_s as usize),
        rejected: result.rejected[0],
        stale_events: result.stale_events[0],
        trace,
    })
}

/// How far below the surface each hand aims for the slow press of [`felt_stiffness_n_per_mm`], mm: far
/// enough that its spring reaches 5 mm of indentation on the soft pad (about 1 N), quasi-statically.
pub fn stiffness_press_depth_mm(hand: HandPreset) -> f32 {
    match hand {
        HandPreset::Light => 45.0,
        HandPreset::Nominal => 16.0,
        _ => 8.0,
    }
}

/// Length of the slow press, s.
pub const STIFFNESS_RUN_S: f64 = 6.5;

/// The stiffness `hand` feels pressing 1-5 mm into the soft pad slowly (6 s) over `link`, N/mm; `None`
/// when the press did not cover 1-5 mm.
pub fn felt_stiffness_n_per_mm(
    hand: HandPreset,
    link: Link,
    mode: ModePolicy,
) -> anyhow::Result<Option<f32>> {
    let world = load_shipped_world("pad.toml")?;
    let script = press(stiffness_press_depth_mm(hand), 6.0);
    let result = run_drill(
        &world,
        &[one_device(hand, script, link, mode)],
        STIFFNESS_RUN_S,
    )?;
    Ok(felt_stiffness(&result.traces[0], 1.0, 5.0))
}

/// Length of a stroke run, s; the error is measured from 2 s on.
pub const STROKE_RUN_S: f64 = 5.0;

/// Strokes of period `period_s` on the soft pad over `link` and over a zero-delay link, same hand and mode:
/// (RMS force error as a fraction of the zero-delay peak, largest server-tool-to-device drift mm, largest
/// device speed mm/s), both from 2 s on.
pub fn stroke_error(
    hand: HandPreset,
    period_s: f32,
    link: Link,
    mode: ModePolicy,
) -> anyhow::Result<(f32, f32, f32)> {
    let world = load_shipped_world("pad.toml")?;
    let run = |link: Link| -> anyhow::Result<DrillResult> {
        run_drill(
            &world,
            &[one_device(hand, stroke(period_s), link, mode)],
            STROKE_RUN_S,
        )
    };
    let reference = run(Link::rtt(0.0))?;
    let delayed = run(link)?;
    let error = rms_error_fraction(&delayed.traces[0], &reference.traces[0], 2.0, STROKE_RUN_S);
    let (drift, speed) = drift_mm(&delayed, 0, 2.0, STROKE_RUN_S);
    Ok((error, drift, speed))
}
