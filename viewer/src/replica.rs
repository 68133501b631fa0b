//! The viewer's copy of the scene, rebuilt from one snapshot and kept current by mesh deltas and tool states.
//!
//! Owns: the replicated objects (quantized positions exactly as the server quantized them, triangles, bounds,
//! per-object frame), the tool descriptions and the latest tool states, and the rules that decide whether a
//! delta applies, is stale, or reveals a gap.
//!
//! Must not: touch zenoh, threads, clocks or rendering. It is plain data so the same rules are unit-tested
//! here and used unchanged by the network client and by the renderer. A refused update never changes state.

use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::{
    MeshDelta, ObjectSnapshot, SceneSnapshot, ToolInfo, ToolStates, TopologyDelta,
};
use thiserror::Error;

/// What [`SceneReplica::apply_delta`] did with a delta it accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeltaOutcome {
    /// The delta followed the object's frame; its positions are now in the replica.
    Applied,
    /// The delta's frame is already folded into the object (e.g. it predates the snapshot); ignored.
    Stale,
}

/// Why a delta was refused. Every variant means "re-query the snapshot"; none changes the replica.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ReplicaError {
    /// The delta does not follow the object's frame: something was missed.
    #[error(
        "gap on object {object}: replica at frame {have_frame}, delta {frame} follows frame {prev_frame}"
    )]
    Gap {
        /// Object index.
        object: u16,
        /// The replica object's frame.
        have_frame: u64,
        /// The frame the delta follows.
        prev_frame: u64,
        /// The delta's frame.
        frame: u64,
    },
    /// The delta names an object the replica does not have (or no snapshot was applied yet).
    #[error("delta for object {object}, but the replica has {objects} objects")]
    UnknownObject {
        /// Object index in the delta.
        object: u16,
        /// Objects in the replica.
        objects: usize,
    },
    /// A vertex index past the end of the object's vertices (a protocol error).
    #[error(
        "delta for object {object} names vertex {index}, but the object has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Object index.
        object: u16,
        /// Offending vertex index.
        index: u32,
        /// Vertices in the replica object.
        vertex_count: usize,
    },
    /// A topology change that does not follow the object's topology epoch: one was missed.
    #[error(
        "topology gap on object {object}: replica at epoch {have_epoch}, change to epoch {epoch}"
    )]
    TopologyGap {
        /// Object index.
        object: u16,
        /// The replica object's epoch.
        have_epoch: u32,
        /// The change's epoch.
        epoch: u32,
    },
    /// A topology change that does not fit the object (a protocol error).
    #[error("topology change for object {object}: {reason}")]
    BadTopology {
        /// Object index.
        object: u16,
        /// What does not fit.
        reason: String,
    },
    /// Indices and positions differ in length (a protocol error; decoding refuses this too).
    #[error("delta for object {object} has {indices} indices but {positions} positions")]
    LengthMismatch {
        /// Object index.
        object: u16,
        /// Number of indices.
        indices: usize,
        /// Number of positions.
        positions: usize,
    },
}

impl ReplicaError {
    /// True for a protocol error (the delta itself is wrong), false for a gap (something was missed).
    pub fn is_protocol_error(&self) -> bool {
        !matches!(
            self,
            ReplicaError::Gap { .. } | ReplicaError::TopologyGap { .. }
        )
    }
}

/// One replicated deformable object.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplicaObject {
    index: u16,
    name: String,
    bounds: QuantBounds,
    triangles: Vec<[u32; 3]>,
    positions_q: Vec<[u16; 3]>,
    frame: u64,
    /// Burn level per vertex, 0-255 (all zero until a cautery tip touches).
    burn: Vec<u8>,
    /// Topology changes folded in (0: the world's mesh).
    topology_epoch: u32,
    /// The server's bound on this replica's error, mm (its delta tolerance, or the quantization's bound).
    error_bound_mm: f32,
}

