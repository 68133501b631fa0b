//! A sharp tip pressing a surface before it punctures it: the surface tents under the tip.
//!
//! Owns: [`SurfacePoint`] (a material point of a surface: a triangle's stable id and barycentric weights, the
//! kind of point a grasp holds, a needle's hole and a thread's anchor are) and [`TipContact`] (one material
//! point of a surface pressed by a tip along a push direction).
//!
//! The model. A tip is a point, so the surface point it meets is held, not a node near it: a needle's tip on a
//! coarse mesh tents the surface at the tip, between the nodes, as a real tip does.
//! - **Hold** (each substep, after the tissue's integration): the point may not lie behind the tip along the
//!   push. If it does, it is moved to the tip's level along the push, spread over its triangle's free corners
//!   by their weights (the minimum-norm correction, as a grasp's), and the corners lose the velocity that
//!   carried it back. While the tip sticks, the point also goes with it across the push (a sharp tip digs
//!   in).
//! - **Force**: the tissue's pull on the point, `sum b_k f_k / sum b_k^2`, the same weighted node forces a
//!   grasp reads; its part along `-push` is the load.
//! - **Stick and slide**: the tip sticks while the pull across the push stays within a stick limit times the
//!   load, and slides past it (Coulomb, the across force held at the limit). A needle's limit is the tangent of
//!   its material's puncture angle: a tip pushed along its own direction within the puncture cone digs in and
//!   builds up to the puncture, a glancing one skates. A sliding tip's contact moves to the surface point now
//!   on its line along the push ([`TipContact::follow`]).
//! - **Lift**: a tip that drew back off the surface no longer holds it ([`TipContact::lifted`]).
//!
//! The push is the surface's rest normal at the point, inward at an entry and outward at an exit (a tip that
//! punctured the near wall of a volume tents the far wall from inside).
//!
//! Must not: allocate or panic; a point whose corners are all fixed, or missing, is left alone.

use crate::collision::{SurfaceCollider, crossing_nearest};
use crate::tissue::subdivision::ElementRemap;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A tip this far across its push from its point has slid off it, mm ([`TipContact::follow`]).
const SLIDE_MM: f32 = 0.02;
/// [`TipContact::follow`] looks for the surface this far either side of the tip along the push, mm.
const FOLLOW_REACH_MM: f32 = 1.0;
/// A tip this far back from its point along the push has lifted off it, mm.
const LIFT_MM: f32 = 0.05;

/// A material point of an object's surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Object index in the world.
    pub object: u16,
    /// Triangle of the object's surface (its stable id).
    pub triangle: u32,
    /// Weights of the triangle's corners (sum 1).
    pub barycentric: [f32; 3],
}

impl SurfacePoint {
    /// The same material point after object `object` was subdivided: on the piece of its triangle that holds it
    /// ([`ElementRemap::triangle`]); unchanged on another object.
    pub fn remapped(&self, object: usize, remap: &ElementRemap<'_>) -> Self {
        if usize::from(self.object) != object {
            return *self;
        }
        let (triangle, barycentric) = remap.triangle(self.triangle, self.barycentric);
        Self {
            triangle,
            barycentric,
            ..*self
        }
    }

    /// The triangle's corners, if the model has it.
    pub fn corners(&self, model: &MassSpringModel) -> Option<[u32; 3]> {
        model.triangles().get(self.triangle as usize).copied()
    }

    /// The corners' `values` (one per node) by the point's weights, if the model has its triangle.
    fn weighted(&self, model: &MassSpringModel, values: &[Vec3]) -> Option<Vec3> {
        let corners = self.corners(model)?;
        let mut sum = Vec3::zeros();
        for (&c, &b) in corners.iter().zip(&self.barycentric) {
            sum += values.get(c as usize)? * b;
        }
        Some(sum)
    }

    /// Where the point is now, mm.
    pub fn position_mm(&self, model: &MassSpringModel, state: &TissueState) -> Option<Vec3> {
        self.weighted(model, &state.positions_mm)
    }

    /// Where the point is at rest, mm.
    pub fn rest_position_mm(&self, model: &MassSpringModel) -> Option<Vec3> {
        self.weighted(model, model.rest_positions_mm())
    }

    /// The surface's outward rest normal at the point (unit), if the model has it.
    pub fn rest_normal(&self, model: &MassSpringModel) -> Option<Vec3> {
        self.weighted(model, model.rest_normals())?
            .try_normalize(1e-6)
    }

    /// Move the point by `shift_mm`, spread over the free corners by weight (minimum norm); with
    /// `stop_along` (unit), each moved corner also loses the part of its velocity against it. False when no
    /// corner is free.
    pub fn shift(
        &self,
        shift_mm: &Vec3,
        stop_along: Option<&Vec3>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) -> bool {
        let Some(corners) = self.corners(model) else {
            return false;
        };
        let n = state.positions_mm.len().min(state.velocities_mm_s.len());
        let free = |c: u32| (c as usize) < n && !model.is_fixed(c as usize);
        let weight: f32 = corners
            .iter()
            .zip(&self.barycentric)
            .filter(|(c, _)| free(**c))
            .map(|(_, b)| b * b)
            .sum();
        if weight.is_nan() || weight <= 0.0 {
            return false;
        }
        let correction = shift_mm / weight;
        for (&c, &b) in corners.iter().zip(&self.barycentric) {
            if b == 0.0 || !free(c) {
                continue;
            }
            let c = c as usize;
            state.positions_mm[c] += correction * b;
            if let Some(dir) = stop_along {
                let v = state.velocities_mm_s[c].dot(dir);
                if v < 0.0 {
                    state.velocities_mm_s[c] -= dir * v;
                }
            }
        }
        true
    }

