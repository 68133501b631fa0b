//! The extension point of the tick: what a tool does beyond pushing tissue with its body.
//!
//! Owns: the [`Instrument`] trait (one hook per pipeline stage an instrument may act in, and the queries the
//! stages ask of it), [`build_instrument`] (descriptor -> implementation) and how the tick calls a hook
//! ([`Sim::with_instrument`]). Each instrument is one file in `instruments/`; adding one is that file, its
//! descriptor (`crate::interaction::InstrumentSpec`) and one arm of [`build_instrument`], touching no other
//! instrument and no stage.
//!
//! Must not: hold tissue or tool state of its own (that is [`Sim`]'s and the instruments').
//!
//! How a hook runs. A hook gets the whole [`Sim`] and its tool's index: it reads its tool's body, drive and
//! contacts there, and may change objects (cut, burn). While it runs, its own instrument is out of the tool
//! (`SimTool::instrument_state` is `None`), so the borrow is plain; a topology change made meanwhile is
//! passed on to it when it is back. Taking a `Box` out of an `Option` and putting it back allocates
//! nothing.

use std::fmt::Debug;

use nalgebra::{Isometry3, UnitQuaternion};

use crate::interaction::suture::{NeedleHold, NeedleTissue, SutureThread};
use crate::interaction::{Grasp, InstrumentSpec, Jaws};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

use super::instruments::{CauteryTip, Grasper, NeedleDriver, Scalpel, Scissors};
use super::*;

/// A tool's instrument: its state between ticks and what it does in each stage of [`Sim::step`]. Every
/// method has a default that does nothing, so an instrument implements only the stages it acts in. The
/// tick calls the tools' hooks in tool order, stage by stage, so results do not depend on which instruments
/// exist.
///
/// Real-time contract of every hook: no allocation in the steady tick (a cut or a grasp taken is an event and
/// may allocate), never panics, never produces a non-finite force.
pub(crate) trait Instrument: Debug + Send + Sync {
    /// Stage 1, after the tools followed their devices and before anything reads the topology: act on it
    /// (blades cut what they swept since the last tick).
    fn before_contacts(&mut self, _sim: &mut Sim, _t: usize, _dt_s: f32, _report: &mut StepReport) {
    }

    /// Stage 4, after the guarded substeps and the tears: act on what the step left (jaws take hold, slip,
    /// let go).
    fn after_substeps(&mut self, _sim: &mut Sim, _t: usize, _dt_s: f32, _report: &mut StepReport) {}

    /// Stage 5, just before this tool's output: act on the surface the body touches (the cautery burns).
    fn before_output(&mut self, _sim: &mut Sim, _t: usize, _dt_s: f32, _report: &mut StepReport) {}

    /// The nodes of object `object` the instrument holds (sorted): regions follow them, the implicit solver
    /// pins them, the body does not push them, the contact solve counts them as held.
    fn attached_nodes(&self, _object: usize) -> &[u32] {
        &[]
    }

    /// Every substep, after the body pushed object `object`'s tissue out: move what the instrument holds
    /// with it (`position_mm`, `rotation`: the tool's pose).
    fn hold(
        &self,
        _object: usize,
        _position_mm: &Vec3,
        _rotation: &UnitQuaternion<f32>,
        _model: &MassSpringModel,
        _state: &mut TissueState,
    ) {
    }

    /// Whether it pulls tissue with forces this tick ([`Instrument::add_forces`]): a thread through holes.
    fn pulls_tissue(&self) -> bool {
        false
    }

    /// Every substep, before the integration: add the instrument's forces on object `object`'s nodes to its
    /// external forces (cleared before, and the ties' added, by the substep). Called only while
    /// [`Instrument::pulls_tissue`].
    fn add_forces(&self, _object: usize, _model: &MassSpringModel, _state: &mut TissueState) {}

    /// Object `object` was reset to rest (a contained fault): let go of it. Returns the points let go.
    fn object_reset(&mut self, _object: usize) -> u32 {
        0
    }

    /// Object `object`'s topology changed (a cut or a tear): re-read what stands on it. Must be idempotent
    /// (it may come for an object whose model did not change).
    fn topology_changed(&mut self, _object: usize, _model: &MassSpringModel) {}

    /// Object `object` was subdivided (a cut that follows the blade split or reshaped elements): re-express the
    /// material points held on it with `remap`, then re-read what stands on it. By default only the latter
    /// (the element ids held stay valid; a point on a split element then lies on the piece that kept the id).
    fn subdivided(
        &mut self,
        object: usize,
        model: &MassSpringModel,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) {
        let _ = remap;
        self.topology_changed(object, model);
    }

    /// The instrument's own pull on the tool this tick, world, N (a grasp's, the drag of cutting), added to
    /// the body's reaction before the clamp.
    fn force_on_tool_n(&self) -> Vec3 {
        Vec3::zeros()
    }

