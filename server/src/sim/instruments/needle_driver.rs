//! A needle driver: jaws holding a curved needle whose tip tents tissue, punctures it and passes through it.
//!
//! Owns: [`NeedleDriver`] (the needle's pose on the tool and its relation to the tissue,
//! [`NeedleTissue`]). The body (the jaws, the tool's `shape`) probes as any body does; the needle's tip is
//! a point that presses a surface point, and the needle's own body does not push tissue: the holes it passes
//! through hold it on its path (`interaction/suture/hole.rs`).
//!
//! The jaws are a ratchet: locked on the needle unless the device's first button is held (a surgeon squeezes
//! the handle past its ratchet to open it). Opening them with the needle in tissue leaves it there, held by its
//! holes; a grasper's jaws closing on it then take it (at the tip, on the far side of a bite) and draw it
//! through, and the needle's forces go to whichever jaws hold it ([`NeedleHold`]). The driver's jaws closing
//! again on a loose needle take it back, where they meet it; closing, without the needle, on its own thread
//! they take the thread (as a surgeon takes the free end to draw a stitch tight), and feel its pull. A driver whose device leaves takes its needle
//! back into its jaws, and everything it held is let go.
//!
//! Stages: before the contacts, the jaws open or close and the needle is placed where its holder holds it;
//! the tip's path since the last tick is tested against the surfaces (a free tip
//! meets one, a tip inside an object reaches its far wall) and the holes the needle left close; each substep
//! the pressed point is held at the tip and the holes hold the needle on its path; after the substeps the
//! holes' forces are read (they stick or slide) and the tip punctures, skates or lifts off.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};

use crate::interaction::suture::{
    NeedleDriverSpec, NeedleFall, NeedleHold, NeedleHolder, NeedleTissue, NeedleWire,
    STANDARD_GRAVITY_MM_PER_S2, SutureThread, THREAD_DIAMETER_MM, TipPhase,
};
use crate::interaction::{JawActivation, JawInput, Jaws};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

use super::super::instrument::Instrument;
use super::super::*;

/// A needle driver's state between ticks.
#[derive(Debug)]
pub(in crate::sim) struct NeedleDriver {
    /// Where the needle sits in the jaws as loaded.
    tool_from_needle: Isometry3<f32>,
    /// The jaws (a ratchet, module doc).
    jaws: Jaws,
    /// Who holds the needle, and where it is this tick.
    hold: NeedleHold,
    needle: NeedleTissue,
    /// The needle's wire diameter, mm.
    diameter_mm: f32,
    /// The thread on the needle's tail (None: a needle without one).
    thread: Option<SutureThread>,
    /// The driver's own tool index (known from its first tick): its jaws' grip on the thread is under it.
    own_tool: Option<u16>,
    /// The needle's pull on the jaws when they let it go, N, and the share of it still felt (1 -> 0 as the
    /// jaws open): the hand does not lose the needle's load in one tick.
    let_go_pull_n: Vec3,
    let_go_share: f32,
    /// The needle's pose at the last tick, and the tool whose jaws held it then (None: no jaws did).
    last_pose: Option<(u16, Isometry3<f32>)>,
    /// The work the turn of the jaws that hold the needle did on the tissue this tick through the needle and
    /// the thread on its tail, mJ, and the tool whose jaws they are ([`Instrument::turn_work_mj`]).
    turn_work_mj: (u16, f64),
    /// The needle as a rigid body while it lies loose out of tissue, and the world's gravity, mm/s^2.
    fall: NeedleFall,
    gravity_mm_per_s2: Vec3,
}

