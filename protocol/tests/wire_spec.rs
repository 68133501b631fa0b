//! `protocol/WIRE.md` cannot drift from the codec: every golden byte vector in it (a fenced block whose info
//! string is `hex <name>`) must be exactly what this build encodes for the example value of that name, and
//! must decode back to it; every message kind has at least one. On a mismatch the test prints the block as
//! it should read.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use sinew_protocol::codec::{Message, encode_to_vec};
use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::*;

/// The sender in every golden vector.
const SENDER: InstanceId = InstanceId(0x0123_4567_89ab_cdef);

fn pose() -> DevicePose {
    DevicePose {
        seq: 1,
        device_time_ns: 1_000_000,
        position_mm: [1.0, 2.0, -3.5],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        linear_velocity_mm_s: [10.0, 0.0, 0.0],
        buttons: 1,
        jaw_angle_rad: 0.0,
        round_trip_us: 2000,
        render_mode: RenderMode::Moderated,
    }
}

fn force_direct() -> ForceCommand {
    ForceCommand {
        seq: 7,
        echo_pose_seq: 1,
        echo_device_time_ns: 1_000_000,
        force_n: [0.0, 0.0, 1.5],
        mode: ForceMode::Direct,
        in_contact: true,
        device_instance: 0x1122_3344_5566_7788,
        pose_wait_us: Some(150),
    }
}

fn force_local_model() -> ForceCommand {
    let mut planes = [ContactPlane::default(); MAX_CONTACT_PLANES];
    planes[0] = ContactPlane {
        normal: [0.0, 0.0, 1.0],
        offset_mm: 4.0,
        stiffness_n_per_mm: 0.5,
        damping_n_s_per_mm: 0.001,
    };
    ForceCommand {
        mode: ForceMode::LocalModel(LocalModel {
            server_time_ns: 2_000_000,
            in_contact: true,
            x0_mm: [0.0, 0.0, -2.0],
            f0_n: [0.0, 0.0, 1.5],
            stiffness_n_per_mm: [0.0, 0.0, 0.25, 0.0, 0.0, 0.0],
            damping_n_s_per_mm: [0.0, 0.0, 0.001, 0.0, 0.0, 0.0],
            radius_mm: 2.0,
            fade_mm: 0.5,
            planes,
            plane_count: 1,
            energy_allowance_mj: 0.0,
            attached: false,
            cut_drag_n: 0.0,
            friction_coefficient: 0.0,
            stick_stiffness_n_per_mm: 0.0,
            cut_facet_mm: 0.0,
            puncture: PunctureTerm::default(),
        }),
        ..force_direct()
    }
}

fn hello() -> ParticipantHello {
    ParticipantHello {
        participant_id: "left".into(),
        role: Role::Haptic,
        device_model: "Touch".into(),
        max_force_n: 3.3,
        tool: "left-probe".into(),
    }
}

fn delta() -> MeshDelta {
    MeshDelta {
        object: 0,
        frame: 12,
        prev_frame: 11,
        indices: vec![5, 300],
        positions_q: vec![[1, 2, 3], [65535, 0, 32768]],
        burn_indices: vec![5],
        burn: vec![200],
        topology: Some(TopologyDelta {
            epoch: 1,
            first_vertex: 301,
            parents: vec![5],
            retargeted: vec![2],
            corners: vec![[4, 301, 6]],
            first_triangle: 10,
            added: vec![[301, 6, 7]],
        }),
    }
}

