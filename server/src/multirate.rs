//! Multi-rate objects: an object too costly for the tick (a large organ) steps every `N` ticks, `N` ticks'
//! time at once, on a thread of its own, while every tick renders it to the tools through the local model of
//! its latest step.
//!
//! Owns: the step job ([`StepJob`]: a copy of the object's model, the state it integrates, its integrator and
//! divergence guard, and per tool the contact it probes and that contact's force, stiffness and damping at the
//! end of the step), the trait that carries a job to wherever it runs ([`StepRunner`]: [`InlineRunner`] here,
//! a thread in `node/step_threads.rs`), the lane that hands jobs out and takes them back at fixed ticks
//! ([`StepLane`]), the tick-side view of a finished step's contact ([`LaneContact`]), and the surface ahead
//! of a tool the tick renders until a step answers ([`LanePlane`]).
//!
//! The hand-off, and why it is deterministic. At tick `kN` the sim takes back the job launched at tick
//! `(k-1)N` (waiting for it if its thread is late), copies its state into the object (what the collider, the
//! viewers and a recording see) and its contacts into the lane, then launches the next job with the tools'
//! poses and broad-phase candidates of tick `kN`. A job's result depends on its inputs alone and is taken at a
//! fixed tick, so a run on a thread and a run inline (a replay, a test) agree to the bit, whatever the
//! threads' timing. Between hand-offs a tool in contact feels `f = f0 - K (x - x0)`, one-sided along `f0`: the
//! force `f0` the step found at the tool's launch position `x0` and the contact's stiffness `K` (the condensed
//! solve of `haptics/contact_stiffness.rs`, run on the job's thread): the local model a latency-moderated device
//! renders, evaluated on the server every tick (with the tool's prior stiffness until the contact's solve
//! finishes). Before a step has found a tool, the tick renders the tool's plane on the object
//! (`multirate/lane_plane.rs`). The object's deformation lags its tools by one step period.
//!
//! Grasping. The tick's grasper takes hold of a multi-rate object's surface on its latest finished step, as
//! it does any object's; each launch copies the tool's attachments to that object into the job
//! (`multirate/job_grasp.rs`), whose substeps hold them on the jaws where the tool was at launch, as the tick
//! holds them on an object it steps. At the end of the step the job measures each point's pull and the
//! condensed stiffness of everything the tool holds (`K`, full 3x3: a grasp pulls back in every direction);
//! the sim lets points pulled past the slip force go at the hand-off, and between hand-offs the grasper feels
//! `g0 - K (x - x0)`, bilateral: `g0` the points' summed pull and the body's push on the tissue it presses
//! (held tissue is rendered whole: a one-sided push model would drop its normal stiffness as the jaws lift
//! away), scaled by the jaws' grip. The tool's turning is not in the model (position only); the lobe follows
//! the jaws one step period late.
//!
//! Cutting. The tick cuts a multi-rate object as it cuts any object, on its latest finished step (the mirror),
//! the moment a blade sweeps, and logs what the cut did to the vertices (`multirate/job_topology.rs`: moved,
//! split, copied). The step under way knows nothing of it: when it comes home, the log replays on its newer
//! state before it becomes the mirror, and the job takes the cut model (a copy), a fresh integrator and guard,
//! and starts its contact solves over (the last `K` stays until one finishes). The cut shows at once; the
//! tissue moves on it from the next step.
//!
//! Tearing goes the same way: the sim tests a multi-rate object's strain on the ticks that take back its step
//! (its state changes only then), and a tear opens the mirror and is logged like a cut.
//!
//! Must not: touch threads or clocks (the node's runner does), or change the model itself: the sim cuts and
//! tears the object's, and the job takes a copy at a hand-off. Burn shrink is refused by the loader (it would
//! change the model every tick a tip burns).

mod job_grasp;
mod job_topology;
mod lane_contact;
mod lane_plane;

use nalgebra::{Matrix3, UnitQuaternion};

use self::job_grasp::JobGrasp;
pub use self::job_topology::TopologyLog;
pub use self::lane_contact::LaneContact;
pub use self::lane_plane::{LANE_PLANE_SPAN_MM, LanePlane};

use crate::collision::ToolCollider;
use crate::haptics::ContactStiffness;
use crate::interaction::{Attachment, Grasp, ProbeContacts, ToolBody};
use crate::tissue::{
    DivergenceGuard, Integrator, MassSpringModel, Stepped, TissueState, Vec3, Verdict, guard,
    step_guarded,
};

