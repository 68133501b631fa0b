//! A grasper: jaws that close on tissue take hold of it as attachments, hold it each substep, and let it go
//! when they open or it slips. Jaws that close on a suture thread (a node of another tool's thread within their
//! bite) take that instead (`interaction/suture/thread_grip.rs`: the thread holds the grip and steps it), and
//! jaws that close on a loose suture needle (let go by its driver, held in the tissue by its holes) take the
//! needle before either: they hold it where it lies and draw it through, and feel its pull
//! (`interaction/suture/needle_hold.rs`).
//!
//! Owns: [`Grasper`] (its jaws, its grasp, the thread it holds, the pulls it felt). Must not: integrate (the tick's substeps call
//! [`Instrument::hold`]).

use nalgebra::UnitQuaternion;

use crate::interaction::{Grasp, GraspEvent, GraspSpec, Jaws};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

use super::super::instrument::Instrument;
use super::super::*;

/// A grasper's state between ticks.
#[derive(Debug)]
pub(in crate::sim) struct Grasper {
    jaws: Jaws,
    grasp: Grasp,
    /// The tissue's pull on the tool through the grasp at the end of the last tick, N.
    pull_n: Vec3,
    /// Since the take, the grasp's share of the force on the tool, 0..1, rising as the jaws close: the rest
    /// is `handed_over_n`. The points are held rigidly from the take; what the hand feels passes from the
    /// body's push on them to the grasp's pull on them as fast as the jaws close, not in one tick.
    take_share: f32,
    /// The body's push through the points it handed to the grasp, at the take, N.
    handed_over_n: Vec3,
    /// The tool whose suture thread the jaws hold (`interaction/suture/thread_grip.rs`), if any.
    thread_of: Option<usize>,
    /// The thread's pull on the jaws, N.
    thread_pull_n: Vec3,
    /// The tool whose needle the jaws hold, if any.
    needle_of: Option<usize>,
    /// The needle's pull on the jaws, N.
    needle_pull_n: Vec3,
}

impl Grasper {
    /// Open jaws holding nothing, for a scene of `objects` objects.
    pub(in crate::sim) fn new(spec: GraspSpec, objects: usize) -> Self {
        Self {
            jaws: Jaws::new(spec.activation, spec.open_angle_rad),
            grasp: Grasp::new(spec, objects),
            pull_n: Vec3::zeros(),
            take_share: 1.0,
            handed_over_n: Vec3::zeros(),
            thread_of: None,
            thread_pull_n: Vec3::zeros(),
            needle_of: None,
            needle_pull_n: Vec3::zeros(),
        }
    }
}

