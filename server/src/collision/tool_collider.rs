//! Tool shapes and pushing points out of them.

use nalgebra::{UnitQuaternion, Vector3};
use parry3d::bounding_volume::{Aabb, BoundingVolume};
use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::{Ball, Capsule, Shape, TriMesh, TriMeshBuilderError, TriMeshFlags};

use super::ToolShapeSpec;
use super::glam_boundary::{from_parry, pose, to_parry};

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

/// Which way a point left the tool ([`ToolCollider::push_out_along`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactSide {
    /// Along the push, to the tool's surface on the tissue side: the tool presses it.
    Front,
    /// Sideways out of the shaft: the point is beside the tool or its handle, not under it.
    Shaft,
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

    /// Distance from `point_mm` to the tool, mm (0 inside it). Never panics.
    pub fn distance_mm(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        point_mm: &Vector3<f32>,
    ) -> f32 {
        self.shape()
            .distance_to_point(&pose(position_mm, rotation), to_parry(point_mm), true)
    }

    /// If `point_mm` is inside the tool, move it along `push_dir` (unit) until it leaves the tool: returns the
    /// exit point on the tool surface and the tool's outward unit normal there. None when the point is
    /// outside. Uses a parry ray cast from inside (non-solid) for the exit. No allocation, never returns
    /// non-finite values.
    ///
    /// Spheres and capsules also have a shaft: the tool swept back out of the tissue, along `-push_dir` (the
    /// surface's outward rest normal), as the handle of a real probe is. A point in the shaft (over the tool's
    /// back half, or above the tool within its radius) leaves sideways, across the shaft, never along the
    /// push: a dent's wall closing in over a deep probe, or a node that slid round the probe's equator, is held
    /// beside the shaft instead of teleported under the tool or let over its top. Without it a 4 mm probe
    /// pressing 15 mm into the pad went through it: the anchors pulled the wall over the probe and the sheet
    /// closed above it (`server/tests/no_tunnelling`).
    ///
    /// `held_in_front`: the point was held on the push side last tick ([`ContactSide::Front`]). Such a point
    /// stays on that side: if one step of the tissue carried it past the core into the shaft (stretched springs
    /// can move a light node several mm in a millisecond), it is brought back the way it came, under the tool,
    /// not let through.
    pub fn push_out_along(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        point_mm: &Vector3<f32>,
        push_dir: &Vector3<f32>,
        held_in_front: bool,
    ) -> Option<(Vector3<f32>, Vector3<f32>, ContactSide)> {
        let mut start = *point_mm;
        if let Some((core, across)) = self.shaft_offset(position_mm, rotation, point_mm, push_dir) {
            if !held_in_front {
                return self
                    .push_out_of_shaft(point_mm, push_dir, across)
                    .map(|(exit, normal)| (exit, normal, ContactSide::Shaft));
            }
            // Back to the core's level, inside the tool, then out along the push as usual.
            start = core + across;
        }
        let point_mm = &start;
        let tool_pose = pose(position_mm, rotation);
        let p = to_parry(point_mm);
        if !self.shape().contains_point(&tool_pose, p) {
            return None;
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
        Some((exit, normal / len, ContactSide::Front))
    }

    /// Where a point sits against the shaft of a sphere or capsule ([`Self::push_out_along`]): its core
    /// point and its offset across the shaft, when it lies on the shaft side of the core (along `-push_dir`)
    /// within the radius across it. None for mesh tools and for points on the push side or beside the shaft.
    fn shaft_offset(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        point_mm: &Vector3<f32>,
        push_dir: &Vector3<f32>,
    ) -> Option<(Vector3<f32>, Vector3<f32>)> {
        let up = -push_dir;
        let (core, radius) = match self {
            ToolCollider::Ball(b) => (*position_mm, b.radius),
            ToolCollider::Capsule(c) => {
                let a = position_mm + rotation * from_parry(c.segment.a);
                let b = position_mm + rotation * from_parry(c.segment.b);
                // The segment point under the point, seen along the shaft (across it, in the plane normal
                // to `up`); a segment along the shaft offers its deeper end.
                let ab = b - a;
                let ab_across = ab - up * ab.dot(&up);
                let len2 = ab_across.norm_squared();
                let t = if len2 < 1e-6 {
                    if ab.dot(&up) > 0.0 { 0.0 } else { 1.0 }
                } else {
                    let ap = point_mm - a;
                    ((ap - up * ap.dot(&up)).dot(&ab_across) / len2).clamp(0.0, 1.0)
                };
                (a + ab * t, c.radius)
            }
            ToolCollider::Mesh(_) => return None,
        };
        let offset = point_mm - core;
        let along = offset.dot(&up);
        let across = offset - up * along;
        (along > 0.0 && across.norm_squared() < radius * radius).then_some((core, across))
    }

    /// A point in the shaft leaves it sideways, across the shaft, to its wall. None if not finite.
    fn push_out_of_shaft(
        &self,
        point_mm: &Vector3<f32>,
        push_dir: &Vector3<f32>,
        across: Vector3<f32>,
    ) -> Option<(Vector3<f32>, Vector3<f32>)> {
        let radius = match self {
            ToolCollider::Ball(b) => b.radius,
            ToolCollider::Capsule(c) => c.radius,
            ToolCollider::Mesh(_) => return None,
        };
        let distance = across.norm();
        let normal = if distance > 1e-4 {
            across / distance
        } else {
            // On the axis: any direction across it will do; this one is deterministic.
            let side = if push_dir.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let across = side - push_dir * side.dot(push_dir);
            across / across.norm()
        };
        let exit = point_mm + normal * (radius - distance);
        exit.iter()
            .chain(normal.iter())
            .all(|c| c.is_finite())
            .then_some((exit, normal))
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
    /// Where `point_mm` must go to lie `clearance_mm` clear of the tool's surface, by the nearest way out
    /// (parry's projection onto the surface); None when it already does, or when no way out can be told (a
    /// point exactly on a mesh tool's surface). A thin body (a thread's node) meeting the tool. No allocation,
    /// never non-finite.
    pub fn keep_clear(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
        point_mm: &Vector3<f32>,
        clearance_mm: f32,
    ) -> Option<Vector3<f32>> {
        let projection =
            self.shape()
                .project_point(&pose(position_mm, rotation), to_parry(point_mm), false);
        let surface = from_parry(projection.point);
        let offset = point_mm - surface;
        let distance = offset.norm();
        if !projection.is_inside && distance >= clearance_mm {
            return None;
        }
        let outward = if distance > 1e-6 {
            if projection.is_inside {
                -offset / distance
            } else {
                offset / distance
            }
        } else {
            (surface - self.core_point(position_mm, rotation, &surface)).try_normalize(1e-9)?
        };
        let to = surface + outward * clearance_mm.max(0.0);
        to.iter().all(|c| c.is_finite()).then_some(to)
    }

    /// The tool's core where it is a swept sphere, world: the segment (its two ends; one point for a ball)
    /// and the radius swept round it. None for a mesh tool.
    pub fn swept_core(
        &self,
        position_mm: &Vector3<f32>,
        rotation: &UnitQuaternion<f32>,
    ) -> Option<([Vector3<f32>; 2], f32)> {
        match self {
            ToolCollider::Ball(b) => Some(([*position_mm; 2], b.radius)),
            ToolCollider::Capsule(c) => Some((
                [
                    position_mm + rotation * from_parry(c.segment.a),
                    position_mm + rotation * from_parry(c.segment.b),
                ],
                c.radius,
            )),
            ToolCollider::Mesh(_) => None,
        }
    }

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
        let (exit, normal, _) = tool
            .push_out_along(&centre, &q, &Vector3::new(0.0, 0.0, 0.0), &down, false)
            .unwrap();
        assert!(
            (exit - Vector3::new(0.0, 0.0, -2.0)).norm() < 1e-4,
            "{exit:?}"
        );
        assert!((normal - down).norm() < 1e-4);
        // Off-axis: exits on the sphere below, normal radial.
        let (exit, normal, _) = tool
            .push_out_along(&centre, &q, &Vector3::new(3.0, 0.0, 0.0), &down, false)
            .unwrap();
        assert!(
            (exit - Vector3::new(3.0, 0.0, -1.0)).norm() < 1e-4,
            "{exit:?}"
        );
        assert!((normal - Vector3::new(0.6, 0.0, -0.8)).norm() < 1e-4);
        assert!(
            tool.push_out_along(&centre, &q, &Vector3::new(0.0, 0.0, -2.5), &down, false)
                .is_none()
        );
    }

    #[test]
    fn a_point_over_a_balls_centre_leaves_sideways_out_of_the_shaft_not_through_the_ball() {
        let tool = ToolCollider::from_spec(&ToolShapeSpec::Sphere { radius_mm: 4.0 }).unwrap();
        let centre = Vector3::new(0.0, 0.0, -2.0);
        let q = UnitQuaternion::identity();
        let down = -Vector3::z();
        // A dent wall node 0.6 mm above the equator, 0.15 mm inside: along -z it would exit 1.5 mm lower.
        let p = Vector3::new(3.85, 0.0, -1.4);
        let (exit, normal, side) = tool.push_out_along(&centre, &q, &p, &down, false).unwrap();
        assert_eq!(side, ContactSide::Shaft);
        assert!((normal - Vector3::x()).norm() < 1e-5, "{normal:?}");
        assert!(
            (exit - Vector3::new(4.0, 0.0, -1.4)).norm() < 1e-4,
            "{exit:?}"
        );
        // Above the ball altogether, within its radius: the handle's place, so out sideways too.
        let (exit, normal, side) = tool
            .push_out_along(&centre, &q, &Vector3::new(0.0, -1.0, 3.0), &down, false)
            .unwrap();
        assert_eq!(side, ContactSide::Shaft);
        assert!((normal + Vector3::y()).norm() < 1e-5, "{normal:?}");
        assert!(
            (exit - Vector3::new(0.0, -4.0, 3.0)).norm() < 1e-4,
            "{exit:?}"
        );
        // Beside the shaft, or under the ball and outside it: untouched.
        for free in [Vector3::new(4.5, 0.0, 3.0), Vector3::new(0.0, 0.0, -6.5)] {
            assert!(
                tool.push_out_along(&centre, &q, &free, &down, false)
                    .is_none()
            );
        }
    }

    #[test]
    fn a_point_held_under_a_ball_that_one_step_carried_over_its_centre_goes_back_under() {
        let tool = ToolCollider::from_spec(&ToolShapeSpec::Sphere { radius_mm: 4.0 }).unwrap();
        let centre = Vector3::new(0.0, 0.0, -10.0);
        let q = UnitQuaternion::identity();
        let down = -Vector3::z();
        // Held under the ball last tick; stretched springs threw it 1 mm over the centre (and even above the
        // ball): it is put back on the lower surface, below where it is across the shaft.
        for p in [Vector3::new(2.0, 0.0, -9.0), Vector3::new(1.0, 1.0, -3.0)] {
            let (exit, normal, side) = tool.push_out_along(&centre, &q, &p, &down, true).unwrap();
            assert_eq!(side, ContactSide::Front);
            assert!(exit.z < centre.z, "{exit:?}");
            assert!((exit.xy() - p.xy()).norm() < 1e-5, "{exit:?}");
            assert!(((exit - centre).norm() - 4.0).abs() < 1e-4, "{exit:?}");
            assert!(normal.z < 0.0, "{normal:?}");
        }
        // Without that memory the same point is beside the shaft.
        let (_, _, side) = tool
            .push_out_along(&centre, &q, &Vector3::new(2.0, 0.0, -9.0), &down, false)
            .unwrap();
        assert_eq!(side, ContactSide::Shaft);
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
        let (exit, normal, _) = tool
            .push_out_along(
                &centre,
                &q,
                &Vector3::new(5.0, 0.0, 0.0),
                &-Vector3::z(),
                false,
            )
            .unwrap();
        assert!(
            (exit - Vector3::new(5.0, 0.0, -1.0)).norm() < 1e-3,
            "{exit:?}"
        );
        assert!((normal + Vector3::z()).norm() < 1e-3, "{normal:?}");
    }
}
