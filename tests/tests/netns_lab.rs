//! The namespace lab end to end: a path of 20 ms each way with 5% loss between a server namespace and a
//! device namespace carries ping (RTT about 40 ms) and a real `sinew-server` + `hapticserver` session (forces
//! arrive, round trip >= 40 ms), and every namespace is gone afterwards, also when a test panics.
//!
//! Ignored (with the reason) where the build could not see root and a working `ip netns` (`tests/build.rs` sets
//! `cfg(netns_lab)`); where it could, a lab that then fails to start fails the test. Needs the workspace binaries
//! (`cargo test --workspace --release` builds them) and `ping` (iputils-ping) for the ping part.

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::process::Command;
use std::time::Duration;

use hapticserver::Trace;
use sinew_testkit::harness::serial;
use sinew_testkit::lab_run::{
    assert_namespaces_gone, expect_final_line, relay_loss, require_lab, shipped_world,
    start_lab_server, status_number,
};
use sinew_testkit::netem::ScriptedDrop;
use sinew_testkit::netns::{LabConfig, NetnsLab, Side, role_binary, wait_output};

fn ping_rtts_ms(output: &str) -> Vec<f64> {
    output
        .lines()
        .filter_map(|line| line.split("time=").nth(1))
        .filter_map(|rest| rest.split_whitespace().next()?.parse().ok())
        .collect()
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn a_lossy_40_ms_path_carries_ping_and_a_haptic_session_then_vanishes() {
    // One scenario at a time: each runs 1 kHz loops and a relay on two shared cores.
    let _serial = serial();
    require_lab();
    let server_bin = role_binary("sinew-server").unwrap();
    let haptic_bin = role_binary("hapticserver").unwrap();
    let world = shipped_world("pad");
    let mut lab = NetnsLab::new(LabConfig::symmetric(20.0, 0.0, 0.05, 42)).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let server_ip = lab.server_ip().to_string();

    // ping from the device side to the server side (ARP crosses the relay first).
    let has_ping = Command::new("ping").arg("-V").output().is_ok();
    if has_ping {
        let mut ping = Command::new("ping");
        ping.args(["-n", "-c", "20", "-i", "0.05", "-W", "2", &server_ip]);
        let output = wait_output(
            lab.spawn_in_device_ns(&ping).unwrap(),
            Duration::from_secs(30),
        )
        .unwrap();
        let text = String::from_utf8_lossy(&output.stdout);
        let mut rtts = ping_rtts_ms(&text);
        println!(
            "ping: {} of 20 replies, RTT median {:.1} ms\n{text}",
            rtts.len(),
            if rtts.is_empty() {
                f64::NAN
            } else {
                median(&mut rtts.clone())
            }
        );
        assert!(rtts.len() >= 10, "too few ping replies: {text}");
        let rtt = median(&mut rtts);
        assert!(
            (35.0..70.0).contains(&rtt),
            "ping median RTT {rtt} ms, expected about 40"
        );
    } else {
        println!("SKIP the ping part: no `ping` here (install iputils-ping)");
    }

    // The real roles across the path.
    let listen = format!("tcp/{server_ip}:7447");
    let mut server = Command::new(&server_bin);
    server
        .arg("--world")
        .arg(&world)
        .args(["--listen", &listen, "--duration-s", "9"]);
    let server = lab.spawn_in_server_ns(&server).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let mut haptic = Command::new(&haptic_bin);
    haptic.args([
        "--id",
        "left",
        "--script",
        "press",
        "--connect",
        &listen,
        "--duration-s",
        "6",
    ]);
    let haptic = lab.spawn_in_device_ns(&haptic).unwrap();
    let haptic = wait_output(haptic, Duration::from_secs(30)).unwrap();
    let server = wait_output(server, Duration::from_secs(30)).unwrap();
    let haptic_out = String::from_utf8_lossy(&haptic.stdout);
    let final_line = haptic_out
        .lines()
        .find(|l| l.starts_with("final:"))
        .unwrap_or_else(|| {
            panic!(
                "no `final:` line from hapticserver ({}):\n{haptic_out}\n{}\nserver:\n{}",
                haptic.status,
                String::from_utf8_lossy(&haptic.stderr),
                String::from_utf8_lossy(&server.stdout)
            )
        });
    println!("{final_line}");
    let forces = status_number(final_line, "forces_rx ").unwrap();
    let rtt_p50_us = status_number(final_line, "rtt p50 ").unwrap();
    assert!(forces > 0.0, "no force arrived: {final_line}");
    assert!(
        rtt_p50_us >= 40_000.0,
        "round trip p50 {rtt_p50_us} us is below the path's 40 ms: {final_line}"
    );

    let report = lab.stop_relay().unwrap();
    println!("{report}");
    let (lost, forwarded) = relay_loss(&report);
    let rate = lost as f64 / (lost + forwarded).max(1) as f64;
    assert!(
        forwarded > 1000 && (0.02..0.09).contains(&rate),
        "relay lost {lost} of {} frames ({rate:.3}), expected about 5%",
        lost + forwarded
    );
    drop(lab);
    assert_namespaces_gone(&namespaces);
}

#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn namespaces_are_removed_even_when_the_test_panics() {
    // One scenario at a time: each runs 1 kHz loops and a relay on two shared cores.
    let _serial = serial();
    require_lab();
    let mut names = Vec::new();
    let mut child = None;
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let mut lab = NetnsLab::new(LabConfig::symmetric(1.0, 0.0, 0.0, 1)).unwrap();
        names = lab.namespaces().into_iter().map(str::to_owned).collect();
        let mut sleeper = Command::new("sleep");
        sleeper.arg("600");
        child = Some(lab.spawn_in_server_ns(&sleeper).unwrap());
        panic!("on purpose, with a child running in the lab");
    }));
    assert!(outcome.is_err());
    let ended = wait_output(child.unwrap(), Duration::from_secs(5))
        .expect("the lab's drop ends the children it started");
    assert!(!ended.status.success(), "{}", ended.status);
    assert_eq!(names.len(), 3);
    assert_namespaces_gone(&names);
}

