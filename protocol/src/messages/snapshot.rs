//! Scene snapshot: the whole replicated state, for late joiners and gap recovery.

use serde::{Deserialize, Serialize};

use super::tools::ToolStates;
use crate::codec::{FieldError, Message, MessageKind, check};
use crate::quantize::QuantBounds;

/// A tool's collision shape, millimetres, in the tool frame (capsule axis along local z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ToolShape {
    /// A ball of the given radius centred on the tool origin.
    Sphere {
        /// Radius, mm.
        radius_mm: f32,
    },
    /// A capsule along local z, centred on the tool origin.
    Capsule {
        /// Half the segment length, mm.
        half_length_mm: f32,
        /// Radius, mm.
        radius_mm: f32,
    },
    /// A closed triangle mesh (rigid), counter-clockwise seen from outside.
    Mesh {
        /// Vertex positions in the tool frame, mm.
        positions_mm: Vec<[f32; 3]>,
        /// Triangles (vertex indices).
        triangles: Vec<[u32; 3]>,
    },
}

impl ToolShape {
    /// Radius of a ball around the tool origin that contains the shape, mm.
    pub fn bounding_radius_mm(&self) -> f32 {
        match self {
            ToolShape::Sphere { radius_mm } => *radius_mm,
            ToolShape::Capsule {
                half_length_mm,
                radius_mm,
            } => half_length_mm + radius_mm,
            ToolShape::Mesh { positions_mm, .. } => positions_mm
                .iter()
                .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
                .fold(0.0, f32::max),
        }
    }
}

/// What a tool is beyond its shape, as viewers draw it. Protocol 6.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub enum InstrumentInfo {
    /// Its shape only.
    #[default]
    Probe,
    /// Two jaws: the shape's halves either side of the tool's local `y = 0` plane, hinged about its local x
    /// axis at the back of the shape; `ToolState.jaw_angle_rad` is their opening.
    Grasper {
        /// Length of each jaw, mm.
        jaw_length_mm: f32,
        /// Opening of the open jaws, rad.
        open_angle_rad: f32,
    },
    /// An active tip: the whole shape burns the surface it touches while its button is held
    /// (`MeshDelta.burn`).
    Cautery,
    /// A sharp edge, a segment in the tool frame, that cuts what it sweeps through (`MeshDelta.topology`);
    /// the shape is its blunt back. Protocol 7.
    Scalpel {
        /// One end of the edge, tool frame, mm.
        edge_from_mm: [f32; 3],
        /// The other end, tool frame, mm.
        edge_to_mm: [f32; 3],
    },
    /// Two sharp blades hinged about the tool's local x axis at `hinge_mm`, each `blade_length_mm` long along
    /// the tool's -z and turned by half of `ToolState.jaw_angle_rad` to either side (+y, -y); closing them cuts
    /// what lies between them (`MeshDelta.topology`). The shape probes. Protocol 8.
    Scissors {
        /// The hinge, tool frame, mm.
        hinge_mm: [f32; 3],
        /// Length of each blade from the hinge, mm.
        blade_length_mm: f32,
        /// Opening of the open blades, rad.
        open_angle_rad: f32,
    },
    /// Jaws (each `jaw_length_mm` along the tool's -z) holding a curved suture needle: an arc of
    /// `needle_radius_mm` sweeping `needle_sweep_rad` from its tail to its sharp tip, `needle_diameter_mm`
    /// thick, held `grasp_at_rad` from its tail at the tool origin, square to the jaws, its plane square to
    /// the tool's z ([`crate::needle_point_in_tool_mm`] places it). The shape (the jaws) probes; the tip
    /// punctures tissue. Protocol 13.
    NeedleDriver {
        /// Length of each jaw, mm.
        jaw_length_mm: f32,
        /// The needle's arc radius, mm.
        needle_radius_mm: f32,
        /// The needle's sweep, tail to tip, rad.
        needle_sweep_rad: f32,
        /// The needle's wire diameter, mm.
        needle_diameter_mm: f32,
        /// Where the jaws hold it: the angle from the tail, rad.
        grasp_at_rad: f32,
    },
}

/// Static description of a tool.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToolInfo {
    /// Tool index (matches [`crate::ToolState::tool`]).
    pub tool: u16,
    /// Tool name from the world file.
    pub name: String,
    /// Device id bound to it.
    pub device_id: String,
    /// Collision shape.
    pub shape: ToolShape,
    /// What it is (probe, grasper). Protocol 6.
    pub instrument: InstrumentInfo,
    /// Its shaft, which pushes tissue too. Protocol 8.
    pub shaft: Option<ToolShaft>,
}

/// An instrument's shaft: a capsule from the tool origin up the tool's local +z. Protocol 8.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ToolShaft {
    /// Radius, mm.
    pub radius_mm: f32,
    /// Length from the tool origin, mm.
    pub length_mm: f32,
}

/// One deformable object's full replicated state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectSnapshot {
    /// Object index (matches [`crate::MeshDelta::object`]).
    pub object: u16,
    /// Object name from the world file (also its key segment).
    pub name: String,
    /// Quantization bounds, fixed for the session.
    pub bounds: QuantBounds,
    /// Surface triangles, vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Quantized vertex positions.
    pub positions_q: Vec<[u16; 3]>,
    /// Frame of the last delta already folded into `positions_q`.
    pub frame: u64,
    /// Burn level of each vertex (0-255), or empty when nothing is burnt. Protocol 6.
    pub burn: Vec<u8>,
    /// Connectivity changes (cuts, tears) folded into `triangles` and `positions_q`; 0 for the world's own mesh.
    /// The next [`crate::TopologyDelta`] for this object has `epoch` one more. Protocol 7.
    pub topology_epoch: u32,
    /// How far a replica that applied every delta may be from the server's position of any vertex at its
    /// frame, mm: the server re-sends a vertex once it has moved more than its delta tolerance from what
    /// replicas hold, so this is that tolerance, or the quantization's bound when larger. Protocol 9.
    pub error_bound_mm: f32,
}