impl NeedleDriver {
    /// Jaws holding the needle, touching nothing, in a scene of `objects` objects whose world pulls the thread
    /// down with `gravity_mm_per_s2` (zero: standard gravity down -z).
    pub(in crate::sim) fn new(
        spec: NeedleDriverSpec,
        objects: usize,
        gravity_mm_per_s2: Vec3,
    ) -> Self {
        let tool_from_needle = spec.tool_from_needle();
        Self {
            tool_from_needle,
            jaws: Jaws::new_closed(RATCHET, JAW_OPEN_RAD),
            hold: NeedleHold::in_driver(tool_from_needle, &Isometry3::identity()),
            needle: NeedleTissue::new(spec.arc, spec.diameter_mm, objects),
            diameter_mm: spec.diameter_mm,
            thread: SutureThread::new(spec.thread, gravity_mm_per_s2),
            own_tool: None,
            let_go_pull_n: Vec3::zeros(),
            let_go_share: 0.0,
            last_pose: None,
            turn_work_mj: (0, 0.0),
            fall: NeedleFall::new(&spec.arc, spec.diameter_mm),
            gravity_mm_per_s2: if gravity_mm_per_s2 == Vec3::zeros() {
                Vec3::new(0.0, 0.0, -STANDARD_GRAVITY_MM_PER_S2)
            } else {
                gravity_mm_per_s2
            },
        }
    }

    /// The needle's tail (world, mm) and the way out of it behind the needle (unit), where the thread leaves.
    fn tail(&self, world_from_needle: &Isometry3<f32>) -> (Vec3, Vec3) {
        let tail = self.needle.arc().tail();
        (
            (world_from_needle * Point3::from(tail.point_mm)).coords,
            -(world_from_needle * tail.tangent),
        )
    }

    /// The jaws take this tick's input: opening, they let go of the needle where it is; closing on a loose
    /// needle within reach of the body, they take it there. Then the needle is placed where its holder holds
    /// it. Returns the points let go (1 for a needle let go, 0 else).
    fn follow_jaws(&mut self, sim: &Sim, t: usize, dt_s: f32) -> u32 {
        let tool = &sim.tools[t];
        let was_closed = self.jaws.closed();
        let input = tool.drive.jaw_input;
        let closed = self.jaws.update(
            &JawInput {
                buttons: u32::from(input.buttons & RELEASE_BUTTON == 0),
                ..input
            },
            dt_s,
        );
        let world_from_tool = pose_of(tool);
        let me = t as u16;
        self.own_tool = Some(me);
        let mut let_go = 0;
        self.let_go_share = (self.let_go_share - self.jaws.grip_rate_per_s() * dt_s).max(0.0);
        if was_closed && !closed {
            let pull_n = self.pull_on_holder_n();
            if self.hold.let_go(None) {
                let_go += 1;
                self.let_go_pull_n = pull_n;
                self.let_go_share = 1.0;
            }
            if let Some(thread) = &mut self.thread {
                let_go += u32::from(thread.release_grip(me));
            }
        } else if closed && !was_closed {
            let body = &tool.body.collider;
            let distance_mm = |p: &Vec3| body.distance_mm(&tool.position_mm, &tool.rotation, p);
            let reach_mm = 0.5 * self.diameter_mm + JAW_REACH_MM;
            let in_tissue = !self.needle.holes().is_empty();
            let took = self
                .hold
                .take(
                    None,
                    &world_from_tool,
                    self.needle.arc(),
                    distance_mm,
                    reach_mm,
                    in_tissue,
                )
                .is_some();
            // Without the needle, its own thread (not the node on the needle's tail, nor one a hole holds).
            if let (false, false, Some(thread)) =
                (took, self.hold.in_drivers_jaws(), &mut self.thread)
            {
                let reach_mm = 0.5 * THREAD_DIAMETER_MM + JAW_REACH_MM;
                thread.take_grip(me, &tool.position_mm, &tool.rotation, distance_mm, reach_mm);
            }
        }
        let gone = self.hold.place(&world_from_tool, |k| {
            sim.tools
                .get(usize::from(k))
                .filter(|tool| tool.active)
                .map(pose_of)
        });
        // A needle loose out of tissue falls and comes to rest on it (`needle_fall.rs`).
        if *self.hold.holder() == NeedleHolder::Loose && self.needle.holes().is_empty() {
            let pose = self.fall.step(
                self.hold.world_from_needle(),
                dt_s,
                &self.gravity_mm_per_s2,
                sim.objects.len(),
                needle_objects(sim),
                2 * sim.tools.len(),
                pushing_parts(sim, t, self.jaws.closed()),
            );
            self.hold.lie_at(pose);
        } else {
            self.fall.stop();
        }
        let_go + u32::from(gone)
    }

