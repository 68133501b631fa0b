//! Region of deformation: simulate only the part of an object that moves.
//!
//! Owns: per object, the breadth-first levels of nodes around the current contact (level 0 = the seeds, level
//! k = nodes k springs away), the depth of the active region (levels `0..depth` are integrated, level `depth`
//! is a frozen boundary ring), the rules that grow and shrink it, and the sub-model that the object's own
//! integrator steps unchanged. Must not: know about tools, collision or time beyond the `dt` it is given;
//! the caller hands in the contact nodes (any integrator, any mesh).
//!
//! How it works, once per tick ([`RegionTracker::update`]):
//! - Seeds: the nodes tools may touch this tick (the broad-phase candidates). While they sit at least
//!   [`MARGIN_LEVELS`] levels inside the active region the levels stay; when one does not, the tracker
//!   re-seeds from the contacts plus every active node still moving (so no deforming node is ever dropped),
//!   and rebuilds the levels. After release the last seeds stay while anything moves.
//! - A node is live when it is farther than `threshold_mm` from rest, or moved more than `threshold_mm` in the
//!   last tick (speed x tick). `live` = 1 + the outermost level holding a live node.
//! - Grow when `live + MARGIN_LEVELS > depth` (motion reaches the outer levels): depth becomes
//!   `live + MARGIN_LEVELS + max(2, depth / 2)`, geometric so a spreading dent costs a handful of rebuilds.
//! - Shrink when, for [`SETTLE_S`], the outermost node live at `threshold_mm / 2` (hysteresis) leaves at least
//!   `max(2, depth / 4)` levels to spare; empty the region when no tool touches and nothing is live at
//!   `threshold_mm / 2` for [`SETTLE_S`]. A node leaving the active set keeps its position and has its velocity
//!   zeroed (it is still, up to the threshold).
//! - The sub-model ([`MassSpringModel::rebuild_from`], refilled in place) holds the active nodes plus the boundary ring (fixed), in
//!   the original index order (springs stay local), every spring and tetrahedron touching an active node, and
//!   the original rest positions, masses, law, anchors, drag and gravity. It is rebuilt only when the active
//!   set changes; each substep copies active + boundary state in, steps, and copies the active nodes back.
//!
//! Assumptions (the world loader refuses what breaks them): the untouched tissue is at equilibrium at rest (no
//! gravity), no ties to other objects, no global volume term (it couples every surface node at once).
//! Accuracy: frozen nodes are within `threshold_mm` of rest and still, so the tool force differs from a full
//! step by the force such a displacement makes at the region's edge, which decays towards the tool.
//!
//! Real-time contract: [`RegionTracker::update`] and [`RegionTracker::step`] never panic and never log; they are
//! O(active region) (never O(object)). A rebuild (the active set changed: O(region), a few times per touch)
//! refills the kept parts and sub-model in place, so nothing is allocated once the buffers have held a
//! region this large (`server/tests/no_allocation.rs` counts it).
//!
//! Here: the tracker's settings, state and per-tick decisions ([`RegionTracker::update`]). The levels'
//! breadth-first search and the depth changes are in `levels`; the sub-model, its rebuild and the step
//! through it in `sub_model`.

use super::{MassSpringModel, ModelParts, TissueState, Vec3};

mod levels;
mod sub_model;

/// Quiet levels kept active beyond the outermost live one; contacts must sit this many levels inside.
pub const MARGIN_LEVELS: u32 = 2;

/// How long a shrink (or empty) condition must hold before the region shrinks, seconds.
pub const SETTLE_S: f32 = 0.05;

/// `level_of` / `local_of` value of a node outside the region.
const OUTSIDE: u32 = u32::MAX;

/// How far node `i` is from still at rest: the larger of its distance from rest and its motion in one tick, mm.
#[inline]
fn activity(model: &MassSpringModel, state: &TissueState, i: usize, tick_dt_s: f32) -> f32 {
    let rest = model.rest_positions_mm()[i];
    let displacement = (state.positions_mm[i] - rest).norm();
    let motion = state.velocities_mm_s[i].norm() * tick_dt_s;
    // NaN propagates (f32::max would drop it).
    if motion > displacement || motion.is_nan() {
        motion
    } else {
        displacement
    }
}

