//! One tool in the simulation and what crosses the step's boundary for it: its command in, its output out.
//!
//! Owns: [`SimTool`] and its components ([`ToolBody`], [`ToolDrive`], [`ToolHaptics`]; its contacts and its
//! instrument's state), [`ToolCommand`] and
//! [`ToolOutput`]. Must not: step anything.

use nalgebra::{Matrix3, UnitQuaternion};

use crate::collision::ToolCollider;
use crate::collision::ToolShapeSpec;
use crate::haptics::{
    ContactStiffness, CouplingParams, KineticFrictionEstimate, MAX_PLANES, NormalStiffnessEstimate,
    VirtualCoupling, WorldPlane,
};
use crate::interaction::InstrumentSpec;
use crate::interaction::{Grasp, JawInput, Jaws, ProbeContacts};
use crate::tissue::Vec3;

/// One tool in the simulation: what it is and where it is (public), and its components: its rigid body, how
/// it follows its device, its contacts, its haptic state and its instrument.
#[derive(Debug)]
pub struct SimTool {
    /// Name from the world file.
    pub name: String,
    /// Bound device id.
    pub device_id: String,
    /// Shape as specified.
    pub shape_spec: ToolShapeSpec,
    /// The shaft as the world gives it.
    pub shaft_spec: Option<crate::collision::ShaftSpec>,
    /// What the tool is beyond its body (a probe, a grasper).
    pub instrument: InstrumentSpec,
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
    /// Its rigid body.
    pub(super) body: ToolBody,
    /// How it follows its device.
    pub(super) drive: ToolDrive,
    /// One contact set per object.
    pub(super) contacts: Vec<ProbeContacts>,
    /// What the tissue answers it, kept for the coupling and the local model.
    pub(super) haptic: ToolHaptics,
    /// The instrument's implementation and state (`None`: a probe, or the instrument is out running a hook,
    /// [`Sim::with_instrument`]).
    pub(super) instrument_state: Option<Box<dyn super::instrument::Instrument>>,
}

/// A tool's rigid body.
#[derive(Debug)]
pub(super) struct ToolBody {
    /// The tip's collision shape.
    pub(super) collider: ToolCollider,
    /// The shaft (a capsule along the tool's z, from the origin up), which pushes tissue as the tip does.
    pub(super) shaft: Option<ToolCollider>,
    /// Largest distance from the tool origin to its surface (or its instrument's blades), mm.
    pub(super) reach_mm: f32,
}

/// How a tool follows its device: the coupling, the device's pose this tick and the tool's last.
#[derive(Debug)]
pub(super) struct ToolDrive {
    /// How the tool follows its device pose.
    pub(super) coupling: VirtualCoupling,
    /// Device pose (target of the coupling) this tick, world, mm and mm/s.
    pub(super) device_mm: Vec3,
    pub(super) device_velocity_mm_s: Vec3,
    /// The device's buttons and jaw angle this tick.
    pub(super) jaw_input: JawInput,
    /// Active on the previous tick.
    pub(super) was_active: bool,
    /// Origin on the previous tick, mm.
    pub(super) last_position_mm: Vec3,
    /// Where the tool enters the scene each time a device (re)takes it, world, mm: the device origin lifted
    /// along the nearby tissue's outward rest normal until the tool clears every node ([`entry_point_mm`]).
    /// From there the coupling brings it to the device pose at its speed limit, so it meets every surface
    /// from outside: a device that (re)joins pressing into a thin sheet never finds its tool under it.
    pub(super) entry_mm: Vec3,
    /// The tool has reached its hand since it was (re)taken: until then it is being dragged from its entry
    /// point, and a blade does not cut along that path (the surgeon did not make it).
    pub(super) joined: bool,
}

