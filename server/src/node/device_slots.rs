//! One slot per tool-bound device: the mailbox its poses land in, who holds the id, and what the server
//! knows of it.
//!
//! **Claims.** A device id is held by one hapticserver instance (the envelope's sender): the first whose
//! pose arrives. Poses from any other instance are refused and counted while the holder lives, so a second
//! hapticserver started with the same id never moves the tool. The holder lets go when its presence token
//! goes away or when it has sent nothing for the claim timeout; the next instance heard then takes the id
//! (its tool re-enters from above the tissue, and its force ramps in). A hello that asks for another tool
//! refuses that instance only, never the id.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Instant;

use sinew_protocol::rt::{LatestValue, Throttle};
use sinew_protocol::{DevicePose, InstanceId};

use crate::sim::Sim;

/// A pose and when it arrived.
#[derive(Debug, Clone, Copy)]
pub struct PoseArrival {
    /// The decoded, validated pose.
    pub pose: DevicePose,
    /// Arrival time on the server.
    pub received: Instant,
    /// The hapticserver instance that sent it (the id's holder).
    pub from: InstanceId,
}

/// What [`DeviceSlot::claim`] decided about a pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Claim {
    /// From the holder.
    Held,
    /// The id was free (or its holder had gone): `from` holds it now.
    Taken {
        /// The instance that held it before (none if it was never held).
        previous: InstanceId,
    },
    /// Another instance holds the id: refuse the pose.
    Duplicate {
        /// The holder.
        holder: InstanceId,
        /// This is the first pose refused from this instance.
        first: bool,
    },
    /// This instance asked for another tool, or left (its token was deleted): refuse the pose.
    Refused,
    /// No hello from this instance yet: its tool and force limit are unknown, so it drives nothing.
    Unannounced,
}

/// How often a lasting duplicate is logged again, ns.
pub const DUPLICATE_LOG_PERIOD_NS: u64 = 10_000_000_000;

/// What the server knows of one device.
#[derive(Debug)]
pub struct DeviceSlot {
    /// Device id (key segment).
    pub device_id: String,
    /// Name of the tool the world binds it to.
    pub tool_name: String,
    /// Newest pose.
    pub pose: LatestValue<PoseArrival>,
    /// Its liveliness token was seen and then disappeared.
    pub gone: AtomicBool,
    /// Device max force from its hello, f32 bits (0 = unknown).
    pub hello_max_force_bits: AtomicU32,
    /// Poses accepted.
    pub poses_received: AtomicU64,
    /// The instance holding the id (0: free).
    holder: AtomicU64,
    /// When the holder's latest pose arrived, ns since the slots' epoch.
    holder_heard_ns: AtomicU64,
    /// The instance whose token was deleted last: its in-flight poses must not re-take the id.
    departed: AtomicU64,
    /// Instances refused because another held the id (each counted once).
    pub duplicates_refused: AtomicU64,
    /// The latest instance refused as a duplicate.
    pub last_duplicate: AtomicU64,
    /// The latest instance whose hello asked for another tool (0: none), with the tool it asked for.
    pub wrong_tool_instance: AtomicU64,
    /// The tool that instance asked for.
    pub wrong_tool_asked: Mutex<String>,
    /// Log throttle for refused duplicates.
    pub duplicate_log: Throttle,
    /// The latest instances whose hello this server accepted (a ring): only they may drive the tool.
    greeted: [AtomicU64; GREETED],
    greeted_next: AtomicU64,
}

/// How many greeted instances a slot remembers.
const GREETED: usize = 4;

impl DeviceSlot {
    /// A free slot for `device_id`, bound to the tool `tool_name`.
    pub fn new(device_id: &str, tool_name: &str) -> Self {
        DeviceSlot {
            device_id: device_id.to_owned(),
            tool_name: tool_name.to_owned(),
            pose: LatestValue::new(),
            gone: AtomicBool::new(false),
            hello_max_force_bits: AtomicU32::new(0),
            poses_received: AtomicU64::new(0),
            holder: AtomicU64::new(0),
            holder_heard_ns: AtomicU64::new(0),
            departed: AtomicU64::new(0),
            duplicates_refused: AtomicU64::new(0),
            last_duplicate: AtomicU64::new(0),
            wrong_tool_instance: AtomicU64::new(0),
            wrong_tool_asked: Mutex::new(String::new()),
            duplicate_log: Throttle::new(DUPLICATE_LOG_PERIOD_NS),
            greeted: Default::default(),
            greeted_next: AtomicU64::new(0),
        }
    }

