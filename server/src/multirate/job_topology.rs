//! A cut on a multi-rate object, carried to its step job: the tick cuts the object's model and its mirror state
//! (the latest finished step) the moment a blade sweeps, as it cuts any object, and logs here what the cut did
//! to the state, vertex by vertex. The step under way knows nothing of it; when it comes home, the log replays on
//! its state (a newer one than the cut saw) before it becomes the mirror, and the job takes the new model.
//!
//! Owns: [`TopologyLog`] (the state's changes since the last hand-off, in the order they were made). Must not:
//! decide where to cut (the sim does), or hold anything but vertex ids and shares: the log replays on any
//! state of the model it was recorded on.

use crate::tissue::TissueState;

/// One change a cut made to a state's vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
enum VertexChange {
    /// Vertex `vertex` moved to `(1 - t) vertex + t toward` (a subdivision snapped it onto the cut).
    Moved { vertex: u32, toward: u32, t: f32 },
    /// A vertex appended at `(1 - t) a + t b` (a subdivision split edge `a b`).
    Split { a: u32, b: u32, t: f32 },
    /// A vertex appended where `parent` is (an opening duplicated it).
    Copied { parent: u32 },
}

/// The changes to a multi-rate object's vertices since its last hand-off.
#[derive(Debug, Clone, Default)]
pub struct TopologyLog {
    changes: Vec<VertexChange>,
    /// The model changed (topology, or masses alone): the job takes it at the next hand-off.
    model_changed: bool,
}

impl TopologyLog {
    /// Vertex `vertex` moved `t` of the way toward `toward`, position and velocity.
    pub fn moved(&mut self, vertex: u32, toward: u32, t: f32) {
        self.changes.push(VertexChange::Moved { vertex, toward, t });
        self.model_changed = true;
    }

    /// A vertex appended `t` of the way from `a` to `b`, position and velocity.
    pub fn split(&mut self, a: u32, b: u32, t: f32) {
        self.changes.push(VertexChange::Split { a, b, t });
        self.model_changed = true;
    }

    /// A vertex appended as a copy of `parent`.
    pub fn copied(&mut self, parent: u32) {
        self.changes.push(VertexChange::Copied { parent });
        self.model_changed = true;
    }

    /// The model changed without its vertices (masses floored, springs re-made).
    pub fn model_changed(&mut self) {
        self.model_changed = true;
    }

    /// Whether the job must take the object's model at the next hand-off.
    pub fn pending(&self) -> bool {
        self.model_changed
    }

    /// Vertices the log appends.
    pub fn appended(&self) -> usize {
        self.changes
            .iter()
            .filter(|c| !matches!(c, VertexChange::Moved { .. }))
            .count()
    }

    /// Replay the changes on `state` (positions and velocities, with the same arithmetic as the cut's on the
    /// mirror), in order. A change that names a vertex `state` does not have is skipped; returns false if any
    /// was (the state was not of the model the log was recorded on).
    pub fn replay(&self, state: &mut TissueState) -> bool {
        let mut whole = true;
        for change in &self.changes {
            let n = state.positions_mm.len();
            let x = &mut state.positions_mm;
            let v = &mut state.velocities_mm_s;
            match *change {
                VertexChange::Moved { vertex, toward, t } => {
                    let (i, j) = (vertex as usize, toward as usize);
                    if i >= n || j >= n {
                        whole = false;
                        continue;
                    }
                    x[i] = x[i].lerp(&x[j], t);
                    v[i] = v[i].lerp(&v[j], t);
                }
                VertexChange::Split { a, b, t } => {
                    let (a, b) = (a as usize, b as usize);
                    if a >= n || b >= n {
                        whole = false;
                        continue;
                    }
                    let (xa, va) = (x[a].lerp(&x[b], t), v[a].lerp(&v[b], t));
                    x.push(xa);
                    v.push(va);
                }
                VertexChange::Copied { parent } => {
                    let p = parent as usize;
                    if p >= n {
                        whole = false;
                        continue;
                    }
                    let (xp, vp) = (x[p], v[p]);
                    x.push(xp);
                    v.push(vp);
                }
            }
        }
        whole
    }

    /// Forget everything (the job has taken the model).
    pub fn clear(&mut self) {
        self.changes.clear();
        self.model_changed = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tissue::Vec3;

    fn state(xs: &[f32]) -> TissueState {
        TissueState {
            positions_mm: xs.iter().map(|&x| Vec3::new(x, 0.0, 0.0)).collect(),
            velocities_mm_s: xs.iter().map(|&x| Vec3::new(0.0, x, 0.0)).collect(),
            forces_n: vec![Vec3::zeros(); xs.len()],
            external_forces_n: vec![Vec3::zeros(); xs.len()],
            pinned: Vec::new(),
        }
    }

    #[test]
    fn a_replay_makes_the_same_vertices_as_the_cut_made_on_another_state() {
        let mut log = TopologyLog::default();
        assert!(!log.pending());
        log.moved(0, 1, 0.25);
        log.split(1, 2, 0.5);
        log.copied(3);
        log.copied(1);
        assert!(log.pending());
        assert_eq!(log.appended(), 3);
        let mut s = state(&[0.0, 4.0, 8.0]);
        assert!(log.replay(&mut s));
        let x: Vec<f32> = s.positions_mm.iter().map(|p| p.x).collect();
        assert_eq!(x, [1.0, 4.0, 8.0, 6.0, 6.0, 4.0]);
        let v: Vec<f32> = s.velocities_mm_s.iter().map(|p| p.y).collect();
        assert_eq!(v, [1.0, 4.0, 8.0, 6.0, 6.0, 4.0]);
        log.clear();
        assert!(!log.pending() && log.appended() == 0);
    }

    #[test]
    fn a_log_of_another_model_is_refused_vertex_by_vertex_without_a_panic() {
        let mut log = TopologyLog::default();
        log.copied(7);
        log.split(0, 9, 0.5);
        let mut s = state(&[0.0, 1.0]);
        assert!(!log.replay(&mut s));
        assert_eq!(s.positions_mm.len(), 2);
    }
}
