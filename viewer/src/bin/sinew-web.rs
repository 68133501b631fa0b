//! `sinew-web`: watch a Sinew scene from a browser. Joins the scene as a viewer (read-only), and serves the
//! instructor's page and its WebSocket feed over HTTP.
//!
//! Owns: flag parsing and wiring the viewer client to the gateway ([`sinew_viewer::web_server`]).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Parser;
use sinew_protocol::network::NetworkOptions;
use sinew_viewer::web_server::{WebConfig, WebGateway};
use sinew_viewer::{ViewerClient, ViewerConfig};

/// Watch a Sinew scene from a browser: serve the instructor's page for the scene this process replicates.
#[derive(Debug, Parser)]
#[command(name = "sinew-web", version, about)]
struct Args {
    /// Scene to join.
    #[arg(long, default_value = "pad")]
    scene: String,
    /// This gateway's participant id [default: web-<pid>].
    #[arg(long)]
    id: Option<String>,
    /// zenoh endpoints and mode.
    #[command(flatten)]
    network: sinew_protocol::cli::NetworkArgs,
    /// Where the page is served (`0.0.0.0:8090` for the lab's network; port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:8090", value_name = "ADDR:PORT")]
    http: SocketAddr,
    /// The page's folder (static/ and node_modules/three, from `npm ci --prefix viewer/web`).
    #[arg(long, value_name = "DIR")]
    web_root: Option<PathBuf>,
    /// Feed frames per second sent to each page.
    #[arg(long, default_value_t = 30.0, value_name = "HZ")]
    rate_hz: f64,
    /// Most pages at once.
    #[arg(long, default_value_t = 32)]
    max_pages: u64,
    /// Stop after this many seconds [default: run until killed].
    #[arg(long, value_name = "SECONDS")]
    duration_s: Option<f64>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
    let duration = args
        .duration_s
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .with_context(|| format!("--duration-s must be a non-negative number, got {s}"))
        })
        .transpose()?;
    let viewer_id = args
        .id
        .clone()
        .unwrap_or_else(|| format!("web-{}", std::process::id()));
    let config = ViewerConfig {
        network: args.network.options(NetworkOptions::client_default()),
        ..ViewerConfig::new(args.scene.clone(), viewer_id.clone())
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("sinew-web")
        .enable_all()
        .build()
        .context("starting the gateway's runtime")?;
    let web = WebConfig {
        listen: args.http,
        web_root: args
            .web_root
            .clone()
            .unwrap_or_else(WebConfig::default_web_root),
        rate_hz: args.rate_hz,
        max_pages: args.max_pages,
    };
    let viewer = Arc::new(
        ViewerClient::start(config)
            .with_context(|| format!("joining scene `{}` as `{viewer_id}`", args.scene))?,
    );
    let result = runtime.block_on(async {
        let gateway = WebGateway::bind(web, Arc::clone(&viewer)).await?;
        let addr = gateway.local_addr()?;
        // The one line a launcher (or a test) reads to find the page.
        println!("sinew-web: scene `{}` at http://{addr}/", args.scene);
        gateway.run(stop_signal(duration)).await;
        anyhow::Ok(())
    });
    drop(runtime);
    if let Ok(mut viewer) = Arc::try_unwrap(viewer) {
        viewer.stop();
    }
    result
}

/// Ctrl-C, SIGTERM, or the end of `--duration-s`.
async fn stop_signal(duration: Option<Duration>) {
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut term) => {
                term.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    let limit = async {
        match duration {
            Some(d) => tokio::time::sleep(d).await,
            None => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = terminate => {}
        _ = limit => {}
    }
}
