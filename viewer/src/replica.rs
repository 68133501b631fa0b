//! The viewer's copy of the scene, rebuilt from one snapshot and kept current by mesh deltas and tool states.
//!
//! Owns: the replicated objects (quantized positions exactly as the server quantized them, triangles, bounds,
//! per-object frame), the tool descriptions and the latest tool states, and the rules that decide whether a
//! delta applies, is stale, or reveals a gap. This file holds [`SceneReplica`] (snapshots, tool states, what
//! the replica holds); one object and its topology changes are in `object` ([`ReplicaObject`]), the delta
//! rules and their outcomes in `delta` ([`SceneReplica::apply_delta`], [`DeltaOutcome`], [`ReplicaError`]).
//!
//! Must not: touch zenoh, threads, clocks or rendering. It is plain data so the same rules are unit-tested
//! here and used unchanged by the network client and by the renderer. A refused update never changes state.

use sinew_protocol::{SceneSnapshot, ToolInfo, ToolStates};

mod delta;
mod object;

pub use delta::{DeltaOutcome, ReplicaError};
pub use object::ReplicaObject;

/// The viewer's replica of one scene.
///
/// Build it empty ([`SceneReplica::new`]) and feed it a snapshot, or from a snapshot directly. Equality compares
/// the replicated content (scene, frames, objects, tools), not the [`SceneReplica::revision`] counter.
#[derive(Debug, Clone, Default)]
pub struct SceneReplica {
    has_snapshot: bool,
    scene: String,
    snapshot_frame: u64,
    objects: Vec<ReplicaObject>,
    tools: Vec<ToolInfo>,
    tool_states: ToolStates,
    revision: u64,
    snapshot_revision: u64,
    topology_revision: u64,
}

impl PartialEq for SceneReplica {
    fn eq(&self, other: &Self) -> bool {
        self.has_snapshot == other.has_snapshot
            && self.scene == other.scene
            && self.snapshot_frame == other.snapshot_frame
            && self.objects == other.objects
            && self.tools == other.tools
            && self.tool_states == other.tool_states
    }
}

impl SceneReplica {
    /// An empty replica waiting for its first snapshot.
    pub fn new() -> Self {
        Self::default()
    }

    /// A replica holding `snapshot`.
    pub fn from_snapshot(snapshot: SceneSnapshot) -> Self {
        let mut replica = Self::new();
        replica.apply_snapshot(snapshot);
        replica
    }

    /// Replace the whole replicated state with `snapshot` (the snapshot is authoritative, even if older: a
    /// restarted server counts frames from zero again).
    pub fn apply_snapshot(&mut self, snapshot: SceneSnapshot) {
        self.has_snapshot = true;
        self.scene = snapshot.scene;
        self.snapshot_frame = snapshot.frame;
        self.objects = snapshot
            .objects
            .into_iter()
            .map(ReplicaObject::from_snapshot)
            .collect();
        self.tools = snapshot.tools;
        self.tool_states = snapshot.tool_states;
        self.revision += 1;
        self.snapshot_revision = self.revision;
        self.topology_revision = self.revision;
    }

    /// Take the latest tool states, unless they are older than the ones held. Returns whether they were taken.
    pub fn apply_tools(&mut self, tool_states: ToolStates) -> bool {
        if tool_states.frame < self.tool_states.frame {
            return false;
        }
        self.tool_states = tool_states;
        self.revision += 1;
        true
    }

    /// Whether a snapshot has been applied.
    pub fn has_snapshot(&self) -> bool {
        self.has_snapshot
    }

    /// Scene name from the snapshot (empty before one).
    pub fn scene(&self) -> &str {
        &self.scene
    }

    /// Frame of the snapshot this replica was last rebuilt from.
    pub fn snapshot_frame(&self) -> u64 {
        self.snapshot_frame
    }

    /// Newest publish frame folded into the replica: the latest of the snapshot, any object and the tools.
    pub fn frame(&self) -> u64 {
        self.objects
            .iter()
            .map(|o| o.frame)
            .chain([self.snapshot_frame, self.tool_states.frame])
            .max()
            .unwrap_or(0)
    }