/// Most ticks' worth of the contact-stiffness solve (`ContactStiffness::ITERATIONS_PER_TICK` CG iterations each)
/// one step advances it by. With one tick's budget per tick of the step, the solve cost as much as the step's
/// elements (30% of a 200 Hz fem_block step with two tools: `cargo bench -p sinew-server --bench tick -- --world
/// worlds/fem_block.toml --step-hz 200`); `K` changes slowly, so a solve may span a few steps instead.
pub const MAX_SOLVE_TICKS_PER_STEP: u32 = 1;

/// The same while the tool's jaws hold the object. Held tissue stiffens as it is stretched, and its full 3x3
/// `K` takes three solves' work. Lifting the liver's lobe at 4 mm/s (`server/tests/multirate_grasp.rs`, solves
/// started cold over 8 rings), the force jumped at the worst hand-off by 3.2 times what the model rendered over
/// the step before at one or two ticks' budget (a solve spanned many steps, and its `K` was stale), by 0.05
/// times at four.
pub const MAX_GRASP_SOLVE_TICKS_PER_STEP: u32 = 4;

/// Graph steps a multi-rate object's contact solves cover (the tick's cover
/// [`ContactStiffness::RINGS`], 8). A multi-rate object is large and coarse: 8 rings of the liver's 3-5 mm
/// elements took in 1,623 of its 3,100 nodes, and a grasp's solve nearly doubled its step (49.9 against 26.7 ms
/// with two tools, one grasping as it strokes; `cargo bench -p sinew-server --bench tick -- --world
/// worlds/liver.toml --tools 2 --grasp`). At 5 the grasped step costs 28.7 ms, and `K` along the lift is 11%
/// stiffer than the force's own slope (2% at 8): stiffer errs on the stable side.
pub const SOLVE_RINGS: u32 = 5;

/// What one finished step of a multi-rate object did (summed into the tick's `StepReport` at its hand-off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct JobReport {
    /// Integrator substeps run, retries included.
    pub substeps: u32,
    /// Times the step was rerun with its substep halved.
    pub retries: u32,
    /// Solver iterations.
    pub solver_iterations: u32,
    /// 1 when the object was still broken at the smallest substep and was reset to rest.
    pub faults: u32,
}

/// A tool as a multi-rate object's step sees it: its body, held still at its launch pose for the step.
#[derive(Debug, Clone)]
pub struct ToolSeed {
    /// The tip's shape.
    pub tip: ToolCollider,
    /// The shaft (a capsule along the tool's z from its origin), and its half length, mm.
    pub shaft: Option<(ToolCollider, f32)>,
    /// Server-side force limit, N (the guard's allowance for the tool's work).
    pub max_force_n: f32,
    /// Largest distance from the tool origin to its surface, mm.
    pub reach_mm: f32,
    /// The tool takes hold with jaws (a grasper).
    pub grasps: bool,
}

#[derive(Debug, Clone)]
struct JobTool {
    seed: ToolSeed,
    active: bool,
    was_active: bool,
    position_mm: Vec3,
    last_position_mm: Vec3,
    rotation: UnitQuaternion<f32>,
    contacts: ProbeContacts,
    /// The points of this object the tool's jaws hold.
    grasp: JobGrasp,
    stiffness: ContactStiffness,
    contact: LaneContact,
}

/// One step of a multi-rate object, with everything it needs: it runs wherever its runner sends it.
#[derive(Debug)]
pub struct StepJob {
    model: MassSpringModel,
    state: TissueState,
    integrator: Box<dyn Integrator>,
    guard: DivergenceGuard,
    /// Largest substep, s (the object's `dt_s`).
    max_dt_s: f32,
    /// The step, s (`N` ticks).
    step_dt_s: f32,
    /// Ticks per step: the contact solve's budget is that many ticks' worth.
    ticks: u32,
    friction: f32,
    /// Mechanical energy at the end of the last step, N mm (None at first and after a reset).
    energy_n_mm: Option<f64>,
    tools: Vec<JobTool>,
    report: JobReport,
}

