//! The sub-model the object's own integrator steps: the active nodes and their frozen boundary ring, in
//! the original index order.
//!
//! Owns: rebuilding the sub-model in place when the active set changed ([`RegionTracker::rebuild`]) and
//! one step through it ([`RegionTracker::step`]: state in, step, active nodes back). Must not: choose the
//! active set (the levels do) or touch a node outside it.

use super::*;
use crate::tissue::Integrator;
use crate::tissue::integrators::fit;

impl RegionTracker {
    /// Advance the active region by `dt_s` with `integrator` (any method, unchanged), leaving every other node
    /// as it is. Returns the integrator's iterations (0 when the region is empty). Real-time contract: no
    /// allocation once the integrator is warm for this sub-model, never panics, O(region).
    pub fn step(
        &mut self,
        integrator: &mut dyn Integrator,
        state: &mut TissueState,
        dt_s: f32,
    ) -> u32 {
        let Some(sub) = &self.sub_model else {
            return 0;
        };
        if self.depth == 0 {
            return 0;
        }
        let s = &mut self.sub_state;
        for (k, (&g, &active)) in self.sub_nodes.iter().zip(&self.sub_active).enumerate() {
            let g = g as usize;
            s.positions_mm[k] = state.positions_mm[g];
            s.velocities_mm_s[k] = if active {
                state.velocities_mm_s[g]
            } else {
                Vec3::zeros()
            };
            s.external_forces_n[k] = state.external_forces_n[g];
        }
        s.pinned.clear();
        for &g in &state.pinned {
            if let Some(&local) = self.local_of.get(g as usize)
                && local != OUTSIDE
            {
                s.pinned.push(local);
            }
        }
        s.pinned.sort_unstable();
        let iterations = integrator.step(sub, s, dt_s);
        for (k, (&g, &active)) in self.sub_nodes.iter().zip(&self.sub_active).enumerate() {
            if active {
                let g = g as usize;
                state.positions_mm[g] = s.positions_mm[k];
                state.velocities_mm_s[g] = s.velocities_mm_s[k];
                state.forces_n[g] = s.forces_n[k];
            }
        }
        iterations
    }

    /// The sub-model over the active nodes and their boundary ring, in original index order.
    pub(super) fn rebuild(&mut self, model: &MassSpringModel) {
        for &g in &self.sub_nodes {
            self.local_of[g as usize] = OUTSIDE;
        }
        self.sub_nodes.clear();
        self.sub_active.clear();
        if self.depth == 0 {
            if let Some(model) = self.sub_model.take() {
                self.spare_model = Some(model);
            }
            return;
        }
        self.rebuilds += 1;
        self.sub_nodes.extend_from_slice(&self.order);
        self.sub_nodes.sort_unstable();
        for (k, &g) in self.sub_nodes.iter().enumerate() {
            self.local_of[g as usize] = k as u32;
            self.sub_active.push(self.level_of[g as usize] < self.depth);
        }
        let n = self.sub_nodes.len();
        let rest = model.rest_positions_mm();
        let springs = model.springs();
        // Refill the kept parts in place: no allocation once they have held a region this large.
        let parts = &mut self.parts;
        parts.rest_positions_mm.clear();
        parts
            .rest_positions_mm
            .extend(self.sub_nodes.iter().map(|&g| rest[g as usize]));
        parts.mass_kg.clear();
        parts
            .mass_kg
            .extend(self.sub_nodes.iter().map(|&g| model.mass_kg()[g as usize]));
        parts.fixed.clear();
        parts.fixed.extend(
            self.sub_nodes
                .iter()
                .zip(&self.sub_active)
                .map(|(&g, &active)| !active || model.is_fixed(g as usize)),
        );
        parts.law = Some(model.law());
        parts.anchor_stiffness_n_per_mm = model.anchor_stiffness_n_per_mm();
        parts.drag_per_s = model.drag_per_s();
        parts.gravity_mm_per_s2 = model.gravity_mm_per_s2();
        parts.tet_bulk_modulus_n_per_mm2 = model.tets().bulk_modulus_n_per_mm2;
        parts.fem = model.fem().material();
        parts.edges.clear();
        parts.edge_stiffness_n_per_mm.clear();
        parts.edge_damping_n_s_per_mm.clear();
        parts.tets.clear();
        let expected_springs = n * 3;
        parts.edges.reserve(expected_springs);
        parts.edge_stiffness_n_per_mm.reserve(expected_springs);
        parts.edge_damping_n_s_per_mm.reserve(expected_springs);
        for k in 0..n {
            if !self.sub_active[k] {
                continue;
            }
            let g = self.sub_nodes[k] as usize;
            for &s in model.node_springs(g) {
                let other = self.local_of[model.other_end(s, g)];
                if other == OUTSIDE || (self.sub_active[other as usize] && (other as usize) < k) {
                    // Outside cannot happen (the ring holds every neighbour); an active pair is taken once.
                    continue;
                }
                let k = k as u32;
                parts.edges.push([k.min(other), k.max(other)]);
                parts
                    .edge_stiffness_n_per_mm
                    .push(springs.stiffness_n_per_mm[s as usize]);
                parts
                    .edge_damping_n_s_per_mm
                    .push(springs.damping_n_s_per_mm[s as usize]);
            }
        }
        // Tetrahedra touching an active node, each once; a tet with a vertex beyond the ring (only possible when
        // its edges are not springs) is left out.
        if !self.tet_stamp.is_empty() {
            let stamp = self.rebuilds as u32;
            let tets = model.tets();
            for k in 0..n {
                if !self.sub_active[k] {
                    continue;
                }
                for &t in model.node_tets(self.sub_nodes[k] as usize) {
                    let Some(mark) = self.tet_stamp.get_mut(t as usize) else {
                        continue;
                    };
                    if *mark == stamp {
                        continue;
                    }
                    *mark = stamp;
                    let local = tets.tets[t as usize].map(|v| self.local_of[v as usize]);
                    if local.iter().all(|&v| v != OUTSIDE) {
                        parts.tets.push(local);
                    }
                }
            }
        }
        let mut sub = match self.sub_model.take().or_else(|| self.spare_model.take()) {
            Some(model) => model,
            None => MassSpringModel::from_parts(ModelParts::default()),
        };
        sub.rebuild_from(&self.parts);
        // The region steps on the same threads as the whole object would.
        sub.set_chunk_runner(model.shared_chunk_runner().cloned());
        let s = &mut self.sub_state;
        for buffer in [
            &mut s.positions_mm,
            &mut s.velocities_mm_s,
            &mut s.forces_n,
            &mut s.external_forces_n,
        ] {
            fit(buffer, n);
        }
        self.sub_model = Some(sub);
    }
}