    /// The needle's pull on whoever holds it, world, N: its tip's and holes' forces and the thread's pull on
    /// its tail.
    fn pull_on_holder_n(&self) -> Vec3 {
        let thread = self
            .thread
            .as_ref()
            .map_or(Vec3::zeros(), SutureThread::pull_on_tail_n);
        self.needle.force_on_needle_n() + thread
    }
}

/// The button that opens the driver's ratchet while held.
const RELEASE_BUTTON: u32 = 1;
/// The ratchet's jaws as [`Jaws`] see them: "button held" means locked (the input is turned over).
const RATCHET: JawActivation = JawActivation::Button { mask: 1 };
/// How far the driver's jaws open, rad.
const JAW_OPEN_RAD: f32 = 30.0 * std::f32::consts::PI / 180.0;
/// Closing jaws take a loose needle lying this far outside their body, mm (past the wire's radius).
const JAW_REACH_MM: f32 = 1.0;

/// A tool's pose, world.
fn pose_of(tool: &SimTool) -> Isometry3<f32> {
    Isometry3::from_parts(Translation3::from(tool.position_mm), tool.rotation)
}

/// The objects a needle meets, as [`NeedleTissue`] asks for them (multi-rate objects step on their own
/// thread and are not met).
fn needle_objects<'a>(
    sim: &'a Sim,
) -> impl Fn(
    usize,
) -> Option<(
    &'a crate::collision::SurfaceCollider,
    &'a MassSpringModel,
    &'a TissueState,
)> + 'a {
    |o| {
        let object = sim.objects.get(o).filter(|o| o.lane.is_none())?;
        Some((&object.collider, &object.model, &object.state))
    }
}

/// The tool parts a thread meets: part `2 t` is tool `t`'s tip, `2 t + 1` its shaft (released tools, and a
/// tool without a shaft, have none).
fn tool_parts<'a>(
    sim: &'a Sim,
) -> impl Fn(usize) -> Option<crate::interaction::suture::ThreadTool<'a>> + 'a {
    |k| {
        let tool = sim.tools.get(k / 2).filter(|t| t.active)?;
        let collider = if k % 2 == 0 {
            &tool.body.collider
        } else {
            tool.body.shaft.as_ref()?
        };
        Some((collider, tool.position_mm, tool.rotation))
    }
}

/// The tool parts that push a loose needle: [`tool_parts`] but those of a tool whose jaws are open (they part
/// round the wire, as they must to take it; `own_closed`: the jaws of tool `own`, this driver, whose state is
/// its own while its hook runs).
fn pushing_parts<'a>(
    sim: &'a Sim,
    own: usize,
    own_closed: bool,
) -> impl Fn(usize) -> Option<crate::interaction::suture::ThreadTool<'a>> + 'a {
    let parts = tool_parts(sim);
    move |k| {
        let tool = k / 2;
        let closed = if tool == own {
            own_closed
        } else {
            sim.tools
                .get(tool)
                .and_then(|t| t.instrument_state.as_deref())
                .and_then(|i| i.jaws())
                .is_none_or(|jaws| jaws.closed())
        };
        parts(k).filter(|_| closed)
    }
}

