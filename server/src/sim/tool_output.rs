//! Each tool's output for the tick: the tissue's reaction force (clamped, never non-finite), contact state and
//! the local model a distant device renders (contact stiffness and damping, nearby planes, energy allowance).
//!
//! Owns: [`Sim::tool_output`], [`Sim::local_model`], `limit_force`. Must not: move tissue.

use nalgebra::Matrix3;

use crate::haptics::{MAX_PLANES, WorldPlane, nearest_surface_plane};
use crate::tissue::Vec3;

use super::*;

impl Sim {
    /// The tool's reaction force, clamped, and its contact state.
    pub(super) fn tool_output(&self, t: usize) -> ToolOutput {
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
        let instrument = tool.instrument_state.as_deref();
        let attachments = instrument.map_or(0, |i| i.held_points());
        // Added to +0 first: a -0 pull then adds as +0, to the same bits whatever the instrument.
        force += Vec3::zeros() + instrument.map_or(Vec3::zeros(), |i| i.force_on_tool_n());
        held += u32::from(attachments);
        let mut out = limit_force(force, tool.max_force_n, held);
        out.attachments = attachments;
        if let Some(instrument) = instrument {
            instrument.mark_output(&mut out);
        }
        out
    }

    /// Complete `out` with the local model around tool `t` (contact stiffness and damping, nearby surfaces,
    /// the energy allowance) and remember what the coupling needs next tick. No allocation once warm.
    pub(super) fn local_model(&mut self, t: usize, dt_s: f32, out: &mut ToolOutput) {
        let tool = &mut self.tools[t];
        let mut k = Matrix3::zeros();
        let mut d = Matrix3::zeros();
        let mut planes = [WorldPlane::default(); MAX_PLANES];
        let mut plane_count = 0usize;
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
            let solver = &mut tool.haptic.stiffness[o];
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
                    k += n * n.transpose() * tool.haptic.plane_stiffness_n_per_mm;
                    d += n * n.transpose() * tool.haptic.plane_damping_n_s_per_mm;
                }
                continue;
            }
            if contacts.held.is_empty() && grasped.is_empty() {
                solver.forget();
                if plane_count < MAX_PLANES
                    && let Some(plane) = nearest_surface_plane(
                        &tool.body.collider,
                        &tool.position_mm,
                        &tool.rotation,
                        PLANE_LOOK_AHEAD_MM,
                        &object.model,
                        &object.state,
                        &object.collider,
                        &mut object.marks,
                        &mut tool.haptic.plane_candidates,
                    )
                {
                    planes[plane_count] = WorldPlane {
                        stiffness_n_per_mm: tool.haptic.plane_stiffness_n_per_mm,
                        damping_n_s_per_mm: tool.haptic.plane_damping_n_s_per_mm,
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
                    if let Some(n) = out.force_world_n.try_normalize(1e-9) {
                        k += n * n.transpose() * tool.haptic.plane_stiffness_n_per_mm;
                        d += n * n.transpose() * tool.haptic.plane_damping_n_s_per_mm;
                    }
                }
            }
        }
        if let Some(n) = out.force_world_n.try_normalize(1e-9)
            && out.in_contact
            && tool.active
            && !attached
        {
            // The normal stiffness the tissue actually shows, capped by the frozen-contact solve.
            tool.haptic
                .estimate
                .record(-n.dot(&tool.position_mm), n.dot(&out.force_world_n), dt_s);
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
                tool.haptic.plane_stiffness_n_per_mm = kn;
                tool.haptic.plane_damping_n_s_per_mm = (n.transpose() * d * n)[(0, 0)].max(0.0);
            }
        }
        if !out.in_contact || !tool.active || attached {
            tool.haptic.estimate.reset();
        }
        out.attached = attached;
        tool.haptic.contact_k = k;
        tool.haptic.last_force_n = out.force_world_n;
        if tool.active {
            let step = tool.position_mm - tool.drive.last_position_mm;
            self.budget.record(t, &out.force_world_n, &step, dt_s);
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
    fn limit_force_clamps_and_drops_non_finite() {
        let out = limit_force(Vec3::new(0.0, 0.0, 10.0), 3.0, 4);
        assert!((out.force_world_n.norm() - 3.0).abs() < 1e-5 && out.clamped && out.in_contact);
        let out = limit_force(Vec3::new(f32::NAN, 0.0, 1.0), 3.0, 1);
        assert_eq!(out.force_world_n, Vec3::zeros());
        let out = limit_force(Vec3::new(0.0, 1.0, 0.0), 3.0, 0);
        assert!(!out.clamped && !out.in_contact && out.force_world_n.y == 1.0);
    }
}
