//! Instrument fidelity at a distance: a shipped instrument world run with the demo's scripts at a round trip,
//! against the same trajectories at zero delay.
//!
//! Owns: [`fidelity`] and its figures ([`Fidelity`]): per device, the peak and RMS force the hand felt, their
//! errors against the zero-delay run, the passivity energy withheld, whether the clamp was reached, and the
//! stability of the last second. Issue "Every interaction at a distance" is written in these figures; the
//! acceptance tests (`tests/tests/instrument_fidelity.rs`) assert on them and the `instrument_table` example
//! prints the table BENCHMARKS.md holds.
//!
//! Must not: assert (callers decide), open zenoh sessions or read the wall clock (drill runs on virtual time).

use hapticserver::{HandPreset, HandScript, ModePolicy, TraceSample};
use sinew_server::scene::World;

use crate::drill::{DrillDevice, DrillResult, Link, run_drill};
use crate::harness::surgeon_scripts_for;

/// What one device felt in a delayed run, against the zero-delay run of the same world and hands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceFidelity {
    /// Largest force magnitude felt at zero delay, N.
    pub reference_peak_n: f32,
    /// Largest force magnitude felt at the round trip, N.
    pub peak_n: f32,
    /// RMS force magnitude over the run at zero delay, N.
    pub reference_rms_n: f32,
    /// RMS force magnitude over the run at the round trip, N.
    pub rms_n: f32,
    /// Energy the passivity controller withheld at the round trip, mJ.
    pub withheld_mj: f64,
    /// The rendered force reached the device's maximum.
    pub clamped: bool,
    /// Silences that reached the device's 50 ms rule.
    pub stale_events: u64,
    /// Largest tick-to-tick change of the rendered force, N.
    pub max_step_n: f32,
}

impl DeviceFidelity {
    /// `peak / reference peak - 1`.
    pub fn peak_error(&self) -> f32 {
        self.peak_n / self.reference_peak_n - 1.0
    }

    /// `rms / reference rms - 1`.
    pub fn rms_error(&self) -> f32 {
        self.rms_n / self.reference_rms_n - 1.0
    }

    /// The acceptance for one device: peak and RMS within `fraction` of zero delay, under 1 mJ
    /// withheld, never at the clamp, no silence reaching the 50 ms rule.
    pub fn faithful_within(&self, fraction: f32) -> bool {
        self.peak_error().abs() <= fraction
            && self.rms_error().abs() <= fraction
            && self.withheld_mj < 1.0
            && !self.clamped
            && self.stale_events == 0
    }
}

/// A delayed run against the zero-delay run.
#[derive(Debug, Clone)]
pub struct Fidelity {
    /// One per device (left, right).
    pub devices: Vec<DeviceFidelity>,
    /// The delayed run.
    pub delayed: DrillResult,
    /// The zero-delay run.
    pub reference: DrillResult,
}

impl Fidelity {
    /// One line per device: world, hand, round trip, peak and RMS against zero delay, withheld energy.
    pub fn rows(&self, world: &str, hand: HandPreset, rtt_ms: f64) -> Vec<String> {
        self.devices
            .iter()
            .enumerate()
            .map(|(i, d)| {
                format!(
                    "| {world} | {} | {} | {rtt_ms:.0} ms | {:.3} / {:.3} N ({:+.1}%) | {:.3} / {:.3} N ({:+.1}%) | {:.2} mJ | {} | {:.3} N |",
                    ["left", "right"][i.min(1)],
                    hand.name(),
                    d.peak_n,
                    d.reference_peak_n,
                    100.0 * d.peak_error(),
                    d.rms_n,
                    d.reference_rms_n,
                    100.0 * d.rms_error(),
                    d.withheld_mj,
                    if d.clamped { "clamped" } else { "-" },
                    d.max_step_n,
                )
            })
            .collect()
    }
}

/// Length of an instrument run, s: the demo's scripts grasp, pull, hold and let go within 5 s.
pub const FIDELITY_RUN_S: f64 = 6.0;

fn magnitude(f: [f32; 3]) -> f32 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

/// Peak and RMS of the force magnitude over a whole trace, N.
pub fn peak_and_rms(trace: &[TraceSample]) -> (f32, f32) {
    let peak = trace
        .iter()
        .map(|s| magnitude(s.force_n))
        .fold(0.0, f32::max);
    let sum2: f64 = trace
        .iter()
        .map(|s| f64::from(magnitude(s.force_n)).powi(2))
        .sum();
    (peak, (sum2 / trace.len().max(1) as f64).sqrt() as f32)
}

