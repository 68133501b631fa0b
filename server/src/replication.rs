//! Mesh replication state: quantization bounds, what each object last sent, and delta/snapshot building.
//!
//! Owns: the server side of the replica contract (see [`sinew_protocol::MeshDelta`]): a vertex is sent when
//! its quantized position differs from the last one sent and the position replicas hold (the last one sent,
//! dequantized) is more than the object's delta tolerance from where it is now. A replica that applied every
//! delta therefore holds every vertex within max(tolerance, the quantization's bound) of the server's
//! position at that frame (the snapshot's `error_bound_mm`); with a tolerance of 0 it holds exactly the
//! server's quantized state. Pure data; must not touch zenoh.

pub mod frame_exchange;
pub mod scene_state;

pub use frame_exchange::{FrameData, FrameExchange};
pub use scene_state::{ReplicationState, instrument_info};

use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::{MeshDelta, ObjectSnapshot, TopologyDelta};

use crate::tissue::Vec3;

/// An object's connectivity as the sim left it: what a replica needs to follow its cuts and tears.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ObjectTopology {
    /// The sim's count of topology changes of this object (see `SimObject::topology_version`).
    pub version: u32,
    /// Surface triangles.
    pub triangles: Vec<[u32; 3]>,
    /// The world mesh's vertex count: vertices from here on were split off a parent.
    pub first_split: u32,
    /// The parent of each split vertex, in id order.
    pub parents: Vec<u32>,
}

impl ObjectTopology {
    /// Copy `object`'s topology in when its version differs (allocation only then).
    pub fn follow(&mut self, object: &crate::sim::SimObject) {
        if self.version == object.topology_version() && !self.triangles.is_empty() {
            return;
        }
        let (first, parents) = object.split_parents();
        self.version = object.topology_version();
        self.triangles.clear();
        self.triangles.extend_from_slice(object.model.triangles());
        self.first_split = first;
        self.parents.clear();
        self.parents.extend_from_slice(parents);
    }
    /// Copy `other` in when its version differs (allocation only then).
    pub fn sync_from(&mut self, other: &ObjectTopology) {
        if self.version != other.version || self.triangles.len() != other.triangles.len() {
            self.clone_from(other);
        }
    }
}

/// Replication state of one object.
#[derive(Debug, Clone)]
pub struct ObjectReplication {
    name: String,
    bounds: QuantBounds,
    triangles: Vec<[u32; 3]>,
    sent_q: Vec<[u16; 3]>,
    /// True positions at `last_frame` (for measuring a replica's error).
    sent_true_mm: Vec<[f32; 3]>,
    last_frame: u64,
    clamped: u64,
    /// Burn level last sent per vertex (0-255).
    sent_burn: Vec<u8>,
    /// The sim topology version the sent state follows.
    sent_version: u32,
    /// Topology deltas sent (the wire's epoch).
    sent_epoch: u32,
    /// A vertex is re-sent once replicas hold it further than this from its position, mm.
    tolerance_mm: f32,
}

impl ObjectReplication {
    /// Start from rest positions: bounds are their box grown by `margin_mm`; nothing sent yet (frame 0). A
    /// vertex is re-sent once replicas hold it more than `tolerance_mm` from its position (0: on every change
    /// of its quantized position).
    pub fn new(
        name: &str,
        rest_positions_mm: &[Vec3],
        triangles: &[[u32; 3]],
        margin_mm: f32,
        tolerance_mm: f32,
    ) -> Self {
        let mut min = [f32::INFINITY; 3];
        let mut max = [f32::NEG_INFINITY; 3];
        for p in rest_positions_mm {
            for a in 0..3 {
                min[a] = min[a].min(p[a]);
                max[a] = max[a].max(p[a]);
            }
        }
        let bounds = QuantBounds {
            min_mm: min.map(|v| v - margin_mm),
            max_mm: max.map(|v| v + margin_mm),
        };
        let true_mm: Vec<[f32; 3]> = rest_positions_mm.iter().map(|p| [p.x, p.y, p.z]).collect();
        let sent_q = true_mm.iter().map(|p| bounds.quantize(*p).0).collect();
        Self {
            name: name.to_owned(),
            bounds,
            triangles: triangles.to_vec(),
            sent_burn: vec![0; true_mm.len()],
            sent_q,
            sent_true_mm: true_mm,
            last_frame: 0,
            clamped: 0,
            sent_version: 0,
            sent_epoch: 0,
            tolerance_mm: tolerance_mm.max(0.0),
        }
    }

    /// How far a replica that applied every delta may be from the server's position of a vertex, mm.
    pub fn error_bound_mm(&self) -> f32 {
        self.tolerance_mm.max(self.bounds.max_error_mm())
    }

    /// Object name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Quantization bounds.
    pub fn bounds(&self) -> &QuantBounds {
        &self.bounds
    }

    /// Frame of the last delta sent.
    pub fn last_frame(&self) -> u64 {
        self.last_frame
    }

    /// True positions at the last delta sent, mm.
    pub fn sent_true_mm(&self) -> &[[f32; 3]] {
        &self.sent_true_mm
    }

