//! Every wire message: random round trips, and malformed input (truncated, wrong version, wrong kind,
//! garbage, out-of-domain fields) refused with a typed error and never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use sinew_protocol::codec::{Message, PROTOCOL_VERSION, encode_to_vec};
use sinew_protocol::quantize::QuantBounds;
use sinew_protocol::*;

fn v3(rng: &mut fastrand::Rng) -> [f32; 3] {
    std::array::from_fn(|_| (rng.f32() - 0.5) * 200.0)
}

fn unit_quat(rng: &mut fastrand::Rng) -> [f32; 4] {
    let q: [f32; 4] = std::array::from_fn(|_| rng.f32() - 0.5 + 1e-3);
    let n = q.iter().map(|c| c * c).sum::<f32>().sqrt();
    q.map(|c| c / n)
}

fn text(rng: &mut fastrand::Rng) -> String {
    (0..rng.usize(1..12)).map(|_| rng.alphanumeric()).collect()
}

fn pose(rng: &mut fastrand::Rng) -> DevicePose {
    DevicePose {
        seq: rng.u64(..),
        device_time_ns: rng.u64(..),
        position_mm: v3(rng),
        orientation_xyzw: unit_quat(rng),
        linear_velocity_mm_s: v3(rng),
        buttons: rng.u32(..),
        jaw_angle_rad: rng.f32(),
        round_trip_us: rng.u32(..),
        render_mode: if rng.bool() {
            RenderMode::Moderated
        } else {
            RenderMode::Direct
        },
    }
}

/// A random symmetric positive semi-definite matrix: `A^T A` of a random `A`, in the wire layout.
fn psd(rng: &mut fastrand::Rng, scale: f32) -> Sym3 {
    let a: [[f32; 3]; 3] =
        std::array::from_fn(|_| std::array::from_fn(|_| (rng.f32() - 0.5) * scale));
    let m = |i: usize, j: usize| (0..3).map(|k| a[k][i] * a[k][j]).sum::<f32>();
    [m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2)]
}

fn local_model(rng: &mut fastrand::Rng) -> LocalModel {
    let radius_mm = 1.0 + rng.f32() * 20.0;
    let plane_count = rng.u8(0..=4);
    let planes = std::array::from_fn(|_| {
        let n = v3(rng);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(1e-3);
        ContactPlane {
            normal: n.map(|c| c / len),
            offset_mm: (rng.f32() - 0.5) * 100.0,
            stiffness_n_per_mm: rng.f32() * 2.0,
            damping_n_s_per_mm: rng.f32() * 0.01,
        }
    });
    LocalModel {
        server_time_ns: rng.u64(..),
        in_contact: rng.bool(),
        x0_mm: v3(rng),
        f0_n: v3(rng).map(|c| c / 50.0),
        stiffness_n_per_mm: psd(rng, 1.0),
        damping_n_s_per_mm: psd(rng, 0.05),
        radius_mm,
        fade_mm: radius_mm * (0.01 + 0.99 * rng.f32()),
        planes,
        plane_count,
        energy_allowance_mj: rng.f32() * 50.0,
        attached: rng.bool(),
        cut_drag_n: rng.f32() * 0.5,
        friction_coefficient: rng.f32() * 2.0,
        stick_stiffness_n_per_mm: rng.f32() * 3.0,
        cut_facet_mm: if rng.bool() { rng.f32() * 2.0 } else { 0.0 },
        puncture: if rng.bool() {
            let axis = v3(rng);
            let len = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2])
                .sqrt()
                .max(1e-3);
            PunctureTerm {
                press: rng.u32(1..),
                pop_at_n: 0.1 + rng.f32() * 3.0,
                tip_axis: axis.map(|c| c / len),
                f0_after_n: v3(rng).map(|c| c / 50.0),
                stiffness_after_n_per_mm: psd(rng, 1.0),
                drag_after_n: rng.f32() * 0.5,
                tip_lever_mm: v3(rng),
                orientation_xyzw: unit_quat(rng),
            }
        } else {
            PunctureTerm::default()
        },
    }
}