/// The demo's two devices on `world` ([`surgeon_scripts_for`]), both with `hand`, in `--mode auto`, over
/// `left` and `right` links.
pub fn demo_devices(world: &World, hand: HandPreset, left: Link, right: Link) -> Vec<DrillDevice> {
    let (left_script, right_script): (HandScript, HandScript) = surgeon_scripts_for(world);
    let mut devices = Vec::new();
    for (id, script, link) in [("left", left_script, left), ("right", right_script, right)] {
        if world.tools.iter().any(|t| t.device_id == id) {
            devices.push(DrillDevice {
                id: id.into(),
                hand,
                script,
                link,
                mode: ModePolicy::default(),
            });
        }
    }
    devices
}

/// Run `world` with the demo's scripts and `hand` at round trips `left` / `right` and at zero delay; compare.
pub fn fidelity(
    world: &World,
    hand: HandPreset,
    left: Link,
    right: Link,
) -> anyhow::Result<Fidelity> {
    let reference = run_drill(
        world,
        &demo_devices(world, hand, Link::rtt(0.0), Link::rtt(0.0)),
        FIDELITY_RUN_S,
    )?;
    let delayed = run_drill(
        world,
        &demo_devices(world, hand, left, right),
        FIDELITY_RUN_S,
    )?;
    let max_force_n = hapticserver::sim_device::sim_device_model().max_force_n;
    let devices = (0..delayed.traces.len())
        .map(|d| {
            let (reference_peak_n, reference_rms_n) = peak_and_rms(&reference.traces[d]);
            let (peak_n, rms_n) = peak_and_rms(&delayed.traces[d]);
            DeviceFidelity {
                reference_peak_n,
                peak_n,
                reference_rms_n,
                rms_n,
                withheld_mj: delayed.passivity_withheld_mj[d],
                clamped: delayed.max_force_n[d] >= max_force_n * 0.999,
                stale_events: delayed.stale_events[d],
                max_step_n: crate::drill::max_force_step(&delayed.traces[d], 0.0, FIDELITY_RUN_S),
            }
        })
        .collect();
    Ok(Fidelity {
        devices,
        delayed,
        reference,
    })
}

/// Mean force magnitude over `from_s..to_s`, N.
pub fn mean_force_n(trace: &[TraceSample], from_s: f64, to_s: f64) -> f32 {
    let window: Vec<f32> = trace
        .iter()
        .filter(|s| s.t_s >= from_s && s.t_s < to_s)
        .map(|s| magnitude(s.force_n))
        .collect();
    window.iter().sum::<f32>() / window.len().max(1) as f32
}

/// Mean force vector over `from_s..to_s`, N.
fn mean_force_vector_n(trace: &[TraceSample], from_s: f64, to_s: f64) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    let mut count = 0usize;
    for s in trace.iter().filter(|s| s.t_s >= from_s && s.t_s < to_s) {
        for (a, f) in sum.iter_mut().zip(s.force_n) {
            *a += f;
        }
        count += 1;
    }
    sum.map(|a| a / count.max(1) as f32)
}

/// When the tug of war's left hand starts and ends its pull, s (the scripts below): right has held for
/// 0.7 s, so its take is over at the server and at its device whatever the round trip.
pub const TUG_PULL_S: (f64, f64) = (2.0, 3.0);
/// Right's force before left's pull reaches it (the window ends before left's take at 1.8 s reaches the
/// server), s.
pub const TUG_BEFORE_S: (f64, f64) = (1.7, 1.8);
/// The tug of war's hold after the pull, before left's jaws open at 5 s, s.
pub const TUG_HOLD_S: (f64, f64) = (4.0, 4.9);
/// Length of a tug-of-war run, s.
pub const TUG_RUN_S: f64 = 5.5;

/// Two graspers on one sheet (`tug_of_war.toml`): both take hold 1.5 mm deep; left then pulls 6 mm outward
/// and 8 mm up over 1 s and holds; right holds where it took hold. What each felt.
#[derive(Debug, Clone)]
pub struct TugOfWar {
    /// How much the force right feels changed from before left's pull to the hold after it, N (the other
    /// surgeon's pull, felt through the tissue).
    pub right_feels_n: f32,
    /// The same for left (its own pull against the sheet and right's grip), N.
    pub left_feels_n: f32,
    /// Per device (left, right): the hold window's stillness.
    pub hold: Vec<crate::drill::HoldMetrics>,
    /// Per device: net energy the rendered force put into the hand over the run, mJ.
    pub energy_out_mj: Vec<f64>,
    /// Per device: energy the passivity controller withheld, mJ.
    pub withheld_mj: Vec<f64>,
    /// Per device: the rendered force reached the device's maximum.
    pub clamped: Vec<bool>,
    /// Per device: silences that reached the device's 50 ms rule.
    pub stale_events: Vec<u64>,
    /// The sheet in the middle of the hold (4.5 s), every node, mm.
    pub sheet_mm: Vec<[f32; 3]>,
    /// Every device tick, per device.
    pub traces: Vec<Vec<TraceSample>>,
}

