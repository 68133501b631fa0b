//! Where two deforming surfaces come near each other: the box they may meet in, and, for a point of one, the
//! face of the other it lies under or above.
//!
//! Owns: [`meeting_box`] (two colliders' whole-surface boxes, each loosened by a reach, intersected) and
//! [`nearest_face`] (the triangle of a surface nearest a point along its outward normal, within a reach, whose
//! plane the point projects inside). The broad phase is each collider's tree (boxes a tick old at most: the
//! reach covers a tick's motion); the exact test is on the triangles at `positions_mm`, so the answer is for
//! the surface as it is now. Which side is outside is read from the triangle's winding (counter-clockwise seen
//! from outside, as every surface here is wound).
//!
//! Must not: allocate or panic on any input (a degenerate triangle or a non-finite point finds nothing).

use parry3d::bounding_volume::{Aabb, BoundingVolume};

use super::SurfaceCollider;
use super::glam_boundary::to_parry;
use crate::tissue::Vec3;

/// A point's projection may fall this far outside a triangle (in barycentric weight) and still count as over
/// it: a node at a face's edge or corner meets the face it leans on rather than none.
pub const EDGE_TOLERANCE: f32 = 0.1;

/// A face counts as facing a point when their outward normals are at least this far apart (cosine): 120
/// degrees. A block's side face is not what its top face's node leans on, however near it.
pub const FACING_COS: f32 = -0.5;

/// A face of a surface near a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearFace {
    /// The triangle's corners (node ids of the surface's object).
    pub corners: [u32; 3],
    /// The point's distance from the triangle's plane along its outward normal, mm (negative: under the face,
    /// inside the object).
    pub signed_mm: f32,
}

/// The box where surfaces `a` and `b` may meet this tick: each one's whole box loosened by `reach_mm`,
/// intersected. `None` when they are farther apart than that.
pub fn meeting_box(a: &SurfaceCollider, b: &SurfaceCollider, reach_mm: f32) -> Option<Aabb> {
    let reach = reach_mm.max(0.0);
    let (box_a, box_b) = (a.root_aabb().loosened(reach), b.root_aabb().loosened(reach));
    if !box_a.intersects(&box_b) {
        return None;
    }
    Some(box_a.intersection(&box_b).unwrap_or(box_a))
}

/// Of the triangles of `collider`'s surface (`triangles` at `positions_mm`) whose boxes come within `reach_mm`
/// of `point_mm`, the one whose plane is nearest the point (by the absolute signed distance along its outward
/// normal, at most `reach_mm`) among those the point projects inside (within [`EDGE_TOLERANCE`]) and that face
/// it (the point's own surface's outward normal `facing`, unit, turned against theirs: [`FACING_COS`]). `None`
/// when no face is so near. No allocation.
pub fn nearest_face(
    collider: &SurfaceCollider,
    triangles: &[[u32; 3]],
    positions_mm: &[Vec3],
    point_mm: &Vec3,
    facing: &Vec3,
    reach_mm: f32,
) -> Option<NearFace> {
    if !point_mm.iter().all(|c| c.is_finite()) || reach_mm.is_nan() || reach_mm <= 0.0 {
        return None;
    }
    let reach = Vec3::repeat(reach_mm);
    let aabb = Aabb::new(to_parry(&(point_mm - reach)), to_parry(&(point_mm + reach)));
    let mut best: Option<NearFace> = None;
    for t in collider.triangles_near(&aabb) {
        let Some(&corners) = triangles.get(t as usize) else {
            continue;
        };
        let Some((weights, signed_mm, normal)) = project_on_face(positions_mm, corners, point_mm)
        else {
            continue;
        };
        if signed_mm.abs() > reach_mm
            || weights.iter().any(|&w| w < -EDGE_TOLERANCE)
            || normal.dot(facing) > FACING_COS
        {
            continue;
        }
        if best.is_none_or(|b| signed_mm.abs() < b.signed_mm.abs()) {
            best = Some(NearFace { corners, signed_mm });
        }
    }
    best
}

