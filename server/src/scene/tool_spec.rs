//! A tool as the engine takes it: its body, the device that drives it, its coupling and its instrument.
//!
//! Owns: [`ToolSpec`]. Must not: read files or build simulation state ([`crate::sim`] builds tools from it).

use crate::collision::{ShaftSpec, ToolShapeSpec};
use crate::haptics::CouplingParams;
use crate::interaction::InstrumentSpec;

/// A tool and the device that drives it.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Name.
    pub name: String,
    /// Device id bound to it (key segment).
    pub device_id: String,
    /// Collision shape.
    pub shape: ToolShapeSpec,
    /// Where the device frame's origin sits in the world, mm (device axes are world axes).
    pub device_origin_in_world_mm: [f32; 3],
    /// Largest force the server will ever send for this tool, N (the device's own maximum also applies).
    pub max_force_n: f32,
    /// How the tool follows its device pose (`coupling = { ... }`).
    pub coupling: CouplingParams,
    /// What the tool does beyond pushing (`instrument = { kind = ... }`; default a probe).
    pub instrument: InstrumentSpec,
    /// The instrument's shaft (`shaft = { radius_mm, length_mm }`), which pushes tissue as the tip does.
    pub shaft: Option<ShaftSpec>,
}
