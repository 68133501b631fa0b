//! A lab's `zenohd` across a real, distant path (issue 34): the router and the server in the hub's namespace,
//! the surgeons' site in another, the lab's relay between them adding 25 ms +-5 ms each way and 2% loss. Every
//! role is a client of the router over mutual TLS on QUIC with the certificates `sinew certs` issues and the
//! router file it writes; the hapticservers render in latency-moderated mode.
//!
//! Checked: both surgeons press and feel the pad at the far site; a headless viewer and `sinew-recorder` with
//! the observer's certificate, at the surgeons' site, replicate the scene and record both surgeons' poses and
//! presence; the server killed and a new one started leaves the router and the hands running, their forces
//! fade to zero and come back; the router killed and started again, likewise.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::process::{Child, Command};
use std::time::{Duration, Instant};

use sinew_server::recording::survey;
use sinew_testkit::harness::serial;
use sinew_testkit::lab_run::{
    assert_namespaces_gone, relay_loss, require_lab, shipped_world, status_number,
};
use sinew_testkit::netns::{LabConfig, NetnsLab, Side, role_binary, wait_output};
use sinew_testkit::zenohd::{tls_args, zenohd_binary};

/// The router's port in the hub namespace (QUIC, so UDP).
const ROUTER_PORT: u16 = 7447;

/// Start `zenohd -c config` in the hub namespace and wait until it has bound its UDP port there.
fn start_router(lab: &mut NetnsLab, config: &std::path::Path) -> Child {
    let mut zenohd = Command::new(zenohd_binary());
    zenohd.arg("-c").arg(config);
    let child = lab.spawn_in(Side::Server, &zenohd).unwrap();
    let namespace = lab.namespace(Side::Server).to_owned();
    let bound = || {
        Command::new("ip")
            .args(["netns", "exec", &namespace, "ss", "-Hlun"])
            .arg(format!("sport = :{ROUTER_PORT}"))
            .output()
            .map(|o| !String::from_utf8_lossy(&o.stdout).trim().is_empty())
            .unwrap_or(false)
    };
    let deadline = Instant::now() + Duration::from_secs(10);
    while !bound() {
        assert!(Instant::now() < deadline, "zenohd never bound its port");
        std::thread::sleep(Duration::from_millis(50));
    }
    child
}

/// Each `<id>: ...` status line's rendered force, N, in order (one a second).
fn forces_over_time(output: &std::process::Output, id: &str) -> Vec<f64> {
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter(|l| l.starts_with(&format!("{id}: ")))
        .filter_map(|l| status_number(l, "force "))
        .collect()
}