impl Instrument for NeedleDriver {
    fn before_contacts(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        let tool = &sim.tools[t];
        if !tool.active {
            report.attachments_released += self.needle.release();
            if let Some(thread) = &mut self.thread {
                report.attachments_released += thread.release_holes(None);
                thread.lift();
            }
            self.jaws = Jaws::new_closed(RATCHET, JAW_OPEN_RAD);
            self.hold = NeedleHold::in_driver(self.tool_from_needle, &pose_of(tool));
            self.let_go_share = 0.0;
            return;
        }
        report.attachments_released += self.follow_jaws(sim, t, dt_s);
        let pose = *self.hold.world_from_needle();
        let events = self
            .needle
            .before_substeps(&pose, sim.objects.len(), needle_objects(sim));
        report.needle_holes_closed += events.holes_closed;
        // The holes the needle's tail left take the thread; the wire is thinner than the needle, and squeezed
        // by that much less.
        let thinner = THREAD_DIAMETER_MM / self.diameter_mm;
        for hole in self.needle.take_passed_tail() {
            let friction = sim
                .objects
                .get(usize::from(hole.point.object))
                .map_or(0.0, |o| o.puncture.needle_friction);
            // The squeeze is the wire's diameter pressed into the tissue's stiffness against a point.
            let stiffness_n_per_mm = hole.squeeze_n / self.diameter_mm;
            if let Some(thread) = &mut self.thread {
                thread.take_hole(
                    hole.point,
                    hole.squeeze_n * thinner,
                    friction,
                    stiffness_n_per_mm,
                );
            }
        }
    }

    fn after_substeps(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        if !sim.tools[t].active {
            return;
        }
        let pose = *self.hold.world_from_needle();
        let events = self
            .needle
            .after_substeps(&pose, needle_objects(sim), |o| sim.objects[o].puncture);
        report.punctures += events.punctures;
        let (tail_mm, away) = self.tail(&pose);
        if let Some(thread) = &mut self.thread {
            if thread.is_laid_out() {
                let wire = NeedleWire::new(pose, *self.needle.arc(), 0.5 * self.diameter_mm);
                thread.step(
                    dt_s,
                    &tail_mm,
                    2 * sim.tools.len(),
                    tool_parts(sim),
                    Some(&wire),
                    sim.objects.len(),
                    needle_objects(sim),
                );
            } else {
                thread.lay_out(&tail_mm, &away);
            }
        }
        // The turn's work through the needle's loads and the thread's pull on its tail, for the jaws that hold it
        // (the driver's, or a grasper's drawing it out along its curve).
        self.turn_work_mj = (0, 0.0);
        let holder = match self.hold.holder() {
            NeedleHolder::Driver { .. } => Some(t as u16),
            NeedleHolder::Tool { tool, .. } => Some(*tool),
            NeedleHolder::Loose => None,
        };
        let held = holder.and_then(|h| sim.tools.get(usize::from(h)).map(|tool| (h, tool)));
        if let Some((h, tool)) = held {
            let step_mm = tool.position_mm - tool.drive.last_position_mm;
            if let Some((before_holder, before)) = self.last_pose
                && before_holder == h
            {
                let tail_pull_n = self
                    .thread
                    .as_ref()
                    .map_or(Vec3::zeros(), |th| th.pull_on_tail_n());
                let work = self
                    .needle
                    .turn_work_mj(&before, &pose, &step_mm, &tail_pull_n);
                self.turn_work_mj = (h, if work.is_finite() { work } else { 0.0 });
            }
            self.last_pose = Some((h, pose));
        } else {
            self.last_pose = None;
        }
    }

    fn attached_nodes(&self, object: usize) -> &[u32] {
        self.needle.held_nodes(object)
    }

    /// The needle is held where its holder put it this tick (tools do not move within a tick).
    fn hold(
        &self,
        object: usize,
        _position_mm: &Vec3,
        _rotation: &UnitQuaternion<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        self.needle
            .hold(object, self.hold.world_from_needle(), model, state);
    }

    fn object_reset(&mut self, object: usize) -> u32 {
        let thread = self
            .thread
            .as_mut()
            .map_or(0, |t| t.release_holes(Some(object)));
        self.needle.object_reset(object) + thread
    }

