//! Fault drills: kill -9 of a client role's process, over real zenoh on loopback (issue "Safe under faults";
//! the server's own kill -9 is `server_kill.rs`). The killed process says no goodbye: its sockets are closed by
//! the kernel and its liveliness token dies with them. The server in this process is the witness.
//!
//! - A hapticserver killed mid-contact: its tool is released, the tissue relaxes, nothing keeps its id (a new
//!   hapticserver with the same id takes it and presses), and the other surgeon is not disturbed.
//! - A viewer killed while replicating: nothing else notices. The server ticks and publishes on, the pressing
//!   device sees no silence, another viewer stays within its error bound, and a new viewer joins.
//!
//! Every wait has a timeout; the child processes are killed when the test ends, however it ends.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use hapticserver::HandScript;
use sinew_protocol::network::with_udp_twin;
use sinew_testkit::harness::{
    KillOnDrop, Pacing, deepest_dent_mm, replica_error, serial, start_pad_server, start_sim_device,
    start_viewer, surgeon_scripts, wait_until,
};
use sinew_testkit::netns::role_binary;

fn connect_args(endpoint: &str) -> Vec<String> {
    with_udp_twin(endpoint)
        .into_iter()
        .flat_map(|e| ["--connect".to_owned(), e])
        .collect()
}

fn spawn_role(binary: &str, args: &[&str], endpoint: &str) -> KillOnDrop {
    let child = Command::new(role_binary(binary).unwrap())
        .args(args)
        .args(connect_args(endpoint))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("starting {binary}: {e}"));
    KillOnDrop(child)
}

/// A hapticserver process for device `left` pressing 6 mm into the pad (its probe's centre 2 mm below the
/// surface).
fn pressing_left(endpoint: &str) -> KillOnDrop {
    spawn_role(
        "hapticserver",
        &["--id", "left", "--script", "press", "--depth-mm", "6"],
        endpoint,
    )
}

#[test]
fn a_hapticserver_process_killed_by_sigkill_mid_contact_frees_its_tool_and_id_and_the_tissue_relaxes()
 {
    let _serial = serial();
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    // The other surgeon holds its probe in the pad on the right, in this process.
    let right = start_sim_device(
        "pad",
        "right",
        HandScript::Hold {
            position_mm: [0.0, 0.0, -5.0],
        },
        &endpoint,
        Pacing::Sleep,
    )
    .unwrap();
    let mut left = pressing_left(&endpoint);
    assert!(
        wait_until(Duration::from_secs(15), || {
            let stats = server.stats();
            stats.devices[0].active && stats.devices[1].active && deepest_dent_mm(&server) > 2.0
        }),
        "both devices press: {:?}",
        server.stats().devices
    );
    let right_stale_before = right.report().safety.stale_events;

    let killed = Instant::now();
    left.0.kill().expect("SIGKILL to the hapticserver");
    let _ = left.0.wait();
    assert!(
        wait_until(Duration::from_secs(5), || !server.stats().devices[0].active),
        "the server still drives the killed device's tool: {:?}",
        server.stats().devices[0]
    );
    let released_ms = killed.elapsed().as_secs_f64() * 1e3;
    // The left dent relaxes; the right probe keeps its own.
    let left_dent_mm = || left_side_dent_mm(&server);
    assert!(
        wait_until(Duration::from_secs(5), || left_dent_mm() < 0.1),
        "the left of the pad is still dented {} mm",
        left_dent_mm()
    );
    let relaxed_ms = killed.elapsed().as_secs_f64() * 1e3;
    assert!(server.stats().devices[1].active);
    assert_eq!(
        right.report().safety.stale_events,
        right_stale_before,
        "the other surgeon's force stream went silent"
    );
    assert!(right.report().last_rendered_force_magnitude_n() > 0.3);
    println!(
        "hapticserver SIGKILL: tool released after {released_ms:.0} ms, left of the pad relaxed after \
         {relaxed_ms:.0} ms"
    );

    // Nothing keeps the id: a new hapticserver for `left` takes it and presses. (Until the dead instance's
    // liveliness token is gone the id is still claimed, and the newcomer's first poses are refused as a
    // duplicate's; that lasts a fraction of a second, then the claim goes with the token.)
    let restarted = Instant::now();
    let _again = pressing_left(&endpoint);
    assert!(
        wait_until(Duration::from_secs(15), || server.stats().devices[0].active
            && left_dent_mm() > 2.0),
        "a new device for `left` did not take the tool: {:?}",
        server.stats().devices[0]
    );
    let stats = server.stats();
    println!(
        "a new hapticserver for `left` pressed {:.0} ms after its start ({} of its poses refused while the \
         dead instance's claim lasted)",
        restarted.elapsed().as_secs_f64() * 1e3,
        stats.rejected.duplicate_device
    );
    assert_ne!(stats.devices[0].holder_instance, 0);
    assert!(
        stats.rejected.duplicate_device < 5000,
        "the dead instance kept the id for {} poses",
        stats.rejected.duplicate_device
    );
}

