//! A thread's segment against a tissue's edge: a segment whose two nodes lie outside a surface but whose
//! middle cuts through it (drawn across an edge or a corner of the tissue, where no node is there to meet a
//! face) is put back out.
//!
//! Owns: [`keep_segment_out`]. The node contacts (`thread.rs`) keep every node out of the surfaces; between
//! two nodes 2.3 mm apart a segment drawn taut round an edge cuts the corner, and a thread dragged off a block
//! hooked under it with one segment through the whole block (found by the coiling test in
//! `server/tests/suture_thread.rs`). The test: the segment's first crossing into the surface from each end
//! (`collision::crossing_nearest`, the triangles as they are now); the part between the two lies inside. Its
//! middle goes out along the sum of the two faces' outward normals (round the edge), to the thread's radius
//! outside both faces' planes, the push spread over the two nodes by their weights at that point and their
//! inverse masses (the minimum-norm position correction), as the self contact spreads its pushes.
//!
//! Not covered: a segment through a sheet thinner than the segment (entry and exit faces facing opposite ways:
//! no way round is told), which the node contacts' continuous test prevents from happening in the first place
//! unless a node is stuck on the far side.
//!
//! Must not: allocate or panic; a degenerate segment or triangle is left alone.

use crate::collision::{SurfaceCollider, crossing_nearest};
use crate::tissue::Vec3;

/// How loose the broad phase's boxes are taken for the crossing tests, mm.
const MARGIN_MM: f32 = 0.5;
/// The most a middle is moved in one substep, mm (a segment deep in a tissue goes out over several).
const MAX_PUSH_MM: f32 = 2.0;
/// The least cosine between the push and either face's normal: faces nearer opposite than this tell no way
/// round.
const MIN_COSINE: f32 = 0.1;

/// Put the segment `a b` (nodes of inverse masses `wa`, `wb`) back out of the surface `triangles` at
/// `positions_mm` (through `collider`'s tree) if it cuts through it between its nodes, `radius_mm` clear of
/// both faces it crosses (module doc). Returns whether it moved the segment. No allocation.
#[allow(clippy::too_many_arguments)] // the segment, and one surface as the sim holds it
pub fn keep_segment_out(
    a: &mut Vec3,
    b: &mut Vec3,
    wa: f32,
    wb: f32,
    collider: &SurfaceCollider,
    triangles: &[[u32; 3]],
    positions_mm: &[Vec3],
    radius_mm: f32,
) -> bool {
    if wa + wb <= 0.0 || (wa + wb).is_nan() {
        return false;
    }
    // The first crossing into the surface walking from one node toward the other.
    let first_entry = |from: &Vec3, to: &Vec3| {
        crossing_nearest(
            collider,
            triangles,
            positions_mm,
            from,
            to,
            MARGIN_MM,
            0.0,
            Some(true),
        )
    };
    let (Some(into), Some(out)) = (first_entry(a, b), first_entry(b, a)) else {
        return false;
    };
    let (from, to) = (into.along, 1.0 - out.along);
    if to <= from {
        return false;
    }
    let normal = |t: u32| {
        let [i, j, k] = *triangles.get(t as usize)?;
        let p = |i: u32| positions_mm.get(i as usize).copied();
        let (p0, p1, p2) = (p(i)?, p(j)?, p(k)?);
        (p1 - p0).cross(&(p2 - p0)).try_normalize(1e-12)
    };
    let (Some(n_in), Some(n_out)) = (normal(into.triangle), normal(out.triangle)) else {
        return false;
    };
    let Some(push) = (n_in + n_out).try_normalize(1e-6) else {
        return false;
    };
    let m = 0.5 * (from + to);
    let middle = *a + (*b - *a) * m;
    let mut depth_mm = 0.0f32;
    for (place, n) in [(into.point_mm, n_in), (out.point_mm, n_out)] {
        let cosine = push.dot(&n);
        if cosine < MIN_COSINE {
            return false;
        }
        depth_mm = depth_mm.max((radius_mm - (middle - place).dot(&n)) / cosine);
    }
    let depth_mm = depth_mm.min(MAX_PUSH_MM);
    let sum = wa * (1.0 - m) * (1.0 - m) + wb * m * m;
    if !(depth_mm > 0.0 && sum > 0.0) {
        return false;
    }
    let lambda = depth_mm / sum;
    *a += push * (lambda * wa * (1.0 - m));
    *b += push * (lambda * wb * m);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube [0, 1]^3's surface, wound counter-clockwise seen from outside.
    fn cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        let quads = [
            [0, 2, 3, 1], // z = 0, facing -z
            [4, 5, 7, 6], // z = 1, +z
            [0, 1, 5, 4], // y = 0, -y
            [2, 6, 7, 3], // y = 1, +y
            [0, 4, 6, 2], // x = 0, -x
            [1, 3, 7, 5], // x = 1, +x
        ];
        let t = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (p, t)
    }

    #[test]
    fn a_segment_cutting_a_cubes_edge_goes_round_it() {
        let (p, t) = cube();
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        // From over the top (z = 1) to beside the +x face, cutting the edge x = 1, z = 1 at y = 0.5.
        let mut a = Vec3::new(0.6, 0.5, 1.2);
        let mut b = Vec3::new(1.2, 0.5, 0.6);
        assert!(keep_segment_out(
            &mut a, &mut b, 1.0, 1.0, &collider, &t, &p, 0.05
        ));
        // Its middle now lies outside both faces' planes by the radius, pushed along (+x +z).
        let middle = 0.5 * (a + b);
        assert!(
            middle.x >= 1.05 - 1e-4 || middle.z >= 1.05 - 1e-4,
            "{middle:?}"
        );
        assert!((a.y - 0.5).abs() < 1e-6 && (b.y - 0.5).abs() < 1e-6);
        assert!(
            (a.x - 0.6 - (a.z - 1.2)).abs() < 1e-5,
            "pushed along x and z alike: {a:?}"
        );
        // Out now: the crossings are gone.
        assert!(!keep_segment_out(
            &mut a, &mut b, 1.0, 1.0, &collider, &t, &p, 0.05
        ));
        // A segment clear of the cube is left alone; so is one whose nodes are held.
        let (mut c, mut d) = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0));
        assert!(!keep_segment_out(
            &mut c, &mut d, 1.0, 1.0, &collider, &t, &p, 0.05
        ));
        let (mut e, mut f) = (Vec3::new(0.6, 0.5, 1.2), Vec3::new(1.2, 0.5, 0.6));
        assert!(!keep_segment_out(
            &mut e, &mut f, 0.0, 0.0, &collider, &t, &p, 0.05
        ));
    }

    #[test]
    fn a_segment_through_the_whole_cube_tells_no_way_round_and_is_left_alone() {
        let (p, t) = cube();
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        let (mut a, mut b) = (Vec3::new(0.5, 0.5, 2.0), Vec3::new(0.5, 0.5, -1.0));
        assert!(!keep_segment_out(
            &mut a, &mut b, 1.0, 1.0, &collider, &t, &p, 0.05
        ));
        assert_eq!(
            (a, b),
            (Vec3::new(0.5, 0.5, 2.0), Vec3::new(0.5, 0.5, -1.0))
        );
    }
}
