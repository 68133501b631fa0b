//! Tetrahedral volume meshes: [`TetMesh`], the boundary surface of a set of tetrahedra, and reading Gmsh
//! `.msh` files (MSH 4.1, ASCII or binary, through `mshio`).
//!
//! Owns: the checks a volume mesh must pass (at least one tetrahedron, every node defined and finite, no
//! degenerate tetrahedron, no face shared by more than two tetrahedra, no two tetrahedra on the same side of
//! a shared face), orienting every tetrahedron positively, and computing the surface: the faces used by exactly
//! one tetrahedron, wound outward (normal away from the tetrahedron's fourth vertex), so it is closed and
//! consistent by construction. A file's own surface triangles are ignored. Nodes no tetrahedron uses are
//! dropped; the rest are renumbered surface nodes first, then interior nodes, each group in file order (so
//! the nodes a viewer draws form a prefix). Must not: know the world file format or build simulation state.
//!
//! Limitation (mshio 0.4): when a file's node tags are dense (`max - min + 1 == count`), mshio drops them and
//! the tag of a node is `min_node_tag` plus its running index in block order. Gmsh always writes dense tags in
//! that order; a hand-edited file listing dense tags out of order would be misread (its tetrahedra would then
//! almost surely fail the degenerate or overlap checks). Sparse tags are read as written.

use std::path::Path;

use mshio::{ElementType, MshParserError};

use super::mesh_file::{MeshError, validate_surface};
use super::volume_mesh_error::VolumeMeshError;
use crate::tissue::SurfaceMesh;

/// A tetrahedral volume mesh in millimetres.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    /// Every node (surface nodes first, then interior nodes, which no triangle references) and the boundary
    /// triangles, counter-clockwise seen from outside.
    pub surface: SurfaceMesh,
    /// Tetrahedra over `surface.positions_mm`, positively oriented: the fourth vertex lies on the side
    /// `(b - a) x (c - a)` points to.
    pub tets: Vec<[u32; 4]>,
}

impl TetMesh {
    /// Build from node positions and tetrahedra (any orientation); node and element ids in errors are the
    /// 0-based indices.
    pub fn from_tets(positions_mm: &[[f32; 3]], tets: &[[u32; 4]]) -> Result<Self, MeshError> {
        build(positions_mm, tets, u64::from, |e| e as u64)
    }

    /// Nodes `0..surface_node_count()` are the ones the surface triangles use; the rest are interior.
    pub fn surface_node_count(&self) -> usize {
        self.surface
            .triangles
            .iter()
            .flatten()
            .max()
            .map_or(0, |&m| m as usize + 1)
    }

    /// Sum of the tetrahedra's volumes, mm^3.
    pub fn volume_mm3(&self) -> f64 {
        self.tets
            .iter()
            .map(|t| signed_volume_mm3(&self.surface.positions_mm, *t))
            .sum()
    }
}

/// Signed volume of a tetrahedron, mm^3, in f64 (positive when `d` lies where `(b - a) x (c - a)` points).
pub(crate) fn signed_volume_mm3(positions_mm: &[[f32; 3]], tet: [u32; 4]) -> f64 {
    let [a, b, c, d] = tet.map(|i| positions_mm[i as usize].map(f64::from));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
    let cross = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    (cross[0] * w[0] + cross[1] * w[1] + cross[2] * w[2]) / 6.0
}

/// Whether a positively oriented tetrahedron's volume is too small to simulate: below the `1e-9` mm^3 the
/// volume term drops, or below `1e-7` of its longest edge cubed (a regular one has about 0.118).
pub(crate) fn too_flat(positions_mm: &[[f32; 3]], tet: [u32; 4], volume_mm3: f64) -> bool {
    let mut longest_sq = 0.0f64;
    for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
        let (p, q) = (positions_mm[tet[i] as usize], positions_mm[tet[j] as usize]);
        let d: f64 = (0..3)
            .map(|k| (f64::from(p[k]) - f64::from(q[k])).powi(2))
            .sum();
        longest_sq = longest_sq.max(d);
    }
    volume_mm3 <= 1e-9 || volume_mm3 <= 1e-7 * longest_sq * longest_sq.sqrt()
}

/// Outward faces of a positively oriented tetrahedron `[0, 1, 2, 3]`, by local vertex index (face `k` is
/// opposite vertex `k`).
const OUTWARD_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// The rotation of a triangle that starts at its smallest vertex (same winding).
fn canonical(f: [u32; 3]) -> [u32; 3] {
    let k = (0..3).min_by_key(|&k| f[k]).unwrap_or(0);
    [f[k], f[(k + 1) % 3], f[(k + 2) % 3]]
}

