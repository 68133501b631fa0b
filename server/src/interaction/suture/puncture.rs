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
//! Holes ([`Hole`], `hole.rs`): each puncture leaves one, a material point of the surface and the angle on the
//! needle where it holds it. The holes hold the needle on its own path and it slides through them with
//! friction. A hole whose angle passes the tip (the needle drawn back through it) closes; if it was the way in
//! of an object the tip is inside, the tip is free again. A hole whose angle passes the tail (the needle pulled
//! all the way through) is let go (the thread will take it).
//!
//! Must not: allocate once built (holes are capped at [`MAX_HOLES`]) or panic.

use nalgebra::{Isometry3, Point3};

use super::{Hole, NeedleArc, SurfacePoint, TipContact};
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
    /// The needle's wire diameter, mm (the tissue's squeeze on it sets the holes' friction).
    diameter_mm: f32,
    phase: TipPhase,
    holes: Vec<Hole>,
    /// The tip last tick, world, mm (None: not yet placed, or just released).
    last_tip_mm: Option<Vec3>,
    /// Per object, the nodes the pressed point and the holes move, sorted.
    held_nodes: Vec<Vec<u32>>,
    /// Holes the needle's tail left this tick, oldest first, for the thread to take
    /// ([`NeedleTissue::take_passed_tail`]).
    passed_tail: Vec<Hole>,
    punctures: u32,
    /// Surfaces the tip has started to press since it was built (each press is numbered by it).
    presses: u32,
}

/// What the tip pressing a surface would do if it punctured now: what a distant device needs to make the pop
/// itself ([`NeedleTissue::pop_preview`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PopPreview {
    /// The press (numbered from 1).
    pub press: u32,
    /// The tip's direction, unit, world.
    pub tip_axis: Vec3,
    /// The tissue's force on the tip now, world, N (it goes at the puncture).
    pub tip_force_n: Vec3,
    /// The push back along the tip that punctures, N (the material's puncture force).
    pub threshold_n: f32,
    /// The new hole's friction on the needle sliding through it, N (its squeeze times the needle friction).
    pub drag_n: f32,
}

impl NeedleTissue {
    /// A needle of arc `arc`, `diameter_mm` thick, touching nothing, in a scene of `objects` objects.
    pub fn new(arc: NeedleArc, diameter_mm: f32, objects: usize) -> Self {
        Self {
            arc,
            diameter_mm,
            phase: TipPhase::Free,
            holes: Vec::with_capacity(MAX_HOLES),
            passed_tail: Vec::with_capacity(MAX_HOLES),
            last_tip_mm: None,
            held_nodes: (0..objects)
                .map(|_| Vec::with_capacity(3 * (MAX_HOLES + 1)))
                .collect(),
            punctures: 0,
            presses: 0,
        }
    }

    /// Surfaces the tip has started to press since it was built.
    pub fn presses(&self) -> u32 {
        self.presses
    }

    /// While the tip presses a surface at an angle it may puncture at (within the material's `spec`): the
    /// press, the tip's direction and load, and the drag of the hole it would make ([`PopPreview`]). None
    /// otherwise (free, inside, or glancing: the tip would skate, not pop).
    pub fn pop_preview(
        &self,
        world_from_needle: &Isometry3<f32>,
        model: &MassSpringModel,
        state: &TissueState,
        spec: &PunctureSpec,
    ) -> Option<PopPreview> {
        let TipPhase::Pressing { contact, .. } = &self.phase else {
            return None;
        };
        let (_, tip_axis) = self.tip(world_from_needle);
        if contact.push.dot(&tip_axis) < spec.max_angle_rad.cos() {
            return None;
        }
        let squeeze = Hole::squeeze_for(tent_stiffness(contact, model, state), self.diameter_mm);
        let drag_n = spec.needle_friction.max(0.0) * squeeze;
        (tip_axis.iter().all(|c| c.is_finite()) && drag_n.is_finite()).then_some(PopPreview {
            press: self.presses,
            tip_axis,
            tip_force_n: contact.force_n,
            threshold_n: spec.force_n,
            drag_n,
        })
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

    /// The nodes of object `object` the tip presses and the holes hold (sorted).
    pub fn held_nodes(&self, object: usize) -> &[u32] {
        self.held_nodes.get(object).map_or(&[], |v| v.as_slice())
    }

    /// The tissue's force on the needle through its tip and its holes, world, N.
    pub fn force_on_needle_n(&self) -> Vec3 {
        let tip = match self.phase {
            TipPhase::Pressing { contact, .. } => contact.force_n,
            _ => Vec3::zeros(),
        };
        self.holes.iter().fold(tip, |sum, h| sum + h.force_n)
    }

    /// The work the needle did on the tissue through its tip, its holes and its tail (pulled by `tail_pull_n`,
    /// its thread's load) as it moved from `before` to `after` (world from needle), beyond what the holder's
    /// translation `step_mm` accounts for, mJ (N mm): `-sum f_k . (dp_k - step)` over the loads `f_k` on the
    /// needle's points (this tick's) and the motion `dp_k` the move gave those points. Zero for a needle that
    /// only translated. No allocation.
    pub fn turn_work_mj(
        &self,
        before: &Isometry3<f32>,
        after: &Isometry3<f32>,
        step_mm: &Vec3,
        tail_pull_n: &Vec3,
    ) -> f64 {
        let moved = |theta: f32| {
            let local = Point3::from(self.arc.at(theta).point_mm);
            (after * local).coords - (before * local).coords - step_mm
        };
        let tip = match self.phase {
            TipPhase::Pressing { contact, .. } => {
                -f64::from(contact.force_n.dot(&moved(self.arc.sweep_rad())))
            }
            _ => 0.0,
        };
        let work = self.holes.iter().fold(tip, |sum, h| {
            sum - f64::from(h.force_n.dot(&moved(h.theta_rad)))
        });
        // The thread's pull on the tail.
        let work = work - f64::from(tail_pull_n.dot(&moved(0.0)));
        if work.is_finite() { work } else { 0.0 }
    }

    /// The holes the needle's tail left since the last call (the thread takes them), oldest first. No
    /// allocation.
    pub fn take_passed_tail(&mut self) -> std::vec::Drain<'_, Hole> {
        self.passed_tail.drain(..)
    }

