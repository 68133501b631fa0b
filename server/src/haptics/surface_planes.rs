//! Nearby surfaces a tool has not touched yet, as unilateral planes for the local model.
//!
//! Owns: [`nearest_surface_plane`]: for one object, the surface point nearest the tool (among the nodes of the
//! triangles within the look-ahead box) and its current normal, turned into a plane for the tool's origin
//! (shifted out by the tool's reach along the normal), and the surface node it passes through (whose
//! footprint's touch-down stiffness the plane carries before the tool's first contact: `sim::tool_output`). A
//! device renders it at once, so a hand meets a surface even before the server has seen the contact and
//! answered with a model.
//!
//! Must not: move anything, or allocate beyond the candidate buffer's capacity.

use nalgebra::UnitQuaternion;

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

/// The current outward normal at node `i`: area-weighted over its triangles (the rest normal if it has none
/// or they are degenerate).
fn current_normal(model: &MassSpringModel, x: &[Vec3], i: usize) -> Vec3 {
    let triangles = model.triangles();
    let mut n = Vec3::zeros();
    for &t in model.node_triangles(i) {
        let [a, b, c] = triangles[t as usize];
        let (a, b, c) = (x[a as usize], x[b as usize], x[c as usize]);
        n += (b - a).cross(&(c - a));
    }
    let len = n.norm();
    if len > 1e-9 {
        n / len
    } else {
        model.rest_normals()[i]
    }
}

/// The plane of `object`'s surface nearest the tool at `position_mm`, within `look_ahead_mm` of the tool's
/// box, or None. `candidates` is scratch. Stiffness and damping are filled in by the caller.
#[allow(clippy::too_many_arguments)]
pub fn nearest_surface_plane(
    tool: &ToolCollider,
    position_mm: &Vec3,
    rotation: &UnitQuaternion<f32>,
    look_ahead_mm: f32,
    model: &MassSpringModel,
    state: &TissueState,
    collider: &SurfaceCollider,
    marks: &mut NodeMarks,
    candidates: &mut Vec<u32>,
) -> Option<WorldPlane> {
    candidates.clear();
    let aabb = tool.aabb(position_mm, rotation, look_ahead_mm);
    collider.nodes_near(&aabb, marks, candidates);
    let x = &state.positions_mm;
    let nearest = candidates
        .iter()
        .map(|&i| i as usize)
        .filter(|&i| i < x.len())
        .min_by(|&a, &b| {
            let da = (x[a] - position_mm).norm_squared();
            let db = (x[b] - position_mm).norm_squared();
            da.total_cmp(&db)
        })?;
    let normal = current_normal(model, x, nearest);
    let reach_mm = tool.reach_along_mm(rotation, &(-normal));
    let offset_mm = normal.dot(&x[nearest]) + reach_mm;
    (normal.iter().all(|c| c.is_finite()) && offset_mm.is_finite()).then_some(WorldPlane {
        normal,
        offset_mm,
        stiffness_n_per_mm: 0.0,
        damping_n_s_per_mm: 0.0,
        node: nearest as u32,
    })
}
