//! The knots the sutures tie: every [`KNOT_PERIOD_TICKS`] ticks, each needle's thread is read for the knot
//! its shape ties (`interaction/suture/knot.rs`: closed above the field, against gravity), and each tool's
//! output carries the knot of the thread it draws ([`SutureActivity::knot`]).
//!
//! Owns: [`KnotWatch`] (a reader and the last reading per tool, by the tool whose needle carries the thread)
//! and [`Sim::watch_knots`]. Must not: allocate once the readers' buffers have grown to the threads' size, or
//! read a knot more often than the period (a thread's reading costs a few projections of its polyline, and
//! a state sum when its diagram changed).

use super::*;
use crate::interaction::suture::{KnotKind, KnotReader};

/// How often each thread is read, ticks (20 ms at 1 kHz): a knot is tied over seconds.
pub const KNOT_PERIOD_TICKS: u64 = 20;

/// Each tool's thread's reader and its last reading.
#[derive(Debug, Default)]
pub(super) struct KnotWatch {
    readers: Vec<KnotReader>,
    kinds: Vec<KnotKind>,
}

impl KnotWatch {
    /// Readers for `tools` tools, none of whose threads ties anything yet.
    pub(super) fn new(tools: usize) -> Self {
        Self {
            readers: (0..tools).map(|_| KnotReader::new()).collect(),
            kinds: vec![KnotKind::None; tools],
        }
    }

    /// What the thread tool `owner`'s needle carries tied at its last reading.
    pub(super) fn kind(&self, owner: usize) -> KnotKind {
        self.kinds.get(owner).copied().unwrap_or(KnotKind::None)
    }
}

impl Sim {
    /// Read every thread's knot, on ticks that are a multiple of [`KNOT_PERIOD_TICKS`] (the readings hold
    /// between). A thread not laid out, or one whose nodes are not finite, ties nothing.
    pub(super) fn watch_knots(&mut self) {
        if !self.steps.is_multiple_of(KNOT_PERIOD_TICKS) {
            return;
        }
        for (t, tool) in self.tools.iter().enumerate() {
            let (Some(reader), Some(kind)) =
                (self.knots.readers.get_mut(t), self.knots.kinds.get_mut(t))
            else {
                break;
            };
            *kind = match tool.thread() {
                Some(thread) if thread.is_laid_out() => reader
                    .read_thread(thread.nodes_mm(), thread.up_unit())
                    .unwrap_or(KnotKind::None),
                _ => KnotKind::None,
            };
        }
    }
}
