//! The browser feed: a replica (and the server's stats) encoded as the messages the instructor's page reads
//! from its WebSocket, built once per feed tick and shared by every page.
//!
//! Owns: the feed's message layout (below; the STATE message is built in `web_feed/state.rs`; `viewer/web/static/feed.js` is its only reader), [`FeedBuilder`],
//! which turns a replica into a [`FeedFrame`] and re-encodes only what changed, and [`FeedCursor`], one page's
//! place in the feed (what it was sent), which picks the messages a page still lacks.
//!
//! Must not: touch sockets, zenoh or clocks. The page only reads: nothing in this file decodes anything a page
//! sends.
//!
//! # Messages (binary WebSocket frames, little-endian)
//! Every message starts with a 4-byte header: `kind: u8`, `flags: u8`, `object: u16`.
//! - `1` SCENE, JSON after the header: `{"scene", "layout", "objects": [{"index", "name", "vertexCount",
//!   "triangleCount", "topologyEpoch"}], "tools": [{"tool", "name", "deviceId", "instrument"}]}`. Sent first,
//!   and again whenever an object's triangles or vertex count change (a cut, a tear, a new snapshot): the page
//!   then drops its meshes and waits for MESH messages.
//! - `2` MESH, one object's triangles: `topology_epoch: u32`, `vertex_count: u32`, `triangle_count: u32`, then
//!   `triangle_count * 3` vertex indices (`u32`).
//! - `3` POSITIONS, one object's vertices: `vertex_count: u32`, `min_mm: [f32; 3]`, `quantum_mm: [f32; 3]`,
//!   then `vertex_count * 3` quantized coordinates (`u16`, position = min + q * quantum, exactly the server's
//!   quantization), then, if `flags & 1`, `vertex_count` burn levels (`u8`, 0 untouched to 255 charred).
//! - `5` POSITIONS_DELTA, the vertices of one object that changed since the previous frame, sent instead of
//!   POSITIONS to a page that holds that frame's: `vertex_count: u32` (the object's, to check), `changed: u32`,
//!   `min_mm: [f32; 3]`, `quantum_mm: [f32; 3]`, `changed` vertex indices (`u32`), then their quantized
//!   coordinates (`changed * 3` `u16`), then, if `flags & 1`, their burn levels (`changed` `u8`).
//! - `4` STATE, JSON after the header: the tools as world-frame parts ([`crate::tool_parts`]), the suture
//!   threads as polylines, each tool's force and its device's limit, and the instructor's overlay (text lines,
//!   force arrows, target rings) as [`crate::InstructorOverlay`] builds it for the native viewer.

use std::sync::Arc;

use bytes::Bytes;
use serde::Serialize;
use sinew_protocol::{InstrumentInfo, ServerStats};

mod state;
use state::state_message;

use crate::replica::{ReplicaObject, SceneReplica};

/// SCENE message kind.
pub const KIND_SCENE: u8 = 1;
/// MESH message kind.
pub const KIND_MESH: u8 = 2;
/// POSITIONS message kind.
pub const KIND_POSITIONS: u8 = 3;
/// STATE message kind.
pub const KIND_STATE: u8 = 4;
/// POSITIONS_DELTA message kind.
pub const KIND_POSITIONS_DELTA: u8 = 5;
/// POSITIONS flag: burn levels follow the coordinates.
pub const FLAG_BURN: u8 = 1;

/// What identifies one object's positions as sent: the replica's snapshot, the object's frame and topology.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PositionsKey {
    snapshot_revision: u64,
    frame: u64,
    topology_epoch: u32,
    vertex_count: usize,
}

impl PositionsKey {
    fn of(replica: &SceneReplica, object: &ReplicaObject) -> Self {
        Self {
            snapshot_revision: replica.snapshot_revision(),
            frame: object.frame(),
            topology_epoch: object.topology_epoch(),
            vertex_count: object.vertex_count(),
        }
    }
}

/// One object's encoded positions, with the key they were encoded for.
#[derive(Debug, Clone)]
struct EncodedPositions {
    key: PositionsKey,
    message: Bytes,
    /// The same positions as a change from the previous frame's (the key a page must hold to take it).
    delta: Option<(PositionsKey, Bytes)>,
}

