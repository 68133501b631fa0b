//! Grasping: jaws that close on tissue take hold of it as attachments, hold it each substep, and let it go
//! when they open or it slips.
//!
//! Owns: [`Sim::update_grasp`]. Must not: integrate.

use crate::interaction::GraspEvent;
use crate::tissue::Vec3;

use super::*;

impl Sim {
    /// A grasper's jaws take this tick's input: on closing, take hold of the tissue the body touches (both
    /// jaws must touch it); on opening, let go; while holding, measure the pull and let slipping points go.
    pub(super) fn update_grasp(&mut self, t: usize, dt_s: f32, report: &mut StepReport) {
        let tool = &mut self.tools[t];
        let (Some(jaws), Some(grasp)) = (&mut tool.jaws, &mut tool.grasp) else {
            return;
        };
        tool.grasp_force_n = Vec3::zeros();
        if !tool.active {
            jaws.open();
            grasp.closing_edge(false);
            if !grasp.attachments().is_empty() {
                report.attachments_released += grasp_released(grasp.release());
            }
            return;
        }
        let closed = jaws.update(&tool.jaw_input, dt_s);
        if grasp.closing_edge(closed) {
            grasp.start_take();
            let bite_mm = grasp.spec().bite_mm;
            // A multi-rate object is not grasped (its nodes move on its own thread).
            for (o, object) in self
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
            report.attachments_released += grasp_released(grasp.release());
        }
        let before = grasp.slipped();
        for (o, object) in self.objects.iter().enumerate() {
            if !grasp.attached_nodes(o).is_empty() {
                tool.grasp_force_n += grasp.settle(o, &object.model, &object.state);
            }
        }
        report.attachments_slipped += (grasp.slipped() - before) as u32;
    }
}

/// How many points a release let go.
pub(super) fn grasp_released(event: GraspEvent) -> u32 {
    match event {
        GraspEvent::Released(n) => u32::from(n),
        _ => 0,
    }
}