impl Stepped for StepJob {
    /// Each substep pushes the tissue out of each tool, then solves with the nodes it holds pinned where it
    /// holds them: the rest of the tissue answers the tool's new place within this substep.
    fn integrate(&mut self, h_s: f32, substeps: u32) {
        for _ in 0..substeps {
            self.state.pinned.clear();
            for tool in self.tools.iter_mut().filter(|t| t.active) {
                let body = ToolBody::posed(
                    &tool.seed.tip,
                    tool.seed
                        .shaft
                        .as_ref()
                        .map(|(shaft, half_mm)| (shaft, *half_mm)),
                    tool.position_mm,
                    tool.rotation,
                );
                tool.contacts.project(
                    &body,
                    &self.model,
                    &mut self.state,
                    tool.grasp.nodes(),
                    self.friction,
                );
                tool.grasp.hold(
                    &tool.position_mm,
                    &tool.rotation,
                    &self.model,
                    &mut self.state,
                );
                self.state.pinned.extend_from_slice(&tool.contacts.held);
                self.state.pinned.extend_from_slice(tool.grasp.nodes());
            }
            self.state.pinned.sort_unstable();
            self.state.pinned.dedup();
            self.report.solver_iterations +=
                self.integrator.step(&self.model, &mut self.state, h_s);
        }
    }

    fn judge(&mut self) -> (bool, f64) {
        let assessment = self.guard.assess(&self.model, &self.state);
        (assessment.broken, assessment.energy_n_mm)
    }

    fn restore(&mut self) {
        self.guard.restore(&mut self.state);
    }
}

impl StepJob {
    /// Take the object's new `model` (cut since this job left; its state already has the model's vertices) with
    /// a fresh `integrator`: the guard is made again, the energy forgotten, each tool's probe contacts and
    /// contact solve start over (their node sets were of the old model; the last solve's `K` and the contact
    /// the finished step measured stay until the next ones: a cut does not drop the force). Allocates.
    fn take_model(&mut self, model: &MassSpringModel, integrator: Box<dyn Integrator>) {
        self.model.clone_from(model);
        let n = model.node_count();
        self.state.forces_n.resize(n, Vec3::zeros());
        self.state.external_forces_n.resize(n, Vec3::zeros());
        self.integrator = integrator;
        self.guard = DivergenceGuard::new(model);
        self.energy_n_mm = None;
        for tool in &mut self.tools {
            tool.contacts.forget();
            tool.stiffness.topology_changed(n);
        }
    }

    /// Run the step: integrate `step_dt_s` in substeps of at most `max_dt_s`, pushing the tissue out of each
    /// active tool after every substep; rerun with halved substeps while the guard finds it broken or gaining
    /// energy the tools cannot have put in (as `Sim::step` does), reset it to rest if still broken at the
    /// smallest; then measure each tool's contact. No allocation once warm, never panics.
    pub fn run(&mut self) {
        self.report = JobReport::default();
        let planned = (self.step_dt_s / self.max_dt_s).ceil().max(1.0) as u32;
        let energy_before = match self.energy_n_mm.take() {
            Some(e) => e,
            None => self.guard.assess(&self.model, &self.state).energy_n_mm,
        };
        let allowance_n_mm: f64 = self
            .tools
            .iter()
            .filter(|t| t.active)
            .map(|t| {
                let travel_mm = guard::tool_travel_mm(
                    t.was_active,
                    &t.position_mm,
                    &t.last_position_mm,
                    t.seed.reach_mm,
                );
                guard::tool_work_allowance_n_mm(t.seed.max_force_n, travel_mm)
            })
            .sum();
        self.guard.save(&self.state);
        let step = step_guarded(self, self.step_dt_s, planned, energy_before, allowance_n_mm);
        self.report.substeps += step.substeps;
        self.report.retries += step.retries;
        self.energy_n_mm = Some(step.energy_n_mm);
        if step.gave_up() && step.verdict == Verdict::Broken {
            self.state.reset_to_rest(&self.model);
            self.energy_n_mm = None;
            self.report.faults += 1;
            for tool in &mut self.tools {
                tool.contacts.forget();
                tool.grasp.clear();
                tool.stiffness.forget();
            }
        }
        for tool in &mut self.tools {
            tool.contact = if tool.active {
                Self::measure(tool, &self.model, &self.state, self.friction, self.ticks)
            } else {
                tool.contacts.forget();
                tool.grasp.clear();
                tool.stiffness.forget();
                LaneContact::default()
            };
        }
    }

