//! `sinew-viewer`: watch a Sinew scene: headless stats, an offscreen PNG, or an interactive window.
//!
//! Owns: flag parsing and wiring the library together. Must not: hold logic the library could test.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{ArgGroup, Parser};
use sinew_protocol::network::NetworkOptions;
use sinew_viewer::{
    InstructorOverlay, ViewerClient, ViewerConfig, ViewerError, ViewerHandle, ViewerStats,
    display_available, render_png_with_overlay, run_window,
};

/// Watch a Sinew scene: replicate it from the server's mesh deltas and draw it.
#[derive(Debug, Parser)]
#[command(name = "sinew-viewer", version, about)]
#[command(group(ArgGroup::new("output").required(true).args(["headless", "png", "window"])))]
struct Args {
    /// Scene to join.
    #[arg(long, default_value = "pad")]
    scene: String,
    /// This viewer's participant id [default: viewer-<pid>].
    #[arg(long)]
    id: Option<String>,
    /// zenoh endpoints and mode.
    #[command(flatten)]
    network: sinew_protocol::cli::NetworkArgs,
    /// How long one snapshot query waits for the server, seconds.
    #[arg(long, default_value_t = 2.0, value_name = "SECONDS")]
    snapshot_timeout_s: f64,

    /// Print one line of stats per second.
    #[arg(long)]
    headless: bool,
    /// With --headless: stop after this many seconds [default: run until killed].
    #[arg(long, value_name = "SECONDS", requires = "headless")]
    duration_s: Option<f64>,

    /// Wait for the snapshot, render the replica offscreen to FILE (PNG) and exit.
    #[arg(long, value_name = "FILE")]
    png: Option<PathBuf>,
    /// With --png: apply this many seconds of live updates before rendering.
    #[arg(long, default_value_t = 0.0, value_name = "SECONDS", requires = "png")]
    after_s: f64,
    /// With --png: give up if no snapshot arrives within this many seconds.
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS", requires = "png")]
    wait_s: f64,

    /// Open an interactive window (needs a display).
    #[arg(long)]
    window: bool,

    /// Image or window width, pixels.
    #[arg(long, default_value_t = 1024)]
    width: u32,
    /// Image or window height, pixels.
    #[arg(long, default_value_t = 768)]
    height: u32,
}

fn seconds(value: f64, flag: &str) -> Result<Duration> {
    Duration::try_from_secs_f64(value)
        .with_context(|| format!("--{flag} must be a non-negative number of seconds, got {value}"))
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.png.is_some() {
        give_the_graphics_stack_a_runtime_dir();
    }
    init_tracing();

    if args.window && !display_available() {
        // Fail before joining the scene.
        return Err(ViewerError::NoDisplay).context("interactive window");
    }

    let network = args.network.options(NetworkOptions::client_default());
    let viewer_id = args
        .id
        .clone()
        .unwrap_or_else(|| format!("viewer-{}", std::process::id()));
    let config = ViewerConfig {
        network,
        snapshot_timeout: seconds(args.snapshot_timeout_s, "snapshot-timeout-s")?,
        ..ViewerConfig::new(args.scene.clone(), viewer_id.clone())
    };
    let endpoints = describe_endpoints(&config.network);
    let mut viewer = ViewerClient::start(config).with_context(|| {
        format!(
            "starting viewer `{viewer_id}` on scene `{}` ({endpoints})",
            args.scene
        )
    })?;

    let result = if args.headless {
        let duration = args
            .duration_s
            .map(|s| seconds(s, "duration-s"))
            .transpose()?;
        // Ctrl-C / SIGTERM: leave the loop, print the final line, stop within half a second.
        let interrupted = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let flag = interrupted.clone();
        ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::Release))
            .context("installing the Ctrl-C handler")?;
        run_headless(&viewer, duration, &interrupted);
        Ok(())
    } else if let Some(path) = &args.png {
        run_png(&viewer, &args, path, &endpoints)
    } else {
        run_window(
            &viewer,
            &format!("Sinew viewer: {}", args.scene),
            args.width,
            args.height,
        )
        .context("interactive window")
    };
    viewer.stop();
    result
}

fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
}

fn describe_endpoints(network: &NetworkOptions) -> String {
    let mut parts = Vec::new();
    if !network.connect.is_empty() {
        parts.push(format!("connect {}", network.connect.join(",")));
    }
    if !network.listen.is_empty() {
        parts.push(format!("listen {}", network.listen.join(",")));
    }
    if let Some(file) = &network.config_file {
        parts.push(format!("zenoh config {}", file.display()));
    }
    parts.join("; ")
}

