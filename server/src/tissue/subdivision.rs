//! Subdivision: a model's edges split where a blade crosses them, and vertices snapped onto the blade's path,
//! with ids that never change, so a cut can follow the blade instead of the mesh's own facets.
//!
//! Owns: the topological and material half of a cut by subdivision. A [`CutPlan`] (from
//! `interaction::blade_crossings`) names the vertices to move onto the cut (a crossing within a snapping
//! distance of a vertex moves that vertex there, along the crossed edge: no short edge is made) and the edges to
//! split (a new vertex at the crossing). [`subdivide_into`] applies it to the model's parts:
//! - an edge `a b` split at `t` gets a vertex `p` at `(1 - t) a + t b`, at rest as now; every element holding
//!   the edge becomes two, the element itself keeping its index with `b` replaced by `p` and a new one appended
//!   with `a` replaced by `p` (each keeps its orientation); a volume's surface triangles on the edge split the
//!   same way. Edges are split one after the other, so a tetrahedron crossed on three or four edges ends as
//!   children that each lie on one side of the cut, and the cut's faces are faces of the mesh, which
//!   `tissue::seams` then opens;
//! - masses are shared out again by measure (area or volume) over the touched vertices, keeping their total;
//!   each piece of a split edge keeps the edge's spring, each new edge takes the mean spring of the element it
//!   crosses, and a new vertex's springs are scaled down if it would be stiffer for its mass than any node of
//!   the model was (so the stable step the world was checked for still holds);
//! - [`Subdivision`] records what changed, and re-expresses a material point (an element and its weights, as a
//!   grasp or a suture's hole holds one) on the elements it is in now, at the same place ([`remap`]).
//!
//! Must not: know about tools or blades, step anything, or renumber anything: vertices, elements and surface
//! triangles are only appended or re-pointed.

mod remap;
mod shares;
mod split;

pub use remap::ElementRemap;
pub use shares::{floor_masses, floor_model_masses, rate_ceiling};
pub use split::move_keeps_quality;

use crate::tissue::seams::NO_VERTEX;
use crate::tissue::{MassSpringModel, ModelParts, Vec3};

/// A crossing closer than this share of its edge's length to a vertex snaps to the vertex rather than split
/// the edge: no piece of a split edge is shorter than this share of it.
pub const SNAP_SHARE: f32 = 0.25;

/// A crossing this close to a vertex that may not move (a share of its edge) takes the vertex as on the cut
/// where it lies: the cut surface passes at most this share of the edge off the blade's path there.
pub const PIN_SHARE: f32 = 0.05;

/// A vertex moved onto a cut leaves each of its elements at least this share of its rest measure (area or
/// volume), with the same orientation; else it is not moved.
pub const MIN_MEASURE_SHARE: f32 = 0.2;

/// An edge to split: the new vertex lies at `(1 - t) a + t b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeSplit {
    /// The edge's first end.
    pub a: u32,
    /// The edge's second end.
    pub b: u32,
    /// Where along it, from `a` (0) to `b` (1).
    pub t: f32,
}

impl EdgeSplit {
    /// The end the new vertex lies nearer.
    pub fn nearer_end(&self) -> u32 {
        if self.t <= 0.5 { self.a } else { self.b }
    }
}

/// A vertex to move onto a cut: to `(1 - t) vertex + t toward`, at rest as now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VertexMove {
    /// The vertex moved.
    pub vertex: u32,
    /// The other end of the edge it moves along.
    pub toward: u32,
    /// How far along it, as a share of the edge.
    pub t: f32,
}

/// What a blade's crossing changes this tick: vertices moved onto its path, then edges split.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CutPlan {
    /// Vertices moved onto the cut (each vertex at most once).
    pub moves: Vec<VertexMove>,
    /// Edges split (original edges of the model, no end of which is moved).
    pub splits: Vec<EdgeSplit>,
    /// Vertices within [`PIN_SHARE`] of the path that may not move (fixed, on an edge or corner of the
    /// object's shape, or beside a moved vertex): taken to be on it where they are. Changes nothing in the
    /// model; the blade's bookkeeping counts them as on the cut.
    pub pinned: Vec<u32>,
}