/// Validate, orient, extract the boundary and renumber. `node_id` and `element_id` name nodes and
/// tetrahedra in errors.
fn build(
    positions_mm: &[[f32; 3]],
    tets: &[[u32; 4]],
    node_id: impl Fn(u32) -> u64,
    element_id: impl Fn(usize) -> u64,
) -> Result<TetMesh, MeshError> {
    if tets.is_empty() {
        return Err(VolumeMeshError::NoTetrahedra.into());
    }
    if u32::try_from(positions_mm.len()).is_err() {
        return Err(VolumeMeshError::TooManyNodes {
            nodes: positions_mm.len(),
        }
        .into());
    }
    let n = positions_mm.len();
    let mut oriented = Vec::with_capacity(tets.len());
    for (e, &tet) in tets.iter().enumerate() {
        if let Some(&node) = tet.iter().find(|&&v| v as usize >= n) {
            return Err(VolumeMeshError::UnknownNode {
                element: element_id(e),
                node: u64::from(node),
            }
            .into());
        }
        if let Some(&node) = tet
            .iter()
            .find(|&&v| positions_mm[v as usize].iter().any(|c| !c.is_finite()))
        {
            return Err(VolumeMeshError::NonFiniteNode {
                node: node_id(node),
            }
            .into());
        }
        let mut tet = tet;
        let mut volume = signed_volume_mm3(positions_mm, tet);
        if volume < 0.0 {
            tet.swap(2, 3);
            volume = -volume;
        }
        let repeated = (0..4).any(|i| (i + 1..4).any(|j| tet[i] == tet[j]));
        if repeated || too_flat(positions_mm, tet, volume) {
            return Err(VolumeMeshError::DegenerateTet {
                element: element_id(e),
            }
            .into());
        }
        oriented.push(tet);
    }

    // Every face as (sorted nodes, tet, local face); runs of equal keys are the tets sharing a face.
    let mut faces: Vec<([u32; 3], u32, u8)> = Vec::with_capacity(oriented.len() * 4);
    for (t, tet) in oriented.iter().enumerate() {
        for (k, face) in OUTWARD_FACES.iter().enumerate() {
            let mut key = face.map(|i| tet[i]);
            key.sort_unstable();
            faces.push((key, t as u32, k as u8));
        }
    }
    faces.sort_unstable();
    let outward = |t: u32, k: u8| OUTWARD_FACES[k as usize].map(|i| oriented[t as usize][i]);
    let mut boundary: Vec<(u32, u8)> = Vec::new();
    let mut start = 0;
    while start < faces.len() {
        let mut end = start + 1;
        while end < faces.len() && faces[end].0 == faces[start].0 {
            end += 1;
        }
        let (_, t, k) = faces[start];
        match end - start {
            1 => boundary.push((t, k)),
            2 => {
                let (_, u, l) = faces[start + 1];
                // Neighbours on opposite sides see the shared face with opposite windings.
                let [a, b, c] = canonical(outward(t, k));
                if canonical(outward(u, l)) != [a, c, b] {
                    return Err(VolumeMeshError::Overlap {
                        a: element_id(t as usize),
                        b: element_id(u as usize),
                    }
                    .into());
                }
            }
            count => {
                return Err(VolumeMeshError::NonManifoldFace {
                    element: element_id(t as usize),
                    count,
                }
                .into());
            }
        }
        start = end;
    }
    boundary.sort_unstable();

    // Renumber: surface nodes first, then interior nodes, each in input order; unused nodes dropped.
    const UNUSED: u8 = 0;
    const INTERIOR: u8 = 1;
    const SURFACE: u8 = 2;
    let mut kind = vec![UNUSED; n];
    for tet in &oriented {
        for &v in tet {
            kind[v as usize] = INTERIOR;
        }
    }
    for &(t, k) in &boundary {
        for v in outward(t, k) {
            kind[v as usize] = SURFACE;
        }
    }
    let mut new_index = vec![u32::MAX; n];
    let mut positions = Vec::with_capacity(n);
    for wanted in [SURFACE, INTERIOR] {
        for (old, _) in kind.iter().enumerate().filter(|(_, k)| **k == wanted) {
            new_index[old] = positions.len() as u32;
            positions.push(positions_mm[old]);
        }
    }
    let remap = |v: u32| new_index[v as usize];
    let surface = SurfaceMesh {
        positions_mm: positions,
        triangles: boundary
            .iter()
            .map(|&(t, k)| outward(t, k).map(remap))
            .collect(),
    };
    validate_surface(&surface)?;
    Ok(TetMesh {
        surface,
        tets: oriented.iter().map(|t| t.map(remap)).collect(),
    })
}

