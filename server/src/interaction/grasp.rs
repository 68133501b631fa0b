//! Grasping: closed jaws hold tissue by attachments until they open, or the tissue slips out.
//!
//! Owns: [`Grasp`], one grasper's [`Attachment`]s, how they are taken when the jaws close, how they hold the
//! tissue each substep, and the force they put on the tool.
//!
//! - **Taking.** When the jaws close, the nodes the tool's body holds (and free surface nodes within the bite
//!   of it) are offered. The jaws are the body's two halves either side of the tool's local `y = 0` plane; the
//!   grasp takes hold only if both halves touch tissue, else nothing is held until the jaws open and close
//!   again (closed jaws cannot grab).
//! - **Attachments.** Each is a material point of the surface: a triangle (its stable id), barycentric
//!   coordinates, and the point's place in the tool frame when it was taken (the jaws hold it there). A
//!   node taken by the jaws is the corner of one of its triangles (barycentric `(1, 0, 0)` up to order); a
//!   suture's anchors will be interior points of the same kind.
//! - **Holding.** After each substep's integration and probing, the point is moved to its place on the jaws,
//!   distributed over the triangle's free nodes by their weights (the minimum-norm correction), and those
//!   nodes keep no velocity of their own: the constraint is hard and the compliance between hand and tissue
//!   is the tool's virtual coupling, as for probing.
//! - **Force.** What the tool feels through an attachment is the tissue's pull on the point: the weighted
//!   internal forces of its nodes, `sum_k b_k f_k / sum_k b_k^2`. Pulling grasped tissue away from its rest
//!   therefore feels like pulling: the force points back toward the tissue and grows with the pull.
//! - **Slip.** An attachment whose pull exceeds the grasp's `slip_force_n` lets go; the load moves to the
//!   others, so a hard pull slips the tissue out of the jaws point by point.
//!
//! Must not: allocate once built (the buffers are sized for [`MAX_ATTACHMENTS`]), or panic on any state.

use nalgebra::UnitQuaternion;

use super::GraspSpec;
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// The most attachments one grasp may hold (`max_attachments` is checked against it).
pub const MAX_ATTACHMENTS: u16 = 256;

/// A node offered to the jaws this far from the jaw plane (tool-local |y|) or less touches neither jaw, mm: it
/// lies in the gap between them.
const JAW_GAP_MM: f32 = 0.05;

/// A material point of a surface held by a tool.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attachment {
    /// Object index in the world.
    pub object: u16,
    /// Triangle of the object's surface (its stable id).
    pub triangle: u32,
    /// Weights of the triangle's three corners (sum 1).
    pub barycentric: [f32; 3],
    /// Where the tool holds the point, tool frame, mm.
    pub anchor_tool_mm: Vec3,
}

/// What a call to [`Grasp::finish_take`] or [`Grasp::release`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GraspEvent {
    /// The jaws closed on tissue touching both of them: this many points are held.
    Took(u16),
    /// The jaws closed without tissue on both sides: nothing is held.
    Missed,
    /// The jaws opened (or the tool left): this many points were let go.
    Released(u16),
}

/// One grasper's hold on the tissue.
#[derive(Debug, Clone)]
pub struct Grasp {
    spec: GraspSpec,
    attachments: Vec<Attachment>,
    /// Per object, the nodes some attachment moves, sorted (the probe leaves them alone).
    attached_nodes: Vec<Vec<u32>>,
    /// Per attachment, the tissue's pull on the tool at the end of the last tick, N.
    pull_n: Vec<Vec3>,
    /// During a take: a node touched the +y jaw, the -y jaw.
    touched: [bool; 2],
    /// The jaws were closed last tick (a take happens on the closing edge only).
    was_closed: bool,
    /// Attachments that slipped since the grasp was built.
    slipped: u64,
    /// How firmly the points are held, 0..1 ([`Grasp::set_grip`]): each substep moves a point this share of
    /// the way to its place on the jaws, and the tool feels this share of its pull.
    grip: f32,
}

