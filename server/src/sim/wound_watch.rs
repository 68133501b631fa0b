//! The wound an exercise judges: how far open it is after each tick ([`StepReport::wound_gap_mm`]), for the
//! training layer to score a stitch by ("wound gap after tightening").
//!
//! Owns: [`Sim::wound_gap_now`]. The two objects are the world's suture exercise's `wound`
//! (`scene/exercise_spec.rs`); the gap is `tissue::wound_gap`'s. Must not: allocate or panic (a
//! world without a wound reports none).

use super::*;

impl Sim {
    /// The gap of the exercise's wound now, mm (None: the world names no wound, or it has no gap to tell).
    pub(super) fn wound_gap_now(&self) -> Option<f32> {
        let [a, b] = self.wound?;
        let (a, b) = (self.objects.get(a)?, self.objects.get(b)?);
        let gap = crate::tissue::wound_gap::wound_gap_between_mm(
            (a.model.rest_positions_mm(), &a.state.positions_mm),
            (b.model.rest_positions_mm(), &b.state.positions_mm),
        )?;
        gap.is_finite().then_some(gap)
    }
}
