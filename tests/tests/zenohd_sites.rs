//! A lab's `zenohd` across a real, distant path (issue 34): the router and the server in the hub's namespace,
//! the surgeons' site in another, the lab's relay between them adding 25 ms +-5 ms each way and 2% loss. Every
//! role is a client of the router over mutual TLS on QUIC with the certificates `sinew certs` issues and the
//! router file it writes; the hapticservers render in latency-moderated mode.
//!
//! Checked: both surgeons press and feel the pad at the far site; a headless viewer and `sinew-recorder` with
//! the observer's certificate, at the surgeons' site, replicate the scene and record both surgeons' poses and
//! presence; the server killed and a new one started leaves the router and the hands running, their forces
//! fade to zero and come back; the router killed and started again, likewise; the new server (access rules
//! on, behind the router) prints no warning.
//!
//! Then two surgeons at two sites: the lab's second site has its own path to the hub (50 ms each way on each,
//! no loss), one surgeon at each, in the tug of war. Each grasps the sheet and pulls; each feels the other's
//! pull through the tissue, rendered by the local model (the devices pick moderated for themselves), with no
//! silence while the scripts run. With 1% loss on each path the same run saw silences (docs/sites.md): not
//! yet solved, so not asserted here.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::process::{Child, Command};
use std::time::{Duration, Instant};

