//! The deterministic simulation core: objects, tools, and one fixed-dt step.
//!
//! Owns: the per-tick pipeline `tools <- device poses; broad phase; regions of deformation; substeps
//! (integrate, push out of tools); tool reaction forces; refit colliders; fault containment`. Time and dt come in as arguments, so tests run
//! on virtual time and a recording replays exactly. Must not: touch zenoh, threads or wall-clock time.

use std::sync::Arc;

use nalgebra::{Matrix3, Quaternion, UnitQuaternion};
use thiserror::Error;

use crate::collision::{NodeMarks, SurfaceCollider, ToolCollider};
use crate::haptics::{
    ContactStiffness, CouplingParams, EnergyBudget, MAX_PLANES, NormalStiffnessEstimate,
    VirtualCoupling, WorldPlane, nearest_surface_plane,
};
use crate::interaction::{
    BladeSweep, CutScratch, Grasp, GraspEvent, JawInput, Jaws, ProbeContacts, ToolBody,
    swept_seams, torn_seams,
};
use crate::multirate::{StepLane, StepRunner, ToolSeed};
use crate::tissue::seams::{Facet, Opening, open_model_into, shared_by_two};
use crate::tissue::{
    DivergenceGuard, Integrator, MassSpringModel, ModelParts, RegionTracker, TieSet, TissueState,
    Vec3, Verdict, guard, integrator_for,
};
use crate::world::{InstrumentSpec, IntegratorName, ToolShapeSpec, World};
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

/// Plane stiffness before a tool has touched anything, N/mm (then the last measured contact's normal
/// stiffness): the pad's contact stiffness at a few mm.
pub const PLANE_STIFFNESS_PRIOR_N_PER_MM: f32 = 0.2;

/// One deformable object in the simulation.
#[derive(Debug)]
pub struct SimObject {
    /// Name from the world file.
    pub name: String,
    /// Topology and material.
    pub model: MassSpringModel,
    /// Positions and velocities.
    pub state: TissueState,
    integrator: Box<dyn Integrator>,
    /// The integrator as the world names it, to make a fresh one after a topology change.
    integrator_spec: (IntegratorName, Option<u32>),
    guard: DivergenceGuard,
    collider: SurfaceCollider,
    marks: NodeMarks,
    max_dt_s: f32,
    /// Some when only the region of deformation is integrated.
    region: Option<RegionTracker>,
    /// How burnt each node is, 0 (untouched) to 65535 (charred): the wire's 0-255 level is the high byte.
    /// Material damage: a reset to rest keeps it.
    burn: Vec<u16>,
    /// Facets a blade or a tear has cut that still join two elements, sorted: they open as soon as the cut
    /// around them separates a vertex (see [`Sim::open_seams`]).
    severed: Vec<Facet>,
    /// Topology changes so far (0: the world's mesh as loaded).
    topology_version: u32,
    /// The world mesh's vertex count: vertices from here on were split off a parent by a cut or tear.
    first_split_vertex: u32,
    /// The parent of each split vertex, in id order.
    split_parents: Vec<u32>,
    /// The material's tear strain (the tissue tears where a spring is stretched past it); `None`: never tears.
    tear_strain: Option<f32>,
    /// The material's drag against a sharp edge cutting it, N.
    cut_resistance_n: f32,
    /// The share of rest length a spring between two fully burnt nodes loses (0: burns do not shrink).
    burn_shrink: f32,
    /// Coulomb friction between a tool and this tissue (0: frictionless).
    friction: f32,
    /// Scratch of a topology change: the parts the model is rebuilt from.
    parts: ModelParts,
    /// Scratch of the tear test: the facets torn this tick.
    torn: Vec<Facet>,
    /// Some when the object steps at its own, lower rate (`step_hz`): its steps run as jobs, and `state` is
    /// the latest finished step's (see [`crate::multirate`]).
    lane: Option<StepLane>,
    /// The integrator solves with the tools' held nodes pinned (implicit Euler): each substep pushes out
    /// first, then integrates, and the contacts are sticky.
    pins_held: bool,
    /// The collider has not followed this tick's motion yet (it does in the tick's tail, after the forces).
    refit_due: bool,
}

impl SimObject {
    /// Refit the collider to the positions, if this tick's refit is still due: the moved nodes' triangles for a
    /// region object (only its active nodes moved), every leaf otherwise.
    fn finish_refit(&mut self) {
        if !std::mem::take(&mut self.refit_due) {
            return;
        }
        match &self.region {
            Some(region) => {
                self.collider
                    .refit_nodes(&self.state.positions_mm, region.active_nodes());
            }
            None => {
                self.collider
                    .refit_on(&self.state.positions_mm, self.model.chunk_runner());
            }
        }
    }

    /// The integrator's name.
    pub fn integrator_name(&self) -> &'static str {
        self.integrator.name()
    }

    /// The region of deformation, when the object is region-tracked.
    pub fn region(&self) -> Option<&RegionTracker> {
        self.region.as_ref()
    }

    /// The step lane of a multi-rate object (None: it steps every tick).
    pub fn step_lane(&self) -> Option<&StepLane> {
        self.lane.as_ref()
    }

    /// Topology changes (cuts and tears that opened something) so far; 0 for the mesh as loaded.
    pub fn topology_version(&self) -> u32 {
        self.topology_version
    }

    /// The world mesh's vertex count, and the parent of every vertex split off since (vertex
    /// `first + k` from `parents[k]`).
    pub fn split_parents(&self) -> (u32, &[u32]) {
        (self.first_split_vertex, &self.split_parents)
    }

    /// How burnt each node is, 0 to 65535 (the 0-255 level is `value >> 8`).
    pub fn burn(&self) -> &[u16] {
        &self.burn
    }

    /// With a material that shrinks when burnt, set the rest length of node `i`'s springs from their ends'
    /// burn: a spring between two charred nodes loses `burn_shrink` of its length. No allocation.
    fn shrink_springs_of(&mut self, i: usize) {
        if self.burn_shrink <= 0.0 {
            return;
        }
        for k in 0..self.model.node_springs(i).len() {
            let s = self.model.node_springs(i)[k];
            let j = self.model.other_end(s, i);
            let (Some(&a), Some(&b)) = (self.burn.get(i), self.burn.get(j)) else {
                continue;
            };
            let burnt = (f32::from(a) + f32::from(b)) / (2.0 * f32::from(u16::MAX));
            self.model
                .set_spring_rest_share(s, 1.0 - self.burn_shrink * burnt);
        }
    }

    /// One substep of `h` of the integrator, over the region of deformation when there is one.
    fn integrate(&mut self, h: f32) -> u32 {
        match &mut self.region {
            Some(region) => region.step(self.integrator.as_mut(), &mut self.state, h),
            None => self.integrator.step(&self.model, &mut self.state, h),
        }
    }

    /// The guard's absolute test on this tick: over the active region only when region-tracked (nothing
    /// else moved).
    fn broken(&self) -> bool {
        match &self.region {
            Some(region) => {
                self.guard
                    .broken_nodes(&self.model, &self.state, region.active_nodes())
            }
            None => self.guard.assess(&self.model, &self.state).broken,
        }
    }
}