fn magnitude(f: [f32; 3]) -> f32 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

/// Latency-moderated mode through the real network stack: the server in one namespace, a hapticserver in
/// another, 50 ms +-10 ms each way with 5% loss on the bridge between them, the devices on their default
/// multilink (poses and forces over UDP). The nominal hand presses and holds: it holds still, no silence
/// reaches the device's 50 ms rule while the server lives, and after a kill -9 of the server the force ramps to
/// zero through the silence rule and stays there (no stale model is rendered).
#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn moderated_mode_through_a_lossy_100_ms_path_holds_still_and_zeroes_for_good_when_the_server_dies()
{
    // One scenario at a time: each runs 1 kHz loops and a relay on two shared cores.
    let _serial = serial();
    require_lab();
    let haptic_bin = role_binary("hapticserver").unwrap();
    let mut lab = NetnsLab::new(LabConfig::symmetric(50.0, 10.0, 0.05, 7)).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let csv_path =
        std::env::temp_dir().join(format!("sinew-netns-moderated-{}.csv", std::process::id()));
    let (mut server, tcp, udp) = start_lab_pad_server(&mut lab);
    let mut haptic = Command::new(&haptic_bin);
    haptic
        .args(["--id", "left", "--script", "press", "--depth-mm", "10"])
        .args(["--hand", "nominal", "--mode", "moderated"])
        .args(["--connect", &tcp, "--connect", &udp, "--duration-s", "10"])
        .arg("--trace-csv")
        .arg(&csv_path);
    let haptic = lab.spawn_in_device_ns(&haptic).unwrap();
    // Joined, pressed (1 s) and held for a while, then the server dies mid-contact.
    std::thread::sleep(Duration::from_millis(7000));
    server.kill().unwrap();
    let _ = server.wait();
    let haptic = wait_output(haptic, Duration::from_secs(40)).unwrap();
    // Kept when an assertion fails, for a look at the ticks.
    let csv = std::fs::read_to_string(&csv_path).unwrap_or_default();
    println!("device trace: {}", csv_path.display());
    let final_line = &expect_final_line(&haptic);
    println!("{final_line}");
    let report = lab.stop_relay().unwrap();
    println!("{report}");
    drop(lab);
    assert_namespaces_gone(&namespaces);

    assert!(
        final_line.contains(": moderated "),
        "not in moderated mode: {final_line}"
    );
    assert_eq!(
        status_number(final_line, "rejects "),
        Some(0.0),
        "{final_line}"
    );
    assert!(
        status_number(final_line, "rtt p50 ").unwrap() >= 100_000.0,
        "round trip below the path's 100 ms: {final_line}"
    );
    // One silence, the kill's: none while the server lived, through 5% loss.
    assert_eq!(
        status_number(final_line, "stale "),
        Some(1.0),
        "silences other than the kill's reached the device: {final_line}"
    );
    let rows = Trace::parse_csv(&csv).unwrap_or_default();
    assert!(rows.len() > 5000, "trace has {} ticks", rows.len());
    let first_contact = rows
        .iter()
        .position(|r| magnitude(r.force_n) > 0.3)
        .unwrap_or_else(|| panic!("never pressed: {final_line}"));
    let silence = first_contact
        + rows[first_contact..]
            .iter()
            .position(|r| r.stale)
            .expect("the kill never made the stream stale");
    let silence_t = rows[silence].t_s;
    // The hold: the 2 s that end 100 ms before the silence started.
    let hold: Vec<_> = rows
        .iter()
        .filter(|r| r.t_s >= silence_t - 2.15 && r.t_s < silence_t - 0.15)
        .collect();
    // The device logs the ticks it ran: a stalled machine skips periods (counted as overruns), so the hold is
    // judged on the ticks there are, as long as they cover the 2 s from end to end (a CI run on a loaded
    // machine logged 1,143 of 2,000 with 1,680 overruns in the run).
    assert!(
        hold.len() > 500,
        "only {} ticks of hold: {final_line}",
        hold.len()
    );
    let hold_start_s = hold.first().unwrap().t_s - (silence_t - 2.15);
    let hold_end_s = (silence_t - 0.15) - hold.last().unwrap().t_s;
    assert!(
        hold_start_s < 0.1 && hold_end_s < 0.1,
        "the hold's ticks leave {hold_start_s:.3} s uncovered at its start and {hold_end_s:.3} s at its end"
    );
    let p2p = (0..3)
        .map(|axis| {
            let (lo, hi) = hold.iter().fold((f32::MAX, f32::MIN), |(lo, hi), r| {
                (lo.min(r.force_n[axis]), hi.max(r.force_n[axis]))
            });
            hi - lo
        })
        .fold(0.0f32, f32::max);
    let mean = hold.iter().map(|r| magnitude(r.force_n)).sum::<f32>() / hold.len() as f32;
    println!("hold: {mean:.2} N, peak-to-peak {p2p:.4} N");
    assert!(mean > 0.3, "not pressing while holding: {mean:.3} N");
    assert!(p2p < 0.1, "force peak-to-peak {p2p:.4} N while holding");
    // After the silence: zero within the rule's 20 ms ramp (70 ms allowed), and zero for good.
    let zero = silence
        + rows[silence..]
            .iter()
            .position(|r| magnitude(r.force_n) == 0.0)
            .expect("the force never reached zero after the kill");
    let ramp_ms = (rows[zero].t_s - silence_t) * 1e3;
    assert!(
        ramp_ms <= 70.0,
        "zero {ramp_ms:.1} ms after the silence began"
    );
    if let Some(r) = rows[zero..].iter().find(|r| magnitude(r.force_n) != 0.0) {
        panic!(
            "{:.3} s: {:?} N rendered after the force had reached zero",
            r.t_s, r.force_n
        );
    }
    assert!(rows.len() - zero > 1000, "too little trace after the kill");
    let (lost, forwarded) = relay_loss(&report);
    let rate = lost as f64 / (lost + forwarded).max(1) as f64;
    assert!(
        forwarded > 2000 && (0.02..0.09).contains(&rate),
        "relay lost {lost} of {} frames ({rate:.3}), expected about 5%",
        lost + forwarded
    );
    let _ = std::fs::remove_file(&csv_path);
}

