//! The tissue surface as an owned parry BVH over its triangles, refitted in place, and the broad phase over it.
//!
//! Owns: the surface's vertex positions as parry last saw them, its triangles, the vertex -> triangle
//! adjacency, one BVH leaf per triangle, and two refit paths: every triangle (objects simulated whole), or
//! only the triangles around the nodes that moved (objects simulated by region of deformation). Must not:
//! move nodes, decide which nodes moved, or rebuild the tree in a tick (its shape is the rest shape's; refits
//! only resize boxes).
//!
//! Why not parry's `TriMesh`: its refit (`set_vertices`) walks every triangle, ~100 us for 10k triangles, and it
//! has no partial refit; an owned [`Bvh`] has one (`refit_partial`, O(changed x tree height)). Queries are the
//! same: `nodes_near` only needs the tree and the triangles.

use parry3d::bounding_volume::Aabb;
use parry3d::bounding_volume::BoundingVolume;
use parry3d::math::Vector;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};
use parry3d::shape::Triangle;
use thiserror::Error;

use super::glam_boundary::to_parry;
use crate::tissue::Vec3;
use sinew_parallel::{ChunkRunner, chunk_range, for_chunks_mut};

/// Per-index stamps (nodes, or triangles) that deduplicate without clearing or allocating.
#[derive(Debug, Clone)]
pub struct NodeMarks {
    stamps: Vec<u32>,
    current: u32,
}

impl NodeMarks {
    /// Marks for `n` nodes.
    pub fn new(n: usize) -> Self {
        Self {
            stamps: vec![0; n],
            current: 0,
        }
    }

    /// Start a new round: every index is unseen again. O(1) (O(n) once every 2^32 rounds).
    pub fn next_round(&mut self) {
        self.current = self.current.wrapping_add(1);
        if self.current == 0 {
            self.stamps.fill(0);
            self.current = 1;
        }
    }

    /// True the first time `i` is seen this round (false for an index out of range).
    pub fn first_visit(&mut self, i: u32) -> bool {
        let Some(stamp) = self.stamps.get_mut(i as usize) else {
            return false;
        };
        let first = *stamp != self.current;
        *stamp = self.current;
        first
    }
}

/// Why a surface could not become a collider.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SurfaceColliderError {
    /// No triangles.
    #[error("surface has no triangles")]
    Empty,
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} names vertex {vertex}, but there are {vertices} vertices")]
    IndexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// The bad vertex index.
        vertex: u32,
        /// Vertex count.
        vertices: usize,
    },
}

/// A deformable triangle surface: BVH refitted in place, never rebuilt (its topology is the rest shape's). No
/// oriented pseudo-normals: they would be stale on a deforming mesh.
pub struct SurfaceCollider {
    bvh: Bvh,
    vertices: Vec<Vector>,
    triangles: Vec<[u32; 3]>,
    /// CSR vertex -> incident triangles.
    vertex_triangle_start: Vec<u32>,
    vertex_triangles: Vec<u32>,
    /// Scratch of the partial refit: triangles touched this refit (capacity: every triangle).
    changed: Vec<u32>,
    triangle_marks: NodeMarks,
    /// Leaf boxes are this much larger than their triangle (0: exact).
    refit_margin_mm: f32,
    /// A copy of every leaf's box as the tree holds it, so the common case (the triangle is still inside its
    /// fattened box) is one containment test here instead of a leaf lookup inside parry.
    leaf_boxes: Vec<Aabb>,
    /// Scratch of [`Self::refit_on`]: per triangle, its new box when it left its stored one.
    fresh_boxes: Vec<Option<Aabb>>,
}

/// Vertices per chunk of [`SurfaceCollider::refit_on`]'s copy.
const VERTEX_CHUNK: usize = 1024;
/// Triangles per chunk of its box tests.
const TRIANGLE_CHUNK: usize = 1024;

impl std::fmt::Debug for SurfaceCollider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SurfaceCollider")
            .field("triangles", &self.triangles.len())
            .field("refit_margin_mm", &self.refit_margin_mm)
            .finish()
    }
}

/// Every corner of `triangles` names one of `n` vertices.
fn check_indices(n: usize, triangles: &[[u32; 3]]) -> Result<(), SurfaceColliderError> {
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&vertex) = tri.iter().find(|&&v| v as usize >= n) {
            return Err(SurfaceColliderError::IndexOutOfRange {
                triangle: t,
                vertex,
                vertices: n,
            });
        }
    }
    Ok(())
}

fn triangle_aabb(vertices: &[Vector], t: &[u32; 3]) -> Aabb {
    Triangle::new(
        vertices[t[0] as usize],
        vertices[t[1] as usize],
        vertices[t[2] as usize],
    )
    .local_aabb()
}

