//! Why a tetrahedral volume mesh (a `.msh` file or an extrusion) was refused.
//!
//! Owns: [`VolumeMeshError`]. Its own file so the surface checks ([`super::mesh_file`], whose [`MeshError`]
//! wraps it) and the volume loaders ([`super::tet_mesh`], [`super::extrude`]) both import it, neither the other.
//!
//! [`MeshError`]: super::mesh_file::MeshError

use thiserror::Error;

/// Why a volume mesh was refused. Node and element numbers are the file's tags (0-based indices for meshes
/// built in memory, such as an extrusion).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VolumeMeshError {
    /// No linear tetrahedra at all.
    #[error(
        "no tetrahedra: a volume mesh needs at least one linear tetrahedron (Gmsh element type 4)"
    )]
    NoTetrahedra,
    /// A volume element other than a linear tetrahedron.
    #[error(
        "element {element} is a {kind}: only linear tetrahedra (Gmsh type 4) are supported as volume elements \
         (export first-order tetrahedra, e.g. Mesh.ElementOrder = 1)"
    )]
    UnsupportedElement {
        /// Element tag.
        element: u64,
        /// mshio's name of the element type.
        kind: String,
    },
    /// A tetrahedron names a node the file does not define.
    #[error("element {element} references node {node}, which the file does not define")]
    UnknownNode {
        /// Element tag.
        element: u64,
        /// Node tag.
        node: u64,
    },
    /// A node block repeats a node tag.
    #[error("node block {block} repeats a node tag")]
    DuplicateNode {
        /// 0-based block index.
        block: usize,
    },
    /// A node with a NaN or infinite coordinate (after unit scaling).
    #[error("node {node} has a non-finite coordinate")]
    NonFiniteNode {
        /// Node tag.
        node: u64,
    },
    /// A tetrahedron with a repeated node or (nearly) zero volume.
    #[error("tetrahedron {element} is degenerate (repeated node or zero volume)")]
    DegenerateTet {
        /// Element tag.
        element: u64,
    },
    /// More than two tetrahedra share a face.
    #[error(
        "a face of tetrahedron {element} is shared by {count} tetrahedra (at most two may share a face)"
    )]
    NonManifoldFace {
        /// Element tag of one of them.
        element: u64,
        /// Tetrahedra sharing it.
        count: usize,
    },
    /// Two tetrahedra share a face and lie on the same side of it: they overlap (a tangled mesh).
    #[error("tetrahedra {a} and {b} overlap: they lie on the same side of their shared face")]
    Overlap {
        /// Element tag.
        a: u64,
        /// Element tag.
        b: u64,
    },
    /// The node count does not fit the u32 indices the simulation uses.
    #[error("{nodes} nodes: too many (at most {} fit)", u32::MAX)]
    TooManyNodes {
        /// Nodes asked for.
        nodes: usize,
    },
    /// An extrusion turns a prism inside out (too thick for the surface's curvature, or folded normals).
    #[error(
        "extrusion folds at triangle {triangle}, layer {layer}: the thickness is too large for the surface's \
         curvature there"
    )]
    ExtrusionFolds {
        /// 0-based triangle index in the surface mesh.
        triangle: usize,
        /// 0-based layer (0 = next to the surface).
        layer: u32,
    },
    /// A surface vertex whose triangles' normals cancel: no direction to extrude along.
    #[error("vertex {vertex} has no normal (its triangles' normals cancel): nowhere to extrude it")]
    NoNormal {
        /// 0-based vertex index in the surface mesh.
        vertex: usize,
    },
}
