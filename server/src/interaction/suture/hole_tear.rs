//! A suture cutting out of its tissue: a thread that pulls on the tissue at one of its holes harder than the
//! material holds tears the tissue there, toward the pull (issue 32: "past the material's tear limit, the
//! existing tearing fires at the hole").
//!
//! Owns: [`plan_hole_tear`] (whether a hole tears this tick, the slit its thread cuts as a blade's sweep, and
//! where the hole is to go) and [`surface_point_near`] (the point of a face on the hole's side nearest a
//! place). The tick's stage that runs them is `sim/hole_tearing.rs`; the thread's side is `thread/tear.rs`.
//!
//! The model (a suture cutting through, "cheese-wiring"):
//! - **When.** The thread's pull on the tissue at a surface hole, meaned over the tick
//!   ([`ThreadHole::pull_on_tissue_n`]), past the material's `suture_tear_n`: skin lets a 3-0 to 5-0 suture cut
//!   out at 3.3-4.1 N. A hole tears at most once every [`TEAR_PERIOD_S`]: the tissue gives [`STEP_MM`], the
//!   thread's pull there falls, and a hand that keeps pulling tears it on, a step at a time.
//! - **The slit.** The thread's line through the tissue from the hole (from [`ABOVE_MM`] over the surface) to
//!   the other hole of its bite, turned about that hole so that its end at this one moves [`STEP_MM`] along the
//!   pull's part along the surface: the tissue bridge between the thread and where it pulls is cut, as a
//!   blade's sweep ([`BladeSweep`]) whose seams open as a scalpel's do, at the mesh's own facets (the cut
//!   facets open once the slit separates something: it reaches the tissue's edge). A hole with no other hole
//!   in its bite (the thread ends inside) cuts the line along the surface's normal to [`DEPTH_MM`] under it.
//! - **Where the hole goes.** To the point of a face on the hole's side (its outward normal within
//!   [`SAME_SIDE_COS`] of the hole's) nearest the swept-to place, within [`REACH_MM`] of it. None there: the
//!   slit has reached the tissue's edge (a wound's face, or skin drawn round the edge of one) and the thread
//!   cuts through: the bridge left is cut ([`HoleTear::through`], the slit carried [`THROUGH_MM`] on) and its
//!   bite lets the thread go.
//! - A pull mostly along the surface's normal (its part along the surface under [`ALONG_SHARE`] of it) tears
//!   nothing: it lifts the hole's rim rather than dragging the thread across the tissue.
//!
//! Must not: allocate or panic; a hole in the volume (a ring of the track), a point whose triangle is gone, or a
//! non-finite value tears nothing.

use parry3d::bounding_volume::Aabb;

use super::thread_hole::{HolePoint, ThreadHole};
use super::tip_contact::SurfacePoint;
use crate::collision::glam_boundary::to_parry;
use crate::collision::{SurfaceCollider, project_on_face};
use crate::interaction::BladeSweep;
use crate::tissue::{MassSpringModel, Vec3};

/// A hole tears at most this often, s.
pub const TEAR_PERIOD_S: f64 = 0.02;
/// How far one tear runs along the surface, mm.
pub const STEP_MM: f32 = 1.0;
/// The slit's blade starts this far over the surface, mm.
pub const ABOVE_MM: f32 = 0.5;
/// ... and, with no other hole in its bite, reaches this deep under it, mm.
pub const DEPTH_MM: f32 = 2.0;
/// The hole moves to a face whose outward normal is within this cosine of its own (about 37 degrees).
pub const SAME_SIDE_COS: f32 = 0.8;
/// ... lying within this of where the slit reached, mm.
pub const REACH_MM: f32 = 1.0;
/// A thread cutting through its bite's edge cuts the slit on this far past the hole, mm.
pub const THROUGH_MM: f32 = 3.0;
/// A pull whose part along the surface is under this share of it tears nothing.
pub const ALONG_SHARE: f32 = 0.25;
/// A projection this far outside a triangle (in barycentric weight) still lies on it.
const EDGE_TOLERANCE: f32 = 0.02;

/// A tear at one hole: the slit to open in object `object`, and the place the hole goes to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoleTear {
    /// The object the hole is in.
    pub object: usize,
    /// The thread's line into the tissue, swept along the pull: the slit.
    pub sweep: BladeSweep,
    /// The same carried [`THROUGH_MM`] on: the slit when the thread cuts through the edge.
    pub through: BladeSweep,
    /// Where the slit reaches on the surface, mm.
    pub to_mm: Vec3,
    /// The surface's outward normal at the hole (unit).
    pub normal: Vec3,
}

