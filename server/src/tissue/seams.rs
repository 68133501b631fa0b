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

use super::Vec3;

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

/// The facet two elements share, if they share `K - 1` corners.
fn shared_facet<const K: usize>(a: &[u32; K], b: &[u32; K]) -> Option<Facet> {
    (0..K)
        .find(|&skip| !b.contains(&a[skip]))
        .map(|skip| facet_without(a, skip))
        .filter(|f| f.iter().filter(|&&v| v != NO_VERTEX).all(|v| b.contains(v)))
}

/// Smallest root, path-halving union-find over a fan's few elements.
fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Open `seams` among `elements` (`K` = 3: triangles and edge facets; `K` = 4: tetrahedra and face facets).
/// `vertex_count` is the number of vertices before; new vertex ids follow it. Elements are rewritten in place;
/// nothing else is touched. Deterministic: vertices are visited in id order, and in each vertex's ring the piece
/// holding the lowest element id keeps the vertex.
pub fn open_seams<const K: usize>(
    elements: &mut [[u32; K]],
    vertex_count: u32,
    seams: &[Facet],
) -> Opening {
    let mut seams: Vec<Facet> = seams.to_vec();
    seams.sort_unstable();
    seams.dedup();
    let original: Vec<[u32; K]> = elements.to_vec();
    let is_seam = |f: &Facet| seams.binary_search(f).is_ok();

    // Rings of the vertices on a seam: (vertex, element), sorted.
    let mut touched: Vec<u32> = seams
        .iter()
        .flatten()
        .copied()
        .filter(|&v| v != NO_VERTEX)
        .collect();
    touched.sort_unstable();
    touched.dedup();
    let mut ring: Vec<(u32, u32)> = Vec::new();
    for (e, element) in original.iter().enumerate() {
        for &v in element {
            if touched.binary_search(&v).is_ok() {
                ring.push((v, e as u32));
            }
        }
    }
    ring.sort_unstable();

    // A seam is opened when two elements share it.
    let mut seams_opened = 0;
    for seam in &seams {
        let Some(&(_, first)) = ring
            .iter()
            .find(|(v, e)| *v == seam[0] && facet_has(&original[*e as usize], seam))
        else {
            continue;
        };
        let shared = ring
            .iter()
            .any(|&(v, e)| v == seam[0] && e != first && facet_has(&original[e as usize], seam));
        seams_opened += usize::from(shared);
    }

    let mut opening = Opening {
        first_new_vertex: vertex_count,
        seams_opened,
        ..Opening::default()
    };
    let mut renames: Vec<(u32, u32, u32)> = Vec::new(); // (element, old vertex, new vertex)
    let mut start = 0;
    let mut parent: Vec<usize> = Vec::new();
    while start < ring.len() {
        let v = ring[start].0;
        let end = start + ring[start..].iter().take_while(|(w, _)| *w == v).count();
        let fan: Vec<u32> = ring[start..end].iter().map(|&(_, e)| e).collect();
        start = end;
        parent.clear();
        parent.extend(0..fan.len());
        for i in 0..fan.len() {
            for j in i + 1..fan.len() {
                let (a, b) = (&original[fan[i] as usize], &original[fan[j] as usize]);
                if let Some(f) = shared_facet(a, b)
                    && f.contains(&v)
                    && !is_seam(&f)
                {
                    let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                    parent[ri.max(rj)] = ri.min(rj);
                }
            }
        }
        // Pieces in order of their lowest element (the fan is sorted, so a piece's root is its lowest).
        let mut piece_vertex: Vec<(usize, u32)> = Vec::new();
        for (i, &element) in fan.iter().enumerate() {
            let root = find(&mut parent, i);
            if root == 0 {
                continue; // the first piece keeps the vertex
            }
            let id = match piece_vertex.iter().find(|(r, _)| *r == root) {
                Some(&(_, id)) => id,
                None => {
                    let id = vertex_count + opening.parents.len() as u32;
                    opening.parents.push(v);
                    piece_vertex.push((root, id));
                    id
                }
            };
            renames.push((element, v, id));
        }
    }
    for &(e, old, new) in &renames {
        for corner in &mut elements[e as usize] {
            if *corner == old {
                *corner = new;
            }
        }
        opening.changed_elements.push(e);
    }
    opening.changed_elements.sort_unstable();
    opening.changed_elements.dedup();
    opening
}

