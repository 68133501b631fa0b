//! Building the simulation from a scene descriptor ([`crate::scene::World`], from a world file or built in
//! code): objects (model, collider, region, lane), tools (colliders, coupling, instruments, entry points) and
//! ties.
//!
//! Owns: [`Sim::new`] and where a tool enters the scene. Must not: step anything.

use nalgebra::{Matrix3, UnitQuaternion};

use crate::collision::{NodeMarks, SurfaceCollider, ToolCollider};
use crate::haptics::{
    ContactStiffness, EnergyBudget, KineticFrictionEstimate, NormalStiffnessEstimate,
    VirtualCoupling,
};
use crate::interaction::{JawInput, ProbeContacts};
use crate::multirate::{StepLane, ToolSeed};
use crate::scene::World;
use crate::tissue::IntegratorName;
use crate::tissue::{
    DivergenceGuard, MassSpringModel, ModelParts, RegionTracker, TissueState, Vec3, integrator_for,
};

use super::*;

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
                cut_follows_blade: spec.material.cut_follows_blade,
                rate_ceiling: None,
                burn_shrink: spec.material.burn_shrink,
                friction: spec.material.friction_coefficient,
                puncture: spec.material.puncture,
                torn: Vec::new(),
                lane: None,
                pins_held: spec.integrator == IntegratorName::ImplicitEuler,
                triangle_contact: spec.triangle_contact,
                tied: Vec::new(),
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
            let reach_mm = spec.instrument.reach_mm(reach_mm);
            let origin = Vec3::from(spec.device_origin_in_world_mm);
            let entry_mm = entry_point_mm(&origin, reach_mm, &objects);
            tools.push(SimTool {
                name: spec.name.clone(),
                device_id: spec.device_id.clone(),
                shape_spec: spec.shape.clone(),
                shaft_spec: spec.shaft,
                instrument: spec.instrument,
                device_origin_in_world_mm: Vec3::from(spec.device_origin_in_world_mm),
                max_force_n: spec.max_force_n,
                position_mm: Vec3::from(spec.device_origin_in_world_mm),
                rotation: UnitQuaternion::identity(),
                active: false,
                body: ToolBody {
                    collider,
                    shaft: spec.shaft.map(|s| {
                        ToolCollider::Capsule(parry3d::shape::Capsule::new_z(
                            0.5 * s.length_mm,
                            s.radius_mm,
                        ))
                    }),
                    reach_mm,
                },
                drive: ToolDrive {
                    coupling: VirtualCoupling::new(spec.coupling, origin),
                    device_mm: origin,
                    device_velocity_mm_s: Vec3::zeros(),
                    jaw_input: JawInput::default(),
                    was_active: false,
                    last_position_mm: Vec3::from(spec.device_origin_in_world_mm),
                    entry_mm,
                    joined: false,
                },
                contacts: objects
                    .iter()
                    .map(|o| {
                        // A grasper's jaws bite the nodes by its tip: it keeps node contact
                        // (`StepLane::with_triangle_contact`).
                        let contacts = ProbeContacts::with_capacity(4096).with_triangles(
                            o.triangle_contact && spec.instrument.grasp().is_none(),
                        );
                        if o.pins_held {
                            contacts.sticky()
                        } else {
                            contacts
                        }
                    })
                    .collect(),
                haptic: ToolHaptics {
                    stiffness: objects
                        .iter()
                        .map(|o| ContactStiffness::new(o.model.node_count()))
                        .collect(),
                    stiffness_due: vec![None; objects.len()],
                    last_force_n: Vec3::zeros(),
                    contact_k: Matrix3::zeros(),
                    plane_stiffness_n_per_mm: PLANE_STIFFNESS_PRIOR_N_PER_MM,
                    plane_damping_n_s_per_mm: 0.0,
                    plane_measured: false,
                    // Each built on its own (a clone of an empty Vec drops its capacity).
                    touchdown: (0..objects.len())
                        .map(|_| crate::haptics::Touchdown::default())
                        .collect(),
                    touchdown_plane: None,
                    lane_planes: vec![crate::multirate::LanePlane::default(); objects.len()],
                    plane_candidates: Vec::with_capacity(8192),
                    estimate: NormalStiffnessEstimate::default(),
                    friction: KineticFrictionEstimate::default(),
                },
                instrument_state: instrument::build_instrument(
                    &spec.instrument,
                    objects.len(),
                    Vec3::from(world.gravity_mm_per_s2),
                ),
            });
        }
        // Multi-rate objects step as jobs that see each tool's body at its pose when the step leaves.
        let seeds: Vec<ToolSeed> = tools
            .iter()
            .map(|tool| ToolSeed {
                tip: tool.body.collider.clone(),
                shaft: tool
                    .body
                    .shaft
                    .clone()
                    .zip(tool.shaft_spec.map(|s| 0.5 * s.length_mm)),
                max_force_n: tool.max_force_n,
                reach_mm: tool.body.reach_mm,
                grasps: tool.instrument.grasp().is_some(),
            })
            .collect();
        for tie in &world.ties {
            for &(a, b, _) in &tie.pairs {
                if let Some(o) = objects.get_mut(tie.object_a) {
                    o.tied.push(a);
                }
                if let Some(o) = objects.get_mut(tie.object_b) {
                    o.tied.push(b);
                }
            }
        }
        for object in &mut objects {
            object.tied.sort_unstable();
            object.tied.dedup();
        }
        for object in objects.iter_mut().filter(|o| o.pins_held) {
            object.state.pinned = Vec::with_capacity(
                (4096 + usize::from(crate::interaction::MAX_ATTACHMENTS)) * tools.len(),
            );
        }
        for (object, spec) in objects.iter_mut().zip(&world.objects) {
            if spec.ticks_per_step > 1 {
                object.lane = Some(
                    StepLane::new(
                        &object.model,
                        &object.state,
                        integrator_for(spec.integrator, spec.solver_iterations),
                        spec.dt_s,
                        object.friction,
                        spec.ticks_per_step,
                        &seeds,
                    )
                    .with_triangle_contact(spec.triangle_contact),
                );
            }
        }
        // A multi-rate object's touch-down solves run on the tick's tail over its mirror, as far out as its
        // step's own solves reach (on a coarse organ 8 rings take in half of it).
        for (o, spec) in world.objects.iter().enumerate() {
            if spec.ticks_per_step > 1 {
                for tool in &mut tools {
                    if let Some(solver) = tool.haptic.stiffness.get_mut(o) {
                        *solver = ContactStiffness::new(objects[o].model.node_count())
                            .with_rings(crate::multirate::SOLVE_RINGS);
                    }
                }
            }
        }
        let mut sim = Self {
            budget: EnergyBudget::new(tools.len()),
            knots: super::knot_watch::KnotWatch::new(tools.len()),
            objects,
            tools,
            ties: world.ties.clone(),
            pairs: super::tissue_contact::tissue_pairs(world, world.collision_margin_mm),
            last_energy_n_mm: None,
            tail_due: false,
            openings: 0,
            hole_tear_scratch: crate::interaction::CutScratch::default(),
            wound: world.exercise.as_ref().and_then(|e| e.wound),
            pattern: world
                .exercise
                .as_ref()
                .and_then(|e| e.pattern)
                .map(super::pattern_watch::PatternWatch::new),
            collision_margin_mm: world.collision_margin_mm,
            time_s: 0.0,
            steps: 0,
        };
        // The pattern's first reading, so that no tick allocates for it before a cut.
        sim.pattern_cut_now();
        Ok(sim)
    }
}

/// Where a tool with origin `origin` and reach `reach_mm` enters the scene: `origin` if no rest node lies within
/// its reach plus a 2 mm margin, else `origin` moved along the mean outward rest normal of those nodes, 1 mm at a
/// time (at most 200 mm), until none does. Pure; runs once per tool when the simulation is built.
pub(super) fn entry_point_mm(origin: &Vec3, reach_mm: f32, objects: &[SimObject]) -> Vec3 {
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
