//! Where a moving point's path crosses a deforming surface: a needle tip's segment from one tick to the next
//! against a tissue's triangles.
//!
//! Owns: [`SurfaceCrossing`] and [`crossing_nearest`]. The broad phase is the surface collider's tree (whose
//! boxes may be a tick old: the query box is loosened by a margin); the exact test is Moller-Trumbore on the
//! triangles at `positions_mm`, so the answer is for the surface as it is now. Which side a crossing enters
//! from is read against the triangle's winding (counter-clockwise seen from outside).
//!
//! Must not: allocate or panic on any input (a degenerate triangle or a zero-length segment crosses nothing).

use parry3d::bounding_volume::Aabb;

use super::SurfaceCollider;
use super::glam_boundary::to_parry;
use crate::tissue::Vec3;

/// One crossing of a segment through a surface triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceCrossing {
    /// The triangle crossed (its stable id).
    pub triangle: u32,
    /// Where on it, by its corners' weights (sum 1).
    pub barycentric: [f32; 3],
    /// Where along the segment, 0 (its start) to 1 (its end).
    pub along: f32,
    /// The crossing point, mm.
    pub point_mm: Vec3,
    /// The segment runs against the triangle's outward normal: it goes into the object.
    pub entering: bool,
}

/// Of the crossings of the segment `from_mm -> to_mm` through the surface (`triangles` at `positions_mm`,
/// found through `collider`'s tree loosened by `margin_mm`) that enter it (`entering = Some(true)`), leave it
/// (`Some(false)`) or either (`None`), the one whose place along the segment is nearest `near_along` (0: the
/// first from `from_mm`). `None` when it crosses nothing so. No allocation.
#[allow(clippy::too_many_arguments)] // one surface as the sim holds it, the segment, and what to look for
pub fn crossing_nearest(
    collider: &SurfaceCollider,
    triangles: &[[u32; 3]],
    positions_mm: &[Vec3],
    from_mm: &Vec3,
    to_mm: &Vec3,
    margin_mm: f32,
    near_along: f32,
    entering: Option<bool>,
) -> Option<SurfaceCrossing> {
    let dir = to_mm - from_mm;
    if dir.norm_squared().is_nan()
        || dir.norm_squared() <= 1e-18
        || !dir.iter().chain(from_mm.iter()).all(|c| c.is_finite())
    {
        return None;
    }
    let lo = from_mm.inf(to_mm);
    let hi = from_mm.sup(to_mm);
    let margin = Vec3::repeat(margin_mm.max(0.0));
    let aabb = Aabb::new(to_parry(&(lo - margin)), to_parry(&(hi + margin)));
    let mut best: Option<SurfaceCrossing> = None;
    for t in collider.triangles_near(&aabb) {
        let Some(corners) = triangles.get(t as usize) else {
            continue;
        };
        let [Some(a), Some(b), Some(c)] = corners.map(|i| positions_mm.get(i as usize)) else {
            continue;
        };
        let Some((along, u, v, enters)) = segment_triangle(from_mm, &dir, a, b, c) else {
            continue;
        };
        if entering.is_some_and(|want| want != enters) {
            continue;
        }
        if best.is_none_or(|k| (along - near_along).abs() < (k.along - near_along).abs()) {
            best = Some(SurfaceCrossing {
                triangle: t,
                barycentric: [1.0 - u - v, u, v],
                along,
                point_mm: from_mm + dir * along,
                entering: enters,
            });
        }
    }
    best
}

/// Moller-Trumbore: where `origin + s dir` (s in 0..1) meets triangle `abc`: `(s, u, v, entering)` with the
/// point `a + u (b - a) + v (c - a)`; `entering` when `dir` runs against the normal `(b - a) x (c - a)`.
fn segment_triangle(
    origin: &Vec3,
    dir: &Vec3,
    a: &Vec3,
    b: &Vec3,
    c: &Vec3,
) -> Option<(f32, f32, f32, bool)> {
    let e1 = b - a;
    let e2 = c - a;
    let p = dir.cross(&e2);
    let det = e1.dot(&p);
    let scale = e1.norm() * e2.norm() * dir.norm();
    if det.is_nan() || det.abs() <= 1e-7 * scale {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - a;
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(&e1);
    let v = dir.dot(&q) * inv;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let along = e2.dot(&q) * inv;
    if !(0.0..=1.0).contains(&along) {
        return None;
    }
    // det = e1 . (dir x e2) = dir . (e2 x e1) = -dir . n: positive when the segment runs against n.
    Some((along, u, v, det > 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles making the square [0, 2] x [0, 2] on z = 0, facing +z.
    fn square() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ];
        (p, vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn a_segment_down_through_the_square_enters_it_where_it_crosses() {
        let (p, t) = square();
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        let from = Vec3::new(1.5, 0.5, 1.0);
        let to = Vec3::new(1.5, 0.5, -1.0);
        let hit = crossing_nearest(&collider, &t, &p, &from, &to, 0.1, 0.0, None).unwrap();
        assert_eq!(hit.triangle, 0);
        assert!(hit.entering);
        assert!((hit.along - 0.5).abs() < 1e-6);
        let back: Vec3 = t[0]
            .iter()
            .zip(hit.barycentric)
            .map(|(&c, w)| p[c as usize] * w)
            .sum();
        assert!((back - Vec3::new(1.5, 0.5, 0.0)).norm() < 1e-5, "{back:?}");
        // Upward it leaves; beside the square or short of it, nothing.
        let up = crossing_nearest(&collider, &t, &p, &to, &from, 0.1, 0.0, None).unwrap();
        assert!(!up.entering);
        // Asked for entries only, the upward path has none.
        assert!(crossing_nearest(&collider, &t, &p, &to, &from, 0.1, 0.0, Some(true)).is_none());
        let beside = Vec3::new(3.0, 0.5, 0.0);
        assert!(
            crossing_nearest(
                &collider,
                &t,
                &p,
                &(beside + Vec3::z()),
                &(beside - Vec3::z()),
                0.1,
                0.0,
                None
            )
            .is_none()
        );
        assert!(
            crossing_nearest(
                &collider,
                &t,
                &p,
                &from,
                &Vec3::new(1.5, 0.5, 0.1),
                0.1,
                0.0,
                None
            )
            .is_none()
        );
        assert!(crossing_nearest(&collider, &t, &p, &from, &from, 0.1, 0.0, None).is_none());
        let nan = Vec3::new(f32::NAN, 0.0, 0.0);
        assert!(crossing_nearest(&collider, &t, &p, &nan, &to, 0.1, 0.0, None).is_none());
    }

    #[test]
    fn of_two_sheets_the_crossing_nearest_the_asked_place_is_returned() {
        let (mut p, mut t) = square();
        // A second square 1 mm lower.
        p.extend(p.clone().iter().map(|x| x - Vec3::z()));
        t.extend([[4, 5, 6], [4, 6, 7]]);
        let collider = SurfaceCollider::new(&p, &t).unwrap();
        let from = Vec3::new(0.5, 1.5, 0.5);
        let to = Vec3::new(0.5, 1.5, -1.5);
        let first = crossing_nearest(&collider, &t, &p, &from, &to, 0.1, 0.0, None).unwrap();
        assert!(first.point_mm.z.abs() < 1e-6);
        let last = crossing_nearest(&collider, &t, &p, &from, &to, 0.1, 1.0, None).unwrap();
        assert!((last.point_mm.z + 1.0).abs() < 1e-6);
        assert!(last.triangle >= 2);
    }
}
