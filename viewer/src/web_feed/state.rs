//! The feed's STATE message: the tools as world-frame parts, the threads, each tool's force and its device's
//! limit, and the instructor's overlay, as JSON (the layout is in the parent module's doc).
//!
//! Owns: [`state_message`] and the JSON shapes it writes. Must not: keep state between frames.

use bytes::Bytes;
use serde::Serialize;
use sinew_protocol::ServerStats;

use super::{KIND_STATE, json_message};
use crate::instructor_overlay::{InstructorOverlay, Rgb};
use crate::replica::SceneReplica;
use crate::tool_parts::{ToolPart, tool_parts};

/// One tool part as the page draws it.
#[derive(Serialize)]
#[serde(tag = "kind", rename_all = "camelCase")]
enum PartJson<'a> {
    Sphere {
        c: [f32; 3],
        r: f32,
        rgb: Rgb,
    },
    Capsule {
        a: [f32; 3],
        b: [f32; 3],
        r: f32,
        rgb: Rgb,
    },
    Mesh {
        positions: &'a [[f32; 3]],
        triangles: &'a [[u32; 3]],
        rgb: Rgb,
    },
}

impl<'a> From<&'a ToolPart> for PartJson<'a> {
    fn from(part: &'a ToolPart) -> Self {
        match part {
            ToolPart::Sphere {
                centre_mm,
                radius_mm,
                rgb,
            } => Self::Sphere {
                c: *centre_mm,
                r: *radius_mm,
                rgb: *rgb,
            },
            ToolPart::Capsule {
                from_mm,
                to_mm,
                radius_mm,
                rgb,
            } => Self::Capsule {
                a: *from_mm,
                b: *to_mm,
                r: *radius_mm,
                rgb: *rgb,
            },
            ToolPart::Mesh {
                positions_mm,
                triangles,
                rgb,
            } => Self::Mesh {
                positions: positions_mm,
                triangles,
                rgb: *rgb,
            },
        }
    }
}

/// The STATE message: tools, threads, forces and the overlay.
pub(super) fn state_message(replica: &SceneReplica, stats: Option<&ServerStats>) -> Bytes {
    #[derive(Serialize)]
    #[serde(rename_all = "camelCase")]
    struct Tool<'a> {
        tool: u16,
        device_id: &'a str,
        active: bool,
        in_contact: bool,
        force_n: f32,
        /// The device's force limit, N (0: not known yet).
        limit_n: f32,
        parts: Vec<PartJson<'a>>,
    }
    #[derive(Serialize)]
    struct Line<'a> {
        text: &'a str,
        rgb: Rgb,
    }
    #[derive(Serialize)]
    #[serde(rename_all = "camelCase")]
    struct Arrow {
        tool: u16,
        from: [f32; 3],
        to: [f32; 3],
        force_n: f32,
        rgb: Rgb,
    }
    #[derive(Serialize)]
    #[serde(rename_all = "camelCase")]
    struct Ring {
        centre: [f32; 3],
        radius_mm: f32,
        rgb: Rgb,
    }
    #[derive(Serialize)]
    #[serde(rename_all = "camelCase")]
    struct State<'a> {
        frame: u64,
        sim_time_s: f64,
        tools: Vec<Tool<'a>>,
        threads: Vec<Vec<[f32; 3]>>,
        lines: Vec<Line<'a>>,
        arrows: Vec<Arrow>,
        targets: Vec<Ring>,
    }
    let overlay = InstructorOverlay::build(replica, stats);
    let states = replica.tool_states();
    let parts: Vec<(u16, Vec<ToolPart>)> = replica
        .tools()
        .iter()
        .filter_map(|info| {
            let state = states.tools.iter().find(|s| s.tool == info.tool)?;
            Some((info.tool, tool_parts(info, state, &states.needles)))
        })
        .collect();
    let tools = replica
        .tools()
        .iter()
        .filter_map(|info| {
            let state = states.tools.iter().find(|s| s.tool == info.tool)?;
            let limit_n = stats
                .and_then(|s| s.devices.iter().find(|d| d.device_id == info.device_id))
                .map_or(0.0, |d| d.force_limit_n);
            let force_n = state.force_n.iter().map(|c| c * c).sum::<f32>().sqrt();
            Some(Tool {
                tool: info.tool,
                device_id: &info.device_id,
                active: state.active,
                in_contact: state.in_contact,
                force_n: if force_n.is_finite() { force_n } else { 0.0 },
                limit_n,
                parts: parts
                    .iter()
                    .find(|(tool, _)| *tool == info.tool)
                    .map(|(_, p)| p.iter().map(PartJson::from).collect())
                    .unwrap_or_default(),
            })
        })
        .collect();
    let threads = states
        .threads
        .iter()
        .map(|t| t.nodes_q.iter().map(|q| t.bounds.dequantize(*q)).collect())
        .collect();
    json_message(
        KIND_STATE,
        &State {
            frame: states.frame,
            sim_time_s: states.sim_time_s,
            tools,
            threads,
            lines: overlay
                .lines
                .iter()
                .map(|l| Line {
                    text: &l.text,
                    rgb: l.rgb,
                })
                .collect(),
            arrows: overlay
                .arrows
                .iter()
                .map(|a| Arrow {
                    tool: a.tool,
                    from: a.from_mm,
                    to: a.to_mm,
                    force_n: a.force_n,
                    rgb: a.rgb,
                })
                .collect(),
            targets: overlay
                .targets
                .iter()
                .map(|t| Ring {
                    centre: t.centre_mm,
                    radius_mm: t.radius_mm,
                    rgb: t.rgb,
                })
                .collect(),
        },
    )
}
