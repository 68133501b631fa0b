//! Fault drill (issue "Safe under faults", items 4 and 5): the server process is killed while a hand presses
//! into the pad and a new one starts on the same endpoint. The device rejoins on its own; its tool enters the new
//! server's scene from above the pad (not at the device pose, under the sheet), and the force at the hand comes
//! back to what it was, growing from zero without a kick: no overshoot beyond 10% of the steady force.
//!
//! Real processes and sessions: `sinew-server` is the workspace binary; the hapticserver runs in-process with a
//! simulated hand, both over zenoh on loopback (multilink).

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::time::Duration;

use hapticserver::{HapticServer, SimDevice};
use sinew_testkit::harness::{
    KillOnDrop, free_loopback_endpoint, pad_device_config, spawn_pad_server_process, wait_until,
};
use sinew_testkit::scenarios::press;

fn start_server(endpoint: &str) -> KillOnDrop {
    KillOnDrop(spawn_pad_server_process(endpoint, &[], false).unwrap())
}

fn norm(f: [f32; 3]) -> f32 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

#[test]
fn after_a_server_restart_the_pressing_hand_feels_the_pad_again_without_a_kick() {
    let endpoint = free_loopback_endpoint().unwrap();
    let mut first = start_server(&endpoint);
    let device = SimDevice::new(press(6.0, 1.0));
    let mut config = pad_device_config("left", Box::new(device), &endpoint);
    config.trace_ticks = 120_000;
    let mut device = HapticServer::start(config).expect("starting the hapticserver");

    // Pressing and settled: 0.5 s with the force above 0.3 N and the stylus all but still.
    let mut since = None;
    let settled = wait_until(Duration::from_secs(30), || {
        let report = device.report();
        let pressing = report.last_rendered_force_magnitude_n() > 0.3
            && report.last_second.ticks > 0
            && report.last_second.speed_rms_mm_s < 1.0;
        match (pressing, since) {
            (false, _) => since = None,
            (true, None) => since = Some(device.clock_s()),
            (true, Some(t)) => return device.clock_s() - t > 0.5,
        }
        false
    });
    assert!(settled, "never settled in the pad: {:?}", device.report());
    let killed_s = device.clock_s();
    first.0.kill().unwrap();
    first.0.wait().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let restarted_s = device.clock_s();
    let _second = start_server(&endpoint);

    // The device rejoins on its own; then 2 s of pressing on the new server.
    let received = device.report().forces_received;
    let rejoined = wait_until(Duration::from_secs(30), || {
        device.report().forces_received > received + 100
    });
    assert!(rejoined, "the device never rejoined: {:?}", device.report());
    let rejoined_s = device.clock_s();
    assert!(wait_until(Duration::from_secs(20), || device.clock_s()
        >= rejoined_s + 2.0));
    device.stop().unwrap();
    let trace = device.take_trace();
    let samples = trace.samples();

    let mean = |from: f64, to: f64| {
        let window: Vec<f32> = samples
            .iter()
            .filter(|s| s.t_s >= from && s.t_s < to)
            .map(|s| norm(s.force_n))
            .collect();
        window.iter().sum::<f32>() / window.len().max(1) as f32
    };
    let before = mean(killed_s - 0.3, killed_s);
    let after = mean(rejoined_s + 1.5, rejoined_s + 2.0);
    // From the restart on: the force returns from zero; its peak says whether it kicked. (The stylus speed is
    // printed only: the simulated hand moves as the force leaves and returns, kick or not.)
    let back: Vec<_> = samples.iter().filter(|s| s.t_s >= restarted_s).collect();
    let peak = back.iter().map(|s| norm(s.force_n)).fold(0.0f32, f32::max);
    let fastest = back
        .iter()
        .map(|s| norm(s.velocity_mm_s))
        .fold(0.0f32, f32::max);
    let first_force = back.iter().find(|s| norm(s.force_n) > 0.0).unwrap();
    let reached = back
        .iter()
        .find(|s| norm(s.force_n) >= 0.9 * after)
        .unwrap();
    println!(
        "before the kill {before:.3} N; after the restart {after:.3} N, peak {peak:.3} N, stylus at most \
         {fastest:.1} mm/s; force back {:.0} ms after the restart, at 90% {:.0} ms after that",
        (first_force.t_s - restarted_s) * 1e3,
        (reached.t_s - first_force.t_s) * 1e3
    );
    assert!(
        (after - before).abs() <= 0.1 * before,
        "the pad pushes {after:.3} N after the restart, {before:.3} N before: the tool is not on top"
    );
    assert!(
        peak <= 1.1 * after,
        "the force kicked to {peak:.3} N on the way back to {after:.3} N"
    );
}
