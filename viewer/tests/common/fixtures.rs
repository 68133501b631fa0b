//! Snapshot and delta builders shared by every viewer test: a grid sheet like the pad with one probe, a
//! one-triangle scene, and the deltas between two quantized states.
//!
//! One file, compiled twice: into the integration tests through `tests/common/mod.rs`, and into the crate's
//! own unit tests as `crate::test_fixtures` (`src/lib.rs` includes it with `#[path]`, under `cfg(test)`).
//!
//! Must not: use the viewer crate (it is built inside it and outside it, so it names protocol types only),
//! assert anything, or hold state.

#![allow(dead_code)]

use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::{
    MeshDelta, ObjectSnapshot, SceneSnapshot, ToolInfo, ToolShape, ToolState, ToolStates,
};

/// Quantization bounds of the sheet: the pad plus margin, mm.
pub const SHEET_BOUNDS: QuantBounds = QuantBounds {
    min_mm: [-50.0, -40.0, -30.0],
    max_mm: [50.0, 40.0, 30.0],
};

/// The probe 10 mm above the sheet's centre, mm.
pub const PROBE_ABOVE_MM: [f32; 3] = [0.0, 0.0, 10.0];

/// An `n` x `n` grid of vertices spanning 80 x 60 mm around the origin at z = 0, row-major in y.
pub fn sheet_positions_mm(n: usize) -> Vec<[f32; 3]> {
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

/// Two counter-clockwise (seen from +z) triangles per grid cell.
pub fn sheet_triangles(n: usize) -> Vec<[u32; 3]> {
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

/// Quantize positions against [`SHEET_BOUNDS`].
pub fn quantize_all(positions_mm: &[[f32; 3]]) -> Vec<[u16; 3]> {
    positions_mm
        .iter()
        .map(|p| SHEET_BOUNDS.quantize(*p).0)
        .collect()
}

/// Object 0, `pad`, quantized against [`SHEET_BOUNDS`], last changed at `frame`: no burns, the world's
/// topology, no delta tolerance.
pub fn pad_object(
    triangles: Vec<[u32; 3]>,
    positions_q: Vec<[u16; 3]>,
    frame: u64,
) -> ObjectSnapshot {
    ObjectSnapshot {
        object: 0,
        name: "pad".to_owned(),
        bounds: SHEET_BOUNDS,
        triangles,
        positions_q,
        frame,
        burn: Vec::new(),
        topology_epoch: 0,
        error_bound_mm: 0.0,
    }
}

/// A one-object, one-tool scene at `frame`: the sheet with `positions_q`, and a 4 mm probe at `tool_mm`.
pub fn sheet_snapshot(
    positions_q: Vec<[u16; 3]>,
    n: usize,
    frame: u64,
    tool_mm: [f32; 3],
) -> SceneSnapshot {
    SceneSnapshot {
        scene: "pad".to_owned(),
        frame,
        objects: vec![pad_object(sheet_triangles(n), positions_q, frame)],
        tools: vec![ToolInfo {
            tool: 0,
            name: "probe".to_owned(),
            device_id: "left".to_owned(),
            shape: ToolShape::Sphere { radius_mm: 4.0 },
            instrument: sinew_protocol::InstrumentInfo::Probe,
            shaft: None,
        }],
        tool_states: ToolStates {
            frame,
            sim_time_s: 0.0,
            tools: vec![ToolState {
                tool: 0,
                position_mm: tool_mm,
                orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                force_n: [0.0; 3],
                active: true,
                in_contact: false,
                ..ToolState::default()
            }],
            threads: Vec::new(),
            needles: Vec::new(),
        },
    }
}

/// The smallest scene: one triangle whose three vertices all sit at quantized `[0; 3]`, no tools; the scene
/// at `frame`, the object last changed at `object_frame`.
pub fn triangle_snapshot(frame: u64, object_frame: u64) -> SceneSnapshot {
    SceneSnapshot {
        scene: "pad".to_owned(),
        frame,
        objects: vec![pad_object(vec![[0, 1, 2]], vec![[0; 3]; 3], object_frame)],
        tools: Vec::new(),
        tool_states: ToolStates::default(),
    }
}

/// The vertices whose quantized position differs between `before` and `after`, as a delta for object 0.
pub fn diff_delta(
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

/// A delta for object 0 that moves one vertex, `index`, to quantized `[value; 3]`.
pub fn vertex_delta(prev_frame: u64, frame: u64, index: u32, value: u16) -> MeshDelta {
    MeshDelta {
        object: 0,
        frame,
        prev_frame,
        indices: vec![index],
        positions_q: vec![[value; 3]],
        ..MeshDelta::default()
    }
}
