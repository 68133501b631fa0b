//! Contact between two deforming objects: one tissue's surface kept out of another's (a wound's edges pressing
//! on each other as a stitch closes it, an organ resting on another).
//!
//! Owns: [`TissuePair`]: once a tick, which surface nodes of each object lie near a face of the other
//! ([`TissuePair::find`], through [`crate::collision::nearest_face`]); every substep, for each such node under
//! its face, a penalty spring-damper along the face's outward normal, the node pushed out and the reaction
//! spread over the face's corners by the node's barycentric weights on it ([`TissuePair::accumulate`], into
//! both objects' `external_forces_n`, as the ties do); and the springs' energy for the guard. Both ways round
//! (each object's nodes against the other's faces), so neither side wins. Frictionless.
//!
//! The spring is [`CONTACT_STIFFNESS_PER_NODE`] times the stiffer side's own stiffness at the contact (the
//! tissue against a point: its springs' sum at the node, [`MassSpringModel::diagonal_stiffness_n_per_mm`]), no
//! more than an explicit force's stability allows at the substep ([`STABLE_OMEGA_H`]), and damped at
//! [`CONTACT_DAMPING_RATIO`] of critical.
//!
//! Must not: allocate once its buffers have grown (the tick's real-time contract), panic, or pass on a
//! non-finite force. Known gaps: one object against itself (the two faces of a cut) is not handled; a node
//! that moves more than the reach in a tick is missed until the next.

use crate::collision::{NodeMarks, SurfaceCollider, meeting_box, nearest_face, project_on_face};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A contact's spring, in units of the stiffer side's own stiffness at it: the faces give a quarter as much
/// as the tissue around them does under the same load.
pub const CONTACT_STIFFNESS_PER_NODE: f32 = 4.0;

/// The contact's damping, as a share of its critical damping.
pub const CONTACT_DAMPING_RATIO: f32 = 0.5;

/// The most a contact's spring may be, as its natural frequency times the substep (an explicit force on a
/// node is stable below 2; this keeps it far from that with the tissue's own springs on the same node).
pub const STABLE_OMEGA_H: f32 = 0.5;

/// A node is let go of in a substep when its projection falls this far outside its face (in barycentric
/// weight): it has slid off it since the tick found them.
const SLID_OFF: f32 = 0.5;

/// One object's side of a pair this tick: its surface as the collider last saw it and as it is now.
pub struct PairSide<'a> {
    /// The surface's tree.
    pub collider: &'a SurfaceCollider,
    /// The object's model (its surface's triangles and their normals).
    pub model: &'a MassSpringModel,
    /// The object's nodes, now, mm.
    pub positions_mm: &'a [Vec3],
    /// Scratch marks over the object's nodes.
    pub marks: &'a mut NodeMarks,
}

/// A node of one object near a face of the other.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PairContact {
    /// The node is object b's and the face object a's (else the other way round).
    node_of_b: bool,
    node: u32,
    face: [u32; 3],
}

/// Contact between two objects (module doc).
#[derive(Debug, Clone)]
pub struct TissuePair {
    /// Index of the first object.
    pub object_a: usize,
    /// Index of the second object.
    pub object_b: usize,
    /// How far apart a node and a face may be and still be watched this tick, mm (the broad phase's margin:
    /// what a surface moves in a tick).
    reach_mm: f32,
    contacts: Vec<PairContact>,
    /// Scratch: one side's surface nodes in the box where the surfaces meet.
    nodes: Vec<u32>,
    /// The substep the forces were last computed for, s (the spring's stability bound depends on it).
    h_s: f32,
}

impl TissuePair {
    /// Contact between objects `object_a` and `object_b`, watched within `reach_mm`.
    pub fn new(object_a: usize, object_b: usize, reach_mm: f32) -> Self {
        Self {
            object_a,
            object_b,
            reach_mm: if reach_mm.is_finite() {
                reach_mm.max(0.1)
            } else {
                2.0
            },
            contacts: Vec::new(),
            nodes: Vec::new(),
            h_s: 0.0,
        }
    }

    /// Node-face pairs watched this tick.
    pub fn contact_count(&self) -> usize {
        self.contacts.len()
    }

