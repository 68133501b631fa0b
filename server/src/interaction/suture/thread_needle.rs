//! A thread against its own needle: the curved wire it is swaged to is a solid the thread lies on and wraps
//! round, not one it passes through (a knot's loop slides off over the needle's tail, not through its body).
//!
//! Owns: [`NeedleWire`] (the needle's arc, its pose this tick and its thickness) and the push that puts a
//! segment back out of it ([`NeedleWire::keep_segment_clear`]).
//!
//! The wire is the arc swept by a ball of the needle's radius (a torus section, capped round at the tail; open
//! past the sharp tip, which a thread slips off rather than hooks on: a capped tip carried a thread hanging
//! past it into the skin). Segments, not nodes: the thread's nodes sit 2.3 mm apart and the wire is half a
//! millimetre thick, so a thread draped over the needle rests on it between two nodes. Per segment (in the
//! needle's frame), the point of the segment nearest the arc: found against the arc's chords ([`CHORDS`] of
//! them) by segment-segment closest points, then refined by alternate projections onto the arc itself and
//! back (the chords alone miss the arc's bulge between chord ends). A segment closer than the needle's radius
//! plus the thread's goes out from the arc to that clearance, the push spread over its two nodes by their
//! weights at that point and their inverse masses (the minimum-norm correction against a kinematic wire, as
//! the thread's self contact spreads its pushes), without friction. The side it goes out on is the one the
//! same point of the segment lay on at the substep's start: a thread springing past the wire within a substep
//! goes back, not on through. A node resting on a surface is not pushed into it. Against the needle's pose
//! this tick in both (the needle moves once a tick): a needle swung faster than about the clearance a substep
//! can still carry a segment through itself (`docs/suturing.md`).
//!
//! Pure and allocation-free: it runs in the thread's substeps.

use nalgebra::{Isometry3, Point3};

use super::NeedleArc;
use super::thread_self_contact::closest_params;
use crate::tissue::Vec3;

/// Chords the arc is taken as to find a segment's nearest point.
pub const CHORDS: usize = 24;
/// Alternate projections that refine it.
const REFINE: usize = 4;

/// The needle a thread meets this tick: where it is and how thick, and its chords in its own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeedleWire {
    world_from_needle: Isometry3<f32>,
    arc: NeedleArc,
    radius_mm: f32,
    chord_ends_mm: [Vec3; CHORDS + 1],
    /// The arc's box in its frame (low, high corners), mm.
    low_mm: Vec3,
    high_mm: Vec3,
}

impl NeedleWire {
    /// The needle of `arc` at `world_from_needle` this tick, its wire `radius_mm` thick.
    pub fn new(world_from_needle: Isometry3<f32>, arc: NeedleArc, radius_mm: f32) -> Self {
        let mut chord_ends_mm = [Vec3::zeros(); CHORDS + 1];
        let mut low_mm = Vec3::repeat(f32::INFINITY);
        let mut high_mm = Vec3::repeat(f32::NEG_INFINITY);
        for (k, end) in chord_ends_mm.iter_mut().enumerate() {
            *end = arc.at(arc.sweep_rad() * k as f32 / CHORDS as f32).point_mm;
            low_mm = low_mm.inf(end);
            high_mm = high_mm.sup(end);
        }
        Self {
            world_from_needle,
            arc,
            radius_mm,
            chord_ends_mm,
            low_mm,
            high_mm,
        }
    }