/// Everything a page needs at one feed tick, encoded once and shared by every page.
#[derive(Debug, Clone)]
pub struct FeedFrame {
    /// Counts frames built (from 1).
    pub seq: u64,
    /// Changes whenever a mesh's triangles or vertex count change: a page resends SCENE and every MESH.
    pub layout: u64,
    scene: Bytes,
    meshes: Vec<Bytes>,
    positions: Vec<EncodedPositions>,
    state: Bytes,
    /// Vertices over all objects (for the gateway's log line).
    pub vertices: usize,
}

impl FeedFrame {
    /// The SCENE message.
    pub fn scene_message(&self) -> &Bytes {
        &self.scene
    }

    /// The STATE message.
    pub fn state_message(&self) -> &Bytes {
        &self.state
    }
}

/// Builds feed frames from a replica, re-encoding only what changed since the last one.
#[derive(Debug, Default)]
pub struct FeedBuilder {
    seq: u64,
    last: Option<Arc<FeedFrame>>,
    topology_revision: Option<u64>,
    /// Per object, the quantized positions and burn levels last encoded (what a page at the last frame has).
    encoded_q: Vec<Vec<[u16; 3]>>,
    encoded_burn: Vec<Vec<u8>>,
}

impl FeedBuilder {
    /// A builder that has built nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// The frame for the replica now, or None if there is no snapshot yet or nothing changed since the last
    /// frame.
    pub fn build(
        &mut self,
        replica: &SceneReplica,
        stats: Option<&ServerStats>,
    ) -> Option<Arc<FeedFrame>> {
        if !replica.has_snapshot() {
            return None;
        }
        let layout_changed = self.topology_revision != Some(replica.topology_revision());
        let previous = self.last.as_deref().filter(|_| !layout_changed);
        let (layout, scene, meshes) = match previous {
            Some(p) => (p.layout, p.scene.clone(), p.meshes.clone()),
            None => {
                let layout = self.last.as_ref().map_or(1, |p| p.layout + 1);
                (
                    layout,
                    scene_message(replica, layout),
                    replica.objects().iter().map(mesh_message).collect(),
                )
            }
        };
        if previous.is_none() {
            self.encoded_q = vec![Vec::new(); replica.objects().len()];
            self.encoded_burn = vec![Vec::new(); replica.objects().len()];
        }
        let mut positions_changed = false;
        let positions: Vec<EncodedPositions> = replica
            .objects()
            .iter()
            .enumerate()
            .map(|(i, object)| {
                let key = PositionsKey::of(replica, object);
                let old = previous.and_then(|p| p.positions.get(i));
                if let Some(old) = old
                    && old.key == key
                {
                    return old.clone();
                }
                positions_changed = true;
                let delta = old.zip(self.encoded_q.get(i)).and_then(|(old, q)| {
                    let burn = self.encoded_burn.get(i).map_or(&[][..], Vec::as_slice);
                    positions_delta_message(object, q, burn).map(|m| (old.key, m))
                });
                if let Some(q) = self.encoded_q.get_mut(i) {
                    q.clear();
                    q.extend_from_slice(object.quantized());
                }
                if let Some(b) = self.encoded_burn.get_mut(i) {
                    b.clear();
                    b.extend_from_slice(object.burn());
                }
                EncodedPositions {
                    key,
                    message: positions_message(object),
                    delta,
                }
            })
            .collect();
        let state = state_message(replica, stats);
        if let Some(p) = previous
            && !positions_changed
            && p.state == state
        {
            return None;
        }
        self.seq += 1;
        self.topology_revision = Some(replica.topology_revision());
        let frame = Arc::new(FeedFrame {
            seq: self.seq,
            layout,
            scene,
            meshes,
            positions,
            state,
            vertices: replica.objects().iter().map(|o| o.vertex_count()).sum(),
        });
        self.last = Some(Arc::clone(&frame));
        Some(frame)
    }
}

/// One page's place in the feed: the layout, positions and state it was last sent.
#[derive(Debug, Default)]
pub struct FeedCursor {
    layout: Option<u64>,
    positions: Vec<Option<PositionsKey>>,
    state_seq: Option<u64>,
}