impl CutPlan {
    /// The plan for a blade's path crossing edges `crossings` of `model` (`a`, `b`, and where along from `a`):
    /// a crossing within [`SNAP_SHARE`] of a vertex moves that vertex onto the path (the nearest first) where
    /// the move keeps the object's shape and its elements' quality and no neighbour of it moves; any other is
    /// split. An edge with an end already on the path (`on_cut`, or moved by this plan) is left alone. A vertex
    /// that `stays` (tied to another object by its id and rest place) is never moved: it is pinned or its edge
    /// split.
    pub fn from_crossings(
        &mut self,
        model: &MassSpringModel,
        crossings: &mut [EdgeSplit],
        on_cut: impl Fn(u32) -> bool,
        stays: impl Fn(u32) -> bool,
    ) {
        self.clear();
        crossings.sort_by(|x, y| x.t.min(1.0 - x.t).total_cmp(&y.t.min(1.0 - y.t)));
        for c in crossings.iter() {
            let moved =
                |v: u32| self.moves.iter().any(|m| m.vertex == v) || self.pinned.contains(&v);
            if on_cut(c.a) || on_cut(c.b) || moved(c.a) || moved(c.b) {
                continue;
            }
            if !(c.t > 0.0 && c.t < 1.0) {
                continue;
            }
            let snap = if c.t < SNAP_SHARE {
                Some(VertexMove {
                    vertex: c.a,
                    toward: c.b,
                    t: c.t,
                })
            } else if c.t > 1.0 - SNAP_SHARE {
                Some(VertexMove {
                    vertex: c.b,
                    toward: c.a,
                    t: 1.0 - c.t,
                })
            } else {
                None
            };
            match snap {
                Some(m) if !stays(m.vertex) && split::can_move(model, &m, &self.moves) => {
                    self.moves.push(m)
                }
                Some(m) if m.t < PIN_SHARE => self.pinned.push(m.vertex),
                _ => self.splits.push(*c),
            }
        }
    }

    /// Whether the plan changes nothing in the model.
    pub fn is_empty(&self) -> bool {
        self.moves.is_empty() && self.splits.is_empty()
    }

    /// Empty it, keeping its buffers.
    pub fn clear(&mut self) {
        self.moves.clear();
        self.splits.clear();
        self.pinned.clear();
    }
}

/// An element's corners before a change: a tetrahedron's four, or a triangle's three and [`NO_VERTEX`].
pub type Corners = [u32; 4];

/// What a subdivision changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Subdivision {
    /// Id of the first new vertex (the vertex count before).
    pub first_new_vertex: u32,
    /// The edge each new vertex split, in id order.
    pub new_vertices: Vec<EdgeSplit>,
    /// The vertices moved, with their rest positions before, mm.
    pub moved: Vec<(VertexMove, Vec3)>,
    /// The elements (tetrahedra of a volume, else triangles) split or re-pointed, with their corners before,
    /// in increasing order of id.
    pub changed_elements: Vec<(u32, Corners)>,
    /// Id of the first element appended.
    pub first_new_element: u32,
    /// The element each appended one was split from (an id below `first_new_element`).
    pub element_origins: Vec<u32>,
    /// A volume's surface triangles split (a sheet's are its elements: empty), with their corners before, in
    /// increasing order of id.
    pub changed_triangles: Vec<(u32, [u32; 3])>,
    /// Id of the first surface triangle appended (a sheet's: `first_new_element`).
    pub first_new_triangle: u32,
    /// The triangle each appended surface triangle was split from.
    pub triangle_origins: Vec<u32>,
}

impl Subdivision {
    /// Whether anything changed.
    pub fn is_empty(&self) -> bool {
        self.new_vertices.is_empty() && self.moved.is_empty()
    }

    /// The surface triangles whose corners changed or that were appended, in increasing order: what a collider
    /// and a replica re-read.
    pub fn touched_triangles(&self, volume: bool) -> Vec<u32> {
        let mut out: Vec<u32> = if volume {
            self.changed_triangles.iter().map(|&(t, _)| t).collect()
        } else {
            self.changed_elements.iter().map(|&(t, _)| t).collect()
        };
        let (first, count) = if volume {
            (self.first_new_triangle, self.triangle_origins.len())
        } else {
            (self.first_new_element, self.element_origins.len())
        };
        out.extend(first..first + count as u32);
        out
    }
}

/// `model` subdivided by `plan` into `parts` (its buffers reused): vertices moved, edges split, masses and
/// springs shared out again, no touched vertex stiffer for its mass than `rate_ceiling` ([`rate_ceiling`] of
/// the uncut model). Allocates: for a cut, not the steady tick. A plan naming a vertex or edge the model does
/// not have changes nothing for that entry.
pub fn subdivide_into(
    model: &MassSpringModel,
    plan: &CutPlan,
    parts: &mut ModelParts,
    rate_ceiling: f32,
) -> Subdivision {
    model.to_parts_into(parts);
    let mut change = split::apply(model, plan, parts);
    if change.is_empty() {
        change.changed_elements.clear();
        change.changed_triangles.clear();
        return change;
    }
    shares::share_out(model, &change, parts, rate_ceiling);
    change
}

/// A sheet's triangle or a volume's tetrahedron as [`Corners`].
fn corners_of<const K: usize>(element: &[u32; K]) -> Corners {
    let mut c = [NO_VERTEX; 4];
    c[..K].copy_from_slice(element);
    c
}

#[cfg(test)]
mod tests;
