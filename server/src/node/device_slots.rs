//! One slot per tool-bound device: the mailbox its poses land in and what the server knows of it.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Instant;

use sinew_protocol::DevicePose;
use sinew_protocol::rt::LatestValue;

use crate::sim::Sim;

/// A pose and when it arrived.
#[derive(Debug, Clone, Copy)]
pub struct PoseArrival {
    /// The decoded, validated pose.
    pub pose: DevicePose,
    /// Arrival time on the server.
    pub received: Instant,
}

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
    /// Its hello asked for another tool: its poses are ignored.
    pub refused: AtomicBool,
    /// Device max force from its hello, f32 bits (0 = unknown).
    pub hello_max_force_bits: AtomicU32,
    /// Poses accepted.
    pub poses_received: AtomicU64,
}

impl DeviceSlot {
    /// Device max force from its hello, if announced.
    pub fn hello_max_force_n(&self) -> Option<f32> {
        let v = f32::from_bits(self.hello_max_force_bits.load(Ordering::Acquire));
        (v > 0.0).then_some(v)
    }
}

/// Slots in tool order.
#[derive(Debug)]
pub struct DeviceSlots {
    slots: Vec<DeviceSlot>,
}

impl DeviceSlots {
    /// One slot per tool of the sim.
    pub fn new(sim: &Sim) -> Self {
        Self {
            slots: sim
                .tools
                .iter()
                .map(|t| DeviceSlot {
                    device_id: t.device_id.clone(),
                    tool_name: t.name.clone(),
                    pose: LatestValue::new(),
                    gone: AtomicBool::new(false),
                    refused: AtomicBool::new(false),
                    hello_max_force_bits: AtomicU32::new(0),
                    poses_received: AtomicU64::new(0),
                })
                .collect(),
        }
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
