//! The limits of [`ForceSafety`](super::ForceSafety): [`SafetyConfig`], its defaults, how it follows a
//! device's limits (tightened, never loosened), and its domain ([`SafetyConfigError`]).
//!
//! Must not: filter a force (that is the parent's [`ForceSafety`](super::ForceSafety)), or loosen a device's
//! limits.

use thiserror::Error;

use crate::device::DeviceModel;

/// A [`SafetyConfig`] value out of its domain.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("safety config {field} = {value} is invalid: {reason}")]
pub struct SafetyConfigError {
    /// The field.
    pub field: &'static str,
    /// The value given.
    pub value: f64,
    /// Why.
    pub reason: &'static str,
}

/// Limits applied by [`ForceSafety`](super::ForceSafety).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyConfig {
    /// Largest force magnitude rendered, N (the device maximum, or lower).
    pub max_force_n: f32,
    /// Largest change of the force vector per second, N/s (norm of the per-tick change / dt).
    pub max_force_rate_n_per_s: f32,
    /// A command older than this is stale, s.
    pub stale_after_s: f64,
    /// Once stale, the force falls linearly to exactly zero within this time, s (0 = at once).
    pub ramp_to_zero_s: f64,
    /// When commands arrive again after a silence of at least `ramp_in_after_s` (a rejoin: the server was
    /// restarted, or a partition outlasted the pose timeout) or for the first time, the force is scaled by a gain
    /// that rises linearly from 0 to 1 over this time, s (0 = at once). While the device was silent its hand
    /// kept pressing where the tissue no longer pushed back; a returning force at full gain would throw it back
    /// out (a 30% overshoot and 125 mm/s after a server restart); ramped in, the hand settles on the way.
    pub ramp_in_s: f64,
    /// The shortest silence after which the force ramps in, s. A shorter one (a few lost or late messages) ends
    /// with the force back through the rate limit alone: a hand resting on the tissue must not lose its support
    /// for `ramp_in_s` because a network hiccup passed the silence rule.
    pub ramp_in_after_s: f64,
}

impl SafetyConfig {
    /// Default force-rate limit, N/s.
    pub const DEFAULT_MAX_FORCE_RATE_N_PER_S: f32 = 200.0;
    /// Default staleness threshold, s.
    pub const DEFAULT_STALE_AFTER_S: f64 = 0.050;
    /// Default ramp-to-zero time, s.
    pub const DEFAULT_RAMP_TO_ZERO_S: f64 = 0.020;
    /// Default ramp-in time after a silence, s: several periods of a hand's contact resonance (5-15 Hz), short
    /// enough that a surgeon who rejoins feels the tissue within a third of a second.
    pub const DEFAULT_RAMP_IN_S: f64 = 0.300;
    /// Default shortest silence that ramps in, s: longer than the server's default pose timeout (0.1 s), after
    /// which its tool was released and re-enters from outside the tissue.
    pub const DEFAULT_RAMP_IN_AFTER_S: f64 = 0.250;

    /// Defaults with the given maximum force.
    pub fn new(max_force_n: f32) -> Self {
        Self {
            max_force_n,
            max_force_rate_n_per_s: Self::DEFAULT_MAX_FORCE_RATE_N_PER_S,
            stale_after_s: Self::DEFAULT_STALE_AFTER_S,
            ramp_to_zero_s: Self::DEFAULT_RAMP_TO_ZERO_S,
            ramp_in_s: Self::DEFAULT_RAMP_IN_S,
            ramp_in_after_s: Self::DEFAULT_RAMP_IN_AFTER_S,
        }
    }

    /// Defaults for a device: its maximum force, and the smaller of its rate limit and the default.
    pub fn for_device(model: &DeviceModel) -> Self {
        let mut config = Self::new(model.max_force_n);
        if model.max_force_rate_n_per_s.is_finite() && model.max_force_rate_n_per_s > 0.0 {
            config.max_force_rate_n_per_s = config
                .max_force_rate_n_per_s
                .min(model.max_force_rate_n_per_s);
        }
        config
    }

    /// This config tightened to a device's limits (never loosened).
    pub fn limited_to(mut self, model: &DeviceModel) -> Self {
        let device = Self::for_device(model);
        self.max_force_n = self.max_force_n.min(device.max_force_n);
        self.max_force_rate_n_per_s = self
            .max_force_rate_n_per_s
            .min(device.max_force_rate_n_per_s);
        self
    }

    /// Check every field.
    pub fn validate(&self) -> Result<(), SafetyConfigError> {
        let checks = [
            (
                "max_force_n",
                f64::from(self.max_force_n),
                self.max_force_n > 0.0,
                "must be > 0",
            ),
            (
                "max_force_rate_n_per_s",
                f64::from(self.max_force_rate_n_per_s),
                self.max_force_rate_n_per_s > 0.0,
                "must be > 0",
            ),
            (
                "stale_after_s",
                self.stale_after_s,
                self.stale_after_s >= 0.0,
                "must be >= 0",
            ),
            (
                "ramp_to_zero_s",
                self.ramp_to_zero_s,
                self.ramp_to_zero_s >= 0.0,
                "must be >= 0",
            ),
            (
                "ramp_in_s",
                self.ramp_in_s,
                (0.0..=5.0).contains(&self.ramp_in_s),
                "must be in [0, 5] s",
            ),
            (
                "ramp_in_after_s",
                self.ramp_in_after_s,
                self.ramp_in_after_s >= 0.0,
                "must be >= 0",
            ),
        ];
        for (field, value, ok, reason) in checks {
            if !(ok && value.is_finite()) {
                return Err(SafetyConfigError {
                    field,
                    value,
                    reason,
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::safety::ForceSafety;

    #[test]
    fn bad_configs_are_refused() {
        for config in [
            SafetyConfig::new(0.0),
            SafetyConfig::new(f32::NAN),
            SafetyConfig {
                stale_after_s: -1.0,
                ..SafetyConfig::new(1.0)
            },
            SafetyConfig {
                max_force_rate_n_per_s: f32::INFINITY,
                ..SafetyConfig::new(1.0)
            },
            SafetyConfig {
                ramp_in_s: -0.1,
                ..SafetyConfig::new(1.0)
            },
            SafetyConfig {
                ramp_in_s: f64::NAN,
                ..SafetyConfig::new(1.0)
            },
        ] {
            assert!(ForceSafety::new(config).is_err(), "{config:?} accepted");
        }
    }
}