    /// Counts every change applied (snapshots, deltas, tool states); a renderer redraws when it moves.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// The [`Self::revision`] at which the last snapshot was applied: when it moves, every position may have
    /// changed (object frames alone do not tell, since a restarted server counts frames from zero again).
    pub fn snapshot_revision(&self) -> u64 {
        self.snapshot_revision
    }

    /// The [`Self::revision`] at which some object's triangles or vertex count last changed (a snapshot, or a
    /// cut or tear): a renderer rebuilds its meshes when it moves.
    pub fn topology_revision(&self) -> u64 {
        self.topology_revision
    }

    /// The replicated objects, in index order.
    pub fn objects(&self) -> &[ReplicaObject] {
        &self.objects
    }

    /// One object by index.
    pub fn object(&self, object: u16) -> Option<&ReplicaObject> {
        self.objects.get(usize::from(object))
    }

    /// One object by name.
    pub fn object_by_name(&self, name: &str) -> Option<&ReplicaObject> {
        self.objects.iter().find(|o| o.name == name)
    }

    /// Dequantized positions of one object, mm (`None` for an unknown object).
    pub fn positions_mm(&self, object: u16) -> Option<Vec<[f32; 3]>> {
        self.object(object).map(ReplicaObject::positions_mm)
    }

    /// Quantized positions of one object (empty for an unknown object).
    pub fn quantized(&self, object: u16) -> &[[u16; 3]] {
        self.object(object).map_or(&[], ReplicaObject::quantized)
    }

    /// The replica's error bound for one object, mm (`None` for an unknown object).
    pub fn max_error_mm(&self, object: u16) -> Option<f32> {
        self.object(object).map(ReplicaObject::max_error_mm)
    }

    /// The largest error bound over all objects, mm (0 with no objects).
    pub fn max_error_mm_all(&self) -> f32 {
        self.objects
            .iter()
            .map(ReplicaObject::max_error_mm)
            .fold(0.0, f32::max)
    }

    /// Tool descriptions from the snapshot.
    pub fn tools(&self) -> &[ToolInfo] {
        &self.tools
    }

    /// The latest tool states.
    pub fn tool_states(&self) -> &ToolStates {
        &self.tool_states
    }

    /// The replicated state as a snapshot (for tests, and for relaying to another peer).
    pub fn to_snapshot(&self) -> SceneSnapshot {
        SceneSnapshot {
            scene: self.scene.clone(),
            frame: self.frame(),
            objects: self
                .objects
                .iter()
                .map(ReplicaObject::to_snapshot)
                .collect(),
            tools: self.tools.clone(),
            tool_states: self.tool_states.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_fixtures::{PROBE_ABOVE_MM, quantize_all, sheet_positions_mm, sheet_snapshot};

    #[test]
    fn older_tool_states_are_ignored() {
        let n = 3;
        let mut replica = SceneReplica::from_snapshot(sheet_snapshot(
            quantize_all(&sheet_positions_mm(n)),
            n,
            5,
            PROBE_ABOVE_MM,
        ));
        let mut newer = replica.tool_states().clone();
        newer.frame = 8;
        newer.tools[0].position_mm = [1.0, 2.0, 3.0];
        assert!(replica.apply_tools(newer.clone()));
        let mut older = newer.clone();
        older.frame = 7;
        older.tools[0].position_mm = [9.0, 9.0, 9.0];
        assert!(!replica.apply_tools(older));
        assert_eq!(replica.tool_states(), &newer);
        assert_eq!(replica.frame(), 8);
    }

    #[test]
    fn snapshot_replaces_state_even_when_older() {
        let n = 3;
        let positions = quantize_all(&sheet_positions_mm(n));
        let mut replica =
            SceneReplica::from_snapshot(sheet_snapshot(positions.clone(), n, 500, PROBE_ABOVE_MM));
        let restarted = sheet_snapshot(positions, n, 2, PROBE_ABOVE_MM);
        replica.apply_snapshot(restarted.clone());
        assert_eq!(replica, SceneReplica::from_snapshot(restarted.clone()));
        assert_eq!(replica.to_snapshot(), restarted);
    }
}
