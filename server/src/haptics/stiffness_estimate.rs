//! The contact's normal stiffness as the tissue actually answers: a least-squares slope of force on depth.
//!
//! Owns: [`NormalStiffnessEstimate`]. The condensed solve ([`crate::haptics::contact_stiffness`]) gives the
//! stiffness with the set of held nodes frozen; the simulated contact is softer than that (measured on the
//! pad at 5 mm: 0.2 N/mm of slope against 0.7 N/mm from the solve), and a model stiffer than the tissue hands
//! the difference back late, which near a light hand's resonance (about 13 Hz on 0.7 N/mm) acts as negative
//! damping. So the model's normal stiffness is this slope, from the server tool's own recent motion: a
//! weighted least-squares fit of the normal force against the depth along the contact normal, with
//! exponential forgetting ([`NormalStiffnessEstimate::MEMORY_S`]), updated only on ticks where the tool moved
//! along the normal (so a still tool, or one the OTHER surgeon's push moves the tissue under, keeps its
//! estimate instead of fitting the wrong cause), and capped by the solve's value (it never goes above the
//! frozen-contact stiffness). Until the fit has seen [`NormalStiffnessEstimate::MIN_SPAN_MM`] of depth, the
//! solve's value stands.
//!
//! Must not: allocate, or report a negative or non-finite stiffness.

/// The running fit for one tool.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NormalStiffnessEstimate {
    w: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    last_depth_mm: Option<f64>,
    span_lo_mm: f64,
    span_hi_mm: f64,
}

impl NormalStiffnessEstimate {
    /// Samples older than this weigh 1/e, s.
    pub const MEMORY_S: f64 = 0.5;
    /// A tick counts as motion when the depth changed by at least this much, mm.
    pub const MIN_STEP_MM: f64 = 0.002;
    /// The fit is used once its depths span this much, mm.
    pub const MIN_SPAN_MM: f64 = 0.3;

    /// Forget everything (the contact ended).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// One tick of contact: depth along the contact normal (mm, into the tissue) and the normal force (N).
    pub fn record(&mut self, depth_mm: f32, force_n: f32, dt_s: f32) {
        let (x, y) = (f64::from(depth_mm), f64::from(force_n));
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let moved = self
            .last_depth_mm
            .is_none_or(|last| (x - last).abs() >= Self::MIN_STEP_MM);
        if !moved {
            return;
        }
        self.last_depth_mm = Some(x);
        let keep = (-f64::from(dt_s) / Self::MEMORY_S).exp();
        self.w = self.w * keep + 1.0;
        self.sx = self.sx * keep + x;
        self.sy = self.sy * keep + y;
        self.sxx = self.sxx * keep + x * x;
        self.sxy = self.sxy * keep + x * y;
        if self.w <= 1.0 {
            self.span_lo_mm = x;
            self.span_hi_mm = x;
        } else {
            self.span_lo_mm = self.span_lo_mm.min(x);
            self.span_hi_mm = self.span_hi_mm.max(x);
        }
    }

    /// The fitted slope, N/mm, capped at `ceiling_n_per_mm`; None until the depths span enough.
    pub fn stiffness_n_per_mm(&self, ceiling_n_per_mm: f32) -> Option<f32> {
        if self.span_hi_mm - self.span_lo_mm < Self::MIN_SPAN_MM || self.w < 10.0 {
            return None;
        }
        let var = self.sxx / self.w - (self.sx / self.w).powi(2);
        let cov = self.sxy / self.w - self.sx * self.sy / self.w.powi(2);
        if var.is_nan() || var <= 1e-9 {
            return None;
        }
        let slope = (cov / var) as f32;
        slope
            .is_finite()
            .then(|| slope.clamp(0.0, ceiling_n_per_mm.max(0.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_the_slope_of_a_press_and_holds_it_when_still() {
        let mut e = NormalStiffnessEstimate::default();
        for tick in 0..1000 {
            let depth = tick as f32 * 0.005;
            e.record(depth, 0.3 + 0.25 * depth, 0.001);
        }
        let k = e.stiffness_n_per_mm(1.0).unwrap();
        assert!((k - 0.25).abs() < 1e-3, "{k}");
        // Still: the force changes (another surgeon) but the depth does not; the estimate stands.
        for tick in 0..1000 {
            e.record(5.0, 1.55 + (tick as f32 * 0.01).sin(), 0.001);
        }
        assert!((e.stiffness_n_per_mm(1.0).unwrap() - 0.25).abs() < 1e-3);
        assert_eq!(e.stiffness_n_per_mm(0.1), Some(0.1), "capped by the solve");
        e.reset();
        assert_eq!(e.stiffness_n_per_mm(1.0), None);
    }
}
