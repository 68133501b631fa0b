//! One replicated deformable object: its quantized positions, triangles, burn levels and frame, and the
//! topology changes (cuts, tears) folded into it.
//!
//! Owns: [`ReplicaObject`] and its conversion from and to the wire's object snapshot, and the check and the
//! application of a topology change (its epoch follows, its ids start where the object ends, every id it
//! names exists; new vertices start at their parents).
//!
//! Must not: decide whether a delta applies (that is `delta`, which calls the topology check before any
//! write), or touch zenoh, threads, clocks or rendering.

use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::{ObjectSnapshot, TopologyDelta};

use super::ReplicaError;

/// One replicated deformable object.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplicaObject {
    index: u16,
    pub(super) name: String,
    bounds: QuantBounds,
    triangles: Vec<[u32; 3]>,
    pub(super) positions_q: Vec<[u16; 3]>,
    pub(super) frame: u64,
    /// Burn level per vertex, 0-255 (all zero until a cautery tip touches).
    pub(super) burn: Vec<u8>,
    /// Topology changes folded in (0: the world's mesh).
    topology_epoch: u32,
    /// The server's bound on this replica's error, mm (its delta tolerance, or the quantization's bound).
    error_bound_mm: f32,
}

impl ReplicaObject {
    pub(super) fn from_snapshot(object: ObjectSnapshot) -> Self {
        let burn = if object.burn.len() == object.positions_q.len() {
            object.burn
        } else {
            vec![0; object.positions_q.len()]
        };
        Self {
            index: object.object,
            name: object.name,
            bounds: object.bounds,
            triangles: object.triangles,
            positions_q: object.positions_q,
            frame: object.frame,
            burn,
            topology_epoch: object.topology_epoch,
            error_bound_mm: object.error_bound_mm,
        }
    }

    /// Burn level of each vertex, 0 (untouched) to 255 (charred).
    pub fn burn(&self) -> &[u8] {
        &self.burn
    }

    pub(super) fn to_snapshot(&self) -> ObjectSnapshot {
        ObjectSnapshot {
            object: self.index,
            name: self.name.clone(),
            bounds: self.bounds,
            triangles: self.triangles.clone(),
            positions_q: self.positions_q.clone(),
            frame: self.frame,
            burn: if self.burn.iter().all(|&b| b == 0) {
                Vec::new()
            } else {
                self.burn.clone()
            },
            topology_epoch: self.topology_epoch,
            error_bound_mm: self.error_bound_mm,
        }
    }

    /// Topology changes (cuts, tears) folded in; 0 for the world's mesh.
    pub fn topology_epoch(&self) -> u32 {
        self.topology_epoch
    }

    /// Check a topology change against this object: its epoch follows, its ids start where the object ends,
    /// and every id it names exists. Changes nothing.
    pub(super) fn check_topology(&self, change: &TopologyDelta) -> Result<(), ReplicaError> {
        let object = self.index;
        if change.epoch != self.topology_epoch.wrapping_add(1) {
            return Err(ReplicaError::TopologyGap {
                object,
                have_epoch: self.topology_epoch,
                epoch: change.epoch,
            });
        }
        let bad = |reason: String| Err(ReplicaError::BadTopology { object, reason });
        let (vertices, triangles) = (self.positions_q.len(), self.triangles.len());
        if change.first_vertex as usize != vertices {
            return bad(format!(
                "first new vertex {} but the object has {vertices}",
                change.first_vertex
            ));
        }
        if change.first_triangle as usize != triangles {
            return bad(format!(
                "first new triangle {} but the object has {triangles}",
                change.first_triangle
            ));
        }
        if let Some(p) = change.parents.iter().find(|&&p| p as usize >= vertices) {
            return bad(format!("parent {p} is not a vertex"));
        }
        if let Some(t) = change.retargeted.iter().find(|&&t| t as usize >= triangles) {
            return bad(format!("retargeted triangle {t} does not exist"));
        }
        if change.retargeted.len() != change.corners.len() {
            return bad("retargeted and corners differ in length".to_owned());
        }
        let count = vertices + change.parents.len();
        if let Some(v) = change
            .corners
            .iter()
            .chain(&change.added)
            .flatten()
            .find(|&&v| v as usize >= count)
        {
            return bad(format!("corner {v} is not a vertex"));
        }
        Ok(())
    }

