//! Every message that crosses zenoh, one file each. Each struct's doc states direction, rate, reliability and units.

mod force;
mod hello;
pub mod local_model;
mod mesh_delta;
mod needle_geometry;
mod pose;
pub mod puncture_term;
mod snapshot;
mod stats;
mod tools;

pub use force::{ForceCommand, ForceMode};
pub use hello::{ParticipantHello, Role};
pub use local_model::{
    CUT_DRAG_SMOOTHING_MM_S, CUT_DRAG_TAU_S, ContactPlane, LocalModel, MAX_CONTACT_PLANES,
    MAX_FRICTION_COEFFICIENT, Sym3,
};
pub use mesh_delta::{MeshDelta, TopologyDelta};
pub use needle_geometry::needle_point_in_tool_mm;
pub use pose::{DevicePose, RenderMode};
pub use puncture_term::PunctureTerm;
pub use snapshot::{InstrumentInfo, ObjectSnapshot, SceneSnapshot, ToolInfo, ToolShaft, ToolShape};
pub use stats::{DeviceStats, ExerciseStats, RejectCounts, ServerStats, TargetMark, TrainingStats};
pub use tools::{HoleMark, NeedleState, ThreadState, ToolState, ToolStates};