#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn through_zenohd_at_a_distance_both_surgeons_feel_are_watched_recorded_and_rejoin_after_restarts()
{
    let _serial = serial();
    require_lab();
    let mut lab = NetnsLab::new(LabConfig::symmetric(25.0, 5.0, 0.02, 11)).unwrap();
    let namespaces: Vec<String> = lab.namespaces().map(str::to_owned).to_vec();
    let hub_ip = lab.server_ip().to_string();
    let dir = std::env::temp_dir().join(format!("sinew-zenohd-sites-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // The hub's address is in every certificate: each role checks the name it dialled.
    let certs = sinew::certs::make_lab_certs(
        &dir,
        "pad",
        &["left".into(), "right".into()],
        std::slice::from_ref(&hub_ip),
    )
    .unwrap();
    let router_config =
        sinew::certs::write_router_config(&dir, &[format!("quic/0.0.0.0:{ROUTER_PORT}")]).unwrap();
    let router = format!("quic/{hub_ip}:{ROUTER_PORT}");
    let role = |name: &str| tls_args(certs.role(name).unwrap());
    let client = ["--zenoh-mode", "client", "--connect", &router];

    let mut zenohd = start_router(&mut lab, &router_config);
    let server_command = || {
        let mut server = Command::new(role_binary("sinew-server").unwrap());
        server
            .arg("--world")
            .arg(shipped_world("pad"))
            .args(client)
            .args(role("server"));
        server
    };
    let mut server = lab.spawn_in(Side::Server, &server_command()).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let hand = |id: &str| {
        let mut haptic = Command::new(role_binary("hapticserver").unwrap());
        haptic
            .args(["--id", id, "--script", "press", "--mode", "moderated"])
            .args(["--duration-s", "32"])
            .args(client)
            .args(role(&format!("device-{id}")));
        haptic
    };
    let left = lab.spawn_in(Side::Device, &hand("left")).unwrap();
    let right = lab.spawn_in(Side::Device, &hand("right")).unwrap();
    // The script, from the hands' start (their status lines come once a second from then on).
    let started = Instant::now();
    let at = |s: u64| {
        let due = started + Duration::from_secs(s);
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
    };
    at(6);

    // The instructor at the surgeons' site: a viewer and a recorder with the observer's certificate.
    let mut viewer = Command::new(role_binary("sinew-viewer").unwrap());
    viewer
        .args(["--headless", "--duration-s", "4"])
        .args(client)
        .args(role("observer"));
    let viewer = lab.spawn_in(Side::Device, &viewer).unwrap();
    let file = dir.join("site.mcap");
    let mut recorder = Command::new(role_binary("sinew-recorder").unwrap());
    recorder
        .args(["--out", file.to_str().unwrap(), "--scene", "pad"])
        .args(["--duration-s", "3", "--id", "instructor-recorder"])
        .args(client)
        .args(role("observer"));
    let recorder = lab.spawn_in(Side::Device, &recorder).unwrap();
    let recorder = wait_output(recorder, Duration::from_secs(30)).unwrap();
    let viewer = wait_output(viewer, Duration::from_secs(30)).unwrap();

    // The server dies at 12 s, a new one at 16 s; the router dies at 22 s and is back at 26 s.
    at(12);
    server.kill().unwrap();
    let _ = server.wait();
    at(16);
    server = lab.spawn_in(Side::Server, &server_command()).unwrap();
    at(22);
    zenohd.kill().unwrap();
    let _ = zenohd.wait();
    at(26);
    zenohd = start_router(&mut lab, &router_config);
    let left = wait_output(left, Duration::from_secs(40)).unwrap();
    let right = wait_output(right, Duration::from_secs(40)).unwrap();
    server.kill().unwrap();
    let server = wait_output(server, Duration::from_secs(10)).unwrap();
    let server_out = String::from_utf8_lossy(&server.stdout);
    let server_log = dir.join("second-server.log");
    std::fs::write(
        &server_log,
        format!("{server_out}\n{}", String::from_utf8_lossy(&server.stderr)),
    )
    .unwrap();
    println!(
        "the second server ({}): {}",
        server_log.display(),
        server_out
            .lines()
            .rev()
            .find(|l| l.contains("ticks"))
            .unwrap_or_default()
    );
    zenohd.kill().unwrap();
    let relay = lab.stop_relay().unwrap();
    drop(lab);
    assert_namespaces_gone(&namespaces);

    let viewer_out = String::from_utf8_lossy(&viewer.stdout);
    println!("viewer: {}", viewer_out.lines().last().unwrap_or_default());
    assert!(
        viewer_out.lines().any(|l| l.starts_with("final: frame ")),
        "the observer's viewer never replicated the scene:\n{viewer_out}\n{}",
        String::from_utf8_lossy(&viewer.stderr)
    );
    assert!(
        recorder.status.success(),
        "{}",
        String::from_utf8_lossy(&recorder.stderr)
    );
    let wire = survey(&file).unwrap();
    println!("recorder: {:?}", wire.topic_counts);
    for id in ["left", "right"] {
        let poses = wire
            .topic_counts
            .get(&format!("sinew/pad/device/{id}/pose"))
            .copied()
            .unwrap_or(0);
        assert!(poses > 1000, "{id}: {poses} poses recorded in 3 s");
        let key = format!("sinew/pad/presence/haptic/{id}");
        assert!(
            wire.presence
                .iter()
                .any(|(_, k, joined)| *k == key && *joined),
            "{key} never recorded as joined"
        );
    }

    for (id, output) in [("left", &left), ("right", &right)] {
        let forces = forces_over_time(output, id);
        let last = String::from_utf8_lossy(&output.stdout)
            .lines()
            .rfind(|l| l.starts_with("final:"))
            .unwrap_or_default()
            .to_owned();
        println!("{id}: forces each second {forces:.2?}\n{last}");
        assert!(last.contains(": moderated "), "{id} not moderated: {last}");
        assert!(
            status_number(&last, "rtt p50 ").unwrap_or(0.0) >= 50_000.0,
            "{id}'s round trip below the path's 50 ms: {last}"
        );
        // Pressing before the server's kill (status lines 4-8 s), faded with it gone, back before the
        // router's kill, faded with the router gone, and back at the end.
        let felt = |range: std::ops::Range<usize>| forces[range].iter().any(|f| *f > 0.3);
        let faded = |range: std::ops::Range<usize>| forces[range].iter().any(|f| *f < 0.05);
        assert!(forces.len() >= 30, "{id}: {} status lines", forces.len());
        assert!(felt(3..10), "{id} never felt the pad: {forces:?}");
        assert!(
            faded(10..16),
            "{id}'s force did not fade with the server gone: {forces:?}"
        );
        assert!(felt(14..22), "{id} never felt the new server: {forces:?}");
        assert!(
            faded(20..26),
            "{id}'s force did not fade with the router gone: {forces:?}"
        );
        assert!(
            felt(25..forces.len()),
            "{id} never felt the pad after the router's restart: {forces:?}"
        );
    }
    let (lost, forwarded) = relay_loss(&relay);
    println!("relay: lost {lost} of {} frames", lost + forwarded);
    assert!(lost > 0, "the path lost nothing: {relay}");
    let _ = std::fs::remove_dir_all(&dir);
}