    /// Device max force from its hello, if announced.
    pub fn hello_max_force_n(&self) -> Option<f32> {
        let v = f32::from_bits(self.hello_max_force_bits.load(Ordering::Acquire));
        (v > 0.0).then_some(v)
    }

    /// `from`'s hello was accepted: it may drive the tool (its max force and tool are known).
    pub fn greet(&self, from: InstanceId) {
        if self.greeted(from) {
            return;
        }
        let i = self.greeted_next.fetch_add(1, Ordering::AcqRel) as usize % GREETED;
        self.greeted[i].store(from.0, Ordering::Release);
    }

    /// Whether `from`'s hello was accepted.
    pub fn greeted(&self, from: InstanceId) -> bool {
        self.greeted
            .iter()
            .any(|g| g.load(Ordering::Acquire) == from.0)
    }

    /// The instance holding the id.
    pub fn holder(&self) -> InstanceId {
        InstanceId(self.holder.load(Ordering::Acquire))
    }

    /// Decide about a pose from `from` arriving at `now_ns` (ns since the slots' epoch), given the claim
    /// timeout. Lock-free: runs on zenoh's callback threads.
    pub fn claim(&self, from: InstanceId, now_ns: u64, timeout_ns: u64) -> Claim {
        if from.0 == self.wrong_tool_instance.load(Ordering::Acquire)
            || from.0 == self.departed.load(Ordering::Acquire)
        {
            return Claim::Refused;
        }
        if !self.greeted(from) {
            return Claim::Unannounced;
        }
        loop {
            let holder = self.holder.load(Ordering::Acquire);
            if holder == from.0 {
                self.holder_heard_ns.fetch_max(now_ns, Ordering::AcqRel);
                return Claim::Held;
            }
            let quiet =
                now_ns.saturating_sub(self.holder_heard_ns.load(Ordering::Acquire)) >= timeout_ns;
            if holder != 0 && !quiet {
                let first = self.last_duplicate.swap(from.0, Ordering::AcqRel) != from.0;
                if first {
                    self.duplicates_refused.fetch_add(1, Ordering::Relaxed);
                }
                return Claim::Duplicate {
                    holder: InstanceId(holder),
                    first,
                };
            }
            if self
                .holder
                .compare_exchange(holder, from.0, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
            {
                self.holder_heard_ns.store(now_ns, Ordering::Release);
                // A new holder is present whatever an earlier holder's token did.
                self.gone.store(false, Ordering::Release);
                return Claim::Taken {
                    previous: InstanceId(holder),
                };
            }
        }
    }

    /// The id's presence token is (back) up. A token that comes back after a delete is a device whose
    /// transport closed and reopened (a link that flapped, a partition that healed): whichever instance it
    /// is, it may drive again, so the departed mark is cleared (it only guards the poses in flight after a
    /// delete, which have landed by the time a new transport has been opened and declared).
    pub fn present(&self) {
        self.departed.store(0, Ordering::Release);
        self.gone.store(false, Ordering::Release);
    }

    /// The id's presence token was deleted: the holder left. Its in-flight poses are refused from now on,
    /// and the next instance heard takes the id. Returns the instance that held it.
    pub fn release(&self) -> InstanceId {
        let holder = self.holder.swap(0, Ordering::AcqRel);
        if holder != 0 {
            self.departed.store(holder, Ordering::Release);
        }
        self.gone.store(true, Ordering::Release);
        InstanceId(holder)
    }
}

/// Slots in tool order.
#[derive(Debug)]
pub struct DeviceSlots {
    slots: Vec<DeviceSlot>,
    epoch: Instant,
}

impl DeviceSlots {
    /// One slot per tool of the sim.
    pub fn new(sim: &Sim) -> Self {
        Self {
            slots: sim
                .tools
                .iter()
                .map(|t| DeviceSlot::new(&t.device_id, &t.name))
                .collect(),
            epoch: Instant::now(),
        }
    }