    fn pulls_tissue(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.holes().is_empty())
    }

    fn add_forces(&self, object: usize, model: &MassSpringModel, state: &mut TissueState) {
        let Some(thread) = &self.thread else {
            return;
        };
        for hole in thread
            .holes()
            .iter()
            .chain(thread.tracks())
            .filter(|h| usize::from(h.point.object()) == object)
        {
            let Some(now_mm) = hole.point.position_mm(model, state) else {
                continue;
            };
            let pull = hole.pull_on_tissue_at_n(&now_mm);
            hole.point
                .spread(model, &pull, &mut state.external_forces_n);
        }
    }

    fn topology_changed(&mut self, object: usize, model: &MassSpringModel) {
        self.needle.topology_changed(object, model);
    }

    fn subdivided(
        &mut self,
        object: usize,
        model: &MassSpringModel,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) {
        self.needle.subdivided(object, model, remap);
        if let Some(thread) = &mut self.thread {
            thread.subdivided(object, remap);
        }
    }

    /// The needle's pull while the driver's own jaws hold it (fading as they open once they let it go), and
    /// the thread's while they hold the thread.
    fn force_on_tool_n(&self) -> Vec3 {
        let needle = if self.hold.in_drivers_jaws() {
            self.pull_on_holder_n()
        } else {
            self.let_go_pull_n * self.let_go_share
        };
        let grip = self
            .thread
            .as_ref()
            .zip(self.own_tool)
            .and_then(|(thread, me)| thread.grip_of(me))
            .map_or(Vec3::zeros(), |grip| grip.pull_n());
        needle + grip
    }

    fn mark_output(&self, out: &mut ToolOutput) {
        out.jaws_closed = self.jaws.closed();
        out.jaw_angle_rad = self.jaws.angle_rad();
    }

    fn jaws(&self) -> Option<&Jaws> {
        Some(&self.jaws)
    }

    fn needle_hold(&self) -> Option<&NeedleHold> {
        Some(&self.hold)
    }

    fn take_needle(
        &mut self,
        taker: u16,
        world_from_taker: &Isometry3<f32>,
        distance_mm: &dyn Fn(&Vec3) -> f32,
        reach_mm: f32,
    ) -> bool {
        let in_tissue = !self.needle.holes().is_empty();
        self.hold
            .take(
                Some(taker),
                world_from_taker,
                self.needle.arc(),
                distance_mm,
                reach_mm + 0.5 * self.diameter_mm,
                in_tissue,
            )
            .is_some()
    }

    fn let_go_of_needle(&mut self, taker: u16) -> bool {
        self.hold.let_go(Some(taker))
    }

    fn needle_pull_on_n(&self, holder: u16) -> Option<Vec3> {
        self.hold.held_by(holder).then(|| self.pull_on_holder_n())
    }

    fn turn_work_mj(&self, tool: u16) -> f64 {
        if self.turn_work_mj.0 == tool {
            self.turn_work_mj.1
        } else {
            0.0
        }
    }

    fn loads_tool(&self) -> bool {
        let needle_in_tissue =
            !matches!(self.needle.phase(), TipPhase::Free) || !self.needle.holes().is_empty();
        let needle_pulls = if self.hold.in_drivers_jaws() {
            needle_in_tissue || self.thread.as_ref().is_some_and(|t| !t.holes().is_empty())
        } else {
            self.let_go_share > 0.0
        };
        let grips_thread = self
            .thread
            .as_ref()
            .zip(self.own_tool)
            .is_some_and(|(thread, me)| thread.grip_of(me).is_some());
        needle_pulls || grips_thread
    }

    fn held_points(&self) -> u16 {
        u16::from(matches!(self.needle.phase(), TipPhase::Pressing { .. }))
    }

    fn needle(&self) -> Option<&NeedleTissue> {
        Some(&self.needle)
    }

    fn thread(&self) -> Option<&SutureThread> {
        self.thread.as_ref()
    }

    fn thread_mut(&mut self) -> Option<&mut SutureThread> {
        self.thread.as_mut()
    }
}
