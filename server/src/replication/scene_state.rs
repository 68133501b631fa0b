//! The replicated scene as the publish thread and the snapshot queryable share it: every object's replica
//! state, the tools' static descriptions, the last tool states and the replication counters.
//!
//! Owns: [`ReplicationState`] (and what viewers need to draw an instrument, [`instrument_info`]). Pure state:
//! the server node guards it with a mutex and publishes from it; a debrief replays into it without a network.
//!
//! Must not: touch zenoh or threads.

use sinew_protocol::{SceneSnapshot, ToolInfo, ToolShape, ToolStates};

use super::ObjectReplication;
use crate::collision::ToolShapeSpec;
use crate::scene::World;
use crate::sim::Sim;

/// What has been replicated: per-object quantized state, tool states, counters. Guarded by a mutex shared
/// by the publish thread and the snapshot queryable (never by the sim thread).
#[derive(Debug)]
pub struct ReplicationState {
    /// Per object.
    pub objects: Vec<ObjectReplication>,
    /// Static tool descriptions.
    pub tools: Vec<ToolInfo>,
    /// Last publish frame.
    pub frame: u64,
    /// Last tool states published.
    pub tool_states: ToolStates,
    /// Mesh delta messages sent.
    pub deltas_sent: u64,
    /// Mesh delta bytes sent (encoded payloads).
    pub delta_bytes: u64,
    /// Snapshots served.
    pub snapshots_served: u64,
}

impl ReplicationState {
    /// Initial state: rest positions, frame 0.
    pub fn new(world: &World, sim: &Sim) -> Self {
        let objects = world
            .objects
            .iter()
            .zip(&sim.objects)
            .map(|(spec, o)| {
                ObjectReplication::new(
                    &o.name,
                    o.model.rest_positions_mm(),
                    o.model.triangles(),
                    spec.quant_margin_mm,
                    spec.delta_tolerance_mm,
                )
            })
            .collect();
        let tools = sim
            .tools
            .iter()
            .enumerate()
            .map(|(t, tool)| ToolInfo {
                tool: t as u16,
                name: tool.name.clone(),
                device_id: tool.device_id.clone(),
                shape: match &tool.shape_spec {
                    ToolShapeSpec::Sphere { radius_mm } => ToolShape::Sphere {
                        radius_mm: *radius_mm,
                    },
                    ToolShapeSpec::Capsule {
                        half_length_mm,
                        radius_mm,
                    } => ToolShape::Capsule {
                        half_length_mm: *half_length_mm,
                        radius_mm: *radius_mm,
                    },
                    ToolShapeSpec::Mesh(surface) => ToolShape::Mesh {
                        positions_mm: surface.positions_mm.clone(),
                        triangles: surface.triangles.clone(),
                    },
                },
                instrument: instrument_info(&tool.instrument),
                shaft: tool.shaft_spec.map(|s| sinew_protocol::ToolShaft {
                    radius_mm: s.radius_mm,
                    length_mm: s.length_mm,
                }),
            })
            .collect();
        Self {
            objects,
            tools,
            frame: 0,
            tool_states: ToolStates::default(),
            deltas_sent: 0,
            delta_bytes: 0,
            snapshots_served: 0,
        }
    }

    /// The whole replicated scene.
    pub fn snapshot(&self, scene: &str) -> SceneSnapshot {
        SceneSnapshot {
            scene: scene.to_owned(),
            frame: self.frame,
            objects: self
                .objects
                .iter()
                .enumerate()
                .map(|(i, o)| o.snapshot(i as u16))
                .collect(),
            tools: self.tools.clone(),
            tool_states: self.tool_states.clone(),
        }
    }
}

/// What viewers need to draw an instrument.
pub fn instrument_info(
    spec: &crate::interaction::InstrumentSpec,
) -> sinew_protocol::InstrumentInfo {
    match spec {
        crate::interaction::InstrumentSpec::Probe => sinew_protocol::InstrumentInfo::Probe,
        crate::interaction::InstrumentSpec::Grasper(g) => sinew_protocol::InstrumentInfo::Grasper {
            jaw_length_mm: g.jaw_length_mm,
            open_angle_rad: g.open_angle_rad,
        },
        crate::interaction::InstrumentSpec::Cautery(_) => sinew_protocol::InstrumentInfo::Cautery,
        crate::interaction::InstrumentSpec::Scissors(s) => {
            sinew_protocol::InstrumentInfo::Scissors {
                hinge_mm: s.hinge_mm,
                blade_length_mm: s.blade_length_mm,
                open_angle_rad: s.open_angle_rad,
            }
        }
        crate::interaction::InstrumentSpec::NeedleDriver(n) => {
            sinew_protocol::InstrumentInfo::NeedleDriver {
                jaw_length_mm: n.jaw_length_mm,
                needle_radius_mm: n.arc.radius_mm(),
                needle_sweep_rad: n.arc.sweep_rad(),
                needle_diameter_mm: n.diameter_mm,
                grasp_at_rad: n.grasp_at_rad,
            }
        }
        crate::interaction::InstrumentSpec::Scalpel(s) => sinew_protocol::InstrumentInfo::Scalpel {
            edge_from_mm: s.edge_mm[0],
            edge_to_mm: s.edge_mm[1],
        },
    }
}
