//! Each tool's output for the tick: the tissue's reaction force (clamped, never non-finite), contact state and
//! the local model a distant device renders (contact stiffness and damping, nearby planes, energy allowance).
//!
//! Owns: [`Sim::tool_output`], [`Sim::local_model`], `limit_force`. Must not: move tissue.

use nalgebra::Matrix3;

use crate::haptics::{MAX_PLANES, Surface, WorldPlane, nearest_shaft_plane, nearest_surface_plane};
use crate::tissue::Vec3;

use super::*;

impl Sim {
    /// The tool's reaction force, clamped, and its contact state.
    pub(super) fn tool_output(&self, t: usize) -> ToolOutput {
        let tool = &self.tools[t];
        let mut force = Vec3::zeros();
        let mut friction_n = Vec3::zeros();
        let mut friction_coefficient = 0.0f32;
        let mut held = 0;
        for (o, (object, contacts)) in self.objects.iter().zip(&tool.contacts).enumerate() {
            if let Some(lane) = &object.lane {
                // A multi-rate object pushes through its latest step's local model, at the tool's position now;
                // before its step has found the tool, through the tool's plane on it (`LanePlane`).
                let contact = lane.contact(t);
                let push =
                    contact.force_at(&tool.position_mm, tool.haptic.unsolved_stiffness_n_per_mm());
                if tool.active && push != Vec3::zeros() {
                    force += push;
                    held += contact.held_nodes;
                } else if tool.active && tool.attached_nodes(o).is_empty() {
                    force += tool.haptic.lane_planes[o].force_at(&tool.position_mm);
                }
                continue;
            }
            let (push, pull) =
                contacts.reaction_and_friction_n(&object.model, &object.state, object.friction);
            force += push;
            friction_n += pull;
            if !contacts.held.is_empty() && object.friction.is_finite() {
                friction_coefficient = friction_coefficient.max(object.friction);
            }
            held += contacts.held.len() as u32;
        }
        let instrument = tool.instrument_state.as_deref();
        let attachments = instrument.map_or(0, |i| i.held_points());
        // Added to +0 first: a -0 pull then adds as +0, to the same bits whatever the instrument.
        force += Vec3::zeros() + instrument.map_or(Vec3::zeros(), |i| i.force_on_tool_n());
        held += u32::from(attachments);
        let mut out = limit_force(force, tool.max_force_n, held);
        // A needle in the tissue or a thread in the jaws loads the tool as held tissue does: the output is in
        // contact (a distant device renders the model only in contact; before, the needle driver's model was
        // out of contact once the needle was through, and a remote surgeon felt nothing of a stitch).
        out.in_contact |= tool.active && instrument.is_some_and(|i| i.loads_tool());
        // The friction along the surface: each node's pull is tangent to the tool where that node touches
        // it, so on a curved tool the sum has a part along the contact normal; that part stays in the push
        // (the device's cone is about the push's normal). Scaled as the clamp scaled the force (zero if the
        // force was dropped).
        if let Some(n) = (force - friction_n).try_normalize(1e-9) {
            friction_n -= n * n.dot(&friction_n);
        }
        let magnitude = force.norm();
        out.friction_world_n = if out.clamped && magnitude > 0.0 && magnitude.is_finite() {
            friction_n * (out.force_world_n.norm() / magnitude)
        } else if out.clamped {
            Vec3::zeros()
        } else {
            friction_n
        };
        out.friction_coefficient = friction_coefficient;
        out.attachments = attachments;
        if let Some(instrument) = instrument {
            instrument.mark_output(&mut out);
        }
        out
    }

