//! Rejoin after a server restart, over real zenoh on loopback (issue "Safe under faults", item 7): a device and
//! a viewer connected to a server that stops; after 1.5 s (long enough for zenoh's retry to back off to its
//! longest period) a new server starts on the same endpoint. Both clients rejoin on their own: the device gets
//! forces from the new server and the viewer a snapshot of it. The times are printed (they are figures for
//! BENCHMARKS.md, not asserted: these machines are shared); the bounds here are generous functional ones.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::time::{Duration, Instant};

use hapticserver::HandScript;
use hapticserver::server_watch::Link;
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, start_server, start_sim_device,
    start_viewer, wait_until,
};

#[test]
fn a_device_and_a_viewer_rejoin_a_restarted_server_on_their_own() {
    let endpoint = free_loopback_endpoint().unwrap();
    let world = || load_shipped_world("pad.toml").unwrap();
    let mut first = start_server(world(), &endpoint, Pacing::Sleep).unwrap();
    let device = start_sim_device(
        "pad",
        "left",
        HandScript::Hold {
            position_mm: [0.0, 0.0, -4.0],
        },
        &endpoint,
        Pacing::Sleep,
    )
    .unwrap();
    let viewer = start_viewer("pad", "instructor", &endpoint).unwrap();
    assert!(viewer.wait_for_snapshot(Duration::from_secs(10)));
    assert!(wait_until(Duration::from_secs(10), || device
        .report()
        .last_rendered_force_magnitude_n()
        > 0.3));
    let first_instance = first.instance();

    let mut device_ms = Vec::new();
    let mut viewer_ms = Vec::new();
    for round in 0..3 {
        first.stop();
        assert!(
            wait_until(Duration::from_secs(5), || matches!(
                device.report().server_link,
                Link::Lost { .. }
            )),
            "the device notices: {}",
            device.report()
        );
        std::thread::sleep(Duration::from_millis(1500));
        let forces = device.report().forces_received;
        let snapshots = viewer.stats().snapshots_fetched;
        first = start_server(world(), &endpoint, Pacing::Sleep).unwrap();
        let returned = Instant::now();
        let mut device_back = None;
        let mut viewer_back = None;
        let both = wait_until(Duration::from_secs(10), || {
            if device_back.is_none() && device.report().forces_received > forces {
                device_back = Some(returned.elapsed());
            }
            if viewer_back.is_none() && viewer.stats().snapshots_fetched > snapshots {
                viewer_back = Some(returned.elapsed());
            }
            device_back.is_some() && viewer_back.is_some()
        });
        assert!(
            both,
            "round {round}: device back {device_back:?}, viewer back {viewer_back:?}: {} / {:?}",
            device.report(),
            viewer.stats()
        );
        device_ms.push(device_back.unwrap().as_secs_f64() * 1e3);
        viewer_ms.push(viewer_back.unwrap().as_secs_f64() * 1e3);
        // The device follows the new server, a new run.
        assert!(wait_until(Duration::from_secs(5), || device
            .report()
            .server_link
            == Link::Joined(first.instance())));
        assert_ne!(first.instance(), first_instance);
    }
    eprintln!(
        "rejoin after the server's return (3 restarts, ms): device {device_ms:.0?}, viewer {viewer_ms:.0?}"
    );
}
