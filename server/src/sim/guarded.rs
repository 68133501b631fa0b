//! The tick's guarded substeps: every every-tick object integrated in lockstep (ties coupling them), the
//! tissue pushed out of each tool and held in each grasp every substep, judged by the guard.
//!
//! Owns: the tick's [`Stepped`] ([`TickStepper`]), the substeps, the assessment and the tools' work
//! allowance. Must not: contain a fault (the step does, on the guard's verdict).

use crate::interaction::ToolBody;
use crate::tissue::{Stepped, Vec3, guard};

use super::*;

/// The tick's every-tick objects as one [`Stepped`]: the guarded step's substeps, judgement and restore.
pub(super) struct TickStepper<'a> {
    pub(super) sim: &'a mut Sim,
    pub(super) report: &'a mut StepReport,
}

impl Stepped for TickStepper<'_> {
    fn integrate(&mut self, h_s: f32, substeps: u32) {
        self.sim.run_substeps(h_s, substeps, self.report);
    }

    fn judge(&mut self) -> (bool, f64) {
        self.sim.assess()
    }

    fn restore(&mut self) {
        for object in self.sim.objects.iter_mut().filter(|o| o.lane.is_none()) {
            match &object.region {
                Some(region) => object
                    .guard
                    .restore_nodes(&mut object.state, region.active_nodes()),
                None => object.guard.restore(&mut object.state),
            }
        }
    }
}

impl Sim {
    /// The guard's measurements over every object: whether any is broken, and the mechanical energy of the
    /// objects that are not region-tracked plus the ties', N mm (a region-tracked object is judged by the
    /// absolute tests over its active nodes only: a whole-object energy pass would cost what region tracking
    /// saves).
    pub(super) fn assess(&self) -> (bool, f64) {
        let mut broken = false;
        let mut energy = 0.0;
        // A multi-rate object's step is judged on its own thread.
        for object in self.objects.iter().filter(|o| o.lane.is_none()) {
            match &object.region {
                Some(region) => {
                    broken |= object.guard.broken_nodes(
                        &object.model,
                        &object.state,
                        region.active_nodes(),
                    );
                }
                None => {
                    let assessment = object.guard.assess(&object.model, &object.state);
                    broken |= assessment.broken;
                    energy += assessment.energy_n_mm;
                }
            }
        }
        energy += self.tissue_contact_energy_n_mm();
        for tie in &self.ties {
            if let (Some(a), Some(b)) = (
                self.objects.get(tie.object_a),
                self.objects.get(tie.object_b),
            ) {
                energy += tie.energy_n_mm(&a.state, &b.state);
            }
        }
        (broken, energy)
    }

    /// The most work the tools can have done on the tissue this tick, N mm
    /// ([`guard::tool_work_allowance_n_mm`] of each active tool).
    pub(super) fn tool_work_allowance_n_mm(&self) -> f64 {
        self.tools
            .iter()
            .filter(|t| t.active)
            .map(|t| {
                let travel_mm = guard::tool_travel_mm(
                    t.drive.was_active,
                    &t.position_mm,
                    &t.drive.last_position_mm,
                    t.body.reach_mm,
                );
                guard::tool_work_allowance_n_mm(t.max_force_n, travel_mm)
            })
            .sum()
    }

    /// `substeps` steps of `h` for every object: ties, integrate, push out of the tools.
    pub(super) fn run_substeps(&mut self, h: f32, substeps: u32, report: &mut StepReport) {
        let pulls = self.tools.iter().any(|t| t.pulls_tissue());
        let touching = self.tissue_contacts_watched();
        for _ in 0..substeps {
            if !self.ties.is_empty() || pulls || touching {
                // Region-tracked objects are never tied (refused at build) and not pulled: a thread's holes in one
                // hold the thread but do not pull the tissue (docs/suturing.md, the holes' known gaps). Their
                // external forces stay zero.
                for object in self.objects.iter_mut().filter(|o| o.region.is_none()) {
                    object.state.external_forces_n.fill(Vec3::zeros());
                }
                for tie in &self.ties {
                    if let Ok([a, b]) = self.objects.get_disjoint_mut([tie.object_a, tie.object_b])
                    {
                        tie.accumulate(&mut a.state, &mut b.state);
                    }
                }
                super::tissue_contact::accumulate_tissue_contacts(
                    &mut self.pairs,
                    &mut self.objects,
                    h,
                );
                if pulls {
                    for (o, object) in self.objects.iter_mut().enumerate() {
                        if object.region.is_some() || object.lane.is_some() {
                            continue;
                        }
                        for tool in self.tools.iter().filter(|t| t.pulls_tissue()) {
                            tool.add_forces(o, &object.model, &mut object.state);
                        }
                    }
                }
            }
            for (o, object) in self.objects.iter_mut().enumerate() {
                if object.lane.is_some() {
                    continue;
                }
                if object.pins_held {
                    // Implicit Euler: push out and grasp first, then solve with the held nodes pinned where
                    // the tools hold them (see `TissueState::pinned`), so the rest of the tissue answers them there.
                    hold_in_tools(&mut self.tools, o, object);
                    object.state.pinned.clear();
                    for tool in self.tools.iter().filter(|t| t.active) {
                        object
                            .state
                            .pinned
                            .extend_from_slice(&tool.contacts[o].held);
                        object
                            .state
                            .pinned
                            .extend_from_slice(tool.attached_nodes(o));
                    }
                    object.state.pinned.sort_unstable();
                    object.state.pinned.dedup();
                    report.solver_iterations += object.integrate(h);
                } else {
                    report.solver_iterations += object.integrate(h);
                    hold_in_tools(&mut self.tools, o, object);
                }
            }
            report.substeps += self.objects.iter().filter(|o| o.lane.is_none()).count() as u32;
        }
    }
}

/// Push object `o`'s tissue out of every active tool and hold what each instrument holds (a grasper's jaws).
pub(super) fn hold_in_tools(tools: &mut [SimTool], o: usize, object: &mut SimObject) {
    for tool in tools.iter_mut().filter(|t| t.active) {
        let grasped = tool
            .instrument_state
            .as_ref()
            .map_or(&[][..], |i| i.attached_nodes(o));
        let half_mm = tool.shaft_spec.map_or(0.0, |s| 0.5 * s.length_mm);
        let body = ToolBody::posed(
            &tool.body.collider,
            tool.body.shaft.as_ref().map(|s| (s, half_mm)),
            tool.position_mm,
            tool.rotation,
        );
        tool.contacts[o].project(
            &body,
            &object.model,
            &mut object.state,
            grasped,
            object.friction,
        );
        if let Some(instrument) = &tool.instrument_state {
            instrument.hold(
                o,
                &tool.position_mm,
                &tool.rotation,
                &object.model,
                &mut object.state,
            );
        }
    }
}
