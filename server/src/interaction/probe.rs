//! Probing: the tool pushes surface nodes out of itself; the tissue's reaction on those nodes is the tool force.
//!
//! Each tissue node found inside the tool is pushed into the tissue (along minus its rest outward normal) until
//! it reaches the tool surface, and it is held there with the tool's (quasi-static) velocity: the surface
//! yields and stays put. Pushing along the tissue normal, not radially, keeps a sheet from sliding round a tool and
//! wrapping over it. Contact is sided: a sphere or capsule has a shaft back out of the tissue, a node that comes
//! in over the tool (a deep dent's wall closing in) is held beside the shaft, and a node held under the tool
//! stays under it even when one step carried it past the tool's core ([`ToolCollider::push_out_along`]); so a
//! thin sheet never closes over a probe pressed deep into it. Held nodes act on the tool through its surface normal `n_i` there: with `f_i` the node's
//! internal force, the tool feels `(f_i . n_i) n_i` when `f_i . n_i < 0` (push-only). The sum points out of the
//! tissue, grows with depth, and resists lateral strokes through the dent's walls.
//!
//! Friction (Coulomb, stick-slip, with the material's coefficient `mu`): a held node sticks to the point of the
//! tool surface where it was held last substep (kept in the tool frame, so it rides with the tool) while the
//! tangential part of its internal force `f_t` stays within `mu |f_n|`; the tool feels `f_t`. Past that it slips:
//! it moves from the stuck point toward where it would lie without friction by the excess force over its
//! stiffness (`(|f_t| - mu |f_n|) / k_ii`, a return mapping), and the tool feels the kinetic `mu |f_n|` along
//! `f_t`. So a probe stroked across the tissue drags the surface until the pull exceeds the friction, then
//! slides; a still, deep press holds its nodes where they are instead of letting them creep round the tool.

use nalgebra::UnitQuaternion;

mod triangles;

