//! The pose -> force round trip through zenoh's own router against the server as the router, and raw zenoh
//! ping-pong through each, over plain TCP and over mutual TLS on QUIC: every phase in one run, so they share the
//! machine's conditions. All on loopback; the routers are `zenohd` 1.10.2 processes, the server and the two
//! simulated devices (left presses and strokes, right presses and holds, on worlds/pad.toml) run in this
//! process, each with its own zenoh session in client mode.
//!
//! Phases:
//! 1. raw ping-pong, two peer sessions (the baseline of `round_trip`);
//! 2. raw ping-pong, two clients of `zenohd` (TCP);
//! 3. pose -> force, the server as the router (TCP and UDP), devices its clients;
//! 4. pose -> force, server and devices clients of `zenohd` (TCP);
//! 5. raw ping-pong through the lab's `zenohd` on QUIC with the lab's certificates and access rules (a device's
//!    certificate publishes the pose, the server's echoes it as the force, on the scene's own keys);
//! 6. pose -> force, the server as the router on QUIC with its certificate;
//! 7. pose -> force through the lab's `zenohd` on QUIC.
//!
//! Run: `cargo bench -p sinew-testkit --bench zenohd_round_trip` (add `-- --seconds N`, default 8 per phase).
//! Needs `zenohd` (`cargo install zenohd --version 1.10.2 --locked`).

#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Duration;

use sinew_protocol::keys::SceneKeys;
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_protocol::rt::LatencyHistogram;
use sinew_protocol::security::TlsFiles;
use sinew_testkit::bench_support::{self, arg, encoded_pose_len, round_trips_since, us};
use sinew_testkit::harness::{
    Pacing, SimDeviceSetup, free_loopback_endpoint, load_shipped_world, start_server_networked,
    start_sim_device_networked, surgeon_scripts,
};
use sinew_testkit::zenohd::{start_lab_router, start_plain_router};

fn client(endpoint: &[String], tls: Option<&TlsFiles>) -> NetworkOptions {
    NetworkOptions {
        connect: endpoint.to_vec(),
        mode: Some("client".to_owned()),
        tls: tls.cloned(),
        ..NetworkOptions::default()
    }
}

/// Ping-pong of an encoded pose's size between `a` and `b` on `keys` (ping, pong), after 1.5 s for the
/// declarations to cross the router.
fn ping_pong(
    seconds: f64,
    a: &NetworkOptions,
    b: &NetworkOptions,
    keys: (&str, &str),
) -> LatencyHistogram {
    bench_support::ping_pong(
        seconds,
        a,
        b,
        keys,
        encoded_pose_len(),
        Duration::from_millis(1500),
    )
    .unwrap()
}

/// The server on `server`, two devices on `devices`: the left and right devices' rendered and wire round
/// trips over `seconds` after 2 s.
fn pose_to_force(
    seconds: f64,
    server: NetworkOptions,
    devices: [NetworkOptions; 2],
) -> Vec<(String, LatencyHistogram, LatencyHistogram)> {
    let world = load_shipped_world("pad.toml").unwrap();
    let mut server =
        start_server_networked(world, server, Pacing::Spin, Default::default(), None).unwrap();
    let (left, right) = surgeon_scripts();
    let [left_net, right_net] = devices;
    let mut hands =
        [("left", left, left_net), ("right", right, right_net)].map(|(id, script, net)| {
            start_sim_device_networked(
                "pad",
                id,
                script,
                net,
                Pacing::Spin,
                SimDeviceSetup::default(),
            )
            .unwrap()
        });
    std::thread::sleep(Duration::from_secs(2));
    let settled: Vec<_> = hands.iter().map(|d| d.report()).collect();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let after: Vec<_> = hands.iter().map(|d| d.report()).collect();
    for hand in &mut hands {
        hand.stop().unwrap();
    }
    server.stop();
    round_trips_since(&after, &settled)
}

fn row(
    label: &str,
    h: &LatencyHistogram,
    baseline: &LatencyHistogram,
    router_baseline: &LatencyHistogram,
) {
    println!(
        "| {label} | {:.0} us | {:.0} us | {:.1} / {:.1} | {:.1} / {:.1} | {} |",
        us(h, 50.0),
        us(h, 99.0),
        us(h, 50.0) / us(baseline, 50.0),
        us(h, 99.0) / us(baseline, 99.0),
        us(h, 50.0) / us(router_baseline, 50.0),
        us(h, 99.0) / us(router_baseline, 99.0),
        h.count()
    );
}