fn stats_line(stats: &ViewerStats) -> String {
    if !stats.has_snapshot {
        return format!(
            "waiting for snapshot: queries {} failed {} server {}",
            stats.snapshot_queries,
            stats.snapshot_failures,
            if stats.server_present {
                "present"
            } else {
                "not seen"
            }
        );
    }
    format!(
        "frame {} | {:.1} frames/s | {:.0} B/s | {:.1} deltas/s | gaps {} | snapshots {} | err <= {:.4} mm | applied {} stale {} | decode errors {}",
        stats.replica_frame,
        stats.frames_per_s,
        stats.bytes_per_s,
        stats.deltas_per_s,
        stats.gaps,
        stats.snapshots_fetched,
        stats.replica_error_bound_mm,
        stats.deltas_applied,
        stats.deltas_stale,
        stats.decode_errors.total(),
    )
}

fn run_headless(
    viewer: &ViewerHandle,
    duration: Option<Duration>,
    interrupted: &std::sync::atomic::AtomicBool,
) {
    let started = Instant::now();
    let mut next = started + Duration::from_secs(1);
    loop {
        let now = Instant::now();
        if duration.is_some_and(|limit| now.duration_since(started) >= limit)
            || interrupted.load(std::sync::atomic::Ordering::Acquire)
        {
            break;
        }
        let wake = duration.map_or(next, |limit| next.min(started + limit));
        std::thread::sleep(
            wake.saturating_duration_since(now)
                .min(Duration::from_millis(50)),
        );
        if Instant::now() >= next {
            println!("{}", stats_line(&viewer.stats()));
            next += Duration::from_secs(1);
        }
    }
    println!("final: {}", stats_line(&viewer.stats()));
}

/// wgpu's GL backend, which kiss3d always enables, probes for a Wayland display; with no `XDG_RUNTIME_DIR` (a
/// CI runner, an ssh session, a service) libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set in the
/// environment.` twice, which reads as a failure of the render. Offscreen rendering needs no display: when the
/// variable is unset or not a directory, point it at a private empty one, so the probe fails quietly.
fn give_the_graphics_stack_a_runtime_dir() {
    use std::os::unix::fs::MetadataExt;
    let valid = std::env::var_os("XDG_RUNTIME_DIR")
        .filter(|dir| !dir.is_empty())
        .is_some_and(|dir| Path::new(&dir).is_dir());
    if valid {
        return;
    }
    let Ok(uid) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
        return;
    };
    // One per user, reused; refused if someone else made it or opened it up.
    let dir = std::env::temp_dir().join(format!("sinew-viewer-runtime-{uid}"));
    if create_private_dir(&dir).is_err()
        || std::fs::symlink_metadata(&dir)
            .map(|m| !m.is_dir() || m.uid() != uid || m.mode() & 0o077 != 0)
            .unwrap_or(true)
    {
        return; // the probe then prints its line; rendering works either way
    }
    // SAFETY: called first thing in `main`, before tracing, zenoh or any other thread exists, so no other thread
    // can read or write the environment concurrently.
    #[allow(unsafe_code)]
    unsafe {
        std::env::set_var("XDG_RUNTIME_DIR", &dir);
    }
}

fn create_private_dir(dir: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::DirBuilderExt;
    match std::fs::DirBuilder::new().mode(0o700).create(dir) {
        Err(e) if e.kind() != std::io::ErrorKind::AlreadyExists => Err(e),
        _ => Ok(()),
    }
}

fn run_png(viewer: &ViewerHandle, args: &Args, path: &Path, endpoints: &str) -> Result<()> {
    let wait = seconds(args.wait_s, "wait-s")?;
    if !viewer.wait_for_snapshot(wait) {
        bail!(
            "no snapshot of scene `{}` within {:.1} s ({endpoints}); is sinew-server running and reachable? last stats: {}",
            args.scene,
            args.wait_s,
            stats_line(&viewer.stats())
        );
    }
    std::thread::sleep(seconds(args.after_s, "after-s")?);
    let replica = viewer.replica();
    let overlay = InstructorOverlay::build(&replica, viewer.server_stats().as_ref());
    let stats = render_png_with_overlay(&replica, Some(&overlay), path, args.width, args.height)
        .with_context(|| format!("rendering scene `{}` to {}", args.scene, path.display()))?;
    println!(
        "wrote {} ({}x{}, {} objects, {} triangles, {} tools, {} covered pixels, frame {}, {:.0} ms)",
        path.display(),
        stats.width,
        stats.height,
        stats.objects,
        stats.triangles,
        stats.tools,
        stats.covered_pixels,
        replica.frame(),
        stats.render_ms
    );
    println!("{}", stats_line(&viewer.stats()));
    Ok(())
}
