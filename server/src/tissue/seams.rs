//! Seams: opening a cut or a tear along the faces between elements, with ids that never change.
//!
//! Owns: the topological half of a cut. A seam is a facet shared by two elements: an edge between two
//! triangles of a sheet, or a face between two tetrahedra of a volume. Opening seams separates the elements
//! either side: every vertex whose ring of elements the seams split into several pieces is duplicated, one copy
//! per extra piece, and that piece's elements are re-pointed to the copy. Nothing is split or subdivided, so no
//! short edge or light node appears (every integrator stays within the step the world was checked for), and
//! the cut follows the mesh's own facets.
//!
//! Stable ids: a vertex keeps its id for ever and new vertices are appended, each with the id of the vertex it
//! was split from (its parent); an element keeps its index and its slot (only its corners change); surface
//! triangles of a volume that a seam exposes are appended. An attachment (triangle and barycentric weights)
//! made before a cut is therefore still valid after it, and follows the side its triangle went to.
//!
//! Must not: know about tools, blades or forces (the seams come from `interaction::cut`), or renumber anything.
//!
//! Here: facets, what an opening changed, and the facet queries the parts share. Opening seams among
//! elements is in `elements`; exposing a volume's opened faces as surface triangles in `surface`; the
//! model with seams opened (masses and springs shared out again) in `parts`.

mod elements;
mod parts;
mod surface;

pub use elements::open_seams;
pub use parts::{open_model, open_model_into, open_parts};
pub use surface::expose_volume_seams;

/// A facet's vertex ids in increasing order: an edge is `[a, b, NO_VERTEX]`, a face `[a, b, c]`.
pub type Facet = [u32; 3];

/// The filler of an edge's third slot in a [`Facet`].
pub const NO_VERTEX: u32 = u32::MAX;

/// An edge as a facet.
pub fn edge_facet(a: u32, b: u32) -> Facet {
    [a.min(b), a.max(b), NO_VERTEX]
}

/// A face as a facet.
pub fn face_facet(a: u32, b: u32, c: u32) -> Facet {
    let mut f = [a, b, c];
    f.sort_unstable();
    f
}

/// What opening seams changed.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Opening {
    /// Id of the first new vertex (the vertex count before the opening).
    pub first_new_vertex: u32,
    /// Parent of each new vertex, in id order: new vertex `first_new_vertex + k` was split from `parents[k]`.
    pub parents: Vec<u32>,
    /// Elements whose corners changed, in increasing order.
    pub changed_elements: Vec<u32>,
    /// Surface triangles whose corners changed (volumes; a sheet's elements are its triangles), in order.
    pub changed_triangles: Vec<u32>,
    /// Index of the first surface triangle appended (the triangle count before the opening).
    pub first_new_triangle: u32,
    /// Seams that were opened (a facet that is not shared by two elements is not a seam, and is skipped).
    pub seams_opened: usize,
}

impl Opening {
    /// Number of vertices added.
    pub fn new_vertices(&self) -> usize {
        self.parents.len()
    }

    /// Whether anything changed.
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }
}

/// The facet of `element` opposite corner `skip`: the sorted ids of the corners other than `skip` (an edge of a
/// triangle, a face of a tetrahedron).
pub fn facet_without<const K: usize>(element: &[u32; K], skip: usize) -> Facet {
    let mut f = [NO_VERTEX; 3];
    let mut n = 0;
    for (k, &v) in element.iter().enumerate() {
        if k != skip {
            f[n] = v;
            n += 1;
        }
    }
    f[..n].sort_unstable();
    f
}

/// Whether `element` has every vertex of `facet`.
fn facet_has<const K: usize>(element: &[u32; K], facet: &Facet) -> bool {
    facet
        .iter()
        .filter(|&&v| v != NO_VERTEX)
        .all(|v| element.contains(v))
}

