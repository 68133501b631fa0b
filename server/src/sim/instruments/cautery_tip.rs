//! Cautery: an active tip burns the tissue it touches while its button is held.
//!
//! Owns: [`CauteryTip`]. Must not: change topology (burnt springs shrink through `SimObject::shrink_springs_of`).

use crate::interaction::CauterySpec;

use super::super::instrument::Instrument;
use super::super::*;

/// A cautery tool's state between ticks.
#[derive(Debug)]
pub(in crate::sim) struct CauteryTip {
    spec: CauterySpec,
    /// It burnt tissue this tick.
    burning: bool,
}

impl CauteryTip {
    /// A cold tip.
    pub(in crate::sim) fn new(spec: CauterySpec) -> Self {
        Self {
            spec,
            burning: false,
        }
    }
}

impl Instrument for CauteryTip {
    /// With its button held, the tip burns the surface it touches (the nodes on or within its reach of the
    /// body), by its rate times `dt_s`. No allocation.
    fn before_output(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        self.burning = false;
        let tool = &sim.tools[t];
        let spec = &self.spec;
        if !tool.active || tool.drive.jaw_input.buttons & spec.button_mask == 0 {
            return;
        }
        // Fixed point: 256 units per burn level; at least one unit a tick so a slow rate still burns.
        let step = (spec.burn_per_s * dt_s * 256.0).clamp(1.0, 65535.0) as u16;
        let mut burnt = 0;
        let mut shrunk = false;
        for (o, object) in sim.objects.iter_mut().enumerate() {
            for &node in &tool.contacts[o].candidates {
                let i = node as usize;
                let (Some(x), Some(level)) =
                    (object.state.positions_mm.get(i), object.burn.get_mut(i))
                else {
                    continue;
                };
                if tool
                    .body
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
            sim.note_state_changed();
        }
        report.nodes_burnt += burnt;
        self.burning = burnt > 0;
    }

    fn mark_output(&self, out: &mut ToolOutput) {
        out.burning = self.burning;
    }
}
