//! Scissors: two blades hinged on the tool cut what lies between them as they close.
//!
//! Owns: [`Scissors`] (their jaws, the opening at the end of the last tick, the cutting state). Must not:
//! open seams itself (`blade_drag::cut_everything` goes through [`Sim::cut`]).

use crate::interaction::{BladeSweep, Jaws, ScissorsSpec};
use crate::tissue::Vec3;

use super::super::instrument::Instrument;
use super::super::*;
use super::blade_drag::{BladeDrag, BladeTick, blade_tick, cut_everything};

/// A pair of scissors' state between ticks.
#[derive(Debug)]
pub(in crate::sim) struct Scissors {
    spec: ScissorsSpec,
    jaws: Jaws,
    /// The jaw opening at the end of the last tick, rad (None while they may not cut).
    blade_angle_rad: Option<f32>,
    drag: BladeDrag,
}

impl Scissors {
    /// Open scissors.
    pub(in crate::sim) fn new(spec: ScissorsSpec) -> Self {
        Self {
            spec,
            jaws: Jaws::new(spec.activation, spec.open_angle_rad),
            blade_angle_rad: None,
            drag: BladeDrag::default(),
        }
    }
}

impl Instrument for Scissors {
    /// The jaws take this tick's input; the blades cut through the part of their opening they closed this
    /// tick, in the tool's current pose (open scissors moved through tissue cut nothing). No allocation
    /// unless something is cut.
    fn before_contacts(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        self.drag.begin_tick(dt_s);
        let tool = &mut sim.tools[t];
        if tool.active {
            self.jaws.update(&tool.drive.jaw_input, dt_s);
        } else {
            self.jaws.open();
        }
        match blade_tick(tool, &mut self.drag) {
            BladeTick::Idle => {
                self.blade_angle_rad = None;
                return;
            }
            BladeTick::Joined => self.blade_angle_rad = None,
            BladeTick::Sweeping => {}
        }
        let world = |p: [f32; 3]| tool.position_mm + tool.rotation * Vec3::from(p);
        let angle_rad = self.jaws.angle_rad();
        let Some(before_rad) = self.blade_angle_rad.replace(angle_rad) else {
            return;
        };
        if angle_rad >= before_rad {
            return;
        }
        // Closing: each blade cuts the wedge of the opening it passed through. The resistance of a snip is in
        // the grip, which no device renders: the tool feels no drag.
        let (was, now) = (
            self.spec.blades_mm(before_rad),
            self.spec.blades_mm(angle_rad),
        );
        let sweeps = [0, 1].map(|k| BladeSweep {
            from_mm: was[k].map(world),
            to_mm: now[k].map(world),
        });
        let mut severed = 0;
        for sweep in &sweeps {
            severed += cut_everything(sim, sweep, &mut self.drag, report);
        }
        self.drag.moving = true;
        if severed > 0 {
            self.drag.level = 1.0;
        }
    }

    fn force_on_tool_n(&self) -> Vec3 {
        self.drag.force_n
    }

    fn mark_output(&self, out: &mut ToolOutput) {
        out.jaws_closed = self.jaws.closed();
        out.jaw_angle_rad = self.jaws.angle_rad();
        // A snip's resistance is in the grip, which no device renders: no drag of cutting in the model either.
        out.cutting = self.drag.cutting();
    }

    fn jaws(&self) -> Option<&Jaws> {
        Some(&self.jaws)
    }
}
