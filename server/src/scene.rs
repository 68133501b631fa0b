//! Scene descriptors: the plain values the simulation, the publisher and the exercise are built from. The
//! world file (`crate::world`) is one front end that validates TOML and produces a [`World`]; a test, a
//! bench or a tool builds one in code.
//!
//! Owns: [`World`] (a whole scene: rates, objects, tools, ties, the exercise), [`ToolSpec`] and the exercise's
//! descriptors. The parts' descriptors live with the layer that runs them (`tissue::ObjectSpec`,
//! `collision::ToolShapeSpec`, `interaction::InstrumentSpec`). Must not: read files, know TOML, or build
//! simulation state.

mod exercise_spec;
mod tool_spec;

use std::path::PathBuf;

pub use exercise_spec::{
    ExerciseKind, ExerciseSpec, PatternSpec, SUTURE_GAP_LIMIT_MM, SampleSpec, TargetSpec,
};
pub use tool_spec::ToolSpec;

use crate::tissue::{ObjectSpec, TieSet};

/// A validated world: everything the server needs to build the scene.
#[derive(Debug, Clone)]
pub struct World {
    /// The file it came from.
    pub source: PathBuf,
    /// Scene name (key segment).
    pub scene: String,
    /// Sim tick rate, Hz.
    pub tick_hz: f64,
    /// Mesh-delta / tool-state publish rate, Hz.
    pub publish_hz: f64,
    /// A device with no pose for this long has its tool released, seconds.
    pub pose_timeout_s: f64,
    /// Broad-phase loosening around each tool, mm.
    pub collision_margin_mm: f32,
    /// Uniform acceleration of every free node, mm/s^2 (default none: the tissue's anchors hold it).
    pub gravity_mm_per_s2: [f32; 3],
    /// `[sim] threads`: threads the tissue passes spread over, the tick's own included (`None`: what the
    /// machine can spare, `crate::world::default_tissue_threads`). Never changes a result, only the time.
    pub tissue_threads: Option<usize>,
    /// Tie-nodes between objects.
    pub ties: Vec<TieSet>,
    /// Deformable objects.
    pub objects: Vec<ObjectSpec>,
    /// Tools.
    pub tools: Vec<ToolSpec>,
    /// The training exercise (`[exercise]`), if the world is one.
    pub exercise: Option<ExerciseSpec>,
}