    /// The tool's contact at the end of the step: the held nodes' push, the held points' pull, and the
    /// contact stiffness solve (over both) advanced by `ticks` ticks' budget, at most
    /// [`MAX_SOLVE_TICKS_PER_STEP`] ([`MAX_GRASP_SOLVE_TICKS_PER_STEP`] while the jaws hold it; a solve longer
    /// than that goes on in the next step, as on the tick).
    fn measure(
        tool: &mut JobTool,
        model: &MassSpringModel,
        state: &TissueState,
        friction: f32,
        ticks: u32,
    ) -> LaneContact {
        let held = &tool.contacts.held;
        let grasped = tool.grasp.holds();
        let out_of_contact = LaneContact {
            position_mm: tool.position_mm,
            ..LaneContact::default()
        };
        if held.is_empty() && !grasped {
            tool.stiffness.forget();
            return out_of_contact;
        }
        let force_n = if held.is_empty() {
            Vec3::zeros()
        } else {
            tool.contacts.reaction_force_n(model, state, friction)
        };
        let grasp_force_n = tool.grasp.measure(model, state);
        let first = held.first().or(tool.grasp.nodes().first()).copied();
        let normal = force_n
            .try_normalize(1e-9)
            .or_else(|| (-grasp_force_n).try_normalize(1e-9))
            .unwrap_or_else(|| {
                first
                    .and_then(|n| model.rest_normals().get(n as usize).copied())
                    .unwrap_or_else(Vec3::z)
            });
        let budget = if grasped {
            MAX_GRASP_SOLVE_TICKS_PER_STEP
        } else {
            MAX_SOLVE_TICKS_PER_STEP
        };
        for _ in 0..ticks.min(budget) {
            if tool.stiffness.advance(
                model,
                state,
                held,
                &tool.contacts.normals,
                tool.grasp.nodes(),
                &normal,
            ) {
                break;
            }
        }
        let along = |m: &Matrix3<f32>| (normal.transpose() * m * normal)[(0, 0)].max(0.0);
        let response = tool.stiffness.response();
        let mut contact = LaneContact {
            position_mm: tool.position_mm,
            solved: response.is_some(),
            ..LaneContact::default()
        };
        if grasped {
            // Held tissue is rendered whole and bilaterally: the body's push with the points' pull, and the
            // full K (a one-sided push model would drop its normal stiffness as the jaws lift away).
            contact.grasp_force_n = force_n + grasp_force_n;
            contact.grasped_points = tool.grasp.nodes().len() as u32;
            if let Some(r) = response {
                contact.grasp_stiffness_n_per_mm = r.stiffness_n_per_mm;
                contact.grasp_damping_n_s_per_mm = r.damping_n_s_per_mm;
            }
        } else {
            contact.force_n = force_n;
            contact.normal = normal;
            contact.held_nodes = held.len() as u32;
            if let Some(r) = response {
                contact.stiffness_n_per_mm = along(&r.stiffness_n_per_mm);
                contact.damping_n_s_per_mm = along(&r.damping_n_s_per_mm);
            }
        }
        let finite = contact.force_n.iter().all(|c| c.is_finite())
            && contact.stiffness_n_per_mm.is_finite()
            && contact.damping_n_s_per_mm.is_finite()
            && contact.grasp_force_n.iter().all(|c| c.is_finite())
            && contact
                .grasp_stiffness_n_per_mm
                .iter()
                .all(|c| c.is_finite())
            && contact
                .grasp_damping_n_s_per_mm
                .iter()
                .all(|c| c.is_finite());
        if !finite {
            return out_of_contact;
        }
        contact
    }
}

/// Carries a job to where it runs and back. `launch` is called with an empty runner; `collect` returns the
/// job launched last, finished, waiting for it if need be (None if it was lost: its thread died).
pub trait StepRunner: Send + std::fmt::Debug {
    /// Start `job`.
    fn launch(&mut self, job: Box<StepJob>);
    /// The launched job, finished.
    fn collect(&mut self) -> Option<Box<StepJob>>;
}

/// Runs a job at launch, on the caller's thread (tests, replays, the tick-cost estimate).
#[derive(Debug, Default)]
pub struct InlineRunner {
    done: Option<Box<StepJob>>,
}

impl StepRunner for InlineRunner {
    fn launch(&mut self, mut job: Box<StepJob>) {
        job.run();
        self.done = Some(job);
    }

    fn collect(&mut self) -> Option<Box<StepJob>> {
        self.done.take()
    }
}

