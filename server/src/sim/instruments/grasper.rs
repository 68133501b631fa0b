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
}

impl Grasper {
    /// Open jaws holding nothing, for a scene of `objects` objects.
    pub(in crate::sim) fn new(spec: GraspSpec, objects: usize) -> Self {
        Self {
            jaws: Jaws::new(spec.activation, spec.open_angle_rad),
            grasp: Grasp::new(spec, objects),
            pull_n: Vec3::zeros(),
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
        if grasp.closing_edge(closed) {
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
                GraspEvent::Took(_) => report.grasps_taken += 1,
                _ => report.grasps_missed += 1,
            }
        } else if !closed && !grasp.attachments().is_empty() {
            report.attachments_released += released(grasp.release());
        }
        let before = grasp.slipped();
        for (o, object) in sim.objects.iter().enumerate() {
            if !grasp.attached_nodes(o).is_empty() {
                self.pull_n += grasp.settle(o, &object.model, &object.state);
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