impl ReplicaObject {
    fn from_snapshot(object: ObjectSnapshot) -> Self {
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

    fn to_snapshot(&self) -> ObjectSnapshot {
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
    fn check_topology(&self, change: &TopologyDelta) -> Result<(), ReplicaError> {
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
    fn apply_topology(&mut self, change: &TopologyDelta) {
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

    /// Object index (as used by [`MeshDelta::object`]).
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

    /// Fold one delta into its object.
    ///
    /// Applies iff `delta.prev_frame` equals the object's frame; a delta whose frame is not after the object's
    /// is [`DeltaOutcome::Stale`]; anything else is a [`ReplicaError::Gap`]. Indices are checked before any
    /// position is written, so a refused delta changes nothing. Never panics, whatever the delta holds.
    pub fn apply_delta(&mut self, delta: &MeshDelta) -> Result<DeltaOutcome, ReplicaError> {
        let objects = self.objects.len();
        let object =
            self.objects
                .get_mut(usize::from(delta.object))
                .ok_or(ReplicaError::UnknownObject {
                    object: delta.object,
                    objects,
                })?;
        if delta.frame <= object.frame {
            return Ok(DeltaOutcome::Stale);
        }
        if delta.prev_frame != object.frame {
            return Err(ReplicaError::Gap {
                object: delta.object,
                have_frame: object.frame,
                prev_frame: delta.prev_frame,
                frame: delta.frame,
            });
        }
        if delta.indices.len() != delta.positions_q.len() {
            return Err(ReplicaError::LengthMismatch {
                object: delta.object,
                indices: delta.indices.len(),
                positions: delta.positions_q.len(),
            });
        }
        if delta.burn_indices.len() != delta.burn.len() {
            return Err(ReplicaError::LengthMismatch {
                object: delta.object,
                indices: delta.burn_indices.len(),
                positions: delta.burn.len(),
            });
        }
        if let Some(change) = &delta.topology {
            object.check_topology(change)?;
        }
        let vertex_count =
            object.positions_q.len() + delta.topology.as_ref().map_or(0, |t| t.parents.len());
        if let Some(&index) = delta
            .indices
            .iter()
            .chain(&delta.burn_indices)
            .find(|&&i| !usize::try_from(i).is_ok_and(|i| i < vertex_count))
        {
            return Err(ReplicaError::IndexOutOfRange {
                object: delta.object,
                index,
                vertex_count,
            });
        }
        if let Some(change) = &delta.topology {
            object.apply_topology(change);
            self.topology_revision = self.revision + 1;
        }
        for (&index, &position_q) in delta.indices.iter().zip(&delta.positions_q) {
            // In range: checked above.
            if let Some(slot) = object.positions_q.get_mut(index as usize) {
                *slot = position_q;
            }
        }
        for (&index, &level) in delta.burn_indices.iter().zip(&delta.burn) {
            if let Some(slot) = object.burn.get_mut(index as usize) {
                *slot = level;
            }
        }
        object.frame = delta.frame;
        self.revision += 1;
        Ok(DeltaOutcome::Applied)
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
    use sinew_protocol::{ToolShape, ToolState};

    const BOUNDS: QuantBounds = QuantBounds {
        min_mm: [-50.0, -40.0, -20.0],
        max_mm: [50.0, 40.0, 20.0],
    };

    /// An `n` x `n` grid sheet, 80 x 60 mm, at z = 0.
    fn sheet_positions_mm(n: usize) -> Vec<[f32; 3]> {
        let mut positions = Vec::with_capacity(n * n);
        for j in 0..n {
            for i in 0..n {
                let x = -40.0 + 80.0 * i as f32 / (n - 1) as f32;
                let y = -30.0 + 60.0 * j as f32 / (n - 1) as f32;
                positions.push([x, y, 0.0]);
            }
        }
        positions
    }

    fn sheet_triangles(n: usize) -> Vec<[u32; 3]> {
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                let b = a + 1;
                let c = a + n as u32;
                let d = c + 1;
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
        }
        triangles
    }

    fn quantize_all(positions_mm: &[[f32; 3]]) -> Vec<[u16; 3]> {
        positions_mm.iter().map(|p| BOUNDS.quantize(*p).0).collect()
    }

    fn snapshot(positions_q: Vec<[u16; 3]>, n: usize, frame: u64) -> SceneSnapshot {
        SceneSnapshot {
            scene: "pad".to_owned(),
            frame,
            objects: vec![ObjectSnapshot {
                object: 0,
                name: "pad".to_owned(),
                bounds: BOUNDS,
                triangles: sheet_triangles(n),
                positions_q,
                frame,
                burn: Vec::new(),
                topology_epoch: 0,
                error_bound_mm: 0.0,
            }],
            tools: vec![ToolInfo {
                tool: 0,
                name: "probe".to_owned(),
                device_id: "left".to_owned(),
                shape: ToolShape::Sphere { radius_mm: 3.0 },
                instrument: sinew_protocol::InstrumentInfo::Probe,
                shaft: None,
            }],
            tool_states: ToolStates {
                frame,
                sim_time_s: 0.0,
                tools: vec![ToolState {
                    tool: 0,
                    position_mm: [0.0, 0.0, 10.0],
                    orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                    ..ToolState::default()
                }],
            },
        }
    }

    /// The vertices whose quantized position differs between `before` and `after`, as a delta.
    fn diff_delta(
        before: &[[u16; 3]],
        after: &[[u16; 3]],
        prev_frame: u64,
        frame: u64,
    ) -> MeshDelta {
        let mut delta = MeshDelta {
            object: 0,
            frame,
            prev_frame,
            ..MeshDelta::default()
        };
        for (i, (b, a)) in before.iter().zip(after).enumerate() {
            if b != a {
                delta.indices.push(i as u32);
                delta.positions_q.push(*a);
            }
        }
        delta
    }

    #[test]
    fn snapshot_then_deltas_in_order_equals_the_expected_state() {
        let n = 5;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(snapshot(start.clone(), n, 10));
        assert!(replica.has_snapshot());
        assert_eq!(replica.frame(), 10);

        let mut expected = start.clone();
        expected[12] = [100, 200, 300];
        let first = diff_delta(&start, &expected, 10, 11);
        assert_eq!(replica.apply_delta(&first), Ok(DeltaOutcome::Applied));

        let mut next = expected.clone();
        next[0] = [1, 2, 3];
        next[24] = [65535, 65535, 65535];
        let second = diff_delta(&expected, &next, 11, 13);
        assert_eq!(replica.apply_delta(&second), Ok(DeltaOutcome::Applied));

        assert_eq!(replica.quantized(0), next.as_slice());
        assert_eq!(replica.object(0).map(ReplicaObject::frame), Some(13));
        assert_eq!(replica.frame(), 13);
        let mm = replica.positions_mm(0).unwrap();
        assert_eq!(mm[24], BOUNDS.max_mm);
        assert_eq!(replica.max_error_mm(0), Some(BOUNDS.max_error_mm()));
        assert!(replica.max_error_mm(0).unwrap() < 0.002);
    }

    #[test]
    fn stale_delta_is_ignored() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(snapshot(start.clone(), n, 20));
        let before = replica.clone();
        let revision = replica.revision();
        let mut moved = start.clone();
        moved[3] = [9, 9, 9];
        // Already folded into the snapshot: frame <= the object's frame.
        for (prev, frame) in [(19, 20), (15, 18), (0, 1)] {
            let delta = diff_delta(&start, &moved, prev, frame);
            assert_eq!(replica.apply_delta(&delta), Ok(DeltaOutcome::Stale));
        }
        assert_eq!(replica, before);
        assert_eq!(replica.revision(), revision);
    }

    #[test]
    fn gap_is_detected_and_state_unchanged() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(snapshot(start.clone(), n, 20));
        let before = replica.clone();
        let mut moved = start.clone();
        moved[3] = [9, 9, 9];
        let delta = diff_delta(&start, &moved, 21, 22);
        assert_eq!(
            replica.apply_delta(&delta),
            Err(ReplicaError::Gap {
                object: 0,
                have_frame: 20,
                prev_frame: 21,
                frame: 22
            })
        );
        assert_eq!(replica, before);
    }

    #[test]
    fn burn_levels_apply_travel_in_the_snapshot_and_bad_ones_change_nothing() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(snapshot(start, n, 20));
        assert!(replica.objects()[0].burn().iter().all(|&b| b == 0));
        let burnt = MeshDelta {
            object: 0,
            frame: 21,
            prev_frame: 20,
            burn_indices: vec![3, 7],
            burn: vec![40, 255],
            ..MeshDelta::default()
        };
        assert_eq!(replica.apply_delta(&burnt), Ok(DeltaOutcome::Applied));
        assert_eq!(replica.objects()[0].burn()[3], 40);
        assert_eq!(replica.objects()[0].burn()[7], 255);
        // A late joiner's snapshot carries them.
        let again = SceneReplica::from_snapshot(replica.to_snapshot());
        assert_eq!(again.objects()[0].burn(), replica.objects()[0].burn());
        // A burn index past the vertices, or a count that does not match, changes nothing.
        let before = replica.clone();
        for bad in [
            MeshDelta {
                frame: 22,
                prev_frame: 21,
                indices: vec![1],
                positions_q: vec![[9, 9, 9]],
                burn_indices: vec![2, 16],
                burn: vec![1, 2],
                ..MeshDelta::default()
            },
            MeshDelta {
                frame: 22,
                prev_frame: 21,
                burn_indices: vec![2],
                burn: vec![1, 2],
                ..MeshDelta::default()
            },
        ] {
            let err = replica.apply_delta(&bad).unwrap_err();
            assert!(err.is_protocol_error(), "{err}");
            assert_eq!(replica, before);
        }
    }

    #[test]
    fn out_of_range_index_is_refused_with_state_unchanged() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(snapshot(start, n, 20));
        let before = replica.clone();
        // Index 2 is valid and comes first: it must not be written either.
        let delta = MeshDelta {
            object: 0,
            frame: 21,
            prev_frame: 20,
            indices: vec![2, 16],
            positions_q: vec![[1, 1, 1], [2, 2, 2]],
            ..MeshDelta::default()
        };
        let err = replica.apply_delta(&delta).unwrap_err();
        assert_eq!(
            err,
            ReplicaError::IndexOutOfRange {
                object: 0,
                index: 16,
                vertex_count: 16
            }
        );
        assert!(err.is_protocol_error());
        assert_eq!(replica, before);

        let huge = MeshDelta {
            indices: vec![u32::MAX],
            positions_q: vec![[0, 0, 0]],
            ..delta.clone()
        };
        assert!(replica.apply_delta(&huge).is_err());
        let mismatched = MeshDelta {
            indices: vec![1, 2],
            positions_q: vec![[0, 0, 0]],
            ..delta
        };
        assert!(matches!(
            replica.apply_delta(&mismatched),
            Err(ReplicaError::LengthMismatch { .. })
        ));
        assert_eq!(replica, before);
    }