impl Instrument for Grasper {
    /// The jaws take this tick's input: on closing, take hold of a suture thread within their bite, else of
    /// the tissue the body touches (both jaws must touch it); on opening, let go; while holding, measure the
    /// pull and let slipping points go.
    fn after_substeps(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        self.pull_n = Vec3::zeros();
        self.thread_pull_n = Vec3::zeros();
        self.needle_pull_n = Vec3::zeros();
        if !sim.tools[t].active {
            self.jaws.open();
            self.grasp.closing_edge(false);
            if !self.grasp.attachments().is_empty() {
                report.attachments_released += released(self.grasp.release());
            }
            report.attachments_released += u32::from(self.let_go_of_thread(sim, t));
            report.attachments_released += u32::from(self.let_go_of_needle(sim, t));
            return;
        }
        let closed = self.jaws.update(&sim.tools[t].drive.jaw_input, dt_s);
        let closing = self.grasp.closing_edge(closed);
        // Jaws that close again while they still hold (opening, not yet open) keep their hold.
        let free = self.grasp.attachments().is_empty()
            && self.thread_of.is_none()
            && self.needle_of.is_none();
        if closing && free {
            self.needle_of = take_needle(sim, t, self.grasp.spec().bite_mm);
            if self.needle_of.is_none() {
                self.thread_of = take_thread(sim, t, self.grasp.spec().bite_mm);
            }
            if self.needle_of.is_some() || self.thread_of.is_some() {
                report.grasps_taken += 1;
            }
        }
        self.hold_thread(sim, t, closed, report);
        self.hold_needle(sim, t, closed, report);
        let tool = &sim.tools[t];
        let (jaws, grasp) = (&mut self.jaws, &mut self.grasp);
        let mut took = false;
        if closing && free && self.thread_of.is_none() && self.needle_of.is_none() {
            grasp.start_take();
            let bite_mm = grasp.spec().bite_mm;
            // A multi-rate object is taken on its latest finished step (its `state`); its step job holds
            // the points from the next launch on (crate::multirate).
            for (o, object) in sim.objects.iter().enumerate() {
                // The nodes the body holds (on its surface) and free surface nodes within the bite of it:
                // the closing jaws draw them in.
                for &node in &tool.contacts[o].candidates {
                    let Some(x) = object.state.positions_mm.get(node as usize) else {
                        continue;
                    };
                    if tool
                        .body
                        .collider
                        .distance_mm(&tool.position_mm, &tool.rotation, x)
                        <= bite_mm + BITE_TOLERANCE_MM
                    {
                        grasp.offer(
                            o,
                            std::slice::from_ref(&node),
                            &tool.position_mm,
                            &tool.rotation,
                            &object.model,
                            &object.state,
                        );
                    }
                }
            }
            match grasp.finish_take() {
                GraspEvent::Took(_) => {
                    // Taken at once, at full grip, at their places on the jaws; the force the hand feels
                    // passes from the body's push on them to their pull over the jaws' closing time.
                    grasp.set_grip(1.0, 1.0);
                    self.take_share = 0.0;
                    took = true;
                    self.handed_over_n = handed_over_n(sim, t, grasp);
                    report.grasps_taken += 1;
                }
                _ => report.grasps_missed += 1,
            }
        }
        // Opening jaws let go progressively: the grip falls as they open, so the force at the hand falls no
        // faster than the jaws move; jaws that close again before they are open hold on.
        let target = if closed { 1.0 } else { jaws.grip() };
        grasp.set_grip(target, jaws.grip_rate_per_s() * dt_s);
        if !closed && grasp.grip() <= 0.0 && !grasp.attachments().is_empty() {
            report.attachments_released += released(grasp.release());
        }
        let before = grasp.slipped();
        for (o, object) in sim.objects.iter().enumerate() {
            if grasp.attached_nodes(o).is_empty() {
                continue;
            }
            match &object.lane {
                // Held on its own thread: its latest step's grasp model at the jaws' place now (the sim
                // settled its pulls, and let the slipping points go, at the hand-off).
                Some(lane) => {
                    self.pull_n += lane.contact(t).grasp_force_at(&tool.position_mm) * grasp.grip();
                }
                None => self.pull_n += grasp.settle(o, &object.model, &object.state),
            }
        }
        if self.take_share < 1.0 {
            if grasp.attachments().is_empty() {
                self.take_share = 1.0;
            } else if took {
                // This tick's contacts still hold the taken points and report their push: the grasp adds
                // nothing until the next tick (counting both stepped the force by their push).
                self.pull_n = Vec3::zeros();
            } else {
                let share = self.take_share;
                self.pull_n = self.pull_n * share + self.handed_over_n * (1.0 - share);
                self.take_share = (share + jaws.grip_rate_per_s() * dt_s).min(1.0);
            }
        }
        report.attachments_slipped += (grasp.slipped() - before) as u32;
    }

    fn attached_nodes(&self, object: usize) -> &[u32] {
        self.grasp.attached_nodes(object)
    }

    fn hold(
        &self,
        object: usize,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        self.grasp.hold(object, position_mm, rotation, model, state);
    }

    fn object_reset(&mut self, object: usize) -> u32 {
        if self.grasp.attached_nodes(object).is_empty() {
            return 0;
        }
        released(self.grasp.release())
    }