/// A multi-rate object's side of the tick: the job when it is home, the runner when it is away, and the
/// contacts of its latest finished step.
#[derive(Debug)]
pub struct StepLane {
    ticks_per_step: u32,
    runner: Box<dyn StepRunner>,
    home: Option<Box<StepJob>>,
    in_flight: bool,
    /// The runner lost a job (its thread died): the object stays where it was, and pushes on nothing.
    lost: bool,
    contacts: Vec<LaneContact>,
    /// What cuts did to the object's vertices and model since the last hand-off (replayed on the step under
    /// way when it comes home).
    topology: TopologyLog,
}

impl StepLane {
    /// A lane for an object with `model` at `state`, stepping every `ticks_per_step` ticks with `integrator`
    /// in substeps of at most `max_dt_s`, touched by `tools` (in the sim's order). Runs inline until
    /// [`Self::set_runner`].
    pub fn new(
        model: &MassSpringModel,
        state: &TissueState,
        integrator: Box<dyn Integrator>,
        max_dt_s: f32,
        friction: f32,
        ticks_per_step: u32,
        tools: &[ToolSeed],
    ) -> Self {
        let mut state = state.clone();
        state.pinned = Vec::with_capacity(4096 * tools.len());
        let job = StepJob {
            model: model.clone(),
            state,
            integrator,
            guard: DivergenceGuard::new(model),
            max_dt_s,
            step_dt_s: 0.0,
            ticks: ticks_per_step,
            friction,
            energy_n_mm: None,
            tools: tools
                .iter()
                .map(|seed| JobTool {
                    seed: seed.clone(),
                    active: false,
                    was_active: false,
                    position_mm: Vec3::zeros(),
                    last_position_mm: Vec3::zeros(),
                    rotation: UnitQuaternion::identity(),
                    contacts: ProbeContacts::with_capacity(4096).sticky(),
                    grasp: JobGrasp::new(),
                    stiffness: ContactStiffness::new(model.node_count())
                        .warm_started()
                        .with_rings(SOLVE_RINGS),
                    contact: LaneContact::default(),
                })
                .collect(),
            report: JobReport::default(),
        };
        Self {
            ticks_per_step,
            runner: Box::new(InlineRunner::default()),
            home: Some(Box::new(job)),
            in_flight: false,
            lost: false,
            contacts: vec![LaneContact::default(); tools.len()],
            topology: TopologyLog::default(),
        }
    }

    /// Ticks per step.
    pub fn ticks_per_step(&self) -> u32 {
        self.ticks_per_step
    }

    /// Whether tick number `tick` (0 first) hands off: the last step comes back, the next one leaves.
    pub fn due(&self, tick: u64) -> bool {
        tick.is_multiple_of(u64::from(self.ticks_per_step))
    }

    /// Run the steps with `runner` from now on (a job under way finishes with the old one first).
    pub fn set_runner(&mut self, runner: Box<dyn StepRunner>) {
        if self.in_flight {
            self.in_flight = false;
            self.home = self.runner.collect();
            self.lost |= self.home.is_none();
        }
        self.runner = runner;
    }

    /// Take the step under way back: copy its positions and velocities into `mirror` and its contacts into the
    /// lane. Returns its report (None when nothing was under way). A lost job counts as a fault: `mirror` stays
    /// where it was and every contact pushes on nothing.
    ///
    /// If the object was cut since the last hand-off (`model` is then not the job's: see
    /// [`Self::topology_mut`]), the cut's changes to the vertices replay on the step's state first, and the job
    /// takes `model` and a fresh `integrator` for its next step (its guard, contact solves and probe contacts
    /// start again; allocates: a cut is an event). A step whose state the log cannot replay on (a bug) is
    /// dropped: the mirror keeps the cut's own state, and the job starts from it. No allocation otherwise.
    pub fn collect(
        &mut self,
        mirror: &mut TissueState,
        model: &MassSpringModel,
        integrator: impl FnOnce() -> Box<dyn Integrator>,
    ) -> Option<JobReport> {
        if !self.in_flight {
            if self.lost {
                // No step will take the cuts of a lane that lost its job.
                self.topology.clear();
            }
            return None;
        }
        self.in_flight = false;
        let Some(mut job) = self.runner.collect() else {
            self.lost = true;
            self.topology.clear();
            self.contacts.fill(LaneContact::default());
            return Some(JobReport {
                faults: 1,
                ..JobReport::default()
            });
        };
        let mut report = job.report;
        if self.topology.pending() {
            let replayed = self.topology.replay(&mut job.state)
                && job.state.positions_mm.len() == mirror.positions_mm.len();
            if !replayed {
                job.state.positions_mm.clone_from(&mirror.positions_mm);
                job.state
                    .velocities_mm_s
                    .clone_from(&mirror.velocities_mm_s);
                report.faults += 1;
            }
            job.take_model(model, integrator());
            self.topology.clear();
        }
        mirror.positions_mm.copy_from_slice(&job.state.positions_mm);
        mirror
            .velocities_mm_s
            .copy_from_slice(&job.state.velocities_mm_s);
        for (slot, tool) in self.contacts.iter_mut().zip(&job.tools) {
            *slot = tool.contact;
        }
        self.home = Some(job);
        Some(report)
    }