    #[test]
    fn delta_before_any_snapshot_is_unknown_object() {
        let mut replica = SceneReplica::new();
        let delta = MeshDelta {
            object: 0,
            frame: 2,
            prev_frame: 1,
            ..MeshDelta::default()
        };
        assert_eq!(
            replica.apply_delta(&delta),
            Err(ReplicaError::UnknownObject {
                object: 0,
                objects: 0
            })
        );
        assert!(!replica.has_snapshot());
        assert_eq!(replica.max_error_mm_all(), 0.0);
    }

    #[test]
    fn older_tool_states_are_ignored() {
        let n = 3;
        let mut replica =
            SceneReplica::from_snapshot(snapshot(quantize_all(&sheet_positions_mm(n)), n, 5));
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
        let mut replica = SceneReplica::from_snapshot(snapshot(positions.clone(), n, 500));
        let restarted = snapshot(positions, n, 2);
        replica.apply_snapshot(restarted.clone());
        assert_eq!(replica, SceneReplica::from_snapshot(restarted.clone()));
        assert_eq!(replica.to_snapshot(), restarted);
    }

    /// Random walk of a mesh on a "server" side, quantized and diffed into deltas like the server does; one
    /// delta is dropped: the replica must report a gap, keep its state, and equal the server after a resnapshot.
    #[test]
    fn random_walk_with_a_dropped_delta_is_detected_and_resnapshot_converges() {
        let mut rng = fastrand::Rng::with_seed(0x5eed);
        let n = 12;
        let mut server_mm = sheet_positions_mm(n);
        let mut server_q = quantize_all(&server_mm);
        let mut server_frame = 100u64;
        let mut last_delta_frame = server_frame;
        let mut replica = SceneReplica::from_snapshot(snapshot(server_q.clone(), n, server_frame));
        let drop_at = 37;
        let mut gap_seen = false;

        for step in 0..80 {
            server_frame += 1;
            // Move a few vertices (sometimes none) by up to 0.2 mm per axis.
            for _ in 0..rng.usize(0..10) {
                let v = rng.usize(0..server_mm.len());
                for coordinate in &mut server_mm[v] {
                    *coordinate += (rng.f32() - 0.5) * 0.4;
                }
            }
            let now_q = quantize_all(&server_mm);
            let delta = diff_delta(&server_q, &now_q, last_delta_frame, server_frame);
            server_q = now_q;
            if delta.indices.is_empty() {
                continue; // The server sends nothing while the object is still.
            }
            last_delta_frame = server_frame;
            if step == drop_at {
                continue; // Lost on the way.
            }
            let before = replica.clone();
            match replica.apply_delta(&delta) {
                Ok(DeltaOutcome::Applied) => assert!(!gap_seen, "applied after a gap"),
                Ok(DeltaOutcome::Stale) => panic!("no delta here is stale"),
                Err(ReplicaError::Gap { .. }) => {
                    gap_seen = true;
                    assert_eq!(replica, before, "a gap changed the replica");
                }
                Err(other) => panic!("unexpected {other}"),
            }
            if !gap_seen {
                assert_eq!(replica.quantized(0), server_q.as_slice());
            }
        }
        assert!(gap_seen, "the dropped delta was not detected");
        assert_ne!(replica.quantized(0), server_q.as_slice());

        let mut resnapshot = snapshot(server_q.clone(), n, server_frame);
        resnapshot.objects[0].frame = last_delta_frame;
        replica.apply_snapshot(resnapshot);
        assert_eq!(replica.quantized(0), server_q.as_slice());
        for (replica_mm, truth_mm) in replica
            .object(0)
            .unwrap()
            .positions_mm_iter()
            .zip(&server_mm)
        {
            let err: f32 = (0..3)
                .map(|a| (replica_mm[a] - truth_mm[a]).powi(2))
                .sum::<f32>()
                .sqrt();
            assert!(
                err <= BOUNDS.max_error_mm() * 1.001 + 1e-5,
                "error {err} mm"
            );
        }
    }

    #[test]
    fn a_cut_appends_vertices_at_their_parents_and_retargets_triangles_and_a_bad_one_changes_nothing()
     {
        let n = 3;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(snapshot(start.clone(), n, 10));
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
