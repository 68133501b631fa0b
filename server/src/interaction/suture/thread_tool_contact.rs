//! A thread's segments against the tools: a segment lying across a tool part is put back out of it whole, not
//! only its nodes. The thread's nodes sit 2.3 mm apart and a grasper's jaws are 3 mm thick: a node-only push
//! lets a segment cut through a tool's rim with both its nodes outside, and a loop drawn along a strand the
//! jaws hold slid over them that way and off the free end past them (docs/suturing.md, "Contact inside the
//! solve").
//!
//! Owns: [`keep_segments_out_of_tools`] (a pass over the thread) and [`clear_segment_of_tool`], the push that puts one segment out of one swept-sphere tool part (a ball,
//! a capsule: the tools' tips and shafts). A mesh tool has no core to measure from, and keeps the nodes'
//! push alone.
//!
//! Per segment, the closest points of the segment and the part's core (segment-segment, or point-segment for
//! a ball); a segment closer than the part's radius plus the thread's goes out to that clearance, the push
//! spread over its two nodes by their weights at that point and their inverse masses (the minimum-norm
//! correction against a kinematic body, as the needle's wire pushes: `thread_needle.rs`), without friction.
//! The way out is the nearest, on the side the same point of the segment lay on at the substep's start (from
//! the part's core where it is now): a segment that crossed the core within a substep goes back, and a tool
//! swept across the thread carries it along rather than jumping over it. A
//! node resting on a surface is not pushed into it (pinched between a tool and the skin, the skin wins, as
//! for the nodes' push).
//!
//! Pure and allocation-free: it runs in the thread's substeps.

use super::thread::ThreadTool;
use super::thread_needle::WireSegment;
use super::thread_self_contact::closest_params;
use crate::tissue::Vec3;

/// One pass over the thread's segments (nodes `now`, at the substep's start `before`, inverse masses
/// `weight(i)`, resting on surfaces of outward normals `floor`) against the tool parts `tool(0..tools)`
/// (part `k` is tool `k / 2`'s): each segment put out of each swept-sphere part ([`clear_segment_of_tool`]),
/// but the tool whose jaws hold a node beside either of its nodes (`jaws_beside(i)`). No allocation.
pub fn keep_segments_out_of_tools<'b>(
    now: &mut [Vec3],
    before: &[Vec3],
    weight: impl Fn(usize) -> f32,
    floor: &[Vec3],
    jaws_beside: impl Fn(usize) -> Option<usize>,
    tools: usize,
    tool: &impl Fn(usize) -> Option<ThreadTool<'b>>,
) {
    for i in 0..now.len().saturating_sub(1) {
        if weight(i) + weight(i + 1) <= 0.0 {
            continue;
        }
        let (jaws_a, jaws_b) = (jaws_beside(i), jaws_beside(i + 1));
        for k in 0..tools {
            if jaws_a == Some(k / 2) || jaws_b == Some(k / 2) {
                continue;
            }
            let Some((collider, position_mm, rotation)) = tool(k) else {
                continue;
            };
            let Some((core, radius_mm)) = collider.swept_core(&position_mm, &rotation) else {
                continue;
            };
            let segment = WireSegment {
                now: [now[i], now[i + 1]],
                before: [before[i], before[i + 1]],
                weights: [weight(i), weight(i + 1)],
                floors: [floor[i], floor[i + 1]],
                swaged: false,
            };
            if let Some([a, b]) =
                clear_segment_of_tool(&core, radius_mm, &segment, 0.5 * super::THREAD_DIAMETER_MM)
            {
                (now[i], now[i + 1]) = (a, b);
            }
        }
    }
}

/// The point of core `c0 c1` nearest `p`, as a parameter in `[0, 1]` (0 for a point core).
fn nearest_on_core(c0: &Vec3, c1: &Vec3, p: &Vec3) -> f32 {
    let axis = c1 - c0;
    let length2 = axis.norm_squared();
    if length2.is_nan() || length2 <= 1e-12 {
        return 0.0;
    }
    ((p - c0).dot(&axis) / length2).clamp(0.0, 1.0)
}

