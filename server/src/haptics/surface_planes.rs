//! Nearby surfaces a tool has not touched yet, as unilateral planes for the local model.
//!
//! Owns: [`nearest_surface_plane`]: for one object, the surface point nearest the tool (among the nodes of the
//! triangles within the look-ahead box) and its current normal, turned into a plane for the tool's origin
//! (shifted out by the tool's reach along the normal), and the surface node it passes through (whose
//! footprint's touch-down stiffness the plane carries before the tool's first contact: `sim::tool_output`). A
//! device renders it at once, so a hand meets a surface even before the server has seen the contact and
//! answered with a model. [`nearest_shaft_plane`] does the same for an instrument's shaft: the surface nearest
//! the shaft, as a plane for the tool's origin (the device renders the origin; the tool is rigid, so a plane
//! that keeps the shaft out is a plane on its origin, shifted by where the shaft sits from it).
//!
//! Must not: move anything, or allocate beyond the candidate buffer's capacity.

use nalgebra::UnitQuaternion;
use parry3d::bounding_volume::Aabb;

use crate::collision::{NodeMarks, SurfaceCollider, ToolCollider};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A plane in the world frame: the tool origin is clear while `normal . x >= offset_mm`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WorldPlane {
    /// Outward unit normal of the surface.
    pub normal: Vec3,
    /// Offset along the normal, mm.
    pub offset_mm: f32,
    /// Stiffness against penetration, N/mm.
    pub stiffness_n_per_mm: f32,
    /// Damping of the approach, N s/mm.
    pub damping_n_s_per_mm: f32,
    /// The surface node the plane passes through (where the tool will touch first).
    pub node: u32,
}

/// One object's surface as the plane queries read it: its model, its current state, and the collider over
/// its triangles.
#[derive(Debug, Clone, Copy)]
pub struct Surface<'a> {
    /// The object's model (triangles, rest normals).
    pub model: &'a MassSpringModel,
    /// Its current state.
    pub state: &'a TissueState,
    /// The bounding-volume tree over its triangles.
    pub collider: &'a SurfaceCollider,
}

impl WorldPlane {
    /// Whether this plane already keeps the tool out of where `other` would: their normals within 1 degree
    /// and `other`'s offset at most 0.05 mm past this one's (the deadband's tolerances for a plane). Pure.
    pub fn keeps_out(&self, other: &WorldPlane) -> bool {
        self.normal.dot(&other.normal) >= 1.0f32.to_radians().cos()
            && other.offset_mm <= self.offset_mm + 0.05
    }
}

/// The surface node within `aabb` (through the collider's leaves) with the least `distance`, or None.
/// `candidates` is scratch.
fn nearest_node(
    aabb: &Aabb,
    surface: &Surface,
    marks: &mut NodeMarks,
    candidates: &mut Vec<u32>,
    distance: impl Fn(&Vec3) -> f32,
) -> Option<usize> {
    candidates.clear();
    surface.collider.nodes_near(aabb, marks, candidates);
    let x = &surface.state.positions_mm;
    candidates
        .iter()
        .map(|&i| i as usize)
        .filter(|&i| i < x.len())
        .min_by(|&a, &b| distance(&x[a]).total_cmp(&distance(&x[b])))
}

/// The plane through `node` with its current normal, for a point whose reach along the normal's inward
/// direction is `reach_mm`, shifted by `shift_mm` along the normal; None if not finite.
fn plane_through(
    surface: &Surface,
    node: usize,
    reach_along: impl Fn(&Vec3) -> f32,
    shift_along: impl Fn(&Vec3) -> f32,
) -> Option<WorldPlane> {
    let x = &surface.state.positions_mm;
    let normal = surface.model.current_normal(x, node);
    let offset_mm = normal.dot(&x[node]) + reach_along(&(-normal)) - shift_along(&normal);
    (normal.iter().all(|c| c.is_finite()) && offset_mm.is_finite()).then_some(WorldPlane {
        normal,
        offset_mm,
        stiffness_n_per_mm: 0.0,
        damping_n_s_per_mm: 0.0,
        node: node as u32,
    })
}

/// The plane of `surface` nearest the tool at `position_mm`, within `look_ahead_mm` of the tool's box, or
/// None. `candidates` is scratch. Stiffness and damping are filled in by the caller.
pub fn nearest_surface_plane(
    tool: &ToolCollider,
    position_mm: &Vec3,
    rotation: &UnitQuaternion<f32>,
    look_ahead_mm: f32,
    surface: &Surface,
    marks: &mut NodeMarks,
    candidates: &mut Vec<u32>,
) -> Option<WorldPlane> {
    let aabb = tool.aabb(position_mm, rotation, look_ahead_mm);
    let nearest = nearest_node(&aabb, surface, marks, candidates, |p| {
        (p - position_mm).norm_squared()
    })?;
    plane_through(
        surface,
        nearest,
        |inward| tool.reach_along_mm(rotation, inward),
        |_| 0.0,
    )
}

/// The plane of `surface` nearest an instrument's `shaft` (centred at `shaft_centre_mm`), within
/// `look_ahead_mm` of its box, for the tool's origin at `position_mm` (the shaft's reach along the plane's
/// inward normal, less how far the shaft's centre sits out along it from the origin), or None. Nearest to
/// the shaft's surface, not its centre: a shaft is long. `candidates` is scratch. Stiffness and damping are
/// filled in by the caller.
#[allow(clippy::too_many_arguments)]
pub fn nearest_shaft_plane(
    shaft: &ToolCollider,
    shaft_centre_mm: &Vec3,
    position_mm: &Vec3,
    rotation: &UnitQuaternion<f32>,
    look_ahead_mm: f32,
    surface: &Surface,
    marks: &mut NodeMarks,
    candidates: &mut Vec<u32>,
) -> Option<WorldPlane> {
    let aabb = shaft.aabb(shaft_centre_mm, rotation, look_ahead_mm);
    let nearest = nearest_node(&aabb, surface, marks, candidates, |p| {
        shaft.distance_mm(shaft_centre_mm, rotation, p)
    })?;
    let out = shaft_centre_mm - position_mm;
    plane_through(
        surface,
        nearest,
        |inward| shaft.reach_along_mm(rotation, inward),
        |normal| normal.dot(&out),
    )
}