/// One tool in the simulation.
#[derive(Debug)]
pub struct SimTool {
    /// Name from the world file.
    pub name: String,
    /// Bound device id.
    pub device_id: String,
    /// Shape as specified.
    pub shape_spec: ToolShapeSpec,
    collider: ToolCollider,
    /// Device frame origin in the world, mm.
    pub device_origin_in_world_mm: Vec3,
    /// Server-side force limit, N.
    pub max_force_n: f32,
    /// Tool origin in the world, mm.
    pub position_mm: Vec3,
    /// Tool orientation in the world.
    pub rotation: UnitQuaternion<f32>,
    /// A device drives it (released tools do not touch the tissue).
    pub active: bool,
    /// Active on the previous tick.
    was_active: bool,
    /// Origin on the previous tick, mm.
    last_position_mm: Vec3,
    /// Largest distance from the tool origin to its surface, mm.
    reach_mm: f32,
    /// Where the tool enters the scene each time a device (re)takes it, world, mm: the device origin lifted
    /// along the nearby tissue's outward rest normal until the tool clears every node ([`entry_point_mm`]).
    /// From there the coupling brings it to the device pose at its speed limit, so it meets every surface
    /// from outside: a device that (re)joins pressing into a thin sheet never finds its tool under it.
    entry_mm: Vec3,
    /// One contact set per object.
    contacts: Vec<ProbeContacts>,
    /// How the tool follows its device pose.
    coupling: VirtualCoupling,
    /// Device pose (target of the coupling) this tick, world, mm and mm/s.
    device_mm: Vec3,
    device_velocity_mm_s: Vec3,
    /// One contact-stiffness solver per object.
    stiffness: Vec<ContactStiffness>,
    /// Per object: the contact normal of a solver iteration due after this tick's forces went out (the tick's
    /// tail, [`Sim::finish_tick`]), if one is.
    stiffness_due: Vec<Option<Vec3>>,
    /// Tissue force on the tool and contact stiffness at the end of the last tick (the coupling's input).
    last_force_n: Vec3,
    contact_k: Matrix3<f32>,
    /// Normal stiffness and damping of this tool's last measured contact (the planes' stiffness).
    plane_stiffness_n_per_mm: f32,
    plane_damping_n_s_per_mm: f32,
    /// Broad-phase scratch of the plane search.
    plane_candidates: Vec<u32>,
    /// The contact's normal stiffness fitted to the tissue's answer.
    estimate: NormalStiffnessEstimate,
    /// What the tool is beyond its body (a probe, a grasper).
    pub instrument: InstrumentSpec,
    /// The device's jaw input this tick.
    jaw_input: JawInput,
    /// A grasper's jaws, and what they hold.
    jaws: Option<Jaws>,
    grasp: Option<Grasp>,
    /// The tissue's pull on the tool through the grasp at the end of the last tick, N.
    grasp_force_n: Vec3,
    /// A scalpel's edge in the world at the end of the last tick (None while inactive: a tool that comes back
    /// does not sweep from where it left).
    edge_world_mm: Option<[Vec3; 2]>,
    /// The shaft as the world gives it.
    pub shaft_spec: Option<crate::world::ShaftSpec>,
    /// The shaft (a capsule along the tool's z, from the origin up), which pushes tissue as the tip does.
    shaft: Option<ToolCollider>,
    /// Scissors' jaw opening at the end of the last tick, rad (None while inactive or not yet joined).
    blade_angle_rad: Option<f32>,
    /// The drag of the tissue this tool's edge cut last, N (its material's `cut_resistance_n`).
    cut_resistance_n: f32,
    /// The blade sweep's scratch.
    cut_scratch: CutScratch,
    /// The drag of cutting this tick, N (world frame, against the edge's motion).
    cut_force_n: Vec3,
    /// The edge is cutting: how recently it cut, 1 on a tick that cut, decaying with [`CUT_DRAG_TAU_S`]
    /// (the edge crosses the mesh's facets one at a time; the drag of cutting is felt in between).
    cut_level: f32,
    /// The edge moved this tick.
    edge_moving: bool,
    /// The tool has reached its hand since it was (re)taken: until then it is being dragged from its entry
    /// point, and a scalpel's edge does not cut along that path (the surgeon did not make it).
    joined: bool,
}

impl SimTool {
    /// The shaft's centre in the world, mm (the tool origin when it has none).
    fn shaft_centre_mm(&self) -> Vec3 {
        let half_mm = self.shaft_spec.map_or(0.0, |s| 0.5 * s.length_mm);
        self.position_mm + self.rotation * Vec3::new(0.0, 0.0, half_mm)
    }

    /// The latest finished contact-stiffness solve of this tool on object `object`.
    pub fn contact_response(&self, object: usize) -> Option<&crate::haptics::ContactResponse> {
        self.stiffness.get(object).and_then(|s| s.response())
    }

    /// The coupling parameters.
    pub fn coupling(&self) -> &CouplingParams {
        self.coupling.params()
    }

    /// A grasper's jaws (None for a probe).
    pub fn jaws(&self) -> Option<&Jaws> {
        self.jaws.as_ref()
    }

    /// What a grasper holds (None for a probe).
    pub fn grasp(&self) -> Option<&Grasp> {
        self.grasp.as_ref()
    }
}

/// What drives a tool this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolCommand {
    /// False releases the tool: it stops touching the tissue.
    pub active: bool,
    /// Device position in the device frame, mm.
    pub position_device_mm: [f32; 3],
    /// Device velocity in the device frame, mm/s.
    pub velocity_device_mm_s: [f32; 3],
    /// Device orientation, unit quaternion (x, y, z, w).
    pub orientation_xyzw: [f32; 4],
    /// The device's buttons and gripper angle (they open and close an instrument's jaws).
    pub jaws: JawInput,
}

impl Default for ToolCommand {
    fn default() -> Self {
        Self {
            active: false,
            position_device_mm: [0.0; 3],
            velocity_device_mm_s: [0.0; 3],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            jaws: JawInput::default(),
        }
    }
}

