//! A needle against tissue: its tip tents a surface, punctures it past a force and within an angle, and the
//! needle then passes through holes.
//!
//! Owns: [`TipPhase`], [`Hole`] and [`NeedleTissue`] (the phase of the tip, the holes the needle passes through,
//! the punctures so far); a material's answer is its [`PunctureSpec`]. The instrument (`sim/instruments/needle_driver.rs`) feeds it the needle's pose and
//! the objects, stage by stage.
//!
//! The tip's life:
//! - **Free**: outside every object. When its path since the last tick enters a surface, it presses the
//!   point it met ([`TipPhase::Pressing`], a [`TipContact`]).
//! - **Pressing**: the surface tents under the tip (a [`TipContact`]: it sticks within the puncture cone and
//!   skates outside it). The tip punctures when, in the same tick, the force it drives with along its own
//!   direction (the tissue's push back along it) reaches the material's `force_n`, and its
//!   direction lies within `max_angle_rad` of the push (the surface's normal): a needle driven square to the
//!   skin goes in, a glancing one slides (Haluck et al. 2001 model puncture on force and angle; iMSTK on angle
//!   alone). On puncture the tented point is let go at once: the load drops to nothing in a tick (the pop of
//!   Frick et al.'s traces), and a hole is left where the tip went in. A tip drawn back off the surface lets
//!   it go without a hole.
//! - **Inside** an object: when its path leaves the object's surface, it presses that point from inside
//!   (outward); puncturing it is the exit, the second peak of a through-bite, and leaves a second hole.
//!
//! Holes: a hole is a material point of the surface and the angle on the needle where it sits (`theta_rad`,
//! from the tail). Each tick a hole's angle is read again from where its point lies against the arc: the needle
//! slides through its holes. A hole whose angle passes the tip (the needle drawn back through it) closes; if
//! it was the way in of an object the tip is inside, the tip is free again. A hole whose angle passes the tail
//! (the needle pulled all the way through) is let go (the thread will take it). The path constraint that holds
//! a hole on the arc, and the friction of the needle sliding through it, come next (`docs/suturing.md`, step
//! 4).
//!
//! Must not: allocate once built (holes are capped at [`MAX_HOLES`]) or panic.

use nalgebra::{Isometry3, Point3};

use super::{NeedleArc, SurfacePoint, TipContact};
use crate::collision::{SurfaceCollider, crossing_nearest};
use crate::tissue::{MassSpringModel, PunctureSpec, TissueState, Vec3};

/// The most holes a needle passes through at once.
pub const MAX_HOLES: usize = 16;

/// Where the needle's tip is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TipPhase {
    /// Outside every object.
    Free,
    /// Pressing a surface point; `exit`: from inside the object, outward.
    Pressing {
        /// The point pressed and the load.
        contact: TipContact,
        /// It presses the surface from inside.
        exit: bool,
    },
    /// Inside object `object`'s volume, through a hole.
    Inside {
        /// The object.
        object: u16,
    },
}

/// A hole the needle passes through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hole {
    /// The material point the tip punctured.
    pub point: SurfacePoint,
    /// Where along the needle it sits: the angle from the tail, rad.
    pub theta_rad: f32,
    /// The tip made it leaving the object (an exit), not entering.
    pub exit: bool,
}

/// What one stage of the needle did, counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NeedleEvents {
    /// Surfaces punctured.
    pub punctures: u32,
    /// Holes closed behind a retracting needle or let go past its tail.
    pub holes_closed: u32,
}

/// The needle's relation to the tissue (module doc).
#[derive(Debug, Clone)]
pub struct NeedleTissue {
    arc: NeedleArc,
    phase: TipPhase,
    holes: Vec<Hole>,
    /// The tip last tick, world, mm (None: not yet placed, or just released).
    last_tip_mm: Option<Vec3>,
    /// The pressed point's corners, sorted, and how many of them there are.
    pressed_nodes: [u32; 3],
    pressed_len: usize,
    punctures: u32,
}

impl NeedleTissue {
    /// A needle of arc `arc` touching nothing.
    pub fn new(arc: NeedleArc) -> Self {
        Self {
            arc,
            phase: TipPhase::Free,
            holes: Vec::with_capacity(MAX_HOLES),
            last_tip_mm: None,
            pressed_nodes: [0; 3],
            pressed_len: 0,
            punctures: 0,
        }
    }

    /// Where the tip is.
    pub fn phase(&self) -> &TipPhase {
        &self.phase
    }

    /// The holes the needle passes through, oldest first.
    pub fn holes(&self) -> &[Hole] {
        &self.holes
    }

    /// Surfaces punctured since it was built.
    pub fn punctures(&self) -> u32 {
        self.punctures
    }

    /// The needle's arc.
    pub fn arc(&self) -> &NeedleArc {
        &self.arc
    }