/// What the tissue answers a tool, kept between ticks: the coupling's inputs, the contact-stiffness solves,
/// the planes' stiffness.
#[derive(Debug)]
pub(super) struct ToolHaptics {
    /// One contact-stiffness solver per object.
    pub(super) stiffness: Vec<ContactStiffness>,
    /// Per object: the contact normal of a solver iteration due after this tick's forces went out (the tick's
    /// tail, [`Sim::finish_tick`]), if one is.
    pub(super) stiffness_due: Vec<Option<Vec3>>,
    /// Tissue force on the tool and contact stiffness at the end of the last tick (the coupling's input).
    pub(super) last_force_n: Vec3,
    pub(super) contact_k: Matrix3<f32>,
    /// Normal stiffness and damping of this tool's last measured contact (the planes' stiffness).
    pub(super) plane_stiffness_n_per_mm: f32,
    pub(super) plane_damping_n_s_per_mm: f32,
    /// This tool has measured a contact: its planes carry that contact's stiffness. Before, each plane
    /// carries the stiffness of a touch-down at the plane's node (below).
    pub(super) plane_measured: bool,
    /// Per object, before the first contact: the touch-down the planes' stiffness comes from.
    pub(super) touchdown: Vec<crate::haptics::Touchdown>,
    /// The normal stiffness and damping the last touch-down plane carried: a first contact's ticks before its
    /// own solve finishes use them (as later contacts use the last measured one).
    pub(super) touchdown_plane: Option<(f32, f32)>,
    /// Per object: the tip's plane on a multi-rate object, rendered on the tick until its step answers.
    pub(super) lane_planes: Vec<crate::multirate::LanePlane>,
    /// Broad-phase scratch of the plane search.
    pub(super) plane_candidates: Vec<u32>,
    /// The contact's normal stiffness fitted to the tissue's answer.
    pub(super) estimate: NormalStiffnessEstimate,
    /// The contact's sliding friction coefficient, measured (the model's cone).
    pub(super) friction: KineticFrictionEstimate,
}

impl ToolHaptics {
    /// The normal stiffness a contact is rendered with before its own solve finishes, N/mm: the touch-down's
    /// (the plane carried it) before the tool's first contact, else the last measured contact's.
    pub(super) fn unsolved_stiffness_n_per_mm(&self) -> f32 {
        match self.touchdown_plane {
            Some((k, _)) if !self.plane_measured && k > 0.0 => k,
            _ => self.plane_stiffness_n_per_mm,
        }
    }

    /// A contact began on object `o`: the touch-down is over. Its solver starts the contact's own solve
    /// afresh; until that finishes, the contact renders (and the coupling uses) the touch-down's stiffness,
    /// which the plane carried (a fixed prior stood for 1-3 ticks and sent the device a model of 0.2 N/mm on
    /// a 0.02 N/mm sheet). Nothing happens if no touch-down was in play.
    pub(super) fn end_touchdown(&mut self, o: usize) {
        if !self.touchdown.get_mut(o).is_some_and(|t| t.end()) {
            return;
        }
        if let Some(solver) = self.stiffness.get_mut(o) {
            solver.forget();
        }
        if let Some((k, d)) = self.touchdown_plane.take()
            && !self.plane_measured
            && k > 0.0
        {
            self.plane_stiffness_n_per_mm = k;
            self.plane_damping_n_s_per_mm = d;
        }
    }
}

impl SimTool {
    /// The shaft's centre in the world, mm (the tool origin when it has none).
    pub(super) fn shaft_centre_mm(&self) -> Vec3 {
        let half_mm = self.shaft_spec.map_or(0.0, |s| 0.5 * s.length_mm);
        self.position_mm + self.rotation * Vec3::new(0.0, 0.0, half_mm)
    }

    /// The latest finished contact-stiffness solve of this tool on object `object`.
    pub fn contact_response(&self, object: usize) -> Option<&crate::haptics::ContactResponse> {
        self.haptic.stiffness.get(object).and_then(|s| s.response())
    }

    /// The coupling parameters.
    pub fn coupling(&self) -> &CouplingParams {
        self.drive.coupling.params()
    }

    /// The instrument's jaws (a grasper's, scissors'; None for a probe).
    pub fn jaws(&self) -> Option<&Jaws> {
        self.instrument_state.as_ref().and_then(|i| i.jaws())
    }

