//! Blades: a scalpel's edge and scissors' blades cut what they sweep, and the hand feels the drag of cutting.
//!
//! Owns: [`Sim::cut_with`] (a tool's sweep this tick), the drag's constants. Must not: open seams itself
//! ([`super::topology`] does).

use crate::interaction::BladeSweep;
use crate::tissue::Vec3;

use super::*;

impl Sim {
    /// A sharp instrument, once its tool has reached the hand (see `SimTool::joined`), cuts what its blades
    /// swept since the last tick ([`Self::cut`]): a scalpel's edge from where it was at the end of the last
    /// tick to where the tool now holds it, and scissors' blades through the part of their opening they closed
    /// this tick (in the tool's current pose: open scissors moved through tissue cut nothing). A scalpel's tool
    /// feels the drag of cutting against the edge's motion while it cuts (the tissue's `cut_resistance_n`,
    /// fading over [`CUT_DRAG_TAU_S`] after the last facet it cut). No allocation unless something is cut.
    pub(super) fn cut_with(&mut self, t: usize, dt_s: f32, report: &mut StepReport) {
        let tool = &mut self.tools[t];
        tool.cut_force_n = Vec3::zeros();
        tool.cut_level *= (-dt_s / CUT_DRAG_TAU_S).exp();
        tool.edge_moving = false;
        let (scalpel, scissors) = (
            tool.instrument.scalpel().copied(),
            tool.instrument.scissors().copied(),
        );
        if scalpel.is_none() && scissors.is_none() {
            return;
        }
        if let (Some(jaws), Some(_)) = (&mut tool.jaws, scissors) {
            if tool.active {
                jaws.update(&tool.jaw_input, dt_s);
            } else {
                jaws.open();
            }
        }
        if !tool.active {
            tool.edge_world_mm = None;
            tool.blade_angle_rad = None;
            tool.cut_level = 0.0;
            return;
        }
        if !tool.joined {
            tool.joined = (tool.device_mm - tool.position_mm).norm() <= JOINED_MM;
            tool.edge_world_mm = None;
            tool.blade_angle_rad = None;
            if !tool.joined {
                return;
            }
        }
        let world = |p: [f32; 3]| tool.position_mm + tool.rotation * Vec3::from(p);
        if let Some(spec) = scalpel {
            let edge_now = spec.edge_mm.map(world);
            let Some(edge_before) = tool.edge_world_mm.replace(edge_now) else {
                return;
            };
            let sweep = BladeSweep {
                from_mm: edge_before,
                to_mm: edge_now,
            };
            let severed = self.cut_everything(t, &sweep, report);
            let tool = &mut self.tools[t];
            if severed > 0 {
                tool.cut_level = 1.0;
            }
            let motion = (edge_now[0] + edge_now[1] - edge_before[0] - edge_before[1]) * 0.5;
            if let Some(direction) = motion.try_normalize(MIN_CUT_SPEED_MM_S * dt_s) {
                tool.edge_moving = true;
                tool.cut_force_n = -direction * tool.cut_resistance_n * tool.cut_level;
            }
        } else if let (Some(spec), Some(jaws)) = (scissors, &tool.jaws) {
            let angle_rad = jaws.angle_rad();
            let Some(before_rad) = tool.blade_angle_rad.replace(angle_rad) else {
                return;
            };
            if angle_rad >= before_rad {
                return;
            }
            // Closing: each blade cuts the wedge of the opening it passed through. The resistance of a snip is
            // in the grip, which no device renders: the tool feels no drag.
            let (was, now) = (spec.blades_mm(before_rad), spec.blades_mm(angle_rad));
            let sweeps = [0, 1].map(|k| BladeSweep {
                from_mm: was[k].map(world),
                to_mm: now[k].map(world),
            });
            let mut severed = 0;
            for sweep in &sweeps {
                severed += self.cut_everything(t, sweep, report);
            }
            let tool = &mut self.tools[t];
            tool.edge_moving = true;
            if severed > 0 {
                tool.cut_level = 1.0;
            }
        }
    }

    /// Cut every object along one sweep of tool `t`'s blade; returns the seams cut, and takes the drag of the
    /// tissue cut (the last object that was).
    pub(super) fn cut_everything(
        &mut self,
        t: usize,
        sweep: &BladeSweep,
        report: &mut StepReport,
    ) -> u32 {
        let mut scratch = std::mem::take(&mut self.tools[t].cut_scratch);
        let mut severed = 0;
        for o in 0..self.objects.len() {
            let opening = self.cut(o, sweep, &mut scratch);
            if !scratch.seams.is_empty() {
                severed += scratch.seams.len() as u32;
                self.tools[t].cut_resistance_n = self.objects[o].cut_resistance_n;
            }
            report.vertices_split += opening.new_vertices() as u32;
        }
        self.tools[t].cut_scratch = scratch;
        report.seams_cut += severed;
        severed
    }
}

/// How long the drag of cutting lasts after the edge last cut a facet, s (time constant of its decay): at a
/// steady 10-20 mm/s the edge crosses a 1 mm mesh's facets every 50-100 ms, and the drag holds in between.
pub(super) const CUT_DRAG_TAU_S: f32 = 0.1;

/// An edge slower than this, mm/s, is held still: it feels no drag and is not cutting (the coupled tool still
/// settles by micrometres after the hand stops).
pub(super) const MIN_CUT_SPEED_MM_S: f32 = 1.0;

/// A (re)taken tool has joined its hand once it is this close to the device pose, mm: the coupling's lag under a
/// hard press is under 1 mm (3.3 N at 5 N/mm).
pub(super) const JOINED_MM: f32 = 1.0;