impl FeedCursor {
    /// A page that has been sent nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// The messages this page lacks to be at `frame`, in the order to send them; the cursor then counts them
    /// as sent.
    pub fn messages_for(&mut self, frame: &FeedFrame) -> Vec<Bytes> {
        let mut out = Vec::new();
        if self.layout != Some(frame.layout) {
            out.push(frame.scene.clone());
            out.extend(frame.meshes.iter().cloned());
            self.layout = Some(frame.layout);
            self.positions = vec![None; frame.positions.len()];
        }
        for (sent, positions) in self.positions.iter_mut().zip(&frame.positions) {
            if *sent == Some(positions.key) {
                continue;
            }
            // The change from the previous frame if this page holds it, else everything.
            match &positions.delta {
                Some((from, delta)) if *sent == Some(*from) => out.push(delta.clone()),
                _ => out.push(positions.message.clone()),
            }
            *sent = Some(positions.key);
        }
        if self.state_seq != Some(frame.seq) {
            out.push(frame.state.clone());
            self.state_seq = Some(frame.seq);
        }
        out
    }
}

fn header(kind: u8, flags: u8, object: u16, capacity: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(4 + capacity);
    out.push(kind);
    out.push(flags);
    out.extend_from_slice(&object.to_le_bytes());
    out
}

fn json_message(kind: u8, value: &impl Serialize) -> Bytes {
    let mut out = header(kind, 0, 0, 256);
    // Serialising plain structs of numbers and strings into a Vec cannot fail; an empty body would be read
    // by the page as a bad message and skipped.
    if serde_json::to_writer(&mut out, value).is_err() {
        out.truncate(4);
    }
    Bytes::from(out)
}

fn len_u32(n: usize) -> [u8; 4] {
    u32::try_from(n).unwrap_or(u32::MAX).to_le_bytes()
}

/// The SCENE message: names and sizes of the objects, and the tools.
fn scene_message(replica: &SceneReplica, layout: u64) -> Bytes {
    #[derive(Serialize)]
    #[serde(rename_all = "camelCase")]
    struct Object<'a> {
        index: u16,
        name: &'a str,
        vertex_count: usize,
        triangle_count: usize,
        topology_epoch: u32,
    }
    #[derive(Serialize)]
    #[serde(rename_all = "camelCase")]
    struct Tool<'a> {
        tool: u16,
        name: &'a str,
        device_id: &'a str,
        instrument: &'static str,
    }
    #[derive(Serialize)]
    struct Scene<'a> {
        scene: &'a str,
        layout: u64,
        objects: Vec<Object<'a>>,
        tools: Vec<Tool<'a>>,
    }
    json_message(
        KIND_SCENE,
        &Scene {
            scene: replica.scene(),
            layout,
            objects: replica
                .objects()
                .iter()
                .map(|o| Object {
                    index: o.index(),
                    name: o.name(),
                    vertex_count: o.vertex_count(),
                    triangle_count: o.triangles().len(),
                    topology_epoch: o.topology_epoch(),
                })
                .collect(),
            tools: replica
                .tools()
                .iter()
                .map(|t| Tool {
                    tool: t.tool,
                    name: &t.name,
                    device_id: &t.device_id,
                    instrument: instrument_name(&t.instrument),
                })
                .collect(),
        },
    )
}

fn instrument_name(instrument: &InstrumentInfo) -> &'static str {
    match instrument {
        InstrumentInfo::Probe => "probe",
        InstrumentInfo::Grasper { .. } => "grasper",
        InstrumentInfo::Cautery => "cautery",
        InstrumentInfo::Scalpel { .. } => "scalpel",
        InstrumentInfo::Scissors { .. } => "scissors",
        InstrumentInfo::NeedleDriver { .. } => "needle driver",
    }
}

