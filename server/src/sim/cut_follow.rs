//! A cut that follows the blade: each sweep subdivides the tissue where the blade crossed it, then opens the
//! facets that lie on the blade's path, in one pass over the model's parts and one rebuild.
//!
//! Owns: [`Sim::cut_following_blade`] (one sweep through one object: plan, subdivide, open, rebuild what stands
//! on the topology once, and re-express what the tools hold on split elements). Must not:
//! decide where a blade is (the instruments do) or how facets open (`topology.rs`, `tissue::seams`).

use super::object::retopologize_collider;
use crate::haptics::ContactStiffness;
use crate::interaction::{BladeSweep, CutScratch};
use crate::tissue::seams::{Facet, Opening, open_parts, shared_by_two};
use crate::tissue::stability::DESIGN_STRAIN;
use crate::tissue::subdivision::{
    CutPlan, ElementRemap, Subdivision, floor_model_masses, rate_ceiling, subdivide_into,
};

use super::*;

impl SimObject {
    /// Subdivide this object's parts (scratch) by `plan`, its state following: vertices moved onto the cut and
    /// new vertices where edges split (each placed, moving and burnt as its edge is there). The model is not
    /// rebuilt yet. An empty change changed nothing but the scratch.
    fn subdivide_parts(&mut self, plan: &CutPlan) -> Subdivision {
        let ceiling = *self
            .rate_ceiling
            .get_or_insert_with(|| rate_ceiling(&self.model));
        let change = subdivide_into(&self.model, plan, &mut self.parts, ceiling);
        if change.is_empty() {
            return change;
        }
        let state = &mut self.state;
        for (m, _) in &change.moved {
            let (v, w) = (m.vertex as usize, m.toward as usize);
            state.positions_mm[v] = state.positions_mm[v].lerp(&state.positions_mm[w], m.t);
            state.velocities_mm_s[v] =
                state.velocities_mm_s[v].lerp(&state.velocities_mm_s[w], m.t);
            if let Some(lane) = &mut self.lane {
                lane.topology_mut().moved(m.vertex, m.toward, m.t);
            }
        }
        for s in &change.new_vertices {
            let (a, b) = (s.a as usize, s.b as usize);
            let x = state.positions_mm[a].lerp(&state.positions_mm[b], s.t);
            let v = state.velocities_mm_s[a].lerp(&state.velocities_mm_s[b], s.t);
            let burn = f32::from(self.burn[a]) * (1.0 - s.t) + f32::from(self.burn[b]) * s.t;
            state.positions_mm.push(x);
            state.velocities_mm_s.push(v);
            self.burn
                .push(burn.round().clamp(0.0, f32::from(u16::MAX)) as u16);
            if let Some(lane) = &mut self.lane {
                lane.topology_mut().split(s.a, s.b, s.t);
            }
        }
        // The collider takes the subdivided surface (the parts' triangles), and refits every leaf once if
        // moved vertices reshaped triangles that were not re-pointed.
        let retargeted: Vec<u32> = if self.parts.tets.is_empty() {
            change.changed_elements.iter().map(|&(t, _)| t).collect()
        } else {
            change.changed_triangles.iter().map(|&(t, _)| t).collect()
        };
        retopologize_collider(
            &mut self.collider,
            &self.state.positions_mm,
            &self.parts.triangles,
            &retargeted,
        );
        if !change.moved.is_empty() {
            self.collider.refit(&self.state.positions_mm);
        }
        change
    }

    /// Open `seams` (and the facets cut before that have not opened yet) in this object's parts, as
    /// [`Sim::open_seams`] does in a model: copies start where their parents are. Returns the opening and the
    /// facets cut so far, or `None` when every seam was cut before (nothing to try).
    fn open_parts_on_path(&mut self, seams: &[Facet]) -> Option<(Opening, Vec<Facet>)> {
        if seams.iter().all(|f| self.severed.binary_search(f).is_ok()) {
            return None;
        }
        let mut all = std::mem::take(&mut self.severed);
        all.extend_from_slice(seams);
        all.sort_unstable();
        all.dedup();
        debug_assert!(
            self.parts.edges.is_sorted(),
            "the parts' springs are unsorted"
        );
        let opening = open_parts(&mut self.parts, &all);
        let state = &mut self.state;
        for &p in &opening.parents {
            let p = p as usize;
            let (x, v, b) = (
                state.positions_mm[p],
                state.velocities_mm_s[p],
                self.burn[p],
            );
            state.positions_mm.push(x);
            state.velocities_mm_s.push(v);
            self.burn.push(b);
            if let Some(lane) = &mut self.lane {
                lane.topology_mut().copied(p as u32);
            }
        }
        Some((opening, all))
    }
}

