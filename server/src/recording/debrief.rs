//! Scene snapshots of a replayed session, taken through the same hand-off and quantization a live viewer's
//! replica gets (frame exchange, then per-object deltas): what the instructor's debrief frames draw.
//!
//! Owns: one replication state for the replay. Must not: publish anything, or be used on the sim thread (a
//! snapshot allocates).

use sinew_protocol::{MeshDelta, SceneSnapshot};

use crate::replication::{FrameExchange, ReplicationState};
use crate::scene::World;
use crate::sim::{Sim, ToolOutput};
use crate::tissue::Vec3;

/// Snapshots of one replay, frame after frame.
#[derive(Debug)]
pub struct DebriefFrames {
    scene: String,
    exchange: FrameExchange,
    replication: ReplicationState,
    positions: Vec<Vec<Vec3>>,
    burn: Vec<Vec<u8>>,
    topology: Vec<crate::replication::ObjectTopology>,
    delta: MeshDelta,
}

impl DebriefFrames {
    /// For a replay of `world` whose simulation is `sim` (at rest).
    pub fn new(world: &World, sim: &Sim) -> Self {
        Self {
            scene: world.scene.clone(),
            exchange: FrameExchange::new(sim),
            replication: ReplicationState::new(world, sim),
            positions: Vec::new(),
            burn: Vec::new(),
            topology: Vec::new(),
            delta: MeshDelta::default(),
        }
    }

    /// The scene as a viewer would hold it after the sim's current state was published.
    pub fn capture(&mut self, sim: &Sim, outputs: &[ToolOutput]) -> SceneSnapshot {
        // Nothing else holds the exchange: the offer always lands.
        let _ = self.exchange.try_offer(sim, outputs);
        let replication = &mut self.replication;
        let positions = &mut self.positions;
        let burn = &mut self.burn;
        let topology = &mut self.topology;
        let tools = self.exchange.with_frame(|frame| {
            positions.resize_with(frame.positions_mm.len(), Vec::new);
            for (dst, src) in positions.iter_mut().zip(&frame.positions_mm) {
                dst.clone_from(src);
            }
            burn.clone_from(&frame.burn);
            topology.resize_with(frame.topology.len(), Default::default);
            for (dst, src) in topology.iter_mut().zip(&frame.topology) {
                dst.sync_from(src);
            }
            (frame.sim_time_s, frame.tools.clone())
        });
        replication.frame += 1;
        let frame = replication.frame;
        if let Some((sim_time_s, tools)) = tools {
            replication.tool_states.frame = frame;
            replication.tool_states.sim_time_s = sim_time_s;
            replication.tool_states.tools = tools;
        }
        for (o, object_positions) in self.positions.iter().enumerate() {
            if let Some(object) = replication.objects.get_mut(o) {
                let object_burn = self.burn.get(o).map_or(&[][..], |b| b.as_slice());
                object.delta(
                    o as u16,
                    object_positions,
                    object_burn,
                    self.topology.get(o),
                    frame,
                    &mut self.delta,
                );
            }
        }
        replication.snapshot(&self.scene)
    }
}
