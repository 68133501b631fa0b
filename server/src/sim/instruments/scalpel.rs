//! A scalpel: its sharp edge cuts what it sweeps between ticks, and the hand feels the drag of cutting.
//!
//! Owns: [`Scalpel`] (where its edge was, its drag). Must not: open seams itself (`blade_drag::cut_everything`
//! goes through [`Sim::cut`]).

use crate::interaction::{BladeSweep, ScalpelSpec};
use crate::tissue::Vec3;

use super::super::instrument::Instrument;
use super::super::*;
use super::blade_drag::{BladeDrag, BladeTick, MIN_CUT_SPEED_MM_S, blade_tick, cut_everything};

/// A scalpel's state between ticks.
#[derive(Debug)]
pub(in crate::sim) struct Scalpel {
    spec: ScalpelSpec,
    /// The edge in the world at the end of the last tick (None while it may not cut).
    edge_world_mm: Option<[Vec3; 2]>,
    drag: BladeDrag,
}

impl Scalpel {
    /// An edge that has not swept yet.
    pub(in crate::sim) fn new(spec: ScalpelSpec) -> Self {
        Self {
            spec,
            edge_world_mm: None,
            drag: BladeDrag::default(),
        }
    }
}

impl Instrument for Scalpel {
    /// The edge cuts what it swept from where it was at the end of the last tick to where the tool now holds
    /// it ([`Sim::cut`]); the tool feels the drag of cutting against the edge's motion while it cuts (the
    /// tissue's `cut_resistance_n`, fading over `CUT_DRAG_TAU_S` after the last facet it cut). No
    /// allocation unless something is cut.
    fn before_contacts(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        self.drag.begin_tick(dt_s);
        let tool = &mut sim.tools[t];
        match blade_tick(tool, &mut self.drag) {
            BladeTick::Idle => {
                self.edge_world_mm = None;
                return;
            }
            BladeTick::Joined => self.edge_world_mm = None,
            BladeTick::Sweeping => {}
        }
        let world = |p: [f32; 3]| tool.position_mm + tool.rotation * Vec3::from(p);
        let edge_now = self.spec.edge_mm.map(world);
        let Some(edge_before) = self.edge_world_mm.replace(edge_now) else {
            return;
        };
        let sweep = BladeSweep {
            from_mm: edge_before,
            to_mm: edge_now,
        };
        let severed = cut_everything(sim, &sweep, &mut self.drag, report);
        let motion = (edge_now[0] + edge_now[1] - edge_before[0] - edge_before[1]) * 0.5;
        self.drag.advance(motion.norm(), severed);
        if let Some(direction) = motion.try_normalize(MIN_CUT_SPEED_MM_S * dt_s) {
            self.drag.moving = true;
            // The drag acts a tick late against the last tick's motion (explicit Coulomb friction): one the size
            // of the force that would have stopped that motion in the coupling throws the tool back next tick,
            // and a still hand felt the tool chatter, the drag flipping each tick. Half of it only slows it.
            let params = *sim.tools[t].drive.coupling.params();
            let stopping_n =
                (params.damping_n_s_per_mm / dt_s + params.stiffness_n_per_mm) * motion.norm();
            self.drag.force_n =
                -direction * (self.drag.resistance_n * self.drag.level).min(0.5 * stopping_n);
        }
    }

    fn force_on_tool_n(&self) -> Vec3 {
        self.drag.force_n
    }

    fn mark_output(&self, out: &mut ToolOutput) {
        self.drag.mark(out);
    }
}