/// Whether `hole`, in a tissue of `model` at `positions_mm` whose material holds a suture to `limit_n`, tears
/// at `now_s`, and how; `bite_mm` gives where the other hole of its bite is (None: it has none), asked only of
/// a hole pulled past the limit. None for a ring
/// of a track, a hole pulled within the limit or mostly along the surface's normal, one that tore less than
/// [`TEAR_PERIOD_S`] ago, or one whose triangle is gone.
pub fn plan_hole_tear(
    hole: &ThreadHole,
    bite_mm: impl FnOnce() -> Option<Vec3>,
    model: &MassSpringModel,
    positions_mm: &[Vec3],
    limit_n: f32,
    now_s: f64,
) -> Option<HoleTear> {
    let HolePoint::Surface(point) = hole.point else {
        return None;
    };
    let pull_n = hole.pull_on_tissue_n();
    let pull = pull_n.norm();
    if !pull.is_finite() || !limit_n.is_finite() || pull <= limit_n {
        return None;
    }
    if hole
        .torn_at_s()
        .is_some_and(|at| now_s - at < TEAR_PERIOD_S)
    {
        return None;
    }
    let corners = point.corners(model)?;
    let [a, b, c] = corners.map(|i| positions_mm.get(i as usize).copied());
    let (a, b, c) = (a?, b?, c?);
    let normal = (b - a).cross(&(c - a)).try_normalize(1e-9)?;
    let at_mm = a * point.barycentric[0] + b * point.barycentric[1] + c * point.barycentric[2];
    let along = pull_n - normal * pull_n.dot(&normal);
    if along.norm() < ALONG_SHARE * pull {
        return None;
    }
    let dir = along.normalize();
    let top = at_mm + normal * ABOVE_MM;
    let other = bite_mm().filter(|b| b.iter().all(|c| c.is_finite()));
    let slit = |length_mm: f32| match other {
        // Turned about the bite's other hole: a triangle of the bridge between the thread and the pull.
        Some(other) => BladeSweep {
            from_mm: [top, other],
            to_mm: [top + dir * length_mm, other],
        },
        None => {
            let line = [top, at_mm - normal * DEPTH_MM];
            BladeSweep {
                from_mm: line,
                to_mm: line.map(|p| p + dir * length_mm),
            }
        }
    };
    let to_mm = at_mm + dir * STEP_MM;
    to_mm.iter().all(|v| v.is_finite()).then_some(HoleTear {
        object: usize::from(point.object),
        sweep: slit(STEP_MM),
        through: slit(THROUGH_MM),
        to_mm,
        normal,
    })
}

/// The point of object `object`'s surface (`collider` over `model`'s triangles at `positions_mm`) nearest
/// `at_mm` on a face whose outward normal lies within [`SAME_SIDE_COS`] of `normal`, within [`REACH_MM`] of it
/// along that face's normal, `at_mm` projecting inside the face. None when there is no such face. No
/// allocation.
pub fn surface_point_near(
    collider: &SurfaceCollider,
    model: &MassSpringModel,
    positions_mm: &[Vec3],
    object: u16,
    at_mm: &Vec3,
    normal: &Vec3,
) -> Option<SurfacePoint> {
    if !at_mm.iter().all(|c| c.is_finite()) {
        return None;
    }
    let reach = Vec3::repeat(REACH_MM);
    let aabb = Aabb::new(to_parry(&(at_mm - reach)), to_parry(&(at_mm + reach)));
    let triangles = model.triangles();
    let mut best: Option<(f32, SurfacePoint)> = None;
    for t in collider.triangles_near(&aabb) {
        let Some(&corners) = triangles.get(t as usize) else {
            continue;
        };
        let Some((weights, signed_mm, face_normal)) = project_on_face(positions_mm, corners, at_mm)
        else {
            continue;
        };
        if signed_mm.abs() > REACH_MM
            || face_normal.dot(normal) < SAME_SIDE_COS
            || weights.iter().any(|&w| w < -EDGE_TOLERANCE)
        {
            continue;
        }
        if best.is_some_and(|(d, _)| d <= signed_mm.abs()) {
            continue;
        }
        let clamped = weights.map(|w| w.max(0.0));
        let sum: f32 = clamped.iter().sum();
        if !sum.is_finite() || sum <= 0.0 {
            continue;
        }
        best = Some((
            signed_mm.abs(),
            SurfacePoint {
                object,
                triangle: t,
                barycentric: clamped.map(|w| w / sum),
            },
        ));
    }
    best.map(|(_, p)| p)
}