/// The MESH message of one object.
fn mesh_message(object: &ReplicaObject) -> Bytes {
    let triangles = object.triangles();
    let mut out = header(KIND_MESH, 0, object.index(), 12 + triangles.len() * 12);
    out.extend_from_slice(&object.topology_epoch().to_le_bytes());
    out.extend_from_slice(&len_u32(object.vertex_count()));
    out.extend_from_slice(&len_u32(triangles.len()));
    for t in triangles {
        for v in t {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    Bytes::from(out)
}

/// The POSITIONS message of one object.
fn positions_message(object: &ReplicaObject) -> Bytes {
    let quantized = object.quantized();
    let burn = object.burn();
    let burnt = burn.len() == quantized.len() && burn.iter().any(|&b| b > 0);
    let mut out = header(
        KIND_POSITIONS,
        if burnt { FLAG_BURN } else { 0 },
        object.index(),
        28 + quantized.len() * 7,
    );
    out.extend_from_slice(&len_u32(quantized.len()));
    let bounds = object.bounds();
    for value in bounds.min_mm.iter().chain(&bounds.quantum_mm()) {
        out.extend_from_slice(&value.to_le_bytes());
    }
    for q in quantized {
        for c in q {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    if burnt {
        out.extend_from_slice(burn);
    }
    Bytes::from(out)
}

/// The POSITIONS_DELTA message of one object against what was last encoded (`q`, `burn`): the vertices whose
/// quantized position or burn level changed. None when the vertex counts differ (a page then takes the whole
/// POSITIONS), or when the change is no smaller than the whole.
fn positions_delta_message(object: &ReplicaObject, q: &[[u16; 3]], burn: &[u8]) -> Option<Bytes> {
    let now_q = object.quantized();
    let now_burn = object.burn();
    if q.len() != now_q.len() {
        return None;
    }
    let burn_of = |b: &[u8], i: usize| b.get(i).copied().unwrap_or(0);
    let changed: Vec<u32> = (0..now_q.len())
        .filter(|&i| now_q[i] != q[i] || burn_of(now_burn, i) != burn_of(burn, i))
        .filter_map(|i| u32::try_from(i).ok())
        .collect();
    let burnt = now_burn.iter().any(|&b| b > 0);
    let per_vertex = if burnt { 11 } else { 10 };
    if changed.len() * per_vertex >= now_q.len() * if burnt { 7 } else { 6 } {
        return None;
    }
    let mut out = header(
        KIND_POSITIONS_DELTA,
        if burnt { FLAG_BURN } else { 0 },
        object.index(),
        32 + changed.len() * per_vertex,
    );
    out.extend_from_slice(&len_u32(now_q.len()));
    out.extend_from_slice(&len_u32(changed.len()));
    let bounds = object.bounds();
    for value in bounds.min_mm.iter().chain(&bounds.quantum_mm()) {
        out.extend_from_slice(&value.to_le_bytes());
    }
    for i in &changed {
        out.extend_from_slice(&i.to_le_bytes());
    }
    for &i in &changed {
        for c in now_q[i as usize] {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    if burnt {
        out.extend(changed.iter().map(|&i| burn_of(now_burn, i as usize)));
    }
    Some(Bytes::from(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_fixtures::{
        PROBE_ABOVE_MM, diff_delta, quantize_all, sheet_positions_mm, sheet_snapshot,
    };

    fn replica() -> SceneReplica {
        let n = 4;
        SceneReplica::from_snapshot(sheet_snapshot(
            quantize_all(&sheet_positions_mm(n)),
            n,
            5,
            PROBE_ABOVE_MM,
        ))
    }

    fn kinds(messages: &[Bytes]) -> Vec<u8> {
        messages.iter().map(|m| m[0]).collect()
    }

    #[test]
    fn a_new_page_gets_the_scene_its_meshes_positions_and_state_then_only_what_changed() {
        let mut replica = replica();
        let mut builder = FeedBuilder::new();
        let first = builder.build(&replica, None).unwrap();
        let mut page = FeedCursor::new();
        let messages = page.messages_for(&first);
        assert_eq!(
            kinds(&messages),
            [KIND_SCENE, KIND_MESH, KIND_POSITIONS, KIND_STATE]
        );
        // MESH: header, epoch, vertex and triangle counts, then the triangles.
        let object = &replica.objects()[0];
        let mesh = &messages[1];
        assert_eq!(
            u32::from_le_bytes(mesh[8..12].try_into().unwrap()) as usize,
            16
        );
        assert_eq!(mesh.len(), 16 + object.triangles().len() * 12);
        // POSITIONS: the server's own quantized values, and min + q * quantum is the replica's position.
        let positions = &messages[2];
        let q0 = u16::from_le_bytes(positions[32..34].try_into().unwrap());
        let min_x = f32::from_le_bytes(positions[8..12].try_into().unwrap());
        let quantum_x = f32::from_le_bytes(positions[20..24].try_into().unwrap());
        assert_eq!(q0, object.quantized()[0][0]);
        assert!((min_x + f32::from(q0) * quantum_x - object.positions_mm()[0][0]).abs() < 1e-3);
        assert_eq!(positions.len(), 32 + 16 * 6);
        // Nothing changed: no frame; a page already there is sent nothing more.
        assert!(builder.build(&replica, None).is_none());
        assert!(page.messages_for(&first).is_empty());
        // The tool moves: only the state.
        let mut states = replica.tool_states().clone();
        states.frame += 1;
        states.tools[0].position_mm[2] -= 1.0;
        replica.apply_tools(states);
        let second = builder.build(&replica, None).unwrap();
        assert_eq!(second.layout, first.layout);
        assert_eq!(kinds(&page.messages_for(&second)), [KIND_STATE]);
        // A page opened late catches up in one go.
        assert_eq!(
            kinds(&FeedCursor::new().messages_for(&second)),
            [KIND_SCENE, KIND_MESH, KIND_POSITIONS, KIND_STATE]
        );
    }

    #[test]
    fn a_page_at_the_previous_frame_gets_only_the_vertices_that_moved_and_a_page_behind_gets_them_all()
     {
        let mut replica = replica();
        let mut builder = FeedBuilder::new();
        let (mut current, mut behind) = (FeedCursor::new(), FeedCursor::new());
        let first = builder.build(&replica, None).unwrap();
        current.messages_for(&first);
        behind.messages_for(&first);
        let step = |replica: &mut SceneReplica, vertex: usize, q: [u16; 3]| {
            let before = replica.objects()[0].quantized().to_vec();
            let mut after = before.clone();
            after[vertex] = q;
            let frame = replica.objects()[0].frame();
            replica
                .apply_delta(&diff_delta(&before, &after, frame, frame + 1))
                .unwrap();
        };
        step(&mut replica, 5, [1, 2, 3]);
        let second = builder.build(&replica, None).unwrap();
        let messages = current.messages_for(&second);
        assert_eq!(kinds(&messages), [KIND_POSITIONS_DELTA, KIND_STATE]);
        // One vertex: header, counts, bounds, its index, its three coordinates.
        let delta = &messages[0];
        assert_eq!(delta.len(), 4 + 8 + 24 + 4 + 6);
        assert_eq!(u32::from_le_bytes(delta[36..40].try_into().unwrap()), 5);
        assert_eq!(u16::from_le_bytes(delta[40..42].try_into().unwrap()), 1);
        step(&mut replica, 6, [4, 5, 6]);
        let third = builder.build(&replica, None).unwrap();
        assert_eq!(
            kinds(&current.messages_for(&third)),
            [KIND_POSITIONS_DELTA, KIND_STATE]
        );
        // A page that skipped the second frame cannot take the third's change: it gets every position.
        assert_eq!(
            kinds(&behind.messages_for(&third)),
            [KIND_POSITIONS, KIND_STATE]
        );
    }

    #[test]
    fn a_new_snapshot_resends_the_layout() {
        let mut replica = replica();
        let mut builder = FeedBuilder::new();
        let mut page = FeedCursor::new();
        let first = builder.build(&replica, None).unwrap();
        page.messages_for(&first);
        replica.apply_snapshot(replica.to_snapshot());
        let second = builder.build(&replica, None).unwrap();
        assert_ne!(second.layout, first.layout);
        assert_eq!(
            kinds(&page.messages_for(&second)),
            [KIND_SCENE, KIND_MESH, KIND_POSITIONS, KIND_STATE]
        );
    }

    #[test]
    fn the_state_names_the_tools_and_carries_the_overlay() {
        let replica = replica();
        let frame = FeedBuilder::new().build(&replica, None).unwrap();
        let state: serde_json::Value = serde_json::from_slice(&frame.state_message()[4..]).unwrap();
        assert_eq!(
            state["tools"].as_array().unwrap().len(),
            replica.tools().len()
        );
        assert!(!state["tools"][0]["parts"].as_array().unwrap().is_empty());
        assert!(
            state["lines"][0]["text"]
                .as_str()
                .unwrap()
                .contains("no server stats yet")
        );
        let scene: serde_json::Value = serde_json::from_slice(&frame.scene_message()[4..]).unwrap();
        assert_eq!(scene["objects"][0]["vertexCount"], 16);
    }
}