fn force(rng: &mut fastrand::Rng) -> ForceCommand {
    ForceCommand {
        seq: rng.u64(..),
        echo_pose_seq: rng.u64(..),
        echo_device_time_ns: rng.u64(..),
        force_n: v3(rng),
        mode: if rng.bool() {
            ForceMode::Direct
        } else {
            ForceMode::LocalModel(local_model(rng))
        },
        in_contact: rng.bool(),
        device_instance: rng.u64(..),
        pose_wait_us: rng.bool().then(|| rng.u32(..)),
    }
}

fn tool_states(rng: &mut fastrand::Rng) -> ToolStates {
    ToolStates {
        frame: rng.u64(..),
        sim_time_s: rng.f64() * 1e4,
        tools: (0..rng.usize(0..4))
            .map(|i| ToolState {
                tool: i as u16,
                position_mm: v3(rng),
                orientation_xyzw: unit_quat(rng),
                force_n: v3(rng),
                active: rng.bool(),
                in_contact: rng.bool(),
                jaw_angle_rad: rng.f32() * 3.0,
                attachments: rng.u16(..),
            })
            .collect(),
        threads: (0..rng.usize(0..3))
            .map(|_| {
                let nodes: Vec<[f32; 3]> = (0..rng.usize(0..70)).map(|_| v3(rng)).collect();
                let mut thread = ThreadState::from_nodes_mm(rng.u16(0..4), &nodes);
                thread.holes = (0..rng.usize(0..6))
                    .map(|_| HoleMark {
                        position_mm: v3(rng),
                        pull_n: rng.f32() * 5.0,
                        on_needle: rng.bool(),
                    })
                    .collect();
                thread
            })
            .collect(),
        needles: (0..rng.usize(0..3))
            .map(|_| NeedleState {
                tool: rng.u16(0..4),
                position_mm: v3(rng),
                orientation_xyzw: unit_quat(rng),
            })
            .collect(),
    }
}

fn delta(rng: &mut fastrand::Rng) -> MeshDelta {
    let mut indices: Vec<u32> = (0..rng.usize(0..200)).map(|_| rng.u32(0..10_000)).collect();
    indices.sort_unstable();
    indices.dedup();
    let positions_q = indices
        .iter()
        .map(|_| std::array::from_fn(|_| rng.u16(..)))
        .collect();
    let prev_frame = rng.u64(0..u64::MAX / 2);
    let mut burn_indices: Vec<u32> = (0..rng.usize(0..20)).map(|_| rng.u32(0..10_000)).collect();
    burn_indices.sort_unstable();
    burn_indices.dedup();
    let burn = burn_indices.iter().map(|_| rng.u8(..)).collect();
    MeshDelta {
        object: rng.u16(..),
        frame: prev_frame + rng.u64(1..100),
        prev_frame,
        indices,
        positions_q,
        burn_indices,
        burn,
        topology: rng.bool().then(|| topology(rng)),
    }
}

fn topology(rng: &mut fastrand::Rng) -> TopologyDelta {
    let first_vertex = rng.u32(1..10_000);
    let parents: Vec<u32> = (0..rng.usize(0..30))
        .map(|_| rng.u32(0..first_vertex))
        .collect();
    let count = first_vertex + parents.len() as u32;
    let first_triangle = rng.u32(1..20_000);
    let mut retargeted: Vec<u32> = (0..rng.usize(0..30))
        .map(|_| rng.u32(0..first_triangle))
        .collect();
    retargeted.sort_unstable();
    retargeted.dedup();
    let corners = retargeted
        .iter()
        .map(|_| std::array::from_fn(|_| rng.u32(0..count)))
        .collect();
    TopologyDelta {
        epoch: rng.u32(1..),
        first_vertex,
        parents,
        retargeted,
        corners,
        first_triangle,
        added: (0..rng.usize(0..10))
            .map(|_| std::array::from_fn(|_| rng.u32(0..count)))
            .collect(),
    }
}