/// What a tool felt this tick, and the local model of the tissue around it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ToolOutput {
    /// Force the tissue exerts on the tool, world frame, N; finite, clamped to the tool's limit.
    pub force_world_n: Vec3,
    /// Tissue nodes held by the tool.
    pub held_nodes: u32,
    /// Touches tissue.
    pub in_contact: bool,
    /// The raw force exceeded the limit and was scaled down.
    pub clamped: bool,
    /// Tool origin after the coupling, world, mm (the model's `x0`).
    pub position_world_mm: Vec3,
    /// Tool velocity, world, mm/s.
    pub velocity_world_mm_s: Vec3,
    /// Where the device pose put the coupling's target, world, mm.
    pub device_world_mm: Vec3,
    /// The device's velocity, world, mm/s.
    pub device_velocity_world_mm_s: Vec3,
    /// Contact stiffness `K`, N/mm (symmetric positive semi-definite; zero out of contact).
    pub stiffness_n_per_mm: Matrix3<f32>,
    /// Contact damping `D`, N s/mm (symmetric positive semi-definite).
    pub damping_n_s_per_mm: Matrix3<f32>,
    /// Surfaces near the tool that it does not touch, world frame (the first `plane_count`).
    pub planes: [WorldPlane; MAX_PLANES],
    /// Planes in use.
    pub plane_count: u8,
    /// Energy this tool's device may output beyond its own input, mJ ([`EnergyBudget`]).
    pub energy_allowance_mj: f32,
    /// A grasper's jaws are closed.
    pub jaws_closed: bool,
    /// A grasper's jaw opening, rad (0 for a probe).
    pub jaw_angle_rad: f32,
    /// Points of tissue the jaws hold.
    pub attachments: u16,
    /// A cautery tool burnt tissue this tick.
    pub burning: bool,
    /// A scalpel's edge cut tissue this tick.
    pub cutting: bool,
}

/// Times the anti-divergence guard may halve a tick's step (down to 1/16 of the planned one) before it gives
/// up: a broken object is then reset to rest, a merely energetic one kept.
pub const MAX_HALVINGS: u32 = 4;

/// What happened in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepReport {
    /// Integrator substeps run (summed over objects, retries included).
    pub substeps: u32,
    /// Times the tick was rerun with its step halved because an object diverged.
    pub retries: u32,
    /// Solver iterations (CG, XPBD sweeps, relaxation sweeps) summed over objects and substeps.
    pub solver_iterations: u32,
    /// Objects still broken (non-finite or beyond the guard's absolute limits) at the smallest step, reset to
    /// rest this step.
    pub faults: u32,
    /// Nodes held by all tools.
    pub held_nodes: u32,
    /// Nodes integrated this tick by region-tracked objects (their active regions, summed).
    pub region_nodes: u32,
    /// Region sub-models rebuilt this tick (the active set changed).
    pub region_rebuilds: u32,
    /// Grasps that took hold this tick (jaws closed on tissue touching both).
    pub grasps_taken: u32,
    /// Jaws that closed this tick without tissue on both sides.
    pub grasps_missed: u32,
    /// Points of tissue let go by opening jaws (or a tool leaving) this tick.
    pub attachments_released: u32,
    /// Points of tissue that slipped out of the jaws this tick (pulled past the grasp's slip force).
    pub attachments_slipped: u32,
    /// Nodes a cautery tool burnt this tick (summed over tools).
    pub nodes_burnt: u32,
    /// Facets scalpels' edges cut this tick (a cut opens once it separates a vertex).
    pub seams_cut: u32,
    /// Springs of sheets stretched past their material's tear strain this tick.
    pub seams_torn: u32,
    /// Vertices split off by cuts and tears this tick.
    pub vertices_split: u32,
}

/// The whole simulated scene.
#[derive(Debug)]
pub struct Sim {
    /// Deformable objects, in world-file order.
    pub objects: Vec<SimObject>,
    /// Tools, in world-file order.
    pub tools: Vec<SimTool>,
    /// Tie-nodes between objects.
    pub ties: Vec<TieSet>,
    /// Energy at the end of the last tick (None after an outside change to a state, or a reset).
    last_energy_n_mm: Option<f64>,
    /// Work each tool does on the tissue, and the allowances it grants the others.
    budget: EnergyBudget,
    collision_margin_mm: f32,
    time_s: f64,
    steps: u64,
    /// The last step left work for its tail ([`Sim::finish_tick`]).
    tail_due: bool,
}

