//! Soak: the server on worlds/pad.toml, two simulated surgeons (left presses and strokes, right presses and
//! holds) and a viewer, over real zenoh on loopback, for 10 minutes (issue "Safe under faults": memory stays
//! flat, and neither tick percentiles nor round trips drift).
//!
//! Every window (default 60 s) it prints the process's resident memory, the live tick's p50/p99 over that
//! window, each device's pose->force round trip (at force arrival) p50/p99 over that window, loop overruns, and
//! the viewer's gaps and snapshots. At the end: RSS at the end over RSS after the first window (warm-up; the
//! issue's bound is 5%), and the last window's p99s over the first's (drift shows as a ratio well above 1; the
//! machine's noise moves single windows by tens of percent, so read the whole column).
//!
//! Run: `cargo bench -p sinew-testkit --bench soak` (options: `--minutes M`, default 10; `--window-s S`, default 60).
#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::time::{Duration, Instant};

use sinew_protocol::rt::LatencyHistogram;
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, start_server, start_sim_device,
    start_viewer, surgeon_scripts, wait_until,
};

fn arg(name: &str, default: f64) -> f64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default, |v| {
            v.parse()
                .unwrap_or_else(|_| panic!("{name} takes a number, got `{v}`"))
        })
}

/// Resident set size of this process, MiB.
fn rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn us(h: &LatencyHistogram, p: f64) -> f64 {
    h.percentile_ns(p) as f64 / 1000.0
}

struct Row {
    rss_mib: f64,
    tick_p99_us: f64,
    rtt_p99_us: [f64; 2],
}

fn main() {
    let minutes = arg("--minutes", 10.0);
    let window = Duration::from_secs_f64(arg("--window-s", 60.0).max(1.0));
    let total = Duration::from_secs_f64(minutes * 60.0);

    let endpoint = free_loopback_endpoint().unwrap();
    let server = start_server(
        load_shipped_world("pad.toml").unwrap(),
        &endpoint,
        Pacing::Spin,
    )
    .unwrap();
    let (left_script, right_script) = surgeon_scripts();
    let left = start_sim_device("pad", "left", left_script, &endpoint, Pacing::Spin).unwrap();
    let right = start_sim_device("pad", "right", right_script, &endpoint, Pacing::Spin).unwrap();
    let viewer = start_viewer("pad", "instructor", &endpoint).unwrap();
    assert!(viewer.wait_for_snapshot(Duration::from_secs(10)));
    assert!(wait_until(Duration::from_secs(10), || server
        .stats()
        .devices
        .iter()
        .all(|d| d.active)));

    println!(
        "soak: server + 2 devices + viewer in one process, {minutes} min, windows of {} s",
        window.as_secs()
    );
    println!(
        "| t s | RSS MiB | tick p50 us | tick p99 us | left rtt p50/p99 us | right rtt p50/p99 us | overruns l/r | viewer gaps | snapshots |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let started = Instant::now();
    let mut tick_before = server.tick_time();
    let mut rtt_before = [
        left.report().wire_round_trip,
        right.report().wire_round_trip,
    ];
    let mut rows = Vec::new();
    while started.elapsed() < total {
        std::thread::sleep(window.min(total.saturating_sub(started.elapsed())));
        let tick_now = server.tick_time();
        let tick = tick_now.since(&tick_before);
        tick_before = tick_now;
        let reports = [left.report(), right.report()];
        let rtt: Vec<LatencyHistogram> = reports
            .iter()
            .zip(&rtt_before)
            .map(|(r, before)| r.wire_round_trip.since(before))
            .collect();
        rtt_before = [
            reports[0].wire_round_trip.clone(),
            reports[1].wire_round_trip.clone(),
        ];
        let stats = viewer.stats();
        let row = Row {
            rss_mib: rss_mib(),
            tick_p99_us: us(&tick, 99.0),
            rtt_p99_us: [us(&rtt[0], 99.0), us(&rtt[1], 99.0)],
        };
        println!(
            "| {:.0} | {:.1} | {:.0} | {:.0} | {:.0} / {:.0} | {:.0} / {:.0} | {} / {} | {} | {} |",
            started.elapsed().as_secs_f64(),
            row.rss_mib,
            us(&tick, 50.0),
            row.tick_p99_us,
            us(&rtt[0], 50.0),
            row.rtt_p99_us[0],
            us(&rtt[1], 50.0),
            row.rtt_p99_us[1],
            reports[0].overruns,
            reports[1].overruns,
            stats.gaps,
            stats.snapshots_fetched,
        );
        rows.push(row);
    }
    let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
        println!("no whole window ran");
        return;
    };
    let rss_ratio = last.rss_mib / first.rss_mib;
    println!(
        "RSS at the end over RSS after warm-up: {rss_ratio:.3} ({:.1} -> {:.1} MiB; bound 1.05: {})",
        first.rss_mib,
        last.rss_mib,
        if rss_ratio <= 1.05 { "flat" } else { "GREW" }
    );
    println!(
        "last window over first: tick p99 {:.2}, left rtt p99 {:.2}, right rtt p99 {:.2}",
        last.tick_p99_us / first.tick_p99_us,
        last.rtt_p99_us[0] / first.rtt_p99_us[0],
        last.rtt_p99_us[1] / first.rtt_p99_us[1]
    );
    let server_stats = server.stats();
    println!(
        "server: {} ticks, {} overruns, {} sim faults, {} rejected; devices: left {} stale, right {} stale",
        server_stats.ticks,
        server_stats.overruns,
        server_stats.sim_faults,
        server_stats.rejected.total(),
        left.report().safety.stale_events,
        right.report().safety.stale_events
    );
}
