//! Weighs the mesh deltas a viewer would get from one object (included with `#[path]` by the benches that
//! report them): one delta per publish frame, encoded as the wire carries it.
#![allow(dead_code)] // each bench uses its own subset

use sinew_protocol::MeshDelta;
use sinew_protocol::codec::{InstanceId, encode_to_vec};
use sinew_server::replication::{ObjectReplication, ObjectTopology};
use sinew_server::sim::SimObject;

/// Count, total bytes and largest of a kind of delta.
#[derive(Debug, Default, Clone, Copy)]
pub struct Weighed {
    pub count: u32,
    pub bytes: usize,
    pub max: usize,
}

impl Weighed {
    fn add(&mut self, bytes: usize) {
        self.count += 1;
        self.bytes += bytes;
        self.max = self.max.max(bytes);
    }

    /// Mean bytes a delta (0 with none).
    pub fn mean(&self) -> f64 {
        self.bytes as f64 / f64::from(self.count.max(1))
    }
}

/// One object's replication, as the server's publish loop keeps it, and what its deltas weighed.
pub struct DeltaScale {
    replication: ObjectReplication,
    topology: ObjectTopology,
    delta: MeshDelta,
    frame: u64,
    /// Deltas that carried a topology change.
    pub with_topology: Weighed,
    /// Deltas of positions only.
    pub plain: Weighed,
}

impl DeltaScale {
    /// For `object` as it is now, quantized with `quant_margin_mm` (the world's).
    pub fn new(object: &SimObject, quant_margin_mm: f32) -> Self {
        Self {
            replication: ObjectReplication::new(
                &object.name,
                object.model.rest_positions_mm(),
                object.model.triangles(),
                quant_margin_mm,
                0.0,
            ),
            topology: ObjectTopology::default(),
            delta: MeshDelta::default(),
            frame: 0,
            with_topology: Weighed::default(),
            plain: Weighed::default(),
        }
    }

    /// A publish frame: the delta `object` gives now, encoded and weighed (none if nothing changed).
    pub fn frame(&mut self, object: &SimObject) {
        self.frame += 1;
        self.topology.follow(object);
        if self.replication.delta(
            0,
            &object.state.positions_mm,
            &[],
            Some(&self.topology),
            self.frame,
            &mut self.delta,
        ) {
            let bytes = encode_to_vec(InstanceId(1), &self.delta).len();
            if self.delta.topology.is_some() {
                self.with_topology.add(bytes);
            } else {
                self.plain.add(bytes);
            }
        }
    }
}