impl Grasp {
    /// A grasp holding nothing, for a world of `object_count` objects.
    pub fn new(spec: GraspSpec, object_count: usize) -> Self {
        let most = usize::from(MAX_ATTACHMENTS);
        Self {
            spec,
            attachments: Vec::with_capacity(most),
            attached_nodes: (0..object_count)
                .map(|_| Vec::with_capacity(3 * most))
                .collect(),
            pull_n: Vec::with_capacity(most),
            touched: [false; 2],
            was_closed: false,
            slipped: 0,
            grip: 0.0,
        }
    }

    /// How firmly the points are held, 0..1.
    pub fn grip(&self) -> f32 {
        self.grip
    }

    /// Move the grip toward `target` (0..1) by at most `max_step`: jaws take hold and let go as they close
    /// and open, so the force at the hand changes no faster than the jaws move.
    pub fn set_grip(&mut self, target: f32, max_step: f32) {
        if !(target.is_finite() && max_step >= 0.0) {
            return;
        }
        let target = target.clamp(0.0, 1.0);
        self.grip += (target - self.grip).clamp(-max_step, max_step);
    }

    /// The grasp's parameters.
    pub fn spec(&self) -> &GraspSpec {
        &self.spec
    }

    /// The points held.
    pub fn attachments(&self) -> &[Attachment] {
        &self.attachments
    }

    /// The nodes of object `object` that attachments move, sorted.
    pub fn attached_nodes(&self, object: usize) -> &[u32] {
        self.attached_nodes
            .get(object)
            .map_or(&[], |v| v.as_slice())
    }

    /// Attachments that slipped since the grasp was built.
    pub fn slipped(&self) -> u64 {
        self.slipped
    }

    /// True on the tick the jaws close (closed now, open last tick); remembers `closed` for the next call.
    pub fn closing_edge(&mut self, closed: bool) -> bool {
        let edge = closed && !self.was_closed;
        self.was_closed = closed;
        edge
    }

    /// Start a take: forget what the last one touched.
    pub fn start_take(&mut self) {
        self.touched = [false; 2];
    }

    /// Offer the nodes of object `object` that the jaws close on (the body holds them, or they lie within
    /// the bite). Each becomes an attachment at its current place in the tool frame, up to the grasp's
    /// limit; nodes on the jaw plane touch neither jaw, nodes without a surface triangle (interior) are
    /// skipped.
    #[allow(clippy::too_many_arguments)] // the tool pose and one object's tissue, as the sim holds them
    pub fn offer(
        &mut self,
        object: usize,
        nodes: &[u32],
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        model: &MassSpringModel,
        state: &TissueState,
    ) {
        let Ok(object_id) = u16::try_from(object) else {
            return;
        };
        let triangles = model.triangles();
        for &node in nodes {
            let i = node as usize;
            let Some(x) = state.positions_mm.get(i) else {
                continue;
            };
            if model.is_fixed(i) {
                continue;
            }
            let local = rotation.inverse_transform_vector(&(x - position_mm));
            if local.y > JAW_GAP_MM {
                self.touched[0] = true;
            } else if local.y < -JAW_GAP_MM {
                self.touched[1] = true;
            }
            if self.attachments.len() >= usize::from(self.spec.max_attachments)
                || self.attached_nodes[object].binary_search(&node).is_ok()
            {
                continue;
            }
            let Some((triangle, corner)) = model.node_triangles(i).first().and_then(|&t| {
                let corners = triangles.get(t as usize)?;
                Some((t, corners.iter().position(|&c| c == node)?))
            }) else {
                continue;
            };
            let mut barycentric = [0.0; 3];
            barycentric[corner] = 1.0;
            self.attachments.push(Attachment {
                object: object_id,
                triangle,
                barycentric,
                anchor_tool_mm: local,
            });
            self.pull_n.push(Vec3::zeros());
            let list = &mut self.attached_nodes[object];
            if let Err(at) = list.binary_search(&node) {
                list.insert(at, node);
            }
        }
    }

    /// End a take: the jaws hold what was offered if tissue touched both of them, else nothing.
    pub fn finish_take(&mut self) -> GraspEvent {
        if self.touched == [true, true] && !self.attachments.is_empty() {
            GraspEvent::Took(self.attachments.len() as u16)
        } else {
            self.clear();
            GraspEvent::Missed
        }
    }

    /// Let everything go (the jaws opened, or the tool left).
    pub fn release(&mut self) -> GraspEvent {
        let n = self.attachments.len() as u16;
        self.clear();
        GraspEvent::Released(n)
    }

