//! Cautery: an active tip burns the tissue it touches while its button is held.
//!
//! Owns: [`Sim::cauterize`]. Must not: change topology.

use super::*;

impl Sim {
    /// A cautery tool with its button held burns the surface it touches (the nodes on or within its reach of the
    /// body), by its rate times `dt_s`. Returns the nodes burnt. No allocation.
    pub(super) fn cauterize(&mut self, t: usize, dt_s: f32) -> u32 {
        let tool = &self.tools[t];
        let Some(spec) = tool.instrument.cautery() else {
            return 0;
        };
        if !tool.active || tool.jaw_input.buttons & spec.button_mask == 0 {
            return 0;
        }
        // Fixed point: 256 units per burn level; at least one unit a tick so a slow rate still burns.
        let step = (spec.burn_per_s * dt_s * 256.0).clamp(1.0, 65535.0) as u16;
        let mut burnt = 0;
        let mut shrunk = false;
        for (o, object) in self.objects.iter_mut().enumerate() {
            for &node in &tool.contacts[o].candidates {
                let i = node as usize;
                let (Some(x), Some(level)) =
                    (object.state.positions_mm.get(i), object.burn.get_mut(i))
                else {
                    continue;
                };
                if tool
                    .collider
                    .distance_mm(&tool.position_mm, &tool.rotation, x)
                    <= spec.reach_mm + BITE_TOLERANCE_MM
                {
                    *level = level.saturating_add(step);
                    burnt += 1;
                    object.shrink_springs_of(i);
                    shrunk |= object.burn_shrink > 0.0;
                }
            }
        }
        if shrunk {
            // The rest lengths changed after the guard measured this tick's energy.
            self.last_energy_n_mm = None;
        }
        burnt
    }
}