    /// Where the segment `seg` goes to lie at least `clearance_mm` (the thread's radius) outside the wire
    /// (module doc); None if it need not move. A segment through the arc itself (no way out to tell), a held one
    /// or a non-finite one is left where it is (None).
    pub fn clear_segment(&self, seg: &WireSegment, clearance_mm: f32) -> Option<[Vec3; 2]> {
        let [a, b] = &seg.now;
        let [a_before, b_before] = &seg.before;
        let [wa, wb] = seg.weights;
        let from_chord = usize::from(seg.swaged);
        let from_theta_rad = self.arc.sweep_rad() * from_chord as f32 / CHORDS as f32;
        let nearest_mm = |p: &Vec3| {
            let theta_rad = self.arc.offset_of(p).nearest.theta_rad.max(from_theta_rad);
            self.arc.at(theta_rad).point_mm
        };
        let reach_mm = self.radius_mm + clearance_mm;
        let la = self
            .world_from_needle
            .inverse_transform_point(&Point3::from(*a))
            .coords;
        let lb = self
            .world_from_needle
            .inverse_transform_point(&Point3::from(*b))
            .coords;
        let near = (0..3).all(|k| {
            la[k].min(lb[k]) <= self.high_mm[k] + reach_mm
                && la[k].max(lb[k]) >= self.low_mm[k] - reach_mm
        });
        if !near || (wa + wb).is_nan() || wa + wb <= 0.0 {
            return None;
        }
        // The segment's point nearest the arc, over the chords.
        let mut best: Option<(f32, f32)> = None;
        for chord in self.chord_ends_mm[from_chord..].windows(2) {
            let Some((s, _)) = closest_params(&la, &lb, &chord[0], &chord[1]) else {
                continue;
            };
            let p = la + (lb - la) * s;
            let away = p - nearest_mm(&p);
            let distance_mm = away.norm();
            if best.is_none_or(|(d, _)| distance_mm < d) {
                best = Some((distance_mm, s));
            }
        }
        let (_, mut s) = best?;
        // The chords only find the stretch: a segment lying along the wire touches it where the arc bulges
        // between chord ends. Alternate projections (segment point to the arc, arc point back to the segment)
        // settle on the segment's nearest point itself.
        let along = lb - la;
        let length2 = along.norm_squared();
        for _ in 0..REFINE {
            if length2.is_nan() || length2 <= 1e-12 {
                break;
            }
            let q = nearest_mm(&(la + along * s));
            s = ((q - la).dot(&along) / length2).clamp(0.0, 1.0);
        }
        let p = la + along * s;
        let away = p - nearest_mm(&p);
        let distance_mm = away.norm();
        if distance_mm.is_nan() || distance_mm >= reach_mm {
            return None;
        }
        // Past the sharp tip the wire has no cap: a thread across the point slips off it, it is not carried.
        let tip = self.arc.tip();
        if (p - tip.point_mm).dot(&tip.tangent) > 0.0 {
            return None;
        }
        // The side: the one the same point of the segment lay on at the substep's start, from the arc's point
        // nearest it then (a segment that crossed the wire within the substep goes back, not on through).
        let p_before = self
            .world_from_needle
            .inverse_transform_point(&Point3::from(a_before + (b_before - a_before) * s))
            .coords;
        let away_before = p_before - nearest_mm(&p_before);
        let out = if away_before.norm() > 1e-6 {
            away_before.normalize()
        } else if distance_mm > 1e-6 {
            away / distance_mm
        } else {
            return None;
        };
        // The point at s out to the reach on that side (a thread pinched between the wire and the skin slides
        // out from under the wire along the skin, or stays pinched: the skin has the last word, as with the
        // tools).
        let rotation = self.world_from_needle.rotation;
        seg.moved_at(s, |denominator| {
            rotation * ((out * reach_mm - away) / denominator)
        })
    }
}

impl WireSegment {
    /// Its nodes moved so that its point at `s` (0: the first node, 1: the second) moves by a correction `c`
    /// (world, mm): the minimum-norm correction, each node by its weight at `s` and its inverse mass times
    /// `push(d) = c / d`, `d` the weights' sum at `s`; a node resting on a surface is not pushed into it. None for
    /// a held segment or a non-finite result.
    pub fn moved_at(&self, s: f32, push: impl Fn(f32) -> Vec3) -> Option<[Vec3; 2]> {
        let [wa, wb] = self.weights;
        let (ga, gb) = (1.0 - s, s);
        let denominator = wa * ga * ga + wb * gb * gb;
        if denominator.is_nan() || denominator <= 1e-12 {
            return None;
        }
        let push = push(denominator);
        let moved = |at: &Vec3, by: Vec3, floor: &Vec3| {
            let into = by.dot(floor);
            at + if into < 0.0 { by - floor * into } else { by }
        };
        let [a, b] = &self.now;
        let to = [
            moved(a, push * (wa * ga), &self.floors[0]),
            moved(b, push * (wb * gb), &self.floors[1]),
        ];
        to.iter()
            .all(|p| p.iter().all(|c| c.is_finite()))
            .then_some(to)
    }
}