    /// Let go of everything (the tool left, or the tissue was reset): no contact, no holes.
    pub fn release(&mut self) -> u32 {
        let closed = self.holes.len() as u32;
        self.holes.clear();
        self.passed_tail.clear();
        self.phase = TipPhase::Free;
        self.last_tip_mm = None;
        for list in &mut self.held_nodes {
            list.clear();
        }
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
        }
        if let Some(list) = self.held_nodes.get_mut(object) {
            list.clear();
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
        let closed = self.close_holes();
        if closed > 0 {
            events.holes_closed += closed;
            for o in 0..objects {
                if let Some((_, model, _)) = object(o) {
                    self.rebuild_nodes(o, model);
                }
            }
        }
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
                // A crossing beside one of the needle's own holes is the hole's tissue springing back along
                // the needle, not the far wall.
                if let Some((hit, model)) = crossing(o, false)
                    && let Some((_, _, state)) = object(o)
                    && !self.holes.iter().any(|h| {
                        usize::from(h.point.object) == o
                            && h.point
                                .position_mm(model, state)
                                .is_some_and(|x| (x - hit.point_mm).norm() < HOLE_CLEARANCE_MM)
                    })
                {
                    self.press(o, hit.triangle, hit.barycentric, true, model);
                }
            }
            TipPhase::Pressing { .. } => {}
        }
        events
    }

    /// Every substep, after object `object`'s integration: the pressed point is held at the tip, and each hole
    /// holds the needle on its path.
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
        for hole in self
            .holes
            .iter()
            .filter(|h| usize::from(h.point.object) == object)
        {
            hole.hold(&self.arc, world_from_needle, model, state);
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
        for hole in &mut self.holes {
            let o = usize::from(hole.point.object);
            match object(o) {
                Some((_, model, state)) => hole.settle(
                    &self.arc,
                    world_from_needle,
                    puncture(o).needle_friction,
                    model,
                    state,
                ),
                None => hole.force_n = Vec3::zeros(),
            }
        }
        let TipPhase::Pressing { mut contact, exit } = self.phase else {
            return events;
        };
        let o = usize::from(contact.point.object);
        let Some((collider, model, state)) = object(o) else {
            self.phase = TipPhase::Free;
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
            self.rebuild_nodes(o, model);
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
                let squeeze =
                    Hole::squeeze_for(tent_stiffness(&contact, model, state), self.diameter_mm);
                self.holes
                    .push(Hole::new(contact.point, &self.arc, exit, squeeze));
            }
            self.phase = if exit {
                TipPhase::Free
            } else {
                TipPhase::Inside {
                    object: contact.point.object,
                }
            };
            self.rebuild_nodes(o, model);
            return events;
        }
        contact.follow(&tip_mm, collider, model, state);
        self.phase = TipPhase::Pressing { contact, exit };
        self.rebuild_nodes(o, model);
        events
    }

    /// Re-read the corners of what stands on object `object` (a topology change may have re-pointed them).
    pub fn topology_changed(&mut self, object: usize, model: &MassSpringModel) {
        self.rebuild_nodes(object, model);
    }

    /// Object `object` was subdivided: the pressed point and every hole on it are re-expressed on the pieces of
    /// their triangles that hold them (the same places), then the corners re-read.
    pub fn subdivided(
        &mut self,
        object: usize,
        model: &MassSpringModel,
        remap: &crate::tissue::subdivision::ElementRemap<'_>,
    ) {
        if let TipPhase::Pressing { contact, .. } = &mut self.phase {
            contact.point = contact.point.remapped(object, remap);
        }
        for hole in self.holes.iter_mut().chain(self.passed_tail.iter_mut()) {
            hole.point = hole.point.remapped(object, remap);
        }
        self.rebuild_nodes(object, model);
    }

    fn press(
        &mut self,
        object: usize,
        triangle: u32,
        barycentric: [f32; 3],
        exit: bool,
        model: &MassSpringModel,
    ) {
        let Ok(object_id) = u16::try_from(object) else {
            return;
        };
        let point = SurfacePoint {
            object: object_id,
            triangle,
            barycentric,
        };
        if let Some(contact) = TipContact::new(point, exit, model) {
            self.presses = self.presses.wrapping_add(1).max(1);
            self.phase = TipPhase::Pressing { contact, exit };
            self.rebuild_nodes(object, model);
        }
    }

    /// Object `object`'s held nodes from the pressed point and the holes on it (sorted, once each).
    fn rebuild_nodes(&mut self, object: usize, model: &MassSpringModel) {
        let Some(list) = self.held_nodes.get_mut(object) else {
            return;
        };
        list.clear();
        let pressed = match self.phase {
            TipPhase::Pressing { contact, .. } => Some(contact.point),
            _ => None,
        };
        let points = pressed
            .into_iter()
            .chain(self.holes.iter().map(|h| h.point))
            .filter(|p| usize::from(p.object) == object);
        for point in points {
            let Some(corners) = point.corners(model) else {
                continue;
            };
            for (&c, &b) in corners.iter().zip(&point.barycentric) {
                if b != 0.0
                    && let Err(at) = list.binary_search(&c)
                {
                    list.insert(at, c);
                }
            }
        }
    }

    /// Close the holes the needle left: drawn back past the tip, or pulled through past the tail. A tip inside
    /// an object whose way in closed behind it is free again.
    fn close_holes(&mut self) -> u32 {
        // A hole is left once the needle has drawn back (or on) past it by a hair: a hole made at the tip sits
        // at the sweep itself.
        let margin = HOLE_LEFT_MM / self.arc.radius_mm();
        let (first, last) = (-margin, self.arc.sweep_rad() + margin);
        let before = self.holes.len();
        let mut tip_left = None;
        let passed_tail = &mut self.passed_tail;
        self.holes.retain(|hole| {
            if hole.theta_rad > last && !hole.exit {
                tip_left = Some(hole.point.object);
            }
            if hole.theta_rad < first && passed_tail.len() < MAX_HOLES {
                passed_tail.push(*hole);
            }
            (first..=last).contains(&hole.theta_rad)
        });
        if let (Some(o), TipPhase::Inside { object }) = (tip_left, self.phase)
            && o == object
            && !self.holes.iter().any(|h| h.point.object == o && !h.exit)
        {
            self.phase = TipPhase::Free;
        }
        (before - self.holes.len()) as u32
    }
}

/// The tissue's stiffness against the tip, N/mm: the load over how far the tent has carried the point from its
/// rest along the push.
fn tent_stiffness(contact: &TipContact, model: &MassSpringModel, state: &TissueState) -> f32 {
    let depth_mm = contact
        .point
        .position_mm(model, state)
        .zip(contact.point.rest_position_mm(model))
        .map_or(0.0, |(x, rest)| (x - rest).dot(&contact.push));
    contact.load_n / depth_mm.max(MIN_TENT_MM)
}

/// A tent shallower than this is taken as this deep when the tissue's stiffness is read from it, mm.
const MIN_TENT_MM: f32 = 0.1;

/// The needle has left a hole once it lies this far past the tip or the tail, mm along the arc.
const HOLE_LEFT_MM: f32 = 0.3;

/// A tip inside an object meets its far wall only this far from the needle's holes in it, mm.
const HOLE_CLEARANCE_MM: f32 = 2.0;

/// The tip's path is tested against surface boxes loosened by this, mm (the tree is refitted in the tick's
/// tail, so its boxes may be a tick behind the surface).
const CROSSING_MARGIN_MM: f32 = 2.0;
