//! System figures, all in one run so they share the machine's conditions:
//! 1. raw zenoh ping-pong of a pose-sized payload at 1 kHz between two peer sessions on loopback (baseline);
//! 2. the full pose -> force round trip for two simulated devices against a server on worlds/pad.toml
//!    (left presses and strokes, right presses and holds), measured at each hapticserver both at force
//!    arrival ("wire") and at the device tick that renders it ("rendered");
//! 3. the hapticservers' 1 kHz loop interval deviation;
//! 4. the server tick time inside the live system;
//! 5. mesh-delta bytes/s while the tissue is stroked, against sending the whole mesh at the same rate.
//!
//! Run: `cargo bench -p sinew-testkit --bench round_trip` (add `-- --seconds N`, default 10).

#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::{Duration, Instant};

use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::LatencyHistogram;
use sinew_testkit::bench_support::{self, arg, encoded_pose_len, us};
use sinew_testkit::harness::{
    Pacing, SimDeviceSetup, free_loopback_endpoint, load_shipped_world, start_server,
    start_sim_device_emulated, surgeon_scripts,
};

fn ping_pong(seconds: f64, payload_len: usize) -> LatencyHistogram {
    let endpoint = free_loopback_endpoint().unwrap();
    bench_support::ping_pong(
        seconds,
        &NetworkOptions {
            listen: vec![endpoint.clone()],
            ..NetworkOptions::default()
        },
        &NetworkOptions {
            connect: vec![endpoint],
            ..NetworkOptions::default()
        },
        ("bench/ping", "bench/pong"),
        payload_len,
        Duration::from_millis(500),
    )
    .unwrap()
}

/// One run of the live system: server + two simulated hapticservers, `phase_align` on or off. Prints its
/// rows of the table (measured over `seconds` after 1.5 s of settling) and returns what the caller reports.
fn run_system(
    seconds: f64,
    phase_align: bool,
    baseline: &LatencyHistogram,
) -> (
    sinew_protocol::ServerStats,
    sinew_protocol::ServerStats,
    f64,
    usize,
    Vec<hapticserver::HapticReport>,
) {
    let endpoint = free_loopback_endpoint().unwrap();
    let world = load_shipped_world("pad.toml").unwrap();
    let mut server = start_server(world, &endpoint, Pacing::Spin).unwrap();
    let (left, right) = surgeon_scripts();
    let setup = SimDeviceSetup {
        phase_align,
        ..SimDeviceSetup::default()
    };
    let mut devices = [
        start_sim_device_emulated("pad", "left", left, &endpoint, Pacing::Spin, setup).unwrap(),
        start_sim_device_emulated("pad", "right", right, &endpoint, Pacing::Spin, setup).unwrap(),
    ];
    std::thread::sleep(Duration::from_secs_f64(1.5));
    let before = server.stats();
    let settled: Vec<_> = devices.iter().map(|d| d.report()).collect();
    let vertices = server.published_positions(0).map(|(_, p)| p.len()).unwrap();
    let t0 = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let elapsed = t0.elapsed().as_secs_f64();
    let after = server.stats();
    let sim_report = server.sim_report();
    let mut reports: Vec<_> = devices.iter().map(|d| d.report()).collect();
    for d in &mut devices {
        d.stop().unwrap();
    }
    server.stop();
    for (r, s) in reports.iter_mut().zip(&settled) {
        r.round_trip = r.round_trip.since(&s.round_trip);
        r.wire_round_trip = r.wire_round_trip.since(&s.wire_round_trip);
        r.interval_deviation = r.interval_deviation.since(&s.interval_deviation);
    }
    let label = if phase_align {
        "phase aligned"
    } else {
        "phase alignment off"
    };
    for r in &reports {
        for (what, h) in [
            ("wire (force arrival)", &r.wire_round_trip),
            ("rendered (device tick)", &r.round_trip),
        ] {
            println!(
                "| pose -> force, device `{}`, {what}, {label} | {:.0} us | {:.0} us | {:.1} / {:.1} | {} |",
                r.device_id,
                us(h, 50.0),
                us(h, 99.0),
                us(h, 50.0) / us(baseline, 50.0),
                us(h, 99.0) / us(baseline, 99.0),
                h.count()
            );
        }
    }
    for r in &reports {
        println!(
            "| hapticserver `{}` loop interval deviation from 1 ms, {label} | {:.1} us | {:.1} us | - | {} (overruns {}; phase: {} corrections, net shift {:+.0} us, median wait {:.0} us, target {:.0} us, rest of the round trip {:.0} us) |",
            r.device_id,
            us(&r.interval_deviation, 50.0),
            us(&r.interval_deviation, 99.0),
            r.interval_deviation.count(),
            r.overruns,
            r.phase.corrections,
            r.phase.net_shift_us,
            r.phase.last_median_wait_us,
            r.phase.last_target_us,
            r.phase.last_rest_us,
        );
    }
    println!(
        "| server tick in the live system (whole run, 2 tools), {label} | {:.0} us | {:.0} us | - | {} (overruns {}) |",
        after.tick_p50_us, after.tick_p99_us, after.ticks, after.overruns
    );
    if let Some(report) = &sim_report {
        println!(
            "| server tick start -> forces handed to zenoh (whole run), {label} | {:.0} us | {:.0} us | - | {} |",
            us(&report.force_time, 50.0),
            us(&report.force_time, 99.0),
            report.force_time.count()
        );
    }
    (before, after, elapsed, vertices, reports)
}

fn main() {
    let seconds = arg("--seconds", 10.0);
    let pose_len = encoded_pose_len();

    let baseline = ping_pong(seconds, pose_len);

    println!("| measurement | p50 | p99 | ratio p50 / p99 to baseline | samples |");
    println!("|---|---|---|---|---|");
    println!(
        "| raw zenoh ping-pong, {pose_len}-byte payload at 1 kHz, peer to peer (baseline) | {:.0} us | {:.0} us | 1.0 / 1.0 | {} |",
        us(&baseline, 50.0),
        us(&baseline, 99.0),
        baseline.count()
    );
    // Without phase alignment first (the device loops keep whatever phase they start at), then with it (the
    // default). Each run measures after a settling time that covers the alignment's convergence.
    let _ = run_system(seconds, false, &baseline);
    let (before, after, elapsed, vertices, reports) = run_system(seconds, true, &baseline);
    let delta_bytes = (after.delta_bytes_sent - before.delta_bytes_sent) as f64;
    let full_mesh_bytes_per_s = (vertices * 6) as f64 * 60.0;
    println!();
    println!(
        "mesh deltas while stroking: {:.1} kB/s ({} deltas in {:.1} s); whole mesh ({} vertices x 6 bytes) at 60 Hz: {:.1} kB/s; deltas are {:.1}% of it",
        delta_bytes / elapsed / 1000.0,
        after.deltas_sent - before.deltas_sent,
        elapsed,
        vertices,
        full_mesh_bytes_per_s / 1000.0,
        100.0 * delta_bytes / elapsed / full_mesh_bytes_per_s
    );
    for r in &reports {
        println!(
            "device {}: max rendered force {:.2} N, safety {:?}",
            r.device_id, r.max_rendered_force_n, r.safety
        );
    }
}