/// Whether `element` has every vertex of `facet`.
fn facet_has<const K: usize>(element: &[u32; K], facet: &Facet) -> bool {
    facet
        .iter()
        .filter(|&&v| v != NO_VERTEX)
        .all(|v| element.contains(v))
}

/// After [`open_seams`] on a volume's tetrahedra (`before` as they were, `tets` as they are now): re-point
/// each surface triangle to the corners its tetrahedron now has, and append, for every opened face, one
/// surface triangle per side, wound outward from its tetrahedron (`rest_positions_mm` decides the side).
/// Fills `opening.changed_triangles` and `opening.first_new_triangle`.
pub fn expose_volume_seams(
    before: &[[u32; 4]],
    tets: &[[u32; 4]],
    seams: &[Facet],
    rest_positions_mm: &[Vec3],
    triangles: &mut Vec<[u32; 3]>,
    opening: &mut Opening,
) {
    opening.first_new_triangle = triangles.len() as u32;
    if opening.changed_elements.is_empty() {
        return;
    }
    // Faces of the changed tetrahedra, as they were: (facet, tet).
    let mut faces: Vec<(Facet, u32)> = Vec::new();
    for &t in &opening.changed_elements {
        for skip in 0..4 {
            faces.push((facet_without(&before[t as usize], skip), t));
        }
    }
    faces.sort_unstable();
    let renamed = |t: u32, old: u32| -> u32 {
        let k = before[t as usize]
            .iter()
            .position(|&v| v == old)
            .unwrap_or(0);
        tets[t as usize][k]
    };
    for (i, tri) in triangles.iter_mut().enumerate() {
        let key = face_facet(tri[0], tri[1], tri[2]);
        let Ok(at) = faces.binary_search_by(|(f, _)| f.cmp(&key)) else {
            continue;
        };
        let t = faces[at].1;
        let new = tri.map(|v| renamed(t, v));
        if new != *tri {
            *tri = new;
            opening.changed_triangles.push(i as u32);
        }
    }
    let mut seams: Vec<Facet> = seams.to_vec();
    seams.sort_unstable();
    seams.dedup();
    for seam in &seams {
        let sides: Vec<u32> = faces
            .iter()
            .filter(|(f, _)| f == seam)
            .map(|&(_, t)| t)
            .collect();
        let mut shared: Vec<u32> = Vec::new();
        for (t, tet) in before.iter().enumerate() {
            if shared.len() == 2 {
                break;
            }
            if facet_has(tet, seam) {
                shared.push(t as u32);
            }
        }
        if shared.len() != 2 || sides.is_empty() {
            continue; // not an interior face, or nothing moved there
        }
        let mut now = shared.iter().map(|&t| {
            let mut f = seam.map(|v| renamed(t, v));
            f.sort_unstable();
            f
        });
        if now.next() == now.next() {
            continue; // its tetrahedra changed elsewhere, and still share it: not open yet
        }
        for &t in &shared {
            let tet = before[t as usize];
            let apex = tet.iter().find(|v| !seam.contains(v)).copied().unwrap_or(0);
            let [a, b, c] = [seam[0], seam[1], seam[2]];
            let p = |v: u32| rest_positions_mm[v as usize];
            let outward = (p(b) - p(a)).cross(&(p(c) - p(a))).dot(&(p(a) - p(apex))) > 0.0;
            let wound = if outward { [a, b, c] } else { [a, c, b] };
            triangles.push(wound.map(|v| renamed(t, v)));
        }
    }
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

/// `model` with `seams` opened: the parts of the model to rebuild, and what changed. New vertices start at
/// their parent's rest position, fixed if it was; each parent's mass is shared among it and its copies by the
/// area (sheets) or volume (volumes) of the elements each now has, so the total mass is kept. Springs are the
/// unique edges of the elements again, each with the stiffness and damping of the spring between the parents
/// of its ends. A cut surface is no longer closed, so the global volume term is turned off once anything opens.
/// Allocates: for a cut or tear, not the steady tick.
pub fn open_model(model: &super::MassSpringModel, seams: &[Facet]) -> (super::ModelParts, Opening) {
    let mut parts = super::ModelParts::default();
    let opening = open_model_into(model, seams, &mut parts);
    (parts, opening)
}

/// [`open_model`] into `parts`, reusing its buffers: the sim keeps one per object, so a cut does not fault in
/// fresh pages for a whole model's worth of arrays.
pub fn open_model_into(
    model: &super::MassSpringModel,
    seams: &[Facet],
    parts: &mut super::ModelParts,
) -> Opening {
    model.to_parts_into(parts);
    let n = parts.rest_positions_mm.len() as u32;
    let volume = !parts.tets.is_empty();
    let mut opening = if volume {
        let before = parts.tets.clone();
        let mut opening = open_seams(&mut parts.tets, n, seams);
        expose_volume_seams(
            &before,
            &parts.tets,
            seams,
            &parts.rest_positions_mm,
            &mut parts.triangles,
            &mut opening,
        );
        opening
    } else {
        let mut opening = open_seams(&mut parts.triangles, n, seams);
        opening.changed_triangles = opening.changed_elements.clone();
        opening.first_new_triangle = parts.triangles.len() as u32;
        opening
    };
    if opening.is_empty() {
        opening.changed_elements.clear();
        opening.changed_triangles.clear();
        return opening;
    }
    let parent = |v: u32| -> u32 {
        if v < n {
            v
        } else {
            opening.parents[(v - n) as usize]
        }
    };
    for &p in &opening.parents {
        let rest = parts.rest_positions_mm[p as usize];
        let fixed = parts.fixed[p as usize];
        parts.rest_positions_mm.push(rest);
        parts.fixed.push(fixed);
        parts.mass_kg.push(0.0);
    }

    // Masses: each family (a parent and its copies) shares the parent's mass by element measure.
    let total = parts.rest_positions_mm.len();
    let mut measure = vec![0.0f32; total];
    let rest = &parts.rest_positions_mm;
    if volume {
        for tet in &parts.tets {
            let v = super::volume::tet_volume_mm3(rest, *tet).abs() / 4.0;
            for &i in tet {
                measure[i as usize] += v;
            }
        }
    } else {
        for tri in &parts.triangles {
            let [a, b, c] = tri.map(|v| rest[v as usize]);
            let area = 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            for &i in tri {
                measure[i as usize] += area;
            }
        }
    }
    let mut family = vec![0.0f32; n as usize];
    for v in 0..total as u32 {
        family[parent(v) as usize] += measure[v as usize];
    }
    let mut families: Vec<u32> = opening.parents.clone();
    families.sort_unstable();
    families.dedup();
    for v in 0..total as u32 {
        let p = parent(v);
        if families.binary_search(&p).is_err() || family[p as usize] <= 0.0 {
            continue;
        }
        let m = model.mass_kg()[p as usize];
        parts.mass_kg[v as usize] = m * measure[v as usize] / family[p as usize];
    }

    // Springs: an edge no changed element has keeps its spring. The edges of the changed elements, before and
    // after, are reconsidered: each takes the stiffness and damping of the spring between its ends' parents,
    // scaled by the share of that spring's elements it now borders (an edge a seam split between two sides
    // gives each side's copy half, so a split vertex, with half the mass, keeps the stiffness-to-mass ratio and
    // the stable step it had); one no element has any more is gone.
    let (old_tets, old_triangles) = (&model.tets().tets, model.triangles());
    let (new_tets, new_triangles) = (&parts.tets, &parts.triangles);
    let old_element = |e: usize| -> &[u32] {
        if volume {
            &old_tets[e]
        } else {
            &old_triangles[e]
        }
    };
    let new_element = |e: usize| -> &[u32] {
        if volume {
            &new_tets[e]
        } else {
            &new_triangles[e]
        }
    };
    let new_count = if volume {
        new_tets.len()
    } else {
        new_triangles.len()
    };
    let mut affected: Vec<[u32; 2]> = Vec::new();
    for &e in &opening.changed_elements {
        for element in [old_element(e as usize), new_element(e as usize)] {
            for (i, &p) in element.iter().enumerate() {
                for &q in &element[i + 1..] {
                    affected.push([p.min(q), p.max(q)]);
                }
            }
        }
    }
    affected.sort_unstable();
    affected.dedup();
    let mut ends: Vec<u32> = affected.iter().flatten().copied().collect();
    ends.sort_unstable();
    ends.dedup();
    let mut ring: Vec<(u32, u32)> = Vec::new();
    for e in 0..new_count {
        for &v in new_element(e) {
            if ends.binary_search(&v).is_ok() {
                ring.push((v, e as u32));
            }
        }
    }
    ring.sort_unstable();
    let now_count = |[a, b]: [u32; 2]| -> usize {
        let from = ring.partition_point(|&(v, _)| v < a);
        ring[from..]
            .iter()
            .take_while(|&&(v, _)| v == a)
            .filter(|&&(_, e)| new_element(e as usize).contains(&b))
            .count()
    };
    let was_count = |[a, b]: [u32; 2]| -> usize {
        let around = if volume {
            model.node_tets(a as usize)
        } else {
            model.node_triangles(a as usize)
        };
        around
            .iter()
            .filter(|&&e| old_element(e as usize).contains(&b))
            .count()
    };
    let mut reconsidered: Vec<([u32; 2], f32, f32)> = Vec::with_capacity(affected.len());
    for &edge in &affected {
        let now = now_count(edge);
        if now == 0 {
            continue;
        }
        let (pa, pb) = (parent(edge[0]), parent(edge[1]));
        let key = [pa.min(pb), pa.max(pb)];
        let Ok(s) = parts.edges.binary_search(&key) else {
            continue; // no spring joined the parents (an edge of a new surface triangle only)
        };
        let was = was_count(key);
        let share = if was == 0 {
            1.0
        } else {
            (now as f32 / was as f32).min(1.0)
        };
        reconsidered.push((
            edge,
            parts.edge_stiffness_n_per_mm[s] * share,
            parts.edge_damping_n_s_per_mm[s] * share,
        ));
    }
    // Merge the kept springs (in order) with the reconsidered ones (in order).
    let total = parts.edges.len() + reconsidered.len();
    let (mut edges, mut stiffness, mut damping) = (
        Vec::with_capacity(total),
        Vec::with_capacity(total),
        Vec::with_capacity(total),
    );
    let mut next = reconsidered.iter().peekable();
    for (s, &edge) in parts.edges.iter().enumerate() {
        while let Some(&&(e, k, c)) = next.peek() {
            if e > edge {
                break;
            }
            edges.push(e);
            stiffness.push(k);
            damping.push(c);
            next.next();
        }
        if affected.binary_search(&edge).is_ok() {
            continue;
        }
        edges.push(edge);
        stiffness.push(parts.edge_stiffness_n_per_mm[s]);
        damping.push(parts.edge_damping_n_s_per_mm[s]);
    }
    for &(e, k, c) in next {
        edges.push(e);
        stiffness.push(k);
        damping.push(c);
    }
    parts.edges = edges;
    parts.edge_stiffness_n_per_mm = stiffness;
    parts.edge_damping_n_s_per_mm = damping;
    parts.global_bulk_modulus_n_per_mm2 = 0.0;
    opening
}

#[cfg(test)]
mod tests {
    use super::*;

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
