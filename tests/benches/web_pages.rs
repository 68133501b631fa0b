//! Browser pages on a live scene: what `sinew-web` sends each page (feed updates per second, bytes per second),
//! and what the pages cost the surgeons: the devices' round trip and the server's tick.
//!
//! Three phases in one run (the same machine's conditions): no gateway; the gateway with no page; the gateway
//! with N pages (default 8). Everything runs in this process on loopback: the server with two devices
//! stroking the pad, a gateway (`WebGateway` on a 2-worker tokio runtime, joined to the scene as a viewer), and
//! each page a WebSocket client that takes every message and reads its kind (a browser's cost of drawing is
//! its own machine's, not the scene's).
//!
//! Run: `cargo bench -p sinew-testkit --bench web_pages` (add `-- --seconds N`, default 10 per phase, and
//! `-- --pages N`, default 8).

#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use futures_util::StreamExt;
use sinew_protocol::rt::LatencyHistogram;
use sinew_testkit::bench_support::{arg, round_trips_since, us};
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, start_server, start_sim_device,
    start_viewer, surgeon_scripts,
};
use sinew_viewer::web_feed::KIND_STATE;
use sinew_viewer::web_server::{WebConfig, WebGateway};

/// What one page received.
#[derive(Default)]
struct PageCounters {
    bytes: AtomicU64,
    states: AtomicU64,
    messages: AtomicU64,
}

struct Phase {
    label: String,
    /// Per device: id, rendered round trip, wire round trip.
    devices: Vec<(String, LatencyHistogram, LatencyHistogram)>,
    tick_p99_us: f32,
    /// Per page over the window: (bytes, state updates).
    pages: Vec<(u64, u64)>,
}

fn run(seconds: f64, gateway: bool, pages: usize) -> Phase {
    let endpoint = free_loopback_endpoint().unwrap();
    let world = load_shipped_world("pad.toml").unwrap();
    let mut server = start_server(world, &endpoint, Pacing::Spin).unwrap();
    let (left, right) = surgeon_scripts();
    let mut devices = [("left", left), ("right", right)]
        .into_iter()
        .map(|(id, script)| start_sim_device("pad", id, script, &endpoint, Pacing::Spin).unwrap())
        .collect::<Vec<_>>();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let counters: Vec<Arc<PageCounters>> = (0..pages).map(|_| Arc::default()).collect();
    let viewer = gateway.then(|| Arc::new(start_viewer("pad", "web", &endpoint).unwrap()));
    if let Some(viewer) = &viewer {
        let config = WebConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            web_root: WebConfig::default_web_root(),
            rate_hz: 30.0,
            max_pages: 64,
        };
        let gateway = runtime
            .block_on(WebGateway::bind(config, Arc::clone(viewer)))
            .expect("the gateway (is viewer/web installed: `npm ci --prefix viewer/web`?)");
        let addr = gateway.local_addr().unwrap();
        runtime.spawn(gateway.run(async {
            let _ = stopped.await;
        }));
        for page in &counters {
            let page = Arc::clone(page);
            runtime.spawn(async move {
                let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/feed"))
                    .await
                    .expect("a page connects");
                while let Some(Ok(message)) = socket.next().await {
                    let data = message.into_data();
                    page.messages.fetch_add(1, Ordering::Relaxed);
                    page.bytes.fetch_add(data.len() as u64, Ordering::Relaxed);
                    if data.first() == Some(&KIND_STATE) {
                        page.states.fetch_add(1, Ordering::Relaxed);
                    }
                }
            });
        }
    }
    std::thread::sleep(Duration::from_secs(2));
    let settled: Vec<_> = devices.iter().map(|d| d.report()).collect();
    let pages_before: Vec<(u64, u64)> = counters
        .iter()
        .map(|c| {
            (
                c.bytes.load(Ordering::Relaxed),
                c.states.load(Ordering::Relaxed),
            )
        })
        .collect();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let after: Vec<_> = devices.iter().map(|d| d.report()).collect();
    let pages_after: Vec<(u64, u64)> = counters
        .iter()
        .map(|c| {
            (
                c.bytes.load(Ordering::Relaxed),
                c.states.load(Ordering::Relaxed),
            )
        })
        .collect();
    let stats = server.stats();
    let _ = stop.send(());
    runtime.shutdown_timeout(Duration::from_secs(2));
    if let Some(viewer) = viewer
        && let Ok(mut viewer) = Arc::try_unwrap(viewer)
    {
        viewer.stop();
    }
    for d in &mut devices {
        d.stop().unwrap();
    }
    server.stop();
    Phase {
        label: match (gateway, pages) {
            (false, _) => "no gateway".to_owned(),
            (true, n) => format!("gateway, {n} pages"),
        },
        devices: round_trips_since(&after, &settled),
        tick_p99_us: stats.tick_p99_us,
        pages: pages_after
            .iter()
            .zip(&pages_before)
            .map(|(a, b)| (a.0 - b.0, a.1 - b.1))
            .collect(),
    }
}

fn main() {
    let seconds = arg("--seconds", 10.0);
    let pages = arg("--pages", 8.0) as usize;
    let phases = [
        run(seconds, false, 0),
        run(seconds, true, 0),
        run(seconds, true, pages),
    ];
    println!("| phase | device | rendered p50 | rendered p99 | wire p50 | wire p99 | samples |");
    println!("|---|---|---|---|---|---|---|");
    let mut worst = Vec::new();
    for phase in &phases {
        let mut p99 = 0.0f64;
        for (id, rendered, wire) in &phase.devices {
            println!(
                "| {} | {id} | {:.0} us | {:.0} us | {:.0} us | {:.0} us | {} |",
                phase.label,
                us(rendered, 50.0),
                us(rendered, 99.0),
                us(wire, 50.0),
                us(wire, 99.0),
                rendered.count()
            );
            p99 = p99.max(us(rendered, 99.0));
        }
        println!(
            "| {} | server tick p99 (whole run) | {:.0} us | | | | |",
            phase.label, phase.tick_p99_us
        );
        worst.push(p99);
    }
    println!();
    println!(
        "worst device rendered round trip p99: {:.0} us without a gateway, {:.0} us ({:.2}x) with it and no page, {:.0} us ({:.2}x) with {pages} pages",
        worst[0],
        worst[1],
        worst[1] / worst[0],
        worst[2],
        worst[2] / worst[0],
    );
    let fed = &phases[2].pages;
    if !fed.is_empty() {
        let rate: Vec<f64> = fed.iter().map(|p| p.1 as f64 / seconds).collect();
        let kbps: Vec<f64> = fed.iter().map(|p| p.0 as f64 / seconds / 1000.0).collect();
        let range = |v: &[f64]| {
            (
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(0.0, f64::max),
            )
        };
        let (r0, r1) = range(&rate);
        let (k0, k1) = range(&kbps);
        println!(
            "each page: {r0:.1}-{r1:.1} updates/s, {k0:.1}-{k1:.1} kB/s ({:.1} kB/s for all {pages})",
            kbps.iter().sum::<f64>()
        );
    }
}
