//! A needle driver: jaws holding a curved needle whose tip tents tissue, punctures it and passes through it.
//!
//! Owns: [`NeedleDriver`] (the needle's pose on the tool and its relation to the tissue,
//! [`NeedleTissue`]). The body (the jaws, the tool's `shape`) probes as any body does; the needle's tip is
//! a point that presses a surface point, and the needle's own body does not push tissue: the holes it passes
//! through hold it on its path (`interaction/suture/hole.rs`).
//!
//! Stages: before the contacts, the tip's path since the last tick is tested against the surfaces (a free tip
//! meets one, a tip inside an object reaches its far wall) and the holes the needle left close; each substep
//! the pressed point is held at the tip and the holes hold the needle on its path; after the substeps the
//! holes' forces are read (they stick or slide) and the tip punctures, skates or lifts off.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};

use crate::interaction::suture::{
    NeedleDriverSpec, NeedleTissue, SutureThread, THREAD_DIAMETER_MM, TipPhase,
};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

use super::super::instrument::Instrument;
use super::super::*;

/// A needle driver's state between ticks.
#[derive(Debug)]
pub(in crate::sim) struct NeedleDriver {
    tool_from_needle: Isometry3<f32>,
    needle: NeedleTissue,
    /// The needle's wire diameter, mm.
    diameter_mm: f32,
    /// The thread on the needle's tail (None: a needle without one).
    thread: Option<SutureThread>,
}

impl NeedleDriver {
    /// Jaws holding the needle, touching nothing, in a scene of `objects` objects whose world pulls the thread
    /// down with `gravity_mm_per_s2` (zero: standard gravity down -z).
    pub(in crate::sim) fn new(
        spec: NeedleDriverSpec,
        objects: usize,
        gravity_mm_per_s2: Vec3,
    ) -> Self {
        Self {
            tool_from_needle: spec.tool_from_needle(),
            needle: NeedleTissue::new(spec.arc, spec.diameter_mm, objects),
            diameter_mm: spec.diameter_mm,
            thread: SutureThread::new(spec.thread, gravity_mm_per_s2),
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

    fn world_from_needle(
        &self,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
    ) -> Isometry3<f32> {
        Isometry3::from_parts(Translation3::from(*position_mm), *rotation) * self.tool_from_needle
    }
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

impl Instrument for NeedleDriver {
    fn before_contacts(&mut self, sim: &mut Sim, t: usize, _dt_s: f32, report: &mut StepReport) {
        let tool = &sim.tools[t];
        if !tool.active {
            report.attachments_released += self.needle.release();
            if let Some(thread) = &mut self.thread {
                report.attachments_released += thread.release_holes(None);
                thread.lift();
            }
            return;
        }
        let pose = self.world_from_needle(&tool.position_mm, &tool.rotation);
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
        let tool = &sim.tools[t];
        if !tool.active {
            return;
        }
        let pose = self.world_from_needle(&tool.position_mm, &tool.rotation);
        let events = self
            .needle
            .after_substeps(&pose, needle_objects(sim), |o| sim.objects[o].puncture);
        report.punctures += events.punctures;
        let (tail_mm, away) = self.tail(&pose);
        if let Some(thread) = &mut self.thread {
            if thread.is_laid_out() {
                thread.step(
                    dt_s,
                    &tail_mm,
                    2 * sim.tools.len(),
                    tool_parts(sim),
                    sim.objects.len(),
                    needle_objects(sim),
                );
            } else {
                thread.lay_out(&tail_mm, &away);
            }
        }
    }

    fn attached_nodes(&self, object: usize) -> &[u32] {
        self.needle.held_nodes(object)
    }

    fn hold(
        &self,
        object: usize,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        let pose = self.world_from_needle(position_mm, rotation);
        self.needle.hold(object, &pose, model, state);
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

    fn force_on_tool_n(&self) -> Vec3 {
        let thread = self
            .thread
            .as_ref()
            .map_or(Vec3::zeros(), SutureThread::pull_on_tail_n);
        self.needle.force_on_needle_n() + thread
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
