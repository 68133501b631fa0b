//! How far a wound between two objects is open: the metric a stitch is judged by ("wound gap after
//! tightening").
//!
//! Owns: [`wound_gap_between_mm`] (the training layer's `wound_gap_mm` reads it from two sim objects; the sim
//! reports it for an exercise's wound, `sim/wound_watch.rs`). A wound here is two objects facing each other (each one edge, as in
//! `worlds/suture.toml`): the direction across it runs from the centre of one's rest bounding box to the
//! other's (a cut's or a tear's split vertices, copies at their parents' rest places, do not turn it); each
//! edge's face is its nodes that lie, at rest, at its extreme along that direction toward the other (to within
//! 0.01 mm); the gap is the least that the second edge's face reaches back along the direction, less the most
//! that the first's reaches forward, now. Negative: the edges have passed into each other that far. Must not:
//! allocate or panic.

use crate::tissue::Vec3;

/// A node lies on its edge's face when its rest position is within this of the face's plane, mm.
const FACE_TOLERANCE_MM: f32 = 0.01;

/// The gap of a wound from each edge's rest and current node positions, mm (a replica's, say). `None` for an
/// object without nodes or two objects whose rest boxes have the same centre.
pub fn wound_gap_between_mm(
    (a_rest, a_now): (&[Vec3], &[Vec3]),
    (b_rest, b_now): (&[Vec3], &[Vec3]),
) -> Option<f32> {
    // (Not the mean of the nodes: a vertex split by a cut adds a copy at its parent's rest place, which moves
    // the mean and would turn the direction enough to leave most of a face out of the 0.01 mm tolerance.)
    let centre = |rest: &[Vec3]| {
        let first = rest.first()?;
        let (lo, hi) = rest
            .iter()
            .fold((*first, *first), |(lo, hi), r| (lo.inf(r), hi.sup(r)));
        Some((lo + hi) * 0.5)
    };
    let across = (centre(b_rest)? - centre(a_rest)?).try_normalize(1e-6)?;
    // The face of an object toward the other (sign +1: its most along `across`; -1: its least), and how far
    // its nodes reach that way now (the most for +1, the least for -1, in `across`'s terms).
    let reach = |rest: &[Vec3], now: &[Vec3], sign: f32| {
        let face = rest
            .iter()
            .map(|r| sign * r.dot(&across))
            .fold(f32::NEG_INFINITY, f32::max);
        rest.iter()
            .zip(now)
            .filter(|(r, _)| face - sign * r.dot(&across) <= FACE_TOLERANCE_MM)
            .map(|(_, now)| sign * now.dot(&across))
            .fold(f32::NEG_INFINITY, f32::max)
    };
    let gap = -reach(b_rest, b_now, -1.0) - reach(a_rest, a_now, 1.0);
    gap.is_finite().then_some(gap)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube's corners, shifted by `dx` along x.
    fn cube(dx: f32) -> Vec<Vec3> {
        (0..8)
            .map(|k| Vec3::new((k & 1) as f32 + dx, ((k >> 1) & 1) as f32, (k >> 2) as f32))
            .collect()
    }

    #[test]
    fn the_gap_is_between_the_facing_faces_now() {
        let (a, b) = (cube(0.0), cube(3.0));
        // At rest: 3 - 1 = 2 mm open.
        let gap = wound_gap_between_mm((&a, &a), (&b, &b)).unwrap();
        assert!((gap - 2.0).abs() < 1e-6, "{gap}");
        // One corner of b's facing face drawn 2.5 mm toward a: they overlap 0.5 mm there.
        let mut b_now = b.clone();
        b_now[0].x -= 2.5;
        let gap = wound_gap_between_mm((&a, &a), (&b, &b_now)).unwrap();
        assert!((gap + 0.5).abs() < 1e-6, "{gap}");
        // A far corner of b moving changes nothing.
        let mut b_far = b.clone();
        b_far[1].x += 5.0;
        let gap = wound_gap_between_mm((&a, &a), (&b, &b_far)).unwrap();
        assert!((gap - 2.0).abs() < 1e-6, "{gap}");
        // A vertex split off one of b's corners (a copy at its rest place, appended), drawn toward a with it:
        // the gap reads the same as for the corner alone.
        let mut b_split = b.clone();
        b_split.push(b[3]);
        let mut b_split_now = b_now.clone();
        b_split_now.push(b_now[3]);
        let gap = wound_gap_between_mm((&a, &a), (&b_split, &b_split_now)).unwrap();
        assert!((gap + 0.5).abs() < 1e-6, "{gap}");
        assert_eq!(wound_gap_between_mm((&a, &a), (&a, &a)), None);
        assert_eq!(wound_gap_between_mm((&[], &[]), (&b, &b)), None);
    }
}
