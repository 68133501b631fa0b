//! The thread's side of a suture cutting out of its tissue (`hole_tear.rs` decides when and where).
//!
//! Owns: moving one of the thread's holes to where the tissue tore ([`SutureThread::tear_hole_to`]) and letting a
//! bite go once the thread has cut through its tissue ([`SutureThread::tear_out`]).
//!
//! Must not: allocate; an index out of range changes nothing.

use super::SutureThread;
use crate::interaction::suture::thread_hole::{HolePoint, inside_by_holes};

impl SutureThread {
    /// The tissue tore under hole `i` at `now_s`: the hole holds the thread at `point` from now on. False for no
    /// such hole.
    pub fn tear_hole_to(&mut self, i: usize, point: HolePoint, now_s: f64) -> bool {
        match self.holes.get_mut(i) {
            Some(hole) => {
                hole.tear_to(point, now_s);
                true
            }
            None => false,
        }
    }

    /// The other hole of hole `i`'s bite: its neighbour along the thread in the same tissue, the thread running
    /// inside that tissue between them (None: none, or no such hole).
    pub fn bite_partner(&self, i: usize) -> Option<usize> {
        let hole = self.holes.get(i)?;
        let (object, u_mm) = (hole.point.object(), hole.u_mm);
        [i + 1, i.wrapping_sub(1)].into_iter().find(|&j| {
            self.holes.get(j).is_some_and(|h| {
                h.point.object() == object
                    && inside_by_holes(&self.holes, object, 0.5 * (u_mm + h.u_mm))
            })
        })
    }

    /// The thread has cut through the tissue at hole `i`: the hole lets it go, with its bite's other hole in the
    /// same tissue (the neighbour along the thread that the thread runs inside that tissue to) and the track's
    /// rings between them. Returns how many holes let go (0 for no such hole).
    pub fn tear_out(&mut self, i: usize) -> u32 {
        let Some(hole) = self.holes.get(i) else {
            return 0;
        };
        let (object, u_mm) = (hole.point.object(), hole.u_mm);
        let partner = self.bite_partner(i);
        let (lo_mm, hi_mm) = partner
            .and_then(|j| self.holes.get(j))
            .map_or((u_mm, u_mm), |h| (u_mm.min(h.u_mm), u_mm.max(h.u_mm)));
        self.tracks
            .retain(|r| r.point.object() != object || r.u_mm < lo_mm || r.u_mm > hi_mm);
        let mut gone = [Some(i), partner];
        gone.sort_unstable_by(|a, b| b.cmp(a));
        let mut released = 0;
        for j in gone.into_iter().flatten() {
            self.holes.remove(j);
            released += 1;
        }
        released
    }
}
