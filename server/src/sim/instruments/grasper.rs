//! A grasper: jaws that close on tissue take hold of it as attachments, hold it each substep, and let it go
//! when they open or it slips.
//!
//! Owns: [`Grasper`] (its jaws, its grasp, the pull it felt). Must not: integrate (the tick's substeps call
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
        }
    }
}

impl Instrument for Grasper {
    /// The jaws take this tick's input: on closing, take hold of the tissue the body touches (both jaws must
    /// touch it); on opening, let go; while holding, measure the pull and let slipping points go.
    fn after_substeps(&mut self, sim: &mut Sim, t: usize, dt_s: f32, report: &mut StepReport) {
        let tool = &sim.tools[t];
        let (jaws, grasp) = (&mut self.jaws, &mut self.grasp);
        self.pull_n = Vec3::zeros();
        if !tool.active {
            jaws.open();
            grasp.closing_edge(false);
            if !grasp.attachments().is_empty() {
                report.attachments_released += released(grasp.release());
            }
            return;
        }
        let closed = jaws.update(&tool.drive.jaw_input, dt_s);
        let mut took = false;
        // Jaws that close again while they still hold (opening, not yet open) keep their hold.
        if grasp.closing_edge(closed) && grasp.attachments().is_empty() {
            grasp.start_take();
            let bite_mm = grasp.spec().bite_mm;
            // A multi-rate object is not grasped (its nodes move on its own thread).
            for (o, object) in sim
                .objects
                .iter()
                .enumerate()
                .filter(|(_, o)| o.lane.is_none())
            {
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
            if !grasp.attached_nodes(o).is_empty() {
                self.pull_n += grasp.settle(o, &object.model, &object.state);
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

    fn force_on_tool_n(&self) -> Vec3 {
        self.pull_n
    }

    fn held_points(&self) -> u16 {
        self.grasp.attachments().len() as u16
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