/// Read a Gmsh MSH 4.1 file (ASCII or binary), scale it by `scale_to_mm`, and build its [`TetMesh`].
pub fn load_msh_mesh(path: &Path, scale_to_mm: f32) -> Result<TetMesh, MeshError> {
    if !path.is_file() {
        return Err(MeshError::Load(format!("no such file: {}", path.display())));
    }
    let bytes =
        std::fs::read(path).map_err(|e| MeshError::Load(format!("{}: {e}", path.display())))?;
    parse_msh(path, &bytes, scale_to_mm)
}

/// Parse MSH 4.1 bytes (`name` labels parse errors, which give the line and byte where parsing stopped).
pub fn parse_msh(name: &Path, bytes: &[u8], scale_to_mm: f32) -> Result<TetMesh, MeshError> {
    // mshio has a few `unwrap`s on malformed headers (e.g. a data size that overflows): contain them so a bad
    // file is an error, never a crash of the server.
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|e| describe_parse_error(name, bytes, &e))
    })
    .map_err(|_| {
        MeshError::Load(format!(
            "{}: not a valid MSH 4.1 file (the parser gave up on its header)",
            name.display()
        ))
    })?;
    let msh = parsed.map_err(MeshError::Load)?;

    // Nodes as (tag, position), sorted by tag for lookup.
    let mut tagged: Vec<(u64, [f64; 3])> = Vec::new();
    if let Some(nodes) = &msh.data.nodes {
        let mut next_dense_tag = nodes.min_node_tag;
        for (b, block) in nodes.node_blocks.iter().enumerate() {
            match &block.node_tags {
                Some(tags) => {
                    if tags.len() != block.nodes.len() {
                        return Err(VolumeMeshError::DuplicateNode { block: b }.into());
                    }
                    for (&tag, &index) in tags {
                        if let Some(p) = block.nodes.get(index) {
                            tagged.push((tag, [p.x, p.y, p.z]));
                        }
                    }
                }
                None => {
                    for p in &block.nodes {
                        tagged.push((next_dense_tag, [p.x, p.y, p.z]));
                        next_dense_tag += 1;
                    }
                }
            }
        }
    }
    tagged.sort_unstable_by_key(|(tag, _)| *tag);
    if tagged.windows(2).any(|w| w[0].0 == w[1].0) {
        return Err(VolumeMeshError::DuplicateNode { block: 0 }.into());
    }
    let scale = f64::from(scale_to_mm);
    let positions_mm: Vec<[f32; 3]> = tagged
        .iter()
        .map(|(_, p)| p.map(|c| (c * scale) as f32))
        .collect();

    let mut tets: Vec<[u32; 4]> = Vec::new();
    let mut element_tags: Vec<u64> = Vec::new();
    for block in msh.data.elements.iter().flat_map(|e| &e.element_blocks) {
        match block.element_type {
            ElementType::Tet4 => {
                for element in &block.elements {
                    let mut tet = [0u32; 4];
                    for (slot, &node) in tet.iter_mut().zip(&element.nodes) {
                        let index = tagged
                            .binary_search_by_key(&node, |(tag, _)| *tag)
                            .map_err(|_| VolumeMeshError::UnknownNode {
                                element: element.element_tag,
                                node,
                            })?;
                        *slot =
                            u32::try_from(index).map_err(|_| VolumeMeshError::TooManyNodes {
                                nodes: tagged.len(),
                            })?;
                    }
                    tets.push(tet);
                    element_tags.push(element.element_tag);
                }
            }
            // Points, lines and surface elements: ignored (the surface comes from the tetrahedra).
            other if block.entity_dim == 3 => {
                return Err(VolumeMeshError::UnsupportedElement {
                    element: block.elements.first().map_or(0, |e| e.element_tag),
                    kind: format!("{other:?}"),
                }
                .into());
            }
            _ => {}
        }
    }
    build(
        &positions_mm,
        &tets,
        |n| tagged.get(n as usize).map_or(u64::from(n), |(tag, _)| *tag),
        |e| element_tags.get(e).copied().unwrap_or(e as u64),
    )
}