/// Whether two elements of `model` (tetrahedra of a volume, else triangles) share `facet`: whether it is
/// still a seam that could open.
pub fn shared_by_two(model: &super::MassSpringModel, facet: &Facet) -> bool {
    let v = facet[0] as usize;
    if v >= model.node_count() {
        return false;
    }
    let tets = &model.tets().tets;
    let sharing = if tets.is_empty() {
        model
            .node_triangles(v)
            .iter()
            .filter(|&&t| facet_has(&model.triangles()[t as usize], facet))
            .count()
    } else {
        model
            .node_tets(v)
            .iter()
            .filter(|&&t| facet_has(&tets[t as usize], facet))
            .count()
    };
    sharing >= 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tissue::Vec3;

    /// A 3 x 2 grid of squares split into triangles: vertices `y * 4 + x`.
    fn strip() -> Vec<[u32; 3]> {
        let mut t = Vec::new();
        for y in 0..2u32 {
            for x in 0..3u32 {
                let v = y * 4 + x;
                t.push([v, v + 1, v + 5]);
                t.push([v, v + 5, v + 4]);
            }
        }
        t
    }

    #[test]
    fn a_seam_across_a_sheet_splits_its_vertices_and_keeps_every_id() {
        let mut tris = strip();
        let before = tris.clone();
        // The vertical line x = 1 from the top to the bottom edge: edges (1,5) and (5,9).
        let seams = [edge_facet(1, 5), edge_facet(5, 9)];
        let opening = open_seams(&mut tris, 12, &seams);
        assert_eq!(opening.seams_opened, 2);
        assert_eq!(opening.parents, vec![1, 5, 9]);
        assert_eq!(tris.len(), before.len());
        // The left column (triangles 0, 1, 6, 7) keeps the old ids; the rest use the copies.
        for t in [0usize, 1, 6, 7] {
            assert_eq!(tris[t], before[t]);
        }
        for t in [2usize, 3, 8, 9] {
            assert!(
                tris[t].iter().all(|v| ![1, 5, 9].contains(v)),
                "{:?}",
                tris[t]
            );
        }
        // The two sides share no vertex any more.
        let left: Vec<u32> = [0usize, 1, 6, 7].iter().flat_map(|&t| tris[t]).collect();
        let right: Vec<u32> = (0..tris.len())
            .filter(|t| ![0, 1, 6, 7].contains(t))
            .flat_map(|t| tris[t])
            .collect();
        assert!(left.iter().all(|v| !right.contains(v)));
    }

    #[test]
    fn a_seam_that_stops_inside_leaves_a_crack_tip_and_a_boundary_edge_is_no_seam() {
        let mut tris = strip();
        // From the top edge to the middle vertex 5 only: 1 splits, 5 is the tip and stays whole.
        let opening = open_seams(&mut tris, 12, &[edge_facet(1, 5)]);
        assert_eq!(opening.parents, vec![1]);
        let mut tris = strip();
        let opening = open_seams(&mut tris, 12, &[edge_facet(0, 1)]);
        assert!(opening.is_empty() && opening.seams_opened == 0);
        assert_eq!(tris, strip());
    }

    #[test]
    fn an_opened_face_between_two_tetrahedra_becomes_two_outward_surface_triangles() {
        // Two tetrahedra on either side of the face (0, 1, 2).
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.2, 0.2, 1.0),
            Vec3::new(0.2, 0.2, -1.0),
        ];
        let before = vec![[0u32, 1, 2, 3], [0, 2, 1, 4]];
        let mut tets = before.clone();
        let mut surface = vec![
            [0u32, 1, 3],
            [1, 2, 3],
            [2, 0, 3],
            [0, 4, 1],
            [1, 4, 2],
            [2, 4, 0],
        ];
        let seams = [face_facet(0, 1, 2)];
        let mut opening = open_seams(&mut tets, 5, &seams);
        assert_eq!(opening.parents, vec![0, 1, 2]);
        expose_volume_seams(&before, &tets, &seams, &p, &mut surface, &mut opening);
        assert_eq!(opening.first_new_triangle, 6);
        assert_eq!(surface.len(), 8);
        assert_eq!(opening.changed_triangles, vec![3, 4, 5]);
        // Each new triangle points away from its own tetrahedron's apex.
        let q = |v: u32| {
            if v < 5 {
                p[v as usize]
            } else {
                p[(v - 5) as usize]
            }
        };
        for (tri, apex) in [(surface[6], 3u32), (surface[7], 4)] {
            let n = (q(tri[1]) - q(tri[0])).cross(&(q(tri[2]) - q(tri[0])));
            assert!(n.dot(&(q(tri[0]) - p[apex as usize])) > 0.0, "{tri:?}");
        }
        // The lower tetrahedron and its surface use only the copies of 0, 1, 2.
        assert!(tets[1].iter().all(|&v| v >= 4));
        assert!(surface[3..6].iter().flatten().all(|&v| v >= 4));
    }
}