    /// What a grasper holds (None for another instrument).
    pub fn grasp(&self) -> Option<&Grasp> {
        self.instrument_state.as_ref().and_then(|i| i.grasp())
    }

    /// A needle driver's needle against the tissue (None for another instrument).
    pub fn needle(&self) -> Option<&crate::interaction::suture::NeedleTissue> {
        self.instrument_state.as_ref().and_then(|i| i.needle())
    }

    /// Whether its instrument pulls tissue with forces this tick.
    pub(super) fn pulls_tissue(&self) -> bool {
        self.active
            && self
                .instrument_state
                .as_ref()
                .is_some_and(|i| i.pulls_tissue())
    }

    /// Add its instrument's forces on object `object` to the object's external forces.
    pub(super) fn add_forces(
        &self,
        object: usize,
        model: &crate::tissue::MassSpringModel,
        state: &mut crate::tissue::TissueState,
    ) {
        if let Some(i) = &self.instrument_state {
            i.add_forces(object, model, state);
        }
    }

    /// Who holds a needle driver's needle, and where it is (None for another instrument).
    pub fn needle_hold(&self) -> Option<&crate::interaction::suture::NeedleHold> {
        self.instrument_state.as_ref().and_then(|i| i.needle_hold())
    }

    /// A needle driver's thread (None for another instrument, or a needle without one).
    pub fn thread(&self) -> Option<&crate::interaction::suture::SutureThread> {
        self.instrument_state.as_ref().and_then(|i| i.thread())
    }

    /// A needle driver's thread, to lay it out as a scenario starts ([`SutureThread::lay_along`]).
    ///
    /// [`SutureThread::lay_along`]: crate::interaction::suture::SutureThread::lay_along
    pub fn thread_mut(&mut self) -> Option<&mut crate::interaction::suture::SutureThread> {
        self.instrument_state.as_mut().and_then(|i| i.thread_mut())
    }

    /// The nodes of object `object` the tool's instrument holds (sorted; none for most instruments).
    pub(super) fn attached_nodes(&self, object: usize) -> &[u32] {
        self.instrument_state
            .as_ref()
            .map_or(&[], |i| i.attached_nodes(object))
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
    /// The tool holds tissue (a grasp's attachments): the local model is bilateral and `K` full rank.
    pub attached: bool,
    /// The drag of cutting the local model carries, N (>= 0; 0 when the blade has not cut lately): the
    /// tissue's cutting resistance times how recently the edge cut.
    pub cut_drag_n: f32,
    /// How far the edge travels between the facets it cuts, mm (0: unknown, and `cut_drag_n` is the drag's
    /// mean; positive: `cut_drag_n` is the drag at a facet cut, and a distant device makes the sawtooth).
    pub cut_facet_mm: f32,
    /// The drag of cutting inside `force_world_n`, world frame, N (the model renders it from `cut_drag_n`
    /// against the device's own motion, so its `f0` leaves it out).
    pub cut_drag_world_n: Vec3,
    /// The friction inside `force_world_n` along the surface: the held nodes' tangential pulls, less their
    /// part along the contact's push, world frame, N (clamped with it). A distant device renders friction
    /// from its own stick point, so the model's `f0` leaves it out.
    pub friction_world_n: Vec3,
    /// Coulomb's coefficient of the tissue the tool pushes on (the largest, if several; 0: frictionless or
    /// not pushing): the model's friction cone.
    pub friction_coefficient: f32,
    /// Stiffness of the stuck contact along the surface as the device feels it, N/mm (0 without friction):
    /// the model's stick spring ([`super::Sim::local_model`]).
    pub stick_stiffness_n_per_mm: f32,
    /// What the tool's needle and thread are doing (the training layer's suturing states).
    pub suture: super::SutureActivity,
    /// The pop of the needle its jaws hold, while its tip presses a surface (the model's puncture term).
    pub needle_pop: super::NeedlePop,
}
