//! The deterministic simulation core: objects, tools, and one fixed-dt step. Time and dt come in as arguments,
//! so tests run on virtual time and a recording replays exactly. Must not: touch zenoh, threads or wall-clock
//! time.
//!
//! The tick's pipeline ([`Sim::step`], here), in order, with the file that runs each stage:
//! 1. the last tick's tail if nobody ran it ([`Sim::finish_tick`], here); the tools follow their device poses
//!    through their couplings (`drive.rs`); instruments act before contacts are found (blades cut what they
//!    swept: `instruments/scalpel.rs`, `instruments/scissors.rs`, opening seams through `topology.rs`);
//! 2. multi-rate objects hand back their finished step and launch the next ([`crate::multirate`]); the broad
//!    phase; where one object's surface meets another's (`tissue_contact.rs`); regions of deformation follow
//!    the contacts (here);
//! 3. the guarded substeps: integrate every every-tick object (ties and tissue-tissue contact pulling on them),
//!    push the tissue out of the tools, hold what the jaws hold, retry with halved substeps on the guard's
//!    verdict (`guarded.rs`, over
//!    [`crate::tissue::guarded_step`]); a fault still there at the smallest substep is contained (here);
//! 4. overstretched tissue tears (`tearing.rs`, through `topology.rs`); instruments act on the step's result (grasps
//!    take hold, slip and let go: `instruments/grasper.rs`; the needle and its thread step); a thread pulled
//!    past its tissue's limit tears it at its holes (`hole_tearing.rs`);
//! 5. per tool: its instrument acts on the surface it touches (the cautery burns: `instruments/cautery_tip.rs`);
//!    the reaction force, clamped, and the local model a distant device renders (`tool_output.rs`);
//! 6. the tail, after the forces are out: colliders refit, contact-stiffness iterations ([`Sim::finish_tick`]).
//!
//! The parts: `object.rs` ([`SimObject`]), `tool.rs` ([`SimTool`], [`ToolCommand`], [`ToolOutput`]),
//! `step_report.rs` ([`StepReport`]), `suture_output.rs` ([`SutureActivity`], a tool's needle and thread
//! as its output tells the training layer); built from a scene descriptor in `from_scene.rs`. What a tool does beyond
//! its body is its instrument: one trait with a hook per stage (`instrument.rs`), one file per instrument
//! (`instruments/`).

mod cut_follow;
mod drive;
mod from_scene;
mod guarded;
mod hole_tearing;
mod instrument;
mod instruments;
mod knot_watch;
mod needle_model;
mod object;
mod pattern_watch;
mod step_report;
mod suture_output;
mod tearing;
mod tissue_contact;
mod tool;
mod tool_output;
mod topology;
mod wound_watch;

use guarded::TickStepper;
pub use knot_watch::KNOT_PERIOD_TICKS;
pub use needle_model::NeedlePop;
pub use object::SimObject;
pub use step_report::StepReport;
pub use suture_output::SutureActivity;
pub use tool::{SimTool, ToolCommand, ToolOutput};
use tool::{ToolBody, ToolDrive, ToolHaptics};

use std::sync::Arc;

use thiserror::Error;

use crate::haptics::EnergyBudget;
use crate::multirate::StepRunner;
use crate::tissue::{TieSet, integrator_for, step_guarded};
use sinew_parallel::{ChunkRunner, for_chunks_mut};

/// Why a world could not become a simulation.
#[derive(Debug, Error)]
pub enum SimBuildError {
    /// parry refused an object's or a tool's surface.
    #[error("`{object}`: collision mesh: {message}")]
    Collider {
        /// Object or tool name.
        object: String,
        /// parry's reason.
        message: String,
    },
    /// Region tracking asked for an object it cannot simulate faithfully.
    #[error("`{object}`: region of deformation: {message}")]
    Region {
        /// Object name.
        object: String,
        /// Why.
        message: String,
    },
}

/// Leaf boxes of every object's collider are this much larger than their triangles, mm: a still or creeping
/// surface then rewrites no BVH leaf at all, and a refit touches only the leaves whose triangle moved out of
/// its box. Far below the broad-phase margin (2 mm in the shipped worlds), so the broad phase only gains,
/// never loses, candidates. Measured on the pad under two stroking probes
/// (`cargo bench -p sinew-server --bench tick`): tick p50 279 -> 262 us going from 0.05 to 0.2 mm.
pub const REFIT_MARGIN_MM: f32 = 0.2;

/// A tool's planes cover surfaces within this distance of its box, mm: what a hand moving at 100 mm/s covers
/// in a 200 ms round trip, so a distant device always has the surface it is about to meet.
pub const PLANE_LOOK_AHEAD_MM: f32 = 20.0;