/// Everything a viewer (or a hapticserver) needs to start replicating.
///
/// Direction: server -> querier, as the reply to a zenoh query on `sinew/<scene>/snapshot`. Rate: on join and
/// after a detected gap. Reliability: query/reply. Units: see the fields.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneSnapshot {
    /// Scene name.
    pub scene: String,
    /// Publish frame the snapshot was taken at.
    pub frame: u64,
    /// Deformable objects.
    pub objects: Vec<ObjectSnapshot>,
    /// Tool descriptions.
    pub tools: Vec<ToolInfo>,
    /// Tool states at `frame`.
    pub tool_states: ToolStates,
}

impl Message for SceneSnapshot {
    const KIND: MessageKind = MessageKind::SceneSnapshot;
    fn validate(&self) -> Result<(), FieldError> {
        for (i, object) in self.objects.iter().enumerate() {
            if object.object as usize != i {
                return Err(("objects.object", "indices are not 0..n in order"));
            }
            object.bounds.validate()?;
            if !(object.error_bound_mm.is_finite() && object.error_bound_mm >= 0.0) {
                return Err((
                    "objects.error_bound_mm",
                    "not a finite non-negative distance",
                ));
            }
            let n = object.positions_q.len() as u64;
            if object
                .triangles
                .iter()
                .any(|t| t.iter().any(|&v| u64::from(v) >= n))
            {
                return Err(("objects.triangles", "vertex index out of range"));
            }
            if object.frame > self.frame {
                return Err(("objects.frame", "after the snapshot frame"));
            }
            if !object.burn.is_empty() && object.burn.len() as u64 != n {
                return Err(("objects.burn", "neither empty nor one level per vertex"));
            }
        }
        for tool in &self.tools {
            let dims: &[f32] = match &tool.shape {
                ToolShape::Sphere { radius_mm } => &[*radius_mm],
                ToolShape::Capsule {
                    half_length_mm,
                    radius_mm,
                } => &[*half_length_mm, *radius_mm],
                ToolShape::Mesh {
                    positions_mm,
                    triangles,
                } => {
                    if positions_mm
                        .iter()
                        .any(|p| p.iter().any(|c| !c.is_finite()))
                    {
                        return Err(("tools.shape", "mesh vertex not finite"));
                    }
                    let n = positions_mm.len() as u64;
                    if triangles.is_empty()
                        || triangles
                            .iter()
                            .any(|t| t.iter().any(|&v| u64::from(v) >= n))
                    {
                        return Err(("tools.shape", "mesh triangles empty or index out of range"));
                    }
                    &[]
                }
            };
            check::finite("tools.shape", dims)?;
            if dims.iter().any(|d| *d < 0.0) {
                return Err(("tools.shape", "negative dimension"));
            }
            if let InstrumentInfo::Grasper {
                jaw_length_mm,
                open_angle_rad,
            } = tool.instrument
            {
                check::finite("tools.instrument", &[jaw_length_mm, open_angle_rad])?;
                if jaw_length_mm <= 0.0 || !(0.0..=std::f32::consts::PI).contains(&open_angle_rad) {
                    return Err((
                        "tools.instrument",
                        "jaw length not positive or opening outside 0 to pi",
                    ));
                }
            }
            if let InstrumentInfo::Scalpel {
                edge_from_mm,
                edge_to_mm,
            } = tool.instrument
            {
                check::finite("tools.instrument", &edge_from_mm)?;
                check::finite("tools.instrument", &edge_to_mm)?;
            }
            if let InstrumentInfo::NeedleDriver {
                jaw_length_mm,
                needle_radius_mm,
                needle_sweep_rad,
                needle_diameter_mm,
                grasp_at_rad,
            } = tool.instrument
            {
                check::finite(
                    "tools.instrument",
                    &[
                        jaw_length_mm,
                        needle_radius_mm,
                        needle_sweep_rad,
                        needle_diameter_mm,
                        grasp_at_rad,
                    ],
                )?;
                if jaw_length_mm <= 0.0
                    || needle_radius_mm <= 0.0
                    || needle_diameter_mm <= 0.0
                    || !(needle_sweep_rad > 0.0 && needle_sweep_rad < std::f32::consts::TAU)
                    || !(0.0..=needle_sweep_rad).contains(&grasp_at_rad)
                {
                    return Err((
                        "tools.instrument",
                        "needle driver: a length not positive, a sweep outside 0 to 2 pi, or a grasp off the needle",
                    ));
                }
            }
            if let Some(shaft) = tool.shaft {
                check::finite("tools.shaft", &[shaft.radius_mm, shaft.length_mm])?;
                if shaft.radius_mm <= 0.0 || shaft.length_mm <= 0.0 {
                    return Err(("tools.shaft", "radius or length not positive"));
                }
            }
            if let InstrumentInfo::Scissors {
                hinge_mm,
                blade_length_mm,
                open_angle_rad,
            } = tool.instrument
            {
                check::finite("tools.instrument", &hinge_mm)?;
                check::finite("tools.instrument", &[blade_length_mm, open_angle_rad])?;
                if blade_length_mm <= 0.0 || !(0.0..=std::f32::consts::PI).contains(&open_angle_rad)
                {
                    return Err((
                        "tools.instrument",
                        "blade length not positive or opening outside 0 to pi",
                    ));
                }
            }
        }
        self.tool_states.validate()
    }
}