impl Sim {
    /// Build the simulation of a validated world.
    pub fn new(world: &World) -> Result<Self, SimBuildError> {
        let mut objects = Vec::with_capacity(world.objects.len());
        for spec in &world.objects {
            let model = MassSpringModel::build(spec, Vec3::from(world.gravity_mm_per_s2));
            let state = TissueState::at_rest(&model);
            let collider = SurfaceCollider::new(model.rest_positions_mm(), model.triangles())
                .map_err(|e| SimBuildError::Collider {
                    object: spec.name.clone(),
                    message: e.to_string(),
                })?
                .with_refit_margin(REFIT_MARGIN_MM);
            let region = match spec.region {
                None => None,
                Some(params) => {
                    let o = objects.len();
                    let refuse = |message: &str| SimBuildError::Region {
                        object: spec.name.clone(),
                        message: message.to_owned(),
                    };
                    if model.global_volume().is_some() {
                        return Err(refuse(
                            "the global volume term couples every surface node: turn one of them off",
                        ));
                    }
                    if world.gravity_mm_per_s2 != [0.0; 3] {
                        return Err(refuse(
                            "gravity moves the whole object, not a region: it needs sim.gravity_mm_per_s2 = 0",
                        ));
                    }
                    if world
                        .ties
                        .iter()
                        .any(|t| t.object_a == o || t.object_b == o)
                    {
                        return Err(refuse("tied objects move where ties pull them: untie it"));
                    }
                    if !(params.threshold_mm.is_finite() && params.threshold_mm > 0.0) {
                        return Err(refuse("threshold_mm must be a positive number"));
                    }
                    Some(RegionTracker::new(&model, params))
                }
            };
            objects.push(SimObject {
                region,
                burn: vec![0; model.node_count()],
                severed: Vec::new(),
                topology_version: 0,
                first_split_vertex: model.node_count() as u32,
                split_parents: Vec::new(),
                tear_strain: spec.material.tear_strain,
                cut_resistance_n: spec.material.cut_resistance_n,
                burn_shrink: spec.material.burn_shrink,
                friction: spec.material.friction_coefficient,
                torn: Vec::new(),
                lane: None,
                pins_held: spec.integrator == IntegratorName::ImplicitEuler,
                parts: ModelParts::default(),
                name: spec.name.clone(),
                marks: NodeMarks::new(model.node_count()),
                refit_due: false,
                integrator: integrator_for(spec.integrator, spec.solver_iterations),
                integrator_spec: (spec.integrator, spec.solver_iterations),
                guard: DivergenceGuard::new(&model),
                collider,
                state,
                model,
                max_dt_s: spec.dt_s,
            });
        }
        let mut tools = Vec::with_capacity(world.tools.len());
        for spec in &world.tools {
            let collider =
                ToolCollider::from_spec(&spec.shape).map_err(|e| SimBuildError::Collider {
                    object: spec.name.clone(),
                    message: format!("{e:?}"),
                })?;
            let reach_mm = {
                let aabb = collider.aabb(&Vec3::zeros(), &UnitQuaternion::identity(), 0.0);
                let (lo, hi) = (aabb.mins, aabb.maxs);
                (0..3)
                    .map(|a| lo[a].abs().max(hi[a].abs()).powi(2))
                    .sum::<f32>()
                    .sqrt()
            };
            // A scalpel's edge and scissors' blades reach beyond the body: they enter clear of the tissue too.
            let reach_mm = spec.instrument.scalpel().map_or(reach_mm, |s| {
                s.edge_mm
                    .iter()
                    .map(|p| Vec3::from(*p).norm())
                    .fold(reach_mm, f32::max)
            });
            let reach_mm = spec.instrument.scissors().map_or(reach_mm, |s| {
                s.blades_mm(s.open_angle_rad)
                    .iter()
                    .flatten()
                    .map(|p| Vec3::from(*p).norm())
                    .fold(reach_mm, f32::max)
            });
            let origin = Vec3::from(spec.device_origin_in_world_mm);
            let entry_mm = entry_point_mm(&origin, reach_mm, &objects);
            tools.push(SimTool {
                coupling: VirtualCoupling::new(spec.coupling, origin),
                device_mm: origin,
                device_velocity_mm_s: Vec3::zeros(),
                stiffness: objects
                    .iter()
                    .map(|o| ContactStiffness::new(o.model.node_count()))
                    .collect(),
                stiffness_due: vec![None; objects.len()],
                last_force_n: Vec3::zeros(),
                contact_k: Matrix3::zeros(),
                plane_stiffness_n_per_mm: PLANE_STIFFNESS_PRIOR_N_PER_MM,
                plane_damping_n_s_per_mm: 0.0,
                plane_candidates: Vec::with_capacity(8192),
                estimate: NormalStiffnessEstimate::default(),
                instrument: spec.instrument,
                jaw_input: JawInput::default(),
                jaws: spec
                    .instrument
                    .jaws()
                    .map(|(activation, open_rad)| Jaws::new(activation, open_rad)),
                grasp: spec
                    .instrument
                    .grasp()
                    .map(|g| Grasp::new(*g, objects.len())),
                grasp_force_n: Vec3::zeros(),
                edge_world_mm: None,
                shaft: spec.shaft.map(|s| {
                    ToolCollider::Capsule(parry3d::shape::Capsule::new_z(
                        0.5 * s.length_mm,
                        s.radius_mm,
                    ))
                }),
                shaft_spec: spec.shaft,
                blade_angle_rad: None,
                cut_resistance_n: 0.0,
                cut_scratch: CutScratch::default(),
                cut_force_n: Vec3::zeros(),
                cut_level: 0.0,
                edge_moving: false,
                joined: false,
                name: spec.name.clone(),
                device_id: spec.device_id.clone(),
                shape_spec: spec.shape.clone(),
                collider,
                device_origin_in_world_mm: Vec3::from(spec.device_origin_in_world_mm),
                max_force_n: spec.max_force_n,
                position_mm: Vec3::from(spec.device_origin_in_world_mm),
                rotation: UnitQuaternion::identity(),
                active: false,
                was_active: false,
                last_position_mm: Vec3::from(spec.device_origin_in_world_mm),
                reach_mm,
                entry_mm,
                contacts: objects
                    .iter()
                    .map(|o| {
                        let contacts = ProbeContacts::with_capacity(4096);
                        if o.pins_held {
                            contacts.sticky()
                        } else {
                            contacts
                        }
                    })
                    .collect(),
            });
        }
        // Multi-rate objects step as jobs that see each tool's body at its pose when the step leaves.
        let seeds: Vec<ToolSeed> = tools
            .iter()
            .map(|tool| ToolSeed {
                tip: tool.collider.clone(),
                shaft: tool
                    .shaft
                    .clone()
                    .zip(tool.shaft_spec.map(|s| 0.5 * s.length_mm)),
                max_force_n: tool.max_force_n,
                reach_mm: tool.reach_mm,
            })
            .collect();
        for object in objects.iter_mut().filter(|o| o.pins_held) {
            object.state.pinned = Vec::with_capacity(
                (4096 + usize::from(crate::interaction::MAX_ATTACHMENTS)) * tools.len(),
            );
        }
        for (object, spec) in objects.iter_mut().zip(&world.objects) {
            if spec.ticks_per_step > 1 {
                object.lane = Some(StepLane::new(
                    &object.model,
                    &object.state,
                    integrator_for(spec.integrator, spec.solver_iterations),
                    spec.dt_s,
                    object.friction,
                    spec.ticks_per_step,
                    &seeds,
                ));
            }
        }
        Ok(Self {
            budget: EnergyBudget::new(tools.len()),
            objects,
            tools,
            ties: world.ties.clone(),
            last_energy_n_mm: None,
            tail_due: false,
            collision_margin_mm: world.collision_margin_mm,
            time_s: 0.0,
            steps: 0,
        })
    }

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
    /// way (see [`crate::parallel`]): a recording replays the same on any thread count.
    pub fn set_chunk_runner(&mut self, runner: Option<Arc<dyn ChunkRunner>>) {
        for object in self.objects.iter_mut().filter(|o| o.lane.is_none()) {
            object.model.set_chunk_runner(runner.clone());
        }
    }

    /// Open `seams` in object `object` (see [`crate::tissue::seams`]): vertices whose ring the seams split are
    /// duplicated (new ids appended, each starting where its parent is, with its velocity and burn), elements
    /// keep their ids, and everything built on the object's topology is rebuilt for the new one: springs and
    /// masses, the collider's tree, the integrator's scratch, the region of deformation, the guard, and each
    /// tool's contact solver on it; grasps re-read the corners of the triangles they hold, so an attachment made
    /// before the cut holds on after it. Allocates (a cut or tear is an event, not the steady tick). An object
    /// index out of range, or seams that open nothing, change nothing.
    pub fn open_seams(&mut self, object: usize, seams: &[Facet]) -> Opening {
        // A multi-rate object's model is stepped on its own thread: it is never cut (see crate::multirate).
        let Some(o) = self.objects.get_mut(object).filter(|o| o.lane.is_none()) else {
            return Opening::default();
        };
        // A tear opens mid-tick: the collider first follows the tick's motion (the tree is kept across the
        // change, and the region it would refit by is rebuilt below).
        o.finish_refit();
        // Nothing new: the facets cut before and still joined did not open with this model, and will not now
        // (a blade sweeping again through a crack it made finds them again; no allocation).
        if seams.iter().all(|f| o.severed.binary_search(f).is_ok()) {
            return Opening::default();
        }
        // Facets cut before that have not come apart yet (a crack inside a volume, a slit that has not reached
        // a border) are cut still: they open with these once the cut separates something.
        let mut all = std::mem::take(&mut o.severed);
        all.extend_from_slice(seams);
        all.sort_unstable();
        all.dedup();
        let opening = open_model_into(&o.model, &all, &mut o.parts);
        if opening.is_empty() {
            all.retain(|f| shared_by_two(&o.model, f));
            o.severed = all;
            return opening;
        }
        // The model is rebuilt in place: its buffers are reused, not faulted in afresh.
        o.model.rebuild_from(&o.parts);
        let model = &o.model;
        let n = model.node_count();
        let state = &mut o.state;
        for &p in &opening.parents {
            let p = p as usize;
            let (x, v, b) = (state.positions_mm[p], state.velocities_mm_s[p], o.burn[p]);
            state.positions_mm.push(x);
            state.velocities_mm_s.push(v);
            o.burn.push(b);
        }
        state.forces_n.resize(n, Vec3::zeros());
        state.external_forces_n.resize(n, Vec3::zeros());
        let mut retargeted = opening.changed_triangles.clone();
        retargeted.sort_unstable();
        if o.collider
            .retopologize(&state.positions_mm, model.triangles(), &retargeted)
            .is_err()
            && let Ok(collider) = SurfaceCollider::new(&state.positions_mm, model.triangles())
        {
            o.collider = collider.with_refit_margin(REFIT_MARGIN_MM);
        }
        o.marks = NodeMarks::new(n);
        o.guard = DivergenceGuard::new(model);
        o.integrator = integrator_for(o.integrator_spec.0, o.integrator_spec.1);
        o.region = o
            .region
            .as_ref()
            .map(|r| RegionTracker::new(model, r.params()));
        for i in 0..n {
            if o.burn[i] > 0 {
                o.shrink_springs_of(i);
            }
        }
        o.topology_version += 1;
        o.split_parents.extend_from_slice(&opening.parents);
        all.retain(|f| shared_by_two(&o.model, f));
        o.severed = all;
        for tool in &mut self.tools {
            if let Some(stiffness) = tool.stiffness.get_mut(object) {
                *stiffness = ContactStiffness::new(n);
            }
            if let Some(grasp) = &mut tool.grasp {
                grasp.topology_changed(object, &self.objects[object].model);
            }
        }
        self.last_energy_n_mm = None;
        opening
    }

