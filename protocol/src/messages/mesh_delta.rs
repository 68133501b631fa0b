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
        Ok(())
    }
}
