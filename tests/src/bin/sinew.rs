//! `sinew`: the launcher. `sinew demo` runs a server, two simulated surgeons and a viewer in one go.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Parser, Subcommand};
use sinew::demo::{DemoOptions, run_demo};
use sinew_protocol::network::DEFAULT_ENDPOINT;

/// Sinew: networked haptic surgical simulation.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Server + two simulated hapticservers + a viewer over zenoh on loopback, with live figures.
    Demo {
        /// World file.
        #[arg(long, default_value = "worlds/pad.toml")]
        world: PathBuf,
        /// How long to run, seconds.
        #[arg(long, default_value_t = 10.0)]
        duration_s: f64,
        /// The server's TCP endpoint; it also listens on the same port over UDP, where the devices send poses
        /// and get forces (multilink), and the viewer connects to TCP alone.
        #[arg(long, default_value = DEFAULT_ENDPOINT)]
        listen: String,
        /// Open the viewer window (needs a display).
        #[arg(long)]
        window: bool,
        /// Write a PNG of the viewer's replica at the end.
        #[arg(long)]
        png: Option<PathBuf>,
        /// Emulate a distant server: this round trip (ms) between the devices and the server, half on the
        /// poses and half on the forces. Feel (or read in the summary) what distance does to each mode.
        #[arg(long, default_value_t = 0.0)]
        rtt_ms: f64,
        /// How the devices render forces: direct, moderated or auto.
        #[arg(long, default_value = "auto")]
        mode: hapticserver::ModePolicy,
        /// The simulated surgeons' hand: grip (default), light, nominal or firm. The light hand is the
        /// hardest for stability: try `--rtt-ms 100 --hand light` with `--mode direct`, then `moderated`.
        #[arg(long, default_value = "grip")]
        hand: hapticserver::HandPreset,
    },
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .init();
    match Args::parse().command {
        Command::Demo {
            world,
            duration_s,
            listen,
            window,
            png,
            rtt_ms,
            mode,
            hand,
        } => {
            anyhow::ensure!(
                duration_s.is_finite() && duration_s > 0.0,
                "--duration-s must be positive"
            );
            run_demo(&DemoOptions {
                world,
                endpoint: listen,
                duration: Duration::from_secs_f64(duration_s),
                window,
                png,
                rtt_ms,
                mode,
                hand,
            })?;
        }
    }
    Ok(())
}
