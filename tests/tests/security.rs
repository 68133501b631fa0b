//! Sessions only the invited can join, over real mutual-TLS zenoh sessions on loopback: certificates from
//! `sinew certs`, a server that enforces the roles' access rules, and the refusals each rule makes.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::sync::Arc;
use std::time::Duration;

use hapticserver::sim_device::sim_device_model;
use hapticserver::{HandPreset, HandScript, HapticConfig, HapticServer, SimDevice};
use sinew::certs::{LabCerts, make_lab_certs};
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::LatestValue;
use sinew_protocol::security::TlsFiles;
use sinew_server::node::{ServerConfig, ServerHandle, ServerNode};
use sinew_testkit::harness::{
    deepest_dent_mm, load_shipped_world, serial, wait_device_active, wait_until,
};

fn lab(name: &str) -> LabCerts {
    sinew_server::node::access_refusals::install_for_tests();
    let dir = std::env::temp_dir().join(format!("sinew-certs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    make_lab_certs(&dir, "pad", &["left".into(), "right".into()], &[]).unwrap()
}

/// A free loopback port as a secured (QUIC, TLS 1.3) endpoint.
fn tls_endpoint() -> String {
    let tcp = sinew_testkit::harness::free_loopback_endpoint().unwrap();
    tcp.replacen("tcp/", "quic/", 1)
}

fn start_tls_server(certs: &LabCerts, endpoint: &str) -> ServerHandle {
    let config = ServerConfig {
        network: NetworkOptions {
            listen: vec![endpoint.to_owned()],
            tls: Some(certs.role("server").unwrap().clone()),
            ..NetworkOptions::default()
        },
        server_id: "server".into(),
        spin_native_accuracy_ns: 0,
        ..ServerConfig::default()
    };
    ServerNode::start(load_shipped_world("pad.toml").unwrap(), config).unwrap()
}

fn start_tls_device(
    id: &str,
    files: &TlsFiles,
    endpoint: &str,
    target: &Arc<LatestValue<[f32; 3]>>,
) -> hapticserver::HapticHandle {
    let device = SimDevice::with_params(
        HandScript::Follow(target.clone()),
        HandPreset::Grip.params(),
        sim_device_model(),
    );
    let mut config = HapticConfig::new("pad", id, Box::new(device));
    config.network = NetworkOptions {
        connect: vec![endpoint.to_owned()],
        tls: Some(files.clone()),
        ..NetworkOptions::default()
    };
    config.spin_accuracy_ns = 0;
    HapticServer::start(config).unwrap()
}

/// Let `device` (publishing as `id` with a certificate that may not) press for 3 s, then check that the
/// server refused it: `id`'s tool never moved, the tissue is untouched, and at least 90% of the poses it
/// published were counted as refused (the last few may still be in flight). Returns the stats.
fn assert_refused(
    server: &ServerHandle,
    device: &hapticserver::HapticHandle,
    id: &str,
) -> sinew_protocol::ServerStats {
    std::thread::sleep(Duration::from_secs(3));
    let published = device.report().poses_published;
    let stats = server.stats();
    let slot = stats.devices.iter().find(|d| d.device_id == id).unwrap();
    assert!(!slot.active && slot.poses_received == 0, "{slot:?}");
    assert!(deepest_dent_mm(server) < 0.05, "the tissue moved");
    assert!(
        published > 1000 && stats.rejected.access_denied as f64 >= 0.9 * published as f64,
        "{published} poses published, refusals counted: {:?}",
        stats.rejected
    );
    stats
}

fn cleanup(certs: &LabCerts) {
    let _ = std::fs::remove_dir_all(&certs.dir);
}

#[test]
fn a_device_with_its_lab_certificate_presses_the_pad_over_mutual_tls() {
    let _serial = serial();
    let certs = lab("press");
    let endpoint = tls_endpoint();
    let server = start_tls_server(&certs, &endpoint);
    let target = Arc::new(LatestValue::new());
    target.store([0.0, 0.0, 15.0]);
    let mut left = start_tls_device(
        "left",
        certs.role("device-left").unwrap(),
        &endpoint,
        &target,
    );
    assert!(
        wait_device_active(&server, "left", Duration::from_secs(10)),
        "left never drove its tool over TLS: {:?}",
        server.stats().devices
    );
    target.store([0.0, 0.0, -5.0]);
    assert!(
        wait_until(Duration::from_secs(10), || left
            .report()
            .last_commanded_force_n[2]
            > 0.3),
        "no force over TLS: {}\n{:?}",
        left.report(),
        server.stats()
    );
    assert!(
        wait_until(Duration::from_secs(10), || deepest_dent_mm(&server) > 1.0),
        "no dent"
    );
    let rejected = server.stats().rejected;
    assert_eq!(
        rejected.access_denied, 0,
        "a lab device was denied: {rejected:?}"
    );
    assert_eq!(rejected.tls_refused, 0, "{rejected:?}");
    left.stop().unwrap();
    drop(server);
    cleanup(&certs);
}

#[test]
fn a_device_publishing_another_devices_pose_is_refused_and_that_tool_does_not_move() {
    let _serial = serial();
    let certs = lab("impostor");
    let endpoint = tls_endpoint();
    let server = start_tls_server(&certs, &endpoint);
    let target = Arc::new(LatestValue::new());
    target.store([0.0, 0.0, -5.0]);
    // Left's certificate, claiming to be right.
    let mut impostor = start_tls_device(
        "right",
        certs.role("device-left").unwrap(),
        &endpoint,
        &target,
    );
    // Its poses (1 kHz), hellos and presence token were refused, and counted.
    let stats = assert_refused(&server, &impostor, "right");
    assert_eq!(stats.rejected.total(), stats.rejected.access_denied);
    assert_eq!(
        stats.rejected.tls_refused, 0,
        "a lab certificate passes the handshake"
    );
    impostor.stop().unwrap();
    drop(server);
    cleanup(&certs);
}

/// One lab (one CA, one site) holds two scenes: `left`'s certificate of the cautery scene is signed by the same
/// CA and passes the handshake, but its name (`device-left@cautery`) is in none of the pad's rules: the pad's
/// server sends it nothing (not even its subscriptions, so its poses never leave its own session: a few
/// hellos are all the server counts as refused), hears nothing of it, and its tool does not move.
#[test]
fn a_device_certificate_of_another_scene_in_the_same_lab_is_refused() {
    let _serial = serial();
    let certs = lab("two-scenes");
    let cautery = make_lab_certs(&certs.dir, "cautery", &["left".into()], &[]).unwrap();
    assert_eq!(cautery.ca, certs.ca, "the second scene reuses the lab's CA");
    let endpoint = tls_endpoint();
    let server = start_tls_server(&certs, &endpoint);
    let target = Arc::new(LatestValue::new());
    target.store([0.0, 0.0, -5.0]);
    let mut stranger = start_tls_device(
        "left",
        cautery.role("device-left").unwrap(),
        &endpoint,
        &target,
    );
    std::thread::sleep(Duration::from_secs(3));
    let report = stranger.report();
    let stats = server.stats();
    let slot = stats
        .devices
        .iter()
        .find(|d| d.device_id == "left")
        .unwrap();
    println!(
        "cautery's left at the pad: {} poses published, {} received, {:?}, link {:?}",
        report.poses_published, slot.poses_received, stats.rejected, report.server_link
    );
    assert!(report.poses_published > 1000);
    assert!(!slot.active && slot.poses_received == 0, "{slot:?}");
    assert!(deepest_dent_mm(&server) < 0.05, "the tissue moved");
    assert_eq!(report.forces_received, 0);
    assert!(
        !matches!(
            report.server_link,
            hapticserver::server_watch::Link::Joined(_)
        ),
        "it saw the pad's server: {report}"
    );
    assert_eq!(
        stats.rejected.tls_refused, 0,
        "the same CA signed it: the handshake passes"
    );
    stranger.stop().unwrap();
    drop(server);
    cleanup(&certs);
}

#[test]
fn an_observer_publishing_a_pose_is_refused_and_the_tissue_does_not_move() {
    let _serial = serial();
    let certs = lab("observer");
    let endpoint = tls_endpoint();
    let server = start_tls_server(&certs, &endpoint);
    let target = Arc::new(LatestValue::new());
    target.store([0.0, 0.0, -5.0]);
    // A device loop pressing 5 mm deep as `left`, holding an observer's certificate.
    let mut intruder =
        start_tls_device("left", certs.role("observer").unwrap(), &endpoint, &target);
    assert_refused(&server, &intruder, "left");
    // It still sees the server (reading is allowed to every lab certificate).
    let report = intruder.report();
    assert!(
        matches!(
            report.server_link,
            hapticserver::server_watch::Link::Joined(_)
        ),
        "{report}"
    );
    // A viewer with the same observer certificate replicates the scene: watching is what it may do.
    let mut config = sinew_viewer::ViewerConfig::new("pad", "instructor");
    config.network = NetworkOptions {
        connect: vec![endpoint.clone()],
        tls: Some(certs.role("observer").unwrap().clone()),
        ..NetworkOptions::default()
    };
    let mut viewer = sinew_viewer::ViewerClient::start(config).unwrap();
    assert!(
        viewer.wait_for_snapshot(Duration::from_secs(10)),
        "the observer's viewer got no snapshot over TLS"
    );
    viewer.stop();
    intruder.stop().unwrap();
    drop(server);
    cleanup(&certs);
}

#[test]
fn a_peer_without_a_lab_certificate_is_refused_at_the_handshake() {
    let _serial = serial();
    let certs = lab("outsider-lab");
    let other = lab("outsider-other");
    let endpoint = tls_endpoint();
    let server = start_tls_server(&certs, &endpoint);
    let target = Arc::new(LatestValue::new());
    target.store([0.0, 0.0, -5.0]);
    // A certificate named device-left, from another CA: the server's TLS refuses the link.
    let outsider = std::panic::catch_unwind(|| {
        start_tls_device(
            "left",
            other.role("device-left").unwrap(),
            &endpoint,
            &target,
        )
    });
    std::thread::sleep(Duration::from_secs(2));
    let stats = server.stats();
    let left = stats
        .devices
        .iter()
        .find(|d| d.device_id == "left")
        .unwrap();
    assert!(!left.active && left.poses_received == 0, "{left:?}");
    assert!(deepest_dent_mm(&server) < 0.05, "the tissue moved");
    // Every attempt to connect was refused at the handshake, and counted.
    assert!(stats.rejected.tls_refused >= 1, "{:?}", stats.rejected);
    assert_eq!(
        stats.rejected.access_denied, 0,
        "nothing got far enough to be denied"
    );
    drop(outsider);
    drop(server);
    cleanup(&certs);
    cleanup(&other);
}
