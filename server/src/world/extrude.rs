//! Extruding a surface mesh into a layer of tetrahedra: a sheet given a thickness.
//!
//! Owns: offsetting every surface vertex inward (along minus its area-weighted normal) in `layers` equal
//! steps to `thickness_mm`, and splitting each prism (one per triangle per layer) into three positively
//! oriented tetrahedra. Each quad side of a prism is cut along the diagonal from its vertex with the smallest
//! global index, the rule that makes neighbouring prisms agree (Dompierre et al. 1999), so the tetrahedra
//! conform. The result is a [`TetMesh`]: its surface is the tetrahedra's boundary (the original surface on
//! top, the inner surface, and side walls along open borders), so it is closed. Must not: read files or know
//! the world format.

use super::mesh_file::MeshError;
use super::tet_mesh::{TetMesh, signed_volume_mm3, too_flat};
use super::volume_mesh_error::VolumeMeshError;
use crate::tissue::SurfaceMesh;

/// Most layers an extrusion may have.
pub const MAX_EXTRUDE_LAYERS: u32 = 16;

/// Extrude a validated surface by `thickness_mm` inward in `layers` layers (`3 * triangles * layers`
/// tetrahedra). Layer `k` of vertex `v` is node `k * n + v` before the [`TetMesh`] renumbering, which keeps
/// the original surface's vertices first and in order (as long as every vertex is on a triangle).
pub fn extrude_surface(
    surface: &SurfaceMesh,
    thickness_mm: f32,
    layers: u32,
) -> Result<TetMesh, MeshError> {
    let n = surface.positions_mm.len();
    let node_count = n.saturating_mul(layers as usize + 1);
    if u32::try_from(node_count).is_err() {
        return Err(VolumeMeshError::TooManyNodes { nodes: node_count }.into());
    }
    // Area-weighted vertex normals (sum of the triangles' cross products), in f64.
    let p = |v: u32| surface.positions_mm[v as usize].map(f64::from);
    let mut normal_sum = vec![[0.0f64; 3]; n];
    // Sum of the triangles' |cross| per vertex (0: on no triangle), to tell cancelling normals apart.
    let mut area_sum = vec![0.0f64; n];
    for tri in &surface.triangles {
        let [a, b, c] = tri.map(p);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let cross = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        let area = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        for &v in tri {
            area_sum[v as usize] += area;
            for k in 0..3 {
                normal_sum[v as usize][k] += cross[k];
            }
        }
    }
    let mut inward = vec![[0.0f64; 3]; n];
    for (v, ((dir, s), area)) in inward
        .iter_mut()
        .zip(&normal_sum)
        .zip(&area_sum)
        .enumerate()
    {
        let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        if len > 1e-6 * area {
            *dir = s.map(|c| -c / len);
        } else if *area > 0.0 {
            return Err(VolumeMeshError::NoNormal { vertex: v }.into());
        }
    }
    let step_mm = f64::from(thickness_mm) / f64::from(layers.max(1));
    let mut positions_mm = Vec::with_capacity(node_count);
    for k in 0..=layers {
        let depth_mm = step_mm * f64::from(k);
        for (q, dir) in surface.positions_mm.iter().zip(&inward) {
            positions_mm.push([0, 1, 2].map(|a| (f64::from(q[a]) + dir[a] * depth_mm) as f32));
        }
    }

    let mut tets = Vec::with_capacity(surface.triangles.len() * 3 * layers as usize);
    for k in 0..layers {
        let (top, bottom) = (k * n as u32, (k + 1) * n as u32);
        for (t, tri) in surface.triangles.iter().enumerate() {
            let mut sorted = *tri;
            sorted.sort_unstable();
            let [v0, v1, v2] = sorted;
            // Sorting keeps the winding when it is a rotation of the triangle.
            let same_winding = [
                [tri[0], tri[1], tri[2]],
                [tri[1], tri[2], tri[0]],
                [tri[2], tri[0], tri[1]],
            ]
            .contains(&sorted);
            let (a0, a1, a2) = (top + v0, top + v1, top + v2);
            let (b0, b1, b2) = (bottom + v0, bottom + v1, bottom + v2);
            // Diagonals a0-b1, a1-b2, a0-b2 (smallest top vertex to the other's bottom vertex).
            let prism = if same_winding {
                [[a0, a2, a1, b2], [a0, a1, b1, b2], [a0, b0, b2, b1]]
            } else {
                [[a0, a1, a2, b2], [a0, a1, b2, b1], [a0, b0, b1, b2]]
            };
            for tet in prism {
                let volume = signed_volume_mm3(&positions_mm, tet);
                if volume <= 0.0 || too_flat(&positions_mm, tet, volume) {
                    return Err(VolumeMeshError::ExtrusionFolds {
                        triangle: t,
                        layer: k,
                    }
                    .into());
                }
                tets.push(tet);
            }
        }
    }
    TetMesh::from_tets(&positions_mm, &tets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::validate_closed;

    /// An `n` x `n` cell sheet of `cell` mm squares on z = 0, normal +z, diagonals alternating.
    fn sheet(n: usize, cell: f32) -> SurfaceMesh {
        crate::world::grid_sheet(n, n, cell)
    }

    #[test]
    fn a_flat_sheet_extrudes_to_positive_tets_with_volume_area_times_thickness() {
        let surface = sheet(6, 2.0);
        for layers in [1, 2, 3] {
            let mesh = extrude_surface(&surface, 3.0, layers).unwrap();
            assert_eq!(
                mesh.tets.len(),
                3 * surface.triangles.len() * layers as usize
            );
            assert!(
                mesh.tets
                    .iter()
                    .all(|t| signed_volume_mm3(&mesh.surface.positions_mm, *t) > 0.0)
            );
            let expected = 12.0 * 12.0 * 3.0;
            assert!((mesh.volume_mm3() - expected).abs() < 0.01 * expected);
            validate_closed(&mesh.surface).unwrap();
            // Top, bottom, and 4 walls of 6 cells x layers quads.
            assert_eq!(
                mesh.surface.triangles.len(),
                2 * surface.triangles.len() + 4 * 6 * 2 * layers as usize
            );
            // The original vertices keep their indices and positions.
            assert_eq!(mesh.surface.positions_mm[..49], surface.positions_mm[..]);
            let deepest = mesh
                .surface
                .positions_mm
                .iter()
                .map(|p| p[2])
                .fold(0.0, f32::min);
            assert!(
                (deepest + 3.0).abs() < 1e-6,
                "extruded along minus the normal"
            );
        }
    }

    #[test]
    fn the_split_conforms_whatever_the_triangle_winding_and_numbering() {
        // Reversed windings and shuffled indices: every interior face must still be shared by exactly two
        // tets on opposite sides (TetMesh checks both) and the volume must add up.
        let mut surface = sheet(4, 1.0);
        let perm: Vec<u32> = (0..25u32).map(|v| (v * 7) % 25).collect();
        let mut shuffled = vec![[0.0; 3]; 25];
        for (old, &new) in perm.iter().enumerate() {
            shuffled[new as usize] = surface.positions_mm[old];
        }
        surface.positions_mm = shuffled;
        for tri in &mut surface.triangles {
            *tri = tri.map(|v| perm[v as usize]);
            tri.rotate_left(1);
        }
        let mesh = extrude_surface(&surface, 1.5, 2).unwrap();
        assert!((mesh.volume_mm3() - 16.0 * 1.5).abs() < 1e-4);
        validate_closed(&mesh.surface).unwrap();
    }

    #[test]
    fn too_thick_a_shell_on_a_sharp_fold_is_refused() {
        // A roof: two 1.4 mm slopes meeting at a 90 degree ridge; 10 mm inward the feet cross over.
        let surface = SurfaceMesh {
            positions_mm: vec![
                [0.0, -1.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, -1.0, 1.0],
                [1.0, 1.0, 1.0],
                [2.0, -1.0, 0.0],
                [2.0, 1.0, 0.0],
            ],
            triangles: vec![[0, 2, 3], [0, 3, 1], [2, 4, 5], [2, 5, 3]],
        };
        assert!(extrude_surface(&surface, 0.1, 1).is_ok());
        assert!(matches!(
            extrude_surface(&surface, 10.0, 1),
            Err(MeshError::Volume(VolumeMeshError::ExtrusionFolds { .. }))
        ));
    }
}
