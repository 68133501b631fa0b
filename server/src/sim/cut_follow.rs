//! A cut that follows the blade: each sweep subdivides the tissue where the blade crossed it, then opens the
//! facets that lie on the blade's path.
//!
//! Owns: [`Sim::subdivide`] (apply a cut plan and rebuild what stands on the topology, re-expressing what the
//! tools hold) and [`Sim::cut_following_blade`] (one sweep through one object: plan, subdivide, open). Must not:
//! decide where a blade is (the instruments do) or how facets open (`topology.rs`, `tissue::seams`).

use crate::collision::{NodeMarks, SurfaceCollider};
use crate::haptics::ContactStiffness;
use crate::interaction::{BladeSweep, CutScratch};
use crate::tissue::seams::Opening;
use crate::tissue::stability::DESIGN_STRAIN;
use crate::tissue::subdivision::{
    CutPlan, ElementRemap, Subdivision, floor_model_masses, rate_ceiling, subdivide_into,
};
use crate::tissue::{DivergenceGuard, RegionTracker, Vec3, integrator_for};

use super::*;

impl Sim {
    /// Subdivide object `object` by `plan` ([`crate::tissue::subdivision`]): vertices moved onto the cut and
    /// new vertices where edges split (each placed, moving and burnt as its edge is there), and everything built
    /// on the topology rebuilt as after a seam opening (springs and masses, the collider, the integrator, the
    /// region, the guard, each tool's contact stiffness); what the tools hold on a split element is
    /// re-expressed on the piece that holds it ([`crate::sim::Instrument::subdivided`]). Each new vertex's
    /// replication parent is the nearer end of its edge. Allocates (a cut is an event). An object out of range,
    /// stepped on its own thread, or a plan that changes nothing, changes nothing.
    pub fn subdivide(&mut self, object: usize, plan: &CutPlan) -> Subdivision {
        let Some(o) = self.objects.get_mut(object).filter(|o| o.lane.is_none()) else {
            return Subdivision::default();
        };
        if plan.is_empty() {
            return Subdivision::default();
        }
        o.finish_refit();
        let ceiling = *o.rate_ceiling.get_or_insert_with(|| rate_ceiling(&o.model));
        let change = subdivide_into(&o.model, plan, &mut o.parts, ceiling);
        if change.is_empty() {
            return change;
        }
        o.model.rebuild_from(&o.parts);
        let n = o.model.node_count();
        let state = &mut o.state;
        for (m, _) in &change.moved {
            let (v, w) = (m.vertex as usize, m.toward as usize);
            state.positions_mm[v] = state.positions_mm[v].lerp(&state.positions_mm[w], m.t);
            state.velocities_mm_s[v] =
                state.velocities_mm_s[v].lerp(&state.velocities_mm_s[w], m.t);
        }
        for s in &change.new_vertices {
            let (a, b) = (s.a as usize, s.b as usize);
            let x = state.positions_mm[a].lerp(&state.positions_mm[b], s.t);
            let v = state.velocities_mm_s[a].lerp(&state.velocities_mm_s[b], s.t);
            let burn = f32::from(o.burn[a]) * (1.0 - s.t) + f32::from(o.burn[b]) * s.t;
            state.positions_mm.push(x);
            state.velocities_mm_s.push(v);
            o.burn
                .push(burn.round().clamp(0.0, f32::from(u16::MAX)) as u16);
        }
        state.forces_n.resize(n, Vec3::zeros());
        state.external_forces_n.resize(n, Vec3::zeros());
        let volume = !o.model.tets().tets.is_empty();
        let retargeted: Vec<u32> = if volume {
            change.changed_triangles.iter().map(|&(t, _)| t).collect()
        } else {
            change.changed_elements.iter().map(|&(t, _)| t).collect()
        };
        if o.collider
            .retopologize(&state.positions_mm, o.model.triangles(), &retargeted)
            .is_err()
            && let Ok(collider) = SurfaceCollider::new(&state.positions_mm, o.model.triangles())
        {
            o.collider = collider.with_refit_margin(REFIT_MARGIN_MM);
        }
        // Moved vertices reshape triangles that were not re-pointed: refit every leaf once.
        if !change.moved.is_empty() {
            o.collider.refit(&state.positions_mm);
        }
        o.marks = NodeMarks::new(n);
        o.guard = DivergenceGuard::new(&o.model);
        o.integrator = integrator_for(o.integrator_spec.0, o.integrator_spec.1);
        o.region = o
            .region
            .as_ref()
            .map(|r| RegionTracker::new(&o.model, r.params()));
        for i in 0..n {
            if o.burn[i] > 0 {
                o.shrink_springs_of(i);
            }
        }
        o.topology_version += 1;
        o.split_parents
            .extend(change.new_vertices.iter().map(|s| s.nearer_end()));
        let model = &self.objects[object].model;
        let remap = ElementRemap::new(&change, model);
        for tool in &mut self.tools {
            if let Some(stiffness) = tool.haptic.stiffness.get_mut(object) {
                *stiffness = ContactStiffness::new(n);
            }
            if let Some(instrument) = &mut tool.instrument_state {
                instrument.subdivided(object, model, &remap);
            }
        }
        self.last_energy_n_mm = None;
        change
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
            o.guard = DivergenceGuard::new(&o.model);
            o.integrator = integrator_for(o.integrator_spec.0, o.integrator_spec.1);
            o.region = o
                .region
                .as_ref()
                .map(|r| RegionTracker::new(&o.model, r.params()));
        }
    }

    /// Cut object `object` where a blade swept this tick, following the blade: the edges it crossed are split
    /// where it crossed them (or a vertex near the crossing moved onto it), and the facets then on its path
    /// open ([`Self::open_seams`]). `scratch.seams` holds the facets found on the path this sweep.
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
        let Some(o) = self.objects.get(object).filter(|o| o.lane.is_none()) else {
            return Opening::default();
        };
        let margin_mm = scratch.margin_for(&o.model);
        scratch
            .path
            .plan_sweep(object_id, &o.model, &o.state.positions_mm, sweep, margin_mm);
        let plan = std::mem::take(&mut scratch.path.plan);
        let change = self.subdivide(object, &plan);
        scratch.path.plan = plan;
        let o = &self.objects[object];
        scratch
            .path
            .record_plan(object_id, &change, &o.state.positions_mm);
        let mut seams = std::mem::take(&mut scratch.seams);
        scratch.path.facets_on_path(object_id, &o.model, &mut seams);
        let opening = self.open_seams(object, &seams);
        scratch.path.record_opening(object_id, &opening);
        self.floor_opened_masses(object, &opening);
        scratch.seams = seams;
        opening
    }
}
