//! Which server a client follows: the first server instance it hears, until that one leaves or goes quiet.
//!
//! Two servers live for one scene (a second one started by mistake, or two that were partitioned and met
//! again) both publish forces and deltas on the same keys. A client that took both would render two force
//! streams and thrash its replica. Each client therefore admits messages only from the server instance it
//! joined (the envelope's sender), and counts the rest. It moves to another instance only when the joined
//! one has left (its presence token went away: [`JoinedServer::release`]) or has been silent for
//! [`JoinedServer::QUIET_SWITCH_NS`], which is how a restarted server is taken up.
//!
//! Lock-free: `admit` runs on zenoh's callback threads, several at once.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::codec::InstanceId;

/// What [`JoinedServer::admit`] decided about one message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Admission {
    /// The first server heard: joined now.
    Joined,
    /// From the joined server.
    Same,
    /// The joined server had left or gone quiet; this one is joined now.
    Switched {
        /// The server followed until now.
        from: InstanceId,
    },
    /// From another server while the joined one lives: refuse it.
    Foreign {
        /// The server this client follows.
        joined: InstanceId,
    },
}

impl Admission {
    /// Whether the message is to be used.
    pub fn admitted(self) -> bool {
        !matches!(self, Admission::Foreign { .. })
    }
}

/// The server a client follows, shared by its callbacks.
#[derive(Debug, Default)]
pub struct JoinedServer {
    current: AtomicU64,
    last_heard_ns: AtomicU64,
    foreign: AtomicU64,
    last_foreign: AtomicU64,
    switches: AtomicU64,
}

impl JoinedServer {
    /// A joined server silent this long may be replaced by the next one heard, ns. Longer than any gap a
    /// live server leaves (its heartbeat is 7 ms, its stats 1 s apart but tool states flow at the publish
    /// rate), shorter than a server restart.
    pub const QUIET_SWITCH_NS: u64 = 300_000_000;

    /// Nobody joined yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Decide about a message from `from`, heard at `now_ns` (any monotonic clock, the same on every call).
    pub fn admit(&self, from: InstanceId, now_ns: u64) -> Admission {
        loop {
            let current = self.current.load(Ordering::Acquire);
            if current == from.0 {
                self.last_heard_ns.fetch_max(now_ns, Ordering::AcqRel);
                return Admission::Same;
            }
            let quiet = now_ns.saturating_sub(self.last_heard_ns.load(Ordering::Acquire))
                >= Self::QUIET_SWITCH_NS;
            if current != 0 && !quiet {
                self.foreign.fetch_add(1, Ordering::Relaxed);
                self.last_foreign.store(from.0, Ordering::Relaxed);
                return Admission::Foreign {
                    joined: InstanceId(current),
                };
            }
            if self
                .current
                .compare_exchange(current, from.0, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
            {
                self.last_heard_ns.store(now_ns, Ordering::Release);
                if current == 0 {
                    return Admission::Joined;
                }
                self.switches.fetch_add(1, Ordering::Relaxed);
                return Admission::Switched {
                    from: InstanceId(current),
                };
            }
        }
    }

    /// The joined server left (its presence token was deleted): the next server heard is joined at once.
    /// Returns the instance that was joined.
    pub fn release(&self) -> InstanceId {
        InstanceId(self.current.swap(0, Ordering::AcqRel))
    }

    /// The server followed now ([`InstanceId::NONE`] before the first message or after a release).
    pub fn current(&self) -> InstanceId {
        InstanceId(self.current.load(Ordering::Acquire))
    }

    /// When the joined server was last heard, on the callers' clock, ns.
    pub fn last_heard_ns(&self) -> u64 {
        self.last_heard_ns.load(Ordering::Acquire)
    }

    /// Note a message from the joined server that did not go through [`JoinedServer::admit`] (none today);
    /// also lets a test age the joined server.
    pub fn heard(&self, now_ns: u64) {
        self.last_heard_ns.fetch_max(now_ns, Ordering::AcqRel);
    }

    /// Messages refused because they came from another server.
    pub fn foreign(&self) -> u64 {
        self.foreign.load(Ordering::Relaxed)
    }

    /// The latest other server refused ([`InstanceId::NONE`] if none).
    pub fn last_foreign(&self) -> InstanceId {
        InstanceId(self.last_foreign.load(Ordering::Relaxed))
    }

    /// Times the client moved to another server after the joined one left or went quiet.
    pub fn switches(&self) -> u64 {
        self.switches.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn the_first_server_is_kept_while_it_speaks_and_others_are_refused_and_counted() {
        let joined = JoinedServer::new();
        let (a, b) = (InstanceId(0xa), InstanceId(0xb));
        assert_eq!(joined.admit(a, 10 * MS), Admission::Joined);
        assert_eq!(joined.admit(b, 11 * MS), Admission::Foreign { joined: a });
        assert_eq!(joined.admit(a, 200 * MS), Admission::Same);
        assert_eq!(joined.admit(b, 450 * MS), Admission::Foreign { joined: a });
        assert_eq!(joined.foreign(), 2);
        assert_eq!(joined.last_foreign(), b);
        assert_eq!(joined.current(), a);
    }

    #[test]
    fn a_quiet_or_departed_server_is_replaced_by_the_next_one_heard() {
        let joined = JoinedServer::new();
        let (a, b, c) = (InstanceId(1), InstanceId(2), InstanceId(3));
        joined.admit(a, 0);
        assert!(
            !joined
                .admit(b, JoinedServer::QUIET_SWITCH_NS - 1)
                .admitted()
        );
        assert_eq!(
            joined.admit(b, JoinedServer::QUIET_SWITCH_NS),
            Admission::Switched { from: a }
        );
        assert_eq!(joined.release(), b);
        assert_eq!(
            joined.admit(c, JoinedServer::QUIET_SWITCH_NS + MS),
            Admission::Joined
        );
        assert_eq!(joined.switches(), 1);
    }
}