fn snapshot(rng: &mut fastrand::Rng) -> SceneSnapshot {
    let frame = rng.u64(10..u64::MAX / 2);
    let objects = (0..rng.usize(0..3))
        .map(|i| {
            let n = rng.usize(3..300);
            ObjectSnapshot {
                object: i as u16,
                name: text(rng),
                bounds: QuantBounds {
                    min_mm: [-10.0, -20.0, -30.0],
                    max_mm: [10.0, 20.0, 30.0 + rng.f32()],
                },
                triangles: (0..rng.usize(0..100))
                    .map(|_| std::array::from_fn(|_| rng.u32(0..n as u32)))
                    .collect(),
                positions_q: (0..n)
                    .map(|_| std::array::from_fn(|_| rng.u16(..)))
                    .collect(),
                frame: rng.u64(0..=frame),
                burn: if rng.bool() {
                    Vec::new()
                } else {
                    (0..n).map(|_| rng.u8(..)).collect()
                },
                topology_epoch: rng.u32(..),
                error_bound_mm: rng.f32(),
            }
        })
        .collect();
    SceneSnapshot {
        scene: text(rng),
        frame,
        objects,
        tools: (0..rng.usize(0..3))
            .map(|i| ToolInfo {
                tool: i as u16,
                name: text(rng),
                device_id: text(rng),
                shape: match rng.u8(0..3) {
                    0 => ToolShape::Sphere {
                        radius_mm: rng.f32() * 5.0,
                    },
                    1 => ToolShape::Capsule {
                        half_length_mm: rng.f32() * 10.0,
                        radius_mm: rng.f32(),
                    },
                    _ => ToolShape::Mesh {
                        positions_mm: (0..4).map(|_| v3(rng)).collect(),
                        triangles: vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
                    },
                },
                instrument: match rng.u8(0..5) {
                    0 => InstrumentInfo::Probe,
                    1 => InstrumentInfo::Grasper {
                        jaw_length_mm: 0.5 + rng.f32() * 10.0,
                        open_angle_rad: rng.f32() * 3.0,
                    },
                    2 => InstrumentInfo::Cautery,
                    3 => InstrumentInfo::Scalpel {
                        edge_from_mm: v3(rng),
                        edge_to_mm: v3(rng),
                    },
                    _ => InstrumentInfo::Scissors {
                        hinge_mm: v3(rng),
                        blade_length_mm: 0.5 + rng.f32() * 20.0,
                        open_angle_rad: rng.f32() * 1.5,
                    },
                },
                shaft: rng.bool().then(|| ToolShaft {
                    radius_mm: 0.1 + rng.f32() * 5.0,
                    length_mm: 1.0 + rng.f32() * 100.0,
                }),
            })
            .collect(),
        tool_states: tool_states(rng),
    }
}

fn stats(rng: &mut fastrand::Rng) -> ServerStats {
    ServerStats {
        sim_time_s: rng.f64() * 100.0,
        ticks: rng.u64(..),
        tick_p50_us: rng.f32() * 100.0,
        tick_p99_us: rng.f32() * 400.0,
        tick_max_us: rng.f32() * 4000.0,
        overruns: rng.u64(..),
        sim_faults: rng.u64(..),
        deltas_sent: rng.u64(..),
        delta_bytes_sent: rng.u64(..),
        snapshots_served: rng.u64(..),
        quantization_clamps: rng.u64(..),
        rejected: RejectCounts {
            malformed: rng.u64(..),
            wrong_version: rng.u64(..),
            invalid: rng.u64(..),
            unknown_device: rng.u64(..),
            duplicate_device: rng.u64(..),
            wrong_tool: rng.u64(..),
            no_hello: rng.u64(..),
            access_denied: rng.u64(..),
            tls_refused: rng.u64(..),
        },
        devices: (0..rng.usize(0..3))
            .map(|_| DeviceStats {
                device_id: text(rng),
                active: rng.bool(),
                poses_received: rng.u64(..),
                forces_sent: rng.u64(..),
                last_round_trip_us: rng.u32(..),
                max_force_n: rng.f32() * 3.0,
                moderated: rng.bool(),
                forces_suppressed: rng.u64(..),
                tool: text(rng),
                holder_instance: rng.u64(..),
                duplicates_refused: rng.u64(..),
                last_refused_instance: rng.u64(..),
                wrong_tool_instance: rng.u64(..),
                wrong_tool_asked: text(rng),
                force_limit_n: rng.f32() * 5.0,
                training: TrainingStats {
                    skill_state: text(rng),
                    contacts: rng.u64(..),
                    contact_time_s: rng.f32() * 100.0,
                    path_length_mm: rng.f32() * 1000.0,
                    peak_force_n: rng.f32() * 3.0,
                    harm_n_s: rng.f32(),
                },
            })
            .collect(),
        server_id: text(rng),
        foreign_server_messages: rng.u64(..),
        foreign_server_instance: rng.u64(..),
        exercise: rng.bool().then(|| ExerciseStats {
            kind: text(rng),
            score: rng.f32() * 100.0,
            hits: rng.u32(..),
            total: rng.u32(..),
            errors: rng.u32(..),
            time_s: rng.f32() * 60.0,
            completed: rng.bool(),
            timed_out: rng.bool(),
            targets: (0..rng.usize(0..5))
                .map(|_| TargetMark {
                    at_mm: v3(rng),
                    radius_mm: 0.5 + rng.f32() * 5.0,
                    hit: rng.bool(),
                })
                .collect(),
        }),
    }
}

