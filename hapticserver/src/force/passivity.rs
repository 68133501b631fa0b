//! Time-domain passivity observer and a smooth passivity controller (after Hannaford and Ryu, 2002).
//!
//! Owns: the energy account of the device port and the one correction it may make. The observer integrates
//! the energy the rendered force puts into the hand, `E -= F . v dt` (N mm = mJ): a passive environment (tissue
//! springs, dampers) only gives back what the hand stored in it, so `E` stays >= 0; a delayed or otherwise
//! active loop drives it negative.
//!
//! The controller is a variable damper on the hand's motion away from the tissue (its speed along the force,
//! `v_out >= 0`): it removes `alpha v_out` from the force's magnitude, never more than the force. While the
//! account shows a deficit, `alpha` aims at the damping that pays it back within [`PAYBACK_S`]
//! (`deficit / (v_out^2 PAYBACK_S)`, at most [`MAX_DAMPING_N_S_PER_MM`]); otherwise it aims at zero. It moves
//! towards that aim by at most [`MAX_DAMPING_STEP_N`] of force a tick. Hannaford and Ryu's controller pays the
//! whole deficit back on the tick it appears: where a hand rests with its account near zero, every slight
//! outward twitch then removes the whole force, a square wave of up to the safety rate limit (0.2 N a tick,
//! measured on taps at 100 ms). A damper that ramps cannot step, and a damper that only resists outward motion
//! is passive in itself (the classic alternative, scaling the force down and letting it recover, is not: a
//! force that recovers while the hand moves in stores energy the hand never put in, and it drove the stiff pad
//! into a 10 Hz limit cycle even at 10 ms). The price is a bounded lag: a proportional controller settles
//! where the deficit sizes the damping it needs, `deficit = alpha v_out^2 PAYBACK_S` (0.14 mJ for a
//! 0.01 N s/mm active element at 38 mm/s).
//!
//! The controller only ever removes a component of the force it is given: it never adds force, never exceeds
//! the safety filter's output, and zero in gives zero out (the ramp-to-zero guarantee is untouched).
//!
//! A per-port controller alone cannot tell a delayed, active loop from energy that legitimately flows between
//! two surgeons through the tissue (one yields to the other's pull): it would delete exactly that shared feel.
//! So the controller takes an allowance: the energy the server's budget (`sinew_server::haptics::
//! energy_budget`) says the OTHER ports put into the shared tissue, and acts only when `E + allowance < 0`.
//! In latency-moderated mode the controller is on with that allowance; in direct mode it is opt-in
//! ([`PassivityMode::Control`], `--passivity control`) and the default only observes.
//! Must not: clamp, rate-limit or handle staleness (that is [`crate::safety`]). Real-time contract: no
//! allocation, never panics, never returns a non-finite value.

/// Stored energy is capped here (mJ), so long stretches of dissipation cannot be banked to excuse later
/// activity; far above what the pad's springs store at the device's maximum force (~55 mJ at 3.3 N).
pub const ENERGY_RESERVE_CAP_MJ: f64 = 100.0;

/// The controller aims to pay a deficit back within this time, s.
pub const PAYBACK_S: f64 = 0.01;
/// Speeds below this count as this when sizing the damping, mm/s (a hand at rest needs no damping to speak of).
pub const PAYBACK_SPEED_FLOOR_MM_S: f64 = 5.0;
/// The controller's damping never exceeds this, N s/mm (100 N s/m: about seven times a firm hand's own).
pub const MAX_DAMPING_N_S_PER_MM: f64 = 0.1;
/// Changing the damping changes the force by at most this much a tick, N: well under what a hand feels as a tap.
pub const MAX_DAMPING_STEP_N: f64 = 0.04;

/// Whether the controller may correct forces.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum PassivityMode {
    /// Account and report the port's energy; never change a force.
    #[default]
    Observe,
    /// Also remove force while the port is active.
    Control,
}

/// What the controller has done.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PassivityCounters {
    /// Ticks on which the port was active (in Control mode, force was removed on each of them).
    pub active_ticks: u64,
    /// Energy it withheld from the hand, mJ.
    pub withheld_mj: f64,
    /// Current observed energy, mJ (negative: the loop has injected energy not yet paid back).
    pub energy_mj: f64,
    /// The controller's damping of outward motion now, N s/mm (0 when the port is passive).
    pub damping_n_s_per_mm: f64,
}

