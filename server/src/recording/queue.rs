//! The recorder's queue: what travels from the sim thread and the wire tap to the writer thread.
//!
//! Owns: the queue's message ([`Item`]), what the wire tap hears ([`WireItem`]) and the tap's bounded end of the
//! queue ([`WireSink`]). The writer ([`super::writer`]) owns the queue and its other end; the tap
//! ([`super::wire_tap`]) only offers into it. Both import this module, neither the other.
//!
//! Must not: block or allocate on the sim thread's side.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::SyncSender;

use super::tick_record::{FinalState, TickRecord};

/// What goes through the queue.
#[derive(Debug)]
pub(super) enum Item {
    Tick(Box<TickRecord>),
    Final(FinalState),
    Wire(WireItem),
    /// The session is over: finish the file, whatever still holds a sender.
    End,
}

/// Wire items in the writer's queue at most; more are dropped and counted.
pub const WIRE_QUEUE: usize = 512;

/// One thing heard on the wire.
#[derive(Debug, Clone, PartialEq)]
pub enum WireItem {
    /// A message, as published (envelope and postcard body), on its key.
    Sample {
        /// The zenoh key it was published on.
        key: String,
        /// When it was heard, on the recording's clock, ns.
        log_time_ns: u64,
        /// The bytes.
        payload: Vec<u8>,
    },
    /// A participant's presence token appeared or went away.
    Presence {
        /// The token's key (`sinew/<scene>/presence/<role>/<id>`).
        key: String,
        /// Appeared (true) or went away.
        joined: bool,
        /// When, on the recording's clock, ns.
        log_time_ns: u64,
    },
}

/// The tap's end of the recorder's queue: never blocks; drops and counts past [`WIRE_QUEUE`] items in flight.
#[derive(Debug, Clone)]
pub struct WireSink {
    queue: SyncSender<Item>,
    in_flight: Arc<AtomicUsize>,
    dropped: Arc<AtomicU64>,
}

impl WireSink {
    pub(super) fn new(queue: SyncSender<Item>, in_flight: Arc<AtomicUsize>) -> Self {
        Self {
            queue,
            in_flight,
            dropped: Arc::new(AtomicU64::new(0)),
        }
    }

    /// Hand an item over, or count it as dropped.
    pub fn offer(&self, item: WireItem) {
        if self.in_flight.fetch_add(1, Ordering::AcqRel) >= WIRE_QUEUE {
            self.in_flight.fetch_sub(1, Ordering::AcqRel);
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self.queue.try_send(Item::Wire(item)).is_err() {
            self.in_flight.fetch_sub(1, Ordering::AcqRel);
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Items dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}
