//! Opening seams among elements: the vertex rings split into pieces, and each extra piece's elements
//! re-pointed to a new copy of the vertex.
//!
//! Owns: [`open_seams`], for triangles (edge facets) and tetrahedra (face facets) alike. Must not: touch
//! positions, masses, springs or surface triangles (the callers do, from the [`Opening`] it returns).

use super::*;

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
    let mut is_touched = vec![false; vertex_count as usize];
    for &v in &touched {
        if let Some(slot) = is_touched.get_mut(v as usize) {
            *slot = true;
        }
    }
    let mut ring: Vec<(u32, u32)> = Vec::new();
    for (e, element) in original.iter().enumerate() {
        for &v in element {
            if is_touched.get(v as usize).copied().unwrap_or(false) {
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
