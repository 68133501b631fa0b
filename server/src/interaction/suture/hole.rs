//! A hole the needle passes through, and the path constraint it makes: the tissue holds the needle on its own
//! path, and the needle slides through it with friction.
//!
//! Owns: [`Hole`] (a punctured material point of the surface and the angle on the needle where it holds it)
//! and its two steps: [`Hole::hold`] each substep, [`Hole::settle`] after them.
//!
//! The model (Haluck et al.'s line constraint, Coulomb's friction along it):
//! - **Across the path the constraint is hard.** Each substep the hole's point is brought onto the needle's
//!   arc: onto the arc point at its angle while it sticks, onto the arc's line through its place (its offset
//!   along the tangent left alone) while it slides. The force on the needle is the tissue's pull on the point,
//!   as a grasp reads it. A sideways push therefore meets the tissue's own stiffness through the hole, and the
//!   hand feels it through the coupling, as it feels any contact.
//! - **Along it the needle slides with friction.** The hole sticks while the pull along the tangent stays within
//!   `needle_friction` times the hole's normal load, and slides past it, the along force then held at that limit
//!   and the hole's angle read again from where the point lies; once sliding it keeps sliding (kinetic
//!   friction at the limit, against the motion) while the needle moves through it faster than 1 mm/s, so a
//!   needle driven steadily drags steadily instead of alternating stick and slip each tick. (While a hole
//!   slides the tissue is held across the path only: the kinetic drag reaches the hand, not the tissue.) The
//!   normal load is the pull across the path plus
//!   the tissue's squeeze on the needle: the needle's diameter pressed into the tissue's stiffness against a
//!   point, which the tip measured as it tented the surface there (the load at puncture over the tent's depth),
//!   so a needle driven straight along its own path still drags (published needle-tissue friction
//!   coefficients are 0.12-0.34).
//!
//! Must not: allocate or panic.

use nalgebra::{Isometry3, Point3};

use super::{NeedleArc, SurfacePoint};
use crate::tissue::{MassSpringModel, TissueState, Vec3};

/// A sliding hole keeps sliding while the needle moves through it more than this a tick, mm (1 mm/s at 1 kHz).
const KINETIC_MM: f32 = 0.001;

/// A hole the needle passes through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hole {
    /// The material point the tip punctured.
    pub point: SurfacePoint,
    /// Where along the needle it holds it: the angle from the tail, rad.
    pub theta_rad: f32,
    /// The tip made it leaving the object (an exit), not entering.
    pub exit: bool,
    /// The needle slid through it at the last settle.
    pub sliding: bool,
    /// The tissue's force on the needle through it at the last settle, world, N.
    pub force_n: Vec3,
    /// The tissue's squeeze on the needle through it, N: the normal load its friction has even when nothing
    /// pulls across the path.
    pub squeeze_n: f32,
}

impl Hole {
    /// A hole just punctured at the tip of a needle of `arc`. It starts sliding: the tented tissue springs back
    /// along the needle (the pop), held only across it, until its pull along the needle falls within the
    /// friction.
    /// `squeeze_n` is the tissue's squeeze on the needle ([`Hole::squeeze_n`]).
    pub fn new(point: SurfacePoint, arc: &NeedleArc, exit: bool, squeeze_n: f32) -> Self {
        Self {
            point,
            theta_rad: arc.sweep_rad(),
            exit,
            sliding: true,
            force_n: Vec3::zeros(),
            squeeze_n: if squeeze_n.is_finite() {
                squeeze_n.max(0.0)
            } else {
                0.0
            },
        }
    }

    /// The squeeze of tissue whose stiffness against a point is `stiffness_n_per_mm` on a needle `diameter_mm`
    /// thick, N: the wire pressed into the hole's wall by its diameter.
    pub fn squeeze_for(stiffness_n_per_mm: f32, diameter_mm: f32) -> f32 {
        (stiffness_n_per_mm * diameter_mm).max(0.0)
    }

    /// The arc's point and tangent at the hole's angle, world.
    fn on_needle(&self, arc: &NeedleArc, world_from_needle: &Isometry3<f32>) -> (Vec3, Vec3) {
        let at = arc.at(self.theta_rad);
        (
            (world_from_needle * Point3::from(at.point_mm)).coords,
            world_from_needle * at.tangent,
        )
    }

    /// One substep: bring the point onto the needle (module doc).
    pub fn hold(
        &self,
        arc: &NeedleArc,
        world_from_needle: &Isometry3<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        let Some(x) = self.point.position_mm(model, state) else {
            return;
        };
        let (target, tangent) = self.on_needle(arc, world_from_needle);
        let mut shift = target - x;
        if self.sliding {
            shift -= tangent * shift.dot(&tangent);
        }
        if let Some(dir) = shift.try_normalize(1e-9)
            && shift.iter().all(|c| c.is_finite())
        {
            // Stop what carries it back off the path (the correction's direction, reversed).
            self.point.shift(&shift, Some(&dir), model, state);
        }
    }

    /// After the substeps: read the tissue's force on the needle through the hole; stick or slide (module doc).
    /// `friction` is the material's needle friction. No allocation.
    pub fn settle(
        &mut self,
        arc: &NeedleArc,
        world_from_needle: &Isometry3<f32>,
        friction: f32,
        model: &MassSpringModel,
        state: &TissueState,
    ) {
        let (_, tangent) = self.on_needle(arc, world_from_needle);
        let pull = self.point.pull_n(model, state);
        let along = pull.dot(&tangent);
        let across = pull - tangent * along;
        let limit = friction.max(0.0) * (across.norm() + self.squeeze_n);
        // The needle's angle at the point now: while the hole slides, how far the needle slid through it.
        let theta_now = self.point.position_mm(model, state).and_then(|x| {
            let local = (world_from_needle.inverse() * Point3::from(x)).coords;
            let offset = arc.offset_of(&local);
            let theta = offset.nearest.theta_rad + offset.along_mm / arc.radius_mm();
            theta.is_finite().then_some(theta)
        });
        let slid_mm = theta_now.map_or(0.0, |t| (t - self.theta_rad) * arc.radius_mm());
        // Static friction holds up to the limit; a sliding hole keeps sliding (kinetic friction, at the limit
        // against the motion) while the needle moves through it faster than KINETIC_MM a tick.
        let keeps_sliding = self.sliding && slid_mm.abs() > KINETIC_MM;
        let along = if keeps_sliding && along.abs() <= limit {
            limit.copysign(slid_mm)
        } else {
            along.clamp(-limit, limit)
        };
        self.sliding = keeps_sliding || pull.dot(&tangent).abs() > limit;
        self.force_n = across + tangent * along;
        if !self.force_n.iter().all(|c| c.is_finite()) {
            self.force_n = Vec3::zeros();
        }
        if self.sliding
            && let Some(theta) = theta_now
        {
            self.theta_rad = theta;
        }
    }
}
