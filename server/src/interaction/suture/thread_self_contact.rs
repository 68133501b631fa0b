//! A thread against itself: no two of its segments come closer than its diameter, and none passes through
//! another.
//!
//! Owns: [`SelfContact`] (its pass over the thread's segment pairs, and the side each close pair lay on when
//! last apart) and the segment-segment closest points it works on ([`closest_params`]).
//!
//! The pass, after the tissue and tool contacts of a substep: for every pair of segments that are not
//! neighbours (they share no node) and whose boxes, loosened by the diameter, overlap:
//! - their closest points now, at parameters `(s, t)`, and the same parameters' points at the substep's start;
//! - the side: the one the pair lay on when last apart (remembered per pair while their boxes overlap, and
//!   turned with them each pass they are apart), or for a pair just come close the direction from one closest
//!   point to the other at the substep's start. If the pair is now on the other side of it, it crossed (within
//!   the substep, or pushed through by another pair's push or a contact since: the memory is what catches
//!   those, where the substep's start would take the crossed state for the side);
//! - the correction: the pair is put the diameter apart along that side, the push spread over the four nodes
//!   by their weights at `(s, t)` and their inverse masses (the minimum-norm PBD correction); a held node does
//!   not move, and neither does a node resting on a surface that the push would drive into it (its floor: a
//!   strand lying on another that lies on the skin is lifted, the lower one is not pressed into the skin,
//!   which the self pass after the contacts would leave there).
//!
//! The pairs are found by a sweep and prune along x over boxes taken once a pass, and taken in the order of
//! their indices (Gauss-Seidel). The thread runs the pass twice a substep, before and after the tissue and tool
//! contacts (`thread.rs`): a tight knot may need more, and the knot will say.
//!
//! Must not: allocate or panic; a degenerate segment is skipped.

use crate::tissue::Vec3;

