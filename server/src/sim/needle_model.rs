//! The needle's terms of a tool's local model: what a distant device needs to feel a needle's tip tent a
//! surface and pop through it the tick its own push passes the material's threshold (issue 32, "At a
//! distance").
//!
//! Owns: [`NeedlePop`] (in each [`ToolOutput`]) and [`Sim::needle_pop`]. While the needle a tool's jaws hold
//! presses a surface at an angle it may puncture at, the tool's model carries, besides its tenting (the pressed
//! point's nodes held, so the model is bilateral with the solved `K`):
//! - the push back along the tip at which it punctures: the material's puncture force plus what the rest of
//!   the model's force (the needle's holes, the thread on its tail) pushes back along the tip;
//! - the model after the pop: the tip's load gone from `f0`; `K` without its part along the tip (the needle
//!   slides on through its new hole, held across it by the tissue); the new hole's friction as a drag against
//!   the motion;
//! - the tip's lever from the tool's origin and the tool's orientation: a needle is driven by rolling its
//!   driver, and the device adds the push its own turn gives the tip (`PunctureTerm::rolled_push_n`).
//!
//! Must not: change the simulation (it reads the tick's result), or allocate.

use nalgebra::Matrix3;

use crate::tissue::Vec3;

use super::*;

/// A needle's pop, as the tool's model carries it (world frame; all zero: no needle presses).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NeedlePop {
    /// Which press (0: none).
    pub press: u32,
    /// The push back along the tip at which the tip punctures, N (> 0 when `press` is not 0).
    pub pop_at_n: f32,
    /// The tip's direction, unit, world.
    pub tip_axis: Vec3,
    /// The model's force at `x0` after the pop, world, N.
    pub f0_after_n: Vec3,
    /// The model's stiffness after the pop, N/mm (symmetric positive semi-definite).
    pub stiffness_after_n_per_mm: Matrix3<f32>,
    /// The needle's drag through its new hole after the pop, N (>= 0).
    pub drag_after_n: f32,
    /// The tip less the tool's origin, world, mm.
    pub tip_lever_mm: Vec3,
    /// The tool's orientation, world.
    pub orientation: nalgebra::UnitQuaternion<f32>,
}

impl Sim {
    /// Tool `t`'s needle pop for its output `out` (after [`Sim::local_model`]): see the module doc. No
    /// allocation.
    pub(super) fn needle_pop(&self, t: usize, out: &ToolOutput) -> NeedlePop {
        let none = NeedlePop::default();
        if !self.tools.get(t).is_some_and(|tool| tool.active) || !out.attached {
            return none;
        }
        let Some((_, needle, hold)) = self.needle_in_jaws(t) else {
            return none;
        };
        let crate::interaction::suture::TipPhase::Pressing { contact, .. } = needle.phase() else {
            return none;
        };
        let Some(object) = self.objects.get(usize::from(contact.point.object)) else {
            return none;
        };
        let Some(preview) = needle.pop_preview(
            hold.world_from_needle(),
            &object.model,
            &object.state,
            &object.puncture,
        ) else {
            return none;
        };
        let axis = preview.tip_axis;
        // The model's f0 is the tool's force (a needle driver carries no drag of cutting); the device compares
        // its whole linear force along the tip, so the rest of that force counts toward the threshold.
        let rest_n = out.force_world_n - preview.tip_force_n;
        let pop_at_n = preview.threshold_n - rest_n.dot(&axis);
        let across = Matrix3::identity() - axis * axis.transpose();
        let stiffness = across * out.stiffness_n_per_mm * across;
        let stiffness = (stiffness + stiffness.transpose()) * 0.5;
        let tool = &self.tools[t];
        let tip_mm = hold.world_from_needle() * nalgebra::Point3::from(needle.arc().tip().point_mm);
        let pop = NeedlePop {
            press: preview.press,
            pop_at_n,
            tip_axis: axis,
            f0_after_n: rest_n,
            stiffness_after_n_per_mm: stiffness,
            drag_after_n: preview.drag_n,
            tip_lever_mm: tip_mm.coords - tool.position_mm,
            orientation: tool.rotation,
        };
        let finite = pop_at_n.is_finite()
            && pop.tip_lever_mm.iter().all(|c| c.is_finite())
            && rest_n.iter().all(|c| c.is_finite())
            && stiffness.iter().all(|c| c.is_finite());
        if finite && pop_at_n > 0.0 && preview.press != 0 {
            pop
        } else {
            none
        }
    }
}
