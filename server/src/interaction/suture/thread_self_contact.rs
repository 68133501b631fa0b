//! A thread against itself: no two of its segments come closer than its diameter, and none passes through
//! another.
//!
//! Owns: [`keep_apart`], one position-based pass over the thread's segment pairs, and the segment-segment
//! closest points it works on ([`closest_params`]).
//!
//! The pass, after the tissue and tool contacts of a substep: for every pair of segments that are not
//! neighbours (they share no node) and whose boxes, loosened by the diameter, overlap:
//! - their closest points now, at parameters `(s, t)`, and the same parameters' points at the substep's start;
//! - the side: the direction from one closest point to the other at the start (the segments were apart
//!   then). If the pair is now on the other side of it, it crossed during the substep (continuous, for the
//!   speeds a thread reaches within a substep);
//! - the correction: the pair is put the diameter apart along that side, the push spread over the four nodes
//!   by their weights at `(s, t)` and their inverse masses (the minimum-norm PBD correction); a held node does
//!   not move.
//!
//! All pairs are tried with a box test on boxes taken once a pass, about 2,000 pairs for 64 segments (the
//! bench's figure is the whole thread's step; a sweep along one axis or a spatial hash is the next step if
//! threads grow). Gauss-Seidel over the pairs in order, once a
//! substep: a tight knot may need more sweeps, and the knot will say.
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

/// One pass keeping the segments of the polyline `now` (which was `before` at the substep's start) the
/// `diameter_mm` apart (module doc). `w` are the nodes' inverse masses (0: held); `boxes` is scratch, one per
/// segment (a shorter one leaves the rest of the segments out). Returns the pairs pushed. No allocation.
pub fn keep_apart(
    before: &[Vec3],
    now: &mut [Vec3],
    w: &[f32],
    diameter_mm: f32,
    boxes: &mut [[Vec3; 2]],
) -> u32 {
    let n = now
        .len()
        .min(before.len())
        .min(w.len())
        .min(boxes.len() + 1);
    if n < 4 || diameter_mm.is_nan() || diameter_mm <= 0.0 {
        return 0;
    }
    let segments = n - 1;
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
    let mut pushed = 0;
    for i in 0..segments {
        let [lo_a, hi_a] = boxes[i];
        for j in i + 2..segments {
            let [lo_b, hi_b] = boxes[j];
            if lo_a.x > hi_b.x
                || lo_b.x > hi_a.x
                || lo_a.y > hi_b.y
                || lo_b.y > hi_a.y
                || lo_a.z > hi_b.z
                || lo_b.z > hi_a.z
            {
                continue;
            }
            let (a0, a1, b0, b1) = (now[i], now[i + 1], now[j], now[j + 1]);
            let Some((s, t)) = closest_params(&a0, &a1, &b0, &b1) else {
                continue;
            };
            let on_a = a0 + (a1 - a0) * s;
            let on_b = b0 + (b1 - b0) * t;
            let gap = on_a - on_b;
            // The side the pair was on at the substep's start, at the same parameters.
            let was = (before[i] + (before[i + 1] - before[i]) * s)
                - (before[j] + (before[j + 1] - before[j]) * t);
            let side = was.try_normalize(1e-9).or_else(|| gap.try_normalize(1e-9));
            let Some(side) = side else {
                continue;
            };
            let along = gap.dot(&side);
            if along >= diameter_mm {
                continue;
            }
            let weights = [1.0 - s, s, 1.0 - t, t];
            let nodes = [i, i + 1, j, j + 1];
            let sum: f32 = nodes.iter().zip(&weights).map(|(&k, b)| w[k] * b * b).sum();
            if sum.is_nan() || sum <= 0.0 {
                continue;
            }
            let lambda = (diameter_mm - along) / sum;
            for (m, (&k, b)) in nodes.iter().zip(&weights).enumerate() {
                let sign = if m < 2 { 1.0 } else { -1.0 };
                now[k] += side * (sign * lambda * w[k] * b);
            }
            pushed += 1;
        }
    }
    pushed
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let mut boxes = [[Vec3::zeros(); 2]; 3];
        assert_eq!(keep_apart(&before, &mut now, &w, 0.25, &mut boxes), 1);
        assert!(
            (now[2].z - 0.25).abs() < 1e-5 && (now[3].z - 0.25).abs() < 1e-5,
            "{now:?}"
        );
        // Apart by more than the diameter: nothing moves.
        let mut far = before;
        assert_eq!(keep_apart(&before, &mut far, &w, 0.25, &mut boxes), 0);
        assert_eq!(far, before);
    }
}
