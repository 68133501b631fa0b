//! A volume's opened faces as surface: surface triangles re-pointed to their tetrahedra's new corners, and
//! one new outward triangle per side of every opened face.
//!
//! Owns: [`expose_volume_seams`]. Must not: open seams itself (that is `elements`) or change the
//! tetrahedra.

use super::*;
use crate::tissue::Vec3;

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