/// Where each grasper takes hold, world x, mm: left at -6, right at +6, 12 mm apart (on grasp_pull's anchored
/// sheet a pull's response decays within a few mm; tug_of_war.toml's looser sheet carries it across).
pub const TUG_GRASP_X_MM: f32 = 6.0;

/// The tug of war's scripts for `world`'s devices: (left, right), each taking hold at [`TUG_GRASP_X_MM`] either
/// side of the sheet's centre (device frame: the world point less the device's origin).
pub fn tug_scripts(world: &World) -> (HandScript, HandScript) {
    let origin_x_mm = |device: &str| {
        world
            .tools
            .iter()
            .find(|t| t.device_id == device)
            .map_or(0.0, |t| t.device_origin_in_world_mm[0])
    };
    let grasp =
        |at_x_mm: f32, settle_s: f32, pull_mm: [f32; 3], hold_s: f32| HandScript::GraspPull {
            at_mm: [at_x_mm, 0.0, 0.0],
            depth_mm: 1.5,
            approach_mm: 15.0,
            descend_s: 1.0,
            settle_s,
            pull_mm,
            pull_s: 1.0,
            hold_s,
        };
    // Left closes at 1.8 s, pulls from 2 s to 3 s, opens at 5 s; right closes at 1.3 s and holds past the end.
    (
        grasp(
            -TUG_GRASP_X_MM - origin_x_mm("left"),
            0.8,
            [-6.0, 0.0, 8.0],
            2.0,
        ),
        grasp(TUG_GRASP_X_MM - origin_x_mm("right"), 0.3, [0.0; 3], 4.0),
    )
}

/// Run the tug of war on `world` (two graspers, `left` and `right`: `tug_of_war.toml`) with `hand` for both surgeons over `left` and `right` links
/// (`--mode auto`).
pub fn tug_of_war(
    world: &World,
    hand: HandPreset,
    left: Link,
    right: Link,
) -> anyhow::Result<TugOfWar> {
    let (left_script, right_script) = tug_scripts(world);
    let devices =
        [("left", left_script, left), ("right", right_script, right)].map(|(id, script, link)| {
            DrillDevice {
                id: id.into(),
                hand,
                script,
                link,
                mode: ModePolicy::default(),
            }
        });
    let mut tick = 0usize;
    let mut sheet_mm = Vec::new();
    let result = crate::drill::run_drill_observed(world, &devices, TUG_RUN_S, |server, _| {
        tick += 1;
        if tick == 4500 {
            sheet_mm = server
                .positions_mm(0)
                .map(|p| p.iter().map(|v| (*v).into()).collect())
                .unwrap_or_default();
        }
    })?;
    let max_force_n = hapticserver::sim_device::sim_device_model().max_force_n;
    Ok(TugOfWar {
        left_feels_n: tug_felt_n(&result.traces[0]),
        right_feels_n: tug_felt_n(&result.traces[1]),
        hold: result
            .traces
            .iter()
            .map(|t| crate::drill::hold_metrics(t, TUG_HOLD_S.0, TUG_HOLD_S.1))
            .collect(),
        energy_out_mj: result
            .traces
            .iter()
            .map(|t| crate::drill::energy_output_mj(t))
            .collect(),
        withheld_mj: result.passivity_withheld_mj.clone(),
        clamped: result
            .max_force_n
            .iter()
            .map(|&f| f >= max_force_n * 0.999)
            .collect(),
        stale_events: result.stale_events.clone(),
        sheet_mm,
        traces: result.traces,
    })
}

/// What a tug-of-war trace felt of the pull (script time): the change of the mean force vector from
/// [`TUG_BEFORE_S`] to [`TUG_HOLD_S`], N.
pub fn tug_felt_n(trace: &[TraceSample]) -> f32 {
    let before = mean_force_vector_n(trace, TUG_BEFORE_S.0, TUG_BEFORE_S.1);
    let after = mean_force_vector_n(trace, TUG_HOLD_S.0, TUG_HOLD_S.1);
    magnitude(std::array::from_fn(|i| after[i] - before[i]))
}

/// Largest distance between two snapshots of the same sheet, mm.
pub fn sheet_difference_mm(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(p, q)| magnitude(std::array::from_fn(|i| p[i] - q[i])))
        .fold(0.0, f32::max)
}
