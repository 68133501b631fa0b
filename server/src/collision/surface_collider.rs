//! The tissue surface as a deformable parry TriMesh, and the broad phase over it.

use parry3d::bounding_volume::Aabb;
use parry3d::math::Vector;
use parry3d::shape::{TriMesh, TriMeshBuilderError, TriMeshFlags};

use super::glam_boundary::to_parry;
use crate::tissue::Vec3;

/// Per-node stamps that deduplicate candidate nodes without clearing or allocating.
#[derive(Debug, Clone)]
pub struct NodeMarks {
    stamps: Vec<u32>,
    current: u32,
}

impl NodeMarks {
    /// Marks for `n` nodes.
    pub fn new(n: usize) -> Self {
        Self {
            stamps: vec![0; n],
            current: 0,
        }
    }

    fn next_round(&mut self) {
        self.current = self.current.wrapping_add(1);
        if self.current == 0 {
            self.stamps.fill(0);
            self.current = 1;
        }
    }

    /// True the first time `i` is seen this round.
    fn first_visit(&mut self, i: u32) -> bool {
        let stamp = &mut self.stamps[i as usize];
        let first = *stamp != self.current;
        *stamp = self.current;
        first
    }
}

/// A deformable TriMesh (BVH refitted in place, never rebuilt; no ORIENTED flag: pseudo-normals would be
/// stale on a deforming mesh).
pub struct SurfaceCollider {
    mesh: TriMesh,
    vertices_scratch: Vec<Vector>,
}

impl std::fmt::Debug for SurfaceCollider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SurfaceCollider")
            .field("triangles", &self.mesh.num_triangles())
            .finish()
    }
}

impl SurfaceCollider {
    /// Build from positions and triangles (validated beforehand: indices in range).
    pub fn new(positions_mm: &[Vec3], triangles: &[[u32; 3]]) -> Result<Self, TriMeshBuilderError> {
        let vertices: Vec<Vector> = positions_mm.iter().map(to_parry).collect();
        let mesh = TriMesh::with_flags(
            vertices.clone(),
            triangles.to_vec(),
            TriMeshFlags::DEFORMABLE,
        )?;
        Ok(Self {
            mesh,
            vertices_scratch: vertices,
        })
    }

    /// Move the vertices and refit the BVH. No allocation (same vertex count).
    pub fn refit(&mut self, positions_mm: &[Vec3]) {
        for (dst, src) in self.vertices_scratch.iter_mut().zip(positions_mm) {
            *dst = to_parry(src);
        }
        self.mesh.set_vertices(&self.vertices_scratch);
    }

    /// The parry mesh (for narrow-phase queries).
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// Append to `out` every node of every triangle whose box overlaps `aabb` (each node once).
    /// No allocation once `out` has grown to the contact size.
    pub fn nodes_near(&self, aabb: &Aabb, marks: &mut NodeMarks, out: &mut Vec<u32>) {
        marks.next_round();
        let indices = self.mesh.indices();
        for tri in self.mesh.bvh().intersect_aabb(aabb) {
            for &v in &indices[tri as usize] {
                if marks.first_visit(v) {
                    out.push(v);
                }
            }
        }
    }
}
