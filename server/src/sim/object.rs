//! One deformable object in the simulation: its model, state, integrator, guard, collider, region, lane,
//! burn and topology bookkeeping.
//!
//! Owns: [`SimObject`]. Must not: step itself (the tick's pipeline in [`super`] does).

use crate::collision::{NodeMarks, SurfaceCollider};
use crate::multirate::StepLane;
use crate::tissue::IntegratorName;
use crate::tissue::seams::Facet;
use crate::tissue::{
    DivergenceGuard, Integrator, MassSpringModel, ModelParts, RegionTracker, TissueState, Vec3,
    integrator_for,
};

/// One deformable object in the simulation.
#[derive(Debug)]
pub struct SimObject {
    /// Name from the world file.
    pub name: String,
    /// Topology and material.
    pub model: MassSpringModel,
    /// Positions and velocities.
    pub state: TissueState,
    pub(super) integrator: Box<dyn Integrator>,
    /// The integrator as the world names it, to make a fresh one after a topology change.
    pub(super) integrator_spec: (IntegratorName, Option<u32>),
    pub(super) guard: DivergenceGuard,
    pub(super) collider: SurfaceCollider,
    pub(super) marks: NodeMarks,
    pub(super) max_dt_s: f32,
    /// Some when only the region of deformation is integrated.
    pub(super) region: Option<RegionTracker>,
    /// How burnt each node is, 0 (untouched) to 65535 (charred): the wire's 0-255 level is the high byte.
    /// Material damage: a reset to rest keeps it.
    pub(super) burn: Vec<u16>,
    /// Facets a blade or a tear has cut that still join two elements, sorted: they open as soon as the cut
    /// around them separates a vertex (see [`Sim::open_seams`]).
    pub(super) severed: Vec<Facet>,
    /// Topology changes so far (0: the world's mesh as loaded).
    pub(super) topology_version: u32,
    /// The world mesh's vertex count: vertices from here on were split off a parent by a cut or tear.
    pub(super) first_split_vertex: u32,
    /// The parent of each split vertex, in id order.
    pub(super) split_parents: Vec<u32>,
    /// The material's tear strain (the tissue tears where a spring is stretched past it); `None`: never tears.
    pub(super) tear_strain: Option<f32>,
    /// The material's drag against a sharp edge cutting it, N.
    pub(super) cut_resistance_n: f32,
    /// A blade splits the edges it crosses (see [`crate::tissue::subdivision`]) rather than opening facets.
    pub(super) cut_follows_blade: bool,
    /// The uncut model's largest stiffness rate (`subdivision::rate_ceiling`), taken at its first cut that
    /// follows the blade: no vertex a cut touches is left stiffer for its mass.
    pub(super) rate_ceiling: Option<f32>,
    /// The share of rest length a spring between two fully burnt nodes loses (0: burns do not shrink).
    pub(super) burn_shrink: f32,
    /// Coulomb friction between a tool and this tissue (0: frictionless).
    pub(super) friction: f32,
    /// How it answers a suture needle.
    pub(super) puncture: crate::tissue::PunctureSpec,
    /// Nodes tied to another object (`tissue::ties`), sorted: a cut that follows the blade never moves them
    /// (a tie holds a node by its id and its rest place).
    pub(super) tied: Vec<u32>,
    /// Scratch of a topology change: the parts the model is rebuilt from.
    pub(super) parts: ModelParts,
    /// Scratch of the tear test: the facets torn this tick.
    pub(super) torn: Vec<Facet>,
    /// Some when the object steps at its own, lower rate (`step_hz`): its steps run as jobs, and `state` is
    /// the latest finished step's (see [`crate::multirate`]).
    pub(super) lane: Option<StepLane>,
    /// The integrator solves with the tools' held nodes pinned (implicit Euler): each substep pushes out
    /// first, then integrates, and the contacts are sticky.
    pub(super) pins_held: bool,
    /// Tools keep its surface's triangles out of their tips too (`ObjectSpec::triangle_contact`).
    pub(super) triangle_contact: bool,
    /// The collider has not followed this tick's motion yet (it does in the tick's tail, after the forces).
    pub(super) refit_due: bool,
}

impl SimObject {
    /// Refit the collider to the positions, if this tick's refit is still due: the moved nodes' triangles for a
    /// region object (only its active nodes moved), every leaf otherwise.
    pub(super) fn finish_refit(&mut self) {
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

    /// After the model was rebuilt for a new topology: the state's force buffers sized to it, and what stands
    /// on the topology built again (node marks, guard, a fresh integrator, the region of deformation, burnt
    /// nodes' shrunk springs); the topology version moves on. Allocates: a topology change is an event.
    pub(super) fn rebuilt_for_topology(&mut self) {
        let n = self.model.node_count();
        self.state.forces_n.resize(n, Vec3::zeros());
        self.state.external_forces_n.resize(n, Vec3::zeros());
        self.marks = NodeMarks::new(n);
        self.remake_for_model();
        for i in 0..n {
            if self.burn[i] > 0 {
                self.shrink_springs_of(i);
            }
        }
        self.topology_version += 1;
    }

    /// What is built from the model's nodes and springs made again for it (after its topology or masses
    /// changed): the guard, a fresh integrator, the region of deformation.
    pub(super) fn remake_for_model(&mut self) {
        if let Some(lane) = &mut self.lane {
            // Its step job takes the new model at the next hand-off.
            lane.topology_mut().model_changed();
        }
        self.guard = DivergenceGuard::new(&self.model);
        self.integrator = integrator_for(self.integrator_spec.0, self.integrator_spec.1);
        self.region = self
            .region
            .as_ref()
            .map(|r| RegionTracker::new(&self.model, r.params()));
    }

    /// The integrator's name.
    pub fn integrator_name(&self) -> &'static str {
        self.integrator.name()
    }

    /// The region of deformation, when the object is region-tracked.
    pub fn region(&self) -> Option<&RegionTracker> {
        self.region.as_ref()
    }

    /// What its material does against a suture's needle and thread.
    pub fn puncture_spec(&self) -> &crate::tissue::PunctureSpec {
        &self.puncture
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
    pub(super) fn shrink_springs_of(&mut self, i: usize) {
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
    pub(super) fn integrate(&mut self, h: f32) -> u32 {
        match &mut self.region {
            Some(region) => region.step(self.integrator.as_mut(), &mut self.state, h),
            None => self.integrator.step(&self.model, &mut self.state, h),
        }
    }

    /// The guard's absolute test on this tick: over the active region only when region-tracked (nothing
    /// else moved).
    pub(super) fn broken(&self) -> bool {
        match &self.region {
            Some(region) => {
                self.guard
                    .broken_nodes(&self.model, &self.state, region.active_nodes())
            }
            None => self.guard.assess(&self.model, &self.state).broken,
        }
    }
}

/// `collider` re-pointed at `triangles` (the triangles `retargeted`, sorted, changed corners; any past the old
/// count are new), at `positions_mm`; built afresh if its tree cannot take the change.
pub(super) fn retopologize_collider(
    collider: &mut SurfaceCollider,
    positions_mm: &[Vec3],
    triangles: &[[u32; 3]],
    retargeted: &[u32],
) {
    if collider
        .retopologize(positions_mm, triangles, retargeted)
        .is_err()
        && let Ok(fresh) = SurfaceCollider::new(positions_mm, triangles)
    {
        *collider = fresh.with_refit_margin(super::REFIT_MARGIN_MM);
    }
}