    /// Forget this tick's contacts (an object was reset or re-meshed).
    pub fn forget(&mut self) {
        self.contacts.clear();
    }

    /// This tick's broad and narrow phase: each surface node of either object inside the box where the two
    /// surfaces meet, with the face of the other it lies nearest (within the reach, under or above it).
    pub fn find(&mut self, a: PairSide<'_>, b: PairSide<'_>) {
        self.contacts.clear();
        let Some(meet) = meeting_box(a.collider, b.collider, self.reach_mm) else {
            return;
        };
        let (mut a, mut b) = (a, b);
        for node_of_b in [false, true] {
            let (from, to) = if node_of_b {
                (&mut b, &a)
            } else {
                (&mut a, &b)
            };
            self.nodes.clear();
            from.collider.nodes_near(&meet, from.marks, &mut self.nodes);
            for &node in &self.nodes {
                let Some(point) = from.positions_mm.get(node as usize) else {
                    continue;
                };
                let inside = (0..3).all(|k| point[k] >= meet.mins[k] && point[k] <= meet.maxs[k]);
                if !inside {
                    continue;
                }
                let facing = from.model.current_normal(from.positions_mm, node as usize);
                if let Some(face) = nearest_face(
                    to.collider,
                    to.model.triangles(),
                    to.positions_mm,
                    point,
                    &facing,
                    self.reach_mm,
                ) {
                    self.contacts.push(PairContact {
                        node_of_b,
                        node,
                        face: face.corners,
                    });
                }
            }
        }
    }

    /// One substep's contact forces, added to both objects' external forces (the caller zeroes them once per
    /// substep). `h_s` is the substep.
    pub fn accumulate(
        &mut self,
        h_s: f32,
        (model_a, a): (&MassSpringModel, &mut TissueState),
        (model_b, b): (&MassSpringModel, &mut TissueState),
    ) {
        self.h_s = h_s;
        for c in &self.contacts {
            let ((node_model, node_state), (face_model, face_state)) = if c.node_of_b {
                ((model_b, &mut *b), (model_a, &mut *a))
            } else {
                ((model_a, &mut *a), (model_b, &mut *b))
            };
            let sides = Sides {
                node: (node_model, node_state),
                face: (face_model, face_state),
            };
            let Some(push) = contact_push(c, h_s, self.reach_mm, sides) else {
                continue;
            };
            if let Some(f) = node_state.external_forces_n.get_mut(c.node as usize) {
                *f += push.force_n;
            }
            for (corner, w) in c.face.iter().zip(push.weights) {
                if let Some(f) = face_state.external_forces_n.get_mut(*corner as usize) {
                    *f -= push.force_n * w;
                }
            }
        }
    }

    /// Energy stored in the contacts' springs now, N mm (at the last substep's stiffness).
    pub fn energy_n_mm(
        &self,
        a: (&MassSpringModel, &TissueState),
        b: (&MassSpringModel, &TissueState),
    ) -> f64 {
        self.contacts
            .iter()
            .filter_map(|c| {
                let (node, face) = if c.node_of_b { (b, a) } else { (a, b) };
                let g = contact_geometry(c, self.h_s, self.reach_mm, Sides { node, face })?;
                Some(f64::from(0.5 * g.k * g.depth_mm * g.depth_mm))
            })
            .sum()
    }
}

/// A contact's two objects as a substep reads them: the node's, and the face's.
#[derive(Clone, Copy)]
struct Sides<'a> {
    node: (&'a MassSpringModel, &'a TissueState),
    face: (&'a MassSpringModel, &'a TissueState),
}

/// Where a contact's node is against its face this substep, and its spring.
struct Geometry {
    /// The node's weights on the face (clamped to it, summing to 1).
    weights: [f32; 3],
    /// How deep under the face the node is, mm.
    depth_mm: f32,
    /// The face's outward unit normal.
    normal: Vec3,
    /// The contact's spring, N/mm.
    k: f32,
}

/// A contact's force on its node, and the face's weights that share the reaction.
struct Push {
    force_n: Vec3,
    weights: [f32; 3],
}