/// Deepest point of the pad's left half below its rest plane, mm (the left probe works at x = -18 mm, the
/// right one at +18 mm).
fn left_side_dent_mm(server: &sinew_server::node::ServerHandle) -> f32 {
    server
        .latest_positions(0)
        .unwrap_or_default()
        .iter()
        .filter(|p| p[0] < 0.0)
        .fold(0.0f32, |deepest, p| deepest.max(-p[2]))
}

#[test]
fn a_viewer_process_killed_by_sigkill_disturbs_nothing_and_a_new_viewer_joins() {
    let _serial = serial();
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    // The demo's stroking surgeon keeps the tissue moving, so the server keeps publishing mesh deltas.
    let device =
        start_sim_device("pad", "left", surgeon_scripts().0, &endpoint, Pacing::Sleep).unwrap();
    let staying = start_viewer("pad", "staying", &endpoint).unwrap();
    assert!(staying.wait_for_snapshot(Duration::from_secs(10)));
    let served_before = server.stats().snapshots_served;
    let mut viewer = spawn_role("sinew-viewer", &["--headless", "--id", "doomed"], &endpoint);
    assert!(
        wait_until(Duration::from_secs(15), || server.stats().snapshots_served
            > served_before),
        "the viewer process never fetched its snapshot"
    );
    assert!(wait_until(Duration::from_secs(10), || device
        .report()
        .last_rendered_force_magnitude_n()
        > 0.3));
    let stale_before = device.report().safety.stale_events;
    let ticks_before = server.stats().ticks;
    let deltas_before = server.stats().deltas_sent;

    viewer.0.kill().expect("SIGKILL to the viewer");
    let _ = viewer.0.wait();
    std::thread::sleep(Duration::from_secs(2));
    let stats = server.stats();
    assert!(
        stats.ticks > ticks_before + 1000,
        "the server stopped ticking"
    );
    assert!(
        stats.deltas_sent > deltas_before + 60,
        "the server stopped publishing"
    );
    assert_eq!(
        device.report().safety.stale_events,
        stale_before,
        "the device's force stream went silent when a viewer died"
    );
    assert!(device.report().last_rendered_force_magnitude_n() > 0.3);
    let error = replica_error(&server, &staying, 0, Duration::from_secs(5))
        .expect("the staying viewer still replicates");
    assert!(
        error.max_error_mm <= error.bound_mm * 1.001 + 1e-6,
        "{error:?}"
    );

    // A new viewer process joins as usual.
    let served_after_kill = server.stats().snapshots_served;
    let _new = spawn_role("sinew-viewer", &["--headless", "--id", "fresh"], &endpoint);
    assert!(
        wait_until(Duration::from_secs(15), || server.stats().snapshots_served
            > served_after_kill),
        "a new viewer process did not join after the kill"
    );
}