impl SurfaceCollider {
    /// Build from positions and triangles, with exact leaf boxes.
    pub fn new(
        positions_mm: &[Vec3],
        triangles: &[[u32; 3]],
    ) -> Result<Self, SurfaceColliderError> {
        if triangles.is_empty() {
            return Err(SurfaceColliderError::Empty);
        }
        let n = positions_mm.len();
        check_indices(n, triangles)?;
        let vertices: Vec<Vector> = positions_mm.iter().map(to_parry).collect();
        let leaf_boxes: Vec<Aabb> = triangles
            .iter()
            .map(|t| triangle_aabb(&vertices, t))
            .collect();
        let bvh = Bvh::from_iter(
            BvhBuildStrategy::Binned,
            leaf_boxes.iter().copied().enumerate(),
        );
        let (start, list) = crate::incidence::incidence(n, triangles);
        Ok(Self {
            bvh,
            vertices,
            triangles: triangles.to_vec(),
            vertex_triangle_start: start,
            vertex_triangles: list,
            changed: Vec::with_capacity(triangles.len()),
            triangle_marks: NodeMarks::new(triangles.len()),
            refit_margin_mm: 0.0,
            leaf_boxes,
            fresh_boxes: Vec::new(),
        })
    }

    /// Rewrite leaf `t`'s box if its triangle left it; true when it did. No allocation.
    #[inline]
    fn update_leaf(&mut self, t: u32) -> bool {
        let aabb = triangle_aabb(&self.vertices, &self.triangles[t as usize]);
        let Some(stored) = self.leaf_boxes.get_mut(t as usize) else {
            return false;
        };
        if self.refit_margin_mm > 0.0 && stored.contains(&aabb) {
            return false;
        }
        *stored = aabb.loosened(self.refit_margin_mm);
        self.bvh
            .update_partially_if_present(aabb, t, self.refit_margin_mm)
            .is_some()
    }

    /// Fatten every leaf box refitted from now on by `margin_mm` (clamped to >= 0): a leaf is then rewritten
    /// only when its triangle leaves the fat box, so a still or slowly creeping surface costs no tree walk.
    /// Queries stay conservative (they may return a triangle up to `margin_mm` beyond the query box, never miss
    /// one). For broad phases whose own margin dwarfs this one.
    pub fn with_refit_margin(mut self, margin_mm: f32) -> Self {
        self.refit_margin_mm = if margin_mm.is_finite() {
            margin_mm.max(0.0)
        } else {
            0.0
        };
        self
    }