    fn topology_changed(&mut self, object: usize, model: &MassSpringModel) {
        self.grasp.topology_changed(object, model);
    }

    fn subdivided(
        &mut self,
        object: usize,
        model: &MassSpringModel,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) {
        self.grasp.subdivided(object, model, remap);
    }

    fn force_on_tool_n(&self) -> Vec3 {
        self.pull_n + self.thread_pull_n + self.needle_pull_n
    }

    fn held_points(&self) -> u16 {
        self.grasp.attachments().len() as u16
    }

    fn loads_tool(&self) -> bool {
        self.thread_of.is_some() || self.needle_of.is_some()
    }

    fn mark_output(&self, out: &mut ToolOutput) {
        out.jaws_closed = self.jaws.closed();
        out.jaw_angle_rad = self.jaws.angle_rad();
    }

    fn jaws(&self) -> Option<&Jaws> {
        Some(&self.jaws)
    }

    fn grasp(&self) -> Option<&Grasp> {
        Some(&self.grasp)
    }

    fn grasp_mut(&mut self) -> Option<&mut Grasp> {
        Some(&mut self.grasp)
    }
}

impl Grasper {
    /// While the jaws hold a thread: read its pull, notice it slipped out, let go of it once the jaws are open
    /// (jaws that close again before they are open keep it).
    fn hold_thread(&mut self, sim: &mut Sim, t: usize, closed: bool, report: &mut StepReport) {
        let Some(k) = self.thread_of else {
            return;
        };
        if !closed && self.jaws.grip() <= 0.0 {
            report.attachments_released += u32::from(self.let_go_of_thread(sim, t));
            return;
        }
        let grip = sim
            .tools
            .get(k)
            .and_then(|tool| tool.instrument_state.as_ref())
            .and_then(|instrument| instrument.thread())
            .and_then(|thread| thread.grip_of(t as u16));
        match grip {
            Some(grip) => self.thread_pull_n = grip.pull_n(),
            None => {
                // It slipped out of the jaws (or its needle driver let it go).
                self.thread_of = None;
                report.attachments_slipped += 1;
            }
        }
    }

    /// While the jaws hold a needle: read its pull, notice it left them (its driver took it back, or left),
    /// let go of it once the jaws are open.
    fn hold_needle(&mut self, sim: &mut Sim, t: usize, closed: bool, report: &mut StepReport) {
        let Some(k) = self.needle_of else {
            return;
        };
        if !closed && self.jaws.grip() <= 0.0 {
            report.attachments_released += u32::from(self.let_go_of_needle(sim, t));
            return;
        }
        let pull = sim
            .tools
            .get(k)
            .and_then(|tool| tool.instrument_state.as_ref())
            .and_then(|instrument| instrument.needle_pull_on_n(t as u16));
        match pull {
            Some(pull) if pull.iter().all(|c| c.is_finite()) => self.needle_pull_n = pull,
            Some(_) => {}
            // Taken from these jaws (hand to hand): they hold nothing now.
            None => {
                self.needle_of = None;
                self.needle_pull_n = Vec3::zeros();
            }
        }
    }

    /// Let go of the needle the jaws hold. Returns whether they held one.
    fn let_go_of_needle(&mut self, sim: &mut Sim, t: usize) -> bool {
        let Some(k) = self.needle_of.take() else {
            return false;
        };
        self.needle_pull_n = Vec3::zeros();
        sim.tools
            .get_mut(k)
            .and_then(|tool| tool.instrument_state.as_mut())
            .is_some_and(|instrument| instrument.let_go_of_needle(t as u16))
    }

    /// Let go of the thread the jaws hold. Returns whether they held one.
    fn let_go_of_thread(&mut self, sim: &mut Sim, t: usize) -> bool {
        let Some(k) = self.thread_of.take() else {
            return false;
        };
        self.thread_pull_n = Vec3::zeros();
        sim.tools
            .get_mut(k)
            .and_then(|tool| tool.instrument_state.as_mut())
            .and_then(|instrument| instrument.thread_mut())
            .is_some_and(|thread| thread.release_grip(t as u16))
    }
}

