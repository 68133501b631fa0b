//! A cut that follows the blade: where each sweep crosses a model's edges (the cut plan), the vertices the blade
//! has put on its path, and which facets lie on that path (the seams to open).
//!
//! Owns: [`BladePath`], one per blade (a scalpel's edge, a pair of scissors' two). Each sweep gets a stamp and
//! is remembered for [`HISTORY_SWEEPS`] sweeps. A vertex the cut puts on the blade's path (a new vertex where an
//! edge was split, a vertex moved onto the path, one taken as on it where it lies, and later the copies a seam
//! makes of these) is remembered with its sweep's stamp and where it was then. A facet whose every vertex is on
//! the path lies on the cut when its centre (at those places) is within a quarter of its size of a remembered
//! sweep: the cut between two crossings follows the blade's path between them (in whichever sweeps passed there:
//! a path that comes back to its start closes through sweeps made before and after), and a chord across a bend
//! of the path does not open.
//!
//! Must not: change the model (the sim subdivides and opens, `sim/cut_follow.rs`), or allocate outside a cut.

use std::collections::VecDeque;

use parry3d::bounding_volume::{Aabb, BoundingVolume};
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::Triangle;

use super::BladeSweep;
use crate::collision::glam_boundary::to_parry;
use crate::tissue::seams::{Facet, NO_VERTEX, Opening, facet_without};
use crate::tissue::subdivision::{CutPlan, EdgeSplit, Subdivision};
use crate::tissue::{MassSpringModel, Vec3};

/// Sweeps remembered: 4 s at 1 kHz. A facet whose vertices were put on the path further apart than this is
/// taken as on it unchecked.
pub const HISTORY_SWEEPS: usize = 4096;

/// A facet lies on the cut when its centre is within this share of its mean edge of the blade's path.
const ON_PATH_SHARE: f32 = 0.25;

/// A vertex the blade has put on its path.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CutVertex {
    object: u16,
    vertex: u32,
    /// The sweep that put it there.
    stamp: u64,
    /// Where it was then, world frame, mm.
    place_mm: Vec3,
}

/// One blade's cut by subdivision: its sweeps and the vertices on its path.
#[derive(Debug, Default)]
pub struct BladePath {
    /// The latest sweeps, oldest first: their boxes and triangles.
    sweeps: VecDeque<(Aabb, [Triangle; 2])>,
    /// The latest sweep itself (a second object cut by the same sweep gets the same stamp).
    last: Option<BladeSweep>,
    /// Stamp of the latest sweep.
    stamp: u64,
    /// Vertices on the path, sorted by (object, vertex).
    on_cut: Vec<CutVertex>,
    /// This sweep's new vertices on the path (object, vertex).
    fresh: Vec<(u16, u32)>,
    /// Scratch: the edges near the sweep.
    edges: Vec<[u32; 2]>,
    /// Scratch: per vertex, on which sides of the sweep's reach it lies ([`outcode`]).
    outcodes: Vec<u8>,
    /// Scratch: where the sweep crosses them.
    crossings: Vec<EdgeSplit>,
    /// The plan of the latest sweep on the latest object.
    pub plan: CutPlan,
    /// Where the blade's edge was [`CATCH_UP_SWEEPS`] contiguous sweeps ago (or since the stroke began, if
    /// fewer): the start of the catch-up chord, and how many sweeps it spans.
    stroke: VecDeque<[Vec3; 2]>,
}

/// Sweeps the plan looks back over: besides the latest sweep, it splits any edge that now crosses the
/// quadrilateral from where the edge was this many contiguous sweeps ago to where it is now. Tissue that moves
/// as the blade does (a retracted plate lifting as its attachment is divided) can carry an edge's crossing
/// from ahead of the blade to behind it between two ticks, so that no one sweep's quadrilateral holds it; the
/// blade passed through that edge all the same. 16 sweeps is 0.32 mm at 20 mm/s: a chord across so little of
/// a path is within rounding of the path itself.
pub const CATCH_UP_SWEEPS: usize = 16;