impl Sim {
    /// Each tool after object `object` was subdivided by `change` (and opened too, `opened`): a fresh contact
    /// stiffness on it, and what its instrument holds re-expressed on the pieces.
    fn tools_after_subdivision(&mut self, object: usize, change: &Subdivision, opened: bool) {
        let model = &self.objects[object].model;
        let n = model.node_count();
        let remap = ElementRemap::new(change, model);
        for tool in &mut self.tools {
            if let Some(stiffness) = tool.haptic.stiffness.get_mut(object) {
                *stiffness = ContactStiffness::new(n);
            }
            if let Some(instrument) = &mut tool.instrument_state {
                instrument.subdivided(object, model, &remap);
                if opened {
                    instrument.topology_changed(object, model);
                }
            }
        }
    }

    /// After a seam opening of a cut that follows the blade: a copy on the side of a thin piece gets that
    /// piece's small share of its parent's mass but keeps the full springs on its side, so raise the masses
    /// of the split vertices and their copies to the object's rate ceiling ([`floor_model_masses`]), in place.
    fn floor_opened_masses(&mut self, object: usize, opening: &Opening) {
        let Some(o) = self.objects.get_mut(object) else {
            return;
        };
        let Some(ceiling) = o.rate_ceiling.filter(|_| !opening.is_empty()) else {
            return;
        };
        let mut touched: Vec<u32> = opening.parents.clone();
        touched.extend((0..opening.parents.len() as u32).map(|k| opening.first_new_vertex + k));
        touched.sort_unstable();
        touched.dedup();
        let stiffening = o.model.law().stiffening_at(DESIGN_STRAIN);
        if floor_model_masses(&mut o.model, &touched, ceiling, stiffening) {
            o.remake_for_model();
        }
    }

    /// Cut object `object` where a blade swept this tick, following the blade: the edges it crossed are split
    /// where it crossed them (or a vertex near the crossing moved onto it), and the facets then on its path
    /// open. A sweep that splits something subdivides and opens the model's parts in one pass and rebuilds the
    /// model once; one that splits nothing opens as [`Self::open_seams`] does. `scratch.seams` holds the facets
    /// found on the path this sweep.
    pub fn cut_following_blade(
        &mut self,
        object: usize,
        sweep: &BladeSweep,
        scratch: &mut CutScratch,
    ) -> Opening {
        scratch.seams.clear();
        let Ok(object_id) = u16::try_from(object) else {
            return Opening::default();
        };
        let Some(o) = self.objects.get_mut(object) else {
            return Opening::default();
        };
        scratch
            .path
            .plan_sweep(object_id, &o.model, &o.state.positions_mm, sweep, &o.tied);
        let change = if scratch.path.plan.is_empty() {
            Subdivision::default()
        } else {
            o.finish_refit();
            o.subdivide_parts(&scratch.path.plan)
        };
        scratch
            .path
            .record_plan(object_id, &change, &o.state.positions_mm);
        let mut seams = std::mem::take(&mut scratch.seams);
        if change.is_empty() {
            // Nothing split: the facets on the path open as a facet cut's do.
            scratch.path.facets_on_path(object_id, &o.model, &mut seams);
            let opening = self.open_seams(object, &seams);
            scratch.path.record_opening(object_id, &opening);
            self.floor_opened_masses(object, &opening);
            scratch.seams = seams;
            return opening;
        }
        scratch
            .path
            .facets_on_path_of(object_id, &o.parts.triangles, &o.parts.tets, &mut seams);
        let opened = o.open_parts_on_path(&seams);
        o.model.rebuild_from(&o.parts);
        let opening = match opened {
            Some((opening, mut cut)) => {
                if !opening.is_empty() {
                    let mut retargeted = opening.changed_triangles.clone();
                    retargeted.sort_unstable();
                    retopologize_collider(
                        &mut o.collider,
                        &o.state.positions_mm,
                        o.model.triangles(),
                        &retargeted,
                    );
                }
                cut.retain(|f| shared_by_two(&o.model, f));
                o.severed = cut;
                opening
            }
            None => Opening::default(),
        };
        o.rebuilt_for_topology();
        o.split_parents
            .extend(change.new_vertices.iter().map(|s| s.nearer_end()));
        o.split_parents.extend_from_slice(&opening.parents);
        self.tools_after_subdivision(object, &change, !opening.is_empty());
        if !opening.is_empty() {
            self.openings += 1;
        }
        self.last_energy_n_mm = None;
        scratch.path.record_opening(object_id, &opening);
        self.floor_opened_masses(object, &opening);
        scratch.seams = seams;
        opening
    }
}
