//! What a tool's needle and thread are doing this tick, as its output tells the training layer
//! ([`SutureActivity`] in each [`ToolOutput`]).
//!
//! Owns: [`SutureActivity`] and [`Sim::suture_activity`]. Read from the needle drivers' needles and threads
//! after the tick's instruments have acted: a needle driver's own needle and thread, and a grasper's grip on
//! any tool's thread. Must not: change anything (it reads the tick's result).

use crate::interaction::suture::TipPhase;

use super::*;

/// A tool's suturing this tick (all zero for a tool that holds no needle and no thread).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SutureActivity {
    /// The tool's jaws hold a needle.
    pub needle_held: bool,
    /// The needle's tip presses a surface (tenting it, from outside or from inside toward its exit).
    pub needle_pressing: bool,
    /// The needle runs through tissue (holes it made hold it on its path).
    pub needle_in_tissue: bool,
    /// Surfaces the needle has punctured so far.
    pub punctures: u32,
    /// The tool's jaws hold a suture thread (its own needle's, or another tool's).
    pub thread_held: bool,
    /// Holes the thread this tool draws runs through (its needle's thread, or the thread its jaws hold).
    pub thread_holes: u16,
    /// The thread's pull on the tool, N: on the needle's tail for a needle driver, in the jaws for a tool
    /// holding a thread (the larger, if both).
    pub thread_pull_n: f32,
}

impl Sim {
    /// Tool `t`'s suturing now.
    pub(super) fn suture_activity(&self, t: usize) -> SutureActivity {
        let mut activity = SutureActivity::default();
        let Some(tool) = self.tools.get(t).filter(|tool| tool.active) else {
            return activity;
        };
        let instrument = tool.instrument_state.as_ref();
        if let Some(needle) = instrument.and_then(|i| i.needle()) {
            activity.needle_held = true;
            activity.needle_pressing = matches!(needle.phase(), TipPhase::Pressing { .. });
            activity.needle_in_tissue = !needle.holes().is_empty();
            activity.punctures = needle.punctures();
        }
        if let Some(thread) = tool.thread() {
            activity.thread_holes = thread.holes().len().min(usize::from(u16::MAX)) as u16;
            activity.thread_pull_n = finite_or_zero(thread.pull_on_tail_n().norm());
        }
        let Ok(me) = u16::try_from(t) else {
            return activity;
        };
        for thread in self.tools.iter().filter_map(|other| other.thread()) {
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
