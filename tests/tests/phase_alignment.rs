//! Phase alignment over real zenoh sessions on loopback: the server and two simulated hapticservers rendering
//! directly, each aligning its loop. Each settles at its target wait (at most 150 us, less on a loaded server:
//! `hapticserver/src/force/phase_align.rs`): the server's measured waits for its poses (`ForceCommand::pose_wait_us`)
//! end within 100 us of it, in steps of at most 10 us a tick. Two loops at independent random phases both land
//! within 100 us of a target by chance only about one time in 25, and at least one of them must have moved. A
//! device with alignment off still measures its waits and never shifts its loop. Wall-clock
//! latency is not asserted (benches measure it: `cargo bench -p sinew-testkit --bench round_trip`).

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::time::Duration;

use hapticserver::sim_device::sim_device_model;
use hapticserver::{HandPreset, HandScript, HapticConfig, HapticHandle, HapticServer, ModePolicy};
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, start_server, wait_until,
};

fn start_device(endpoint: &str, id: &str, at_x_mm: f32, align: Option<f32>) -> HapticHandle {
    let script = HandScript::Press {
        at_mm: [at_x_mm, 0.0, 0.0],
        depth_mm: 3.0,
        approach_mm: 5.0,
        descend_s: 0.5,
    };
    let device =
        hapticserver::SimDevice::with_params(script, HandPreset::Grip.params(), sim_device_model());
    let mut config = HapticConfig::new("pad", id, Box::new(device));
    config.network = NetworkOptions {
        connect: with_udp_twin(endpoint),
        ..NetworkOptions::default()
    };
    config.mode = ModePolicy::Direct;
    config.phase_align = align.is_some();
    if let Some(target_us) = align {
        config.phase_target_us = target_us;
    }
    HapticServer::start(config).unwrap()
}

#[test]
fn direct_devices_settle_at_their_target_pose_wait() {
    let endpoint = free_loopback_endpoint().unwrap();
    let world = load_shipped_world("pad.toml").unwrap();
    let mut server = start_server(world, &endpoint, Pacing::Sleep).unwrap();
    let mut devices = [
        start_device(&endpoint, "left", 14.0, Some(150.0)),
        start_device(&endpoint, "right", -14.0, Some(150.0)),
    ];

    // Alignment converges within a second of the first forces; give a loaded machine several.
    let settled = wait_until(Duration::from_secs(30), || {
        devices.iter().all(|d| {
            let r = d.report();
            r.forces_received > 3000
        })
    });
    assert!(
        settled,
        "forces did not flow: {:?}",
        devices.iter().map(HapticHandle::report).collect::<Vec<_>>()
    );
    let near_target = |d: &HapticHandle| {
        let phase = d.report().phase;
        phase.waits_used >= 64 && (phase.last_median_wait_us - phase.last_target_us).abs() <= 100.0
    };
    let both_near = wait_until(Duration::from_secs(20), || {
        near_target(&devices[0]) && near_target(&devices[1])
    });
    let reports: Vec<_> = devices.iter().map(HapticHandle::report).collect();
    for device in &mut devices {
        device.stop().unwrap();
    }
    server.stop();

    assert!(
        both_near,
        "median waits {} us (target {}) and {} us (target {}): {:?} {:?}",
        reports[0].phase.last_median_wait_us,
        reports[0].phase.last_target_us,
        reports[1].phase.last_median_wait_us,
        reports[1].phase.last_target_us,
        reports[0].phase,
        reports[1].phase
    );
    for r in &reports {
        assert!(r.phase.enabled && r.phase.waits_used >= 64, "{:?}", r.phase);
        assert!(
            (20.0..=150.0).contains(&r.phase.last_target_us),
            "{:?}",
            r.phase
        );
        // Every shift is at most 10 us: the net shift is at most 10 us per tick run.
        assert!(
            r.phase.net_shift_us.abs() <= 10.0 * r.ticks as f64,
            "{:?}",
            r.phase
        );
        assert_eq!(r.safety.nan_dropped, 0);
    }
    assert!(
        reports.iter().any(|r| r.phase.corrections > 0),
        "neither loop ever shifted: {:?} {:?}",
        reports[0].phase,
        reports[1].phase
    );
}

#[test]
fn with_alignment_off_the_loop_measures_and_never_shifts() {
    let endpoint = free_loopback_endpoint().unwrap();
    let world = load_shipped_world("pad.toml").unwrap();
    let mut server = start_server(world, &endpoint, Pacing::Sleep).unwrap();
    let mut device = start_device(&endpoint, "left", 14.0, None);
    let measured = wait_until(Duration::from_secs(30), || {
        device.report().phase.waits_used >= 64
    });
    let report = device.report();
    device.stop().unwrap();
    server.stop();
    assert!(measured, "{:?}", report.phase);
    assert!(!report.phase.enabled);
    assert_eq!(report.phase.corrections, 0);
    assert_eq!(report.phase.net_shift_us, 0.0);
    assert!(
        (0.0..=2000.0).contains(&report.phase.last_median_wait_us),
        "{:?}",
        report.phase
    );
}
