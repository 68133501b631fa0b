//! The friction coefficient a contact actually shows while the tool slides: the cone a distant device renders.
//!
//! Owns: [`KineticFrictionEstimate`]. The material's Coulomb coefficient caps each held node's tangential
//! pull at `mu` times that node's push, but a tool sliding over a mesh never has every node on its cone: a node
//! entering the contact sticks, its pull builds up as the tool moves on, and it slips only once the pull
//! reaches the cone (the probe's stick anchors). So the friction on the whole tool is a fraction of `mu` times
//! its push: on the pad with `mu = 0.5`, stroked by the nominal hand, 0.14 N of friction against 0.79 N of
//! push (0.18). A device rendering the material's `mu` felt 0.4 N instead: the stroke felt 60% too heavy at
//! 200 ms. So the model's cone is this ratio, measured: an exponential average of `|f_t| / N` over the ticks on
//! which the tool slides along the surface (tangential speed above [`KineticFrictionEstimate::MIN_SLIDE_MM_S`];
//! a still or stuck tool's ratio is only what holds it, not what it takes to slide), never above the
//! material's `mu`. Until the tool has slid there is no estimate and no friction term: the model's `f0` carries
//! the server's friction as it is (one round trip late, as the stick builds up). Starting from the material's
//! `mu` instead made the first stroke's start 0.43 N heavy against 0.18-0.30 N for a round trip (the peak
//! 10% over at 200 ms). It is kept while the tool stays active (the same tool on the same tissue slides the
//! same way on the next touch) and forgotten when the tool is released.
//!
//! Must not: allocate, or report a coefficient outside `0..=mu`.

use crate::tissue::Vec3;

/// The running estimate for one tool.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KineticFrictionEstimate {
    ratio: Option<f32>,
}

impl KineticFrictionEstimate {
    /// A tick counts as sliding above this tangential speed of the tool, mm/s.
    pub const MIN_SLIDE_MM_S: f32 = 2.0;
    /// Time constant of the average, s.
    pub const TIME_CONSTANT_S: f32 = 0.1;

    /// Forget everything (the tool was released).
    pub fn reset(&mut self) {
        self.ratio = None;
    }

    /// One tick of contact: the friction along the surface `friction_n` (N), the push along the contact
    /// normal `push_n` (N, > 0 to count), the tool's velocity `velocity_mm_s` and the contact normal `normal`
    /// (unit), over `dt_s`. Non-finite input is ignored.
    pub fn record(
        &mut self,
        friction_n: &Vec3,
        push_n: f32,
        velocity_mm_s: &Vec3,
        normal: &Vec3,
        dt_s: f32,
    ) {
        let tangential = velocity_mm_s - normal * normal.dot(velocity_mm_s);
        let speed = tangential.norm();
        let ratio = friction_n.norm() / push_n;
        if !(push_n > 0.0
            && push_n.is_finite()
            && ratio.is_finite()
            && speed.is_finite()
            && speed >= Self::MIN_SLIDE_MM_S
            && dt_s.is_finite()
            && dt_s > 0.0)
        {
            return;
        }
        let keep = (-dt_s / Self::TIME_CONSTANT_S).exp();
        self.ratio = Some(match self.ratio {
            Some(previous) => previous * keep + ratio * (1.0 - keep),
            None => ratio,
        });
    }

    /// The coefficient to render for a material of Coulomb coefficient `material_mu`: the measured sliding
    /// ratio, at most `material_mu`; zero (no friction term) until the tool has slid, and for a non-finite or
    /// non-positive `material_mu`.
    pub fn coefficient(&self, material_mu: f32) -> f32 {
        if !(material_mu.is_finite() && material_mu > 0.0) {
            return 0.0;
        }
        self.ratio.map_or(0.0, |r| r.clamp(0.0, material_mu))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sliding_ratio_is_averaged_capped_and_kept_while_still() {
        let mut estimate = KineticFrictionEstimate::default();
        let up = Vec3::z();
        assert_eq!(estimate.coefficient(0.5), 0.0);
        // Still (0.1 mm/s): not counted.
        estimate.record(
            &Vec3::new(0.1, 0.0, 0.0),
            1.0,
            &Vec3::new(0.1, 0.0, 0.0),
            &up,
            0.001,
        );
        assert_eq!(estimate.coefficient(0.5), 0.0);
        // Sliding at 10 mm/s with 0.2 N on 1 N: 0.2 at once, then averaged.
        estimate.record(
            &Vec3::new(-0.2, 0.0, 0.0),
            1.0,
            &Vec3::new(10.0, 0.0, 0.0),
            &up,
            0.001,
        );
        assert!((estimate.coefficient(0.5) - 0.2).abs() < 1e-6);
        for _ in 0..1000 {
            estimate.record(
                &Vec3::new(-0.3, 0.0, 0.0),
                1.0,
                &Vec3::new(10.0, 0.0, 0.0),
                &up,
                0.001,
            );
        }
        assert!((estimate.coefficient(0.5) - 0.3).abs() < 1e-3);
        // Moving along the normal only is not sliding; a stuck tool's small ratio is not recorded.
        estimate.record(&Vec3::zeros(), 1.0, &Vec3::new(0.0, 0.0, -50.0), &up, 0.001);
        assert!((estimate.coefficient(0.5) - 0.3).abs() < 1e-3);
        // Never above the material's coefficient.
        assert!((estimate.coefficient(0.25) - 0.25).abs() < 1e-6);
        estimate.reset();
        assert_eq!(estimate.coefficient(0.5), 0.0);
    }

    #[test]
    fn bad_input_changes_nothing() {
        let mut estimate = KineticFrictionEstimate::default();
        let up = Vec3::z();
        let slide = Vec3::new(10.0, 0.0, 0.0);
        estimate.record(&Vec3::new(-0.2, 0.0, 0.0), 1.0, &slide, &up, 0.001);
        for (f, push, dt) in [
            (Vec3::new(f32::NAN, 0.0, 0.0), 1.0, 0.001),
            (Vec3::new(-0.2, 0.0, 0.0), 0.0, 0.001),
            (Vec3::new(-0.2, 0.0, 0.0), f32::INFINITY, 0.001),
            (Vec3::new(-0.2, 0.0, 0.0), 1.0, f32::NAN),
        ] {
            estimate.record(&f, push, &slide, &up, dt);
            assert!((estimate.coefficient(0.5) - 0.2).abs() < 1e-6);
        }
        assert_eq!(estimate.coefficient(f32::NAN), 0.0);
        assert_eq!(estimate.coefficient(-1.0), 0.0);
    }
}