/// The barycentric weights of `point_mm`'s projection on the plane of the triangle `corners` (unclamped: a
/// negative weight is outside the opposite edge) and its signed distance from that plane along the outward
/// normal, mm, and that normal. `None` for a degenerate or missing triangle.
pub fn project_on_face(
    positions_mm: &[Vec3],
    corners: [u32; 3],
    point_mm: &Vec3,
) -> Option<([f32; 3], f32, Vec3)> {
    let [a, b, c] = corners.map(|i| positions_mm.get(i as usize).copied());
    let (a, b, c) = (a?, b?, c?);
    let (ab, ac, ap) = (b - a, c - a, point_mm - a);
    let cross = ab.cross(&ac);
    let area2 = cross.norm_squared();
    if !area2.is_finite() || area2 <= 1e-12 {
        return None;
    }
    let normal = cross / area2.sqrt();
    let signed_mm = ap.dot(&normal);
    // Barycentrics of the projection: the sub-triangles' signed areas over the whole.
    let w_b = ap.cross(&ac).dot(&cross) / area2;
    let w_c = ab.cross(&ap).dot(&cross) / area2;
    let weights = [1.0 - w_b - w_c, w_b, w_c];
    weights
        .iter()
        .all(|w| w.is_finite())
        .then_some((weights, signed_mm, normal))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit-ish box surface: the cube [0, s]^3, outward-wound.
    fn cube(s: f32, offset: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for k in 0..2 {
            for j in 0..2 {
                for i in 0..2 {
                    p.push(offset + Vec3::new(i as f32, j as f32, k as f32) * s);
                }
            }
        }
        // Corner id = i + 2j + 4k; each face as two triangles, counter-clockwise seen from outside.
        let quads = [
            [0, 2, 3, 1], // z = 0, normal -z
            [4, 5, 7, 6], // z = s, normal +z
            [0, 1, 5, 4], // y = 0, normal -y
            [2, 6, 7, 3], // y = s, normal +y
            [0, 4, 6, 2], // x = 0, normal -x
            [1, 3, 7, 5], // x = s, normal +x
        ];
        let mut t = Vec::new();
        for q in quads {
            t.push([q[0], q[1], q[2]]);
            t.push([q[0], q[2], q[3]]);
        }
        (p, t)
    }

    #[test]
    fn a_point_under_a_face_is_inside_by_its_depth_and_a_point_above_is_outside() {
        let (p, t) = cube(10.0, Vec3::zeros());
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        let down = -Vec3::z();
        let under = nearest_face(&collider, &t, &p, &Vec3::new(5.0, 4.0, 9.7), &down, 2.0).unwrap();
        assert!((under.signed_mm + 0.3).abs() < 1e-5, "{under:?}");
        assert!(
            under.corners.iter().all(|&c| c >= 4),
            "the top face: {under:?}"
        );
        let above =
            nearest_face(&collider, &t, &p, &Vec3::new(5.0, 4.0, 11.5), &down, 2.0).unwrap();
        assert!((above.signed_mm - 1.5).abs() < 1e-5, "{above:?}");
        assert_eq!(
            nearest_face(&collider, &t, &p, &Vec3::new(5.0, 4.0, 12.5), &down, 2.0),
            None
        );
        // Deep inside, every face is beyond the reach.
        assert_eq!(
            nearest_face(&collider, &t, &p, &Vec3::new(5.0, 5.0, 5.0), &down, 2.0),
            None
        );
        // Beside the cube, not over any face.
        assert_eq!(
            nearest_face(&collider, &t, &p, &Vec3::new(12.0, 12.0, 5.0), &down, 2.5),
            None
        );
    }

    #[test]
    fn near_an_edge_the_nearest_face_turned_toward_the_point_wins() {
        let (p, t) = cube(10.0, Vec3::zeros());
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        let point = Vec3::new(9.8, 5.0, 9.5);
        // 0.5 under the top, 0.2 inside the x = 10 side: a point facing -x goes out through the side...
        let face = nearest_face(&collider, &t, &p, &point, &-Vec3::x(), 2.0).unwrap();
        assert!((face.signed_mm + 0.2).abs() < 1e-5, "{face:?}");
        assert!(
            face.corners.iter().all(|&c| c % 2 == 1),
            "the x = s face: {face:?}"
        );
        // ... one facing down (a block resting on this one) through the top.
        let face = nearest_face(&collider, &t, &p, &point, &-Vec3::z(), 2.0).unwrap();
        assert!((face.signed_mm + 0.5).abs() < 1e-5, "{face:?}");
        assert!(
            face.corners.iter().all(|&c| c >= 4),
            "the top face: {face:?}"
        );
        // Facing the same way as every face near it: none.
        assert_eq!(
            nearest_face(
                &collider,
                &t,
                &p,
                &point,
                &Vec3::new(0.7, 0.0, 0.7).normalize(),
                2.0
            ),
            None
        );
    }

    #[test]
    fn surfaces_meet_only_within_their_reach() {
        let (pa, ta) = cube(10.0, Vec3::zeros());
        let (pb, tb) = cube(10.0, Vec3::new(13.0, 0.0, 0.0));
        let (a, b) = (
            SurfaceCollider::new(&pa, &ta).unwrap(),
            SurfaceCollider::new(&pb, &tb).unwrap(),
        );
        assert!(meeting_box(&a, &b, 1.0).is_none());
        let meet = meeting_box(&a, &b, 2.0).unwrap();
        assert!(meet.mins.x >= 10.9 && meet.maxs.x <= 12.1, "{meet:?}");
    }

    #[test]
    fn bad_input_finds_nothing() {
        let (p, t) = cube(10.0, Vec3::zeros());
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        let down = -Vec3::z();
        let nan = Vec3::new(f32::NAN, 0.0, 0.0);
        assert_eq!(nearest_face(&collider, &t, &p, &nan, &down, 2.0), None);
        assert_eq!(
            nearest_face(
                &collider,
                &t,
                &p,
                &Vec3::new(5.0, 5.0, 9.5),
                &down,
                f32::NAN
            ),
            None
        );
        assert!(project_on_face(&p, [0, 0, 1], &Vec3::zeros()).is_none());
        assert!(project_on_face(&p, [0, 1, 99], &Vec3::zeros()).is_none());
    }
}