/// A correction that would move a node further than this is not a contact's (the segment is pinned through the
/// part, say): it is left to the nodes' push, mm.
const MAX_MOVE_MM: f32 = 2.0;
/// Corrections per segment: a segment turned by its push (one node held, say) has a new nearest point, which
/// the next one puts out.
const CORRECTIONS: usize = 3;

/// Where segment `seg` goes to lie at least `clearance_mm` (the thread's radius) outside the swept sphere of
/// radius `radius_mm` round the core `core` (world; both ends equal for a ball); None if it need not move. A
/// segment through the core itself with no side to tell, a held one or a non-finite one is left where it is.
pub fn clear_segment_of_tool(
    core: &[Vec3; 2],
    radius_mm: f32,
    seg: &WireSegment,
    clearance_mm: f32,
) -> Option<[Vec3; 2]> {
    let mut now = correct_once(core, radius_mm, seg, clearance_mm)?;
    for _ in 1..CORRECTIONS {
        let again = WireSegment { now, ..*seg };
        match correct_once(core, radius_mm, &again, clearance_mm) {
            Some(to) => now = to,
            None => break,
        }
    }
    Some(now)
}

/// One minimum-norm correction of [`clear_segment_of_tool`].
fn correct_once(
    core: &[Vec3; 2],
    radius_mm: f32,
    seg: &WireSegment,
    clearance_mm: f32,
) -> Option<[Vec3; 2]> {
    let [a, b] = &seg.now;
    let [wa, wb] = seg.weights;
    if (wa + wb).is_nan() || wa + wb <= 0.0 {
        return None;
    }
    let [c0, c1] = core;
    let reach_mm = radius_mm + clearance_mm;
    // A held node inside the part: no move of the other clears the segment.
    let inside = |p: &Vec3| (p - (c0 + (c1 - c0) * nearest_on_core(c0, c1, p))).norm() < reach_mm;
    if (wa <= 0.0 && inside(a)) || (wb <= 0.0 && inside(b)) {
        return None;
    }
    // A quick reject on the boxes.
    let far = (0..3).any(|k| {
        a[k].min(b[k]) > c0[k].max(c1[k]) + reach_mm || a[k].max(b[k]) < c0[k].min(c1[k]) - reach_mm
    });
    if far {
        return None;
    }
    let s = if (c1 - c0).norm_squared() > 1e-12 {
        closest_params(a, b, c0, c1).map(|(s, _)| s)
    } else {
        let along = b - a;
        let length2 = along.norm_squared();
        (length2 > 1e-12).then(|| ((c0 - a).dot(&along) / length2).clamp(0.0, 1.0))
    }?;
    let p = a + (b - a) * s;
    let q = c0 + (c1 - c0) * nearest_on_core(c0, c1, &p);
    let away = p - q;
    let distance_mm = away.norm();
    if distance_mm.is_nan() || distance_mm >= reach_mm {
        return None;
    }
    // The way out: the nearest, on the side where the same point of the segment lay at the substep's start
    // (from the core as it is now); straight back to that side through the core.
    let [a_before, b_before] = &seg.before;
    let p_before = a_before + (b_before - a_before) * s;
    let away_before = p_before - (c0 + (c1 - c0) * nearest_on_core(c0, c1, &p_before));
    let out = if distance_mm > 1e-6 {
        let nearest = away / distance_mm;
        if nearest.dot(&away_before) < 0.0 {
            -nearest
        } else {
            nearest
        }
    } else if away_before.norm() > 1e-6 {
        away_before.normalize()
    } else {
        return None;
    };
    // The point at s goes to the reach on that side.
    let to = seg.moved_at(s, |denominator| (q + out * reach_mm - p) / denominator)?;
    ((to[0] - a).norm() <= MAX_MOVE_MM && (to[1] - b).norm() <= MAX_MOVE_MM).then_some(to)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn segment(now: [Vec3; 2], before: [Vec3; 2]) -> WireSegment {
        WireSegment {
            now,
            before,
            weights: [1.0, 1.0],
            floors: [Vec3::zeros(); 2],
            swaged: false,
        }
    }

    /// A capsule along z, 1.5 mm round a core from z = -3 to 3.
    const CORE: [Vec3; 2] = [Vec3::new(0.0, 0.0, -3.0), Vec3::new(0.0, 0.0, 3.0)];

    /// A segment whose two nodes lie outside the capsule but whose middle cuts through its rim (the case the
    /// nodes' push misses) goes back out on the side it came from, its middle the clearance clear.
    #[test]
    fn a_segment_cutting_a_capsules_rim_goes_back_out_whole_on_the_side_it_came_from() {
        let (x, y) = (1.0, 1.3);
        let now = [Vec3::new(x, -y, 0.0), Vec3::new(x, y, 0.0)];
        // Both nodes are outside the capsule plus the thread's radius: a node push would leave it.
        assert!(now.iter().all(|p| p.xy().norm() > 1.6));
        let before = [
            now[0] + Vec3::new(1.0, 0.0, 0.0),
            now[1] + Vec3::new(1.0, 0.0, 0.0),
        ];
        let [a, b] = clear_segment_of_tool(&CORE, 1.5, &segment(now, before), 0.1).unwrap();
        let middle = 0.5 * (a + b);
        assert!((middle.xy().norm() - 1.6).abs() < 1e-4, "{middle:?}");
        assert!(middle.x > 0.0, "pushed through to the far side: {middle:?}");
        // Equal weights at the middle: both nodes move alike, along x.
        assert!(((a - now[0]) - (b - now[1])).norm() < 1e-5);
        // Clear already: nothing.
        assert!(clear_segment_of_tool(&CORE, 1.5, &segment([a, b], [a, b]), 0.1).is_none());
    }

    /// A segment swept through the core within a substep goes back the way it came, not on through: the
    /// side is the start's.
    #[test]
    fn a_segment_that_crossed_the_core_in_a_substep_goes_back_the_way_it_came() {
        let now = [Vec3::new(-0.3, -2.0, 1.0), Vec3::new(-0.3, 2.0, 1.0)];
        let before = [Vec3::new(2.0, -2.0, 1.0), Vec3::new(2.0, 2.0, 1.0)];
        let [a, b] = clear_segment_of_tool(&CORE, 1.5, &segment(now, before), 0.1).unwrap();
        assert!(a.x > 1.59 && b.x > 1.59, "{a:?} {b:?}");
    }

    /// A ball's core is a point; a held node takes nothing (the other takes it all); a node on a floor is not
    /// pushed into it; a non-finite segment is left alone.
    #[test]
    fn a_ball_pushes_the_free_node_and_never_into_a_floor_nor_a_nan() {
        let ball = [Vec3::zeros(); 2];
        let now = [Vec3::new(-2.0, 0.5, 0.0), Vec3::new(2.0, 0.5, 0.0)];
        let mut seg = segment(now, now);
        seg.weights = [0.0, 1.0];
        let [a, b] = clear_segment_of_tool(&ball, 1.0, &seg, 0.1).unwrap();
        assert_eq!(a, now[0]);
        assert!(b.y > now[1].y);
        let closest = (0..=100)
            .map(|k| (a + (b - a) * (k as f32 / 100.0)).norm())
            .fold(f32::INFINITY, f32::min);
        assert!(closest > 1.09, "{closest}");
        // Resting on a surface below it whose outward normal is -y (the push, along +y, would go into it): the
        // part into it is dropped, which is all of it.
        let mut seg = segment(now, now);
        seg.floors = [-Vec3::y(); 2];
        let [a, b] = clear_segment_of_tool(&ball, 1.0, &seg, 0.1).unwrap();
        assert!((a - now[0]).norm() < 1e-6 && (b - now[1]).norm() < 1e-6);
        let nan = segment([Vec3::new(f32::NAN, 0.0, 0.0), now[1]], now);
        assert!(clear_segment_of_tool(&ball, 1.0, &nan, 0.1).is_none());
        // A held node inside the ball (a thread's end in the jaws that hold it): the other is not flung out.
        let mut seg = segment([Vec3::new(0.5, 0.0, 0.0), Vec3::new(2.5, 0.2, 0.0)], now);
        seg.weights = [0.0, 1.0];
        assert!(clear_segment_of_tool(&ball, 1.0, &seg, 0.1).is_none());
    }
}