/// Tool `t`'s closing jaws take the first suture thread (in tool order) with a node within `bite_mm` and the
/// thread's radius of its body. Returns the tool whose thread it took. No allocation.
fn take_thread(sim: &mut Sim, t: usize, bite_mm: f32) -> Option<usize> {
    let reach_mm =
        bite_mm + 0.5 * crate::interaction::suture::THREAD_DIAMETER_MM + BITE_TOLERANCE_MM;
    for k in (0..sim.tools.len()).filter(|&k| k != t) {
        let Ok([jaws, other]) = sim.tools.get_disjoint_mut([t, k]) else {
            continue;
        };
        let Some(thread) = other
            .instrument_state
            .as_mut()
            .and_then(|instrument| instrument.thread_mut())
        else {
            continue;
        };
        let (position_mm, rotation) = (jaws.position_mm, jaws.rotation);
        let distance_mm = |p: &Vec3| jaws.body.collider.distance_mm(&position_mm, &rotation, p);
        if thread
            .take_grip(t as u16, &position_mm, &rotation, distance_mm, reach_mm)
            .is_some()
        {
            return Some(k);
        }
    }
    None
}

/// Tool `t`'s closing jaws take the first suture needle (in tool order) with a point within `bite_mm` of their
/// body, loose or in other jaws (hand to hand: `NeedleHold::take`). Returns the tool whose needle they took. No
/// allocation.
fn take_needle(sim: &mut Sim, t: usize, bite_mm: f32) -> Option<usize> {
    let reach_mm = bite_mm + BITE_TOLERANCE_MM;
    let world_from_jaws = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::from(sim.tools[t].position_mm),
        sim.tools[t].rotation,
    );
    for k in (0..sim.tools.len()).filter(|&k| k != t) {
        let Ok([jaws, other]) = sim.tools.get_disjoint_mut([t, k]) else {
            continue;
        };
        let Some(instrument) = other.instrument_state.as_mut() else {
            continue;
        };
        let (position_mm, rotation) = (jaws.position_mm, jaws.rotation);
        let distance_mm = |p: &Vec3| jaws.body.collider.distance_mm(&position_mm, &rotation, p);
        if instrument.take_needle(t as u16, &world_from_jaws, &distance_mm, reach_mm) {
            return Some(k);
        }
    }
    None
}

/// How many points a release let go.
fn released(event: GraspEvent) -> u32 {
    match event {
        GraspEvent::Released(n) => u32::from(n),
        _ => 0,
    }
}

/// The push tool `t`'s body felt, at the end of this tick's substeps, through the nodes `grasp` now holds:
/// each held node's push along the tool normal and its friction, as `ProbeContacts::reaction_force_n`
/// counts it. No allocation.
fn handed_over_n(sim: &Sim, t: usize, grasp: &Grasp) -> Vec3 {
    let tool = &sim.tools[t];
    let mut force = Vec3::zeros();
    for (o, object) in sim.objects.iter().enumerate() {
        let taken = grasp.attached_nodes(o);
        let Some(contacts) = tool.contacts.get(o) else {
            continue;
        };
        if taken.is_empty() || contacts.held.is_empty() {
            continue;
        }
        let (model, state) = (&object.model, &object.state);
        let pressure = model.pressure_n_per_mm2(&state.positions_mm);
        for (&node, dir) in contacts.held.iter().zip(&contacts.normals) {
            if taken.binary_search(&node).is_err() {
                continue;
            }
            let f = model.node_force(
                node as usize,
                &state.positions_mm,
                &state.velocities_mm_s,
                pressure,
            );
            crate::interaction::add_node_reaction(&mut force, &f, dir, object.friction);
        }
    }
    force
}