    /// Positions that left the bounds and were clamped (should stay 0).
    pub fn clamped(&self) -> u64 {
        self.clamped
    }

    /// Fill `out` with the topology change since the last delta, if any (`topology`, the sim's; `None` keeps
    /// the world's mesh), then the vertices whose quantized position or burn level (`burn`, one per vertex; an
    /// empty slice changes nothing) changed, for publish `frame`. Returns false (and records nothing) when
    /// nothing changed. Reuses `out`'s buffers; allocates only when the topology changed.
    pub fn delta(
        &mut self,
        object: u16,
        positions_mm: &[Vec3],
        burn: &[u8],
        topology: Option<&ObjectTopology>,
        frame: u64,
        out: &mut MeshDelta,
    ) -> bool {
        out.indices.clear();
        out.positions_q.clear();
        out.burn_indices.clear();
        out.burn.clear();
        out.topology = topology
            .filter(|t| t.version != self.sent_version)
            .and_then(|t| self.follow_topology(t));
        for (i, (&level, sent)) in burn.iter().zip(self.sent_burn.iter_mut()).enumerate() {
            if level != *sent {
                *sent = level;
                out.burn_indices.push(i as u32);
                out.burn.push(level);
            }
        }
        let tolerance_sq = f64::from(self.tolerance_mm).powi(2);
        for (i, (p, sent)) in positions_mm.iter().zip(self.sent_q.iter_mut()).enumerate() {
            let (q, clamped) = self.bounds.quantize([p.x, p.y, p.z]);
            self.clamped += u64::from(clamped);
            if q != *sent && distance_sq_mm(self.bounds.dequantize(*sent), p) > tolerance_sq {
                *sent = q;
                out.indices.push(i as u32);
                out.positions_q.push(q);
            }
        }
        if out.indices.is_empty() && out.burn_indices.is_empty() && out.topology.is_none() {
            return false;
        }
        for (dst, p) in self.sent_true_mm.iter_mut().zip(positions_mm) {
            *dst = [p.x, p.y, p.z];
        }
        out.object = object;
        out.prev_frame = self.last_frame;
        out.frame = frame;
        self.last_frame = frame;
        true
    }

    /// Bring the sent state to `topology` (new vertices start as their parents were sent, as a replica starts
    /// them) and describe the change; `None` when the topology does not extend what was sent (it never
    /// shrinks or renumbers), which keeps the sent state.
    fn follow_topology(&mut self, topology: &ObjectTopology) -> Option<TopologyDelta> {
        let sent = self.sent_q.len();
        let first = topology.first_split as usize;
        let total = first + topology.parents.len();
        let old_triangles = self.triangles.len();
        if total < sent || sent < first || topology.triangles.len() < old_triangles {
            return None;
        }
        let parents = &topology.parents[sent - first..];
        for &p in parents {
            let p = p as usize;
            let (q, b, t) = (
                *self.sent_q.get(p)?,
                *self.sent_burn.get(p)?,
                *self.sent_true_mm.get(p)?,
            );
            self.sent_q.push(q);
            self.sent_burn.push(b);
            self.sent_true_mm.push(t);
        }
        let mut change = TopologyDelta {
            first_vertex: sent as u32,
            parents: parents.to_vec(),
            first_triangle: old_triangles as u32,
            added: topology.triangles[old_triangles..].to_vec(),
            ..TopologyDelta::default()
        };
        for (t, (sent, now)) in self
            .triangles
            .iter_mut()
            .zip(&topology.triangles)
            .enumerate()
        {
            if sent != now {
                *sent = *now;
                change.retargeted.push(t as u32);
                change.corners.push(*now);
            }
        }
        self.triangles.extend_from_slice(&change.added);
        self.sent_version = topology.version;
        self.sent_epoch += 1;
        change.epoch = self.sent_epoch;
        let too_big = [
            change.parents.len(),
            change.retargeted.len(),
            change.added.len(),
        ]
        .iter()
        .any(|&n| n > TopologyDelta::MAX_ITEMS);
        // Too big for one delta: the epoch is spent unsent, so every replica finds a gap (this delta names
        // vertices it lacks, the next change skips an epoch) and re-queries the snapshot, which carries it.
        (!too_big).then_some(change)
    }

    /// The object's full replicated state.
    pub fn snapshot(&self, object: u16) -> ObjectSnapshot {
        ObjectSnapshot {
            object,
            name: self.name.clone(),
            bounds: self.bounds,
            triangles: self.triangles.clone(),
            positions_q: self.sent_q.clone(),
            frame: self.last_frame,
            burn: if self.sent_burn.iter().all(|&b| b == 0) {
                Vec::new()
            } else {
                self.sent_burn.clone()
            },
            topology_epoch: self.sent_epoch,
            error_bound_mm: self.error_bound_mm(),
        }
    }
}