/// Region tracking settings of one object (world file: `region = { threshold_mm = ... }`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionParams {
    /// Motion threshold, mm: a node farther than this from rest, or moving more than this per tick, is live.
    pub threshold_mm: f32,
}

/// What one [`RegionTracker::update`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RegionUpdate {
    /// Active (integrated) nodes after the update.
    pub active_nodes: u32,
    /// The sub-model was rebuilt.
    pub rebuilt: bool,
}

/// Region-of-deformation state of one object. See the module doc.
#[derive(Debug)]
pub struct RegionTracker {
    params: RegionParams,
    /// Contacts of this tick (deduplicated), as handed in by [`Self::add_contacts`].
    contacts: Vec<u32>,
    contact_stamp: Vec<u32>,
    stamp: u32,
    /// Nodes by level: level `l` is `order[level_start[l]..level_start[l + 1]]`.
    order: Vec<u32>,
    level_start: Vec<u32>,
    level_of: Vec<u32>,
    /// Levels `0..depth` are active; level `depth` (if computed) is the frozen boundary ring.
    depth: u32,
    settle_s: f32,
    /// Scratch: seeds of a re-seed, previous active nodes.
    seeds: Vec<u32>,
    previous_active: Vec<u32>,
    /// The sub-model and its state; local node k is global node `sub_nodes[k]`.
    sub_model: Option<MassSpringModel>,
    /// The last sub-model while the region is empty, kept so the next rebuild reuses its buffers.
    spare_model: Option<MassSpringModel>,
    /// The sub-model's parts, refilled in place by every rebuild.
    parts: ModelParts,
    sub_state: TissueState,
    sub_nodes: Vec<u32>,
    sub_active: Vec<bool>,
    local_of: Vec<u32>,
    tet_stamp: Vec<u32>,
    stale: bool,
    rebuilds: u64,
}

impl RegionTracker {
    /// An empty region for `model` (allocates its per-node tables once).
    pub fn new(model: &MassSpringModel, params: RegionParams) -> Self {
        let n = model.node_count();
        Self {
            params,
            contacts: Vec::with_capacity(n),
            contact_stamp: vec![0; n],
            stamp: 0,
            order: Vec::with_capacity(n),
            level_start: {
                let mut starts = Vec::with_capacity(256);
                starts.push(0);
                starts
            },
            level_of: vec![OUTSIDE; n],
            depth: 0,
            settle_s: 0.0,
            seeds: Vec::with_capacity(n),
            previous_active: Vec::with_capacity(n),
            sub_model: None,
            spare_model: None,
            parts: ModelParts::default(),
            sub_state: TissueState {
                positions_mm: Vec::new(),
                velocities_mm_s: Vec::new(),
                forces_n: Vec::new(),
                external_forces_n: Vec::new(),
                pinned: Vec::with_capacity(n),
            },
            sub_nodes: Vec::with_capacity(n),
            sub_active: Vec::with_capacity(n),
            local_of: vec![OUTSIDE; n],
            tet_stamp: vec![0; model.tets().len()],
            stale: false,
            rebuilds: 0,
        }
    }

    /// The settings.
    pub fn params(&self) -> RegionParams {
        self.params
    }

    /// Integrated nodes (levels `0..depth`), by level. Empty when the object is at rest and untouched.
    pub fn active_nodes(&self) -> &[u32] {
        let end = self
            .level_start
            .get(self.depth as usize)
            .copied()
            .unwrap_or(0) as usize;
        &self.order[..end.min(self.order.len())]
    }