    /// The tissue's force on whatever holds the point: its corners' weighted internal forces over the sum
    /// of their squared weights (free corners only), N. Zero when none is free.
    pub fn pull_n(&self, model: &MassSpringModel, state: &TissueState) -> Vec3 {
        let Some(corners) = self.corners(model) else {
            return Vec3::zeros();
        };
        let pressure = model.pressure_n_per_mm2(&state.positions_mm);
        let mut pull = Vec3::zeros();
        let mut weight = 0.0;
        for (&c, &b) in corners.iter().zip(&self.barycentric) {
            let c = c as usize;
            if b == 0.0 || model.is_fixed(c) || c >= state.positions_mm.len() {
                continue;
            }
            pull += model.node_force(c, &state.positions_mm, &state.velocities_mm_s, pressure) * b;
            weight += b * b;
        }
        if weight > 0.0 && pull.iter().all(|c| c.is_finite()) {
            pull / weight
        } else {
            Vec3::zeros()
        }
    }
}

/// A tip pressing a material point of a surface along `push` (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipContact {
    /// The point pressed.
    pub point: SurfacePoint,
    /// Which way the tip presses it (unit, world): the rest normal, inward at an entry, outward at an exit.
    pub push: Vec3,
    /// The tissue's force on the tip at the last [`TipContact::settle`], N: its push back (along `-push`) and,
    /// while the tip sticks, its pull across the push; while it slides, the across part is Coulomb's.
    pub force_n: Vec3,
    /// The part of `force_n` along `-push`, N (>= 0).
    pub load_n: f32,
    /// The tip slid across the surface at the last settle (the across pull passed the stick limit).
    pub sliding: bool,
}

impl TipContact {
    /// A tip meeting `point`, pressing it inward (`exit`: outward, from inside the object). None when the
    /// model lacks its triangle.
    pub fn new(point: SurfacePoint, exit: bool, model: &MassSpringModel) -> Option<Self> {
        let normal = point.rest_normal(model)?;
        Some(Self {
            point,
            push: if exit { normal } else { -normal },
            force_n: Vec3::zeros(),
            load_n: 0.0,
            sliding: false,
        })
    }

    /// One substep's hold: a point behind the tip along the push is brought level with it; a sticking tip
    /// also carries the point across the push with it (module doc).
    pub fn hold(&self, tip_mm: &Vec3, model: &MassSpringModel, state: &mut TissueState) {
        let Some(x) = self.point.position_mm(model, state) else {
            return;
        };
        let offset = tip_mm - x;
        let behind = offset.dot(&self.push);
        let mut shift = self.push * behind.max(0.0);
        if !self.sliding {
            shift += offset - self.push * behind;
        }
        if shift.iter().all(|c| c.is_finite()) && shift != Vec3::zeros() {
            self.point.shift(&shift, Some(&self.push), model, state);
        }
    }

    /// Read the tissue's force on the tip after the substeps, N. The tip sticks while the pull across the push
    /// stays within `stick` times the load (a tip square to the surface digs in), and slides past it, the
    /// across force then held to that limit. Returns the load along the push.
    pub fn settle(&mut self, stick: f32, model: &MassSpringModel, state: &TissueState) -> f32 {
        let pull = self.point.pull_n(model, state);
        let load = -pull.dot(&self.push);
        self.load_n = if load.is_finite() { load.max(0.0) } else { 0.0 };
        let across = pull + self.push * load;
        let limit = stick.max(0.0) * self.load_n;
        let across_n = across.norm();
        self.sliding = across_n > limit;
        let across = if self.sliding && across_n > 0.0 {
            across * (limit / across_n)
        } else {
            across
        };
        self.force_n = -self.push * self.load_n + across;
        if !self.force_n.iter().all(|c| c.is_finite()) {
            self.force_n = Vec3::zeros();
            self.load_n = 0.0;
        }
        self.load_n
    }

    /// The tip drew back off the point (by more than a hair along the push).
    pub fn lifted(&self, tip_mm: &Vec3, model: &MassSpringModel, state: &TissueState) -> bool {
        self.point
            .position_mm(model, state)
            .is_none_or(|x| (x - tip_mm).dot(&self.push) > LIFT_MM)
    }

    /// A sliding tip that moved across the push slides to the surface point now on its line along the push
    /// (within [`FOLLOW_REACH_MM`] of it); it stays put when none is found, or when it sticks. No allocation.
    pub fn follow(
        &mut self,
        tip_mm: &Vec3,
        collider: &SurfaceCollider,
        model: &MassSpringModel,
        state: &TissueState,
    ) {
        if !self.sliding {
            return;
        }
        let Some(x) = self.point.position_mm(model, state) else {
            return;
        };
        let offset = tip_mm - x;
        let across = offset - self.push * offset.dot(&self.push);
        if across.norm() <= SLIDE_MM {
            return;
        }
        let from = tip_mm - self.push * FOLLOW_REACH_MM;
        let to = tip_mm + self.push * FOLLOW_REACH_MM;
        if let Some(hit) = crossing_nearest(
            collider,
            model.triangles(),
            &state.positions_mm,
            &from,
            &to,
            FOLLOW_REACH_MM,
            0.5,
            None,
        ) {
            self.point.triangle = hit.triangle;
            self.point.barycentric = hit.barycentric;
        }
    }
}