    /// Apply a checked topology change: new vertices start at their parents' positions and burn levels.
    pub(super) fn apply_topology(&mut self, change: &TopologyDelta) {
        self.positions_q.reserve(change.parents.len());
        for &p in &change.parents {
            let (q, b) = (self.positions_q[p as usize], self.burn[p as usize]);
            self.positions_q.push(q);
            self.burn.push(b);
        }
        for (&t, &corners) in change.retargeted.iter().zip(&change.corners) {
            self.triangles[t as usize] = corners;
        }
        self.triangles.extend_from_slice(&change.added);
        self.topology_epoch = change.epoch;
    }

    /// Object index (as used by [`MeshDelta::object`](sinew_protocol::MeshDelta::object)).
    pub fn index(&self) -> u16 {
        self.index
    }

    /// Object name from the world file.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Quantization bounds, mm.
    pub fn bounds(&self) -> &QuantBounds {
        &self.bounds
    }

    /// Surface triangles (vertex indices, counter-clockwise seen from outside).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Frame of the last delta folded into this object.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions_q.len()
    }

    /// Quantized positions, exactly as the server quantized them.
    pub fn quantized(&self) -> &[[u16; 3]] {
        &self.positions_q
    }

    /// Dequantized positions, mm, without allocating.
    pub fn positions_mm_iter(&self) -> impl ExactSizeIterator<Item = [f32; 3]> + '_ {
        self.positions_q.iter().map(|q| self.bounds.dequantize(*q))
    }

    /// Dequantized positions, mm.
    pub fn positions_mm(&self) -> Vec<[f32; 3]> {
        self.positions_mm_iter().collect()
    }

    /// Bound on the distance between a replica position and the server's position, mm: the server's delta
    /// tolerance (it re-sends a vertex once the replica holds it further than that), or the quantization's
    /// bound (half a quantum per axis plus f32 rounding, along a cell's diagonal) when larger.
    pub fn max_error_mm(&self) -> f32 {
        self.bounds.max_error_mm().max(self.error_bound_mm)
    }
}

#[cfg(test)]
mod tests {
    use sinew_protocol::MeshDelta;

    use super::*;
    use crate::replica::{DeltaOutcome, SceneReplica};
    use crate::test_fixtures::{PROBE_ABOVE_MM, quantize_all, sheet_positions_mm, sheet_snapshot};

    #[test]
    fn a_cut_appends_vertices_at_their_parents_and_retargets_triangles_and_a_bad_one_changes_nothing()
     {
        let n = 3;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica =
            SceneReplica::from_snapshot(sheet_snapshot(start.clone(), n, 10, PROBE_ABOVE_MM));
        let triangles = replica.object(0).unwrap().triangles().to_vec();
        let cut = TopologyDelta {
            epoch: 1,
            first_vertex: start.len() as u32,
            parents: vec![4],
            retargeted: vec![1],
            corners: vec![triangles[1].map(|v| if v == 4 { start.len() as u32 } else { v })],
            first_triangle: triangles.len() as u32,
            added: Vec::new(),
        };
        let mut delta = MeshDelta {
            object: 0,
            frame: 11,
            prev_frame: 10,
            indices: vec![start.len() as u32],
            positions_q: vec![[7, 8, 9]],
            topology: Some(cut.clone()),
            ..MeshDelta::default()
        };
        // Wrong epoch, a first vertex that is not the end, a corner past the new end: refused, nothing changes.
        let before = replica.clone();
        for bad in [
            TopologyDelta {
                epoch: 2,
                ..cut.clone()
            },
            TopologyDelta {
                first_vertex: 3,
                ..cut.clone()
            },
            TopologyDelta {
                corners: vec![[0, 1, 99]],
                ..cut.clone()
            },
        ] {
            delta.topology = Some(bad);
            assert!(replica.apply_delta(&delta).is_err());
            assert_eq!(replica, before);
        }
        delta.topology = Some(cut);
        let topology_before = replica.topology_revision();
        assert_eq!(replica.apply_delta(&delta), Ok(DeltaOutcome::Applied));
        let object = replica.object(0).unwrap();
        assert_eq!(object.vertex_count(), start.len() + 1);
        assert_eq!(object.quantized()[start.len()], [7, 8, 9]);
        assert_eq!(object.topology_epoch(), 1);
        assert!(object.triangles()[1].contains(&(start.len() as u32)));
        assert!(replica.topology_revision() > topology_before);
        // A snapshot of the replica carries the epoch, and a replica rebuilt from it equals this one.
        let again = SceneReplica::from_snapshot(replica.to_snapshot());
        assert_eq!(again.object(0), replica.object(0));
    }
}