/// A node this close to a tool's surface counts as on it when jaws close, mm (the probe leaves held nodes on
/// the surface to within float rounding).
const BITE_TOLERANCE_MM: f32 = 1e-3;

/// Plane stiffness before a tool has touched anything and before its touch-down solve has finished, and on
/// multi-rate objects, N/mm (see [`crate::haptics::TOUCHDOWN_DEPTH_PER_REACH`]; after a contact, the last measured contact's
/// normal stiffness): the pad's contact stiffness at a few mm.
pub const PLANE_STIFFNESS_PRIOR_N_PER_MM: f32 = 0.2;

/// The whole simulated scene.
#[derive(Debug)]
pub struct Sim {
    /// Deformable objects, in world-file order.
    pub objects: Vec<SimObject>,
    /// Tools, in world-file order.
    pub tools: Vec<SimTool>,
    /// Tie-nodes between objects.
    pub ties: Vec<TieSet>,
    /// Pairs of objects kept out of each other (tissue-tissue contact).
    pairs: Vec<crate::interaction::TissuePair>,
    /// Energy at the end of the last tick (None after an outside change to a state, or a reset).
    last_energy_n_mm: Option<f64>,
    /// Work each tool does on the tissue, and the allowances it grants the others.
    budget: EnergyBudget,
    collision_margin_mm: f32,
    time_s: f64,
    steps: u64,
    /// The last step left work for its tail ([`Sim::finish_tick`]).
    tail_due: bool,
    /// Topology changes so far (seams opened): how an instrument out of its tool during a hook learns it
    /// missed one ([`Sim::with_instrument`]).
    openings: u64,
    /// The two objects whose gap the world's suture exercise judges (`wound_watch.rs`).
    wound: Option<[usize; 2]>,
    /// The pattern the world's pattern-cutting exercise marks, and its cut as last read (`pattern_watch.rs`).
    pattern: Option<pattern_watch::PatternWatch>,
    /// The slits a suture cuts through its tissue (`hole_tearing.rs`).
    hole_tear_scratch: crate::interaction::CutScratch,
    /// The knots the threads tie (`knot_watch.rs`).
    knots: knot_watch::KnotWatch,
}

impl Sim {
    /// Run every multi-rate object's steps with the runner `make` gives for it (by object name) from now on:
    /// the server's threads. A step under way finishes on the old runner first.
    pub fn set_step_runners(&mut self, mut make: impl FnMut(&str) -> Box<dyn StepRunner>) {
        for object in &mut self.objects {
            if let Some(lane) = &mut object.lane {
                lane.set_runner(make(&object.name));
            }
        }
    }

    /// Spread the tissue passes of every object the tick steps (not the multi-rate ones: they have threads of
    /// their own) over `runner`; `None` steps them on the calling thread. The results are the same bits either
    /// way (see [`sinew_parallel`]): a recording replays the same on any thread count.
    pub fn set_chunk_runner(&mut self, runner: Option<Arc<dyn ChunkRunner>>) {
        for object in self.objects.iter_mut().filter(|o| o.lane.is_none()) {
            object.model.set_chunk_runner(runner.clone());
        }
    }