    /// A box around the whole surface as the tree last saw it (conservative: leaf boxes may be fattened by the
    /// refit margin).
    pub fn root_aabb(&self) -> Aabb {
        self.bvh.root_aabb()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Move every vertex and refit the boxes of the triangles that left their (margin-fattened) leaf box.
    /// Returns the leaves rewritten. No allocation (same vertex count); O(triangles) box tests plus the
    /// refit of the changed paths.
    pub fn refit(&mut self, positions_mm: &[Vec3]) -> usize {
        for (dst, src) in self.vertices.iter_mut().zip(positions_mm) {
            *dst = to_parry(src);
        }
        self.changed.clear();
        for t in 0..self.triangles.len() as u32 {
            if self.update_leaf(t) {
                self.changed.push(t);
            }
        }
        self.refit_changed();
        self.changed.len()
    }

    /// [`Self::refit`] with the vertex copy and the box tests spread over `runner`; the leaves that moved are
    /// then rewritten on this thread in triangle order, so the tree, the changed list and every later query are
    /// the same as `refit`'s on any thread count. Allocates only when the triangle count grew.
    pub fn refit_on(&mut self, positions_mm: &[Vec3], runner: &dyn ChunkRunner) -> usize {
        if runner.threads() <= 1 {
            return self.refit(positions_mm);
        }
        let n = self.vertices.len().min(positions_mm.len());
        for_chunks_mut(runner, &mut self.vertices[..n], VERTEX_CHUNK, |c, out| {
            for (dst, i) in out.iter_mut().zip(chunk_range(c, n, VERTEX_CHUNK)) {
                *dst = to_parry(&positions_mm[i]);
            }
        });
        let count = self.triangles.len().min(self.leaf_boxes.len());
        if self.fresh_boxes.len() != count {
            self.fresh_boxes.resize(count, None);
        }
        let (vertices, triangles, stored) = (&self.vertices, &self.triangles, &self.leaf_boxes);
        let margin = self.refit_margin_mm;
        for_chunks_mut(runner, &mut self.fresh_boxes, TRIANGLE_CHUNK, |c, out| {
            for (fresh, t) in out.iter_mut().zip(chunk_range(c, count, TRIANGLE_CHUNK)) {
                let aabb = triangle_aabb(vertices, &triangles[t]);
                *fresh = (margin <= 0.0 || !stored[t].contains(&aabb)).then_some(aabb);
            }
        });
        self.changed.clear();
        for t in 0..count {
            let Some(aabb) = self.fresh_boxes[t] else {
                continue;
            };
            self.leaf_boxes[t] = aabb.loosened(self.refit_margin_mm);
            if self
                .bvh
                .update_partially_if_present(aabb, t as u32, self.refit_margin_mm)
                .is_some()
            {
                self.changed.push(t as u32);
            }
        }
        self.refit_changed();
        self.changed.len()
    }

    /// Follow a topology change (a cut or a tear): `positions_mm` holds the vertices (new ones appended),
    /// `triangles` the surface, whose `changed` triangles were re-pointed and whose triangles past the ones this
    /// collider holds were appended. Re-pointed leaves are refitted and new ones inserted: the tree is kept, not
    /// rebuilt. Refuses (changing nothing) a triangle list shorter than the one held or an index out of range.
    /// Allocates (a cut is an event, not the steady tick).
    pub fn retopologize(
        &mut self,
        positions_mm: &[Vec3],
        triangles: &[[u32; 3]],
        changed: &[u32],
    ) -> Result<(), SurfaceColliderError> {
        let n = positions_mm.len();
        check_indices(n, triangles)?;
        let held = self.triangles.len();
        if triangles.len() < held {
            return Err(SurfaceColliderError::Empty);
        }
        self.vertices.clear();
        self.vertices.extend(positions_mm.iter().map(to_parry));
        self.triangles.clear();
        self.triangles.extend_from_slice(triangles);
        let (start, list) = crate::incidence::incidence(n, triangles);
        self.vertex_triangle_start = start;
        self.vertex_triangles = list;
        self.triangle_marks = NodeMarks::new(triangles.len());
        self.changed.clear();
        self.changed.reserve(triangles.len());
        for &t in changed.iter().filter(|&&t| (t as usize) < held) {
            if self.update_leaf(t) {
                self.changed.push(t);
            }
        }
        self.refit_changed();
        for t in held..triangles.len() {
            let aabb =
                triangle_aabb(&self.vertices, &self.triangles[t]).loosened(self.refit_margin_mm);
            self.leaf_boxes.push(aabb);
            self.bvh.insert(aabb, t as u32);
        }
        Ok(())
    }

    /// Refit the paths above `self.changed`: one partial pass when few leaves changed, one bottom-up pass
    /// over the whole tree when many did.
    fn refit_changed(&mut self) {
        // A partial refit walks each changed leaf's path to the root (no sharing between paths); past about
        // `triangles / height` changed leaves one bottom-up pass over the whole tree is cheaper.
        let kept = self.changed.len();
        let height = usize::BITS - self.triangles.len().leading_zeros();
        if kept * height as usize > self.triangles.len() {
            self.bvh.refit_without_opt();
        } else if kept > 0 {
            self.bvh.refit_partial(&[], &self.changed);
        }
    }

    /// Move only the vertices in `moved` (node indices; repeats and out-of-range indices are harmless) and
    /// refit the triangles around those whose position changed. Equivalent to [`Self::refit`] when no other
    /// vertex moved since the last refit. Returns the leaves rewritten. Real-time contract: no allocation,
    /// never panics; O(triangles around `moved` x tree height).
    pub fn refit_nodes(&mut self, positions_mm: &[Vec3], moved: &[u32]) -> usize {
        self.triangle_marks.next_round();
        self.changed.clear();
        for &i in moved {
            let (Some(src), Some(dst)) = (
                positions_mm.get(i as usize),
                self.vertices.get_mut(i as usize),
            ) else {
                continue;
            };
            let p = to_parry(src);
            if *dst == p {
                continue;
            }
            *dst = p;
            let (from, to) = (
                self.vertex_triangle_start[i as usize] as usize,
                self.vertex_triangle_start[i as usize + 1] as usize,
            );
            for &t in &self.vertex_triangles[from..to] {
                if self.triangle_marks.first_visit(t) {
                    self.changed.push(t);
                }
            }
        }
        // Keep only the leaves whose box actually changed (all of them when the margin is 0).
        let mut kept = 0;
        for k in 0..self.changed.len() {
            let t = self.changed[k];
            if self.update_leaf(t) {
                self.changed[kept] = t;
                kept += 1;
            }
        }
        self.changed.truncate(kept);
        self.refit_changed();
        kept
    }

    /// The triangles whose boxes overlap `aabb` (conservative: up to the refit margin beyond it). No
    /// allocation.
    pub fn triangles_near<'a>(&'a self, aabb: &'a Aabb) -> impl Iterator<Item = u32> + 'a {
        self.bvh.intersect_aabb(aabb)
    }

    /// Append to `out` every node of every triangle whose box overlaps `aabb` (each node once).
    /// No allocation once `out` has grown to the contact size.
    pub fn nodes_near(&self, aabb: &Aabb, marks: &mut NodeMarks, out: &mut Vec<u32>) {
        marks.next_round();
        for tri in self.bvh.intersect_aabb(aabb) {
            let Some(vertices) = self.triangles.get(tri as usize) else {
                continue;
            };
            for &v in vertices {
                if marks.first_visit(v) {
                    out.push(v);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `side` x `side` node sheet of 1 mm cells on z = 0.
    fn sheet(side: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut positions = Vec::new();
        for j in 0..side {
            for i in 0..side {
                positions.push(Vec3::new(i as f32, j as f32, 0.0));
            }
        }
        let id = |i: u32, j: u32| j * side + i;
        let mut triangles = Vec::new();
        for j in 0..side - 1 {
            for i in 0..side - 1 {
                triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (positions, triangles)
    }

    fn near(collider: &SurfaceCollider, aabb: &Aabb, n: usize) -> Vec<u32> {
        let mut marks = NodeMarks::new(n);
        let mut out = Vec::new();
        collider.nodes_near(aabb, &mut marks, &mut out);
        out.sort_unstable();
        out
    }

    #[test]
    fn bad_surfaces_are_refused() {
        let (positions, _) = sheet(3);
        assert_eq!(
            SurfaceCollider::new(&positions, &[]).err(),
            Some(SurfaceColliderError::Empty)
        );
        assert!(matches!(
            SurfaceCollider::new(&positions, &[[0, 1, 99]]),
            Err(SurfaceColliderError::IndexOutOfRange { vertex: 99, .. })
        ));
    }

    #[test]
    fn refit_follows_moved_nodes() {
        let (mut positions, triangles) = sheet(20);
        let mut collider = SurfaceCollider::new(&positions, &triangles).unwrap();
        // Nothing lives 5 mm below the sheet until a node is pulled there.
        let below = Aabb::new(Vector::new(9.5, 9.5, -6.0), Vector::new(10.5, 10.5, -4.0));
        assert!(near(&collider, &below, positions.len()).is_empty());
        positions[10 * 20 + 10].z = -5.0;
        collider.refit(&positions);
        let found = near(&collider, &below, positions.len());
        assert!(found.contains(&(10 * 20 + 10)), "{found:?}");
    }

    #[test]
    fn partial_refit_answers_like_a_full_refit() {
        let (rest, triangles) = sheet(40);
        let n = rest.len();
        let mut full = SurfaceCollider::new(&rest, &triangles).unwrap();
        let mut partial = SurfaceCollider::new(&rest, &triangles).unwrap();
        let mut positions = rest.clone();
        // A dent around (20, 20) deepening over ticks; only nodes within 6 mm move.
        let mut moved = Vec::new();
        for tick in 1..=30 {
            moved.clear();
            for (i, (p, r)) in positions.iter_mut().zip(&rest).enumerate() {
                let d2 = (r.x - 20.0).powi(2) + (r.y - 20.0).powi(2);
                if d2 < 36.0 {
                    p.z = -0.1 * tick as f32 * (1.0 - d2 / 36.0);
                    moved.push(i as u32);
                }
            }
            full.refit(&positions);
            partial.refit_nodes(&positions, &moved);
            for query in [
                Aabb::new(Vector::new(18.0, 18.0, -4.0), Vector::new(22.0, 22.0, -1.0)),
                Aabb::new(Vector::new(14.0, 19.5, -0.5), Vector::new(15.5, 20.5, 0.5)),
                Aabb::new(Vector::new(-1.0, -1.0, -0.1), Vector::new(3.0, 2.0, 0.1)),
                Aabb::new(Vector::new(19.9, 19.9, -3.1), Vector::new(20.1, 20.1, -2.9)),
            ] {
                assert_eq!(
                    near(&full, &query, n),
                    near(&partial, &query, n),
                    "tick {tick}, query {query:?}"
                );
            }
        }
        // With a margin, a partial refit stays conservative: it finds at least what an exact one finds.
        let mut fat = SurfaceCollider::new(&rest, &triangles)
            .unwrap()
            .with_refit_margin(0.05);
        let all: Vec<u32> = (0..n as u32).collect();
        fat.refit_nodes(&positions, &all);
        let query = Aabb::new(Vector::new(18.0, 18.0, -4.0), Vector::new(22.0, 22.0, -1.0));
        let exact = near(&full, &query, n);
        let conservative = near(&fat, &query, n);
        assert!(exact.iter().all(|i| conservative.contains(i)));
    }
}