    /// Cut object `object` where a blade swept this tick ([`crate::interaction::swept_seams`] at the current
    /// positions, then [`Self::open_seams`]).
    pub fn cut(&mut self, object: usize, sweep: &BladeSweep, scratch: &mut CutScratch) -> Opening {
        let Some(o) = self.objects.get(object).filter(|o| o.lane.is_none()) else {
            scratch.seams.clear();
            return Opening::default();
        };
        let mut seams = std::mem::take(&mut scratch.seams);
        seams.clear();
        swept_seams(&o.model, &o.state.positions_mm, sweep, scratch, &mut seams);
        let opening = self.open_seams(object, &seams);
        scratch.seams = seams;
        opening
    }

    /// Tear object `object` wherever a spring is stretched past `max_strain`
    /// ([`crate::interaction::torn_seams`], then [`Self::open_seams`]).
    pub fn tear(&mut self, object: usize, max_strain: f32) -> Opening {
        let Some(o) = self.objects.get(object) else {
            return Opening::default();
        };
        let mut seams = Vec::new();
        torn_seams(&o.model, &o.state.positions_mm, max_strain, &mut seams);
        self.open_seams(object, &seams)
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
        // Scalpels cut what their edges swept since the last tick, before anything reads the topology.
        for t in 0..self.tools.len() {
            self.cut_with(t, dt_s, &mut report);
        }

        // Multi-rate objects due this tick take back their finished step (before the broad phase reads their
        // surfaces).
        let tick = self.steps;
        for (o, object) in self.objects.iter_mut().enumerate() {
            let Some(lane) = object.lane.as_mut().filter(|l| l.due(tick)) else {
                continue;
            };
            if let Some(job) = lane.collect(&mut object.state) {
                report.substeps += job.substeps;
                report.retries += job.retries;
                report.solver_iterations += job.solver_iterations;
                report.faults += job.faults;
                object.collider.refit(&object.state.positions_mm);
                if job.faults > 0 {
                    for tool in &mut self.tools {
                        tool.contacts[o].forget();
                    }
                }
            }
        }

        // Broad phase once per tick, on last tick's refitted surfaces, loosened by the margin.
        let margin = self.collision_margin_mm;
        for tool in &mut self.tools {
            let mut aabb = tool
                .collider
                .aabb(&tool.position_mm, &tool.rotation, margin);
            if let Some(shaft) = &tool.shaft {
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
                } else {
                    contacts.forget();
                }
            }
        }

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
                );
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
                if let Some(grasp) = &tool.grasp {
                    region.add_contacts(grasp.attached_nodes(o));
                }
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
        let mut halvings = 0;
        loop {
            let substeps = planned << halvings;
            self.run_substeps(dt_s / substeps as f32, substeps, &mut report);
            let (broken, energy_after) = self.assess();
            self.last_energy_n_mm = Some(energy_after);
            let verdict = if broken {
                Verdict::Broken
            } else if guard::energy_grew(energy_before, energy_after, work_allowance) {
                Verdict::Growing
            } else {
                Verdict::Fine
            };
            if verdict == Verdict::Fine {
                break;
            }
            if halvings == MAX_HALVINGS {
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
                            if let Some(grasp) = &mut tool.grasp
                                && !grasp.attached_nodes(o).is_empty()
                            {
                                report.attachments_released += grasp_released(grasp.release());
                            }
                        }
                        report.faults += 1;
                        self.last_energy_n_mm = None;
                    }
                }
                break;
            }
            for object in self.objects.iter_mut().filter(|o| o.lane.is_none()) {
                match &object.region {
                    Some(region) => object
                        .guard
                        .restore_nodes(&mut object.state, region.active_nodes()),
                    None => object.guard.restore(&mut object.state),
                }
            }
            halvings += 1;
            report.retries += 1;
        }
        // The colliders follow this tick's motion in the tail, after the forces are out: nothing between here and
        // the outputs needs them but the nearby-surface planes, whose candidates a tree one step old (fat leaves,
        // a look-ahead box) still finds; the next tick's broad phase sees them refitted, as before.
        for object in self.objects.iter_mut().filter(|o| o.lane.is_none()) {
            object.refit_due = true;
        }

        // Sheets overstretched this tick tear before the grasps measure their pull.
        for o in 0..self.objects.len() {
            let object = &mut self.objects[o];
            let Some(strain) = object.tear_strain else {
                continue;
            };
            let mut torn = std::mem::take(&mut object.torn);
            torn.clear();
            torn_seams(&object.model, &object.state.positions_mm, strain, &mut torn);
            // A capped number a tick (the first in spring order: deterministic), so a sheet pulled far past its
            // limit at once rips over a few ticks rather than in one long tick.
            torn.truncate(MAX_TEARS_PER_TICK);
            if !torn.is_empty() {
                report.seams_torn += torn.len() as u32;
                report.vertices_split += self.open_seams(o, &torn).new_vertices() as u32;
            }
            self.objects[o].torn = torn;
        }
        for t in 0..self.tools.len() {
            self.update_grasp(t, dt_s, &mut report);
        }
        for t in 0..self.tools.len() {
            let burnt = self.cauterize(t, dt_s);
            report.nodes_burnt += burnt;
            let mut out = self.tool_output(t);
            out.burning = burnt > 0;
            report.held_nodes += out.held_nodes;
            self.local_model(t, dt_s, &mut out);
            if let Some(slot) = outputs.get_mut(t) {
                *slot = out;
            }
        }
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
                    let Some(normal) = tool.stiffness_due.get_mut(o).and_then(Option::take) else {
                        continue;
                    };
                    let (Some(solver), Some(contacts)) =
                        (tool.stiffness.get_mut(o), tool.contacts.get(o))
                    else {
                        continue;
                    };
                    let grasped = tool.grasp.as_ref().map_or(&[][..], |g| g.attached_nodes(o));
                    solver.advance(
                        model,
                        state,
                        &contacts.held,
                        &contacts.normals,
                        grasped,
                        &normal,
                    );
                }
            });
        }
    }

    /// The tool's reaction force, clamped, and its contact state.
    fn tool_output(&self, t: usize) -> ToolOutput {
        let tool = &self.tools[t];
        let mut force = Vec3::zeros();
        let mut held = 0;
        for (object, contacts) in self.objects.iter().zip(&tool.contacts) {
            if let Some(lane) = &object.lane {
                // A multi-rate object pushes through its latest step's local model, at the tool's position now.
                let contact = lane.contact(t);
                let push = contact.force_at(&tool.position_mm);
                if tool.active && push != Vec3::zeros() {
                    force += push;
                    held += contact.held_nodes;
                }
                continue;
            }
            force += contacts.reaction_force_n(&object.model, &object.state, object.friction);
            held += contacts.held.len() as u32;
        }
        let attachments = tool
            .grasp
            .as_ref()
            .map_or(0, |g| g.attachments().len() as u16);
        force += tool.grasp_force_n + tool.cut_force_n;
        held += u32::from(attachments);
        let mut out = limit_force(force, tool.max_force_n, held);
        out.attachments = attachments;
        if let Some(jaws) = &tool.jaws {
            out.jaws_closed = jaws.closed();
            out.jaw_angle_rad = jaws.angle_rad();
        }
        out.cutting = tool.edge_moving && tool.cut_level > 0.5;
        out
    }

    /// A sharp instrument, once its tool has reached the hand (see `SimTool::joined`), cuts what its blades
    /// swept since the last tick ([`Self::cut`]): a scalpel's edge from where it was at the end of the last
    /// tick to where the tool now holds it, and scissors' blades through the part of their opening they closed
    /// this tick (in the tool's current pose: open scissors moved through tissue cut nothing). A scalpel's tool
    /// feels the drag of cutting against the edge's motion while it cuts (the tissue's `cut_resistance_n`,
    /// fading over [`CUT_DRAG_TAU_S`] after the last facet it cut). No allocation unless something is cut.
    fn cut_with(&mut self, t: usize, dt_s: f32, report: &mut StepReport) {
        let tool = &mut self.tools[t];
        tool.cut_force_n = Vec3::zeros();
        tool.cut_level *= (-dt_s / CUT_DRAG_TAU_S).exp();
        tool.edge_moving = false;
        let (scalpel, scissors) = (
            tool.instrument.scalpel().copied(),
            tool.instrument.scissors().copied(),
        );
        if scalpel.is_none() && scissors.is_none() {
            return;
        }
        if let (Some(jaws), Some(_)) = (&mut tool.jaws, scissors) {
            if tool.active {
                jaws.update(&tool.jaw_input, dt_s);
            } else {
                jaws.open();
            }
        }
        if !tool.active {
            tool.edge_world_mm = None;
            tool.blade_angle_rad = None;
            tool.cut_level = 0.0;
            return;
        }
        if !tool.joined {
            tool.joined = (tool.device_mm - tool.position_mm).norm() <= JOINED_MM;
            tool.edge_world_mm = None;
            tool.blade_angle_rad = None;
            if !tool.joined {
                return;
            }
        }
        let world = |p: [f32; 3]| tool.position_mm + tool.rotation * Vec3::from(p);
        if let Some(spec) = scalpel {
            let edge_now = spec.edge_mm.map(world);
            let Some(edge_before) = tool.edge_world_mm.replace(edge_now) else {
                return;
            };
            let sweep = BladeSweep {
                from_mm: edge_before,
                to_mm: edge_now,
            };
            let severed = self.cut_everything(t, &sweep, report);
            let tool = &mut self.tools[t];
            if severed > 0 {
                tool.cut_level = 1.0;
            }
            let motion = (edge_now[0] + edge_now[1] - edge_before[0] - edge_before[1]) * 0.5;
            if let Some(direction) = motion.try_normalize(MIN_CUT_SPEED_MM_S * dt_s) {
                tool.edge_moving = true;
                tool.cut_force_n = -direction * tool.cut_resistance_n * tool.cut_level;
            }
        } else if let (Some(spec), Some(jaws)) = (scissors, &tool.jaws) {
            let angle_rad = jaws.angle_rad();
            let Some(before_rad) = tool.blade_angle_rad.replace(angle_rad) else {
                return;
            };
            if angle_rad >= before_rad {
                return;
            }
            // Closing: each blade cuts the wedge of the opening it passed through. The resistance of a snip is
            // in the grip, which no device renders: the tool feels no drag.
            let (was, now) = (spec.blades_mm(before_rad), spec.blades_mm(angle_rad));
            let sweeps = [0, 1].map(|k| BladeSweep {
                from_mm: was[k].map(world),
                to_mm: now[k].map(world),
            });
            let mut severed = 0;
            for sweep in &sweeps {
                severed += self.cut_everything(t, sweep, report);
            }
            let tool = &mut self.tools[t];
            tool.edge_moving = true;
            if severed > 0 {
                tool.cut_level = 1.0;
            }
        }
    }

    /// Cut every object along one sweep of tool `t`'s blade; returns the seams cut, and takes the drag of the
    /// tissue cut (the last object that was).
    fn cut_everything(&mut self, t: usize, sweep: &BladeSweep, report: &mut StepReport) -> u32 {
        let mut scratch = std::mem::take(&mut self.tools[t].cut_scratch);
        let mut severed = 0;
        for o in 0..self.objects.len() {
            let opening = self.cut(o, sweep, &mut scratch);
            if !scratch.seams.is_empty() {
                severed += scratch.seams.len() as u32;
                self.tools[t].cut_resistance_n = self.objects[o].cut_resistance_n;
            }
            report.vertices_split += opening.new_vertices() as u32;
        }
        self.tools[t].cut_scratch = scratch;
        report.seams_cut += severed;
        severed
    }

    /// A cautery tool with its button held burns the surface it touches (the nodes on or within its reach of the
    /// body), by its rate times `dt_s`. Returns the nodes burnt. No allocation.
    fn cauterize(&mut self, t: usize, dt_s: f32) -> u32 {
        let tool = &self.tools[t];
        let Some(spec) = tool.instrument.cautery() else {
            return 0;
        };
        if !tool.active || tool.jaw_input.buttons & spec.button_mask == 0 {
            return 0;
        }
        // Fixed point: 256 units per burn level; at least one unit a tick so a slow rate still burns.
        let step = (spec.burn_per_s * dt_s * 256.0).clamp(1.0, 65535.0) as u16;
        let mut burnt = 0;
        let mut shrunk = false;
        for (o, object) in self.objects.iter_mut().enumerate() {
            for &node in &tool.contacts[o].candidates {
                let i = node as usize;
                let (Some(x), Some(level)) =
                    (object.state.positions_mm.get(i), object.burn.get_mut(i))
                else {
                    continue;
                };
                if tool
                    .collider
                    .distance_mm(&tool.position_mm, &tool.rotation, x)
                    <= spec.reach_mm + BITE_TOLERANCE_MM
                {
                    *level = level.saturating_add(step);
                    burnt += 1;
                    object.shrink_springs_of(i);
                    shrunk |= object.burn_shrink > 0.0;
                }
            }
        }
        if shrunk {
            // The rest lengths changed after the guard measured this tick's energy.
            self.last_energy_n_mm = None;
        }
        burnt
    }

    /// A grasper's jaws take this tick's input: on closing, take hold of the tissue the body touches (both
    /// jaws must touch it); on opening, let go; while holding, measure the pull and let slipping points go.
    fn update_grasp(&mut self, t: usize, dt_s: f32, report: &mut StepReport) {
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

    /// Complete `out` with the local model around tool `t` (contact stiffness and damping, nearby surfaces,
    /// the energy allowance) and remember what the coupling needs next tick. No allocation once warm.
    fn local_model(&mut self, t: usize, dt_s: f32, out: &mut ToolOutput) {
        let tool = &mut self.tools[t];
        let mut k = Matrix3::zeros();
        let mut d = Matrix3::zeros();
        let mut planes = [WorldPlane::default(); MAX_PLANES];
        let mut plane_count = 0usize;
        for (o, object) in self.objects.iter_mut().enumerate() {
            let contacts = &tool.contacts[o];
            let grasped = tool.grasp.as_ref().map_or(&[][..], |g| g.attached_nodes(o));
            let solver = &mut tool.stiffness[o];
            if !tool.active {
                solver.forget();
                continue;
            }
            let lane_contact = object
                .lane
                .as_ref()
                .map(|lane| lane.contact(t))
                .filter(|c| c.force_at(&tool.position_mm) != Vec3::zeros());
            if let Some(contact) = lane_contact {
                // A multi-rate object's contact stiffness was solved on its own thread, with its step.
                if contact.solved {
                    k += contact.stiffness_matrix();
                    d += contact.damping_matrix();
                } else {
                    let n = contact.normal;
                    k += n * n.transpose() * tool.plane_stiffness_n_per_mm;
                    d += n * n.transpose() * tool.plane_damping_n_s_per_mm;
                }
                continue;
            }
            if contacts.held.is_empty() && grasped.is_empty() {
                solver.forget();
                if plane_count < MAX_PLANES
                    && let Some(plane) = nearest_surface_plane(
                        &tool.collider,
                        &tool.position_mm,
                        &tool.rotation,
                        PLANE_LOOK_AHEAD_MM,
                        &object.model,
                        &object.state,
                        &object.collider,
                        &mut object.marks,
                        &mut tool.plane_candidates,
                    )
                {
                    planes[plane_count] = WorldPlane {
                        stiffness_n_per_mm: tool.plane_stiffness_n_per_mm,
                        damping_n_s_per_mm: tool.plane_damping_n_s_per_mm,
                        ..plane
                    };
                    plane_count += 1;
                }
                continue;
            }
            let first = contacts
                .held
                .first()
                .or(grasped.first())
                .copied()
                .unwrap_or(0);
            let normal = out.force_world_n.try_normalize(1e-9).unwrap_or_else(|| {
                object
                    .model
                    .rest_normals()
                    .get(first as usize)
                    .copied()
                    .unwrap_or_else(Vec3::z)
            });
            // The solver's next iterations belong to the tick's tail: they read this tick's final state and
            // contacts and refine K for the next ticks, so they run after this tick's forces are published.
            tool.stiffness_due[o] = Some(normal);
            self.tail_due = true;
            match solver.response() {
                Some(response) => {
                    k += response.stiffness_n_per_mm;
                    d += response.damping_n_s_per_mm;
                }
                None => {
                    // First ticks of a contact, before the solve finishes: the last measured normal
                    // stiffness of this tool along the contact normal.
                    if let Some(n) = out.force_world_n.try_normalize(1e-9) {
                        k += n * n.transpose() * tool.plane_stiffness_n_per_mm;
                        d += n * n.transpose() * tool.plane_damping_n_s_per_mm;
                    }
                }
            }
        }
        if let Some(n) = out.force_world_n.try_normalize(1e-9)
            && out.in_contact
            && tool.active
        {
            // The normal stiffness the tissue actually shows, capped by the frozen-contact solve.
            tool.estimate
                .record(-n.dot(&tool.position_mm), n.dot(&out.force_world_n), dt_s);
            // K is rank one along the CURRENT contact normal (the solve may have started on an older one).
            let solved = (n.transpose() * k * n)[(0, 0)].max(0.0);
            let kn = tool.estimate.stiffness_n_per_mm(solved).unwrap_or(solved);
            k = n * n.transpose() * kn;
            let dn = (n.transpose() * d * n)[(0, 0)].max(0.0);
            d = n * n.transpose() * dn;
            if kn.is_finite() && kn > 0.0 {
                tool.plane_stiffness_n_per_mm = kn;
                tool.plane_damping_n_s_per_mm = (n.transpose() * d * n)[(0, 0)].max(0.0);
            }
        }
        if !out.in_contact || !tool.active {
            tool.estimate.reset();
        }
        tool.contact_k = k;
        tool.last_force_n = out.force_world_n;
        if tool.active {
            let step = tool.position_mm - tool.last_position_mm;
            self.budget.record(t, &out.force_world_n, &step, dt_s);
        } else {
            self.budget.release(t);
        }
        let tool = &self.tools[t];
        out.position_world_mm = tool.position_mm;
        out.velocity_world_mm_s = tool.coupling.velocity_mm_s();
        out.device_world_mm = tool.device_mm;
        out.device_velocity_world_mm_s = tool.device_velocity_mm_s;
        out.stiffness_n_per_mm = k;
        out.damping_n_s_per_mm = d;
        out.planes = planes;
        out.plane_count = plane_count as u8;
        out.energy_allowance_mj = self.budget.allowance_mj(t) as f32;
    }

    /// The guard's measurements over every object: whether any is broken, and the mechanical energy of the
    /// objects that are not region-tracked plus the ties', N mm (a region-tracked object is judged by the
    /// absolute tests over its active nodes only: a whole-object energy pass would cost what region tracking
    /// saves).
    fn assess(&self) -> (bool, f64) {
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
    fn tool_work_allowance_n_mm(&self) -> f64 {
        self.tools
            .iter()
            .filter(|t| t.active)
            .map(|t| {
                let travel_mm = if t.was_active {
                    (t.position_mm - t.last_position_mm).norm()
                } else {
                    t.reach_mm
                };
                guard::tool_work_allowance_n_mm(t.max_force_n, travel_mm)
            })
            .sum()
    }

    /// `substeps` steps of `h` for every object: ties, integrate, push out of the tools.
    fn run_substeps(&mut self, h: f32, substeps: u32, report: &mut StepReport) {
        for _ in 0..substeps {
            if !self.ties.is_empty() {
                // Region-tracked objects are never tied (refused at build): their external forces stay zero.
                for object in self.objects.iter_mut().filter(|o| o.region.is_none()) {
                    object.state.external_forces_n.fill(Vec3::zeros());
                }
                for tie in &self.ties {
                    let (a, b) = (tie.object_a, tie.object_b);
                    let (first, second) = self.objects.split_at_mut(a.max(b));
                    let (low, high) = (&mut first[a.min(b)], &mut second[0]);
                    if a < b {
                        tie.accumulate(&mut low.state, &mut high.state);
                    } else {
                        tie.accumulate(&mut high.state, &mut low.state);
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
                        if let Some(grasp) = &tool.grasp {
                            object
                                .state
                                .pinned
                                .extend_from_slice(grasp.attached_nodes(o));
                        }
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

    /// Device poses move the tools through their couplings (a tool that just became active starts at its
    /// device pose).
    fn apply_commands(&mut self, dt_s: f32, commands: &[ToolCommand]) {
        for tool in &mut self.tools {
            tool.was_active = tool.active;
            tool.last_position_mm = tool.position_mm;
        }
        for (t, tool) in self.tools.iter_mut().enumerate() {
            let Some(command) = commands.get(t) else {
                tool.active = false;
                continue;
            };
            let p = command.position_device_mm;
            let v = command.velocity_device_mm_s;
            let q = command.orientation_xyzw;
            let finite = p
                .iter()
                .chain(v.iter())
                .chain(q.iter())
                .all(|c| c.is_finite());
            let norm = q.iter().map(|c| c * c).sum::<f32>().sqrt();
            if !command.active || !finite || norm.is_nan() || norm <= 0.5 {
                tool.active = false;
                continue;
            }
            tool.jaw_input = command.jaws;
            tool.device_mm = tool.device_origin_in_world_mm + Vec3::from(p);
            tool.device_velocity_mm_s = Vec3::from(v);
            if tool.active {
                tool.position_mm = tool.coupling.step(
                    dt_s,
                    &tool.device_mm,
                    &tool.device_velocity_mm_s,
                    &tool.last_force_n,
                    &tool.contact_k,
                );
            } else {
                // (Re)taken: enter from outside the tissue, never at the device pose, which may lie in or beyond
                // a surface (a device that rejoins while pressing, or a pose that jumped while nobody drove
                // the tool). The coupling brings it to the pose at its speed limit.
                tool.coupling.reset(tool.entry_mm);
                tool.joined = false;
                tool.position_mm = tool.entry_mm;
                tool.last_position_mm = tool.entry_mm;
                tool.last_force_n = Vec3::zeros();
                tool.contact_k = Matrix3::zeros();
            }
            tool.active = true;
            tool.rotation =
                UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]));
        }
    }
}

/// How long the drag of cutting lasts after the edge last cut a facet, s (time constant of its decay): at a
/// steady 10-20 mm/s the edge crosses a 1 mm mesh's facets every 50-100 ms, and the drag holds in between.
const CUT_DRAG_TAU_S: f32 = 0.1;

/// An edge slower than this, mm/s, is held still: it feels no drag and is not cutting (the coupled tool still
/// settles by micrometres after the hand stops).
const MIN_CUT_SPEED_MM_S: f32 = 1.0;

/// Most facets one object tears open in one tick.
const MAX_TEARS_PER_TICK: usize = 32;

/// A (re)taken tool has joined its hand once it is this close to the device pose, mm: the coupling's lag under a
/// hard press is under 1 mm (3.3 N at 5 N/mm).
const JOINED_MM: f32 = 1.0;

/// Where a tool with origin `origin` and reach `reach_mm` enters the scene: `origin` if no rest node lies within
/// its reach plus a 2 mm margin, else `origin` moved along the mean outward rest normal of those nodes, 1 mm at a
/// time (at most 200 mm), until none does. Pure; runs once per tool when the simulation is built.
fn entry_point_mm(origin: &Vec3, reach_mm: f32, objects: &[SimObject]) -> Vec3 {
    let clearance = reach_mm + 2.0;
    let near = |p: &Vec3| {
        objects.iter().any(|o| {
            o.model
                .rest_positions_mm()
                .iter()
                .any(|x| (x - p).norm() < clearance)
        })
    };
    if !near(origin) {
        return *origin;
    }
    let mut outward = Vec3::zeros();
    for o in objects {
        for (x, n) in o
            .model
            .rest_positions_mm()
            .iter()
            .zip(o.model.rest_normals())
        {
            if (x - origin).norm() < clearance {
                outward += n;
            }
        }
    }
    let Some(up) = outward.try_normalize(1e-6) else {
        return *origin;
    };
    (1..=200)
        .map(|mm| origin + up * mm as f32)
        .find(|p| !near(p))
        .unwrap_or(*origin)
}

/// Push object `o`'s tissue out of every active tool and hold what each grasper holds on its jaws.
fn hold_in_tools(tools: &mut [SimTool], o: usize, object: &mut SimObject) {
    for tool in tools.iter_mut().filter(|t| t.active) {
        let grasped = tool.grasp.as_ref().map_or(&[][..], |g| g.attached_nodes(o));
        let half_mm = tool.shaft_spec.map_or(0.0, |s| 0.5 * s.length_mm);
        let body = ToolBody::posed(
            &tool.collider,
            tool.shaft.as_ref().map(|s| (s, half_mm)),
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
        if let Some(grasp) = &tool.grasp {
            grasp.hold(
                o,
                &tool.position_mm,
                &tool.rotation,
                &object.model,
                &mut object.state,
            );
        }
    }
}

/// How many points a release let go.
fn grasp_released(event: GraspEvent) -> u32 {
    match event {
        GraspEvent::Released(n) => u32::from(n),
        _ => 0,
    }
}

/// Clamp to `max_force_n`, and never pass a non-finite force. Pure.
fn limit_force(force: Vec3, max_force_n: f32, held: u32) -> ToolOutput {
    let mut out = ToolOutput {
        held_nodes: held,
        in_contact: held > 0,
        ..ToolOutput::default()
    };
    if !force.iter().all(|c| c.is_finite()) {
        out.clamped = true;
        return out;
    }
    let magnitude = force.norm();
    if magnitude > max_force_n {
        out.force_world_n = force * (max_force_n / magnitude);
        out.clamped = true;
    } else {
        out.force_world_n = force;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limit_force_clamps_and_drops_non_finite() {
        let out = limit_force(Vec3::new(0.0, 0.0, 10.0), 3.0, 4);
        assert!((out.force_world_n.norm() - 3.0).abs() < 1e-5 && out.clamped && out.in_contact);
        let out = limit_force(Vec3::new(f32::NAN, 0.0, 1.0), 3.0, 1);
        assert_eq!(out.force_world_n, Vec3::zeros());
        let out = limit_force(Vec3::new(0.0, 1.0, 0.0), 3.0, 0);
        assert!(!out.clamped && !out.in_contact && out.force_world_n.y == 1.0);
    }
}