fn hello(rng: &mut fastrand::Rng) -> ParticipantHello {
    ParticipantHello {
        participant_id: text(rng),
        role: [Role::Server, Role::Haptic, Role::Viewer][rng.usize(0..3)],
        device_model: text(rng),
        max_force_n: rng.f32() * 10.0,
        tool: text(rng),
    }
}

/// Round trip `n` random instances, and check every malformed variant of each is refused.
fn exercise<M: Message + PartialEq + std::fmt::Debug>(make: fn(&mut fastrand::Rng) -> M) {
    let mut rng = fastrand::Rng::with_seed(0x5EED ^ M::KIND as u64);
    for _ in 0..300 {
        let msg = make(&mut rng);
        let bytes = encode_to_vec(sinew_protocol::InstanceId(1), &msg);
        assert_eq!(u16::from_le_bytes([bytes[0], bytes[1]]), PROTOCOL_VERSION);
        let back: M = decode(&bytes).unwrap_or_else(|e| panic!("{msg:?}: {e}"));
        assert_eq!(back, msg);

        // Every strict prefix is refused.
        for cut in 0..bytes.len() {
            assert!(
                decode::<M>(&bytes[..cut]).is_err(),
                "{} prefix {cut} accepted",
                M::KIND.name()
            );
        }
        // Trailing garbage is refused.
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(
            decode::<M>(&longer),
            Err(DecodeError::Malformed { .. })
        ));
        // Another version is refused, naming the version.
        let mut other = bytes.clone();
        other[0] = other[0].wrapping_add(1);
        assert!(matches!(
            decode::<M>(&other),
            Err(DecodeError::WrongVersion { got, .. }) if got != PROTOCOL_VERSION
        ));
        // Another kind is refused.
        let mut kind = bytes.clone();
        kind[2] ^= 0x40;
        assert!(matches!(
            decode::<M>(&kind),
            Err(DecodeError::WrongKind { .. })
        ));
    }
    // Garbage never panics (whatever it decodes to must then validate).
    for _ in 0..2_000 {
        let mut bytes: Vec<u8> = (0..rng.usize(0..64)).map(|_| rng.u8(..)).collect();
        if bytes.len() >= 3 && rng.bool() {
            bytes[..2].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
            bytes[2] = M::KIND as u8;
        }
        if let Ok(msg) = decode::<M>(&bytes) {
            assert!(msg.validate().is_ok());
        }
    }
}

#[test]
fn device_pose_wire() {
    exercise(pose);
}

#[test]
fn force_command_wire() {
    exercise(force);
}

#[test]
fn scene_snapshot_wire() {
    exercise(snapshot);
}

#[test]
fn mesh_delta_wire() {
    exercise(delta);
}

#[test]
fn tool_states_wire() {
    exercise(tool_states);
}

#[test]
fn server_stats_wire() {
    exercise(stats);
}

#[test]
fn participant_hello_wire() {
    exercise(hello);
}