/// The observer/controller of one device port.
#[derive(Debug, Clone, Default)]
pub struct Passivity {
    mode: PassivityMode,
    energy_mj: f64,
    /// The controller's damping of outward motion now, N s/mm.
    damping_n_s_per_mm: f64,
    counters: PassivityCounters,
}

fn dot3(a: &[f32; 3], b: &[f32; 3]) -> f64 {
    (0..3).map(|i| f64::from(a[i]) * f64::from(b[i])).sum()
}

impl Passivity {
    /// A fresh account (E = 0).
    pub fn new(mode: PassivityMode) -> Self {
        Self {
            mode,
            ..Self::default()
        }
    }

    /// Observed ticks on which the port was active (energy below zero while the force did work on the hand)
    /// count as `active_ticks` in both modes; only [`PassivityMode::Control`] corrects them.
    pub fn mode(&self) -> PassivityMode {
        self.mode
    }

    /// Observe and, if needed, correct the force about to be rendered while the stylus moves at
    /// `velocity_mm_s`, over a tick of `dt_s`. Returns the force to render (|out| <= |force_n|).
    pub fn apply(&mut self, force_n: [f32; 3], velocity_mm_s: [f32; 3], dt_s: f32) -> [f32; 3] {
        self.apply_with_allowance(force_n, velocity_mm_s, dt_s, 0.0)
    }

    /// Switch between observing and controlling, keeping the energy account.
    pub fn set_mode(&mut self, mode: PassivityMode) {
        self.mode = mode;
    }

    /// [`Passivity::apply`] where the port may also output `allowance_mj` (>= 0; non-finite or negative
    /// counts as 0) that other ports legitimately put into the shared tissue: the controller acts only while
    /// `E + allowance < 0`.
    pub fn apply_with_allowance(
        &mut self,
        force_n: [f32; 3],
        velocity_mm_s: [f32; 3],
        dt_s: f32,
        allowance_mj: f64,
    ) -> [f32; 3] {
        let allowance_mj = if allowance_mj.is_finite() {
            allowance_mj.max(0.0)
        } else {
            0.0
        };
        let finite = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
        if !(finite(&force_n) && finite(&velocity_mm_s) && dt_s.is_finite() && dt_s > 0.0) {
            // Nothing trustworthy to observe: pass the (already safety-filtered) force, or zero if non-finite.
            return if finite(&force_n) { force_n } else { [0.0; 3] };
        }
        let dt = f64::from(dt_s);
        let force_mag_n = dot3(&force_n, &force_n).sqrt();
        // The hand's speed away from the tissue, along the force (mm/s, >= 0): what the damper acts on.
        let outward_mm_s = if force_mag_n > 0.0 {
            (dot3(&force_n, &velocity_mm_s) / force_mag_n).max(0.0)
        } else {
            0.0
        };
        let deficit_mj = -(self.energy_mj + allowance_mj);
        let active = deficit_mj > 0.0 && outward_mm_s > 0.0;
        if active {
            self.counters.active_ticks += 1;
        }
        let mut out = force_n;
        if self.mode == PassivityMode::Control {
            // The damping that would pay the deficit back over PAYBACK_S at this speed, within its bounds.
            let target = if deficit_mj > 0.0 {
                let speed = outward_mm_s.max(PAYBACK_SPEED_FLOOR_MM_S);
                (deficit_mj / (speed * speed * PAYBACK_S)).min(MAX_DAMPING_N_S_PER_MM)
            } else {
                0.0
            };
            // Changing the damping by d changes the force by d * speed: bounded per tick.
            let max_change = MAX_DAMPING_STEP_N / outward_mm_s.max(1.0);
            self.damping_n_s_per_mm +=
                (target - self.damping_n_s_per_mm).clamp(-max_change, max_change);
            let removed_n = (self.damping_n_s_per_mm * outward_mm_s).min(force_mag_n);
            if removed_n > 0.0 {
                let keep = 1.0 - removed_n / force_mag_n;
                out = force_n.map(|c| (f64::from(c) * keep) as f32);
                self.counters.withheld_mj += removed_n * outward_mm_s * dt;
            }
        }
        self.counters.damping_n_s_per_mm = self.damping_n_s_per_mm;
        self.energy_mj =
            (self.energy_mj - dot3(&out, &velocity_mm_s) * dt).min(ENERGY_RESERVE_CAP_MJ);
        self.counters.energy_mj = self.energy_mj;
        if finite(&out) { out } else { [0.0; 3] }
    }