    /// Complete `out` with the local model around tool `t` (contact stiffness and damping, nearby surfaces,
    /// the energy allowance) and remember what the coupling needs next tick. No allocation once warm.
    pub(super) fn local_model(&mut self, t: usize, dt_s: f32, out: &mut ToolOutput) {
        // The work this tool's hand did by turning a needle its jaws hold (whichever tool carries it).
        let turned_mj: f64 = self
            .tools
            .iter()
            .filter_map(|other| other.instrument_state.as_ref())
            .map(|i| i.turn_work_mj(t as u16))
            .sum();
        let tool = &mut self.tools[t];
        let mut k = Matrix3::zeros();
        let mut d = Matrix3::zeros();
        let mut planes = [WorldPlane::default(); MAX_PLANES];
        let mut plane_count = 0usize;
        // The contact's push without its friction: the friction is rendered from the device's stick point,
        // so the normal, the solve's direction and the measured stiffness are the push's.
        let push_n = out.force_world_n - out.friction_world_n;
        // The tissue's surface normal under the tool: the mean of its held nodes' outward rest normals. The
        // push's own direction tilts as the tool ploughs (a frictional tool) or rides the mesh's relief (a
        // 1.5 mm cautery tip: 0.05 rad as it crosses a node).
        let mut surface_normal = Vec3::zeros();
        // A tool that holds tissue renders it bilaterally, with the full 3x3 stiffness of what it holds.
        let attached = tool.active
            && tool
                .instrument_state
                .as_ref()
                .is_some_and(|i| (0..self.objects.len()).any(|o| !i.attached_nodes(o).is_empty()));
        for (o, object) in self.objects.iter_mut().enumerate() {
            let contacts = &tool.contacts[o];
            let grasped = tool
                .instrument_state
                .as_ref()
                .map_or(&[][..], |i| i.attached_nodes(o));
            if !tool.active {
                tool.haptic.stiffness[o].forget();
                continue;
            }
            if let Some(lane) = &object.lane {
                // A multi-rate object's contact stiffness was solved on its own thread, with its step: the
                // push's normal part while it pushes, the held tissue's full K while the jaws hold it.
                let contact = lane.contact(t);
                let pushing = contact
                    .force_at(&tool.position_mm, tool.haptic.unsolved_stiffness_n_per_mm())
                    != Vec3::zeros();
                let holding = !grasped.is_empty() && contact.grasped_points > 0 && contact.solved;
                if pushing || !grasped.is_empty() {
                    // Its step's own solve takes over; until it finishes, the touch-down's stiffness. The
                    // plane the tick rendered is done until the tool is back outside it.
                    tool.haptic.end_touchdown(o);
                    tool.haptic.lane_planes[o].contact_began();
                }
                if pushing {
                    if contact.solved {
                        k += contact.stiffness_matrix();
                        d += contact.damping_matrix();
                    } else {
                        let n = contact.normal;
                        k += n * n.transpose() * tool.haptic.plane_stiffness_n_per_mm;
                        d += n * n.transpose() * tool.haptic.plane_damping_n_s_per_mm;
                    }
                }
                if holding {
                    k += contact.grasp_stiffness_n_per_mm;
                    d += contact.grasp_damping_n_s_per_mm;
                } else if !grasped.is_empty() {
                    // Taken since the last launch, or its solve not yet finished: the last measured normal
                    // stiffness of this tool, in every direction (as a grasp's first ticks on the tick).
                    k += Matrix3::identity() * tool.haptic.plane_stiffness_n_per_mm;
                    d += Matrix3::identity() * tool.haptic.plane_damping_n_s_per_mm;
                }
                if pushing || !grasped.is_empty() {
                    continue;
                }
            }
            let solver = &mut tool.haptic.stiffness[o];
            let normals = object.model.rest_normals();
            for &node in &contacts.held {
                surface_normal += normals
                    .get(node as usize)
                    .copied()
                    .unwrap_or_else(Vec3::zeros);
            }
            if contacts.held.is_empty() && grasped.is_empty() {
                // Before a tool's first contact its planes carry the stiffness of a touch-down at the plane's
                // node (the solver's result for that node alone; on a multi-rate object, solved on its mirror,
                // the latest finished step).
                let touchdown = !tool.haptic.plane_measured;
                if !touchdown {
                    solver.forget();
                }
                let tip_plane = plane_count;
                let surface = Surface {
                    model: &object.model,
                    state: &object.state,
                    collider: &object.collider,
                };
                if plane_count < MAX_PLANES
                    && let Some(plane) = nearest_surface_plane(
                        &tool.body.collider,
                        &tool.position_mm,
                        &tool.rotation,
                        PLANE_LOOK_AHEAD_MM,
                        &surface,
                        &mut object.marks,
                        &mut tool.haptic.plane_candidates,
                    )
                {
                    let along =
                        |m: &Matrix3<f32>| (plane.normal.transpose() * m * plane.normal)[(0, 0)];
                    let (stiffness_n_per_mm, damping_n_s_per_mm) = match solver.response() {
                        Some(r) if touchdown => {
                            let kd = (
                                along(&r.stiffness_n_per_mm).max(0.0),
                                along(&r.damping_n_s_per_mm).max(0.0),
                            );
                            tool.haptic.touchdown_plane = Some(kd);
                            kd
                        }
                        _ => (
                            tool.haptic.plane_stiffness_n_per_mm,
                            tool.haptic.plane_damping_n_s_per_mm,
                        ),
                    };
                    let queue = &mut tool.haptic.touchdown[o];
                    if touchdown && queue.wants(plane.node, solver.response().is_some()) {
                        // The tool moved down the plane's normal until it presses a quarter of its
                        // reach past the plane (TOUCHDOWN_DEPTH_PER_REACH).
                        let n = plane.normal;
                        let reach_mm = tool.body.collider.reach_along_mm(&tool.rotation, &(-n));
                        let depth_mm = crate::haptics::TOUCHDOWN_DEPTH_PER_REACH * reach_mm;
                        let pressed_mm = tool.position_mm
                            - n * (n.dot(&tool.position_mm) - plane.offset_mm + depth_mm);
                        let (collider, rotation) = (&tool.body.collider, &tool.rotation);
                        queue.queue(
                            plane.node,
                            n,
                            &tool.haptic.plane_candidates,
                            &object.state.positions_mm,
                            |p| collider.distance_mm(&pressed_mm, rotation, p) <= 1e-4,
                        );
                        self.tail_due = true;
                    }
                    planes[plane_count] = WorldPlane {
                        stiffness_n_per_mm,
                        damping_n_s_per_mm,
                        ..plane
                    };
                    plane_count += 1;
                } else if touchdown {
                    solver.forget();
                }
                if object.lane.is_some() {
                    // The tick renders the tip's plane on a multi-rate object until its step answers.
                    let tip = (plane_count > tip_plane).then(|| planes[tip_plane]);
                    let node_mm = tip
                        .and_then(|p| object.state.positions_mm.get(p.node as usize).copied())
                        .unwrap_or_else(Vec3::zeros);
                    let reach_mm = tip.map_or(0.0, |p| {
                        tool.body
                            .collider
                            .reach_along_mm(&tool.rotation, &(-p.normal))
                    });
                    tool.haptic.lane_planes[o].update(tip, node_mm, reach_mm, &tool.position_mm);
                }
                // The shaft's own plane, where it would meet a surface the tip's plane does not keep it
                // out of (a tool laid low over the tissue, its shaft lower than its tip's reach): at the tip's
                // plane's stiffness on this object (before a first contact, its touch-down's: the same
                // tissue, under a footprint no larger than the shaft's, so softer, never stiffer), else the
                // tool's measured stiffness or the prior.
                let (shaft_k, shaft_d) = if plane_count > tip_plane {
                    (
                        planes[tip_plane].stiffness_n_per_mm,
                        planes[tip_plane].damping_n_s_per_mm,
                    )
                } else {
                    (
                        tool.haptic.plane_stiffness_n_per_mm,
                        tool.haptic.plane_damping_n_s_per_mm,
                    )
                };
                let centre_mm = tool.shaft_centre_mm();
                if plane_count < MAX_PLANES
                    && let Some(shaft) = &tool.body.shaft
                    && let Some(plane) = nearest_shaft_plane(
                        shaft,
                        &centre_mm,
                        &tool.position_mm,
                        &tool.rotation,
                        PLANE_LOOK_AHEAD_MM,
                        &surface,
                        &mut object.marks,
                        &mut tool.haptic.plane_candidates,
                    )
                    && !planes[..plane_count].iter().any(|p| p.keeps_out(&plane))
                {
                    planes[plane_count] = WorldPlane {
                        stiffness_n_per_mm: shaft_k,
                        damping_n_s_per_mm: shaft_d,
                        ..plane
                    };
                    plane_count += 1;
                }
                continue;
            }
            tool.haptic.end_touchdown(o);
            let solver = &mut tool.haptic.stiffness[o];
            let first = contacts
                .held
                .first()
                .or(grasped.first())
                .copied()
                .unwrap_or(0);
            let normal = push_n.try_normalize(1e-9).unwrap_or_else(|| {
                object
                    .model
                    .rest_normals()
                    .get(first as usize)
                    .copied()
                    .unwrap_or_else(Vec3::z)
            });
            // The solver's next iterations belong to the tick's tail: they read this tick's final state and
            // contacts and refine K for the next ticks, so they run after this tick's forces are published.
            tool.haptic.stiffness_due[o] = Some(normal);
            self.tail_due = true;
            match solver.response() {
                Some(response) => {
                    k += response.stiffness_n_per_mm;
                    d += response.damping_n_s_per_mm;
                }
                None if attached => {
                    // First ticks of a grasp, before the solve finishes: the last measured normal
                    // stiffness of this tool, in every direction.
                    k += Matrix3::identity() * tool.haptic.plane_stiffness_n_per_mm;
                    d += Matrix3::identity() * tool.haptic.plane_damping_n_s_per_mm;
                }
                None => {
                    // First ticks of a contact, before the solve finishes: the last measured normal
                    // stiffness of this tool along the contact normal.
                    if let Some(n) = push_n.try_normalize(1e-9) {
                        k += n * n.transpose() * tool.haptic.plane_stiffness_n_per_mm;
                        d += n * n.transpose() * tool.haptic.plane_damping_n_s_per_mm;
                    }
                }
            }
        }
        if let Some(n) = push_n.try_normalize(1e-9)
            && out.in_contact
            && tool.active
            && !attached
        {
            // The normal stiffness the tissue actually shows, capped by the frozen-contact solve; measured
            // along the tissue's surface normal under the tool (`s`), which stays put as the tool strokes,
            // where the push's direction turns with the stroke (a frictional tool ploughs: 0.1 rad each way
            // on the pad), and 20 mm out a turn of 0.1 rad moved `-n . p` by 2 mm: the fit saw a force that
            // did not change with a depth that did, and the model lost its normal stiffness (0.04 against
            // 0.2 N/mm), so the hand bobbed by 2 mm at 100 ms; the cautery's tip, frictionless, tilts its push
            // 0.05 rad crossing a node and lost its 0.034 N/mm the same way.
            let s = surface_normal.try_normalize(1e-6).unwrap_or(n);
            tool.haptic
                .estimate
                .record(-s.dot(&tool.position_mm), s.dot(&push_n), dt_s);
            // K is rank one along the CURRENT contact normal (the solve may have started on an older one).
            let solved = (n.transpose() * k * n)[(0, 0)].max(0.0);
            let kn = tool
                .haptic
                .estimate
                .stiffness_n_per_mm(solved)
                .unwrap_or(solved);
            k = n * n.transpose() * kn;
            let dn = (n.transpose() * d * n)[(0, 0)].max(0.0);
            d = n * n.transpose() * dn;
            if kn.is_finite() && kn > 0.0 {
                tool.haptic.plane_measured = true;
                tool.haptic.plane_stiffness_n_per_mm = kn;
                tool.haptic.plane_damping_n_s_per_mm = (n.transpose() * d * n)[(0, 0)].max(0.0);
            }
            if out.friction_coefficient > 0.0 {
                tool.haptic.friction.record(
                    &out.friction_world_n,
                    n.dot(&push_n),
                    &tool.drive.coupling.velocity_mm_s(),
                    &n,
                    dt_s,
                );
                out.friction_coefficient =
                    tool.haptic.friction.coefficient(out.friction_coefficient);
                let k_c = tool.drive.coupling.params().stiffness_n_per_mm;
                // From the frozen-contact solve, not the fitted slope: stuck nodes are exactly a held set
                // that does not change, which is what the solve assumes.
                out.stick_stiffness_n_per_mm = stick_stiffness_n_per_mm(solved, k_c);
            }
        }
        if attached || out.stick_stiffness_n_per_mm <= 0.0 || out.friction_coefficient <= 0.0 {
            // A grasp renders its held tissue bilaterally (no friction term); without a stick spring there
            // is no friction term either, and `f0` keeps the friction.
            out.friction_coefficient = 0.0;
            out.stick_stiffness_n_per_mm = 0.0;
        }
        if !out.in_contact || !tool.active || attached {
            tool.haptic.estimate.reset();
        }
        if !tool.active {
            tool.haptic.friction.reset();
        }
        out.attached = attached;
        tool.haptic.contact_k = k;
        tool.haptic.last_force_n = out.force_world_n;
        if tool.active {
            let step = tool.position_mm - tool.drive.last_position_mm;
            self.budget.record(t, &out.force_world_n, &step, dt_s);
            self.budget.record_turn(t, turned_mj, dt_s);
        } else {
            self.budget.release(t);
        }
        let tool = &self.tools[t];
        out.position_world_mm = tool.position_mm;
        out.velocity_world_mm_s = tool.drive.coupling.velocity_mm_s();
        out.device_world_mm = tool.drive.device_mm;
        out.device_velocity_world_mm_s = tool.drive.device_velocity_mm_s;
        out.stiffness_n_per_mm = if attached {
            // A grasp is rendered from the device position that drove the tool (`device_world_mm`), through
            // the coupling: the tissue's K in series with the coupling's k_c, K_eff = k_c K (K + k_c I)^-1.
            // (Rendering the tissue's K from the tool's position counted the coupling's static lag F / k_c as
            // tissue stretch: +0.3 N at a firm hand's 3 N pull.)
            let k_c = tool.drive.coupling.params().stiffness_n_per_mm;
            (k * k_c)
                * (k + Matrix3::identity() * k_c)
                    .try_inverse()
                    .unwrap_or_else(Matrix3::zeros)
        } else {
            k
        };
        out.damping_n_s_per_mm = d;
        out.planes = planes;
        out.plane_count = plane_count as u8;
        out.energy_allowance_mj = self.budget.allowance_mj(t) as f32;
    }
}