use sinew_server::recording::survey;
use sinew_server::world::load_world;
use sinew_testkit::fidelity::{TUG_RUN_S, peak_and_rms, tug_felt_n, tug_scripts};
use sinew_testkit::harness::serial;
use sinew_testkit::lab_run::{
    assert_namespaces_gone, expect_final_line, grasp_pull_args, read_trace, relay_loss,
    require_lab, shipped_world, status_number, to_script_time,
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
    let namespace = lab.namespace(Side::Server).unwrap().to_owned();
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
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
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
    // A server with access rules behind the router prints no warning (zenoh's note on the QUIC socket's
    // interfaces is left out of the log: access_refusals::QUIET_ACCESS_CONTROL_WARNING).
    let server_err = String::from_utf8_lossy(&server.stderr);
    // The late-tick warning says the machine stalled, not that the site is set up wrong: it is printed, and
    // left out of the check (a run with CPU hogs on the 2 cores skipped 488 of 10,088 periods).
    let (late, warnings): (Vec<String>, Vec<String>) = server_out
        .lines()
        .chain(server_err.lines())
        .filter(|l| l.contains("WARN") || l.contains("ERROR"))
        .map(|l| l.chars().take(200).collect::<String>())
        .partition(|l| l.contains("ticks ran late"));
    for line in &late {
        println!("the second server, on this machine's load: {line}");
    }
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
    assert!(
        warnings.is_empty(),
        "the second server warned:\n{}",
        warnings.join("\n")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// How long after its process started each scripted hand begins its script, s (the sessions join meanwhile).
const TUG_START_DELAY_S: f64 = 3.5;

/// What connects the two sites at the hub.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Hub {
    /// The lab's `zenohd`; the server and both devices its clients.
    Zenohd,
    /// The server itself is the router (`--zenoh-mode router`), the devices its peers.
    ServerAsRouter,
}

/// One two-site tug of war: per device (left, right), its closing status line and its trace in script time,
/// and the relays' report.
struct TwoSiteTug {
    finals: Vec<String>,
    traces: Vec<Vec<hapticserver::TraceSample>>,
    relay: String,
    /// The server's warnings and lateness reports.
    server_notes: Vec<String>,
}

/// The tug of war with left at the lab's first site and right at its second, each path 50 ms each way with
/// `loss`, over mutual TLS on QUIC, joined at the hub by `hub`.
fn run_two_site_tug(loss: f64, hub: Hub) -> TwoSiteTug {
    let world_path = shipped_world("tug_of_war");
    let world = load_world(&world_path).unwrap();
    let (left_script, right_script) = tug_scripts(&world);
    let mut lab =
        NetnsLab::new(LabConfig::symmetric(50.0, 0.0, loss, 13).with_second_site()).unwrap();
    let namespaces: Vec<String> = lab.namespaces().into_iter().map(str::to_owned).collect();
    let hub_for = [
        lab.server_ip().to_string(),
        lab.server_ip_for_second_site().to_string(),
    ];
    let dir = std::env::temp_dir().join(format!("sinew-two-sites-{hub:?}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let certs = sinew::certs::make_lab_certs(
        &dir,
        &world.scene,
        &["left".into(), "right".into()],
        &hub_for,
    )
    .unwrap();
    let listen = format!("quic/0.0.0.0:{ROUTER_PORT}");
    let router_config =
        sinew::certs::write_router_config(&dir, std::slice::from_ref(&listen)).unwrap();
    let role = |name: &str| tls_args(certs.role(name).unwrap());
    let hub_at = |hub_ip: &str| format!("quic/{hub_ip}:{ROUTER_PORT}");
    let client: &[&str] = match hub {
        Hub::Zenohd => &["--zenoh-mode", "client"],
        Hub::ServerAsRouter => &[],
    };

    let mut zenohd = (hub == Hub::Zenohd).then(|| start_router(&mut lab, &router_config));
    let mut server = Command::new(role_binary("sinew-server").unwrap());
    server.arg("--world").arg(&world_path).args(role("server"));
    match hub {
        Hub::Zenohd => server
            .args(client)
            .args(["--connect", &hub_at(&hub_for[0])]),
        Hub::ServerAsRouter => server.args(["--zenoh-mode", "router", "--listen", &listen]),
    };
    let mut server = lab.spawn_in(Side::Server, &server).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let run_s = TUG_START_DELAY_S + TUG_RUN_S + 0.3;
    let csv = |id: &str| dir.join(format!("{id}.csv"));
    let mut hands = Vec::new();
    for (id, script, side, hub_ip) in [
        ("left", &left_script, Side::Device, &hub_for[0]),
        ("right", &right_script, Side::SecondDevice, &hub_for[1]),
    ] {
        let mut haptic = Command::new(role_binary("hapticserver").unwrap());
        haptic
            .args(["--id", id, "--scene", &world.scene])
            .args(grasp_pull_args(script))
            .args(["--hand", "nominal", "--mode", "auto"])
            .args(client)
            .args(["--connect", &hub_at(hub_ip)])
            .args(role(&format!("device-{id}")))
            .args(["--start-delay-s", &TUG_START_DELAY_S.to_string()])
            .args(["--duration-s", &run_s.to_string()])
            .arg("--trace-csv")
            .arg(csv(id));
        hands.push(lab.spawn_in(side, &haptic).unwrap());
    }
    let mut finals = Vec::new();
    for hand in hands {
        let output = wait_output(hand, Duration::from_secs(60)).unwrap();
        let line = expect_final_line(&output);
        println!("{hub:?}, loss {loss}: {line}");
        finals.push(line);
    }
    server.kill().unwrap();
    // What the server said of its own lateness (a stall of the hub's machine is a silence at both sites).
    let server_notes = server
        .wait_with_output()
        .map(|o| {
            [o.stdout, o.stderr]
                .iter()
                .flat_map(|b| {
                    String::from_utf8_lossy(b)
                        .lines()
                        .map(str::to_owned)
                        .collect::<Vec<_>>()
                })
                .filter(|l| l.contains("late") || l.contains("WARN"))
                .collect::<Vec<_>>()
        })
        .unwrap_or_default();
    if let Some(zenohd) = zenohd.as_mut() {
        let _ = (zenohd.kill(), zenohd.wait());
    }
    let relay = lab.stop_relay().unwrap();
    drop(lab);
    assert_namespaces_gone(&namespaces);
    let traces = ["left", "right"]
        .map(|id| {
            let mut trace = read_trace(&csv(id)).unwrap();
            to_script_time(&mut trace).unwrap();
            trace
        })
        .to_vec();
    let _ = std::fs::remove_dir_all(&dir);
    TwoSiteTug {
        finals,
        traces,
        relay,
        server_notes,
    }
}

/// Silences that reach the device's 50 ms rule while the script runs, and the longest run of stale ticks, ms.
fn silences_during_the_run(trace: &[hapticserver::TraceSample]) -> (usize, f64) {
    let run: Vec<_> = trace
        .iter()
        .filter(|s| (0.0..TUG_RUN_S).contains(&s.t_s))
        .collect();
    let starts = run.windows(2).filter(|w| !w[0].stale && w[1].stale).count();
    let mut longest = 0usize;
    let mut current = 0usize;
    for sample in &run {
        current = if sample.stale { current + 1 } else { 0 };
        longest = longest.max(current);
    }
    (starts, longest as f64)
}

/// Where in script time each silence began, and the device loop's own longest pause between two ticks (a
/// stall of the machine the device runs on), for a failure's message.
fn silence_report(trace: &[hapticserver::TraceSample]) -> String {
    let starts: Vec<String> = trace
        .windows(2)
        .filter(|w| !w[0].stale && w[1].stale)
        .map(|w| format!("{:.3}", w[1].t_s))
        .collect();
    let (pause_s, at_s) = trace
        .windows(2)
        .map(|w| (w[1].t_s - w[0].t_s, w[1].t_s))
        .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a });
    format!(
        "silences begin at [{}] s; the device loop's longest pause {:.1} ms, ending at {at_s:.3} s",
        starts.join(", "),
        pause_s * 1000.0
    )
}

