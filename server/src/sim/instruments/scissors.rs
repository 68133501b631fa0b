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
    /// The jaw opening at the end of the last tick, rad, and where the two blades were in the world then
    /// (each from where it starts cutting to its tip), mm (None while they may not cut).
    last: Option<(f32, [[Vec3; 2]; 2])>,
    drag: BladeDrag,
}

impl Scissors {
    /// Open scissors.
    pub(in crate::sim) fn new(spec: ScissorsSpec) -> Self {
        Self {
            spec,
            jaws: Jaws::new(spec.activation, spec.open_angle_rad),
            last: None,
            drag: BladeDrag::default(),
        }
    }
}

impl Instrument for Scissors {
    /// The jaws take this tick's input; while they close, each blade cuts what it swept since the last tick,
    /// from where it was then to where it is now in the world: the part of the opening it closed and, if the
    /// hand moved the scissors meanwhile, what its edge passed through on the way (closing scissors carried
    /// along their own plane cut a continuous line, not a row of teeth). Open or opening scissors moved
    /// through tissue cut nothing. No allocation unless something is cut.
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
                self.last = None;
                return;
            }
            BladeTick::Joined => self.last = None,
            BladeTick::Sweeping => {}
        }
        let world = |p: [f32; 3]| tool.position_mm + tool.rotation * Vec3::from(p);
        let angle_rad = self.jaws.angle_rad();
        let now = self.spec.blades_mm(angle_rad).map(|blade| blade.map(world));
        let Some((before_rad, was)) = self.last.replace((angle_rad, now)) else {
            return;
        };
        if angle_rad >= before_rad {
            return;
        }
        // Closing: each blade cuts what it swept. The resistance of a snip is in the grip, which no device
        // renders: the tool feels no drag.
        let sweeps = [0, 1].map(|k| BladeSweep {
            from_mm: was[k],
            to_mm: now[k],
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