    fn clear(&mut self) {
        self.grip = 0.0;
        self.attachments.clear();
        self.pull_n.clear();
        for list in &mut self.attached_nodes {
            list.clear();
        }
    }

    /// Move each held point of object `object` to its place on the jaws (one substep; at a partial grip, that
    /// share of the way, and that share of its velocity taken). Fixed nodes are not
    /// moved; a point whose nodes are all fixed is left alone.
    pub fn hold(
        &self,
        object: usize,
        position_mm: &Vec3,
        rotation: &UnitQuaternion<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        hold_points(
            &self.attachments,
            object,
            self.grip,
            position_mm,
            rotation,
            model,
            state,
        );
    }

    /// The tissue's pull on the tool through the points of object `object` held at the end of a tick (times the
    /// grip), N; an
    /// attachment pulled harder than `slip_force_n` lets go (counted). Call once per object per tick, after
    /// the substeps. No allocation.
    pub fn settle(&mut self, object: usize, model: &MassSpringModel, state: &TissueState) -> Vec3 {
        let pressure = model.pressure_n_per_mm2(&state.positions_mm);
        for (a, pull) in self.attachments.iter().zip(self.pull_n.iter_mut()) {
            if usize::from(a.object) == object {
                *pull = point_pull_n(a, model, state, pressure);
            }
        }
        self.let_slip(object, model)
    }

    /// Settle the points of object `object` on pulls measured elsewhere (a multi-rate object's step, on its
    /// own thread: `pull_of` gives an attachment's pull, None for a point that step did not hold, which keeps
    /// its last pull). Returns the summed pull times the grip, N; an attachment pulled harder than
    /// `slip_force_n` lets go (counted). No allocation.
    pub fn settle_with(
        &mut self,
        object: usize,
        model: &MassSpringModel,
        pull_of: impl Fn(&Attachment) -> Option<Vec3>,
    ) -> Vec3 {
        for (a, pull) in self.attachments.iter().zip(self.pull_n.iter_mut()) {
            if usize::from(a.object) == object
                && let Some(p) = pull_of(a)
            {
                *pull = p;
            }
        }
        self.let_slip(object, model)
    }

    /// Let go of the points of object `object` pulled harder than the slip force (or not finitely), in stable
    /// order; returns the summed pull of the rest times the grip, N. No allocation.
    fn let_slip(&mut self, object: usize, model: &MassSpringModel) -> Vec3 {
        let slip = self.spec.slip_force_n;
        let before = self.attachments.len();
        let mut keep = 0;
        for k in 0..before {
            let a = self.attachments[k];
            let pull = self.pull_n[k];
            let finite = pull.iter().all(|c| c.is_finite());
            if usize::from(a.object) == object && (!finite || pull.norm() > slip) {
                continue;
            }
            self.attachments[keep] = a;
            self.pull_n[keep] = pull;
            keep += 1;
        }
        if keep < before {
            self.slipped += (before - keep) as u64;
            self.attachments.truncate(keep);
            self.pull_n.truncate(keep);
            self.rebuild_nodes(object, model);
        }
        let pull: Vec3 = self
            .pull_n
            .iter()
            .zip(&self.attachments)
            .filter(|(_, a)| usize::from(a.object) == object)
            .map(|(p, _)| *p)
            .sum();
        pull * self.grip
    }

    /// Object `object`'s topology changed (a cut or tear re-pointed some triangles' corners): re-read the
    /// corners of the triangles held there. Triangle ids are stable, so every attachment stays.
    pub fn topology_changed(&mut self, object: usize, model: &MassSpringModel) {
        self.rebuild_nodes(object, model);
    }

    /// Object `object` was subdivided: each attachment on it is re-expressed on the piece of its triangle that
    /// holds its point ([`crate::tissue::subdivision::ElementRemap`]), then the corners are re-read.
    pub fn subdivided(
        &mut self,
        object: usize,
        model: &MassSpringModel,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) {
        for a in self
            .attachments
            .iter_mut()
            .filter(|a| usize::from(a.object) == object)
        {
            (a.triangle, a.barycentric) = remap.triangle(a.triangle, a.barycentric);
        }
        self.rebuild_nodes(object, model);
    }

