//! Tearing: tissue stretched past its material's limit comes apart along the overstretched springs.
//!
//! Owns: [`Sim::tear_overstretched`] (the tick's stage) and how many facets one object tears a tick. Must
//! not: decide the seams' geometry ([`crate::interaction::torn_seams`] does) or open them itself
//! (`topology.rs` does).

use crate::interaction::torn_seams;

use super::*;

/// Most facets one object tears open in one tick.
const MAX_TEARS_PER_TICK: usize = 32;

impl Sim {
    /// Every object with a tear strain tears where a spring is stretched past it, at most
    /// [`MAX_TEARS_PER_TICK`] facets a tick. A multi-rate object is tested on the ticks that take back its
    /// step (its state changes only then; the step under way takes the tear at the next hand-off, as it takes
    /// a cut). No allocation unless something tears.
    pub(super) fn tear_overstretched(&mut self, report: &mut StepReport) {
        let tick = self.steps;
        for o in 0..self.objects.len() {
            let object = &mut self.objects[o];
            let Some(strain) = object.tear_strain else {
                continue;
            };
            if object.lane.as_ref().is_some_and(|lane| !lane.due(tick)) {
                continue;
            }
            let mut torn = std::mem::take(&mut object.torn);
            torn.clear();
            torn_seams(&object.model, &object.state.positions_mm, strain, &mut torn);
            // A capped number a tick (the first in spring order: deterministic), so a sheet pulled far past its
            // limit at once rips over a few ticks rather than in one long tick.
            torn.truncate(MAX_TEARS_PER_TICK);
            if !torn.is_empty() {
                report.seams_torn += torn.len() as u32;
                report.vertices_split += self.open_seams(o, &torn).new_vertices() as u32;
            }
            self.objects[o].torn = torn;
        }
    }
}
