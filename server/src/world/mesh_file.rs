//! Surface meshes: loading (tobj for OBJ) and the checks a deformable surface must pass.

use std::collections::HashMap;
use std::path::Path;

use thiserror::Error;

use crate::tissue::SurfaceMesh;

/// Why a mesh was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeshError {
    /// The loader could not read or parse it.
    #[error("cannot load: {0}")]
    Load(String),
    /// No triangles.
    #[error("mesh is empty (no triangles)")]
    Empty,
    /// A vertex with a NaN or infinite coordinate.
    #[error("vertex {0} has a non-finite coordinate")]
    NonFinite(usize),
    /// A triangle with a repeated vertex or zero area.
    #[error("triangle {0} is degenerate (repeated vertex or zero area)")]
    Degenerate(usize),
    /// An edge used by only one triangle, where a closed surface is required.
    #[error("not closed: edge ({a}, {b}) borders one triangle (a tool mesh must be watertight)")]
    Open {
        /// First vertex of the edge.
        a: u32,
        /// Second vertex of the edge.
        b: u32,
    },
    /// An edge shared by more than two triangles.
    #[error("non-manifold: edge ({a}, {b}) is shared by {count} triangles")]
    NonManifold {
        /// First vertex of the edge.
        a: u32,
        /// Second vertex of the edge.
        b: u32,
        /// Triangles sharing it.
        count: usize,
    },
    /// A tetrahedral volume mesh (a `.msh` file or an extrusion) that is not valid.
    #[error(transparent)]
    Volume(#[from] super::volume_mesh_error::VolumeMeshError),
}

/// Load an OBJ file (all its models merged), scaled by `scale_to_mm`, and validate it as a surface.
pub fn load_obj_mesh(path: &Path, scale_to_mm: f32) -> Result<SurfaceMesh, MeshError> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    if !path.is_file() {
        return Err(MeshError::Load(format!("no such file: {}", path.display())));
    }
    let (models, _materials) = tobj::load_obj(path, &options)
        .map_err(|e| MeshError::Load(format!("{}: {e}", path.display())))?;
    let mut mesh = SurfaceMesh {
        positions_mm: Vec::new(),
        triangles: Vec::new(),
    };
    for model in models {
        let base = mesh.positions_mm.len() as u32;
        mesh.positions_mm.extend(
            model
                .mesh
                .positions
                .chunks_exact(3)
                .map(|p| [p[0] * scale_to_mm, p[1] * scale_to_mm, p[2] * scale_to_mm]),
        );
        mesh.triangles.extend(
            model
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }
    validate_surface(&mesh)?;
    Ok(mesh)
}

/// Check that a validated surface is closed: every edge borders exactly two triangles.
pub fn validate_closed(mesh: &SurfaceMesh) -> Result<(), MeshError> {
    let mut edge_use: HashMap<(u32, u32), usize> = HashMap::with_capacity(mesh.triangles.len() * 2);
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (p, q) = (tri[k], tri[(k + 1) % 3]);
            *edge_use.entry((p.min(q), p.max(q))).or_insert(0) += 1;
        }
    }
    match edge_use
        .iter()
        .filter(|(_, c)| **c == 1)
        .map(|(e, _)| *e)
        .min()
    {
        Some((a, b)) => Err(MeshError::Open { a, b }),
        None => Ok(()),
    }
}

/// Check a surface: non-empty, finite, indices in range, no degenerate triangle, every edge shared by at
/// most two triangles.
pub fn validate_surface(mesh: &SurfaceMesh) -> Result<(), MeshError> {
    if mesh.triangles.is_empty() || mesh.positions_mm.is_empty() {
        return Err(MeshError::Empty);
    }
    if let Some(i) = mesh
        .positions_mm
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(MeshError::NonFinite(i));
    }
    let n = mesh.positions_mm.len();
    let mut edge_use: HashMap<(u32, u32), usize> = HashMap::with_capacity(mesh.triangles.len() * 2);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if tri.iter().any(|&v| v as usize >= n)
            || tri[0] == tri[1]
            || tri[1] == tri[2]
            || tri[0] == tri[2]
        {
            return Err(MeshError::Degenerate(t));
        }
        let [a, b, c] = tri.map(|v| mesh.positions_mm[v as usize]);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let cross = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let area2 = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        if area2 <= 1e-12 {
            return Err(MeshError::Degenerate(t));
        }
        for k in 0..3 {
            let (p, q) = (tri[k], tri[(k + 1) % 3]);
            *edge_use.entry((p.min(q), p.max(q))).or_insert(0) += 1;
        }
    }
    // Report the smallest offending edge so the message is deterministic.
    if let Some((&(a, b), &count)) = edge_use
        .iter()
        .filter(|(_, count)| **count > 2)
        .min_by_key(|(edge, _)| **edge)
    {
        return Err(MeshError::NonManifold { a, b, count });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> SurfaceMesh {
        SurfaceMesh {
            positions_mm: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn a_clean_quad_passes() {
        validate_surface(&quad()).unwrap();
    }

    #[test]
    fn empty_degenerate_and_non_manifold_are_refused() {
        let mut m = quad();
        m.triangles.clear();
        assert_eq!(validate_surface(&m), Err(MeshError::Empty));
        let mut m = quad();
        m.triangles.push([1, 1, 2]);
        assert_eq!(validate_surface(&m), Err(MeshError::Degenerate(2)));
        let mut m = quad();
        m.positions_mm.push([0.5, 0.5, 1.0]);
        m.triangles.push([0, 2, 4]);
        assert_eq!(
            validate_surface(&m),
            Err(MeshError::NonManifold {
                a: 0,
                b: 2,
                count: 3
            })
        );
        let mut m = quad();
        m.positions_mm[3][1] = f32::NAN;
        assert_eq!(validate_surface(&m), Err(MeshError::NonFinite(3)));
    }
}