    /// The work tool `tool` did on the tissue this tick by turning what this instrument carries (beyond its
    /// force times its translation), mJ: a needle's loads times the motion the turn of the jaws holding it gave
    /// their points ([`crate::haptics::energy_budget`]).
    fn turn_work_mj(&self, _tool: u16) -> f64 {
        0.0
    }

    /// The tool bears a load through what its jaws hold other than tissue (a needle in the tissue, a suture
    /// thread): its output is in contact, so a distant device renders its model.
    fn loads_tool(&self) -> bool {
        false
    }

    /// Points of tissue held (counted as held nodes, and reported).
    fn held_points(&self) -> u16 {
        0
    }

    /// Mark the tool's output with the instrument's state (jaws, cutting, burning).
    fn mark_output(&self, _out: &mut ToolOutput) {}

    /// The jaws, for an instrument with jaws.
    fn jaws(&self) -> Option<&Jaws> {
        None
    }

    /// The grasp, for a grasper.
    fn grasp(&self) -> Option<&Grasp> {
        None
    }

    /// The grasp, for a grasper, to settle on a multi-rate object's finished step (the sim does, at its
    /// hand-off).
    fn grasp_mut(&mut self) -> Option<&mut Grasp> {
        None
    }

    /// The needle against the tissue, for a needle driver.
    fn needle(&self) -> Option<&NeedleTissue> {
        None
    }

    /// Who holds the needle, for a needle driver.
    fn needle_hold(&self) -> Option<&NeedleHold> {
        None
    }

    /// Tool `taker`'s closing jaws, at `world_from_taker`, take this instrument's needle if it is loose and a
    /// point of it lies within `reach_mm` of their body (`distance_mm`: a world point's distance to it).
    /// Returns whether they took it.
    fn take_needle(
        &mut self,
        _taker: u16,
        _world_from_taker: &Isometry3<f32>,
        _distance_mm: &dyn Fn(&Vec3) -> f32,
        _reach_mm: f32,
    ) -> bool {
        false
    }

    /// Tool `taker`'s jaws opened (or it left): they let go of this instrument's needle if they hold it.
    /// Returns whether they held it.
    fn let_go_of_needle(&mut self, _taker: u16) -> bool {
        false
    }

    /// The needle's pull on tool `holder`'s jaws, world, N, while they hold this instrument's needle (None:
    /// they do not).
    fn needle_pull_on_n(&self, _holder: u16) -> Option<Vec3> {
        None
    }

    /// The thread on the needle, for a needle driver with one.
    fn thread(&self) -> Option<&SutureThread> {
        None
    }

    /// The same thread, for another tool's jaws to take hold of it (a hook runs with its own instrument out
    /// of its tool, the others in place).
    fn thread_mut(&mut self) -> Option<&mut SutureThread> {
        None
    }
}

/// The implementation of an instrument descriptor, for a scene of `objects` objects under the world's
/// `gravity_mm_per_s2` (`None`: a probe, the body alone). Allocates (a scene is being built).
pub(crate) fn build_instrument(
    spec: &InstrumentSpec,
    objects: usize,
    gravity_mm_per_s2: Vec3,
) -> Option<Box<dyn Instrument>> {
    match spec {
        InstrumentSpec::Probe => None,
        InstrumentSpec::Grasper(g) => Some(Box::new(Grasper::new(*g, objects))),
        InstrumentSpec::Cautery(c) => Some(Box::new(CauteryTip::new(*c))),
        InstrumentSpec::Scalpel(s) => Some(Box::new(Scalpel::new(*s))),
        InstrumentSpec::Scissors(s) => Some(Box::new(Scissors::new(*s))),
        InstrumentSpec::NeedleDriver(n) => {
            Some(Box::new(NeedleDriver::new(*n, objects, gravity_mm_per_s2)))
        }
    }
}

impl Sim {
    /// Run `hook` on tool `t`'s instrument with the whole simulation at hand (see the module doc); a tool
    /// without one, or an index out of range, runs nothing. No allocation.
    pub(super) fn with_instrument(
        &mut self,
        t: usize,
        hook: impl FnOnce(&mut dyn Instrument, &mut Sim),
    ) {
        let Some(mut instrument) = self
            .tools
            .get_mut(t)
            .and_then(|tool| tool.instrument_state.take())
        else {
            return;
        };
        let openings = self.openings;
        hook(instrument.as_mut(), self);
        if self.openings != openings {
            // A topology change while it was out: it missed `open_seams`' notice.
            for (o, object) in self.objects.iter().enumerate() {
                instrument.topology_changed(o, &object.model);
            }
        }
        self.tools[t].instrument_state = Some(instrument);
    }
}