fn main() {
    let seconds = arg("--seconds", 8.0);
    let keys = SceneKeys::new("pad").unwrap();

    // Plain TCP.
    let peer = free_loopback_endpoint().unwrap();
    let baseline = ping_pong(
        seconds,
        &NetworkOptions {
            listen: vec![peer.clone()],
            ..NetworkOptions::default()
        },
        &NetworkOptions {
            connect: vec![peer],
            ..NetworkOptions::default()
        },
        ("bench/ping", "bench/pong"),
    );
    let router = free_loopback_endpoint().unwrap();
    let zenohd = start_plain_router(&router).unwrap();
    let through_zenohd = ping_pong(
        seconds,
        &client(std::slice::from_ref(&router), None),
        &client(std::slice::from_ref(&router), None),
        ("bench/ping", "bench/pong"),
    );
    let server_router = free_loopback_endpoint().unwrap();
    let as_router = pose_to_force(
        seconds,
        NetworkOptions {
            listen: with_udp_twin(&server_router),
            mode: Some("router".to_owned()),
            ..NetworkOptions::default()
        },
        [(); 2].map(|_| client(&with_udp_twin(&server_router), None)),
    );
    let via_zenohd = pose_to_force(
        seconds,
        client(std::slice::from_ref(&router), None),
        [(); 2].map(|_| client(std::slice::from_ref(&router), None)),
    );
    drop(zenohd);

    // Mutual TLS on QUIC, with the lab's certificates.
    let dir = std::env::temp_dir().join(format!("sinew-bench-certs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let certs =
        sinew::certs::make_lab_certs(&dir, "pad", &["left".into(), "right".into()], &[]).unwrap();
    let role = |name: &str| certs.role(name).unwrap().clone();
    let quic = |e: String| e.replacen("tcp/", "quic/", 1);
    let lab_router = quic(free_loopback_endpoint().unwrap());
    let lab_zenohd = start_lab_router(&certs, &lab_router).unwrap();
    let tls_through_zenohd = ping_pong(
        seconds,
        &client(
            std::slice::from_ref(&lab_router),
            Some(&role("device-left")),
        ),
        &client(std::slice::from_ref(&lab_router), Some(&role("server"))),
        (
            &keys.device_pose("left").unwrap(),
            &keys.device_force("left").unwrap(),
        ),
    );
    let tls_server_router = quic(free_loopback_endpoint().unwrap());
    let tls_as_router = pose_to_force(
        seconds,
        NetworkOptions {
            listen: vec![tls_server_router.clone()],
            mode: Some("router".to_owned()),
            tls: Some(role("server")),
            ..NetworkOptions::default()
        },
        ["left", "right"].map(|id| {
            client(
                std::slice::from_ref(&tls_server_router),
                Some(&role(&format!("device-{id}"))),
            )
        }),
    );
    let tls_via_zenohd = pose_to_force(
        seconds,
        client(std::slice::from_ref(&lab_router), Some(&role("server"))),
        ["left", "right"].map(|id| {
            client(
                std::slice::from_ref(&lab_router),
                Some(&role(&format!("device-{id}"))),
            )
        }),
    );
    drop(lab_zenohd);
    let _ = std::fs::remove_dir_all(&dir);

    println!(
        "| measurement | p50 | p99 | ratio p50 / p99 to peer ping-pong | ratio p50 / p99 to ping-pong through the layout's zenohd | samples |"
    );
    println!("|---|---|---|---|---|---|");
    row(
        "raw ping-pong, peer to peer, TCP (baseline)",
        &baseline,
        &baseline,
        &through_zenohd,
    );
    row(
        "raw ping-pong through zenohd, TCP",
        &through_zenohd,
        &baseline,
        &through_zenohd,
    );
    for (label, phase, router_baseline) in [
        ("server as router, TCP+UDP", &as_router, &through_zenohd),
        ("through zenohd, TCP", &via_zenohd, &through_zenohd),
    ] {
        for (id, rendered, wire) in phase {
            row(
                &format!("pose -> force `{id}`, {label}, wire"),
                wire,
                &baseline,
                router_baseline,
            );
            row(
                &format!("pose -> force `{id}`, {label}, rendered"),
                rendered,
                &baseline,
                router_baseline,
            );
        }
    }
    row(
        "raw ping-pong through the lab's zenohd, TLS on QUIC",
        &tls_through_zenohd,
        &baseline,
        &tls_through_zenohd,
    );
    for (label, phase) in [
        ("server as router, TLS on QUIC", &tls_as_router),
        ("through the lab's zenohd, TLS on QUIC", &tls_via_zenohd),
    ] {
        for (id, rendered, wire) in phase {
            row(
                &format!("pose -> force `{id}`, {label}, wire"),
                wire,
                &baseline,
                &tls_through_zenohd,
            );
            row(
                &format!("pose -> force `{id}`, {label}, rendered"),
                rendered,
                &baseline,
                &tls_through_zenohd,
            );
        }
    }
}