    /// Where the sim logs what a cut does to the object's vertices and model (the tick cuts the mirror; the
    /// step under way replays the log when it comes home).
    pub fn topology_mut(&mut self) -> &mut TopologyLog {
        &mut self.topology
    }

    /// Set tool `t`'s pose and broad-phase candidates (nodes and surface triangles) for the next step (ignored while a step is under way or
    /// the lane is lost). No allocation beyond the contacts' capacity.
    pub fn set_tool(
        &mut self,
        t: usize,
        active: bool,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        candidates: &[u32],
        candidate_triangles: &[u32],
    ) {
        let Some(tool) = self.home.as_mut().and_then(|job| job.tools.get_mut(t)) else {
            return;
        };
        tool.was_active = tool.active;
        tool.last_position_mm = tool.position_mm;
        tool.active = active;
        tool.position_mm = *position_mm;
        tool.rotation = *rotation;
        // The candidates are this tick's; last step's held nodes stay for the sticky test.
        tool.contacts.candidates.clear();
        tool.contacts.candidate_triangles.clear();
        if active {
            tool.contacts.candidates.extend_from_slice(candidates);
            tool.contacts
                .candidate_triangles
                .extend_from_slice(candidate_triangles);
        } else {
            tool.contacts.forget();
            tool.grasp.clear();
        }
    }

    /// Set what tool `t`'s jaws hold of this object (object `object` in the world) for the next step: the
    /// points of it in `grasp` (None: nothing). Call after [`Self::set_tool`]; ignored while a step is under
    /// way, the lane is lost or the tool is inactive. No allocation.
    pub fn set_grasp(&mut self, t: usize, object: usize, grasp: Option<&Grasp>) {
        let Some(job) = self.home.as_mut() else {
            return;
        };
        let Some(tool) = job.tools.get_mut(t) else {
            return;
        };
        if tool.active {
            tool.grasp.set(object, grasp, &job.model);
        }
    }

    /// The pull the step just taken back measured on `attachment` of tool `t`'s jaws (None: that step did
    /// not hold it, or the next step is already away). No allocation.
    pub fn finished_pull(&self, t: usize, attachment: &Attachment) -> Option<Vec3> {
        self.home
            .as_ref()
            .and_then(|job| job.tools.get(t))
            .and_then(|tool| tool.grasp.pull_of(attachment))
    }

    /// Send the next step, `step_dt_s` long, on its way.
    pub fn launch(&mut self, step_dt_s: f32) {
        if let Some(mut job) = self.home.take() {
            job.step_dt_s = step_dt_s;
            self.runner.launch(job);
            self.in_flight = true;
        }
    }

    /// Tools keep the object's surface triangles out of their tips too, not only its nodes
    /// (`ObjectSpec::triangle_contact`), except a grasper: its jaws bite the nodes within `bite_mm` of its tip,
    /// and with the triangles holding the surface off the tip the light hand 100 ms away no longer took the
    /// liver's lobe (`instrument_explore`, 2026-12-07).
    pub fn with_triangle_contact(mut self, on: bool) -> Self {
        if let Some(job) = self.home.as_mut() {
            for tool in &mut job.tools {
                let on = on && !tool.seed.grasps;
                tool.contacts = std::mem::take(&mut tool.contacts).with_triangles(on);
            }
        }
        self
    }

    /// Tool `t`'s contact as the latest finished step left it.
    pub fn contact(&self, t: usize) -> LaneContact {
        self.contacts.get(t).copied().unwrap_or_default()
    }

    /// The runner lost a job: the object no longer steps.
    pub fn lost(&self) -> bool {
        self.lost
    }
}
