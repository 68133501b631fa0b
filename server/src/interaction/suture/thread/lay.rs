//! Placing a thread: laid out straight from its needle's tail, or along a path a scenario gives (a knot, a
//! loop), at rest.
//!
//! Owns: [`SutureThread::lay_out`], [`SutureThread::lay_along`], [`SutureThread::lift`] and whether the thread
//! is laid out. The step (`thread.rs`) lays it out again after [`SutureThread::lift`].
//!
//! Must not: allocate; a non-finite input changes nothing.

use super::SutureThread;
use crate::tissue::Vec3;

impl SutureThread {
    /// Lay the thread out straight and level from `tail_mm`, toward `away` (the way out of the tail) turned
    /// square to gravity, at rest: when it is first placed, and when its needle comes back after a gap (a
    /// thread laid along a tail pointing down would start inside whatever lies below). A non-finite input is
    /// ignored.
    pub fn lay_out(&mut self, tail_mm: &Vec3, away: &Vec3) {
        let Some(down) = self.gravity_mm_per_s2.try_normalize(1e-6) else {
            return;
        };
        let level = away - down * down.dot(away);
        let Some(away) = level
            .try_normalize(1e-3)
            .or_else(|| down.cross(&Vec3::x()).try_normalize(1e-3))
            .or_else(|| down.cross(&Vec3::y()).try_normalize(1e-3))
        else {
            return;
        };
        if !tail_mm.iter().all(|c| c.is_finite()) {
            return;
        }
        self.node_u_mm.copy_from_slice(self.chain.node_u_mm());
        for (p, u_mm) in self.chain.positions_mm.iter_mut().zip(&self.node_u_mm) {
            *p = tail_mm + away * *u_mm;
        }
        self.keep_grips(|_, _| false);
        self.come_to_rest();
        self.last_tail_mm = Some(*tail_mm);
    }

    /// Lay the thread along the polyline `path_mm` from its tail (the path's first point, which must be where
    /// the needle's tail is), each node at its material coordinate along the path (past the path's end, on
    /// along its last segment), at rest: a thread placed by a scenario, tied or looped as it starts. Refused
    /// (false, nothing changed) for a path of fewer than two points, a point that is not finite, a first
    /// segment of no length, or a thread that runs through holes. A grip whose node the path lays within
    /// [`KEEP_GRIP_MM`] of where the jaws hold it keeps it, there (a scenario laying a knot between two
    /// instruments that hold the strands); it lets go of every other grip, as [`SutureThread::lay_out`] does.
    pub fn lay_along(&mut self, path_mm: &[Vec3]) -> bool {
        if path_mm.len() < 2
            || !path_mm.iter().all(|p| p.iter().all(|c| c.is_finite()))
            || (path_mm[1] - path_mm[0]).norm() <= 0.0
            || !self.holes.is_empty()
            || !self.tracks.is_empty()
        {
            return false;
        }
        self.node_u_mm.copy_from_slice(self.chain.node_u_mm());
        let mut leg = 0usize;
        let mut leg_start_mm = 0.0f32;
        for (p, u_mm) in self.chain.positions_mm.iter_mut().zip(&self.node_u_mm) {
            let u_mm = u_mm - self.node_u_mm[0];
            loop {
                let length = (path_mm[leg + 1] - path_mm[leg]).norm();
                if u_mm <= leg_start_mm + length || leg + 2 >= path_mm.len() {
                    let along = path_mm[leg + 1] - path_mm[leg];
                    let share = if length > 0.0 {
                        (u_mm - leg_start_mm) / length
                    } else {
                        0.0
                    };
                    *p = path_mm[leg] + along * share;
                    break;
                }
                leg_start_mm += length;
                leg += 1;
            }
        }
        self.keep_grips(|grip, chain| {
            let node = grip.node as usize;
            let kept = (chain.positions_mm[node] - grip.place_mm()).norm() <= KEEP_GRIP_MM;
            if kept {
                chain.positions_mm[node] = grip.place_mm();
            }
            kept
        });
        self.come_to_rest();
        self.self_contact.forget();
        self.last_tail_mm = Some(path_mm[0]);
        true
    }

    /// Forget where the tail was: the next [`SutureThread::step`] lays the thread out again.
    pub fn lift(&mut self) {
        self.last_tail_mm = None;
    }

    /// Whether it has been laid out.
    pub fn is_laid_out(&self) -> bool {
        self.last_tail_mm.is_some()
    }

    /// At rest where it was put: no speed, no contacts or floors.
    fn come_to_rest(&mut self) {
        self.chain.velocities_mm_s.fill(Vec3::zeros());
        self.contacts.fill(None);
        self.floor.fill(Vec3::zeros());
    }
}

/// A grip keeps its node through [`SutureThread::lay_along`] when the path lays the node this close to the
/// jaws, mm.
pub const KEEP_GRIP_MM: f32 = 1.0;
