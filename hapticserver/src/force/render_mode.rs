//! Which force a device renders: the streamed one (direct) or the local model (latency-moderated), and the
//! switch between them.
//!
//! Owns: [`ModePolicy`] (`--mode direct|moderated|auto`) and [`ModeSwitch`], which follows the policy with
//! the measured round trip and cross-fades between the two forces over [`ModeSwitch::FADE_S`], so a switch
//! never steps the force.
//!
//! `auto` (the default) renders directly while the round trip stays under 2.5 ms and switches to the local
//! model above 4 ms (hysteresis, on a smoothed round trip). On a LAN or loopback the streamed force is the
//! simulation's exact force a millisecond or two late, which a hand cannot tell from immediate; further away a
//! streamed force is felt late and, on stiff contact, goes unstable (passive only while the hand's damping
//! `b > K (T/2 + delay)`), while the local model stays crisp. The band was 10-20 ms until a grasp, the
//! stiffest contact a hand holds (the full 3x3 stiffness of the tissue and the coupling), was measured at
//! 10 ms: streamed, it drove the light and nominal hands to the 3.3 N clamp in grasp_pull
//! (`tests/tests/instrument_fidelity.rs`); the model at 5-10 ms holds them within 3% of zero delay.
//!
//! Must not: evaluate either force (the loop hands both in) or touch safety.

use std::str::FromStr;

/// How the device chooses between the streamed force and the local model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModePolicy {
    /// Always the streamed force.
    Direct,
    /// Always the local model.
    Moderated,
    /// The local model while the smoothed round trip is above `moderate_above_ms`, the streamed force once
    /// it falls below `direct_below_ms`.
    Auto {
        /// Switch to the local model above this round trip, ms.
        moderate_above_ms: f32,
        /// Switch back to the streamed force below this round trip, ms.
        direct_below_ms: f32,
    },
}

impl Default for ModePolicy {
    fn default() -> Self {
        ModePolicy::Auto {
            moderate_above_ms: 4.0,
            direct_below_ms: 2.5,
        }
    }
}

impl ModePolicy {
    /// The command-line name.
    pub fn name(&self) -> &'static str {
        match self {
            ModePolicy::Direct => "direct",
            ModePolicy::Moderated => "moderated",
            ModePolicy::Auto { .. } => "auto",
        }
    }
}

impl FromStr for ModePolicy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "direct" => Ok(ModePolicy::Direct),
            "moderated" => Ok(ModePolicy::Moderated),
            "auto" => Ok(ModePolicy::default()),
            other => Err(format!(
                "unknown mode `{other}`: expected direct, moderated or auto"
            )),
        }
    }
}

/// Follows a [`ModePolicy`] and blends the two forces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModeSwitch {
    policy: ModePolicy,
    moderated: bool,
    /// 0 = all direct, 1 = all local model.
    weight: f32,
    smoothed_rtt_ms: Option<f32>,
    switches: u64,
}

impl ModeSwitch {
    /// Time a switch takes to cross-fade, s.
    pub const FADE_S: f32 = 0.02;
    /// Weight of a new round-trip sample in the smoothed one (about the last 50 samples).
    const RTT_SMOOTHING: f32 = 0.02;

    /// A switch following `policy`, starting in its initial mode (auto starts direct).
    pub fn new(policy: ModePolicy) -> Self {
        let moderated = matches!(policy, ModePolicy::Moderated);
        Self {
            policy,
            moderated,
            weight: if moderated { 1.0 } else { 0.0 },
            smoothed_rtt_ms: None,
            switches: 0,
        }
    }

    /// The policy.
    pub fn policy(&self) -> ModePolicy {
        self.policy
    }

    /// Whether the local model is (becoming) the rendered force.
    pub fn moderated(&self) -> bool {
        self.moderated
    }

    /// Times the mode changed.
    pub fn switches(&self) -> u64 {
        self.switches
    }

    /// The smoothed round trip, ms (None before the first sample).
    pub fn smoothed_rtt_ms(&self) -> Option<f32> {
        self.smoothed_rtt_ms
    }

    /// A measured pose -> force round trip, ms. Under `auto`, may change the mode.
    pub fn observe_round_trip(&mut self, rtt_ms: f32) {
        if !rtt_ms.is_finite() || rtt_ms < 0.0 {
            return;
        }
        let smoothed = match self.smoothed_rtt_ms {
            None => rtt_ms,
            Some(s) => s + Self::RTT_SMOOTHING * (rtt_ms - s),
        };
        self.smoothed_rtt_ms = Some(smoothed);
        if let ModePolicy::Auto {
            moderate_above_ms,
            direct_below_ms,
        } = self.policy
        {
            let want = if self.moderated {
                smoothed >= direct_below_ms
            } else {
                smoothed > moderate_above_ms
            };
            if want != self.moderated {
                self.moderated = want;
                self.switches += 1;
            }
        }
    }

    /// Advance the cross-fade by `dt_s` and blend: `(1 - w) direct + w model`. Never panics.
    pub fn blend(&mut self, dt_s: f32, direct_n: [f32; 3], model_n: [f32; 3]) -> [f32; 3] {
        let target = if self.moderated { 1.0 } else { 0.0 };
        let step = if dt_s.is_finite() && dt_s > 0.0 {
            dt_s / Self::FADE_S
        } else {
            0.0
        };
        self.weight += (target - self.weight).clamp(-step, step);
        let w = self.weight;
        std::array::from_fn(|i| (1.0 - w) * direct_n[i] + w * model_n[i])
    }

    /// The current blend weight of the local model (0..1).
    pub fn weight(&self) -> f32 {
        self.weight
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_switches_with_hysteresis() {
        let mut switch = ModeSwitch::new(ModePolicy::default());
        assert!(!switch.moderated());
        for _ in 0..500 {
            switch.observe_round_trip(3.0);
        }
        assert!(!switch.moderated(), "3 ms is inside the band: stays direct");
        for _ in 0..500 {
            switch.observe_round_trip(100.0);
        }
        assert!(switch.moderated());
        for _ in 0..500 {
            switch.observe_round_trip(3.0);
        }
        assert!(
            switch.moderated(),
            "3 ms is inside the band: stays moderated"
        );
        for _ in 0..500 {
            switch.observe_round_trip(1.0);
        }
        assert!(!switch.moderated());
        assert_eq!(switch.switches(), 2);
    }

    #[test]
    fn a_switch_cross_fades_without_a_step() {
        let mut switch = ModeSwitch::new(ModePolicy::Moderated);
        let direct = [0.0, 0.0, 2.0];
        let model = [0.0, 0.0, 1.0];
        let mut previous = switch.blend(0.001, direct, model);
        assert_eq!(previous, model);
        let mut switch = ModeSwitch {
            moderated: false,
            ..switch
        };
        for _ in 0..40 {
            let out = switch.blend(0.001, direct, model);
            assert!((out[2] - previous[2]).abs() <= 1.0 / 20.0 + 1e-6, "{out:?}");
            previous = out;
        }
        assert_eq!(previous, direct);
    }

    #[test]
    fn policies_parse_by_name() {
        assert_eq!("direct".parse(), Ok(ModePolicy::Direct));
        assert_eq!("moderated".parse(), Ok(ModePolicy::Moderated));
        assert_eq!("auto".parse(), Ok(ModePolicy::default()));
        assert!("fast".parse::<ModePolicy>().unwrap_err().contains("fast"));
    }
}