    /// Recompute the attached-node list of `object` from the attachments (after some let go).
    fn rebuild_nodes(&mut self, object: usize, model: &MassSpringModel) {
        let Some(list) = self.attached_nodes.get_mut(object) else {
            return;
        };
        nodes_held(&self.attachments, object, model, list);
    }
}

/// The nodes of object `object` that `attachments` move, sorted, into `nodes` (cleared first). No allocation
/// beyond `nodes`' capacity.
pub(crate) fn nodes_held(
    attachments: &[Attachment],
    object: usize,
    model: &MassSpringModel,
    nodes: &mut Vec<u32>,
) {
    nodes.clear();
    for (a, corners) in in_object(attachments, object, model.triangles()) {
        for (&c, &b) in corners.iter().zip(&a.barycentric) {
            if b != 0.0
                && let Err(at) = nodes.binary_search(&c)
            {
                nodes.insert(at, c);
            }
        }
    }
}

/// Move each point of object `object` in `attachments` to its place on jaws posed at `position_mm`,
/// `rotation` (one substep; at a partial `grip`, that share of the way, and that share of its velocity taken;
/// the minimum-norm correction over the triangle's free nodes). Fixed nodes are not moved; a point whose
/// nodes are all fixed is left alone. No allocation.
pub(crate) fn hold_points(
    attachments: &[Attachment],
    object: usize,
    grip: f32,
    position_mm: &Vec3,
    rotation: &UnitQuaternion<f32>,
    model: &MassSpringModel,
    state: &mut TissueState,
) {
    for (a, corners) in in_object(attachments, object, model.triangles()) {
        let target = position_mm + rotation.transform_vector(&a.anchor_tool_mm);
        let mut point = Vec3::zeros();
        let mut free_weight = 0.0;
        for (&c, &b) in corners.iter().zip(&a.barycentric) {
            let Some(x) = state.positions_mm.get(c as usize) else {
                continue;
            };
            point += x * b;
            if !model.is_fixed(c as usize) {
                free_weight += b * b;
            }
        }
        if free_weight <= 0.0 {
            continue;
        }
        let correction = (target - point) / free_weight * grip;
        for (&c, &b) in corners.iter().zip(&a.barycentric) {
            let c = c as usize;
            if b == 0.0 || model.is_fixed(c) || c >= state.positions_mm.len() {
                continue;
            }
            state.positions_mm[c] += correction * b;
            state.velocities_mm_s[c] = if grip >= 1.0 {
                Vec3::zeros()
            } else {
                state.velocities_mm_s[c] * (1.0 - grip)
            };
        }
    }
}

/// The tissue's pull on a held point: the weighted internal forces of its triangle's free nodes,
/// `sum_k b_k f_k / sum_k b_k^2`, N (zero for a triangle the model does not have). `pressure` is the model's
/// (`MassSpringModel::pressure_n_per_mm2`). No allocation.
pub(crate) fn point_pull_n(
    a: &Attachment,
    model: &MassSpringModel,
    state: &TissueState,
    pressure: f32,
) -> Vec3 {
    let Some(corners) = model.triangles().get(a.triangle as usize) else {
        return Vec3::zeros();
    };
    let mut pull = Vec3::zeros();
    let mut weight = 0.0;
    for (&c, &b) in corners.iter().zip(&a.barycentric) {
        let c = c as usize;
        if b == 0.0 || model.is_fixed(c) || c >= state.positions_mm.len() {
            continue;
        }
        pull += model.node_force(c, &state.positions_mm, &state.velocities_mm_s, pressure) * b;
        weight += b * b;
    }
    if weight > 0.0 { pull / weight } else { pull }
}

/// The attachments to object `object`, each with its triangle's corners (an attachment naming a triangle the
/// object does not have is skipped).
fn in_object<'a>(
    attachments: &'a [Attachment],
    object: usize,
    triangles: &'a [[u32; 3]],
) -> impl Iterator<Item = (&'a Attachment, &'a [u32; 3])> {
    attachments
        .iter()
        .filter(move |a| usize::from(a.object) == object)
        .filter_map(move |a| Some((a, triangles.get(a.triangle as usize)?)))
}
