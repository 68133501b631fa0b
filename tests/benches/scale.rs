//! A classroom on one server: the devices' round trip with 0 viewers and 2 devices, then with 16 viewers and 4
//! devices, in one run (the same machine's conditions). Every role is a real zenoh session on loopback in this
//! process (peers: each viewer connects to the server, whose session fans the mesh deltas out); the viewers
//! replicate the scene headless. The pad gets two more probes (devices `left2` and `right2`, 15 mm from the
//! first two along y) for the second phase.
//!
//! Run: `cargo bench -p sinew-testkit --bench scale` (add `-- --seconds N`, default 10 per phase, and `-- --viewers N`,
//! default 16).

#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::Duration;

use sinew_protocol::rt::LatencyHistogram;
use sinew_testkit::bench_support::{arg, us};
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, start_server, start_sim_device,
    start_viewer, surgeon_scripts,
};

struct Phase {
    /// Per device: id, rendered round trip, wire round trip, loop overruns.
    devices: Vec<(String, LatencyHistogram, LatencyHistogram, u64)>,
    tick_p99_us: f32,
    deltas_applied: u64,
    viewer_bytes: u64,
}

fn run(seconds: f64, extra_devices: bool, viewers: usize) -> Phase {
    let endpoint = free_loopback_endpoint().unwrap();
    let mut world = load_shipped_world("pad.toml").unwrap();
    if extra_devices {
        for (t, suffix, dy) in [(0, "2", 15.0), (1, "2", -15.0)] {
            let mut tool = world.tools[t].clone();
            tool.name = format!("{}{suffix}", tool.name);
            tool.device_id = format!("{}{suffix}", tool.device_id);
            tool.device_origin_in_world_mm[1] += dy;
            world.tools.push(tool);
        }
    }
    let ids: Vec<String> = world.tools.iter().map(|t| t.device_id.clone()).collect();
    let mut server = start_server(world, &endpoint, Pacing::Spin).unwrap();
    let (left, right) = surgeon_scripts();
    let mut devices: Vec<_> = ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let script = if i % 2 == 0 {
                left.clone()
            } else {
                right.clone()
            };
            start_sim_device("pad", id, script, &endpoint, Pacing::Spin).unwrap()
        })
        .collect();
    let mut watchers: Vec<_> = (0..viewers)
        .map(|v| start_viewer("pad", &format!("student-{v}"), &endpoint).unwrap())
        .collect();
    std::thread::sleep(Duration::from_secs_f64(2.0));
    let settled: Vec<_> = devices.iter().map(|d| d.report()).collect();
    let viewer_before: Vec<_> = watchers.iter().map(|w| w.stats()).collect();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let after: Vec<_> = devices.iter().map(|d| d.report()).collect();
    let viewer_after: Vec<_> = watchers.iter().map(|w| w.stats()).collect();
    let stats = server.stats();
    for w in &mut watchers {
        w.stop();
    }
    for d in &mut devices {
        d.stop().unwrap();
    }
    server.stop();
    Phase {
        devices: after
            .iter()
            .zip(&settled)
            .map(|(a, s)| {
                (
                    a.device_id.clone(),
                    a.round_trip.since(&s.round_trip),
                    a.wire_round_trip.since(&s.wire_round_trip),
                    a.overruns - s.overruns,
                )
            })
            .collect(),
        tick_p99_us: stats.tick_p99_us,
        deltas_applied: viewer_after
            .iter()
            .zip(&viewer_before)
            .map(|(a, b)| a.deltas_applied - b.deltas_applied)
            .sum(),
        viewer_bytes: viewer_after
            .iter()
            .zip(&viewer_before)
            .map(|(a, b)| a.bytes_received - b.bytes_received)
            .sum(),
    }
}

fn main() {
    let seconds = arg("--seconds", 10.0);
    let viewers = arg("--viewers", 16.0) as usize;
    let small = run(seconds, false, 0);
    let large = run(seconds, true, viewers);
    println!(
        "| phase | device | rendered p50 | rendered p99 | wire p50 | wire p99 | loop overruns | samples |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut worst = [0.0f64; 2];
    for (i, (label, phase)) in [
        ("0 viewers, 2 devices", &small),
        (&*format!("{viewers} viewers, 4 devices"), &large),
    ]
    .into_iter()
    .enumerate()
    {
        for (id, rendered, wire, overruns) in &phase.devices {
            println!(
                "| {label} | {id} | {:.0} us | {:.0} us | {:.0} us | {:.0} us | {overruns} | {} |",
                us(rendered, 50.0),
                us(rendered, 99.0),
                us(wire, 50.0),
                us(wire, 99.0),
                rendered.count()
            );
            worst[i] = worst[i].max(us(rendered, 99.0));
        }
        println!(
            "| {label} | server tick p99 (whole run) | {:.0} us | | | | | |",
            phase.tick_p99_us
        );
    }
    println!();
    println!(
        "worst device rendered round trip p99: {:.0} us with 0 viewers and 2 devices, {:.0} us with {viewers} viewers and 4 devices: {:+.1}%",
        worst[0],
        worst[1],
        100.0 * (worst[1] / worst[0] - 1.0)
    );
    println!(
        "viewers: {} deltas applied, {:.1} kB/s received in all ({:.1} kB/s each)",
        large.deltas_applied,
        large.viewer_bytes as f64 / seconds / 1000.0,
        large.viewer_bytes as f64 / seconds / 1000.0 / viewers.max(1) as f64
    );
}