    /// The tip (world, mm) and its unit direction for a needle at `world_from_needle`.
    pub fn tip(&self, world_from_needle: &Isometry3<f32>) -> (Vec3, Vec3) {
        let tip = self.arc.tip();
        (
            (world_from_needle * Point3::from(tip.point_mm)).coords,
            world_from_needle * tip.tangent,
        )
    }

    /// The nodes of object `object` the tip presses (sorted).
    pub fn pressed_nodes(&self, object: usize) -> &[u32] {
        match self.phase {
            TipPhase::Pressing { contact, .. } if usize::from(contact.point.object) == object => {
                &self.pressed_nodes[..self.pressed_len]
            }
            _ => &[],
        }
    }

    /// The tissue's push on the needle through its tip, world, N.
    pub fn force_on_needle_n(&self) -> Vec3 {
        match self.phase {
            TipPhase::Pressing { contact, .. } => contact.force_n,
            _ => Vec3::zeros(),
        }
    }

    /// Let go of everything (the tool left, or the tissue was reset): no contact, no holes.
    pub fn release(&mut self) -> u32 {
        let closed = self.holes.len() as u32;
        self.holes.clear();
        self.phase = TipPhase::Free;
        self.pressed_len = 0;
        self.last_tip_mm = None;
        closed
    }

    /// Object `object` was reset to rest: forget what stood on it.
    pub fn object_reset(&mut self, object: usize) -> u32 {
        let before = self.holes.len();
        self.holes.retain(|h| usize::from(h.point.object) != object);
        let on_it = match self.phase {
            TipPhase::Pressing { contact, .. } => usize::from(contact.point.object) == object,
            TipPhase::Inside { object: o } => usize::from(o) == object,
            TipPhase::Free => false,
        };
        if on_it {
            self.phase = TipPhase::Free;
            self.pressed_len = 0;
        }
        (before - self.holes.len()) as u32
    }

    /// Stage 1 (the needle at this tick's pose, before the substeps): slide the holes along the needle and
    /// close those it left; a free tip whose path entered a surface presses it, a tip inside an object whose
    /// path left its surface presses it from inside. `object(o)` gives object `o`'s collider, model and state
    /// (None: not one a needle meets). No allocation.
    pub fn before_substeps<'a>(
        &mut self,
        world_from_needle: &Isometry3<f32>,
        objects: usize,
        object: impl Fn(usize) -> Option<(&'a SurfaceCollider, &'a MassSpringModel, &'a TissueState)>,
    ) -> NeedleEvents {
        let mut events = NeedleEvents::default();
        let (tip_mm, _) = self.tip(world_from_needle);
        if !tip_mm.iter().all(|c| c.is_finite()) {
            return events;
        }
        events.holes_closed += self.slide_holes(world_from_needle, &object);
        let from = self.last_tip_mm.replace(tip_mm);
        let Some(from) = from else {
            return events;
        };
        // Where the tip's path since the last tick crossed object `o`'s surface, entering it or leaving it.
        let crossing = |o: usize, entering: bool| {
            let (collider, model, state) = object(o)?;
            crossing_nearest(
                collider,
                model.triangles(),
                &state.positions_mm,
                &from,
                &tip_mm,
                CROSSING_MARGIN_MM,
                0.0,
                Some(entering),
            )
            .map(|hit| (hit, model))
        };
        match self.phase {
            TipPhase::Free => {
                // The first surface the tip's path entered.
                let first = (0..objects)
                    .filter_map(|o| crossing(o, true).map(|(hit, model)| (o, hit, model)))
                    .reduce(|best, next| {
                        if next.1.along < best.1.along {
                            next
                        } else {
                            best
                        }
                    });
                if let Some((o, hit, model)) = first {
                    self.press(o, hit.triangle, hit.barycentric, false, model);
                }
            }
            TipPhase::Inside { object: o } => {
                let o = usize::from(o);
                if let Some((hit, model)) = crossing(o, false) {
                    self.press(o, hit.triangle, hit.barycentric, true, model);
                }
            }
            TipPhase::Pressing { .. } => {}
        }
        events
    }

    /// Every substep, after object `object`'s integration: the pressed point is held at the tip.
    pub fn hold(
        &self,
        object: usize,
        world_from_needle: &Isometry3<f32>,
        model: &MassSpringModel,
        state: &mut TissueState,
    ) {
        if let TipPhase::Pressing { contact, .. } = &self.phase
            && usize::from(contact.point.object) == object
        {
            let (tip_mm, _) = self.tip(world_from_needle);
            contact.hold(&tip_mm, model, state);
        }
    }