    /// Tell the guard that an object's state was changed from outside (its energy reference is stale).
    pub fn note_state_changed(&mut self) {
        self.last_energy_n_mm = None;
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Advance by `dt_s`. `commands` and `outputs` are indexed like [`Sim::tools`] (shorter slices leave the
    /// remaining tools released / unreported). Real-time contract: no allocation after the first contacts
    /// have grown their buffers; never panics; never outputs a non-finite force.
    pub fn step(
        &mut self,
        dt_s: f32,
        commands: &[ToolCommand],
        outputs: &mut [ToolOutput],
    ) -> StepReport {
        // The last tick's tail, if whoever stepped it did not run it after publishing its forces: the same
        // work on the same state, so a step's result never depends on who ran the tail, or when.
        self.finish_tick();
        // The tissue passes come within the next hundred microseconds: idle workers get ready.
        if let Some(object) = self.objects.iter().find(|o| o.lane.is_none()) {
            object.model.chunk_runner().prepare();
        }
        let mut report = StepReport::default();
        self.apply_commands(dt_s, commands);
        // Instruments act on the topology before anything reads it (blades cut what they swept since the
        // last tick).
        for t in 0..self.tools.len() {
            self.with_instrument(t, |i, sim| i.before_contacts(sim, t, dt_s, &mut report));
        }

        // Multi-rate objects due this tick take back their finished step (before the broad phase reads their
        // surfaces).
        let tick = self.steps;
        for (o, object) in self.objects.iter_mut().enumerate() {
            let Some(lane) = object.lane.as_mut().filter(|l| l.due(tick)) else {
                continue;
            };
            let spec = object.integrator_spec;
            if let Some(job) = lane.collect(&mut object.state, &object.model, || {
                integrator_for(spec.0, spec.1)
            }) {
                report.substeps += job.substeps;
                report.retries += job.retries;
                report.solver_iterations += job.solver_iterations;
                report.faults += job.faults;
                object.collider.refit(&object.state.positions_mm);
                for (t, tool) in self.tools.iter_mut().enumerate() {
                    let Some(grasp) = tool.instrument_state.as_mut().and_then(|i| i.grasp_mut())
                    else {
                        continue;
                    };
                    if grasp.attached_nodes(o).is_empty() {
                        continue;
                    }
                    // The points' pulls as the step measured them: those pulled past the slip force go.
                    let before = grasp.slipped();
                    grasp.settle_with(o, &object.model, |a| lane.finished_pull(t, a));
                    report.attachments_slipped += (grasp.slipped() - before) as u32;
                }
                if job.faults > 0 {
                    for tool in &mut self.tools {
                        tool.contacts[o].forget();
                        if let Some(instrument) = tool.instrument_state.as_mut() {
                            report.attachments_released += instrument.object_reset(o);
                        }
                    }
                }
            }
        }

        // Broad phase once per tick, on last tick's refitted surfaces, loosened by the margin.
        let margin = self.collision_margin_mm;
        for tool in &mut self.tools {
            let mut aabb = tool
                .body
                .collider
                .aabb(&tool.position_mm, &tool.rotation, margin);
            if let Some(shaft) = &tool.body.shaft {
                parry3d::bounding_volume::BoundingVolume::merge(
                    &mut aabb,
                    &shaft.aabb(&tool.shaft_centre_mm(), &tool.rotation, margin),
                );
            }
            for (object, contacts) in self.objects.iter_mut().zip(tool.contacts.iter_mut()) {
                if tool.active {
                    contacts.clear();
                    object
                        .collider
                        .nodes_near(&aabb, &mut object.marks, &mut contacts.candidates);
                    if contacts.wants_triangles() {
                        contacts
                            .candidate_triangles
                            .extend(object.collider.triangles_near(&aabb));
                    }
                } else {
                    contacts.forget();
                }
            }
        }

        // Where one object's surface meets another's, on the same surfaces.
        report.tissue_contacts = self.find_tissue_contacts();

        // ... and send the next step on its way with the tools where they are now.
        for (o, object) in self.objects.iter_mut().enumerate() {
            let Some(lane) = object.lane.as_mut().filter(|l| l.due(tick)) else {
                continue;
            };
            for (t, tool) in self.tools.iter().enumerate() {
                lane.set_tool(
                    t,
                    tool.active,
                    &tool.position_mm,
                    &tool.rotation,
                    &tool.contacts[o].candidates,
                    &tool.contacts[o].candidate_triangles,
                );
                lane.set_grasp(t, o, tool.instrument_state.as_ref().and_then(|i| i.grasp()));
            }
            lane.launch(dt_s * lane.ticks_per_step() as f32);
        }

        // Regions of deformation follow this tick's contacts and last tick's motion.
        for (o, object) in self.objects.iter_mut().enumerate() {
            let Some(region) = &mut object.region else {
                continue;
            };
            region.clear_contacts();
            for tool in self.tools.iter().filter(|t| t.active) {
                region.add_contacts(&tool.contacts[o].candidates);
                region.add_contacts(tool.attached_nodes(o));
            }
            let update = region.update(&object.model, &mut object.state, dt_s);
            report.region_nodes += update.active_nodes;
            report.region_rebuilds += u32::from(update.rebuilt);
        }

        // All objects step in lockstep (ties couple them every substep), at the smallest object dt.
        let planned = self
            .objects
            .iter()
            .filter(|o| o.lane.is_none())
            .map(|o| (dt_s / o.max_dt_s).ceil().max(1.0) as u32)
            .max()
            .unwrap_or(1);
        // The energy at the start of this tick is the one measured at the end of the last (one pass a tick).
        let energy_before = match self.last_energy_n_mm.take() {
            Some(e) => e,
            None => self.assess().1,
        };
        let work_allowance = self.tool_work_allowance_n_mm();
        for object in self.objects.iter_mut().filter(|o| o.lane.is_none()) {
            match &object.region {
                Some(region) => object
                    .guard
                    .save_nodes(&object.state, region.active_nodes()),
                None => object.guard.save(&object.state),
            }
        }
        let step = step_guarded(
            &mut TickStepper {
                sim: self,
                report: &mut report,
            },
            dt_s,
            planned,
            energy_before,
            work_allowance,
        );
        self.last_energy_n_mm = Some(step.energy_n_mm);
        report.retries += step.retries;
        if step.gave_up() {
            // Still wrong at 1/16 of the step. Growing energy may be a tool's real work: keep it. A broken
            // object (non-finite, or beyond the absolute limits) is contained: reset to rest.
            for (o, object) in self.objects.iter_mut().enumerate() {
                if object.lane.is_none() && object.broken() {
                    object.state.reset_to_rest(&object.model);
                    if let Some(region) = &mut object.region {
                        // Everything moved back to rest: forget the region, refit every triangle.
                        region.clear();
                        object.collider.refit(&object.state.positions_mm);
                    }
                    for tool in &mut self.tools {
                        tool.contacts[o].forget();
                        if let Some(instrument) = &mut tool.instrument_state {
                            report.attachments_released += instrument.object_reset(o);
                        }
                    }
                    report.faults += 1;
                    self.last_energy_n_mm = None;
                    for pair in self
                        .pairs
                        .iter_mut()
                        .filter(|p| p.object_a == o || p.object_b == o)
                    {
                        pair.forget();
                    }
                }
            }
        }
        // The colliders follow this tick's motion in the tail, after the forces are out: nothing between here and
        // the outputs needs them but the nearby-surface planes, whose candidates a tree one step old (fat leaves,
        // a look-ahead box) still finds; the next tick's broad phase sees them refitted, as before.
        for object in self.objects.iter_mut().filter(|o| o.lane.is_none()) {
            object.refit_due = true;
        }

        // Sheets overstretched this tick tear before the grasps measure their pull.
        self.tear_overstretched(&mut report);
        for t in 0..self.tools.len() {
            self.with_instrument(t, |i, sim| i.after_substeps(sim, t, dt_s, &mut report));
        }
        // A suture pulled past its tissue's limit cuts through it at its holes, once the thread has stepped.
        self.tear_at_holes(&mut report);
        // The knots the threads tie now, before the outputs carry them.
        self.watch_knots();
        for t in 0..self.tools.len() {
            self.with_instrument(t, |i, sim| i.before_output(sim, t, dt_s, &mut report));
            let out = &mut self.tool_output(t);
            report.held_nodes += out.held_nodes;
            self.local_model(t, dt_s, out);
            out.needle_pop = self.needle_pop(t, out);
            out.suture = self.suture_activity(t);
            if let Some(slot) = outputs.get_mut(t) {
                *slot = *out;
            }
        }
        report.wound_gap_mm = self.wound_gap_now();
        report.pattern_cut = self.pattern_cut_now();
        self.time_s += f64::from(dt_s);
        self.steps += 1;
        report
    }

    /// The tick's tail: work a step leaves for after its outputs went out (the colliders' refit to the tick's
    /// motion, and the contact-stiffness solver's iterations, which refine the `K` of the next ticks' local
    /// models). The server runs it right after
    /// publishing the tick's forces, so it is not in the pose -> force path; [`Sim::step`] runs it first if
    /// nobody did, on the same state, so results do not depend on it being called. No allocation once warm.
    pub fn finish_tick(&mut self) {
        for object in &mut self.objects {
            object.finish_refit();
        }
        if !std::mem::take(&mut self.tail_due) {
            return;
        }
        // Each tool's solve on an object reads that object and writes only its own solver: the tools run
        // side by side on the object's threads (one chunk per tool), to the same bits as one after another.
        for (o, object) in self.objects.iter().enumerate() {
            let (model, state) = (&object.model, &object.state);
            for_chunks_mut(model.chunk_runner(), &mut self.tools, 1, |_, tools| {
                for tool in tools {
                    let due = tool.haptic.stiffness_due.get_mut(o).and_then(Option::take);
                    let touchdown = tool.haptic.touchdown.get_mut(o);
                    let (Some(solver), Some(contacts)) =
                        (tool.haptic.stiffness.get_mut(o), tool.contacts.get(o))
                    else {
                        continue;
                    };
                    if let Some(normal) = due {
                        let grasped = tool
                            .instrument_state
                            .as_ref()
                            .map_or(&[][..], |i| i.attached_nodes(o));
                        solver.advance(
                            model,
                            state,
                            &contacts.held,
                            &contacts.normals,
                            grasped,
                            &normal,
                        );
                    } else if let Some(touchdown) = touchdown
                        && let Some((node, normal)) = touchdown.due.take()
                    {
                        // A touch-down at the plane's node: its footprint held, the tool's normal there
                        // into the tissue. (A solve under way for the node before finishes first; the
                        // next one starts on this node.)
                        if solver.advance(
                            model,
                            state,
                            &touchdown.held,
                            &touchdown.normals,
                            &[],
                            &normal,
                        ) {
                            touchdown.node = Some(node);
                        }
                    }
                }
            });
        }
    }
}