/// On which sides of `reach` point `p` lies: one bit per side (below the least x, above the greatest x, then y,
/// then z). An element's box misses `reach` exactly when its vertices' codes share a bit (they all lie beyond
/// one side), the test `Aabb::intersects` makes of the element's box, without building it.
/// How far beyond a sweep's box the plan looks for edges, mm. An edge that crosses the swept quadrilateral has
/// ends beyond no single face of the quadrilateral's box, so neither has the element it is on: the box alone
/// finds every crossing, and this covers rounding in the ray test. (The facet cut's margin, two of the longest
/// springs, is for its centroid segments: on the liver it took in thousands of tetrahedra a tick, and a
/// blade held above the organ cost the tick 0.57 ms.)
const PLAN_REACH_MM: f32 = 0.1;

fn outcode(reach: &Aabb, p: &Vec3) -> u8 {
    let mut code = 0;
    for axis in 0..3 {
        code |= u8::from(p[axis] < reach.mins[axis]) << (2 * axis);
        code |= u8::from(p[axis] > reach.maxs[axis]) << (2 * axis + 1);
    }
    code
}

/// Sort `out[start..]` and drop its repeats.
fn sort_dedup_from(out: &mut Vec<Facet>, start: usize) {
    out[start..].sort_unstable();
    let mut kept = start;
    for i in start..out.len() {
        if i == start || out[i] != out[kept - 1] {
            out[kept] = out[i];
            kept += 1;
        }
    }
    out.truncate(kept);
}

/// Where segment `p -> q` crosses either triangle, as a share of the way from `p`.
fn crossing(swept: &[Triangle; 2], p: &Vec3, q: &Vec3) -> Option<f32> {
    let dir = q - p;
    if dir.norm_squared() == 0.0 {
        return None;
    }
    let ray = Ray::new(to_parry(p), to_parry(&dir));
    swept
        .iter()
        .filter_map(|t| t.cast_local_ray(&ray, 1.0, false))
        .reduce(f32::min)
}

impl BladePath {
    /// The stamp of `sweep`: a new one unless it is the sweep seen last (another object on the same sweep).
    fn stamp_for(&mut self, sweep: &BladeSweep) -> u64 {
        if self.last.as_ref() != Some(sweep) {
            if self.sweeps.capacity() < HISTORY_SWEEPS {
                self.sweeps.reserve_exact(HISTORY_SWEEPS);
            }
            self.stamp += 1;
            self.last = Some(*sweep);
            if self.sweeps.len() == HISTORY_SWEEPS {
                self.sweeps.pop_front();
            }
            self.sweeps.push_back((sweep.aabb(), sweep.triangles()));
        }
        self.stamp
    }

    /// The catch-up chord of `sweep` ([`CATCH_UP_SWEEPS`]): from the edge where it was that many contiguous
    /// sweeps ago to where it is now. A sweep that does not start where the last one ended begins a new stroke
    /// (the chord is then the sweep itself). Called once per sweep and object; no allocation once warm.
    fn catch_up_chord(&mut self, sweep: &BladeSweep) -> BladeSweep {
        if self.stroke.back() != Some(&sweep.to_mm) {
            if self.stroke.back() != Some(&sweep.from_mm) {
                self.stroke.clear();
                self.stroke.reserve(CATCH_UP_SWEEPS + 1);
                self.stroke.push_back(sweep.from_mm);
            }
            if self.stroke.len() > CATCH_UP_SWEEPS {
                self.stroke.pop_front();
            }
            self.stroke.push_back(sweep.to_mm);
        }
        BladeSweep {
            from_mm: *self.stroke.front().unwrap_or(&sweep.from_mm),
            to_mm: sweep.to_mm,
        }
    }

    fn find(&self, object: u16, vertex: u32) -> Result<usize, usize> {
        self.on_cut
            .binary_search_by(|c| (c.object, c.vertex).cmp(&(object, vertex)))
    }

    /// Whether vertex `vertex` of object `object` is on the path.
    pub fn is_on_cut(&self, object: u16, vertex: u32) -> bool {
        self.find(object, vertex).is_ok()
    }

    fn put_on_cut(&mut self, object: u16, vertex: u32, stamp: u64, place_mm: Vec3) {
        let entry = CutVertex {
            object,
            vertex,
            stamp,
            place_mm,
        };
        match self.find(object, vertex) {
            Ok(i) => self.on_cut[i] = entry,
            Err(i) => self.on_cut.insert(i, entry),
        }
        self.fresh.push((object, vertex));
    }

