//! Tearing at a suture's holes: the tick's stage where a thread pulled past its tissue's limit cuts through it.
//!
//! Owns: [`Sim::tear_at_holes`] (after the instruments' step, so it reads the thread's pull of this tick).
//! Must not: decide when or where a hole tears (`interaction::suture::hole_tear` does) or open seams itself
//! (`topology.rs` does, through [`Sim::cut`]).

use crate::interaction::BladeSweep;
use crate::interaction::suture::{HolePoint, plan_hole_tear, surface_point_near};

use super::*;

/// Most tear steps one thread takes in one tick (its holes each tear at most once a period anyway).
const MAX_TEARS_PER_TICK: usize = 8;

impl Sim {
    /// Every thread's holes pulled past their material's `suture_tear_n` tear a step toward the pull: the slit
    /// opens (as a blade's cut) and the hole moves to its end; a slit that reached the tissue's edge lets the
    /// bite go. No allocation unless something tears.
    pub(super) fn tear_at_holes(&mut self, report: &mut StepReport) {
        let now_s = self.time_s;
        for t in 0..self.tools.len() {
            let (mut i, mut tears) = (0, 0);
            while tears < MAX_TEARS_PER_TICK {
                let Some(thread) = self.tools[t].thread() else {
                    break;
                };
                let Some(hole) = thread.holes().get(i) else {
                    break;
                };
                let object = usize::from(hole.point.object());
                // The bite's other hole is looked up only for a hole pulled past its limit.
                let bite_mm = || {
                    thread
                        .bite_partner(i)
                        .and_then(|j| thread.holes().get(j))
                        .map(|h| h.place_mm())
                };
                let plan = self.objects.get(object).and_then(|o| {
                    let limit_n = o.puncture.suture_tear_n?;
                    plan_hole_tear(
                        hole,
                        bite_mm,
                        &o.model,
                        &o.state.positions_mm,
                        limit_n,
                        now_s,
                    )
                });
                let Some(plan) = plan else {
                    i += 1;
                    continue;
                };
                tears += 1;
                self.cut_slit(plan.object, &plan.sweep, report);
                let o = &self.objects[plan.object];
                let to = surface_point_near(
                    &o.collider,
                    &o.model,
                    &o.state.positions_mm,
                    plan.object as u16,
                    &plan.to_mm,
                    &plan.normal,
                );
                let Some(thread) = self.tools[t]
                    .instrument_state
                    .as_mut()
                    .and_then(|s| s.thread_mut())
                else {
                    break;
                };
                match to {
                    Some(point) => {
                        thread.tear_hole_to(i, HolePoint::Surface(point), now_s);
                        report.hole_tears += 1;
                        i += 1;
                    }
                    None => {
                        // The slit reached the edge: the bite is cut through (the holes after it move up).
                        report.holes_torn_out += thread.tear_out(i);
                        report.hole_tears += 1;
                        self.cut_slit(plan.object, &plan.through, report);
                    }
                }
            }
        }
    }

    /// Cut the slit `sweep` through object `object` ([`Sim::cut`]), counting the facets cut and the vertices
    /// split.
    fn cut_slit(&mut self, object: usize, sweep: &BladeSweep, report: &mut StepReport) {
        let mut scratch = std::mem::take(&mut self.hole_tear_scratch);
        let opening = self.cut(object, sweep, &mut scratch);
        report.seams_torn += scratch.seams.len() as u32;
        report.vertices_split += opening.new_vertices() as u32;
        self.hole_tear_scratch = scratch;
    }
}