    /// Stage 4 (after the substeps): read the pressed point's load; puncture it, or let it go if the tip
    /// drew back, or slide it along under the tip. `puncture(o)` is object `o`'s material. No allocation.
    pub fn after_substeps<'a>(
        &mut self,
        world_from_needle: &Isometry3<f32>,
        object: impl Fn(usize) -> Option<(&'a SurfaceCollider, &'a MassSpringModel, &'a TissueState)>,
        puncture: impl Fn(usize) -> PunctureSpec,
    ) -> NeedleEvents {
        let mut events = NeedleEvents::default();
        let TipPhase::Pressing { mut contact, exit } = self.phase else {
            return events;
        };
        let o = usize::from(contact.point.object);
        let Some((collider, model, state)) = object(o) else {
            self.phase = TipPhase::Free;
            self.pressed_len = 0;
            return events;
        };
        let (tip_mm, tip_dir) = self.tip(world_from_needle);
        let after = if exit {
            TipPhase::Inside {
                object: contact.point.object,
            }
        } else {
            TipPhase::Free
        };
        if contact.lifted(&tip_mm, model, state) {
            self.phase = after;
            self.pressed_len = 0;
            return events;
        }
        let spec = puncture(o);
        contact.settle(spec.max_angle_rad.tan(), model, state);
        // The force the tip drives with along its own direction is the tissue's push back along it.
        let along_n = -contact.force_n.dot(&tip_dir);
        let square = contact.push.dot(&tip_dir);
        if along_n >= spec.force_n && square >= spec.max_angle_rad.cos() {
            events.punctures += 1;
            self.punctures += 1;
            if self.holes.len() < MAX_HOLES {
                self.holes.push(Hole {
                    point: contact.point,
                    theta_rad: self.arc.sweep_rad(),
                    exit,
                });
            }
            self.phase = if exit {
                TipPhase::Free
            } else {
                TipPhase::Inside {
                    object: contact.point.object,
                }
            };
            self.pressed_len = 0;
            return events;
        }
        contact.follow(&tip_mm, collider, model, state);
        self.phase = TipPhase::Pressing { contact, exit };
        self.set_pressed(&contact, model);
        events
    }

    /// Re-read the pressed point's corners (a topology change may have re-pointed them).
    pub fn topology_changed(&mut self, object: usize, model: &MassSpringModel) {
        if let TipPhase::Pressing { contact, .. } = self.phase
            && usize::from(contact.point.object) == object
        {
            self.set_pressed(&contact, model);
        }
    }

    fn press(
        &mut self,
        object: usize,
        triangle: u32,
        barycentric: [f32; 3],
        exit: bool,
        model: &MassSpringModel,
    ) {
        let Ok(object) = u16::try_from(object) else {
            return;
        };
        let point = SurfacePoint {
            object,
            triangle,
            barycentric,
        };
        if let Some(contact) = TipContact::new(point, exit, model) {
            self.phase = TipPhase::Pressing { contact, exit };
            self.set_pressed(&contact, model);
        }
    }

    fn set_pressed(&mut self, contact: &TipContact, model: &MassSpringModel) {
        self.pressed_len = 0;
        if let Some(corners) = contact.point.corners(model) {
            for (&c, &b) in corners.iter().zip(&contact.point.barycentric) {
                if b != 0.0 && !self.pressed_nodes[..self.pressed_len].contains(&c) {
                    self.pressed_nodes[self.pressed_len] = c;
                    self.pressed_len += 1;
                }
            }
            self.pressed_nodes[..self.pressed_len].sort_unstable();
        }
    }

    /// Read each hole's angle on the needle from where its point lies; close the holes the needle left.
    fn slide_holes<'a>(
        &mut self,
        world_from_needle: &Isometry3<f32>,
        object: &impl Fn(usize) -> Option<(&'a SurfaceCollider, &'a MassSpringModel, &'a TissueState)>,
    ) -> u32 {
        let needle_from_world = world_from_needle.inverse();
        let sweep = self.arc.sweep_rad();
        let before = self.holes.len();
        let mut keep = 0;
        let mut tip_left = None;
        for k in 0..before {
            let mut hole = self.holes[k];
            let o = usize::from(hole.point.object);
            let at = object(o).and_then(|(_, model, state)| hole.point.position_mm(model, state));
            let Some(at) = at else {
                continue;
            };
            let local = (needle_from_world * Point3::from(at)).coords;
            let offset = self.arc.offset_of(&local);
            // Past an end, the offset along the tangent carries on the angle (positive toward the tip).
            let theta = offset.nearest.theta_rad + offset.along_mm / self.arc.radius_mm();
            if !theta.is_finite() {
                continue;
            }
            hole.theta_rad = theta;
            if theta >= sweep {
                // Drawn back through it: the way in of the object the tip is in closes behind it.
                if !hole.exit {
                    tip_left = Some(hole.point.object);
                }
                continue;
            }
            if theta <= 0.0 {
                continue;
            }
            self.holes[keep] = hole;
            keep += 1;
        }
        self.holes.truncate(keep);
        if let (Some(o), TipPhase::Inside { object }) = (tip_left, self.phase)
            && o == object
            && !self.holes.iter().any(|h| h.point.object == o && !h.exit)
        {
            self.phase = TipPhase::Free;
        }
        (before - keep) as u32
    }
}

/// The tip's path is tested against surface boxes loosened by this, mm (the tree is refitted in the tick's
/// tail, so its boxes may be a tick behind the surface).
const CROSSING_MARGIN_MM: f32 = 2.0;
