//! What a sharp instrument keeps between ticks, and the steps a scalpel and scissors share: when a blade may
//! cut (its tool has reached the hand), cutting every object along a sweep, and the drag of cutting.
//!
//! Owns: [`BladeDrag`], [`blade_tick`], [`cut_everything`] and the drag's constants. Must not: open seams
//! itself ([`Sim::cut`] does, through `topology.rs`).

use crate::interaction::{BladeSweep, CutScratch};
use crate::tissue::Vec3;

use super::super::*;

/// How long the drag of cutting lasts after the edge last cut a facet, s (time constant of its decay): the
/// wire's, since a distant device renders the same decay.
pub(super) const CUT_DRAG_TAU_S: f32 = sinew_protocol::CUT_DRAG_TAU_S;

/// Weight of a new interval between facet cuts in the running spacing the model carries.
const FACET_SMOOTHING: f32 = 0.3;

/// A facet cut extends the cut only while the drag of the last one is still above this level (it cut within
/// about 0.3 s); otherwise the edge's travel since is an approach, not a spacing.
const SAME_CUT_LEVEL: f32 = 0.05;

/// Below this mean drag the local model carries none, N (a step this small is below what a hand detects).
pub(super) const MIN_MODEL_DRAG_N: f32 = 0.005;
/// An edge slower than this, mm/s, is held still: it feels no drag and is not cutting (the coupled tool still
/// settles by micrometres after the hand stops).
pub(super) const MIN_CUT_SPEED_MM_S: f32 = 1.0;

/// A (re)taken tool has joined its hand once it is this close to the device pose, mm: the coupling's lag under a
/// hard press is under 1 mm (3.3 N at 5 N/mm).
pub(super) const JOINED_MM: f32 = 1.0;

/// A blade's cutting state between ticks.
#[derive(Debug, Default)]
pub(super) struct BladeDrag {
    /// The drag of the tissue the blade cut last, N (its material's `cut_resistance_n`).
    pub(super) resistance_n: f32,
    /// The sweep's scratch.
    scratch: CutScratch,
    /// The drag of cutting this tick, N (world frame, against the edge's motion).
    pub(super) force_n: Vec3,
    /// How recently it cut: 1 on a tick that cut, decaying with [`CUT_DRAG_TAU_S`] (the edge crosses the
    /// mesh's facets one at a time; the drag of cutting is felt in between).
    pub(super) level: f32,
    /// The blade moved this tick.
    pub(super) moving: bool,
    /// The drag's size averaged over [`CUT_DRAG_TAU_S`], N. The drag itself is a sawtooth (1 at each facet
    /// cut, decaying between): a distant device makes it from [`BladeDrag::facet_mm`] and its own travel;
    /// until a spacing is known the model carries this mean.
    mean_n: f32,
    /// How far the edge travelled since it last cut a facet, mm.
    travel_since_cut_mm: f32,
    /// The edge's travel between facet cuts, running, mm (0 until two cuts in a row have been seen).
    facet_mm: f32,
}

impl BladeDrag {
    /// A new tick: the last drag joins the mean, no drag yet, the level decays.
    pub(super) fn begin_tick(&mut self, dt_s: f32) {
        // The last tick's drag joins the running mean (a tick late: the model is a smoothed figure anyway).
        let magnitude = self.force_n.norm();
        if magnitude.is_finite() {
            self.mean_n += (magnitude - self.mean_n) * (1.0 - (-dt_s / CUT_DRAG_TAU_S).exp());
        }
        self.force_n = Vec3::zeros();
        self.level *= (-dt_s / CUT_DRAG_TAU_S).exp();
        self.moving = false;
    }

    /// The edge travelled `travel_mm` this tick and cut `facets` facets: the running spacing between cuts
    /// takes the travel since the last one (shared among this tick's), while the cut goes on.
    pub(super) fn advance(&mut self, travel_mm: f32, facets: u32) {
        if !(travel_mm.is_finite() && travel_mm >= 0.0) {
            return;
        }
        self.travel_since_cut_mm += travel_mm;
        if facets == 0 {
            return;
        }
        if self.level > SAME_CUT_LEVEL {
            let interval_mm = self.travel_since_cut_mm / facets as f32;
            self.facet_mm = if self.facet_mm > 0.0 {
                self.facet_mm + (interval_mm - self.facet_mm) * FACET_SMOOTHING
            } else {
                interval_mm
            };
        }
        self.travel_since_cut_mm = 0.0;
        self.level = 1.0;
    }

    /// The blade is cutting: moving, and cut recently.
    pub(super) fn cutting(&self) -> bool {
        self.moving && self.level > 0.5
    }

    /// Mark `out` with the drag of cutting: for the local model (none while its mean is below
    /// [`MIN_MODEL_DRAG_N`]) the drag at a facet cut and the spacing of the facets once that is known, its
    /// mean before; and the drag inside the tool's force this tick.
    pub(super) fn mark(&self, out: &mut ToolOutput) {
        out.cutting = self.cutting();
        out.cut_drag_world_n = self.force_n;
        let sawtooth =
            self.facet_mm > 0.0 && self.resistance_n.is_finite() && self.resistance_n > 0.0;
        (out.cut_drag_n, out.cut_facet_mm) = match (self.mean_n >= MIN_MODEL_DRAG_N, sawtooth) {
            (false, _) => (0.0, 0.0),
            (true, true) => (self.resistance_n, self.facet_mm),
            (true, false) => (self.mean_n, 0.0),
        };
    }
}

/// Where a blade stands at the start of its tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum BladeTick {
    /// It cuts nothing and forgets where it was: its tool is inactive (its drag ends too), or has not yet
    /// reached the hand since it was (re)taken (see `SimTool::joined`: until then it is dragged from its
    /// entry point, a path the surgeon did not make). A tool that comes back does not sweep from where it
    /// left.
    Idle,
    /// It reached the hand this tick: it forgets where it was and starts from here (sweeping nothing yet).
    Joined,
    /// It sweeps from where it was at the end of the last tick.
    Sweeping,
}

/// Where tool `tool`'s blade stands this tick (see [`BladeTick`]); marks the tool joined when it reaches the
/// hand.
pub(super) fn blade_tick(tool: &mut SimTool, drag: &mut BladeDrag) -> BladeTick {
    if !tool.active {
        drag.level = 0.0;
        return BladeTick::Idle;
    }
    if !tool.drive.joined {
        tool.drive.joined = (tool.drive.device_mm - tool.position_mm).norm() <= JOINED_MM;
        return if tool.drive.joined {
            BladeTick::Joined
        } else {
            BladeTick::Idle
        };
    }
    BladeTick::Sweeping
}

/// Cut every object along one sweep of tool `t`'s blade; returns the seams cut, and takes the drag of the
/// tissue cut (the last object that was).
pub(super) fn cut_everything(
    sim: &mut Sim,
    sweep: &BladeSweep,
    drag: &mut BladeDrag,
    report: &mut StepReport,
) -> u32 {
    let mut severed = 0;
    for o in 0..sim.objects.len() {
        let opening = sim.cut(o, sweep, &mut drag.scratch);
        if !drag.scratch.seams.is_empty() {
            severed += drag.scratch.seams.len() as u32;
            drag.resistance_n = sim.objects[o].cut_resistance_n;
        }
        report.vertices_split += opening.new_vertices() as u32;
    }
    report.seams_cut += severed;
    severed
}
