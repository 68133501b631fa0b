//! Collision with parry3d, in millimetres.
//!
//! Owns: the tissue surface as an owned parry `Bvh` over its triangles, refitted every tick (whole, or around
//! the nodes that moved), the broad phase that finds the tissue nodes near a tool (BVH query), tool shapes
//! and their point projection, where a moving point crosses a surface ([`crossing_nearest`]), where two
//! surfaces meet and the face of one a point of the other lies under ([`nearest_face`]), how deep a surface
//! triangle reaches into a ball or capsule tool ([`triangle_contact`]), and the one boundary
//! where nalgebra meets parry's glam types
//! ([`glam_boundary`]). Must not: move nodes or compute forces (that is [`crate::interaction`]).

pub mod glam_boundary;
mod segment_crossing;
mod surface_collider;
mod surface_pair;
mod tool_collider;
mod tool_shape;
mod tool_triangle;

pub use segment_crossing::{SurfaceCrossing, crossing_nearest};
pub use surface_collider::{NodeMarks, SurfaceCollider, SurfaceColliderError};
pub use surface_pair::{
    EDGE_TOLERANCE, FACING_COS, NearFace, meeting_box, nearest_face, project_on_face,
};
pub use tool_collider::{ContactSide, ToolCollider};
pub use tool_shape::{ShaftSpec, ToolShapeSpec};
pub use tool_triangle::{
    TriangleContact, closest_point_on_triangle, core_point_nearest, triangle_contact,
};
