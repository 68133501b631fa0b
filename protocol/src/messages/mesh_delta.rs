//! Mesh delta: server -> viewers.

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, Message, MessageKind};

/// The vertices of one object whose quantized position changed since the object's previous delta.
///
/// Direction: server -> viewers, on `sinew/<scene>/mesh/<object>/delta`. Rate: at most one per publish frame
/// (~60 Hz), none while the object is still. Reliability: reliable (a lost delta is a gap; the replica then
/// re-queries the snapshot).
/// Units: positions are `u16` quanta against the object's [`crate::quantize::QuantBounds`] sent in the
/// snapshot; one quantum is `(max_mm - min_mm) / 65535` per axis. The replica holds exactly the server's
/// quantized state, so its error is at most half a quantum per axis (plus f32 rounding: see `QuantBounds::max_error_mm`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct MeshDelta {
    /// Object index in the snapshot.
    pub object: u16,
    /// Publish frame this delta belongs to.
    pub frame: u64,
    /// Frame of this object's previous delta (or of the snapshot state it follows). A replica whose object is
    /// not at `prev_frame` has missed something and must re-query the snapshot.
    pub prev_frame: u64,
    /// Changed vertex indices, ascending.
    pub indices: Vec<u32>,
    /// New quantized positions, one per index.
    pub positions_q: Vec<[u16; 3]>,
    /// Vertices whose burn level changed, ascending. Protocol 6.
    pub burn_indices: Vec<u32>,
    /// New burn levels, one per burn index: 0 untouched .. 255 charred (a cautery tip raised them). Protocol 6.
    pub burn: Vec<u8>,
    /// The object's connectivity changed (a cut or a tear), applied before `indices` and `burn`. Protocol 7.
    pub topology: Option<TopologyDelta>,
}

/// A change of an object's connectivity: vertices split off, triangles re-pointed, surface triangles added.
///
/// Ids never change meaning: vertices and triangles are only appended, and a re-pointed triangle keeps its id
/// (an attachment or a suture anchor on it stays valid). A replica applies it in order: append the new
/// vertices, each starting at its parent's position and burn level; set the re-pointed triangles' corners;
/// append the new triangles; then the delta's positions and burn levels. Protocol 7.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct TopologyDelta {
    /// The object's topology epoch after this change: the snapshot's `topology_epoch` plus the changes folded
    /// in since. A replica at any other epoch than `epoch - 1` has missed one and re-queries the snapshot.
    pub epoch: u32,
    /// Id of the first new vertex: the replica's vertex count before this change.
    pub first_vertex: u32,
    /// Parent of each new vertex, in id order (vertex `first_vertex + k` split from `parents[k]`).
    pub parents: Vec<u32>,
    /// Triangles whose corners changed, ascending ids below `first_triangle`.
    pub retargeted: Vec<u32>,
    /// Their new corners, one per retargeted triangle.
    pub corners: Vec<[u32; 3]>,
    /// Id of the first new triangle: the replica's triangle count before this change.
    pub first_triangle: u32,
    /// Surface triangles appended (a volume's cut faces), counter-clockwise seen from outside.
    pub added: Vec<[u32; 3]>,
}

impl TopologyDelta {
    /// Most new vertices, re-pointed triangles or added triangles one change may carry: a larger change is
    /// refused (a replica re-queries the snapshot instead, which carries any size). A scalpel at the coupling's
    /// speed limit splits a few hundred vertices per publish frame at most.
    pub const MAX_ITEMS: usize = 1 << 16;

    /// The vertex count after this change.
    pub fn vertex_count(&self) -> u64 {
        u64::from(self.first_vertex) + self.parents.len() as u64
    }

    /// Checks that need no replica: counts agree, ids ascend, every parent and corner is a vertex that exists
    /// after the change, and every retargeted triangle existed before it.
    pub fn validate(&self) -> Result<(), FieldError> {
        if self.epoch == 0 {
            return Err(("topology.epoch", "0 is the epoch before any change"));
        }
        for (field, len) in [
            ("topology.parents", self.parents.len()),
            ("topology.retargeted", self.retargeted.len()),
            ("topology.added", self.added.len()),
        ] {
            if len > Self::MAX_ITEMS {
                return Err((
                    field,
                    "more than 65536 items in one change: re-query the snapshot",
                ));
            }
        }
        if self.retargeted.len() != self.corners.len() {
            return Err(("topology.corners", "length differs from retargeted"));
        }
        if self.retargeted.windows(2).any(|w| w[0] >= w[1]) {
            return Err(("topology.retargeted", "not strictly ascending"));
        }
        if self
            .retargeted
            .last()
            .is_some_and(|&t| t >= self.first_triangle)
        {
            return Err((
                "topology.retargeted",
                "names a triangle added by this change",
            ));
        }
        if self.parents.iter().any(|&p| p >= self.first_vertex) {
            return Err(("topology.parents", "a parent is not an existing vertex"));
        }
        let count = self.vertex_count();
        if self
            .corners
            .iter()
            .chain(&self.added)
            .flatten()
            .any(|&v| u64::from(v) >= count)
        {
            return Err(("topology.corners", "a corner is not a vertex"));
        }
        if u64::from(self.first_triangle) + self.added.len() as u64 > u64::from(u32::MAX) {
            return Err(("topology.added", "too many triangles"));
        }
        Ok(())
    }
}

impl Message for MeshDelta {
    const KIND: MessageKind = MessageKind::MeshDelta;
    fn validate(&self) -> Result<(), FieldError> {
        if self.indices.len() != self.positions_q.len() {
            return Err(("positions_q", "length differs from indices"));
        }
        if self.prev_frame >= self.frame {
            return Err(("prev_frame", "not before frame"));
        }
        if self.indices.windows(2).any(|w| w[0] >= w[1]) {
            return Err(("indices", "not strictly ascending"));
        }
        if self.burn_indices.len() != self.burn.len() {
            return Err(("burn", "length differs from burn_indices"));
        }
        if self.burn_indices.windows(2).any(|w| w[0] >= w[1]) {
            return Err(("burn_indices", "not strictly ascending"));
        }
        if let Some(topology) = &self.topology {
            topology.validate()?;
        }
        Ok(())
    }
}