/// Tangential over normal stiffness of a stuck contact on an elastic half-space, Mindlin (1949):
/// `2 (1 - nu) / (2 - nu)`, at Poisson's ratio 0.5 (soft tissue is nearly incompressible).
pub const MINDLIN_TANGENTIAL_RATIO: f32 = 2.0 / 3.0;

/// The stick spring a distant device renders, N/mm: the stuck contact's tangential stiffness (the tissue's
/// normal contact stiffness `kn_n_per_mm` times [`MINDLIN_TANGENTIAL_RATIO`]) in series with the coupling's
/// `k_c_n_per_mm`, as a hand holding a stuck tool through the coupling feels it at zero delay. Zero for
/// non-finite or non-positive input. Pure.
pub fn stick_stiffness_n_per_mm(kn_n_per_mm: f32, k_c_n_per_mm: f32) -> f32 {
    let k_t = MINDLIN_TANGENTIAL_RATIO * kn_n_per_mm;
    let series = k_t * k_c_n_per_mm / (k_t + k_c_n_per_mm);
    if series.is_finite() && series > 0.0 {
        series
    } else {
        0.0
    }
}

/// Clamp to `max_force_n`, and never pass a non-finite force. Pure.
pub(super) fn limit_force(force: Vec3, max_force_n: f32, held: u32) -> ToolOutput {
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
    fn the_stick_spring_is_mindlins_tangential_stiffness_in_series_with_the_coupling() {
        // 0.6 N/mm normal: 0.4 N/mm tangential, with a 5 N/mm coupling 2 / 5.4 N/mm.
        let k = stick_stiffness_n_per_mm(0.6, 5.0);
        assert!((k - 0.4 * 5.0 / 5.4).abs() < 1e-6, "{k}");
        // Never above either spring; nothing for nothing or garbage.
        assert!(stick_stiffness_n_per_mm(100.0, 5.0) < 5.0);
        for (kn, kc) in [
            (0.0, 5.0),
            (0.6, 0.0),
            (f32::NAN, 5.0),
            (-1.0, 5.0),
            (0.6, f32::INFINITY),
        ] {
            let k = stick_stiffness_n_per_mm(kn, kc);
            assert!(k == 0.0 || (k.is_finite() && k > 0.0), "{kn} {kc}: {k}");
        }
        assert_eq!(stick_stiffness_n_per_mm(0.0, 5.0), 0.0);
        assert_eq!(stick_stiffness_n_per_mm(f32::NAN, 5.0), 0.0);
        assert_eq!(stick_stiffness_n_per_mm(-1.0, 5.0), 0.0);
    }

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