    /// Plan the cut of `sweep` through object `object` (`model` at `positions_mm`): every element edge that
    /// crosses it (of the elements that reach its box), and where; then [`CutPlan::from_crossings`]. The plan
    /// is [`Self::plan`].
    pub fn plan_sweep(
        &mut self,
        object: u16,
        model: &MassSpringModel,
        positions_mm: &[Vec3],
        sweep: &BladeSweep,
        stays: &[u32],
    ) {
        self.plan.clear();
        self.fresh.clear();
        self.stamp_for(sweep);
        if sweep.from_mm == sweep.to_mm {
            return;
        }
        let swept = sweep.triangles();
        let chord = self.catch_up_chord(sweep);
        let chord_triangles = chord.triangles();
        let reach = sweep.aabb().merged(&chord.aabb()).loosened(PLAN_REACH_MM);
        self.edges.clear();
        self.outcodes.clear();
        self.outcodes
            .extend(positions_mm.iter().map(|p| outcode(&reach, p)));
        let codes = &self.outcodes;
        let mut near = |element: &[u32]| {
            let beyond = element
                .iter()
                .fold(u8::MAX, |all, &v| all & codes[v as usize]);
            if beyond == 0 {
                for (i, &p) in element.iter().enumerate() {
                    for &q in &element[i + 1..] {
                        self.edges.push([p.min(q), p.max(q)]);
                    }
                }
            }
        };
        let tets = &model.tets().tets;
        if tets.is_empty() {
            model.triangles().iter().for_each(|t| near(t));
        } else {
            tets.iter().for_each(|t| near(t));
        }
        self.edges.sort_unstable();
        self.edges.dedup();
        self.crossings.clear();
        for &[a, b] in &self.edges {
            let (p, q) = (&positions_mm[a as usize], &positions_mm[b as usize]);
            let t = match (crossing(&swept, p, q), crossing(&chord_triangles, p, q)) {
                (Some(s), Some(c)) => Some(s.min(c)),
                (s, c) => s.or(c),
            };
            if let Some(t) = t {
                self.crossings.push(EdgeSplit { a, b, t });
            }
        }
        let mut plan = std::mem::take(&mut self.plan);
        let mut crossings = std::mem::take(&mut self.crossings);
        plan.from_crossings(
            model,
            &mut crossings,
            |v| self.is_on_cut(object, v),
            |v| stays.binary_search(&v).is_ok(),
        );
        self.crossings = crossings;
        self.plan = plan;
    }

    /// The plan has been applied (`change`, the model now at `positions_mm`): remember the vertices it put on
    /// the path.
    pub fn record_plan(&mut self, object: u16, change: &Subdivision, positions_mm: &[Vec3]) {
        let stamp = self.stamp;
        let mut put = Vec::with_capacity(
            change.new_vertices.len() + change.moved.len() + self.plan.pinned.len(),
        );
        put.extend((0..change.new_vertices.len() as u32).map(|k| change.first_new_vertex + k));
        put.extend(change.moved.iter().map(|(m, _)| m.vertex));
        put.extend_from_slice(&self.plan.pinned);
        for v in put {
            if let Some(&place) = positions_mm.get(v as usize) {
                self.put_on_cut(object, v, stamp, place);
            }
        }
    }

    /// A seam opening of object `object` made copies of some vertices: copies of vertices on the path are on
    /// it too, with their parents' stamps and places.
    pub fn record_opening(&mut self, object: u16, opening: &Opening) {
        for (k, &parent) in opening.parents.iter().enumerate() {
            if let Ok(i) = self.find(object, parent) {
                let CutVertex {
                    stamp, place_mm, ..
                } = self.on_cut[i];
                let copy = opening.first_new_vertex + k as u32;
                self.put_on_cut(object, copy, stamp, place_mm);
            }
        }
    }

