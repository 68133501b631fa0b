//! The region's levels: a breadth-first search over the springs from the seeds, and the depth that says
//! which levels are active.
//!
//! Owns: re-seeding ([`RegionTracker::reseed`]) and moving the depth ([`RegionTracker::set_depth`]),
//! zeroing the velocities of nodes that leave the active set. Must not: decide when to grow or shrink
//! (the parent's `update` does) or build the sub-model.

use super::*;

impl RegionTracker {
    /// New levels from `self.seeds`, [`MARGIN_LEVELS`] + 1 deep; nodes that were active and are not any more
    /// have their velocities zeroed.
    pub(super) fn reseed(&mut self, model: &MassSpringModel, state: &mut TissueState) {
        self.previous_active.clear();
        let end = self
            .level_start
            .get(self.depth as usize)
            .copied()
            .unwrap_or(0) as usize;
        self.previous_active
            .extend_from_slice(&self.order[..end.min(self.order.len())]);
        self.clear();
        for &s in &self.seeds {
            if let Some(level) = self.level_of.get_mut(s as usize)
                && *level == OUTSIDE
            {
                *level = 0;
                self.order.push(s);
            }
        }
        self.level_start.push(self.order.len() as u32);
        self.settle_s = 0.0;
        self.set_depth(model, state, 1 + MARGIN_LEVELS);
        for &i in &self.previous_active {
            if self.level_of[i as usize] >= self.depth {
                state.velocities_mm_s[i as usize] = Vec3::zeros();
            }
        }
    }

    /// Make levels `0..depth` active, computing levels up to `depth` (the boundary) as needed; the depth stops
    /// where the BFS runs out of nodes. Nodes leaving the active set have their velocities zeroed.
    pub(super) fn set_depth(
        &mut self,
        model: &MassSpringModel,
        state: &mut TissueState,
        depth: u32,
    ) {
        let computed = |s: &Self| s.level_start.len() as u32 - 1;
        // Extend the BFS until level `depth` exists or the component is exhausted.
        while computed(self) <= depth {
            let level = computed(self);
            if level == 0 {
                break;
            }
            let (from, to) = (
                self.level_start[level as usize - 1] as usize,
                self.level_start[level as usize] as usize,
            );
            if from == to {
                break;
            }
            for k in from..to {
                let i = self.order[k] as usize;
                for &s in model.node_springs(i) {
                    let j = model.other_end(s, i);
                    if self.level_of[j] == OUTSIDE {
                        self.level_of[j] = level;
                        self.order.push(j as u32);
                    }
                }
            }
            self.level_start.push(self.order.len() as u32);
        }
        // Levels with nodes: 0..nonempty.
        let nonempty = (0..computed(self))
            .take_while(|&l| self.level_start[l as usize] < self.level_start[l as usize + 1])
            .count() as u32;
        let depth = depth.min(nonempty);
        if depth < self.depth {
            // Leaving the active set: levels depth..self.depth keep their positions and stop.
            let (from, to) = (
                self.level_start[depth as usize] as usize,
                self.level_start[self.depth as usize] as usize,
            );
            for &i in &self.order[from..to] {
                state.velocities_mm_s[i as usize] = Vec3::zeros();
            }
        }
        // Keep levels 0..=depth (the boundary ring); forget the rest.
        let keep_levels = (depth as usize + 1).min(self.level_start.len() - 1);
        let keep = self.level_start[keep_levels] as usize;
        for &i in &self.order[keep..] {
            self.level_of[i as usize] = OUTSIDE;
        }
        self.order.truncate(keep);
        self.level_start.truncate(keep_levels + 1);
        if depth == 0 {
            self.clear();
        }
        if depth != self.depth {
            self.stale = true;
        }
        self.depth = depth;
    }
}
