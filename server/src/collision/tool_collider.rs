//! Tool shapes and pushing points out of them.

use nalgebra::{UnitQuaternion, Vector3};
use parry3d::bounding_volume::{Aabb, BoundingVolume};
use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::{Ball, Capsule, Shape, TriMesh, TriMeshBuilderError, TriMeshFlags};

use super::glam_boundary::{from_parry, pose, to_parry};
use crate::world::ToolShapeSpec;

/// A tool's parry shape.
#[derive(Debug, Clone)]
pub enum ToolCollider {
    /// Sphere.
    Ball(Ball),
    /// Capsule along local z.
    Capsule(Capsule),
    /// Closed rigid mesh (ORIENTED: pseudo-normals make inside tests exact; it never deforms).
    Mesh(Box<TriMesh>),
}

impl ToolCollider {
    /// From the world spec (a mesh spec is validated closed by the loader).
    pub fn from_spec(spec: &ToolShapeSpec) -> Result<Self, TriMeshBuilderError> {
        Ok(match spec {
            ToolShapeSpec::Sphere { radius_mm } => ToolCollider::Ball(Ball::new(*radius_mm)),
            ToolShapeSpec::Capsule {
                half_length_mm,
                radius_mm,
            } => ToolCollider::Capsule(Capsule::new_z(*half_length_mm, *radius_mm)),
            ToolShapeSpec::Mesh(surface) => {
                let vertices = surface
                    .positions_mm
                    .iter()
                    .map(|p| Vector::new(p[0], p[1], p[2]))
                    .collect();
                ToolCollider::Mesh(Box::new(TriMesh::with_flags(
                    vertices,
                    surface.triangles.clone(),
                    TriMeshFlags::ORIENTED,
                )?))
            }
        })
    }

    fn shape(&self) -> &dyn Shape {
        match self {
            ToolCollider::Ball(b) => b,
            ToolCollider::Capsule(c) => c,
            ToolCollider::Mesh(m) => m.as_ref(),
        }
    }

    /// World-space box of the tool at a pose, loosened by `margin_mm`.
    pub fn aabb(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        margin_mm: f32,
    ) -> Aabb {
        self.shape()
            .compute_aabb(&pose(position_mm, rotation))
            .loosened(margin_mm)
    }

    /// If `point_mm` is inside the tool, move it along `push_dir` (unit) until it leaves the tool: returns the
    /// exit point on the tool surface and the tool's outward unit normal there. None when the point is
    /// outside. Uses a parry ray cast from inside (non-solid) for the exit. No allocation, never returns
    /// non-finite values.
    pub fn push_out_along(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        point_mm: &Vector3<f32>,
        push_dir: &Vector3<f32>,
    ) -> Option<(Vector3<f32>, Vector3<f32>)> {
        let tool_pose = pose(position_mm, rotation);
        let p = to_parry(point_mm);
        if !self.shape().contains_point(&tool_pose, p) {
            return None;
        }
        // A swept sphere's point on the far side of its core from the push (the half of the tool facing out of
        // the tissue) entered from the side, as a dent's wall closes in above a deep probe: along the push it
        // would cross the whole tool and be teleported under it, spring back, re-enter and repeat (a 200 Hz,
        // 3% force chatter at 1.5 probe radii). It leaves the way it came: radially, to the nearest surface.
        if let ToolCollider::Ball(Ball { radius }) | ToolCollider::Capsule(Capsule { radius, .. }) =
            self
        {
            let core = self.core_point(position_mm, rotation, point_mm);
            let out = point_mm - core;
            let len = out.norm();
            if out.dot(push_dir) < 0.0 && len > 1e-4 {
                let normal = out / len;
                let exit = core + normal * *radius;
                return exit.iter().all(|c| c.is_finite()).then_some((exit, normal));
            }
        }
        let ray = Ray::new(p, to_parry(push_dir));
        let max_toi = 2.0 * self.shape().compute_local_aabb().extents().length() + 1.0;
        let (toi, normal) = match self {
            ToolCollider::Ball(b) => {
                let toi = b.cast_ray(&tool_pose, &ray, max_toi, false)?;
                let exit = point_mm + push_dir * toi;
                (toi, exit - self.core_point(position_mm, rotation, &exit))
            }
            ToolCollider::Capsule(c) => {
                let toi = c.cast_ray(&tool_pose, &ray, max_toi, false)?;
                let exit = point_mm + push_dir * toi;
                (toi, exit - self.core_point(position_mm, rotation, &exit))
            }
            ToolCollider::Mesh(m) => {
                // From inside, the first face hit is the exit face; its outward normal points along the push.
                let hit = m.cast_ray_and_get_normal(&tool_pose, &ray, max_toi, false)?;
                let n = from_parry(hit.normal);
                (
                    hit.time_of_impact,
                    if n.dot(push_dir) < 0.0 { -n } else { n },
                )
            }
        };
        let exit = point_mm + push_dir * toi;
        let len = normal.norm();
        if len.is_nan() || len <= 1e-7 || !exit.iter().all(|c| c.is_finite()) {
            return None;
        }
        Some((exit, normal / len))
    }

