//! What a tool's needle and thread are doing this tick, as its output tells the training layer
//! ([`SutureActivity`] in each [`ToolOutput`]).
//!
//! Owns: [`SutureActivity`] and [`Sim::suture_activity`]. Read from the needle drivers' needles and threads
//! after the tick's instruments have acted: the needle a tool's jaws hold (its own, in a needle driver's jaws,
//! or another tool's, taken after its driver let it go) with the thread on it, a needle its driver let go in
//! the tissue, and a grasper's grip on any tool's thread. Must not: change anything (it reads the tick's
//! result).

use crate::interaction::suture::{KnotKind, NeedleHold, NeedleHolder, NeedleTissue, TipPhase};

use super::instrument::Instrument;

use super::*;

/// A tool's suturing this tick (all zero for a tool that holds no needle and no thread).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SutureActivity {
    /// The tool's jaws hold a needle.
    pub needle_held: bool,
    /// The jaws took the needle they hold while it ran through tissue (a regrasp, on the far side of a bite),
    /// and it still does.
    pub needle_regrasped: bool,
    /// The tool is a needle driver that let its needle go in the tissue, and no jaws hold it since.
    pub needle_released: bool,
    /// The needle's tip presses a surface (tenting it, from outside or from inside toward its exit).
    pub needle_pressing: bool,
    /// The needle runs through tissue (holes it made hold it on its path).
    pub needle_in_tissue: bool,
    /// Surfaces the needle has punctured so far.
    pub punctures: u32,
    /// Where the needle's newest hole lies on its tissue at rest, world, mm (the tick it punctures: where that
    /// puncture went in, on the undeformed tissue, as marks are drawn; None while the needle holds no hole).
    pub newest_hole_rest_mm: Option<crate::tissue::Vec3>,
    /// The tool's jaws hold a suture thread (its own needle's, or another tool's).
    pub thread_held: bool,
    /// Holes the thread this tool draws runs through (its needle's thread, or the thread its jaws hold).
    pub thread_holes: u16,
    /// The thread's pull on the tool, N: on the needle's tail for a needle driver, in the jaws for a tool
    /// holding a thread (the larger, if both).
    pub thread_pull_n: f32,
    /// The knot the thread this tool draws ties, at its last reading (`knot_watch.rs`; a knot of throws
    /// wins over none when the tool draws two threads).
    pub knot: KnotKind,
}

impl Sim {
    /// The needle tool `t`'s jaws hold, with the instrument that carries it and its hold (see
    /// [`Sim::jaws_hold_needle_of`]).
    pub(super) fn needle_in_jaws(
        &self,
        t: usize,
    ) -> Option<(&dyn Instrument, &NeedleTissue, &NeedleHold)> {
        self.tools.iter().enumerate().find_map(|(owner, other)| {
            let instrument = other.instrument_state.as_deref()?;
            let (needle, hold) = (instrument.needle()?, instrument.needle_hold()?);
            self.jaws_hold_needle_of(t, owner)
                .then_some((instrument, needle, hold))
        })
    }

    /// Whether tool `t`'s jaws hold the needle tool `owner` carries: its own in a needle driver's jaws, or
    /// another tool's needle its jaws took.
    fn jaws_hold_needle_of(&self, t: usize, owner: usize) -> bool {
        let Some(hold) = self
            .tools
            .get(owner)
            .and_then(|tool| tool.instrument_state.as_deref())
            .and_then(|instrument| instrument.needle_hold())
        else {
            return false;
        };
        if owner == t {
            hold.in_drivers_jaws()
        } else {
            u16::try_from(t).is_ok_and(|me| hold.held_by(me))
        }
    }

    /// Tool `t`'s suturing now.
    pub(super) fn suture_activity(&self, t: usize) -> SutureActivity {
        let mut activity = SutureActivity::default();
        if !self.tools.get(t).is_some_and(|tool| tool.active) {
            return activity;
        }
        let Ok(me) = u16::try_from(t) else {
            return activity;
        };
        if let Some(own) = self.tools[t].instrument_state.as_ref()
            && let (Some(needle), Some(hold)) = (own.needle(), own.needle_hold())
        {
            activity.needle_released =
                !needle.holes().is_empty() && *hold.holder() == NeedleHolder::Loose;
        }
        if let Some((instrument, needle, hold)) = self.needle_in_jaws(t) {
            let in_tissue = !needle.holes().is_empty();
            activity.needle_held = true;
            activity.needle_regrasped = in_tissue && hold.taken_in_tissue();
            activity.needle_pressing = matches!(needle.phase(), TipPhase::Pressing { .. });
            activity.needle_in_tissue = in_tissue;
            activity.punctures = needle.punctures();
            activity.newest_hole_rest_mm = needle.holes().last().and_then(|hole| {
                let object = self.objects.get(usize::from(hole.point.object))?;
                hole.point.rest_position_mm(&object.model)
            });
            if let Some(thread) = instrument.thread() {
                activity.thread_holes = thread.holes().len().min(usize::from(u16::MAX)) as u16;
                activity.thread_pull_n = finite_or_zero(thread.pull_on_tail_n().norm());
            }
        }
        for (owner, other) in self.tools.iter().enumerate() {
            let Some(thread) = other.thread() else {
                continue;
            };
            if (self.jaws_hold_needle_of(t, owner) || thread.grip_of(me).is_some())
                && activity.knot == KnotKind::None
            {
                activity.knot = self.knots.kind(owner);
            }
            if let Some(grip) = thread.grip_of(me) {
                activity.thread_held = true;
                activity.thread_holes = activity
                    .thread_holes
                    .max(thread.holes().len().min(usize::from(u16::MAX)) as u16);
                activity.thread_pull_n = activity
                    .thread_pull_n
                    .max(finite_or_zero(grip.pull_n().norm()));
            }
        }
        activity
    }
}

fn finite_or_zero(x: f32) -> f32 {
    if x.is_finite() { x } else { 0.0 }
}