#[test]
#[cfg_attr(
    not(netns_lab),
    ignore = "needs root and iproute2 (`ip netns`), as CI has"
)]
fn through_zenohd_two_surgeons_at_two_sites_feel_each_others_pull() {
    let _serial = serial();
    require_lab();
    let tug = run_two_site_tug(0.0, Hub::Zenohd);
    let max_force_n = hapticserver::sim_device::sim_device_model().max_force_n;
    for line in &tug.finals {
        assert!(line.contains(": moderated "), "not moderated: {line}");
        let rtt_us = status_number(line, "rtt p50 ").unwrap();
        // 100 ms to the hub and back, the router and the server's tick on the way.
        assert!(
            (100_000.0..160_000.0).contains(&rtt_us),
            "round trip p50 {rtt_us} us: {line}"
        );
        for key in ["clamped ", "rejects "] {
            assert_eq!(status_number(line, key), Some(0.0), "{key}in {line}");
        }
    }
    let mut felt = Vec::new();
    for (id, trace) in ["left", "right"].iter().zip(&tug.traces) {
        let (peak, _) = peak_and_rms(trace);
        assert!(peak < max_force_n * 0.999, "{id}: {peak} N, at the clamp");
        let (silences, _) = silences_during_the_run(trace);
        println!("{id}: {}", silence_report(trace));
        assert_eq!(
            silences,
            0,
            "{id}: silences during the run: {}; the relays: {}; the server: {:?}",
            silence_report(trace),
            tug.relay,
            tug.server_notes
        );
        felt.push(tug_felt_n(trace));
    }
    println!(
        "through zenohd, two sites 100 ms from the hub: left feels the tug {:.4} N, right {:.4} N",
        felt[0], felt[1]
    );
    // As the tug of war at zero delay on one site (netns_tug_of_war.rs): left feels its own pull, right
    // feels left's through the sheet (about 0.06 N there).
    assert!(felt[0] > 0.5, "left felt no pull: {felt:?}");
    assert!(felt[1] > 0.03, "right did not feel left's pull: {felt:?}");
    let (lost, forwarded) = relay_loss(&tug.relay);
    println!("relays: lost {lost} of {} frames", lost + forwarded);
    assert!(
        forwarded > 5000 && tug.relay.matches("bridging").count() == 2,
        "{}",
        tug.relay
    );
}

/// A measurement, not a check (run it with `--ignored --nocapture`): the two-site tug at 1% loss on each path,
/// through `zenohd` and through the server as the router, the silences each device saw while the script ran.
#[test]
#[ignore = "a measurement for docs/sites.md: cargo test --release -p sinew-testkit --test zenohd_sites -- --ignored --nocapture"]
fn measure_silences_at_one_percent_loss_through_zenohd_and_through_the_server_as_router() {
    let _serial = serial();
    require_lab();
    for hub in [Hub::Zenohd, Hub::ServerAsRouter] {
        let tug = run_two_site_tug(0.01, hub);
        for (id, (trace, line)) in ["left", "right"]
            .iter()
            .zip(tug.traces.iter().zip(&tug.finals))
        {
            let (silences, longest_ms) = silences_during_the_run(trace);
            println!(
                "{hub:?} at 1% loss: {id} {silences} silences in {TUG_RUN_S} s, longest {longest_ms} ms stale; \
                 longest gap {:?} ms, rtt p99 {:?} us, felt {:.4} N",
                status_number(line, "longest gap "),
                status_number(line, "p99 "),
                tug_felt_n(trace)
            );
        }
        let (lost, forwarded) = relay_loss(&tug.relay);
        println!("{hub:?}: relays lost {lost} of {}", lost + forwarded);
    }
}