fn tool_states() -> ToolStates {
    ToolStates {
        frame: 12,
        sim_time_s: 0.25,
        tools: vec![ToolState {
            tool: 0,
            position_mm: [-18.0, 0.0, -2.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            force_n: [0.0, 0.0, 1.5],
            active: true,
            in_contact: true,
            jaw_angle_rad: 0.5,
            attachments: 12,
        }],
        threads: vec![ThreadState {
            holes: vec![HoleMark {
                position_mm: [-16.0, 0.0, -3.0],
                pull_n: 0.5,
                on_needle: false,
            }],
            ..ThreadState::from_nodes_mm(0, &[[-18.0, 0.0, -2.0], [-16.0, 0.0, -2.5]])
        }],
        needles: vec![NeedleState {
            tool: 0,
            position_mm: [-18.0, 0.0, 3.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        }],
    }
}

fn snapshot() -> SceneSnapshot {
    SceneSnapshot {
        scene: "pad".into(),
        frame: 12,
        objects: vec![ObjectSnapshot {
            object: 0,
            name: "pad".into(),
            bounds: QuantBounds {
                min_mm: [-40.0, -30.0, -10.0],
                max_mm: [40.0, 30.0, 10.0],
            },
            triangles: vec![[0, 1, 2]],
            positions_q: vec![[0, 0, 32768], [65535, 0, 32768], [0, 65535, 32768]],
            frame: 12,
            burn: Vec::new(),
            topology_epoch: 0,
            error_bound_mm: 0.01,
        }],
        tools: vec![ToolInfo {
            tool: 0,
            name: "left-probe".into(),
            device_id: "left".into(),
            shape: ToolShape::Sphere { radius_mm: 4.0 },
            instrument: InstrumentInfo::Grasper {
                jaw_length_mm: 8.0,
                open_angle_rad: 0.5,
            },
            shaft: Some(ToolShaft {
                radius_mm: 2.5,
                length_mm: 40.0,
            }),
        }],
        tool_states: tool_states(),
    }
}

fn stats() -> ServerStats {
    ServerStats {
        sim_time_s: 1.0,
        ticks: 1000,
        tick_p50_us: 300.0,
        tick_p99_us: 450.0,
        tick_max_us: 900.0,
        devices: vec![DeviceStats {
            device_id: "left".into(),
            active: true,
            poses_received: 990,
            forces_sent: 990,
            last_round_trip_us: 2000,
            max_force_n: 1.5,
            tool: "left-probe".into(),
            holder_instance: 0x1122_3344_5566_7788,
            force_limit_n: 3.3,
            training: TrainingStats {
                skill_state: "contact".into(),
                contacts: 1,
                ..TrainingStats::default()
            },
            ..DeviceStats::default()
        }],
        server_id: "server".into(),
        exercise: Some(ExerciseStats {
            kind: "suture".into(),
            score: 50.0,
            hits: 1,
            total: 2,
            errors: 0,
            time_s: 12.5,
            completed: false,
            timed_out: false,
            targets: vec![
                TargetMark {
                    at_mm: [10.0, 0.0, 0.0],
                    radius_mm: 2.0,
                    hit: true,
                },
                TargetMark {
                    at_mm: [-10.0, 0.0, 0.0],
                    radius_mm: 2.0,
                    hit: false,
                },
            ],
        }),
        ..ServerStats::default()
    }
}

/// Whether bytes decode to the example (with [`SENDER`]).
type DecodesBack = Box<dyn Fn(&[u8]) -> bool>;

/// One golden vector: its name in WIRE.md, the bytes this build encodes, and a check that bytes decode back.
struct Golden {
    name: &'static str,
    kind: MessageKind,
    bytes: Vec<u8>,
    decodes_back: DecodesBack,
}

fn golden<M: Message + PartialEq + Clone + std::fmt::Debug + 'static>(
    name: &'static str,
    value: M,
) -> Golden {
    let bytes = encode_to_vec(SENDER, &value);
    Golden {
        name,
        kind: M::KIND,
        bytes,
        decodes_back: Box::new(move |b| decode_from::<M>(b) == Ok((SENDER, value.clone()))),
    }
}

fn goldens() -> Vec<Golden> {
    vec![
        golden("DevicePose", pose()),
        golden("ForceCommand-direct", force_direct()),
        golden("ForceCommand-local-model", force_local_model()),
        golden("ParticipantHello", hello()),
        golden("MeshDelta", delta()),
        golden("ToolStates", tool_states()),
        golden("SceneSnapshot", snapshot()),
        golden("ServerStats", stats()),
    ]
}

/// The bytes as WIRE.md shows them: lowercase hex pairs, 16 to a line.
fn hex_block(bytes: &[u8]) -> String {
    bytes
        .chunks(16)
        .map(|line| {
            line.iter()
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every ```` ```hex NAME ```` block of the document: (name, bytes).
fn doc_blocks(doc: &str) -> Vec<(String, Result<Vec<u8>, String>)> {
    let mut blocks = Vec::new();
    let mut lines = doc.lines();
    while let Some(line) = lines.next() {
        let Some(name) = line.trim().strip_prefix("```hex ") else {
            continue;
        };
        let mut text = String::new();
        for body in lines.by_ref() {
            if body.trim() == "```" {
                break;
            }
            text.push_str(body);
            text.push(' ');
        }
        let bytes = text
            .split_whitespace()
            .map(|pair| u8::from_str_radix(pair, 16).map_err(|e| format!("`{pair}`: {e}")))
            .collect();
        blocks.push((name.trim().to_owned(), bytes));
    }
    blocks
}

#[test]
fn every_golden_vector_in_wire_md_is_what_the_codec_writes_and_reads() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("WIRE.md");
    let doc = std::fs::read_to_string(&path).unwrap();
    let blocks = doc_blocks(&doc);
    let mut problems = Vec::new();
    for g in goldens() {
        let expected = format!("```hex {}\n{}\n```", g.name, hex_block(&g.bytes));
        match blocks.iter().find(|(name, _)| name == g.name) {
            None => problems.push(format!(
                "WIRE.md has no golden vector `{}`; it should read:\n{expected}",
                g.name
            )),
            Some((_, Err(e))) => problems.push(format!("`{}`: not hex ({e})", g.name)),
            Some((_, Ok(bytes))) if *bytes != g.bytes => problems.push(format!(
                "`{}` differs from the codec; it should read:\n{expected}",
                g.name
            )),
            Some((_, Ok(bytes))) => {
                if !(g.decodes_back)(bytes) {
                    problems.push(format!("`{}` does not decode to its example", g.name));
                }
                assert_eq!(bytes[2], g.kind as u8, "{}: kind byte", g.name);
            }
        }
    }
    for (name, _) in &blocks {
        if !goldens().iter().any(|g| g.name == name) {
            problems.push(format!(
                "WIRE.md has a vector `{name}` this test does not know"
            ));
        }
    }
    // Every kind has a vector.
    for kind in [
        MessageKind::DevicePose,
        MessageKind::ForceCommand,
        MessageKind::SceneSnapshot,
        MessageKind::MeshDelta,
        MessageKind::ToolStates,
        MessageKind::ServerStats,
        MessageKind::ParticipantHello,
    ] {
        assert!(
            goldens().iter().any(|g| g.kind == kind),
            "{} has no golden vector",
            kind.name()
        );
    }
    assert!(problems.is_empty(), "{}", problems.join("\n\n"));
}