    /// Counters for reports.
    pub fn counters(&self) -> PassivityCounters {
        self.counters
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f32 = 0.001;

    fn norm(v: [f32; 3]) -> f32 {
        v.iter().map(|c| c * c).sum::<f32>().sqrt()
    }

    /// A hand oscillating along z through a wall at z = 0 rendered by `force(z, v, t)`; returns the energy the
    /// rendered forces put into the hand over the run (mJ) and the controller.
    fn run(force: impl FnMut(f32, f32, usize) -> f32, with_controller: bool) -> (f64, Passivity) {
        run_for(20_000, force, with_controller)
    }

    fn run_for(
        ticks: usize,
        mut force: impl FnMut(f32, f32, usize) -> f32,
        with_controller: bool,
    ) -> (f64, Passivity) {
        let mut pc = Passivity::new(PassivityMode::Control);
        let mut injected = 0.0;
        let (mut last_f, mut last_v, mut last_removed) = (0.0f32, 0.0f32, 0.0f32);
        for k in 0..ticks {
            let t = k as f32 * DT;
            // Starts on the wall surface moving out (nothing stored, matching the empty account), then dips
            // 3 mm into the wall every 0.5 s.
            let z = 3.0 * (std::f32::consts::TAU * 2.0 * t).sin();
            let v = 3.0 * std::f32::consts::TAU * 2.0 * (std::f32::consts::TAU * 2.0 * t).cos();
            let f = [0.0, 0.0, force(z, v, k)];
            let out = if with_controller {
                pc.apply(f, [0.0, 0.0, v], DT)
            } else {
                f
            };
            assert!(norm(out) <= norm(f) + 1e-6, "the controller added force");
            // What the controller removes changes by at most MAX_DAMPING_STEP_N a tick, plus what its damping
            // and its cap (the force itself) follow from the hand's and the force's own change: it never taps
            // the hand.
            let removed = f[2] - out[2];
            let bound = MAX_DAMPING_STEP_N as f32
                + MAX_DAMPING_N_S_PER_MM as f32 * (v - last_v).abs()
                + (f[2] - last_f).abs()
                + 1e-4;
            assert!(
                (removed - last_removed).abs() <= bound,
                "tick {k}: the removed force stepped {} N (bound {bound})",
                removed - last_removed
            );
            (last_f, last_v, last_removed) = (f[2], v, removed);
            injected += f64::from(out[2]) * f64::from(v) * f64::from(DT);
        }
        (injected, pc)
    }

    #[test]
    fn a_passive_spring_is_barely_touched() {
        // Each dip stores 0.9 mJ and gives it back; only the sampled wall's slight activity may be trimmed.
        let (injected, pc) = run(|z, _, _| (-0.2 * z).max(0.0), true);
        assert!(
            pc.counters().withheld_mj < 0.01 * 0.9 * 40.0,
            "withheld {:?}",
            pc.counters()
        );
        assert!(
            injected.abs() < 0.5,
            "a spring gives back what it stores: {injected} mJ"
        );
    }

    #[test]
    fn observe_mode_reports_but_never_changes_a_force() {
        let mut pc = Passivity::new(PassivityMode::Observe);
        for _ in 0..1000 {
            // A force pushing the hand along its motion: active.
            assert_eq!(
                pc.apply([0.0, 0.0, 1.0], [0.0, 0.0, 10.0], DT),
                [0.0, 0.0, 1.0]
            );
        }
        assert!(pc.counters().active_ticks > 900);
        assert!(pc.counters().energy_mj < -9.0);
        assert_eq!(pc.counters().withheld_mj, 0.0);
    }

    #[test]
    fn a_delayed_spring_injects_energy_and_the_controller_takes_it_back() {
        // The same wall seen 30 ms late: the classic active, destabilising loop.
        let delay = 30;
        let mut history = vec![0.0f32; 20_000];
        let delayed = |z: f32, _: f32, k: usize, history: &mut Vec<f32>| {
            history[k] = z;
            (-0.2 * history[k.saturating_sub(delay)]).max(0.0)
        };
        let mut h1 = history.clone();
        let (open_loop, _) = run(|z, v, k| delayed(z, v, k, &mut h1), false);
        assert!(
            open_loop > 5.0,
            "the delayed wall should inject energy: {open_loop} mJ"
        );
        let (controlled, pc) = run(|z, v, k| delayed(z, v, k, &mut history), true);
        assert!(pc.counters().active_ticks > 0);
        assert!(
            controlled < 0.5,
            "net energy into the hand with the controller: {controlled} mJ"
        );
    }

    #[test]
    fn negative_damping_is_cancelled_and_zero_stays_zero() {
        // The controller is proportional: it settles where the deficit sizes exactly the damping that cancels
        // the -0.01 N s/mm, deficit = 0.01 v^2 PAYBACK_S (0.14 mJ at this hand's 38 mm/s peak), and holds there:
        // a bounded leak that does not grow with time.
        let (injected_10_s, _) = run_for(10_000, |_, v, _| 0.01 * v, true);
        let (injected, pc) = run(|_, v, _| 0.01 * v, true);
        let open_loop: f64 = run(|_, v, _| 0.01 * v, false).0;
        assert!(open_loop > 2.0, "{open_loop}");
        assert!(injected < 0.2, "{injected}");
        assert!(
            (injected - injected_10_s).abs() < 0.01,
            "{injected_10_s} -> {injected}"
        );
        assert!(pc.counters().withheld_mj > 0.0);
        let mut pc = Passivity::new(PassivityMode::Control);
        for _ in 0..100 {
            assert_eq!(pc.apply([0.0; 3], [0.0, 0.0, 50.0], DT), [0.0; 3]);
        }
    }

    #[test]
    fn an_allowance_lets_the_other_ports_energy_through_and_no_more() {
        // A force pushing the hand along its motion outputs 1 N x 10 mm/s x 1 ms = 0.01 mJ a tick.
        let mut granted = Passivity::new(PassivityMode::Control);
        let mut passed = 0.0;
        for _ in 0..1000 {
            let out = granted.apply_with_allowance([0.0, 0.0, 1.0], [0.0, 0.0, 10.0], DT, 5.0);
            passed += f64::from(out[2]) * 10.0 * f64::from(DT);
        }
        // 5 mJ granted: the first 500 ticks pass whole, then the controller's damping ramps up (0.04 N a tick)
        // and holds the port at E = -5 mJ; the ramp lets through at most 25 ticks x 0.01 mJ more.
        assert!(passed > 5.0 && passed < 5.25, "passed {passed} mJ");
        let mut denied = Passivity::new(PassivityMode::Control);
        let mut passed = 0.0;
        let mut out = [1.0; 3];
        for _ in 0..100 {
            out = denied.apply_with_allowance([0.0, 0.0, 1.0], [0.0, 0.0, 10.0], DT, f64::NAN);
            passed += f64::from(out[2]) * 10.0 * f64::from(DT);
        }
        assert_eq!(out, [0.0; 3], "no allowance: the active force is removed");
        assert!(
            passed < 0.25,
            "passed {passed} mJ while the damping ramped up"
        );
    }

    #[test]
    fn non_finite_inputs_never_produce_non_finite_output() {
        let mut pc = Passivity::new(PassivityMode::Control);
        assert_eq!(pc.apply([f32::NAN, 0.0, 1.0], [0.0; 3], DT), [0.0; 3]);
        assert_eq!(
            pc.apply([0.0, 0.0, 1.0], [f32::NAN, 0.0, 0.0], DT),
            [0.0, 0.0, 1.0]
        );
        assert_eq!(
            pc.apply([0.0, 0.0, 1.0], [0.0; 3], f32::NAN),
            [0.0, 0.0, 1.0]
        );
        assert!(pc.counters().energy_mj.is_finite());
    }
}
