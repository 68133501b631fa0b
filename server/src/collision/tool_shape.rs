//! A tool's rigid geometry as the engine takes it: its collision shape and its shaft.
//!
//! Owns: [`ToolShapeSpec`], [`ShaftSpec`]. Must not: build colliders ([`super::ToolCollider`] does).

use crate::tissue::SurfaceMesh;

/// A tool's collision shape, mm.
#[derive(Debug, Clone, PartialEq)]
pub enum ToolShapeSpec {
    /// Ball.
    Sphere {
        /// Radius, mm.
        radius_mm: f32,
    },
    /// Capsule along the tool's local z.
    Capsule {
        /// Half segment length, mm.
        half_length_mm: f32,
        /// Radius, mm.
        radius_mm: f32,
    },
    /// A closed, rigid triangle mesh in the tool frame.
    Mesh(SurfaceMesh),
}

/// An instrument's shaft: a capsule from the tool origin `length_mm` up the tool's local +z (toward the hand),
/// `radius_mm` thick. It is blunt: it pushes the tissue it touches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShaftSpec {
    /// Radius, mm.
    pub radius_mm: f32,
    /// Length from the tool origin, mm.
    pub length_mm: f32,
}