/// A thread segment as the wire meets it. The first segment, swaged into the tail, meets the wire only beyond
/// the arc's first chord: it leaves the tail along the wire's end, and may not fold back through the wire.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WireSegment {
    /// Its two nodes now, world, mm.
    pub now: [Vec3; 2],
    /// The same at the substep's start.
    pub before: [Vec3; 2],
    /// Their inverse masses, 1/kg (0: held).
    pub weights: [f32; 2],
    /// The unit outward normals of the surfaces they rest on (zero: none).
    pub floors: [Vec3; 2],
    /// The thread's first segment, swaged into the tail.
    pub swaged: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn wire() -> NeedleWire {
        NeedleWire::new(
            Isometry3::from_parts(
                Translation3::new(5.0, -2.0, 30.0),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.7),
            ),
            NeedleArc::new(10.0, 120.0).unwrap(),
            0.25,
        )
    }

    fn world(w: &NeedleWire, local: Vector3<f32>) -> Vec3 {
        (w.world_from_needle * Point3::from(local)).coords
    }

    /// Clear the segment `a b` (moved there from `a0 b0`, nodes of inverse masses `wa wb`, on no surface);
    /// true if it moved.
    #[allow(clippy::too_many_arguments)] // the segment now and before, its weights and clearance
    fn clear(
        w: &NeedleWire,
        a: &mut Vec3,
        b: &mut Vec3,
        a0: &Vec3,
        b0: &Vec3,
        wa: f32,
        wb: f32,
        clearance_mm: f32,
    ) -> bool {
        let seg = WireSegment {
            now: [*a, *b],
            before: [*a0, *b0],
            weights: [wa, wb],
            floors: [Vec3::zeros(); 2],
            swaged: false,
        };
        let Some([to_a, to_b]) = w.clear_segment(&seg, clearance_mm) else {
            return false;
        };
        (*a, *b) = (to_a, to_b);
        true
    }

    /// [`clear`] for a segment that has not moved since the substep's start.
    fn clear_here(
        w: &NeedleWire,
        a: &mut Vec3,
        b: &mut Vec3,
        wa: f32,
        wb: f32,
        clearance_mm: f32,
    ) -> bool {
        let (a0, b0) = (*a, *b);
        clear(w, a, b, &a0, &b0, wa, wb, clearance_mm)
    }

    fn local(w: &NeedleWire, world: &Vec3) -> Vec3 {
        w.world_from_needle
            .inverse_transform_point(&Point3::from(*world))
            .coords
    }

    #[test]
    fn a_segment_draped_across_the_wire_goes_out_over_it_to_the_clearance() {
        let w = wire();
        // Across the arc's middle, 0.1 mm out of its plane, its nodes 1.2 mm either side: out along +z until
        // its middle is 0.25 + 0.125 from the arc, both nodes moving alike.
        let mid = 60f32.to_radians();
        let on_arc = Vector3::new(mid.cos(), mid.sin(), 0.0) * 10.0;
        let tangent = Vector3::new(-mid.sin(), mid.cos(), 0.0);
        let across = on_arc.normalize();
        let (mut a, mut b) = (
            world(&w, on_arc + across * 1.2 + Vector3::new(0.0, 0.0, 0.1)),
            world(&w, on_arc - across * 1.2 + Vector3::new(0.0, 0.0, 0.1)),
        );
        assert!(clear_here(&w, &mut a, &mut b, 1.0, 1.0, 0.125));
        let (la, lb) = (local(&w, &a), local(&w, &b));
        assert!(
            (la.z - 0.375).abs() < 1e-3 && (lb.z - 0.375).abs() < 1e-3,
            "{la:?} {lb:?}"
        );
        assert!(la.dot(&tangent).abs() < 1e-3);
        // A held node stays; its partner takes the whole push (twice over at the middle).
        let (mut a, mut b) = (
            world(&w, on_arc + across * 1.2 + Vector3::new(0.0, 0.0, 0.1)),
            world(&w, on_arc - across * 1.2 + Vector3::new(0.0, 0.0, 0.1)),
        );
        let held = a;
        assert!(clear_here(&w, &mut a, &mut b, 0.0, 1.0, 0.125));
        assert_eq!(a, held);
        assert!((local(&w, &b).z - (0.1 + 2.0 * 0.275)).abs() < 1e-3);
    }

    #[test]
    fn a_segment_that_crossed_the_wire_within_the_substep_goes_back_to_its_side() {
        let w = wire();
        let mid = 60f32.to_radians();
        let on_arc = Vector3::new(mid.cos(), mid.sin(), 0.0) * 10.0;
        let across = on_arc.normalize();
        let at = |z: f32| {
            (
                world(&w, on_arc + across * 1.2 + Vector3::new(0.0, 0.0, z)),
                world(&w, on_arc - across * 1.2 + Vector3::new(0.0, 0.0, z)),
            )
        };
        // From 0.5 above the plane to 0.1 below it: back up to 0.375 above, not down to 0.375 below.
        let (a0, b0) = at(0.5);
        let (mut a, mut b) = at(-0.1);
        assert!(clear(&w, &mut a, &mut b, &a0, &b0, 1.0, 1.0, 0.125));
        assert!(
            (local(&w, &a).z - 0.375).abs() < 1e-3,
            "{:?}",
            local(&w, &a)
        );
        assert!((local(&w, &b).z - 0.375).abs() < 1e-3);
    }

    #[test]
    fn the_tail_is_round_the_tip_is_open_and_a_segment_clear_of_the_wire_stays() {
        let w = wire();
        // A short segment just past the tail, along its tangent (-y at angle 0): out to the clearance.
        let (mut a, mut b) = (
            world(&w, Vector3::new(10.0, -0.2, 0.0)),
            world(&w, Vector3::new(10.0, -0.6, 0.0)),
        );
        assert!(clear_here(&w, &mut a, &mut b, 1.0, 1.0, 0.125));
        assert!(
            (local(&w, &a).y + 0.375).abs() < 1e-3,
            "{:?}",
            local(&w, &a)
        );
        // Clear of it: beside the middle by more than the clearance, beyond the tip, through the centre.
        for (p, q) in [
            (Vector3::new(-1.0, 10.0, 0.5), Vector3::new(1.0, 10.0, 0.5)),
            (Vector3::new(10.0, -0.5, 0.0), Vector3::new(10.0, -2.5, 0.0)),
            (Vector3::new(-1.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0)),
        ] {
            let (mut a, mut b) = (world(&w, p), world(&w, q));
            let was = (a, b);
            assert!(!clear_here(&w, &mut a, &mut b, 1.0, 1.0, 0.125));
            assert_eq!((a, b), was);
        }
        // Past the sharp tip (angle 120 degrees, tangent (-sin, cos)), within the clearance of the point: no cap.
        let tip = 120f32.to_radians();
        let beyond = Vector3::new(tip.cos(), tip.sin(), 0.0) * 10.0
            + Vector3::new(-tip.sin(), tip.cos(), 0.0) * 0.2;
        let (mut a, mut b) = (
            world(&w, beyond),
            world(&w, beyond + Vector3::new(0.0, 0.0, 1.0)),
        );
        assert!(!clear_here(&w, &mut a, &mut b, 1.0, 1.0, 0.125));
        // A non-finite node is left as it is.
        let (mut a, mut b) = (
            Vec3::new(f32::NAN, 0.0, 0.0),
            world(&w, Vector3::new(10.0, 0.0, 0.1)),
        );
        assert!(!clear_here(&w, &mut a, &mut b, 1.0, 1.0, 0.125));
        assert!(a.x.is_nan());
    }
}