/// The contact's geometry and spring now; `None` when the node is not under its face (or slid off it, or
/// went deeper than the reach).
fn contact_geometry(
    c: &PairContact,
    h_s: f32,
    reach_mm: f32,
    sides: Sides<'_>,
) -> Option<Geometry> {
    let point = sides.node.1.positions_mm.get(c.node as usize)?;
    let (weights, signed_mm, normal) = project_on_face(&sides.face.1.positions_mm, c.face, point)?;
    let depth_mm = -signed_mm;
    if !(depth_mm > 0.0 && depth_mm <= reach_mm) || weights.iter().any(|&w| w < -SLID_OFF) {
        return None;
    }
    let clamped = weights.map(|w| w.max(0.0));
    let sum: f32 = clamped.iter().sum();
    if sum.is_nan() || sum <= 0.0 {
        return None;
    }
    let weights = clamped.map(|w| w / sum);
    let k = spring_n_per_mm(c, &weights, h_s, sides.node.0, sides.face.0)?;
    Some(Geometry {
        weights,
        depth_mm,
        normal,
        k,
    })
}

/// The contact's spring, N/mm (module doc): the stiffer side's own stiffness times
/// [`CONTACT_STIFFNESS_PER_NODE`], within the explicit bound at substep `h_s` for the lightest mass it moves.
fn spring_n_per_mm(
    c: &PairContact,
    weights: &[f32; 3],
    h_s: f32,
    node_model: &MassSpringModel,
    face_model: &MassSpringModel,
) -> Option<f32> {
    let n = c.node as usize;
    let node_stiffness = node_model.diagonal_stiffness_n_per_mm(n);
    let face_stiffness: f32 = c
        .face
        .iter()
        .zip(weights)
        .map(|(&i, w)| w * face_model.diagonal_stiffness_n_per_mm(i as usize))
        .sum();
    let mut k = CONTACT_STIFFNESS_PER_NODE * node_stiffness.max(face_stiffness);
    // The lightest mass a unit of the contact's force accelerates: the node, or a corner by its share.
    let mut mass_kg = if node_model.is_fixed(n) {
        f32::INFINITY
    } else {
        *node_model.mass_kg().get(n)?
    };
    for (&i, &w) in c.face.iter().zip(weights) {
        if w > 0.0 && !face_model.is_fixed(i as usize) {
            mass_kg = mass_kg.min(face_model.mass_kg().get(i as usize)? / w);
        }
    }
    if h_s > 0.0 && mass_kg.is_finite() {
        // omega^2 = k [N/mm] * 1000 / m [kg]; omega h <= STABLE_OMEGA_H.
        let k_stable = STABLE_OMEGA_H * STABLE_OMEGA_H * mass_kg / (h_s * h_s) / 1000.0;
        k = k.min(k_stable);
    }
    (k.is_finite() && k > 0.0).then_some(k)
}

/// The contact's push on its node this substep (spring and damper along the face's normal, never pulling).
fn contact_push(c: &PairContact, h_s: f32, reach_mm: f32, sides: Sides<'_>) -> Option<Push> {
    let Geometry {
        weights,
        depth_mm,
        normal,
        k,
    } = contact_geometry(c, h_s, reach_mm, sides)?;
    let (node_model, node_state) = sides.node;
    let face_velocity: Vec3 = c
        .face
        .iter()
        .zip(weights)
        .filter_map(|(&i, w)| sides.face.1.velocities_mm_s.get(i as usize).map(|v| v * w))
        .sum();
    let closing_mm_s =
        -(node_state.velocities_mm_s.get(c.node as usize)? - face_velocity).dot(&normal);
    // Critical damping of the spring on the node's mass: 2 sqrt(k m), in N s/mm (k in N/m, m in kg, / 1000).
    let mass_kg = *node_model.mass_kg().get(c.node as usize)?;
    let damping_n_s_per_mm = CONTACT_DAMPING_RATIO * 2.0 * (k * 1000.0 * mass_kg).sqrt() / 1000.0;
    let push_n = (k * depth_mm + damping_n_s_per_mm * closing_mm_s).max(0.0);
    let force_n = normal * push_n;
    force_n
        .iter()
        .all(|f| f.is_finite())
        .then_some(Push { force_n, weights })
}
