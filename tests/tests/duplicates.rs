//! Fault drills for duplicate participants, over real zenoh on loopback (issue "Safe under faults", items 2
//! and 3): two hapticservers with one device id, and two servers for one scene. Every wait has a timeout.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::time::{Duration, Instant};

use hapticserver::server_watch::{Link, Standing};
use hapticserver::{HandScript, HapticHandle};
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_server::node::{ServerConfig, ServerError, ServerHandle, ServerNode};
use sinew_testkit::harness::{
    KillOnDrop, Pacing, deepest_dent_mm, free_loopback_endpoint, load_shipped_world, serial,
    spawn_pad_server_process, start_pad_server, start_sim_device, start_viewer, wait_until,
};

/// Device frame: the pad surface is z = 0 at the device origin.
const HOVER: [f32; 3] = [0.0, 0.0, 10.0];
const PRESS: [f32; 3] = [0.0, 0.0, -5.0];

fn hold(position_mm: [f32; 3]) -> HandScript {
    HandScript::Hold { position_mm }
}

fn left_stats(server: &ServerHandle) -> sinew_protocol::DeviceStats {
    server.stats().devices[0].clone()
}

#[test]
fn a_second_hapticserver_with_a_held_device_id_is_refused_never_moves_the_tool_and_takes_over_when_the_first_leaves()
 {
    let _serial = serial();
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    let first = start_sim_device("pad", "left", hold(HOVER), &endpoint, Pacing::Sleep).unwrap();
    assert!(
        wait_until(Duration::from_secs(10), || left_stats(&server).active
            && matches!(first.report().standing, Standing::Holding { .. })),
        "the first device holds `left`: {:?} / {}",
        left_stats(&server),
        first.report()
    );
    assert_eq!(
        left_stats(&server).holder_instance,
        first.report().instance.0
    );

    // A second hapticserver with the same id presses 5 mm into the pad.
    let second = start_sim_device("pad", "left", hold(PRESS), &endpoint, Pacing::Sleep).unwrap();
    assert!(
        wait_until(Duration::from_secs(10), || matches!(
            second.report().standing,
            Standing::Duplicate { .. }
        )),
        "the second device is told it is refused: {}",
        second.report()
    );
    // It stays refused for two seconds: its poses never reach the tool, it renders nothing, the first keeps
    // the id and feels nothing (it hovers; the pad is untouched).
    let until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < until {
        assert!(
            deepest_dent_mm(&server) < 0.05,
            "the pad was pressed: {} mm",
            deepest_dent_mm(&server)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let stats = server.stats();
    let left = &stats.devices[0];
    assert_eq!(left.holder_instance, first.report().instance.0);
    assert_eq!(left.duplicates_refused, 1, "counted once per instance");
    assert_eq!(left.last_refused_instance, second.report().instance.0);
    assert!(
        stats.rejected.duplicate_device > 500,
        "{:?}",
        stats.rejected
    );
    assert_eq!(second.report().max_rendered_force_n, 0.0);
    assert!(first.report().max_rendered_force_n < 0.05);
    assert!(matches!(first.report().standing, Standing::Holding { .. }));

    // The first leaves: the second takes the id, its tool enters from above and presses, and its force ramps in.
    first.kill();
    assert!(
        wait_until(Duration::from_secs(5), || matches!(
            second.report().standing,
            Standing::Holding { .. }
        ) && second
            .report()
            .last_rendered_force_magnitude_n()
            > 0.5),
        "the second device takes over and presses: {} / {:?}",
        second.report(),
        left_stats(&server)
    );
    assert_eq!(
        left_stats(&server).holder_instance,
        second.report().instance.0
    );
}

fn server_config(listen: &str, connect: &[String]) -> ServerConfig {
    ServerConfig {
        network: NetworkOptions {
            listen: with_udp_twin(listen),
            connect: connect.to_vec(),
            ..NetworkOptions::default()
        },
        spin_native_accuracy_ns: 0,
        ..ServerConfig::default()
    }
}

#[test]
fn a_second_server_for_a_live_scene_refuses_to_start_and_says_so() {
    let _serial = serial();
    let (endpoint, _server) = start_pad_server(Pacing::Sleep).unwrap();

    // In process: the library refuses with a typed error.
    let other = free_loopback_endpoint().unwrap();
    let refused = ServerNode::start(
        load_shipped_world("pad.toml").unwrap(),
        server_config(&other, std::slice::from_ref(&endpoint)),
    );
    match refused {
        Err(ServerError::AnotherServer { scene, found }) => {
            assert_eq!(scene, "pad");
            assert!(found.contains("presence/server"), "{found}");
        }
        other => panic!("a second server started: {other:?}"),
    }

    // As a process: it exits non-zero, naming the reason.
    let other = free_loopback_endpoint().unwrap();
    let child = spawn_pad_server_process(&other, &["--connect", &endpoint], true).unwrap();
    let mut child = KillOnDrop(child);
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = child.0.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the second server kept running");
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(child.0.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert!(!status.success(), "exit status {status}");
    assert!(
        stderr.contains("another server is already live for scene `pad`"),
        "stderr: {stderr}"
    );
}

fn wait_joined(device: &HapticHandle) -> sinew_protocol::InstanceId {
    let mut joined = sinew_protocol::InstanceId::NONE;
    assert!(
        wait_until(Duration::from_secs(10), || {
            if let Link::Joined(instance) = device.report().server_link {
                joined = instance;
                true
            } else {
                false
            }
        }),
        "{}",
        device.report()
    );
    joined
}

#[test]
fn clients_that_reach_two_live_servers_stay_with_the_one_they_joined() {
    let _serial = serial();
    // Two servers that cannot see each other at start (neither connects to the other).
    let (a_endpoint, a) = start_pad_server(Pacing::Sleep).unwrap();
    let (b_endpoint, b) = start_pad_server(Pacing::Sleep).unwrap();
    // A device and a viewer that reach both.
    let device = {
        let hand = hapticserver::SimDevice::with_params(
            hold(PRESS),
            hapticserver::HandPreset::Grip.params(),
            hapticserver::sim_device::sim_device_model(),
        );
        let mut config =
            sinew_testkit::harness::pad_device_config("left", Box::new(hand), &a_endpoint);
        config.network.connect.extend(with_udp_twin(&b_endpoint));
        config.spin_accuracy_ns = 0;
        hapticserver::HapticServer::start(config).unwrap()
    };
    let viewer = {
        let mut config = sinew_viewer::ViewerConfig::new("pad", "instructor");
        config.network.connect = vec![a_endpoint.clone(), b_endpoint.clone()];
        sinew_viewer::ViewerClient::start(config).unwrap()
    };
    let joined = wait_joined(&device);
    assert!(joined == a.instance() || joined == b.instance());
    assert!(
        wait_until(Duration::from_secs(10), || device
            .report()
            .forces_from_other_server
            > 100
            && viewer.stats().from_other_server > 10),
        "both hear the other server and refuse it: {} / {:?}",
        device.report(),
        viewer.stats()
    );
    assert!(viewer.wait_for_snapshot(Duration::from_secs(10)));
    let snapshots = viewer.stats().snapshots_fetched;
    // Three seconds with both servers live: the device holds a steady press from one server, the viewer does
    // not thrash between replicas.
    std::thread::sleep(Duration::from_secs(3));
    let report = device.report();
    assert_eq!(report.server_link, Link::Joined(joined));
    assert!(
        report.last_second.ticks > 0 && report.last_second.force_p2p_n < 0.1,
        "steady force from one server: {:?}",
        report.last_second
    );
    assert!(report.last_rendered_force_magnitude_n() > 0.5, "{report}");
    assert_eq!(viewer.stats().snapshots_fetched, snapshots, "no resync");
    // The servers hear of each other through the clients (zenoh's peer brokering) and say so.
    let (a_stats, b_stats) = (a.stats(), b.stats());
    assert!(
        a_stats.foreign_server_messages > 0 && a_stats.foreign_server_instance == b.instance().0,
        "{a_stats:?}"
    );
    assert!(
        b_stats.foreign_server_messages > 0 && b_stats.foreign_server_instance == a.instance().0,
        "{b_stats:?}"
    );
    let _ = start_viewer; // the default viewer connects to one endpoint only
    drop(viewer);
    drop(device);
    drop((a, b));
}
