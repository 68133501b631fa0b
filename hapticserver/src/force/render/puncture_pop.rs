//! The pop of a needle's puncture, made at the device: a model whose needle tip presses a surface
//! ([`PunctureTerm`]) is rendered as its tissue tents until the device's own rendered push back along the tip
//! passes the term's threshold; from that tick on the device renders the model as it is after the puncture
//! ([`PunctureTerm::after`]), without waiting a round trip for the server's needle to get there.
//!
//! Owns: [`PopLatch`] (which press this device has popped, and when, in the server's time). Models of that
//! press the server built before its own needle punctured keep arriving for a round trip; they are rendered as
//! their after-variant too. If the server's models still show the same press [`POP_LATCH_S`] of server time
//! after the model the device popped on, the server's needle never punctured (its tool stopped short of where
//! the hand went): the latch lets go and the server's models are rendered as they are (blended in like any
//! model).
//!
//! The pop itself is not blended: the tissue giving way is a step in the force at zero delay too (the safety
//! layer's rate limit shapes both alike).
//!
//! Must not: read the clock, allocate, or panic.

use sinew_protocol::{LocalModel, PunctureTerm};

/// How long, in the server's time after the model a device popped on, models of the same press are rendered
/// as punctured, s: longer than any round trip the moderated mode is meant for (200 ms) plus the deadband's
/// heartbeat, so the server's own puncture is seen before the latch lets go.
pub const POP_LATCH_S: f64 = 0.5;

/// The press a device popped on its own (module doc).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PopLatch {
    /// The press popped (0: none).
    press: u32,
    /// The server time of the model it popped on, ns.
    server_time_ns: u64,
    /// Pops made here since start.
    pops: u32,
}

impl PopLatch {
    /// Pops made at this device since it started.
    pub fn pops(&self) -> u32 {
        self.pops
    }

    /// Whether `model`'s press was popped here and the latch still holds for it.
    fn holds(&self, model: &LocalModel) -> bool {
        let term = &model.puncture;
        term.is_active()
            && term.press == self.press
            && model.server_time_ns.saturating_sub(self.server_time_ns)
                <= (POP_LATCH_S * 1e9) as u64
    }

    /// The model to render for `model`: its after-variant when its press was popped here, else itself.
    pub fn view(&self, model: &LocalModel) -> LocalModel {
        if self.holds(model) {
            model.puncture.after(model)
        } else {
            *model
        }
    }

    /// With `model` rendered (not yet popped), its linear part giving `linear_n` (N) at the device this tick,
    /// and the device's turn since the model adding `rolled_n` (N, [`PunctureTerm::rolled_push_n`]) to the
    /// tip's push: whether the tip punctures now. If so the latch takes the press, and the caller renders
    /// [`PopLatch::view`] of the model from now on.
    pub fn watch(&mut self, model: &LocalModel, linear_n: [f32; 3], rolled_n: f32) -> bool {
        let term: &PunctureTerm = &model.puncture;
        if !term.is_active() || self.holds(model) {
            return false;
        }
        let rolled_n = if rolled_n.is_finite() { rolled_n } else { 0.0 };
        let push_back_n = term.push_back_n(linear_n) + rolled_n;
        if push_back_n.is_finite() && push_back_n >= term.pop_at_n {
            self.press = term.press;
            self.server_time_ns = model.server_time_ns;
            self.pops = self.pops.saturating_add(1);
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pressing(press: u32, server_time_ns: u64) -> LocalModel {
        LocalModel {
            server_time_ns,
            in_contact: true,
            f0_n: [0.0, 0.0, 2.0],
            stiffness_n_per_mm: [0.2, 0.2, 1.0, 0.0, 0.0, 0.0],
            radius_mm: 5.0,
            fade_mm: 1.0,
            attached: true,
            puncture: PunctureTerm {
                press,
                pop_at_n: 2.5,
                tip_axis: [0.0, 0.0, -1.0],
                f0_after_n: [0.0, 0.0, 0.1],
                stiffness_after_n_per_mm: [0.2, 0.2, 0.0, 0.0, 0.0, 0.0],
                drag_after_n: 0.15,
                tip_lever_mm: [0.0, 0.0, -10.0],
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
            ..LocalModel::default()
        }
    }

    #[test]
    fn it_pops_at_the_threshold_and_not_below_it() {
        let mut latch = PopLatch::default();
        let model = pressing(1, 0);
        assert!(!latch.watch(&model, [0.0, 0.0, 2.49], 0.0));
        assert_eq!(latch.view(&model), model);
        assert!(latch.watch(&model, [0.0, 0.0, 2.5], 0.0));
        assert_eq!(latch.pops(), 1);
        let after = latch.view(&model);
        assert_eq!(after.f0_n, [0.0, 0.0, 0.1]);
        assert!(!after.puncture.is_active());
        // The same press does not pop twice.
        assert!(!latch.watch(&model, [0.0, 0.0, 9.0], 0.0));
        assert_eq!(latch.pops(), 1);
    }

    #[test]
    fn late_models_of_a_popped_press_are_rendered_punctured_until_the_latch_lets_go() {
        let mut latch = PopLatch::default();
        assert!(latch.watch(&pressing(4, 1_000_000_000), [0.0, 0.0, 3.0], 0.0));
        // A round trip's worth of models the server built while its needle still pressed.
        let late = pressing(4, 1_200_000_000);
        assert!(!latch.view(&late).puncture.is_active());
        // Another press is its own.
        let next = pressing(5, 1_200_000_000);
        assert_eq!(latch.view(&next), next);
        // The server never punctured: half a second on, its model is rendered as it is, and may pop again.
        let stale = pressing(4, 1_000_000_000 + (POP_LATCH_S * 1e9) as u64 + 1);
        assert_eq!(latch.view(&stale), stale);
        assert!(latch.watch(&stale, [0.0, 0.0, 3.0], 0.0));
        assert_eq!(latch.pops(), 2);
    }

    #[test]
    fn a_force_pulling_away_or_not_finite_never_pops() {
        let mut latch = PopLatch::default();
        let model = pressing(1, 0);
        assert!(!latch.watch(&model, [0.0, 0.0, -5.0], 0.0));
        assert!(!latch.watch(&model, [0.0, 0.0, f32::NAN], 0.0));
        assert!(!latch.watch(&LocalModel::default(), [0.0, 0.0, 9.0], 0.0));
        assert_eq!(latch.pops(), 0);
    }
}
