//! Bad input over real zenoh: malformed, truncated, wrong-version, NaN and unknown-device poses are dropped
//! and counted by kind; the server keeps ticking and a good device still works afterwards.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::time::Duration;

use hapticserver::HandScript;
use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::keys::SceneKeys;
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::{DevicePose, PROTOCOL_VERSION};
use sinew_testkit::harness::{Pacing, start_pad_server, start_sim_device, wait_until};
use zenoh::Wait;

#[test]
fn bad_poses_are_dropped_and_counted_and_the_server_keeps_running() {
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    let options = NetworkOptions {
        connect: vec![endpoint.clone()],
        ..NetworkOptions::default()
    };
    let session = sinew_server::node::open_session(&options).unwrap();
    let keys = SceneKeys::new("pad").unwrap();
    let left = keys.device_pose("left").unwrap();

    let good = DevicePose {
        seq: 1,
        orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        position_mm: [0.0, 0.0, -3.0],
        ..DevicePose::default()
    };
    let mut nan = good;
    nan.position_mm[2] = f32::NAN;
    let mut wrong_version = encode_to_vec(sinew_protocol::InstanceId(1), &good);
    wrong_version[..2].copy_from_slice(&(PROTOCOL_VERSION + 1).to_le_bytes());
    let encoded = encode_to_vec(sinew_protocol::InstanceId(1), &good);
    let inputs: Vec<(String, Vec<u8>)> = vec![
        (left.clone(), b"garbage, not a pose".to_vec()),
        (left.clone(), encoded[..encoded.len() - 4].to_vec()),
        (left.clone(), vec![1]),
        (left.clone(), wrong_version),
        (
            left.clone(),
            encode_to_vec(sinew_protocol::InstanceId(1), &nan),
        ),
        (keys.device_pose("ghost").unwrap(), encoded.clone()),
        // A zero sender: an envelope check, counted as `invalid` (WIRE.md's table of counters).
        (
            left.clone(),
            encode_to_vec(sinew_protocol::InstanceId(0), &good),
        ),
    ];
    let ticks_before = wait_until(Duration::from_secs(5), || server.stats().ticks > 100);
    assert!(ticks_before);
    // Publish until every kind has been counted (the first puts may precede route establishment).
    let counted = wait_until(Duration::from_secs(10), || {
        for (key, bytes) in &inputs {
            session.put(key.as_str(), bytes.clone()).wait().unwrap();
        }
        let r = server.stats().rejected;
        r.malformed >= 3 && r.wrong_version >= 1 && r.invalid >= 2 && r.unknown_device >= 1
    });
    let stats = server.stats();
    assert!(counted, "rejections not all counted: {:?}", stats.rejected);
    // None of them moved the left tool: it never became active, no force was sent, the pad is at rest.
    assert!(!stats.devices[0].active);
    assert_eq!(stats.devices[0].poses_received, 0);
    assert_eq!(stats.devices[0].forces_sent, 0);
    assert!(
        server
            .latest_positions(0)
            .unwrap()
            .iter()
            .all(|p| p[2].abs() < 1e-6)
    );
    // The server keeps ticking, and a well-behaved device still works.
    let ticks = stats.ticks;
    assert!(wait_until(Duration::from_secs(5), || server.stats().ticks
        > ticks + 100));
    let device = start_sim_device(
        "pad",
        "left",
        // Probe centre 1 mm above the rest surface: its bottom 3 mm into the pad (about 0.45 N). A probe that
        // appears wholly under the sheet (centre 4 mm down) only lifts it and feels almost nothing.
        HandScript::Hold {
            position_mm: [0.0, 0.0, 1.0],
        },
        &endpoint,
        Pacing::Sleep,
    )
    .unwrap();
    assert!(
        wait_until(Duration::from_secs(10), || device
            .report()
            .last_commanded_force_n[2]
            > 0.2),
        "good device gets no force after the bad input: {:?}",
        device.report().last_commanded_force_n
    );
    assert_eq!(server.stats().sim_faults, 0);
}
