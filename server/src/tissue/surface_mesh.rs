//! A triangle surface: the plain data an object's or a tool's mesh is described by, in millimetres.
//!
//! Owns: [`SurfaceMesh`]. Must not: read files or validate (the world-file layer's `mesh_file` does both).

/// A triangle surface in millimetres.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMesh {
    /// Vertex positions, mm.
    pub positions_mm: Vec<[f32; 3]>,
    /// Triangles (vertex indices), counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}