/// mshio's error without its hex dump of the rest of the file: `name:line: what (in section > block > ...)`.
fn describe_parse_error(name: &Path, bytes: &[u8], error: &MshParserError<&[u8]>) -> String {
    let trace = error.filtered_backtrace();
    let Some((rest, kind)) = trace.first() else {
        return format!("{}: not a valid MSH 4.1 file", name.display());
    };
    // mshio parses some blocks as sub-slices, so locate the error by address rather than remaining length.
    let offset = (rest.as_ptr() as usize)
        .checked_sub(bytes.as_ptr() as usize)
        .filter(|&o| o <= bytes.len())
        .unwrap_or_else(|| bytes.len().saturating_sub(rest.len()));
    let line = bytes[..offset].iter().filter(|&&b| b == b'\n').count() + 1;
    let within: Vec<String> = trace[1..]
        .iter()
        .rev()
        .map(|(_, k)| k.to_string())
        .collect();
    let hint = if matches!(
        kind,
        mshio::error::MshParserErrorKind::UnsupportedMshVersion
    ) {
        " (re-export with Mesh.MshFileVersion = 4.1)"
    } else {
        ""
    };
    format!(
        "{}:{line} (byte {offset}): {kind}{hint}{}",
        name.display(),
        if within.is_empty() {
            String::new()
        } else {
            format!(" (in {})", within.join(" > "))
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::validate_closed;

    /// Two tetrahedra sharing the face (1, 2, 3), the second listed inverted.
    fn two_tets() -> (Vec<[f32; 3]>, Vec<[u32; 4]>) {
        (
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
            vec![[0, 1, 2, 3], [1, 2, 3, 4]],
        )
    }

    #[test]
    fn two_tets_give_a_closed_outward_boundary_of_six_triangles() {
        let (p, t) = two_tets();
        let mesh = TetMesh::from_tets(&p, &t).unwrap();
        assert_eq!(mesh.surface.triangles.len(), 6);
        validate_closed(&mesh.surface).unwrap();
        assert!(
            mesh.tets
                .iter()
                .all(|t| signed_volume_mm3(&mesh.surface.positions_mm, *t) > 0.0)
        );
        let enclosed: f64 = mesh
            .surface
            .triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|v| mesh.surface.positions_mm[v as usize].map(f64::from));
                (a[0] * (b[1] * c[2] - b[2] * c[1])
                    + a[1] * (b[2] * c[0] - b[0] * c[2])
                    + a[2] * (b[0] * c[1] - b[1] * c[0]))
                    / 6.0
            })
            .sum();
        assert!(
            (enclosed - mesh.volume_mm3()).abs() < 1e-9,
            "{enclosed} vs {}",
            mesh.volume_mm3()
        );
        assert_eq!(
            mesh.surface_node_count(),
            5,
            "all five nodes are on the surface"
        );
    }

    #[test]
    fn degenerate_overlapping_and_non_manifold_sets_are_refused() {
        let (mut p, t) = two_tets();
        assert_eq!(
            TetMesh::from_tets(&p, &[]),
            Err(VolumeMeshError::NoTetrahedra.into())
        );
        assert_eq!(
            TetMesh::from_tets(&p, &[[0, 1, 2, 2]]),
            Err(VolumeMeshError::DegenerateTet { element: 0 }.into())
        );
        assert_eq!(
            TetMesh::from_tets(&p, &[[0, 1, 2, 9]]),
            Err(VolumeMeshError::UnknownNode {
                element: 0,
                node: 9
            }
            .into())
        );
        // A fifth node on the same side of (1, 2, 3) as node 0: the two tets overlap.
        p[4] = [0.1, 0.1, 0.1];
        assert_eq!(
            TetMesh::from_tets(&p, &t),
            Err(VolumeMeshError::Overlap { a: 0, b: 1 }.into())
        );
        p.push([1.0, 1.0, 1.0]);
        p[4] = [-1.0, 0.5, 0.5];
        let three = [[0, 1, 2, 3], [1, 2, 3, 5], [1, 2, 3, 4]];
        assert!(matches!(
            TetMesh::from_tets(&p, &three),
            Err(MeshError::Volume(VolumeMeshError::NonManifoldFace {
                count: 3,
                ..
            }))
        ));
        p[3][0] = f32::NAN;
        assert_eq!(
            TetMesh::from_tets(&p, &t[..1]),
            Err(VolumeMeshError::NonFiniteNode { node: 3 }.into())
        );
    }

    #[test]
    fn interior_nodes_come_after_surface_nodes_and_unused_nodes_are_dropped() {
        // A tetrahedron split into four around an interior point, plus an unused node.
        let p = vec![
            [9.0, 9.0, 9.0],
            [0.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [0.0, 3.0, 0.0],
            [0.0, 0.0, 3.0],
            [0.5, 0.5, 0.5],
        ];
        let centre = 5;
        let t = [
            [1, 2, 3, centre],
            [1, 2, 4, centre],
            [1, 3, 4, centre],
            [2, 3, 4, centre],
        ];
        let mesh = TetMesh::from_tets(&p, &t).unwrap();
        assert_eq!(mesh.surface.positions_mm.len(), 5);
        assert_eq!(mesh.surface_node_count(), 4);
        assert_eq!(mesh.surface.positions_mm[4], [0.5, 0.5, 0.5]);
        assert_eq!(mesh.surface.positions_mm[0], [0.0, 0.0, 0.0]);
        assert_eq!(mesh.surface.triangles.len(), 4);
        validate_closed(&mesh.surface).unwrap();
        assert!((mesh.volume_mm3() - 4.5).abs() < 1e-9);
    }
}
