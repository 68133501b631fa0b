//! The drag of cutting rendered at the device: the sawtooth of the facets a blade's edge cuts, made from the
//! device's own travel.
//!
//! Owns: [`CutTexture`], the cutting drag's state (how recently the device "cut a facet", how far it travelled
//! since). The server's scalpel feels `R` (the tissue's cutting resistance) as its edge cuts each facet of the
//! mesh, decaying with [`CUT_DRAG_TAU_S`] until it cuts the next; at 20 mm/s across a 1 mm mesh that is a
//! sawtooth between 0.15 and 0.09 N. A model carried only its mean, so a distant hand felt a flat 0.12 N:
//! the mean right, the peaks 20% low, and a cut without its texture. With the edge's spacing between facets
//! ([`LocalModel::cut_facet_mm`]), the device makes the same law against its own motion: a facet every
//! `cut_facet_mm` of travel, the drag `R * level` with `level` rising to 1 at each (over [`CUT_RISE_S`], so
//! the force has no step) and decaying with `CUT_DRAG_TAU_S` between. The facets fall where the hand's
//! travel puts them, not where the server's did: the texture's phase is the device's, its size and rate the
//! tissue's. Without a spacing (`cut_facet_mm` 0) the drag is `cut_drag_n` throughout, as before.
//!
//! Passive: the drag is always against the motion (`-R level v / sqrt(|v|^2 + v_s^2)`), so it only takes
//! energy out of the hand.
//!
//! Must not: read the clock (time is passed in), allocate, or panic.

use sinew_protocol::{CUT_DRAG_TAU_S, LocalModel};

use super::local_model::cut_drag_force_n;
use super::{all_finite, dot3};

/// How long a facet's drag takes to rise to its full size, s: five ticks at 1 kHz, so a facet's rise is a
/// ramp of at most a fifth of the drag a tick instead of a step.
pub const CUT_RISE_S: f32 = 0.005;

/// Longest time step the texture integrates at once, s: a stalled loop or a clock that jumps does not fire a
/// run of facets.
const MAX_STEP_S: f64 = 0.01;

/// The state of the cutting drag at the device.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CutTexture {
    /// The drag's size relative to the model's `cut_drag_n`, 0..=1.
    level: f32,
    /// Where the level rises to: 1 from a facet until it is reached, then 0 (the decay).
    rising: bool,
    /// Travel since the last facet, mm.
    travel_mm: f32,
    /// The spacing to the next facet, mm: the model's `cut_facet_mm` when the last facet was cut. Latched, so a
    /// model arriving mid-interval with a new spacing does not move the next facet: the renderer evaluates the
    /// old and the new model at a swap, and a facet that one fires and the other does not would add a rise to
    /// the blend's offset (0.176 N felt where 0.15 was the most, cut_under_tension at 200 ms).
    spacing_mm: f32,
    /// Where the device was and when, at the last step.
    last: Option<(f64, [f32; 3])>,
}

impl CutTexture {
    /// No cut under way: the next one starts with a facet.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// The drag's size relative to the model's `cut_drag_n` (0 when not cutting).
    pub fn level(&self) -> f32 {
        self.level
    }