    /// How far the tool reaches from its origin along the unit direction `dir` (world), mm: the support
    /// function `max over tool points q of dir . (q - origin)` at orientation `rotation`. A plane that the
    /// tool must stay out of sits this far from the tool origin. No allocation.
    pub fn reach_along_mm(&self, rotation: &UnitQuaternion<f32>, dir: &Vector3<f32>) -> f32 {
        let local = rotation.inverse() * dir;
        match self {
            ToolCollider::Ball(b) => b.radius,
            ToolCollider::Capsule(c) => {
                let a = from_parry(c.segment.a).dot(&local);
                let b = from_parry(c.segment.b).dot(&local);
                a.max(b) + c.radius
            }
            ToolCollider::Mesh(m) => m
                .vertices()
                .iter()
                .map(|v| from_parry(*v).dot(&local))
                .fold(f32::NEG_INFINITY, f32::max),
        }
    }

    /// Closest point to `p` on the tool's core (ball centre, capsule segment): both shapes are swept spheres,
    /// so the outward normal at a surface point is the direction from its core point.
    fn core_point(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        p: &Vector3<f32>,
    ) -> Vector3<f32> {
        match self {
            ToolCollider::Ball(_) | ToolCollider::Mesh(_) => *position_mm,
            ToolCollider::Capsule(c) => {
                let a = position_mm + rotation * from_parry(c.segment.a);
                let b = position_mm + rotation * from_parry(c.segment.b);
                let ab = b - a;
                let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-12)).clamp(0.0, 1.0);
                a + ab * t
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_inside_a_ball_are_pushed_down_to_its_lower_surface() {
        let tool = ToolCollider::from_spec(&ToolShapeSpec::Sphere { radius_mm: 5.0 }).unwrap();
        let centre = Vector3::new(0.0, 0.0, 3.0);
        let q = UnitQuaternion::identity();
        let down = -Vector3::z();
        let (exit, normal) = tool
            .push_out_along(&centre, &q, &Vector3::new(0.0, 0.0, 0.0), &down)
            .unwrap();
        assert!(
            (exit - Vector3::new(0.0, 0.0, -2.0)).norm() < 1e-4,
            "{exit:?}"
        );
        assert!((normal - down).norm() < 1e-4);
        // Off-axis: exits on the sphere below, normal radial.
        let (exit, normal) = tool
            .push_out_along(&centre, &q, &Vector3::new(3.0, 0.0, 0.0), &down)
            .unwrap();
        assert!(
            (exit - Vector3::new(3.0, 0.0, -1.0)).norm() < 1e-4,
            "{exit:?}"
        );
        assert!((normal - Vector3::new(0.6, 0.0, -0.8)).norm() < 1e-4);
        assert!(
            tool.push_out_along(&centre, &q, &Vector3::new(0.0, 0.0, -2.5), &down)
                .is_none()
        );
    }

    #[test]
    fn a_point_above_a_balls_centre_leaves_radially_not_through_the_ball() {
        let tool = ToolCollider::from_spec(&ToolShapeSpec::Sphere { radius_mm: 4.0 }).unwrap();
        let centre = Vector3::new(0.0, 0.0, -2.0);
        let q = UnitQuaternion::identity();
        // A dent wall node 0.6 mm above the equator, 0.1 mm inside: along -z it would exit 1.5 mm lower.
        let p = Vector3::new(3.85, 0.0, -1.4);
        let (exit, normal) = tool
            .push_out_along(&centre, &q, &p, &-Vector3::z())
            .unwrap();
        let radial = (p - centre).normalize();
        assert!((normal - radial).norm() < 1e-5, "{normal:?}");
        assert!((exit - (centre + radial * 4.0)).norm() < 1e-4, "{exit:?}");
        assert!((exit - p).norm() < 0.11, "moved {} mm", (exit - p).norm());
    }

    #[test]
    fn capsule_normal_points_away_from_its_axis() {
        let tool = ToolCollider::from_spec(&ToolShapeSpec::Capsule {
            half_length_mm: 10.0,
            radius_mm: 2.0,
        })
        .unwrap();
        // Capsule lying along x (rotated 90 degrees about y), centred 1 mm above the origin.
        let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f32::consts::FRAC_PI_2);
        let centre = Vector3::new(0.0, 0.0, 1.0);
        let (exit, normal) = tool
            .push_out_along(&centre, &q, &Vector3::new(5.0, 0.0, 0.0), &-Vector3::z())
            .unwrap();
        assert!(
            (exit - Vector3::new(5.0, 0.0, -1.0)).norm() < 1e-3,
            "{exit:?}"
        );
        assert!((normal + Vector3::z()).norm() < 1e-3, "{normal:?}");
    }
}