    /// Number of active levels (0: empty region).
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Sub-model rebuilds so far.
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds
    }

    /// Nodes in the current sub-model (active plus boundary).
    pub fn sub_model_nodes(&self) -> usize {
        self.sub_nodes.len()
    }

    /// Forget this tick's contacts (call before [`Self::add_contacts`]). O(1).
    pub fn clear_contacts(&mut self) {
        self.contacts.clear();
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.contact_stamp.fill(0);
            self.stamp = 1;
        }
    }

    /// Add nodes tools may touch this tick (repeats and out-of-range indices are ignored). No allocation.
    pub fn add_contacts(&mut self, nodes: &[u32]) {
        for &i in nodes {
            if let Some(stamp) = self.contact_stamp.get_mut(i as usize)
                && *stamp != self.stamp
            {
                *stamp = self.stamp;
                self.contacts.push(i);
            }
        }
    }

    /// Once per tick, after the contacts are in and before stepping: re-seed, grow, shrink or empty the region
    /// from the state at the end of the last tick (`tick_dt_s` converts speeds to per-tick motion), and
    /// rebuild the sub-model if the active set changed. May zero the velocities of nodes leaving the region.
    pub fn update(
        &mut self,
        model: &MassSpringModel,
        state: &mut TissueState,
        tick_dt_s: f32,
    ) -> RegionUpdate {
        let threshold = self.params.threshold_mm;
        let tick_dt_s = if tick_dt_s.is_finite() && tick_dt_s > 0.0 {
            tick_dt_s
        } else {
            0.0
        };

        if !self.contacts.is_empty() {
            let inside = self.depth.saturating_sub(MARGIN_LEVELS);
            let covered = self
                .contacts
                .iter()
                .all(|&c| self.level_of[c as usize] < inside);
            if !covered {
                // Seeds: the contacts, plus every active node still moving (never drop a deforming node).
                self.seeds.clear();
                self.seeds.extend_from_slice(&self.contacts);
                let end = self.level_start[self.depth as usize] as usize;
                for &i in &self.order[..end] {
                    let a = activity(model, state, i as usize, tick_dt_s);
                    if (a > 0.5 * threshold || a.is_nan())
                        && self.contact_stamp[i as usize] != self.stamp
                    {
                        self.seeds.push(i);
                    }
                }
                self.reseed(model, state);
            }
        }
        if self.depth == 0 {
            return self.finish(model);
        }

        // 1 + the outermost level with a node live at the threshold (`live`), and at half of it (`live_half`).
        let (mut live, mut live_half) = (0, 0);
        for l in 0..self.depth as usize {
            let (from, to) = (
                self.level_start[l] as usize,
                self.level_start[l + 1] as usize,
            );
            for &i in &self.order[from..to] {
                let a = activity(model, state, i as usize, tick_dt_s);
                // NaN counts as live: the guard resets a diverged object; the region must not drop it first.
                if a > 0.5 * threshold || a.is_nan() {
                    live_half = l as u32 + 1;
                    if a > threshold || a.is_nan() {
                        live = l as u32 + 1;
                        break;
                    }
                }
            }
        }

        if live + MARGIN_LEVELS > self.depth {
            let depth = live + MARGIN_LEVELS + (self.depth / 2).max(2);
            self.set_depth(model, state, depth);
            self.settle_s = 0.0;
        } else if self.contacts.is_empty() && live_half == 0 {
            self.settle_s += tick_dt_s;
            if self.settle_s >= SETTLE_S {
                self.set_depth(model, state, 0);
                self.settle_s = 0.0;
            }
        } else {
            let target = live_half.max(1) + MARGIN_LEVELS;
            if target + (self.depth / 4).max(2) <= self.depth {
                self.settle_s += tick_dt_s;
                if self.settle_s >= SETTLE_S {
                    self.set_depth(model, state, target);
                    self.settle_s = 0.0;
                }
            } else {
                self.settle_s = 0.0;
            }
        }
        self.finish(model)
    }

    /// Empty the region without touching the state (after the object was reset to rest).
    pub fn clear(&mut self) {
        for &i in &self.order {
            self.level_of[i as usize] = OUTSIDE;
        }
        self.order.clear();
        self.level_start.clear();
        self.level_start.push(0);
        self.depth = 0;
        self.settle_s = 0.0;
        self.stale = true;
    }

    /// Rebuild the sub-model if the active set changed; report.
    fn finish(&mut self, model: &MassSpringModel) -> RegionUpdate {
        let rebuilt = self.stale;
        if self.stale {
            self.rebuild(model);
            self.stale = false;
        }
        RegionUpdate {
            active_nodes: self.active_nodes().len() as u32,
            rebuilt,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tissue::{SpringLaw, SymplecticEuler};

    /// A chain of `n` nodes 1 mm apart along x, ends fixed.
    fn chain(n: usize) -> MassSpringModel {
        MassSpringModel::from_parts(ModelParts {
            rest_positions_mm: (0..n).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect(),
            mass_kg: vec![1e-3; n],
            fixed: (0..n).map(|i| i == 0 || i == n - 1).collect(),
            edges: (0..n as u32 - 1).map(|i| [i, i + 1]).collect(),
            edge_stiffness_n_per_mm: vec![0.1; n - 1],
            edge_damping_n_s_per_mm: vec![0.0; n - 1],
            law: Some(SpringLaw::Linear),
            anchor_stiffness_n_per_mm: 0.05,
            drag_per_s: 50.0,
            ..ModelParts::default()
        })
    }

    #[test]
    fn levels_follow_the_springs_and_the_boundary_ring_is_fixed() {
        let model = chain(101);
        let mut state = TissueState::at_rest(&model);
        let mut region = RegionTracker::new(&model, RegionParams { threshold_mm: 1e-3 });
        region.clear_contacts();
        region.add_contacts(&[50, 50, 9999]);
        let update = region.update(&model, &mut state, 1e-3);
        assert!(update.rebuilt);
        // Seeds and MARGIN_LEVELS levels on each side are active; the ring is one more node on each side.
        let mut active = region.active_nodes().to_vec();
        active.sort_unstable();
        assert_eq!(active, (48..=52).collect::<Vec<u32>>());
        assert_eq!(region.sub_model_nodes(), 7);
    }

    #[test]
    fn a_region_larger_than_the_object_covers_it_whole() {
        let model = chain(9);
        let mut state = TissueState::at_rest(&model);
        let mut region = RegionTracker::new(&model, RegionParams { threshold_mm: 1e-6 });
        let mut integrator = SymplecticEuler;
        for tick in 0..400 {
            region.clear_contacts();
            if tick < 200 {
                region.add_contacts(&[4]);
            }
            region.update(&model, &mut state, 1e-3);
            region.step(&mut integrator, &mut state, 1e-3);
            if tick < 200 {
                state.positions_mm[4].y = 1.0;
            }
            if tick == 199 {
                assert_eq!(region.active_nodes().len(), 9, "whole chain active");
                assert_eq!(region.sub_model_nodes(), 9);
            }
        }
        assert!(
            state
                .positions_mm
                .iter()
                .all(|p| p.iter().all(|c| c.is_finite()))
        );
    }

    #[test]
    fn a_pulled_node_spreads_the_region_and_it_empties_once_still() {
        let model = chain(201);
        let mut state = TissueState::at_rest(&model);
        let mut region = RegionTracker::new(&model, RegionParams { threshold_mm: 1e-3 });
        let mut integrator = SymplecticEuler;
        let mut widest = 0;
        for tick in 0..3000 {
            region.clear_contacts();
            if tick < 300 {
                region.add_contacts(&[100]);
            }
            region.update(&model, &mut state, 1e-3);
            widest = widest.max(region.active_nodes().len());
            region.step(&mut integrator, &mut state, 1e-3);
            if tick < 300 {
                state.positions_mm[100].y = 1.0;
                state.velocities_mm_s[100] = Vec3::zeros();
            }
        }
        assert!(widest > 7, "region never grew: {widest}");
        assert_eq!(region.depth(), 0, "region did not empty");
        assert!(
            state.positions_mm.iter().all(|p| p.y.abs() < 1e-3),
            "tissue left displaced"
        );
    }
}
