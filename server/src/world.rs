//! World descriptions: the TOML file format, its validation, and mesh loading.
//!
//! Owns: turning `worlds/*.toml` plus its mesh files into a validated [`World`]. Every refusal names the
//! file, the key and the line. Must not: build simulation state (that is [`crate::sim`]'s job).

mod file_format;
mod loader;
mod mesh_file;

pub use file_format::{IntegratorName, LengthUnit};
pub use loader::{
    FixedSelection, MassSpec, MaterialSpec, ObjectSpec, ToolShapeSpec, ToolSpec, World, WorldError,
    load_world, parse_world,
};
pub use mesh_file::{MeshError, SurfaceMesh, load_obj_mesh, validate_closed, validate_surface};