    /// The facets of `model` (object `object`) around this sweep's new vertices on the path that lie on the
    /// path, appended to `out` (sorted, once each).
    pub fn facets_on_path(&self, object: u16, model: &MassSpringModel, out: &mut Vec<Facet>) {
        let tets = &model.tets().tets;
        let start = out.len();
        for &(o, v) in &self.fresh {
            if o != object || v as usize >= model.node_count() {
                continue;
            }
            if tets.is_empty() {
                for &t in model.node_triangles(v as usize) {
                    self.push_on_path(object, &model.triangles()[t as usize], v, out);
                }
            } else {
                for &t in model.node_tets(v as usize) {
                    self.push_on_path(object, &tets[t as usize], v, out);
                }
            }
        }
        sort_dedup_from(out, start);
    }

    /// [`Self::facets_on_path`] in a mesh not built into a model yet (a sheet's `triangles`, or a volume's
    /// `tets`): every element is looked at for this sweep's new vertices on the path, and the same facets are
    /// found.
    pub fn facets_on_path_of(
        &self,
        object: u16,
        triangles: &[[u32; 3]],
        tets: &[[u32; 4]],
        out: &mut Vec<Facet>,
    ) {
        let start = out.len();
        let fresh = |v: u32| self.fresh.iter().any(|&(o, f)| o == object && f == v);
        if tets.is_empty() {
            for t in triangles {
                for &v in t.iter().filter(|&&v| fresh(v)) {
                    self.push_on_path(object, t, v, out);
                }
            }
        } else {
            for t in tets {
                for &v in t.iter().filter(|&&v| fresh(v)) {
                    self.push_on_path(object, t, v, out);
                }
            }
        }
        sort_dedup_from(out, start);
    }

    /// Push each facet of `element` holding `v` that lies on the path.
    fn push_on_path<const K: usize>(
        &self,
        object: u16,
        element: &[u32; K],
        v: u32,
        out: &mut Vec<Facet>,
    ) {
        for skip in 0..K {
            if element[skip] == v {
                continue;
            }
            let facet = facet_without(element, skip);
            if self.on_path(object, &facet) {
                out.push(facet);
            }
        }
    }

    /// Whether every vertex of `facet` is on the path and its centre lies on a remembered sweep.
    fn on_path(&self, object: u16, facet: &Facet) -> bool {
        let mut corners = [Vec3::zeros(); 3];
        let mut count = 0;
        let mut first = u64::MAX;
        for &v in facet.iter().filter(|&&v| v != NO_VERTEX) {
            let Ok(i) = self.find(object, v) else {
                return false;
            };
            let c = &self.on_cut[i];
            corners[count] = c.place_mm;
            count += 1;
            first = first.min(c.stamp);
        }
        if count < 2 {
            return false;
        }
        let corners = &corners[..count];
        let centre = corners.iter().sum::<Vec3>() / count as f32;
        let mut size = 0.0;
        let mut edges = 0.0;
        for i in 0..count {
            for j in i + 1..count {
                size += (corners[i] - corners[j]).norm();
                edges += 1.0;
            }
        }
        let tolerance = ON_PATH_SHARE * size / edges;
        // Older than every sweep remembered: taken as on the path unchecked.
        let oldest = self.stamp + 1 - self.sweeps.len() as u64;
        if first < oldest {
            return true;
        }
        let point = to_parry(&centre);
        self.sweeps
            .iter()
            .filter(|(aabb, _)| aabb.loosened(tolerance).contains_local_point(point))
            .flat_map(|(_, triangles)| triangles)
            .any(|t| t.distance_to_local_point(point, true) <= tolerance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edge_through_the_swept_quad_crosses_it_where_it_passes() {
        let sweep = BladeSweep {
            from_mm: [Vec3::new(0.3, 0.0, -3.0), Vec3::new(0.3, 0.0, 3.0)],
            to_mm: [Vec3::new(0.3, 1.0, -3.0), Vec3::new(0.3, 1.0, 3.0)],
        };
        let swept = sweep.triangles();
        let t = crossing(&swept, &Vec3::new(0.0, 0.5, 0.0), &Vec3::new(1.0, 0.5, 0.0));
        assert!((t.unwrap() - 0.3).abs() < 1e-6);
        let t = crossing(&swept, &Vec3::new(1.0, 0.5, 0.0), &Vec3::new(0.0, 0.5, 0.0));
        assert!((t.unwrap() - 0.7).abs() < 1e-6);
        assert!(crossing(&swept, &Vec3::new(0.0, 1.5, 0.0), &Vec3::new(1.0, 1.5, 0.0)).is_none());
    }
}
