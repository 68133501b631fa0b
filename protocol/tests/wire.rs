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
    }
}

fn force(rng: &mut fastrand::Rng) -> ForceCommand {
    ForceCommand {
        seq: rng.u64(..),
        echo_pose_seq: rng.u64(..),
        echo_device_time_ns: rng.u64(..),
        force_n: v3(rng),
        mode: ForceMode::Direct,
        in_contact: rng.bool(),
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
    MeshDelta {
        object: rng.u16(..),
        frame: prev_frame + rng.u64(1..100),
        prev_frame,
        indices,
        positions_q,
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
        },
        devices: (0..rng.usize(0..3))
            .map(|_| DeviceStats {
                device_id: text(rng),
                active: rng.bool(),
                poses_received: rng.u64(..),
                forces_sent: rng.u64(..),
                last_round_trip_us: rng.u32(..),
                max_force_n: rng.f32() * 3.0,
            })
            .collect(),
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
        let bytes = encode_to_vec(&msg);
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
    let err = decode::<DevicePose>(&encode_to_vec(&p)).unwrap_err();
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
        decode::<DevicePose>(&encode_to_vec(&p)),
        Err(DecodeError::Invalid {
            field: "orientation_xyzw",
            ..
        })
    ));

    let mut f = force(&mut rng);
    f.force_n[0] = f32::INFINITY;
    assert!(matches!(
        decode::<ForceCommand>(&encode_to_vec(&f)),
        Err(DecodeError::Invalid {
            field: "force_n",
            ..
        })
    ));

    let mut d = delta(&mut rng);
    d.positions_q.push([0; 3]);
    assert!(matches!(
        decode::<MeshDelta>(&encode_to_vec(&d)),
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
    });
    assert!(matches!(
        decode::<SceneSnapshot>(&encode_to_vec(&s)),
        Err(DecodeError::Invalid {
            field: "objects.triangles",
            ..
        })
    ));
}

#[test]
fn pose_payload_is_small() {
    let mut rng = fastrand::Rng::with_seed(3);
    let bytes = encode_to_vec(&pose(&mut rng));
    assert!(bytes.len() <= 92, "pose is {} bytes", bytes.len());
}