/// The closest points of segments `a0 a1` and `b0 b1`: `(s, t)` in `[0, 1]` with the points `a0 + s (a1 - a0)`
/// and `b0 + t (b1 - b0)` (Ericson, Real-Time Collision Detection, 5.1.9). None for a degenerate segment.
pub fn closest_params(a0: &Vec3, a1: &Vec3, b0: &Vec3, b1: &Vec3) -> Option<(f32, f32)> {
    let d1 = a1 - a0;
    let d2 = b1 - b0;
    let r = a0 - b0;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    if !(a > 1e-12 && e > 1e-12) {
        return None;
    }
    let f = d2.dot(&r);
    let c = d1.dot(&r);
    let b = d1.dot(&d2);
    let denom = a * e - b * b;
    let mut s = if denom > 1e-12 * a * e {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    (s.is_finite() && t.is_finite()).then_some((s, t))
}

/// A thread's self-contact: its scratch and what it remembers of each close pair (module doc).
#[derive(Debug, Clone)]
pub struct SelfContact {
    /// Each segment's swept box this pass.
    boxes: Vec<[Vec3; 2]>,
    /// Per pair `(i, j)`, `i * segments + j`: the side segment `i` lay on from segment `j` when last apart (unit;
    /// zero: nothing remembered), and the pass that last found the pair's boxes overlapping (a memory is kept
    /// only while they overlap pass after pass).
    sides: Vec<Vec3>,
    seen: Vec<u64>,
    pass: u64,
    /// The segments in order of their boxes' low x (sorted again each pass: nearly sorted already), and this
    /// pass's overlapping pairs, `i * segments + j` with `i < j`.
    by_x: Vec<u32>,
    candidates: Vec<u32>,
    segments: usize,
}

impl SelfContact {
    /// For a thread of `segments` segments (allocates its pair table, `segments^2` sides).
    pub fn new(segments: usize) -> Self {
        Self {
            boxes: vec![[Vec3::zeros(); 2]; segments],
            sides: vec![Vec3::zeros(); segments * segments],
            seen: vec![0; segments * segments],
            pass: 1,
            by_x: (0..segments as u32).collect(),
            candidates: Vec::with_capacity(segments * segments / 2 + 1),
            segments,
        }
    }

    /// Forget every pair's side: the thread was placed anew (laid out), and where its segments lay before
    /// says nothing of where they lie now. No allocation.
    pub fn forget(&mut self) {
        // Every memory is then from a pass that did not find its pair close (see `keep_apart`).
        self.pass += 2;
    }

    /// One pass keeping the segments of the polyline `now` (which was `before` at the substep's start) the
    /// `diameter_mm` apart (module doc). `w` are the nodes' inverse masses (0: held), `floor` the unit normal
    /// of the surface each rests on (zero: none); a polyline of other than `segments + 1` nodes is left alone.
    /// Returns the pairs pushed. No allocation.
    pub fn keep_apart(
        &mut self,
        before: &[Vec3],
        now: &mut [Vec3],
        w: &[f32],
        floor: &[Vec3],
        diameter_mm: f32,
    ) -> u32 {
        let segments = self.segments;
        let n = segments + 1;
        if now.len() != n || before.len() != n || w.len() != n || floor.len() != n || n < 4 {
            return 0;
        }
        if diameter_mm.is_nan() || diameter_mm <= 0.0 {
            return 0;
        }
        let boxes = &mut self.boxes;
        // The box each segment swept this substep (a fast pair may have passed through each other from one side to
        // the other), loosened by the diameter; taken once, before the pushes (a push moves nodes by about a
        // diameter: a pair it brings together is met next substep).
        for (s, b) in boxes.iter_mut().enumerate().take(segments) {
            let lo = now[s].inf(&now[s + 1]).inf(&before[s]).inf(&before[s + 1]);
            let hi = now[s].sup(&now[s + 1]).sup(&before[s]).sup(&before[s + 1]);
            *b = [
                lo.add_scalar(-0.5 * diameter_mm),
                hi.add_scalar(0.5 * diameter_mm),
            ];
        }
        self.pass += 1;
        // Sweep and prune along x: the pairs whose boxes overlap, then taken in the order of their indices (the
        // Gauss-Seidel order of a pass over all pairs).
        let by_x = &mut self.by_x;
        for k in 1..by_x.len() {
            let mut m = k;
            while m > 0 && boxes[by_x[m - 1] as usize][0].x > boxes[by_x[m] as usize][0].x {
                by_x.swap(m - 1, m);
                m -= 1;
            }
        }
        self.candidates.clear();
        for (k, &a) in by_x.iter().enumerate() {
            let [lo_a, hi_a] = boxes[a as usize];
            for &b in &by_x[k + 1..] {
                let [lo_b, hi_b] = boxes[b as usize];
                if lo_b.x > hi_a.x {
                    break;
                }
                let apart =
                    lo_a.y > hi_b.y || lo_b.y > hi_a.y || lo_a.z > hi_b.z || lo_b.z > hi_a.z;
                let (i, j) = (a.min(b), a.max(b));
                if apart || j < i + 2 || self.candidates.len() == self.candidates.capacity() {
                    continue;
                }
                self.candidates.push(i * segments as u32 + j);
            }
        }
        self.candidates.sort_unstable();
        let mut pushed = 0;
        for &pair in &self.candidates {
            let pair = pair as usize;
            let (i, j) = (pair / segments, pair % segments);
            // A memory from a pass that did not find the pair close is stale: the pair has been apart since.
            if self.seen[pair] + 1 != self.pass {
                self.sides[pair] = Vec3::zeros();
            }
            self.seen[pair] = self.pass;
            let (a0, a1, b0, b1) = (now[i], now[i + 1], now[j], now[j + 1]);
            let Some((s, t)) = closest_params(&a0, &a1, &b0, &b1) else {
                continue;
            };
            let on_a = a0 + (a1 - a0) * s;
            let on_b = b0 + (b1 - b0) * t;
            let gap = on_a - on_b;
            // The side the pair lay on when last apart; else at the substep's start, at the same parameters.
            let was = (before[i] + (before[i + 1] - before[i]) * s)
                - (before[j] + (before[j + 1] - before[j]) * t);
            let mut remembered = self.sides[pair];
            if remembered == Vec3::zeros() {
                // A pair just come close beside one that is (strands sliding along each other carry their
                // crossing from segment to segment): its neighbour's side.
                remembered = self.neighbour_side(i, j);
            }
            // Strands crossing (closest points inside both, not near parallel): the side is across both, the
            // common normal, and only its sign is remembered or taken from the substep's start. Two strands
            // sliding along each other cross with their points at the same parameters a millimetre along
            // them, so the start's direction at those parameters lies mostly along the strands.
            let side = match crossing_normal(&(a1 - a0), &(b1 - b0), s, t) {
                Some(normal) => {
                    let sign = [remembered, was, gap]
                        .iter()
                        .map(|v| v.dot(&normal))
                        .find(|d| d.abs() > 1e-3 * (1.0 + gap.norm()))
                        .map(f32::signum);
                    sign.map(|sign| normal * sign)
                }
                None if remembered != Vec3::zeros() => Some(remembered),
                None => was.try_normalize(1e-9).or_else(|| gap.try_normalize(1e-9)),
            };
            let Some(side) = side else {
                continue;
            };
            let along = gap.dot(&side);
            if along >= diameter_mm {
                // Apart: remember the side it is on now (a pair turning about each other turns its side).
                self.sides[pair] = gap.try_normalize(1e-9).unwrap_or(side);
                continue;
            }
            let weights = [1.0 - s, s, 1.0 - t, t];
            let nodes = [i, i + 1, j, j + 1];
            // Segment i's nodes move along the side, segment j's against it; one that would be driven into its
            // floor is held for this pair.
            let mobility = |m: usize, k: usize| {
                let sign = if m < 2 { 1.0 } else { -1.0 };
                if (side * sign).dot(&floor[k]) < 0.0 {
                    0.0
                } else {
                    w[k]
                }
            };
            let sum: f32 = (0..4)
                .map(|m| mobility(m, nodes[m]) * weights[m] * weights[m])
                .sum();
            if sum.is_nan() || sum <= 0.0 {
                continue;
            }
            let lambda = (diameter_mm - along) / sum;
            for (m, (&k, b)) in nodes.iter().zip(&weights).enumerate() {
                let sign = if m < 2 { 1.0 } else { -1.0 };
                now[k] += side * (sign * lambda * mobility(m, k) * b);
            }
            self.sides[pair] = side;
            pushed += 1;
        }
        pushed
    }

    /// The side remembered for a pair beside `(i, j)` (a segment along on either strand) this pass or the
    /// last, or zero.
    fn neighbour_side(&self, i: usize, j: usize) -> Vec3 {
        let segments = self.segments;
        let beside = [
            (i.wrapping_sub(1), j),
            (i + 1, j),
            (i, j.wrapping_sub(1)),
            (i, j + 1),
        ];
        beside
            .iter()
            .filter(|&&(a, b)| a < segments && b < segments && b >= a + 2)
            .map(|&(a, b)| a * segments + b)
            .find(|&p| self.seen[p] + 1 >= self.pass && self.sides[p] != Vec3::zeros())
            .map_or_else(Vec3::zeros, |p| self.sides[p])
    }
}

/// The unit common normal of segments `da` and `db` (their directions) when they cross: their closest points
/// `(s, t)` inside both (not at an end) and the two more than 10 degrees from parallel. Else None.
fn crossing_normal(da: &Vec3, db: &Vec3, s: f32, t: f32) -> Option<Vec3> {
    const SIN_MIN: f32 = 0.17;
    let inside = |u: f32| u > 1e-4 && u < 1.0 - 1e-4;
    if !(inside(s) && inside(t)) {
        return None;
    }
    let normal = da.cross(db);
    let floor = SIN_MIN * SIN_MIN * da.norm_squared() * db.norm_squared();
    (normal.norm_squared() > floor).then(|| normal.normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No node resting on a surface.
    const FREE: [Vec3; 4] = [Vec3::new(0.0, 0.0, 0.0); 4];

    /// One pass over the three-segment polyline `now` (from `before`), 0.25 mm thick: it pushes one pair, and
    /// leaves segment 2-3 0.25 mm above z = 0 (where segment 0-1 lies).
    fn put_back_above(before: &[Vec3; 4], now: &mut [Vec3; 4], w: &[f32; 4]) {
        let mut contact = SelfContact::new(3);
        assert_eq!(contact.keep_apart(before, now, w, &FREE, 0.25), 1);
        assert!(
            (now[2].z - 0.25).abs() < 1e-5 && (now[3].z - 0.25).abs() < 1e-5,
            "{now:?}"
        );
    }

    #[test]
    fn closest_points_of_crossing_and_parallel_segments() {
        let (s, t) = closest_params(
            &Vec3::new(-1.0, 0.0, 0.0),
            &Vec3::new(1.0, 0.0, 0.0),
            &Vec3::new(0.0, -1.0, 1.0),
            &Vec3::new(0.0, 1.0, 1.0),
        )
        .unwrap();
        assert!((s - 0.5).abs() < 1e-6 && (t - 0.5).abs() < 1e-6);
        let (s, t) = closest_params(
            &Vec3::new(0.0, 0.0, 0.0),
            &Vec3::new(1.0, 0.0, 0.0),
            &Vec3::new(2.0, 1.0, 0.0),
            &Vec3::new(3.0, 1.0, 0.0),
        )
        .unwrap();
        assert!((s - 1.0).abs() < 1e-6 && t.abs() < 1e-6);
        assert!(closest_params(&Vec3::zeros(), &Vec3::zeros(), &Vec3::x(), &Vec3::y()).is_none());
    }

    #[test]
    fn a_segment_driven_through_another_in_one_step_is_put_back_on_its_side() {
        // Segment 0-1 along x at z = 0; segment 2-3 (joined to it by 1-2) along y, moving from z = +1 to z = -1
        // through it in one step.
        let before = [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, -1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let mut now = before;
        now[2].z = -1.0;
        now[3].z = -1.0;
        let w = [0.0, 0.0, 1.0, 1.0];
        // 1-2 are neighbours; 0-1 and 2-3 are not.
        put_back_above(&before, &mut now, &w);
        // Apart by more than the diameter: nothing moves.
        let mut far = before;
        let mut contact = SelfContact::new(3);
        assert_eq!(contact.keep_apart(&before, &mut far, &w, &FREE, 0.25), 0);
        assert_eq!(far, before);
        // Put apart above it, then (say, pushed by a contact after the pass) 0.1 mm below it at the next substep's
        // start: the remembered side puts it back above, where the substep's start alone would keep it below.
        let mut crossed = now;
        crossed[2].z = -0.1;
        crossed[3].z = -0.1;
        let mut contact = SelfContact::new(3);
        let mut first = before;
        first[2].z = 0.2;
        first[3].z = 0.2;
        assert_eq!(contact.keep_apart(&before, &mut first, &w, &FREE, 0.25), 1);
        let start = crossed;
        assert_eq!(contact.keep_apart(&start, &mut crossed, &w, &FREE, 0.25), 1);
        assert!((crossed[2].z - 0.25).abs() < 1e-5, "{crossed:?}");
    }

    #[test]
    fn a_strand_sliding_along_itself_as_it_crosses_another_goes_back_across_not_along() {
        // Segment 0-1 held along x at z = 0; segment 2-3 along y 0.3 mm above it, centred 1.5 mm along y, moved
        // in one step 1.5 mm along itself and 0.4 mm down, through 0-1 to 0.1 mm below it. The points at the
        // closest parameters now lay 1.5 mm apart along y at the start: that direction would push 2-3 along
        // itself, leaving it below. The side across both (z, signed as at the start) puts it back above.
        let before = [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.5, 0.3),
            Vec3::new(0.0, 2.5, 0.3),
        ];
        let mut now = before;
        now[2] = Vec3::new(0.0, -1.0, -0.1);
        now[3] = Vec3::new(0.0, 1.0, -0.1);
        let w = [0.0, 0.0, 1.0, 1.0];
        put_back_above(&before, &mut now, &w);
        assert!(
            (now[2].y + 1.0).abs() < 1e-5,
            "pushed along itself: {now:?}"
        );
    }

    #[test]
    fn a_strand_resting_on_a_floor_is_not_pressed_into_it_by_one_lying_across_it() {
        // Segment 0-1 along x resting on the floor z = 0 (normal +z); segment 2-3 along y lying across it 0.1 mm
        // above, closer than the 0.25 mm diameter.
        let before = [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, -1.0, 0.1),
            Vec3::new(0.0, 1.0, 0.1),
        ];
        let w = [1.0; 4];
        let up = Vec3::z();
        let floor = [up, up, Vec3::zeros(), Vec3::zeros()];
        let mut now = before;
        let mut contact = SelfContact::new(3);
        assert_eq!(contact.keep_apart(&before, &mut now, &w, &floor, 0.25), 1);
        // The lower strand stays on the floor; the upper one takes the whole push.
        assert_eq!((now[0], now[1]), (before[0], before[1]));
        assert!(
            (now[2].z - 0.25).abs() < 1e-5 && (now[3].z - 0.25).abs() < 1e-5,
            "{now:?}"
        );
        // Without the floor the push is shared.
        let mut shared = before;
        let mut contact = SelfContact::new(3);
        assert_eq!(contact.keep_apart(&before, &mut shared, &w, &FREE, 0.25), 1);
        assert!(shared[0].z < 0.0 && (shared[2].z - shared[0].z - 0.25).abs() < 1e-5);
        // Both on floors that the push would drive them into: nothing moves (the contacts decide).
        let mut pinned = before;
        let down = -Vec3::z();
        let mut contact = SelfContact::new(3);
        let both = [up, up, down, down];
        assert_eq!(contact.keep_apart(&before, &mut pinned, &w, &both, 0.25), 0);
        assert_eq!(pinned, before);
    }
}
