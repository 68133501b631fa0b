//! Topology changes of an object: opening seams (cuts and tears split vertices) and rebuilding what stands on
//! the topology.
//!
//! Owns: [`Sim::open_seams`], [`Sim::cut`], [`Sim::tear`]. Must not: decide where to cut (the instruments
//! and the tear test do).

use super::object::retopologize_collider;
use crate::haptics::ContactStiffness;
use crate::interaction::{BladeSweep, CutScratch, swept_seams, torn_seams};
use crate::tissue::seams::{Facet, Opening, open_model_into, shared_by_two};

use super::*;

impl Sim {
    /// Open `seams` in object `object` (see [`crate::tissue::seams`]): vertices whose ring the seams split are
    /// duplicated (new ids appended, each starting where its parent is, with its velocity and burn), elements
    /// keep their ids, and everything built on the object's topology is rebuilt for the new one: springs and
    /// masses, the collider's tree, the integrator's scratch, the region of deformation, the guard, and each
    /// tool's contact solver on it; grasps re-read the corners of the triangles they hold, so an attachment made
    /// before the cut holds on after it. Allocates (a cut or tear is an event, not the steady tick). An object
    /// index out of range, or seams that open nothing, change nothing.
    pub fn open_seams(&mut self, object: usize, seams: &[Facet]) -> Opening {
        // A multi-rate object's model and mirror are cut here as any object's; its step under way takes the
        // change at the next hand-off (the lane's topology log, crate::multirate).
        let Some(o) = self.objects.get_mut(object) else {
            return Opening::default();
        };
        // A tear opens mid-tick: the collider first follows the tick's motion (the tree is kept across the
        // change, and the region it would refit by is rebuilt below).
        o.finish_refit();
        // Nothing new: the facets cut before and still joined did not open with this model, and will not now
        // (a blade sweeping again through a crack it made finds them again; no allocation).
        if seams.iter().all(|f| o.severed.binary_search(f).is_ok()) {
            return Opening::default();
        }
        // Facets cut before that have not come apart yet (a crack inside a volume, a slit that has not reached
        // a border) are cut still: they open with these once the cut separates something.
        let mut all = std::mem::take(&mut o.severed);
        all.extend_from_slice(seams);
        all.sort_unstable();
        all.dedup();
        let opening = open_model_into(&o.model, &all, &mut o.parts);
        if opening.is_empty() {
            all.retain(|f| shared_by_two(&o.model, f));
            o.severed = all;
            return opening;
        }
        // The model is rebuilt in place: its buffers are reused, not faulted in afresh.
        o.model.rebuild_from(&o.parts);
        let model = &o.model;
        let n = model.node_count();
        let state = &mut o.state;
        for &p in &opening.parents {
            let p = p as usize;
            let (x, v, b) = (state.positions_mm[p], state.velocities_mm_s[p], o.burn[p]);
            state.positions_mm.push(x);
            state.velocities_mm_s.push(v);
            o.burn.push(b);
            if let Some(lane) = &mut o.lane {
                lane.topology_mut().copied(p as u32);
            }
        }
        let mut retargeted = opening.changed_triangles.clone();
        retargeted.sort_unstable();
        retopologize_collider(
            &mut o.collider,
            &state.positions_mm,
            model.triangles(),
            &retargeted,
        );
        o.rebuilt_for_topology();
        o.split_parents.extend_from_slice(&opening.parents);
        all.retain(|f| shared_by_two(&o.model, f));
        o.severed = all;
        for tool in &mut self.tools {
            if let Some(stiffness) = tool.haptic.stiffness.get_mut(object) {
                *stiffness = ContactStiffness::new(n);
            }
            if let Some(instrument) = &mut tool.instrument_state {
                instrument.topology_changed(object, &self.objects[object].model);
            }
        }
        self.openings += 1;
        self.last_energy_n_mm = None;
        opening
    }

    /// Cut object `object` where a blade swept this tick ([`crate::interaction::swept_seams`] at the current
    /// positions, then [`Self::open_seams`]; a tissue whose cut follows the blade: [`Self::cut_following_blade`]).
    pub fn cut(&mut self, object: usize, sweep: &BladeSweep, scratch: &mut CutScratch) -> Opening {
        let Some(o) = self.objects.get(object) else {
            scratch.seams.clear();
            return Opening::default();
        };
        if o.cut_follows_blade {
            return self.cut_following_blade(object, sweep, scratch);
        }
        let mut seams = std::mem::take(&mut scratch.seams);
        seams.clear();
        swept_seams(&o.model, &o.state.positions_mm, sweep, scratch, &mut seams);
        let opening = self.open_seams(object, &seams);
        scratch.seams = seams;
        opening
    }

    /// Tear object `object` wherever a spring is stretched past `max_strain`
    /// ([`crate::interaction::torn_seams`], then [`Self::open_seams`]).
    pub fn tear(&mut self, object: usize, max_strain: f32) -> Opening {
        let Some(o) = self.objects.get(object) else {
            return Opening::default();
        };
        let mut seams = Vec::new();
        torn_seams(&o.model, &o.state.positions_mm, max_strain, &mut seams);
        self.open_seams(object, &seams)
    }
}
