//! Mesh replication state: quantization bounds, what each object last sent, and delta/snapshot building.
//!
//! Owns: the server side of the replica contract (see [`sinew_protocol::MeshDelta`]): a vertex is sent when
//! its quantized position differs from the last one sent, so a replica that applied every delta holds
//! exactly the server's quantized state. Pure data; must not touch zenoh.

use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::{MeshDelta, ObjectSnapshot};

use crate::tissue::Vec3;

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
}

impl ObjectReplication {
    /// Start from rest positions: bounds are their box grown by `margin_mm`; nothing sent yet (frame 0).
    pub fn new(
        name: &str,
        rest_positions_mm: &[Vec3],
        triangles: &[[u32; 3]],
        margin_mm: f32,
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
        }
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

    /// Fill `out` with the vertices whose quantized position or burn level (`burn`, one per vertex; an empty
    /// slice changes nothing) changed, for publish `frame`. Returns false (and records nothing) when nothing
    /// changed. Reuses `out`'s buffers.
    pub fn delta(
        &mut self,
        object: u16,
        positions_mm: &[Vec3],
        burn: &[u8],
        frame: u64,
        out: &mut MeshDelta,
    ) -> bool {
        out.indices.clear();
        out.positions_q.clear();
        out.burn_indices.clear();
        out.burn.clear();
        for (i, (&level, sent)) in burn.iter().zip(self.sent_burn.iter_mut()).enumerate() {
            if level != *sent {
                *sent = level;
                out.burn_indices.push(i as u32);
                out.burn.push(level);
            }
        }
        for (i, (p, sent)) in positions_mm.iter().zip(self.sent_q.iter_mut()).enumerate() {
            let (q, clamped) = self.bounds.quantize([p.x, p.y, p.z]);
            self.clamped += u64::from(clamped);
            if q != *sent {
                *sent = q;
                out.indices.push(i as u32);
                out.positions_q.push(q);
            }
        }
        if out.indices.is_empty() && out.burn_indices.is_empty() {
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deltas_carry_only_changed_vertices_and_chain_frames() {
        let rest = vec![Vec3::zeros(), Vec3::x(), Vec3::y()];
        let mut rep = ObjectReplication::new("o", &rest, &[[0, 1, 2]], 10.0);
        let mut out = MeshDelta::default();
        assert!(!rep.delta(0, &rest, &[], 1, &mut out));
        let mut moved = rest.clone();
        moved[1].z = 1.0;
        assert!(rep.delta(0, &moved, &[], 2, &mut out));
        assert_eq!(out.indices, vec![1]);
        assert_eq!((out.prev_frame, out.frame), (0, 2));
        moved[2].z = -1.0;
        assert!(rep.delta(0, &moved, &[], 5, &mut out));
        assert_eq!(out.indices, vec![2]);
        assert_eq!((out.prev_frame, out.frame), (2, 5));
        let snap = rep.snapshot(0);
        assert_eq!(snap.frame, 5);
        let back = rep.bounds().dequantize(snap.positions_q[1]);
        assert!((back[2] - 1.0).abs() <= rep.bounds().max_error_mm());
    }
}
