//! A structured tetrahedral block: a grid of cubes, each split into six tetrahedra around its main diagonal
//! (Kuhn's subdivision, conforming across faces). For validation against analytic answers and for benches,
//! where a regular mesh makes the expected answer exact and the size easy to scale.

use super::mesh_file::MeshError;
use super::tet_mesh::TetMesh;
use crate::tissue::KUHN;

/// A block of `cells[0] x cells[1] x cells[2]` cubes of `spacing_mm`, from the origin along +x, +y, +z. Node
/// order and surface as [`TetMesh::from_tets`] makes them (surface nodes first).
pub fn tet_grid(cells: [usize; 3], spacing_mm: f32) -> Result<TetMesh, MeshError> {
    let index =
        |i: usize, j: usize, k: usize| (i + (cells[0] + 1) * (j + (cells[1] + 1) * k)) as u32;
    let mut positions = Vec::with_capacity((cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1));
    for k in 0..=cells[2] {
        for j in 0..=cells[1] {
            for i in 0..=cells[0] {
                positions.push([i as f32, j as f32, k as f32].map(|c| c * spacing_mm));
            }
        }
    }
    let mut tets = Vec::with_capacity(6 * cells[0] * cells[1] * cells[2]);
    for k in 0..cells[2] {
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                let corner = |b: usize| index(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
                tets.extend(KUHN.iter().map(|t| t.map(corner)));
            }
        }
    }
    TetMesh::from_tets(&positions, &tets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_fills_its_box_and_is_closed() {
        let mesh = tet_grid([3, 2, 4], 1.5).unwrap();
        assert_eq!(mesh.tets.len(), 6 * 24);
        assert_eq!(mesh.surface.positions_mm.len(), 4 * 3 * 5);
        assert!((mesh.volume_mm3() - 24.0 * 1.5f64.powi(3)).abs() < 1e-3);
        super::super::validate_closed(&mesh.surface).unwrap();
    }
}