/// Squared distance between a replica's position and the server's, mm^2, in f64 (exact for f32 inputs'
/// differences, so the tolerance holds to the last bit).
fn distance_sq_mm(replica_mm: [f32; 3], p: &Vec3) -> f64 {
    (0..3)
        .map(|a| (f64::from(replica_mm[a]) - f64::from(p[a])).powi(2))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deltas_carry_only_changed_vertices_and_chain_frames() {
        let rest = vec![Vec3::zeros(), Vec3::x(), Vec3::y()];
        let mut rep = ObjectReplication::new("o", &rest, &[[0, 1, 2]], 10.0, 0.0);
        let mut out = MeshDelta::default();
        assert!(!rep.delta(0, &rest, &[], None, 1, &mut out));
        let mut moved = rest.clone();
        moved[1].z = 1.0;
        assert!(rep.delta(0, &moved, &[], None, 2, &mut out));
        assert_eq!(out.indices, vec![1]);
        assert_eq!((out.prev_frame, out.frame), (0, 2));
        moved[2].z = -1.0;
        assert!(rep.delta(0, &moved, &[], None, 5, &mut out));
        assert_eq!(out.indices, vec![2]);
        assert_eq!((out.prev_frame, out.frame), (2, 5));
        let snap = rep.snapshot(0);
        assert_eq!(snap.frame, 5);
        let back = rep.bounds().dequantize(snap.positions_q[1]);
        assert!((back[2] - 1.0).abs() <= rep.bounds().max_error_mm());
    }

    #[test]
    fn with_a_tolerance_a_vertex_is_resent_only_once_replicas_hold_it_further_than_that() {
        let rest = vec![Vec3::zeros(), Vec3::x(), Vec3::y()];
        let mut rep = ObjectReplication::new("o", &rest, &[[0, 1, 2]], 10.0, 0.01);
        assert_eq!(rep.error_bound_mm(), 0.01);
        assert_eq!(rep.snapshot(0).error_bound_mm, 0.01);
        let mut out = MeshDelta::default();
        let mut replica: Vec<[u16; 3]> = rep.snapshot(0).positions_q;
        let mut moved = rest.clone();
        let mut frame = 0;
        let mut worst: f32 = 0.0;
        let mut sent = 0;
        // Vertex 1 creeps 1 um a frame along z, vertex 2 jumps 0.5 mm once.
        for k in 1..=100 {
            moved[1].z = k as f32 * 0.001;
            if k == 50 {
                moved[2].x = 0.5;
            }
            frame += 1;
            if rep.delta(0, &moved, &[], None, frame, &mut out) {
                for (&i, q) in out.indices.iter().zip(&out.positions_q) {
                    replica[i as usize] = *q;
                    sent += 1;
                }
            }
            for (q, p) in replica.iter().zip(&moved) {
                let r = rep.bounds().dequantize(*q);
                let e = ((r[0] - p.x).powi(2) + (r[1] - p.y).powi(2) + (r[2] - p.z).powi(2)).sqrt();
                worst = worst.max(e);
            }
        }
        assert!(worst <= 0.01 + 1e-6, "replica error {worst} mm");
        // 100 um of creep in steps of 1 um: re-sent about every 10 um, not on each of its 2.5 um quanta.
        assert!((9..=12).contains(&sent), "{sent} vertex updates");
        // With no tolerance the same creep is sent on every quantum it crosses.
        let mut exact = ObjectReplication::new("o", &rest, &[[0, 1, 2]], 10.0, 0.0);
        let mut exact_sent = 0;
        let mut creep = rest.clone();
        for k in 1..=100 {
            creep[1].z = k as f32 * 0.001;
            if exact.delta(0, &creep, &[], None, k, &mut out) {
                exact_sent += out.indices.len();
            }
        }
        assert!(exact_sent >= 30, "{exact_sent}");
    }

    #[test]
    fn a_change_too_big_for_one_delta_spends_its_epoch_and_the_snapshot_carries_it() {
        let rest = vec![Vec3::zeros(), Vec3::x(), Vec3::y()];
        let mut rep = ObjectReplication::new("o", &rest, &[[0, 1, 2]], 10.0, 0.0);
        let mut out = MeshDelta::default();
        let small = ObjectTopology {
            version: 1,
            triangles: vec![[3, 1, 2]],
            first_split: 3,
            parents: vec![0],
        };
        let mut x = rest.clone();
        x.push(Vec3::zeros());
        assert!(rep.delta(0, &x, &[], Some(&small), 1, &mut out));
        let change = out.topology.clone().unwrap();
        assert_eq!((change.epoch, change.parents.len()), (1, 1));
        // A change of 65537 new vertices: no topology in the delta, the epoch spent, the snapshot complete.
        let n = TopologyDelta::MAX_ITEMS + 1;
        let big = ObjectTopology {
            version: 2,
            triangles: vec![[3, 1, 2]],
            first_split: 3,
            parents: std::iter::once(0)
                .chain(std::iter::repeat_n(1, n))
                .collect(),
        };
        x.resize(4 + n, Vec3::zeros());
        rep.delta(0, &x, &[], Some(&big), 2, &mut out);
        assert!(out.topology.is_none());
        let snap = rep.snapshot(0);
        assert_eq!(snap.topology_epoch, 2);
        assert_eq!(snap.positions_q.len(), 4 + n);
    }
}