use crate::collision::{ContactSide, ToolCollider};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A tool's blunt body at its pose this tick: the tip (the tool's `shape`) and, if it has one, its shaft (a
/// capsule, with its centre in the world).
#[derive(Debug, Clone, Copy)]
pub struct ToolBody<'a> {
    /// The tip.
    pub tip: &'a ToolCollider,
    /// The shaft and its centre in the world, mm.
    pub shaft: Option<(&'a ToolCollider, Vec3)>,
    /// Tool origin in the world, mm.
    pub position_mm: Vec3,
    /// Tool orientation in the world.
    pub rotation: UnitQuaternion<f32>,
}

/// A node held last time stays held (sticky contacts) while it is this close to the tool, mm.
pub const STICK_TOLERANCE_MM: f32 = 1e-3;

impl<'a> ToolBody<'a> {
    /// The body of a tool at `position_mm`, `rotation`: its tip, and its shaft (a capsule of half length
    /// `half_mm` along the tool's z from its origin) if it has one.
    pub fn posed(
        tip: &'a ToolCollider,
        shaft: Option<(&'a ToolCollider, f32)>,
        position_mm: Vec3,
        rotation: UnitQuaternion<f32>,
    ) -> Self {
        Self {
            tip,
            shaft: shaft
                .map(|(s, half_mm)| (s, position_mm + rotation * Vec3::new(0.0, 0.0, half_mm))),
            position_mm,
            rotation,
        }
    }

    /// Distance from `point_mm` to the body (tip or shaft, whichever is nearer), mm; 0 inside.
    pub fn distance_mm(&self, point_mm: &Vec3) -> f32 {
        let tip = self
            .tip
            .distance_mm(&self.position_mm, &self.rotation, point_mm);
        match self.shaft {
            Some((shaft, centre)) => tip.min(shaft.distance_mm(&centre, &self.rotation, point_mm)),
            None => tip,
        }
    }

    /// Push `point_mm` out of the tip, or else out of the shaft, along `push_dir` ([`ToolCollider::push_out_along`]).
    fn push_out_along(
        &self,
        point_mm: &Vec3,
        push_dir: &Vec3,
        held_in_front: bool,
    ) -> Option<(Vec3, Vec3, ContactSide)> {
        self.tip
            .push_out_along(
                &self.position_mm,
                &self.rotation,
                point_mm,
                push_dir,
                held_in_front,
            )
            .or_else(|| {
                let (shaft, centre) = self.shaft?;
                shaft.push_out_along(&centre, &self.rotation, point_mm, push_dir, held_in_front)
            })
    }
}

/// The nodes one tool holds in one object, and the directions it pushes them. Reused every tick.
#[derive(Debug, Clone, Default)]
pub struct ProbeContacts {
    /// Candidate nodes from the broad phase.
    pub candidates: Vec<u32>,
    /// Candidate surface triangles from the broad phase (the triangle pass, `triangles`).
    pub candidate_triangles: Vec<u32>,
    /// Nodes held this tick (subset of candidates).
    pub held: Vec<u32>,
    /// Tool outward normal (unit) at each held node.
    pub normals: Vec<Vec3>,
    /// Nodes held on the push side ([`ContactSide::Front`]) last tick, sorted: they stay on that side.
    in_front: Vec<u32>,
    /// The same for this tick, being built (swapped into `in_front` at the end of [`Self::project`]).
    in_front_now: Vec<u32>,
    /// Where each held node sticks to the tool, tool frame, mm (sorted by node; friction only).
    anchors: Vec<(u32, Vec3)>,
    /// The same for this substep, being built.
    anchors_now: Vec<(u32, Vec3)>,
    /// Keep a node held while it stays on the tool and presses on it (see [`Self::sticky`]).
    sticky: bool,
    /// Last projection's held nodes with their normals, sorted by node (sticky contacts only).
    held_before: Vec<(u32, Vec3)>,
    /// `held_before` was filled by [`Self::clear`] (a new tick's broad phase): the next projection uses it as is.
    carried: bool,
    /// Triangles the triangle pass held last projection, sorted (sticky contacts keep them).
    triangles_held: Vec<u32>,
    /// The same for this projection, being built.
    triangles_held_now: Vec<u32>,
    /// Run the triangle pass (`triangles`): the object's surface is coarse for the tools.
    triangles: bool,
    /// Triangles met in front of the tool (under it) last projection, sorted: they stay on that side.
    triangles_in_front: Vec<u32>,
    /// The same for this projection, being built.
    triangles_in_front_now: Vec<u32>,
}

impl ProbeContacts {
    /// Contacts with room for `capacity` nodes (so a tick does not allocate).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            candidates: Vec::with_capacity(capacity),
            candidate_triangles: Vec::with_capacity(capacity),
            held: Vec::with_capacity(capacity),
            normals: Vec::with_capacity(capacity),
            in_front: Vec::with_capacity(capacity),
            in_front_now: Vec::with_capacity(capacity),
            anchors: Vec::with_capacity(capacity),
            anchors_now: Vec::with_capacity(capacity),
            sticky: false,
            held_before: Vec::new(),
            carried: false,
            triangles_held: Vec::with_capacity(capacity),
            triangles_held_now: Vec::with_capacity(capacity),
            triangles: false,
            triangles_in_front: Vec::with_capacity(capacity),
            triangles_in_front_now: Vec::with_capacity(capacity),
        }
    }

    /// Contacts that also keep the surface's triangles out of a ball or capsule tip (`on`), not only its nodes
    /// (`triangles`); the broad phase then fills [`Self::candidate_triangles`] too.
    pub fn with_triangles(mut self, on: bool) -> Self {
        self.triangles = on;
        self
    }

    /// Whether the broad phase should fill [`Self::candidate_triangles`].
    pub fn wants_triangles(&self) -> bool {
        self.triangles
    }

    /// Contacts for a solver that holds the held nodes still through its step (`TissueState::pinned`): a
    /// node held last time that is still on the tool's surface (within [`STICK_TOLERANCE_MM`]) stays held
    /// while the tissue presses it on the tool, and lets go once it pulls away (Signorini's conditions). A
    /// pinned node does not move into the tool during the solve, so without this it would drop out of the
    /// contact every other step.
    pub fn sticky(mut self) -> Self {
        self.sticky = true;
        self.held_before = Vec::with_capacity(self.held.capacity());
        self
    }

    /// Forget last tick's contacts before a new broad phase (keeps capacity). The side each node was held
    /// on is kept for [`Self::project`].
    pub fn clear(&mut self) {
        if self.sticky {
            self.remember_held();
            self.carried = true;
        }
        self.candidates.clear();
        self.candidate_triangles.clear();
        self.held.clear();
        self.normals.clear();
    }

    /// Forget everything, sides included (the tissue was reset, or the tool left).
    pub fn forget(&mut self) {
        self.clear();
        self.held_before.clear();
        self.carried = false;
        self.in_front.clear();
        self.in_front_now.clear();
        self.anchors.clear();
        self.anchors_now.clear();
        self.triangles_held.clear();
        self.triangles_in_front.clear();
    }

    /// Keep the held nodes and their normals for the sticky test, sorted by node. No allocation beyond capacity.
    fn remember_held(&mut self) {
        self.held_before.clear();
        self.held_before
            .extend(self.held.iter().copied().zip(self.normals.iter().copied()));
        self.held_before.sort_unstable_by_key(|h| h.0);
    }

    /// Push every candidate node that is inside the tool out to its surface, then every candidate triangle the
    /// tip reaches into between its corners (`triangles`); record the held nodes. With
    /// `friction` (the material's Coulomb coefficient, 0: frictionless) a node held last substep sticks to its
    /// point of the tool until it slips (module docs). Fixed nodes are not moved, nor the nodes in `grasped`
    /// (sorted: the tool's jaws hold them). No allocation beyond capacity, never panics.
    pub fn project(
        &mut self,
        body: &ToolBody,
        model: &MassSpringModel,
        state: &mut TissueState,
        grasped: &[u32],
        friction: f32,
    ) {
        if self.sticky && !std::mem::take(&mut self.carried) {
            self.remember_held();
        }
        self.held.clear();
        self.normals.clear();
        self.in_front_now.clear();
        self.anchors_now.clear();
        let friction = if friction.is_finite() {
            friction.max(0.0)
        } else {
            0.0
        };
        let pressure = if (friction > 0.0 && !self.anchors.is_empty()) || self.sticky {
            model.pressure_n_per_mm2(&state.positions_mm)
        } else {
            0.0
        };
        let (position_mm, rotation) = (&body.position_mm, &body.rotation);
        let to_tool = rotation.inverse();
        for &node in &self.candidates {
            let i = node as usize;
            if model.is_fixed(i) || grasped.binary_search(&node).is_ok() {
                continue;
            }
            let push_dir = -model.rest_normals()[i];
            let held_in_front = self.in_front.binary_search(&node).is_ok();
            if let Some((surface, normal, side)) =
                body.push_out_along(&state.positions_mm[i], &push_dir, held_in_front)
            {
                if side == ContactSide::Front {
                    self.in_front_now.push(node);
                }
                let anchor = self
                    .anchors
                    .binary_search_by_key(&node, |a| a.0)
                    .ok()
                    .map(|k| position_mm + rotation * self.anchors[k].1);
                let placed = match anchor {
                    Some(stuck) if friction > 0.0 => {
                        state.positions_mm[i] = stuck;
                        let f = model.node_force(
                            i,
                            &state.positions_mm,
                            &state.velocities_mm_s,
                            pressure,
                        );
                        let f_n = f.dot(&normal);
                        let f_t = f - normal * f_n;
                        let limit_n = friction * (-f_n).max(0.0);
                        let excess_n = f_t.norm() - limit_n;
                        let k = model.diagonal_stiffness_n_per_mm(i);
                        let toward = surface - stuck;
                        let gap = toward.norm();
                        if excess_n <= 0.0 || k <= 0.0 || gap <= 0.0 {
                            stuck
                        } else {
                            // Slip toward the frictionless point by the excess force over the stiffness.
                            stuck + toward * (excess_n / k / gap).min(1.0)
                        }
                    }
                    _ => surface,
                };
                state.positions_mm[i] = placed;
                if friction > 0.0 {
                    self.anchors_now
                        .push((node, to_tool * (placed - position_mm)));
                }
                // A held node moves with the tool: it keeps no velocity of its own. Keeping the tangential
                // part let held nodes creep round the frictionless tool, drop out of contact and snap back
                // in a slow cycle (a ~40 mN, ~2 Hz force ripple under a still hand).
                state.velocities_mm_s[i] = Vec3::zeros();
                self.held.push(node);
                self.normals.push(normal);
            } else if let Ok(k) = self.held_before.binary_search_by_key(&node, |h| h.0) {
                // On the surface, not in the tool: still held while it presses on it.
                let normal = self.held_before[k].1;
                let x = &state.positions_mm[i];
                let on_surface = body.distance_mm(x) <= STICK_TOLERANCE_MM;
                let pressing = model
                    .node_force(i, &state.positions_mm, &state.velocities_mm_s, pressure)
                    .dot(&normal)
                    < 0.0;
                if on_surface && pressing {
                    if held_in_front {
                        self.in_front_now.push(node);
                    }
                    state.velocities_mm_s[i] = Vec3::zeros();
                    self.held.push(node);
                    self.normals.push(normal);
                }
            }
        }
        self.hold_triangles(body, model, state, grasped, pressure);
        self.in_front_now.sort_unstable();
        std::mem::swap(&mut self.in_front, &mut self.in_front_now);
        self.anchors_now.sort_unstable_by_key(|a| a.0);
        std::mem::swap(&mut self.anchors, &mut self.anchors_now);
    }

    /// Force the tissue exerts on the tool through the held nodes, N: each node's push along the tool's normal
    /// and, with `friction`, its tangential pull up to `friction` times that push. No allocation.
    pub fn reaction_force_n(
        &self,
        model: &MassSpringModel,
        state: &TissueState,
        friction: f32,
    ) -> Vec3 {
        self.reaction_and_friction_n(model, state, friction).0
    }

    /// [`ProbeContacts::reaction_force_n`] and, apart, the friction inside it (the sum of the nodes'
    /// tangential pulls, N): a distant device renders friction from its own stick point, so the local model's
    /// `f0` leaves it out. The total is summed exactly as `reaction_force_n` always has (same bits). No
    /// allocation.
    pub fn reaction_and_friction_n(
        &self,
        model: &MassSpringModel,
        state: &TissueState,
        friction: f32,
    ) -> (Vec3, Vec3) {
        let mut force = Vec3::zeros();
        let mut friction_n = Vec3::zeros();
        if self.held.is_empty() {
            return (force, friction_n);
        }
        let pressure = model.pressure_n_per_mm2(&state.positions_mm);
        for (&node, dir) in self.held.iter().zip(&self.normals) {
            let f = model.node_force(
                node as usize,
                &state.positions_mm,
                &state.velocities_mm_s,
                pressure,
            );
            friction_n += add_node_reaction(&mut force, &f, dir, friction);
        }
        (force, friction_n)
    }
}

/// Add to `force` what one held node pushes on the tool: the tissue force `f` on the node along the tool
/// normal `dir` where it pushes, and with `friction` its tangential pull up to `friction` times that push
/// (the two added one after the other, as [`ProbeContacts::reaction_force_n`] always has). Returns the
/// tangential pull added (zero without friction). No allocation.
pub fn add_node_reaction(force: &mut Vec3, f: &Vec3, dir: &Vec3, friction: f32) -> Vec3 {
    let normal = f.dot(dir);
    if normal < 0.0 {
        *force += dir * normal;
        if friction > 0.0 && friction.is_finite() {
            let f_t = f - dir * normal;
            let limit_n = -normal * friction;
            let t = f_t.norm();
            let pull = if t <= limit_n {
                f_t
            } else {
                f_t * (limit_n / t)
            };
            *force += pull;
            return pull;
        }
    }
    Vec3::zeros()
}
