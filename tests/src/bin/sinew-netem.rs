//! `sinew-netem`: bridge two interfaces with delay, jitter and seeded loss per direction (the lab's relay).
//!
//! Owns: flag parsing, the stop signal and the report; the bridge is [`sinew_testkit::netem`].
//!
//! Run as root in a namespace holding both interfaces, e.g.
//! `sinew-netem --a tosrv --b todev --a-to-b delay=50,jitter=20,loss=0.01,seed=1 --b-to-a delay=50,seed=2`.
//! Prints one `bridging ...` line once both sockets are open, and the per-direction counters on SIGTERM,
//! SIGINT or when `--duration-s` runs out.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Parser;
use sinew_protocol::rt::EmulationConfig;
use sinew_testkit::netem::{
    Bridge, BridgeConfig, DEFAULT_SPIN_NS, ScriptedDrop, format_direction, parse_direction,
};

/// Bridge Ethernet frames between two interfaces with one-way delay, jitter and Bernoulli loss.
#[derive(Debug, Parser)]
#[command(name = "sinew-netem", version)]
struct Args {
    /// First interface.
    #[arg(long)]
    a: String,
    /// Second interface.
    #[arg(long)]
    b: String,
    /// Emulation of frames from --a to --b: `delay=MS,jitter=MS,loss=P,seed=N` (missing keys: 0, seed 1).
    #[arg(long, default_value = "", value_parser = parse_spec)]
    a_to_b: EmulationConfig,
    /// Emulation of frames from --b to --a, same syntax.
    #[arg(long, default_value = "", value_parser = parse_spec)]
    b_to_a: EmulationConfig,
    /// spin_sleep native accuracy of the send threads, ns (0: plain sleep).
    #[arg(long, default_value_t = DEFAULT_SPIN_NS)]
    spin_ns: u32,
    /// Also drop these frames from --a to --b, by ordinal among their kind: e.g. `tcp:1,udp:2` drops the
    /// first TCP frame and the second UDP frame.
    #[arg(long, value_delimiter = ',')]
    drop_a_to_b: Vec<ScriptedDrop>,
    /// Also drop these frames from --b to --a, same syntax.
    #[arg(long, value_delimiter = ',')]
    drop_b_to_a: Vec<ScriptedDrop>,
    /// Stop after this many seconds (default: run until SIGTERM/SIGINT).
    #[arg(long)]
    duration_s: Option<f64>,
}

fn parse_spec(spec: &str) -> Result<EmulationConfig, String> {
    parse_direction(spec).map_err(|e| e.to_string())
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .init();
    let args = Args::parse();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Release))
        .context("installing the SIGTERM/SIGINT handler")?;
    let bridge = Bridge::start(&BridgeConfig {
        interface_a: args.a.clone(),
        interface_b: args.b.clone(),
        a_to_b: args.a_to_b,
        b_to_a: args.b_to_a,
        spin_ns: args.spin_ns,
        drops: [args.drop_a_to_b.clone(), args.drop_b_to_a.clone()],
    })
    .context("starting the bridge")?;
    println!(
        "bridging {} <-> {}: {}->{} [{}], {}->{} [{}]",
        args.a,
        args.b,
        args.a,
        args.b,
        format_direction(&args.a_to_b),
        args.b,
        args.a,
        format_direction(&args.b_to_a)
    );
    let deadline = args
        .duration_s
        .map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    while !stop.load(Ordering::Acquire) && deadline.is_none_or(|d| Instant::now() < d) {
        std::thread::sleep(Duration::from_millis(20));
    }
    println!("{}", bridge.stop());
    Ok(())
}
