//! Where a tissue surface triangle meets a swept-sphere tool (a ball, or a capsule: [`ToolCollider::swept_core`]):
//! how deep the triangle reaches into the tool and the tool's outward normal there.
//!
//! Owns: [`triangle_contact`], [`core_point_nearest`] and [`closest_point_on_triangle`] (parry's point
//! projection on a triangle). The
//! probe's contact (`interaction::probe`) holds nodes; on a surface whose nodes are further apart than the tool
//! is wide it also needs the triangles between them, or the tool slips between the nodes into the tissue.
//!
//! Must not: allocate, or return anything non-finite.
//!
//! [`ToolCollider::swept_core`]: super::ToolCollider::swept_core

use parry3d::query::PointQuery;
use parry3d::shape::Triangle;

use super::glam_boundary::{from_parry, to_parry};
use crate::tissue::Vec3;

/// Alternating projections between the capsule's segment and the triangle: both convex, so the pair converges
/// to the nearest points; this many rounds leave it within microns for a millimetre tool.
const SEGMENT_ROUNDS: usize = 6;

/// How a triangle meets a swept-sphere tool.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleContact {
    /// How far the triangle's deepest point is inside the tool's surface, mm (> 0).
    pub depth_mm: f32,
    /// The tool's outward unit normal at that point (from the core toward the triangle).
    pub normal: Vec3,
}

/// The point of the triangle `a`, `b`, `c` nearest `p` (on its plane, an edge or a corner), mm.
pub fn closest_point_on_triangle(p: &Vec3, a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    let triangle = Triangle::new(to_parry(a), to_parry(b), to_parry(c));
    from_parry(triangle.project_local_point(to_parry(p), true).point)
}

/// The point of the segment `s` nearest `p`.
fn closest_point_on_segment(s: &[Vec3; 2], p: &Vec3) -> Vec3 {
    let ab = s[1] - s[0];
    let len2 = ab.norm_squared();
    if len2 <= 1e-12 {
        return s[0];
    }
    s[0] + ab * ((p - s[0]).dot(&ab) / len2).clamp(0.0, 1.0)
}

/// The point of the tool's core segment `core` (both ends the same for a ball) nearest the triangle `corners`.
pub fn core_point_nearest(core: &[Vec3; 2], corners: &[Vec3; 3]) -> Vec3 {
    nearest_pair(core, corners).0
}

/// The nearest points of the core segment and the triangle: (on the core, on the triangle).
fn nearest_pair(core: &[Vec3; 2], corners: &[Vec3; 3]) -> (Vec3, Vec3) {
    let [a, b, c] = corners;
    let mut on_core = closest_point_on_segment(core, &((a + b + c) / 3.0));
    let mut on_triangle = closest_point_on_triangle(&on_core, a, b, c);
    if core[0] != core[1] {
        for _ in 0..SEGMENT_ROUNDS {
            on_core = closest_point_on_segment(core, &on_triangle);
            on_triangle = closest_point_on_triangle(&on_core, a, b, c);
        }
    }
    (on_core, on_triangle)
}

/// The contact of the triangle `corners` with the tool whose core is the segment `core` (both ends the same
/// for a ball) swept by `radius_mm`: None when the triangle stays outside, or anything is not finite. When
/// the core lies on the triangle (no direction from one to the other) the normal is `fallback` (unit).
pub fn triangle_contact(
    core: &[Vec3; 2],
    radius_mm: f32,
    corners: &[Vec3; 3],
    fallback: &Vec3,
) -> Option<TriangleContact> {
    let (on_core, on_triangle) = nearest_pair(core, corners);
    let offset = on_triangle - on_core;
    let distance = offset.norm();
    let depth_mm = radius_mm - distance;
    if !depth_mm.is_finite() || depth_mm <= 0.0 {
        return None;
    }
    let normal = if distance > 1e-4 {
        offset / distance
    } else {
        *fallback
    };
    normal
        .iter()
        .all(|v| v.is_finite())
        .then_some(TriangleContact { depth_mm, normal })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 10 mm right triangle on the plane z = `z`, wound up.
    fn flat(z: f32) -> [Vec3; 3] {
        [
            Vec3::new(-5.0, -5.0, z),
            Vec3::new(5.0, -5.0, z),
            Vec3::new(-5.0, 5.0, z),
        ]
    }

    #[test]
    fn a_ball_over_the_middle_of_a_triangle_meets_it_below_its_centre() {
        let ball = [Vec3::new(-1.0, -1.0, 3.0); 2];
        let contact = triangle_contact(&ball, 4.0, &flat(0.0), &Vec3::z()).unwrap();
        assert!((contact.depth_mm - 1.0).abs() < 1e-5, "{contact:?}");
        assert!((contact.normal - (-Vec3::z())).norm() < 1e-5);
        assert_eq!(triangle_contact(&ball, 2.9, &flat(0.0), &Vec3::z()), None);
    }

    #[test]
    fn a_ball_beside_a_triangle_meets_its_edge_and_a_ball_on_it_takes_the_fallback() {
        // Over the hypotenuse's outside: the nearest point is on that edge.
        let ball = [Vec3::new(2.0, 2.0, 0.0); 2];
        let contact = triangle_contact(&ball, 3.0, &flat(0.0), &Vec3::z()).unwrap();
        let expected = 3.0 - 2.0 * std::f32::consts::SQRT_2;
        assert!((contact.depth_mm - expected).abs() < 1e-4, "{contact:?}");
        let on = [Vec3::new(-1.0, -1.0, 0.0); 2];
        let contact = triangle_contact(&on, 3.0, &flat(0.0), &-Vec3::z()).unwrap();
        assert_eq!(contact.normal, -Vec3::z());
        assert!((contact.depth_mm - 3.0).abs() < 1e-6);
    }

    #[test]
    fn a_capsule_lying_over_a_triangle_meets_it_along_its_length() {
        // Along x, 2.5 mm over the plane, radius 3: 0.5 mm deep wherever it lies over the triangle.
        let capsule = [Vec3::new(-20.0, -2.0, 2.5), Vec3::new(20.0, -2.0, 2.5)];
        let contact = triangle_contact(&capsule, 3.0, &flat(0.0), &Vec3::z()).unwrap();
        assert!((contact.depth_mm - 0.5).abs() < 1e-3, "{contact:?}");
        assert!(contact.normal.z < -0.999);
        // Tilted away from the triangle at one end, the other end clear above it: no contact.
        let clear = [Vec3::new(-20.0, 0.0, 3.1), Vec3::new(20.0, 0.0, 9.0)];
        assert_eq!(triangle_contact(&clear, 3.0, &flat(0.0), &Vec3::z()), None);
    }

    #[test]
    fn nothing_non_finite_comes_out() {
        let ball = [Vec3::new(f32::NAN, 0.0, 0.0); 2];
        assert_eq!(triangle_contact(&ball, 3.0, &flat(0.0), &Vec3::z()), None);
        let ball = [Vec3::new(0.0, 0.0, 1.0); 2];
        assert_eq!(
            triangle_contact(&ball, f32::INFINITY, &flat(0.0), &Vec3::z()),
            None
        );
    }
}
