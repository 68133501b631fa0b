//! The probe's triangle pass: the surface between the held nodes keeps out of a ball or capsule tip too.
//!
//! Owns: [`ProbeContacts::hold_triangles`], run by [`ProbeContacts::project`] after its node pass. Node contact
//! alone holds a surface that is finer than the tool (the pad's 1 mm nodes under a 4 mm probe); on a coarse
//! one (the liver's 3-5 mm surface) a stroked sphere slipped between the nodes, they ended on its sides and
//! the organ closed over it. So every candidate triangle the tip reaches into deeper than a triangle with its
//! corners on the tip's surface would (its sagitta, `L^2 / 8r` for its longest edge `L`, plus
//! [`TRIANGLE_SLACK_MM`]) is moved as a whole along its corners' push (minus their mean outward rest normal)
//! until it is no deeper than that, and its free corners are held there with the tool's normal at the contact:
//! the tool feels them as it feels any held node. On a fine surface the allowance is never reached and the
//! pass moves nothing. A grasper's contacts never run it (`sim::from_scene`, `StepLane::with_triangle_contact`):
//! its jaws bite the nodes by its tip, which the pass would hold away.
//!
//! Only contacts under the tool count (its normal there within 60 degrees of the push): a triangle that meets
//! the tip's side or top is a dent's wall, which the node pass and the shaft already answer. With sticky
//! contacts (a solver that pins the held nodes through its step) a triangle held last time stays held while it
//! is within [`TRIANGLE_STICK_MM`] of its allowance and the tissue presses it on the tool. A triangle met under
//! the tool is remembered as in front while the tool stays over it: if one step (the liver's is 40 ms) carries
//! it past the tip's core, it is brought back under the tip, as the node pass brings back a node held in front,
//! instead of being left over the tool.
//!
//! Must not: allocate beyond capacity, move a fixed or grasped node, or panic.

use super::{ProbeContacts, ToolBody};
use crate::collision::{EDGE_TOLERANCE, core_point_nearest, project_on_face, triangle_contact};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// How much deeper than its sagitta a triangle may reach into the tool before the pass moves it, mm: room for
/// the corners' own contact to settle, so a fine surface is left to the node pass.
pub const TRIANGLE_SLACK_MM: f32 = 0.05;

/// A contact counts when the tool's normal there is within this cosine of the push (60 degrees).
const UNDER_TOOL_COS: f32 = 0.5;

/// With sticky contacts, a triangle held last time stays held while it is within this of its allowance, mm
/// (and the tissue presses it on the tool): the tool's own small motions do not let it go.
const TRIANGLE_STICK_MM: f32 = 0.1;

/// A triangle held in front of the tool is remembered as in front while the core stays over it and within this
/// beyond the tool's radius of its plane, mm, held or not: if a step carries it past the core, it comes back.
const IN_FRONT_REACH_MM: f32 = 2.0;

impl ProbeContacts {
    /// The triangle pass (module doc). `pressure` is the model's pressure term (as the node pass computes it).
    pub(super) fn hold_triangles(
        &mut self,
        body: &ToolBody,
        model: &MassSpringModel,
        state: &mut TissueState,
        grasped: &[u32],
        pressure: f32,
    ) {
        self.triangles_held_now.clear();
        self.triangles_in_front_now.clear();
        if !self.triangles {
            return;
        }
        if let Some((core, radius_mm)) = body.tip.swept_core(&body.position_mm, &body.rotation) {
            for k in 0..self.candidate_triangles.len() {
                let t = self.candidate_triangles[k];
                self.hold_triangle(t, &core, radius_mm, model, state, grasped, pressure);
            }
        }
        self.triangles_held_now.sort_unstable();
        std::mem::swap(&mut self.triangles_held, &mut self.triangles_held_now);
        self.triangles_in_front_now.sort_unstable();
        std::mem::swap(
            &mut self.triangles_in_front,
            &mut self.triangles_in_front_now,
        );
    }

