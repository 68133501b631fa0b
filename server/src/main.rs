//! `sinew-server`: load a world, serve it over zenoh. A thin shell over [`sinew_server::node`].

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Parser;
use sinew_protocol::network::NetworkOptions;
use sinew_server::node::{ServerConfig, ServerNode};
use sinew_server::world::load_world;

/// The authoritative Sinew simulation: soft tissue, tools, forces, replication.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// World description (TOML).
    #[arg(long, default_value = "worlds/pad.toml")]
    world: PathBuf,
    /// zenoh endpoints and mode.
    #[command(flatten)]
    network: sinew_protocol::cli::NetworkArgs,
    /// Stop after this many seconds (default: run until killed).
    #[arg(long)]
    duration_s: Option<f64>,
    /// Participant id of this server.
    #[arg(long, default_value = "server")]
    id: String,
    /// Emulated distance on what this role publishes.
    #[command(flatten)]
    emulation: sinew_protocol::cli::EmulationArgs,
    /// Fault drill: make the sim thread panic at this tick, as a simulation bug would.
    #[arg(long, hide = true)]
    fault_panic_at_tick: Option<u64>,
    /// Record the session (every tick's poses and force commands, and the world) to this MCAP file; replay
    /// it with `sinew replay FILE`.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// Run the sim tick as a real-time thread (SCHED_FIFO, locked memory) where the process may (root, or
    /// CAP_SYS_NICE and an RLIMIT_RTPRIO allowance); the log says at start what it was given.
    #[arg(long)]
    realtime: bool,
    /// Threads for the tissue passes, the tick's own included, instead of the world's `[sim] threads` (or, when
    /// it has none, every core but two). Any count gives the same results; only the tick's time changes.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=64))]
    tissue_threads: Option<u16>,
}

fn main() -> anyhow::Result<()> {
    // The log, and beside it the counter of what access control refuses (the stats' `access_denied`).
    sinew_server::node::access_refusals::init_log_with_counter("info");
    sinew_protocol::rt::panic_report::install_deferred_backtrace_hook();
    let args = Args::parse();
    let emulation = args.emulation.config().map_err(anyhow::Error::msg)?;
    let mut world =
        load_world(&args.world).context("the server refuses to start with this world")?;
    if let Some(threads) = args.tissue_threads {
        world.tissue_threads = Some(usize::from(threads));
    }
    println!(
        "world {}: scene `{}`, {} object(s), {} tool(s), tick {} Hz",
        args.world.display(),
        world.scene,
        world.objects.len(),
        world.tools.len(),
        world.tick_hz
    );
    let config = ServerConfig {
        network: args.network.options(NetworkOptions::server_default()),
        server_id: args.id,
        emulation,
        panic_at_tick: args.fault_panic_at_tick,
        record: args.record,
        realtime: args.realtime,
        ..ServerConfig::default()
    };
    let mut server = ServerNode::start(world, config).context("starting the server")?;
    // Ctrl-C / SIGTERM: stop the threads and withdraw the presence token cleanly.
    let interrupted = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = interrupted.clone();
    ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::Release))
        .context("installing the Ctrl-C handler")?;
    let started = Instant::now();
    let mut next_line = started + Duration::from_secs(1);
    loop {
        std::thread::sleep(Duration::from_millis(50));
        if interrupted.load(std::sync::atomic::Ordering::Acquire) {
            break;
        }
        if let Some(failure) = server.failure().map(str::to_owned) {
            server.stop();
            if let Some(backtrace) = sinew_protocol::rt::panic_report::take_deferred_backtrace()
                .filter(|b| b.status() == std::backtrace::BacktraceStatus::Captured)
            {
                eprintln!("stack backtrace of the panic:\n{backtrace}");
            }
            anyhow::bail!("sinew-server stopped: {failure}");
        }
        if Instant::now() < next_line {
            continue;
        }
        next_line += Duration::from_secs(1);
        let s = server.stats();
        let devices: Vec<String> = s
            .devices
            .iter()
            .map(|d| {
                format!(
                    "{}:{} {} rtt {} us max {:.2} N",
                    d.device_id,
                    if d.active { "on" } else { "off" },
                    if d.moderated { "moderated" } else { "direct" },
                    d.last_round_trip_us,
                    d.max_force_n
                )
            })
            .collect();
        println!(
            "t {:6.1} s  ticks {:7}  tick p50 {:5.0} us p99 {:5.0} us  overruns {}  deltas {} ({} B)  rejected {}  [{}]",
            s.sim_time_s,
            s.ticks,
            s.tick_p50_us,
            s.tick_p99_us,
            s.overruns,
            s.deltas_sent,
            s.delta_bytes_sent,
            rejected_text(&s.rejected),
            devices.join(", ")
        );
        if args
            .duration_s
            .is_some_and(|d| started.elapsed().as_secs_f64() >= d)
        {
            break;
        }
    }
    server.stop();
    Ok(())
}

/// `0`, or the total and each non-zero reason: `1071 (access_denied 1071)`.
fn rejected_text(r: &sinew_protocol::RejectCounts) -> String {
    let total = r.total();
    if total == 0 {
        return "0".to_owned();
    }
    let reasons: Vec<String> = [
        ("malformed", r.malformed),
        ("wrong_version", r.wrong_version),
        ("invalid", r.invalid),
        ("unknown_device", r.unknown_device),
        ("duplicate_device", r.duplicate_device),
        ("wrong_tool", r.wrong_tool),
        ("no_hello", r.no_hello),
        ("access_denied", r.access_denied),
        ("tls_refused", r.tls_refused),
    ]
    .into_iter()
    .filter(|(_, n)| *n > 0)
    .map(|(name, n)| format!("{name} {n}"))
    .collect();
    format!("{total} ({})", reasons.join(", "))
}
