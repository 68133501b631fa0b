//! `sinew-recorder`: record what a scene publishes, from outside the server, into an MCAP file. An instructor
//! records a session without touching the server: the recorder subscribes like a viewer to everything under
//! `sinew/<scene>/` (force commands, mesh deltas, tool states, stats with every device's round trip, hellos,
//! presence; the devices' poses too where they reach it, i.e. through a zenoh router, not when it connects
//! to a server peer), stores each message as published, with JSON views Foxglove reads, and publishes nothing
//! but its own presence (as a viewer).
//!
//! Its file holds what was published, not the server's tick inputs: Foxglove opens it, `sinew replay` says it
//! cannot replay it. For a bit-exact replay, record on the server (`sinew-server --record`).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Parser;
use sinew_protocol::Role;
use sinew_protocol::keys::SceneKeys;
use sinew_protocol::network::NetworkOptions;
use sinew_server::node::open_session;
use sinew_server::recording::{Recorder, TapScope, WireItem, WireTap};
use zenoh::Wait;

/// Record what a Sinew scene publishes into an MCAP file (Foxglove opens it).
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// The file to write (MCAP).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Scene to record.
    #[arg(long, default_value = "pad")]
    scene: String,
    /// This recorder's participant id (it shows as a viewer).
    #[arg(long)]
    id: Option<String>,
    /// zenoh endpoints and mode (a recorder connects like a viewer).
    #[command(flatten)]
    network: sinew_protocol::cli::NetworkArgs,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    duration_s: Option<f64>,
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .init();
    let args = Args::parse();
    let duration = match args.duration_s {
        Some(s) if !(s.is_finite() && s > 0.0) => {
            anyhow::bail!("--duration-s must be a positive number of seconds, got {s}")
        }
        Some(s) => Some(Duration::from_secs_f64(s)),
        None => None,
    };
    let keys = SceneKeys::new(&args.scene)?;
    let id = args
        .id
        .unwrap_or_else(|| format!("recorder-{}", std::process::id()));
    let presence_key = keys.presence(Role::Viewer, &id)?;
    // The file first: an unwritable path is refused before anything joins the scene.
    let recorder = Recorder::start_wire(&args.out, &args.scene)?;
    let network = args.network.options(NetworkOptions::client_default());
    let session = open_session(&network)
        .map_err(|e| anyhow::anyhow!("opening zenoh ({:?}): {e}", network.connect))?;
    let started = Instant::now();
    let clock = Arc::new(move || u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX));
    let sink = recorder.wire_sink();
    // The scene as it stands when the recording starts: the snapshot a viewer would get.
    let snapshot_key = keys.snapshot();
    let replies = session
        .get(&snapshot_key)
        .timeout(Duration::from_secs(2))
        .wait()
        .map_err(|e| anyhow::anyhow!("asking for the snapshot: {e}"))?;
    let mut snapshot = false;
    while let Ok(reply) = replies.recv() {
        if let Ok(sample) = reply.result() {
            sink.offer(WireItem::Sample {
                key: snapshot_key.clone(),
                log_time_ns: clock(),
                payload: sample.payload().to_bytes().into_owned(),
            });
            snapshot = true;
            break;
        }
    }
    let tap = WireTap::start(
        &session,
        &keys,
        TapScope {
            poses_and_forces: true,
        },
        clock,
        sink,
    )
    .map_err(|e| anyhow::anyhow!("subscribing to {}: {e}", keys.everything()))?;
    let token = session
        .liveliness()
        .declare_token(presence_key)
        .wait()
        .map_err(|e| anyhow::anyhow!("declaring presence: {e}"))?;
    println!(
        "recording scene `{}` into {} ({}; {})",
        args.scene,
        args.out.display(),
        if snapshot {
            "snapshot taken"
        } else {
            "no server answered the snapshot query yet"
        },
        duration.map_or("Ctrl-C to stop".to_owned(), |d| format!(
            "for {:.1} s",
            d.as_secs_f64()
        ))
    );
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Release))
        .context("installing the Ctrl-C handler")?;
    while !stop.load(Ordering::Acquire) && duration.is_none_or(|d| started.elapsed() < d) {
        std::thread::sleep(Duration::from_millis(50));
        if recorder.failed() {
            break;
        }
    }
    let dropped = tap.stop();
    let _ = token.undeclare().wait();
    let summary = recorder.join();
    let _ = session.close().wait();
    let bytes = std::fs::metadata(&args.out).map_or(0, |m| m.len());
    println!(
        "recorded {} messages and presence changes ({} dropped) in {:.1} s into {} ({:.1} kB)",
        summary.wire_items,
        dropped,
        started.elapsed().as_secs_f64(),
        args.out.display(),
        bytes as f64 / 1e3
    );
    if let Some(error) = summary.error {
        anyhow::bail!("the recording stopped early: {error}");
    }
    Ok(())
}
