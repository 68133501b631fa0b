//! World descriptions: the TOML file format, its validation, and mesh loading (OBJ surfaces, Gmsh tetrahedral
//! volumes, surfaces extruded into volumes).
//!
//! Owns: turning `worlds/*.toml` plus its mesh files into a validated [`World`]. Every refusal names the
//! file, the key and the line. Must not: keep simulation state (that is [`crate::sim`]'s job): the loader builds a
//! throwaway model of each explicitly integrated object only to check its `dt_s` against the stability bound, and
//! drops it.
//!
//! This is a front end: what it produces are the engine's own descriptors ([`crate::scene::World`],
//! [`crate::tissue::ObjectSpec`], [`crate::interaction::InstrumentSpec`], ...), re-exported here for the
//! callers that load files. Nothing in the engine imports this module.

mod extrude;
mod file_format;
mod grid_sheet;
mod loader;
mod material_presets;
mod mesh_file;
pub(crate) mod tet_grid;
mod tet_mesh;
mod volume_mesh_error;
mod world_error;

pub use extrude::{MAX_EXTRUDE_LAYERS, extrude_surface};
pub use file_format::{ElasticModel, LengthUnit};
pub use grid_sheet::{grid_sheet, to_obj_text};
pub use loader::{MAX_TISSUE_THREADS, default_tissue_threads, load_world, parse_world};
pub use material_presets::{MaterialPreset, PRESETS_TOML, material_presets};
pub use mesh_file::{MeshError, load_obj_mesh, validate_closed, validate_surface};
pub use tet_grid::tet_grid;
pub use tet_mesh::{TetMesh, load_msh_mesh, parse_msh};
pub use volume_mesh_error::VolumeMeshError;
pub use world_error::WorldError;

// The engine's descriptors this front end produces, re-exported for the callers that load files.
pub use crate::collision::{ShaftSpec, ToolShapeSpec};
pub use crate::interaction::{
    CauterySpec, GraspSpec, InstrumentSpec, JawActivation, ScalpelSpec, ScissorsSpec,
};
pub use crate::scene::{ExerciseKind, ExerciseSpec, SampleSpec, TargetSpec, ToolSpec, World};
pub use crate::tissue::{
    FixedSelection, IntegratorName, MassSpec, MaterialSpec, ObjectSpec, SpringCalibration,
    SurfaceMesh,
};