    /// One candidate triangle `t` against the tip whose core is `core`, swept by `radius_mm`.
    #[allow(clippy::too_many_arguments)] // the pass's whole context, passed down once
    fn hold_triangle(
        &mut self,
        t: u32,
        core: &[Vec3; 2],
        radius_mm: f32,
        model: &MassSpringModel,
        state: &mut TissueState,
        grasped: &[u32],
        pressure: f32,
    ) {
        let Some(&corners) = model.triangles().get(t as usize) else {
            return;
        };
        let [Some(a), Some(b), Some(c)] =
            corners.map(|v| state.positions_mm.get(v as usize).copied())
        else {
            return;
        };
        let at = [a, b, c];
        let normals = model.rest_normals();
        let push = -(corners
            .iter()
            .map(|&v| normals.get(v as usize).copied().unwrap_or_default())
            .sum::<Vec3>());
        let Some(push) = push.try_normalize(1e-6) else {
            return;
        };
        let free =
            corners.map(|v| !model.is_fixed(v as usize) && grasped.binary_search(&v).is_err());
        if !free.iter().any(|&f| f) {
            return;
        }
        let longest = (a - b).norm().max((b - c).norm()).max((c - a).norm());
        let allowance_mm = longest * longest / (8.0 * radius_mm) + TRIANGLE_SLACK_MM;
        let in_front = self.triangles_in_front.binary_search(&t).is_ok();
        // Over the face: the core's height over the triangle's plane decides, on either side of it (a triangle
        // held in front that one step carried past the core is brought back under it). Elsewhere (past an
        // edge or a corner) the nearest points do.
        let centre = core_point_nearest(core, &at);
        let face = project_on_face(&state.positions_mm, corners, &centre).and_then(
            |(weights, signed_mm, n)| {
                // Outward: against the push, whichever way the triangle is wound.
                let (outward, height_mm) = if n.dot(&push) > 0.0 {
                    (-n, -signed_mm)
                } else {
                    (n, signed_mm)
                };
                let cos = -push.dot(&outward);
                (weights.iter().all(|&w| w >= -EDGE_TOLERANCE) && cos >= UNDER_TOOL_COS)
                    .then_some((height_mm, outward, cos))
            },
        );
        let (shift_mm, normal) = match face {
            Some((height_mm, outward, cos)) => {
                // Past the core on the far side: back under it if it was in front, unless wholly past the
                // tip (nothing to bring back from there); over the tip's reach: clear of it.
                if (height_mm < 0.0 && (!in_front || height_mm <= -radius_mm))
                    || height_mm >= radius_mm
                {
                    if in_front && height_mm < radius_mm + IN_FRONT_REACH_MM {
                        self.triangles_in_front_now.push(t);
                    }
                    return;
                }
                ((radius_mm - allowance_mm - height_mm) / cos, -outward)
            }
            None => {
                let Some(contact) = triangle_contact(core, radius_mm, &at, &push) else {
                    return;
                };
                let along = contact.normal.dot(&push);
                if along < UNDER_TOOL_COS {
                    return;
                }
                ((contact.depth_mm - allowance_mm) / along, contact.normal)
            }
        };
        self.triangles_in_front_now.push(t);
        if shift_mm > 0.0 {
            let shift = push * shift_mm;
            for (&v, _) in corners.iter().zip(free).filter(|(_, f)| *f) {
                state.positions_mm[v as usize] += shift;
            }
        } else {
            let held_before = self.triangles_held.binary_search(&t).is_ok();
            let pressing = || {
                corners
                    .iter()
                    .zip(free)
                    .filter(|(_, f)| *f)
                    .map(|(&v, _)| {
                        model
                            .node_force(
                                v as usize,
                                &state.positions_mm,
                                &state.velocities_mm_s,
                                pressure,
                            )
                            .dot(&normal)
                    })
                    .sum::<f32>()
                    < 0.0
            };
            if !(self.sticky && held_before && shift_mm > -TRIANGLE_STICK_MM && pressing()) {
                return;
            }
        }
        for (&v, _) in corners.iter().zip(free).filter(|(_, f)| *f) {
            state.velocities_mm_s[v as usize] = Vec3::zeros();
            if !self.held.contains(&v) {
                self.held.push(v);
                self.normals.push(normal);
            }
        }
        self.triangles_held_now.push(t);
    }
}