    /// The drag of cutting of `model` at `now_s` with the device at `position_mm` moving at `velocity_mm_s`,
    /// N: without `cut_drag_n`, zero (and the texture resets); without `cut_facet_mm`, `cut_drag_n` against the
    /// motion; with both, the sawtooth against the motion. A call at the same time and place as the last one
    /// (the renderer evaluating a model swap) moves nothing.
    ///
    /// Real-time contract: no allocation, never panics; finite (zero, and a reset, when any input is not).
    pub fn step(
        &mut self,
        model: &LocalModel,
        now_s: f64,
        position_mm: [f32; 3],
        velocity_mm_s: [f32; 3],
    ) -> [f32; 3] {
        let drag_n = model.cut_drag_n;
        let facet_mm = model.cut_facet_mm;
        if !(drag_n.is_finite()
            && drag_n > 0.0
            && now_s.is_finite()
            && all_finite(position_mm)
            && all_finite(velocity_mm_s))
        {
            self.reset();
            return [0.0; 3];
        }
        let mean = cut_drag_force_n(model, velocity_mm_s);
        if !(facet_mm.is_finite() && facet_mm > 0.0) {
            self.reset();
            return mean;
        }
        match self.last {
            None => {
                // A cut begins as a facet is cut, at full drag (the renderer blends the model change, so the
                // force still has no step; a rise from zero here would add to that blend's offset).
                self.level = 1.0;
                self.rising = false;
                self.travel_mm = 0.0;
                self.spacing_mm = facet_mm;
            }
            Some((last_s, last_mm)) => {
                let dt_s = (now_s - last_s).clamp(0.0, MAX_STEP_S) as f32;
                let moved: [f32; 3] = std::array::from_fn(|i| position_mm[i] - last_mm[i]);
                self.travel_mm += dot3(moved, moved).sqrt();
                if self.travel_mm >= self.spacing_mm {
                    self.travel_mm = (self.travel_mm - self.spacing_mm).min(facet_mm);
                    self.spacing_mm = facet_mm;
                    self.rising = true;
                }
                if self.rising {
                    self.level = (self.level + dt_s / CUT_RISE_S).min(1.0);
                    self.rising = self.level < 1.0;
                } else {
                    self.level *= (-dt_s / CUT_DRAG_TAU_S).exp();
                }
            }
        }
        self.last = Some((now_s, position_mm));
        let force_n = mean.map(|c| c * self.level);
        if all_finite(force_n) {
            force_n
        } else {
            self.reset();
            [0.0; 3]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cutting(facet_mm: f32) -> LocalModel {
        LocalModel {
            cut_drag_n: 0.15,
            cut_facet_mm: facet_mm,
            ..LocalModel::default()
        }
    }

    fn norm(v: [f32; 3]) -> f32 {
        v.iter().map(|c| c * c).sum::<f32>().sqrt()
    }

    /// Drive the texture along +y at `speed_mm_s` for `ticks` 1 ms ticks: the drag's sizes.
    fn stroke(
        texture: &mut CutTexture,
        model: &LocalModel,
        speed_mm_s: f32,
        ticks: u32,
    ) -> Vec<f32> {
        (0..ticks)
            .map(|k| {
                let t = f64::from(k) * 0.001;
                let f = texture.step(
                    model,
                    t,
                    [0.0, speed_mm_s * t as f32, 0.0],
                    [0.0, speed_mm_s, 0.0],
                );
                assert!(f[1] <= 0.0 && f[0] == 0.0 && f[2] == 0.0, "{f:?}");
                norm(f)
            })
            .collect()
    }

    #[test]
    fn a_steady_stroke_feels_the_tissues_sawtooth() {
        // 20 mm/s across 1 mm facets: a facet every 50 ms, the drag from R down to R exp(-0.5) between.
        let model = cutting(1.0);
        let mut texture = CutTexture::default();
        let drag = stroke(&mut texture, &model, 20.0, 1000);
        let steady = &drag[200..];
        let smooth = 0.15 * 20.0 / (20.0f32 * 20.0 + 4.0).sqrt();
        let peak = steady.iter().copied().fold(0.0, f32::max);
        let low = steady.iter().copied().fold(f32::INFINITY, f32::min);
        let mean = steady.iter().sum::<f32>() / steady.len() as f32;
        assert!((peak / smooth - 1.0).abs() < 0.01, "peak {peak}");
        assert!(
            (low / (smooth * (-0.05f32 / CUT_DRAG_TAU_S).exp()) - 1.0).abs() < 0.1,
            "low {low}"
        );
        // The mean of exp(-t/tau) over a 50 ms period: tau / T (1 - exp(-T / tau)) = 0.787.
        assert!((mean / smooth - 0.787).abs() < 0.03, "mean {mean}");
        // Twenty facets a second: count where the drag turns up.
        let rises = steady
            .windows(3)
            .filter(|w| w[2] > w[1] + 1e-4 && w[1] <= w[0] + 1e-6)
            .count();
        assert!((15..=17).contains(&rises), "{rises} facets in 0.8 s");
        // No step: a rise is spread over CUT_RISE_S.
        let largest_step = drag
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f32::max);
        assert!(
            largest_step <= 0.15 * 0.001 / CUT_RISE_S + 1e-4,
            "step {largest_step}"
        );
    }

    #[test]
    fn a_new_spacing_takes_effect_at_the_next_facet() {
        // Two models differing only in spacing give the same force until the next facet: a swap between
        // them has nothing to blend.
        let mut texture = CutTexture::default();
        stroke(&mut texture, &cutting(1.0), 20.0, 140);
        for (k, t) in (140..190).map(|k| (k, f64::from(k) * 0.001)) {
            let (x, v) = ([0.0, 20.0 * t as f32, 0.0], [0.0, 20.0, 0.0]);
            let mut other = texture;
            let a = texture.step(&cutting(1.0), t, x, v);
            let b = other.step(&cutting(1.3), t, x, v);
            assert_eq!(a, b, "tick {k}");
        }
    }

    #[test]
    fn a_hand_that_stops_feels_the_drag_fade_and_none_at_rest() {
        let model = cutting(1.0);
        let mut texture = CutTexture::default();
        stroke(&mut texture, &model, 20.0, 100);
        let at_rest = texture.step(&model, 0.2, [0.0, 2.0, 0.0], [0.0; 3]);
        assert_eq!(at_rest, [0.0; 3]);
        // Still, the level decays: no facet fires from standing.
        for k in 0..500 {
            texture.step(
                &model,
                0.2 + f64::from(k) * 0.001,
                [0.0, 2.0, 0.0],
                [0.0; 3],
            );
        }
        assert!(texture.level() < 0.01, "{}", texture.level());
    }

    #[test]
    fn without_a_spacing_the_drag_is_the_models_throughout_and_without_a_drag_none() {
        let mut texture = CutTexture::default();
        let flat = stroke(&mut texture, &cutting(0.0), 20.0, 300);
        assert!(flat.iter().all(|&f| (f - flat[0]).abs() < 1e-6 && f > 0.14));
        let none = LocalModel::default();
        assert_eq!(
            texture.step(&none, 0.3, [0.0; 3], [0.0, 20.0, 0.0]),
            [0.0; 3]
        );
        assert_eq!(texture, CutTexture::default());
    }

    #[test]
    fn the_same_instant_twice_moves_nothing_and_bad_input_renders_zero() {
        let model = cutting(1.0);
        let mut texture = CutTexture::default();
        stroke(&mut texture, &model, 20.0, 120);
        let before = texture;
        let a = texture.step(&model, 0.119, [0.0, 20.0 * 0.119, 0.0], [0.0, 20.0, 0.0]);
        let b = texture.step(&model, 0.119, [0.0, 20.0 * 0.119, 0.0], [0.0, 20.0, 0.0]);
        assert_eq!(a, b);
        assert_eq!(texture.level(), before.level());
        for bad in [f32::NAN, f32::INFINITY] {
            let mut t = texture;
            assert_eq!(
                t.step(&model, 0.2, [bad, 0.0, 0.0], [0.0, 20.0, 0.0]),
                [0.0; 3]
            );
            assert_eq!(t, CutTexture::default());
        }
        // A clock that jumps a second fires at most one facet.
        let mut t = texture;
        let f = t.step(&model, 1.2, [0.0, 40.0, 0.0], [0.0, 20.0, 0.0]);
        assert!(norm(f) <= 0.15 && t.level() <= 1.0);
    }
}