#[test]
fn out_of_domain_fields_are_refused_by_name() {
    let mut rng = fastrand::Rng::with_seed(1);
    let mut p = pose(&mut rng);
    p.position_mm[1] = f32::NAN;
    let err = decode::<DevicePose>(&encode_to_vec(sinew_protocol::InstanceId(1), &p)).unwrap_err();
    assert_eq!(
        err,
        DecodeError::Invalid {
            expected: MessageKind::DevicePose,
            field: "position_mm",
            reason: "not finite"
        }
    );
    assert!(err.to_string().contains("DevicePose"));

    let mut p = pose(&mut rng);
    p.orientation_xyzw = [0.0, 0.0, 0.0, 2.0];
    assert!(matches!(
        decode::<DevicePose>(&encode_to_vec(sinew_protocol::InstanceId(1), &p)),
        Err(DecodeError::Invalid {
            field: "orientation_xyzw",
            ..
        })
    ));

    let mut f = force(&mut rng);
    f.force_n[0] = f32::INFINITY;
    assert!(matches!(
        decode::<ForceCommand>(&encode_to_vec(sinew_protocol::InstanceId(1), &f)),
        Err(DecodeError::Invalid {
            field: "force_n",
            ..
        })
    ));

    let mut d = delta(&mut rng);
    d.positions_q.push([0; 3]);
    assert!(matches!(
        decode::<MeshDelta>(&encode_to_vec(sinew_protocol::InstanceId(1), &d)),
        Err(DecodeError::Invalid {
            field: "positions_q",
            ..
        })
    ));

    let mut s = snapshot(&mut rng);
    s.objects.push(ObjectSnapshot {
        object: s.objects.len() as u16,
        name: "bad".into(),
        bounds: QuantBounds {
            min_mm: [0.0; 3],
            max_mm: [1.0; 3],
        },
        triangles: vec![[0, 1, 5]],
        positions_q: vec![[0; 3]; 3],
        frame: 0,
        burn: Vec::new(),
        topology_epoch: 0,
        error_bound_mm: 0.0,
    });
    assert!(matches!(
        decode::<SceneSnapshot>(&encode_to_vec(sinew_protocol::InstanceId(1), &s)),
        Err(DecodeError::Invalid {
            field: "objects.triangles",
            ..
        })
    ));

    // Burn levels (protocol 6): one per burn index, ascending; a snapshot's burn is empty or one per vertex.
    let mut d = delta(&mut rng);
    d.burn_indices = vec![1, 2];
    d.burn = vec![9];
    assert!(matches!(
        decode::<MeshDelta>(&encode_to_vec(sinew_protocol::InstanceId(1), &d)),
        Err(DecodeError::Invalid { field: "burn", .. })
    ));
    d.burn_indices = vec![2, 1];
    d.burn = vec![9, 9];
    assert!(matches!(
        decode::<MeshDelta>(&encode_to_vec(sinew_protocol::InstanceId(1), &d)),
        Err(DecodeError::Invalid {
            field: "burn_indices",
            ..
        })
    ));
    let mut s = snapshot(&mut rng);
    s.objects.push(ObjectSnapshot {
        object: s.objects.len() as u16,
        name: "burnt".into(),
        bounds: QuantBounds {
            min_mm: [0.0; 3],
            max_mm: [1.0; 3],
        },
        triangles: vec![[0, 1, 2]],
        positions_q: vec![[0; 3]; 3],
        frame: 0,
        burn: vec![255; 2],
        topology_epoch: 0,
        error_bound_mm: 0.0,
    });
    assert!(matches!(
        decode::<SceneSnapshot>(&encode_to_vec(sinew_protocol::InstanceId(1), &s)),
        Err(DecodeError::Invalid {
            field: "objects.burn",
            ..
        })
    ));
    // Topology changes (protocol 7): refused by name when they contradict themselves.
    let good = topology(&mut rng);
    for (field, bad) in [
        (
            "topology.epoch",
            TopologyDelta {
                epoch: 0,
                ..good.clone()
            },
        ),
        (
            "topology.corners",
            TopologyDelta {
                corners: Vec::new(),
                retargeted: vec![0],
                ..good.clone()
            },
        ),
        (
            "topology.retargeted",
            TopologyDelta {
                retargeted: vec![good.first_triangle],
                corners: vec![[0; 3]],
                ..good.clone()
            },
        ),
        (
            "topology.parents",
            TopologyDelta {
                parents: vec![good.first_vertex],
                ..good.clone()
            },
        ),
        (
            "topology.corners",
            TopologyDelta {
                added: vec![[0, 0, good.first_vertex + good.parents.len() as u32]],
                ..good.clone()
            },
        ),
        (
            "topology.parents",
            TopologyDelta {
                first_vertex: 10,
                parents: vec![0; TopologyDelta::MAX_ITEMS + 1],
                retargeted: Vec::new(),
                corners: Vec::new(),
                added: Vec::new(),
                ..good.clone()
            },
        ),
    ] {
        let mut d = delta(&mut rng);
        d.topology = Some(bad);
        match decode::<MeshDelta>(&encode_to_vec(sinew_protocol::InstanceId(1), &d)) {
            Err(DecodeError::Invalid { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: {other:?}"),
        }
    }
    // Tool states: a jaw opening outside 0..pi is refused by name.
    let mut t = tool_states(&mut rng);
    t.tools.push(ToolState {
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        jaw_angle_rad: -0.5,
        ..ToolState::default()
    });
    assert!(matches!(
        decode::<ToolStates>(&encode_to_vec(sinew_protocol::InstanceId(1), &t)),
        Err(DecodeError::Invalid {
            field: "tools.jaw_angle_rad",
            ..
        })
    ));
}

#[test]
fn local_model_fields_out_of_domain_are_refused_by_name() {
    let mut rng = fastrand::Rng::with_seed(9);
    let refused = |model: LocalModel| -> &'static str {
        let command = ForceCommand {
            mode: ForceMode::LocalModel(model),
            ..ForceCommand::default()
        };
        match decode::<ForceCommand>(&encode_to_vec(sinew_protocol::InstanceId(1), &command)) {
            Err(DecodeError::Invalid {
                expected: MessageKind::ForceCommand,
                field,
                ..
            }) => field,
            other => panic!("accepted or wrong error: {other:?}"),
        }
    };
    let good = local_model(&mut rng);
    // Symmetric but indefinite stiffness (eigenvalues 3 and -1 in the x-y block): the renderer would push the
    // hand INTO the tissue along one direction.
    let mut m = good;
    m.stiffness_n_per_mm = [1.0, 1.0, 0.5, 2.0, 0.0, 0.0];
    assert_eq!(refused(m), "local_model.stiffness_n_per_mm");
    // Negative damping (it would feed energy in).
    let mut m = good;
    m.damping_n_s_per_mm = [-0.01, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(refused(m), "local_model.damping_n_s_per_mm");
    // Non-finite values anywhere in the model.
    for field in 0..5 {
        let mut m = good;
        match field {
            0 => m.x0_mm[2] = f32::NAN,
            1 => m.f0_n[0] = f32::INFINITY,
            2 => m.stiffness_n_per_mm[4] = f32::NAN,
            3 => m.radius_mm = f32::INFINITY,
            _ => {
                m.plane_count = 1;
                m.planes[0].offset_mm = f32::NAN;
            }
        }
        refused(m);
    }
    // Radius <= 0, a fade outside (0, radius].
    for radius in [0.0, -1.0] {
        let mut m = good;
        m.radius_mm = radius;
        assert_eq!(refused(m), "local_model.radius_mm");
    }
    let mut m = good;
    m.fade_mm = m.radius_mm * 2.0;
    assert_eq!(refused(m), "local_model.fade_mm");
    let mut m = good;
    m.fade_mm = 0.0;
    assert_eq!(refused(m), "local_model.fade_mm");
    // More than four planes, a non-unit plane normal, a negative plane stiffness, a negative allowance.
    let mut m = good;
    m.plane_count = 5;
    assert_eq!(refused(m), "local_model.plane_count");
    let mut m = good;
    m.plane_count = 1;
    m.planes[0].normal = [0.0, 0.0, 2.0];
    assert_eq!(refused(m), "local_model.planes.normal");
    let mut m = good;
    m.plane_count = 1;
    m.planes[0].normal = [0.0, 0.0, 1.0];
    m.planes[0].stiffness_n_per_mm = -1.0;
    assert_eq!(refused(m), "local_model.planes.stiffness_n_per_mm");
    let mut m = good;
    m.energy_allowance_mj = -1.0;
    assert_eq!(refused(m), "local_model.energy_allowance_mj");
    // A negative or non-finite drag of cutting.
    let mut m = good;
    m.cut_drag_n = -0.1;
    assert_eq!(refused(m), "local_model.cut_drag_n");
    let mut m = good;
    m.cut_drag_n = f32::INFINITY;
    refused(m);
    // A negative or non-finite facet spacing.
    for bad in [-0.5, f32::NAN, f32::INFINITY] {
        let mut m = good;
        m.cut_facet_mm = bad;
        assert_eq!(refused(m), "local_model.cut_facet_mm");
    }
    // A needle's puncture term out of its domain (each field's own refusals: puncture_term.rs).
    let mut m = good;
    m.puncture = PunctureTerm {
        press: 2,
        pop_at_n: 2.5,
        tip_axis: [0.0, 0.0, 3.0],
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        ..PunctureTerm::default()
    };
    assert_eq!(refused(m), "local_model.puncture.tip_axis");
    let mut m = good;
    m.puncture.pop_at_n = 1.0;
    assert_eq!(refused(m), "local_model.puncture");
    // A friction coefficient out of 0..=2, or not finite; a negative stick spring.
    for bad in [-0.1, 2.5, f32::NAN] {
        let mut m = good;
        m.friction_coefficient = bad;
        assert_eq!(refused(m), "local_model.friction_coefficient");
    }
    let mut m = good;
    m.stick_stiffness_n_per_mm = -1.0;
    assert_eq!(refused(m), "local_model.stick_stiffness_n_per_mm");
}

#[test]
fn a_force_command_with_a_full_model_fits_the_emulated_link() {
    let mut rng = fastrand::Rng::with_seed(4);
    let mut model = local_model(&mut rng);
    model.plane_count = 4;
    let command = ForceCommand {
        seq: u64::MAX,
        echo_pose_seq: u64::MAX,
        echo_device_time_ns: u64::MAX,
        mode: ForceMode::LocalModel(model),
        ..ForceCommand::default()
    };
    let len = encode_to_vec(sinew_protocol::InstanceId(1), &command).len();
    assert!(
        len <= sinew_protocol::rt::MAX_DELAYED_MESSAGE_BYTES,
        "{len} bytes"
    );
}

#[test]
fn pose_payload_is_small() {
    let mut rng = fastrand::Rng::with_seed(3);
    let bytes = encode_to_vec(sinew_protocol::InstanceId(1), &pose(&mut rng));
    assert!(bytes.len() <= 92, "pose is {} bytes", bytes.len());
}

#[test]
fn the_envelope_names_its_sender_and_refuses_none_or_an_older_layout() {
    use sinew_protocol::{InstanceId, decode_from};
    let from = InstanceId(0x0123_4567_89ab_cdef);
    let bytes = encode_to_vec(from, &ForceCommand::default());
    assert_eq!(
        bytes.len() - sinew_protocol::codec::HEADER_LEN,
        encode_to_vec(InstanceId(1), &ForceCommand::default()).len()
            - sinew_protocol::codec::HEADER_LEN
    );
    let (got, _) = decode_from::<ForceCommand>(&bytes).unwrap();
    assert_eq!(got, from);
    let mut anonymous = bytes.clone();
    anonymous[3..11].fill(0);
    assert!(matches!(
        decode::<ForceCommand>(&anonymous),
        Err(DecodeError::Invalid {
            field: "sender",
            ..
        })
    ));
    // A version 2 message (3-byte envelope, no sender) is named by its version, however short.
    assert!(matches!(
        decode::<ForceCommand>(&[2, 0, 2, 0]),
        Err(DecodeError::WrongVersion { got: 2, .. })
    ));
    assert_ne!(InstanceId::random(), InstanceId::random());
    assert!(!InstanceId::random().is_none());
}
