//! The tick's tissue-tissue contact: which pairs of objects are watched, their broad and narrow phase once a
//! tick, and their forces every substep.
//!
//! Owns: building the pairs ([`tissue_pairs`]: every two objects the tick steps together, not tied to each
//! other: a tie holds their shared faces where they are), [`Sim::find_tissue_contacts`] and
//! [`accumulate_tissue_contacts`]. The contact itself is [`crate::interaction::TissuePair`]. Must not: step
//! anything.

use crate::interaction::{PairSide, TissuePair};
use crate::scene::World;
use crate::tissue::TieSet;

use super::*;

/// The pairs of objects whose surfaces are kept apart: both stepped every tick and in full (a multi-rate
/// object steps on its own thread, a region-tracked one holds its external forces at zero), and not tied to
/// each other. Within `reach_mm` (the broad phase's margin).
pub(super) fn tissue_pairs(world: &World, reach_mm: f32) -> Vec<TissuePair> {
    let stepped_whole = |o: usize| {
        world
            .objects
            .get(o)
            .is_some_and(|s| s.region.is_none() && s.ticks_per_step <= 1)
    };
    let tied = |a: usize, b: usize, ties: &[TieSet]| {
        ties.iter()
            .any(|t| (t.object_a, t.object_b) == (a, b) || (t.object_a, t.object_b) == (b, a))
    };
    let n = world.objects.len();
    (0..n)
        .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
        .filter(|&(a, b)| stepped_whole(a) && stepped_whole(b) && !tied(a, b, &world.ties))
        .map(|(a, b)| TissuePair::new(a, b, reach_mm))
        .collect()
}

impl Sim {
    /// Each pair's contacts for this tick, on the colliders as last refitted and the nodes where they are.
    /// Returns the node-face pairs watched. No allocation once the pairs' buffers have grown.
    pub(super) fn find_tissue_contacts(&mut self) -> u32 {
        let mut watched = 0;
        for pair in &mut self.pairs {
            let (a, b) = (pair.object_a, pair.object_b);
            let Ok([oa, ob]) = self.objects.get_disjoint_mut([a, b]) else {
                continue;
            };
            pair.find(side(oa), side(ob));
            watched += pair.contact_count() as u32;
        }
        watched
    }

    /// The energy in the pairs' contact springs, N mm.
    pub(super) fn tissue_contact_energy_n_mm(&self) -> f64 {
        self.pairs
            .iter()
            .filter_map(|pair| {
                let (a, b) = (
                    self.objects.get(pair.object_a)?,
                    self.objects.get(pair.object_b)?,
                );
                Some(pair.energy_n_mm((&a.model, &a.state), (&b.model, &b.state)))
            })
            .sum()
    }

    /// Whether any pair watches a contact this tick (the substeps then zero and fill external forces).
    pub(super) fn tissue_contacts_watched(&self) -> bool {
        self.pairs.iter().any(|p| p.contact_count() > 0)
    }
}

fn side(object: &mut SimObject) -> PairSide<'_> {
    PairSide {
        collider: &object.collider,
        model: &object.model,
        positions_mm: &object.state.positions_mm,
        marks: &mut object.marks,
    }
}

/// One substep's contact forces of every pair, into the objects' external forces (zeroed by the caller).
pub(super) fn accumulate_tissue_contacts(
    pairs: &mut [TissuePair],
    objects: &mut [SimObject],
    h_s: f32,
) {
    for pair in pairs.iter_mut().filter(|p| p.contact_count() > 0) {
        let (a, b) = (pair.object_a, pair.object_b);
        let Ok([oa, ob]) = objects.get_disjoint_mut([a, b]) else {
            continue;
        };
        pair.accumulate(h_s, (&oa.model, &mut oa.state), (&ob.model, &mut ob.state));
    }
}