/// `sinew-server` on worlds/pad.toml in the lab's server namespace ([`start_lab_server`]).
fn start_lab_pad_server(lab: &mut NetnsLab) -> (std::process::Child, String, String) {
    start_lab_server(lab, &shipped_world("pad"), &[]).unwrap()
}

/// Wait for `child` to exit, up to `limit`; how long it took (None: still running, then killed).
fn exit_time(child: &mut std::process::Child, limit: Duration) -> Option<Duration> {
    let start = std::time::Instant::now();
    while start.elapsed() < limit {
        if child.try_wait().ok().flatten().is_some() {
            return Some(start.elapsed());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    None
}

#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn every_role_exits_promptly_on_sigterm_during_a_partition_the_device_at_zero_force_first() {
    // One scenario at a time: each runs 1 kHz loops and a relay on two shared cores.
    let _serial = serial();
    require_lab();
    let haptic_bin = role_binary("hapticserver").unwrap();
    let viewer_bin = role_binary("sinew-viewer").unwrap();
    let mut lab = NetnsLab::new(LabConfig::symmetric(1.0, 0.0, 0.0, 11)).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let (mut server, tcp, udp) = start_lab_pad_server(&mut lab);
    let mut haptic = Command::new(&haptic_bin);
    haptic
        .args(["--id", "left", "--script", "press", "--depth-mm", "6"])
        .args(["--connect", &tcp, "--connect", &udp]);
    let mut haptic = lab.spawn_in_device_ns(&haptic).unwrap();
    let mut viewer = Command::new(&viewer_bin);
    viewer.args(["--headless", "--connect", &tcp]);
    let mut viewer = lab.spawn_in_device_ns(&viewer).unwrap();
    // Joined (the UDP link takes about 2 s) and pressing; then the network is cut, and stays cut.
    std::thread::sleep(Duration::from_millis(5000));
    lab.cut(Side::Device).unwrap();
    std::thread::sleep(Duration::from_millis(2000));
    let term = |child: &std::process::Child| {
        Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
    };
    let limit = Duration::from_secs(5);
    term(&haptic);
    let haptic_exit = exit_time(&mut haptic, limit);
    term(&server);
    let server_exit = exit_time(&mut server, limit);
    term(&viewer);
    let viewer_exit = exit_time(&mut viewer, limit);
    let output = |child: std::process::Child| wait_output(child, Duration::from_secs(5)).unwrap();
    let (haptic, server, viewer) = (output(haptic), output(server), output(viewer));
    let haptic_out = String::from_utf8_lossy(&haptic.stdout).into_owned();
    let haptic_err = String::from_utf8_lossy(&haptic.stderr).into_owned();
    println!(
        "exit after SIGTERM during a partition: hapticserver {haptic_exit:?}, server {server_exit:?}, viewer {viewer_exit:?}"
    );
    drop(lab);
    assert_namespaces_gone(&namespaces);
    // The old behaviour: the hapticserver hung 10 s on zenoh's close and exited 1; the server ran 15 s on.
    for (role, exit) in [
        ("hapticserver", haptic_exit),
        ("sinew-server", server_exit),
        ("sinew-viewer", viewer_exit),
    ] {
        assert!(
            exit.is_some_and(|t| t < Duration::from_secs(3)),
            "{role} did not exit promptly: {exit:?}\nhapticserver:\n{haptic_out}\n{haptic_err}"
        );
    }
    assert!(haptic.status.success(), "{}\n{haptic_err}", haptic.status);
    assert!(server.status.success(), "{}", server.status);
    assert!(viewer.status.success(), "{}", viewer.status);
    let final_line = haptic_out
        .lines()
        .find(|l| l.starts_with("final:"))
        .unwrap_or_else(|| panic!("no final line:\n{haptic_out}\n{haptic_err}"));
    // The force was at zero before the goodbyes: the silence rule had ramped it, and the stop wrote zero.
    assert!(final_line.contains("force 0.00 N"), "{final_line}");
    // Logged to stdout.
    assert!(
        haptic_out.contains("server lost"),
        "the device said it lost the server: {haptic_out}"
    );
}

/// The multi-site layout: `sinew-server --zenoh-mode router` on one "machine", devices on another, every link
/// mutual TLS with certificates from `sinew certs`, across a 10 ms path. The device with its own certificate
/// presses the pad and feels it; a device holding the observer's certificate is refused, and the server's
/// status line counts the refusals.
#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn a_router_server_and_a_device_in_two_namespaces_work_over_mutual_tls_and_refuse_an_observers_pose()
 {
    let _serial = serial();
    require_lab();
    let server_bin = role_binary("sinew-server").unwrap();
    let haptic_bin = role_binary("hapticserver").unwrap();
    let world = shipped_world("pad");
    let mut lab = NetnsLab::new(LabConfig::symmetric(10.0, 0.0, 0.0, 7)).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let server_ip = lab.server_ip().to_string();
    let certs_dir = std::env::temp_dir().join(format!("sinew-router-certs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&certs_dir);
    // The server's lab address goes into every certificate: the devices check the name they dialled.
    let certs = sinew::certs::make_lab_certs(
        &certs_dir,
        "pad",
        &["left".into()],
        std::slice::from_ref(&server_ip),
    )
    .unwrap();
    let tls_args = |role: &str| -> Vec<String> {
        let files = certs.role(role).unwrap();
        vec![
            "--tls-ca".into(),
            files.ca.display().to_string(),
            "--tls-cert".into(),
            files.cert.display().to_string(),
            "--tls-key".into(),
            files.key.display().to_string(),
        ]
    };

    let listen = format!("quic/{server_ip}:7447");
    let mut server = Command::new(&server_bin);
    server
        .arg("--world")
        .arg(&world)
        .args([
            "--zenoh-mode",
            "router",
            "--listen",
            &listen,
            "--duration-s",
            "10",
        ])
        .args(tls_args("server"));
    let server = lab.spawn_in_server_ns(&server).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let device = |id: &str, role: &str| {
        let mut haptic = Command::new(&haptic_bin);
        haptic
            .args([
                "--id",
                id,
                "--script",
                "press",
                "--connect",
                &listen,
                "--duration-s",
                "6",
            ])
            .args(tls_args(role));
        haptic
    };
    let left = lab
        .spawn_in_device_ns(&device("left", "device-left"))
        .unwrap();
    let intruder = lab
        .spawn_in_device_ns(&device("right", "observer"))
        .unwrap();
    let left = wait_output(left, Duration::from_secs(30)).unwrap();
    let intruder = wait_output(intruder, Duration::from_secs(30)).unwrap();
    let server = wait_output(server, Duration::from_secs(30)).unwrap();
    let server_out = String::from_utf8_lossy(&server.stdout);
    let final_of = |output: &std::process::Output| -> String {
        let text = String::from_utf8_lossy(&output.stdout);
        text.lines()
            .find(|l| l.starts_with("final:"))
            .map(str::to_owned)
            .unwrap_or_else(|| {
                panic!(
                    "no `final:` line ({}):\n{text}\n{}\nserver:\n{server_out}\n{}",
                    output.status,
                    String::from_utf8_lossy(&output.stderr),
                    String::from_utf8_lossy(&server.stderr)
                )
            })
    };
    let left_final = final_of(&left);
    let intruder_final = final_of(&intruder);
    println!("left: {left_final}\nintruder: {intruder_final}");
    // Each release of left's tool: one is the device's own exit at 6 s; any more is a transport that dropped
    // and rejoined (zenoh's old tls/ link did this now and then; QUIC has not yet). Counted, not asserted.
    println!(
        "left's tool was released {} times (1 = its exit)",
        server_out.matches("device left: tool released").count()
    );
    // 20 ms round trip: left renders the server's local models (moderated), sent at their own rate.
    assert!(
        status_number(&left_final, "forces_rx ").unwrap() > 300.0,
        "{left_final}"
    );
    assert!(
        server_out.lines().any(|l| l.contains("left:on")),
        "left never drove its tool:\n{server_out}"
    );
    // The intruder hears the server (reading is allowed) but never drives: its poses were refused.
    assert_eq!(
        status_number(&intruder_final, "forces_rx ").unwrap(),
        0.0,
        "{intruder_final}"
    );
    let last_status = server_out
        .lines()
        .rfind(|l| l.contains("rejected "))
        .unwrap_or_else(|| panic!("no status line from the server:\n{server_out}"));
    println!("server: {last_status}");
    assert!(
        status_number(last_status, "rejected ").unwrap() > 1000.0,
        "the intruder's poses were not refused: {last_status}"
    );
    drop(lab);
    assert_namespaces_gone(&namespaces);
    let _ = std::fs::remove_dir_all(&certs_dir);
}

/// A UDP link left half open: the device's first UDP handshake is lost (so its TCP link makes the
/// transport), and on its retry the server's last reply (its second UDP frame) is lost too, so the server adds
/// a UDP link to the transport that the device never gets, and sends its best-effort forces down it. With
/// zenoh's default link lease the device heard nothing for 10 s (through a lossy path this happened about once
/// in twenty starts); with the device's lease (`DEVICE_LINK_LEASE`, 3 s) the server lets the dead link go,
/// forces come over TCP, and the device's next try opens a UDP link its poses take.
#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn a_udp_link_left_half_open_leaves_the_device_deaf_no_longer_than_its_lease() {
    // One scenario at a time: each runs 1 kHz loops and a relay on two shared cores.
    let _serial = serial();
    require_lab();
    let haptic_bin = role_binary("hapticserver").unwrap();
    let mut config = LabConfig::symmetric(20.0, 0.0, 0.0, 5);
    let scripted = |spec: &str| -> ScriptedDrop { spec.parse().unwrap() };
    config.drops_to_server = vec![scripted("udp:1")];
    config.drops_to_device = vec![scripted("udp:2")];
    let mut lab = NetnsLab::new(config).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let (mut server, tcp, udp) = start_lab_pad_server(&mut lab);
    let mut haptic = Command::new(&haptic_bin);
    haptic
        .args(["--id", "left", "--script", "press", "--depth-mm", "10"])
        .args(["--hand", "nominal", "--mode", "moderated"])
        .args(["--connect", &tcp, "--connect", &udp, "--duration-s", "4"]);
    let haptic = lab.spawn_in_device_ns(&haptic).unwrap();
    let haptic = wait_output(haptic, Duration::from_secs(30)).unwrap();
    server.kill().unwrap();
    let _ = server.wait();
    let final_line = &expect_final_line(&haptic);
    println!("{final_line}");
    let report = lab.stop_relay().unwrap();
    println!("{report}");
    drop(lab);
    assert_namespaces_gone(&namespaces);

    let direction = |name: &str| {
        report
            .lines()
            .find(|l| l.starts_with(name))
            .unwrap_or_else(|| panic!("no `{name}` line in the relay's report:\n{report}"))
    };
    let (to_device, to_server) = (direction("tosrv->todev"), direction("todev->tosrv"));
    for line in [to_device, to_server] {
        assert_eq!(
            status_number(line, " lost "),
            Some(1.0),
            "the scripted drop: {line}"
        );
    }
    assert_eq!(
        status_number(final_line, "rejects "),
        Some(0.0),
        "{final_line}"
    );
    assert!(
        status_number(final_line, "forces_rx ").unwrap() > 300.0,
        "the device was deaf: {final_line}"
    );
    let udp_frames: u64 = to_server
        .split(" udp ")
        .nth(1)
        .and_then(|rest| rest.split(')').next()?.parse().ok())
        .unwrap_or_else(|| panic!("no UDP count in {to_server}"));
    assert!(
        udp_frames > 1000,
        "the device's poses never took a UDP link: {to_server}"
    );
}