    /// Now, ns since the slots were made (the clock of [`DeviceSlot::claim`]).
    pub fn now_ns(&self) -> u64 {
        self.epoch.elapsed().as_nanos() as u64
    }

    /// The slot of a device id.
    pub fn find(&self, device_id: &str) -> Option<&DeviceSlot> {
        self.slots.iter().find(|s| s.device_id == device_id)
    }

    /// All slots, tool order.
    pub fn iter(&self) -> std::slice::Iter<'_, DeviceSlot> {
        self.slots.iter()
    }

    /// Slot `i` (tool order).
    pub fn get(&self, i: usize) -> Option<&DeviceSlot> {
        self.slots.get(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slot() -> DeviceSlot {
        DeviceSlot::new("left", "probe")
    }

    const MS: u64 = 1_000_000;
    const TIMEOUT: u64 = 500 * MS;

    #[test]
    fn the_first_instance_keeps_the_id_and_a_second_is_refused_once_counted() {
        let s = slot();
        let (a, b) = (InstanceId(1), InstanceId(2));
        assert_eq!(s.claim(a, 0, TIMEOUT), Claim::Unannounced, "no hello yet");
        s.greet(a);
        s.greet(b);
        assert_eq!(
            s.claim(a, 0, TIMEOUT),
            Claim::Taken {
                previous: InstanceId::NONE
            }
        );
        assert_eq!(
            s.claim(b, MS, TIMEOUT),
            Claim::Duplicate {
                holder: a,
                first: true
            }
        );
        assert_eq!(s.claim(a, 2 * MS, TIMEOUT), Claim::Held);
        assert_eq!(
            s.claim(b, 3 * MS, TIMEOUT),
            Claim::Duplicate {
                holder: a,
                first: false
            }
        );
        assert_eq!(s.duplicates_refused.load(Ordering::Relaxed), 1);
        assert_eq!(s.holder(), a);
    }

    #[test]
    fn a_quiet_or_departed_holder_lets_the_next_instance_take_the_id() {
        let s = slot();
        let (a, b, c) = (InstanceId(1), InstanceId(2), InstanceId(3));
        for i in [a, b, c] {
            s.greet(i);
        }
        s.claim(a, 0, TIMEOUT);
        assert_eq!(s.claim(b, TIMEOUT, TIMEOUT), Claim::Taken { previous: a });
        assert_eq!(s.release(), b);
        assert!(s.gone.load(Ordering::Relaxed));
        // The departed holder's in-flight pose cannot re-take the id.
        assert_eq!(s.claim(b, TIMEOUT + MS, TIMEOUT), Claim::Refused);
        assert_eq!(
            s.claim(c, TIMEOUT + 2 * MS, TIMEOUT),
            Claim::Taken {
                previous: InstanceId::NONE
            }
        );
        assert!(!s.gone.load(Ordering::Relaxed));
    }

    #[test]
    fn a_holder_whose_token_comes_back_after_its_transport_flapped_drives_again() {
        let s = slot();
        let a = InstanceId(1);
        s.greet(a);
        assert_eq!(
            s.claim(a, 0, TIMEOUT),
            Claim::Taken {
                previous: InstanceId::NONE
            }
        );
        // The transport closes (its token is deleted) and reopens (the token is declared again).
        assert_eq!(s.release(), a);
        assert_eq!(s.claim(a, MS, TIMEOUT), Claim::Refused);
        s.present();
        assert_eq!(
            s.claim(a, 2 * MS, TIMEOUT),
            Claim::Taken {
                previous: InstanceId::NONE
            }
        );
        assert!(!s.gone.load(Ordering::Relaxed));
    }

    #[test]
    fn a_wrong_tool_refuses_that_instance_only() {
        let s = slot();
        let (a, b) = (InstanceId(1), InstanceId(2));
        s.greet(a);
        s.greet(b);
        s.wrong_tool_instance.store(a.0, Ordering::Release);
        assert_eq!(s.claim(a, 0, TIMEOUT), Claim::Refused);
        assert_eq!(
            s.claim(b, MS, TIMEOUT),
            Claim::Taken {
                previous: InstanceId::NONE
            }
        );
    }
}
