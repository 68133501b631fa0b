//! `sinew-web`'s HTTP side: the instructor's page, three.js, and a WebSocket per page that carries the feed
//! ([`crate::web_feed`]) from one scene replica.
//!
//! Owns: the routes (`/` the page, `/static/*` its scripts, `/vendor/three/*` three.js as npm installed it,
//! `/feed` the WebSocket, `/stats.json` the gateway's counters), the feed task that builds a frame from the
//! replica at the feed rate, and one task per page that sends it what it lacks.
//!
//! Threads: a tokio runtime the caller provides. The replica is read under the viewer's lock for the time it
//! takes to encode what changed (about a millisecond for a 5000-vertex sheet); pages never touch it. Frames
//! go to the pages through a latest-value channel (`tokio::sync::watch`): a slow page skips frames instead
//! of queueing them, and a page that takes longer than [`SEND_TIMEOUT`] to take one message is dropped.
//!
//! Must not: write to the scene. Read-only by construction: the gateway holds a viewer (it subscribes and
//! queries, never publishes to a scene key), and nothing a page sends is decoded; it is counted and dropped.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Json, Response};
use axum::routing::get;
use serde::Serialize;
use tokio::sync::watch;
use tower_http::services::{ServeDir, ServeFile};

use crate::client::ViewerHandle;
use crate::web_feed::{FeedBuilder, FeedCursor, FeedFrame};

/// A page that does not take one message within this long is dropped (it reconnects and catches up).
pub const SEND_TIMEOUT: Duration = Duration::from_secs(5);

/// How `sinew-web` serves.
#[derive(Debug, Clone)]
pub struct WebConfig {
    /// Where to listen (port 0: any free port; [`WebGateway::local_addr`] says which).
    pub listen: SocketAddr,
    /// The page's folder: `static/` (index.html and its scripts) and `node_modules/three` (`npm ci` there).
    pub web_root: PathBuf,
    /// Feed frames per second.
    pub rate_hz: f64,
    /// Most pages at once; more are refused with 503.
    pub max_pages: u64,
}

impl WebConfig {
    /// The page's folder in this source tree (`viewer/web`).
    pub fn default_web_root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("web")
    }
}

/// Why the gateway could not start.
#[derive(Debug, thiserror::Error)]
pub enum WebError {
    /// A file the page needs is missing.
    #[error("{path} is missing: {hint}")]
    Missing {
        /// The missing file.
        path: PathBuf,
        /// What to do about it.
        hint: &'static str,
    },
    /// The feed rate is not a positive number up to 240 Hz.
    #[error("the feed rate must be above 0 and at most 240 Hz, got {0}")]
    Rate(f64),
    /// Could not listen.
    #[error("listening on {addr}: {source}")]
    Listen {
        /// The address.
        addr: SocketAddr,
        /// The cause.
        source: std::io::Error,
    },
}

/// The gateway's counters, served at `/stats.json`.
#[derive(Debug, Default)]
pub struct WebCounters {
    pages_open: AtomicU64,
    pages_served: AtomicU64,
    pages_refused: AtomicU64,
    pages_dropped_slow: AtomicU64,
    frames_built: AtomicU64,
    messages_sent: AtomicU64,
    bytes_sent: AtomicU64,
    page_messages_ignored: AtomicU64,
}

/// A copy of [`WebCounters`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct WebStats {
    /// Pages connected now.
    pub pages_open: u64,
    /// Pages that connected since the start.
    pub pages_served: u64,
    /// Pages refused (over the limit).
    pub pages_refused: u64,
    /// Pages dropped for taking too long to take a message.
    pub pages_dropped_slow: u64,
    /// Feed frames built.
    pub frames_built: u64,
    /// Messages sent over all pages.
    pub messages_sent: u64,
    /// Bytes sent over all pages (message payloads).
    pub bytes_sent: u64,
    /// Messages pages sent, ignored.
    pub page_messages_ignored: u64,
    /// The replica's frame the last feed frame was built at (0 before a snapshot).
    pub replica_frame: u64,
}

impl WebCounters {
    fn snapshot(&self, replica_frame: u64) -> WebStats {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        WebStats {
            pages_open: get(&self.pages_open),
            pages_served: get(&self.pages_served),
            pages_refused: get(&self.pages_refused),
            pages_dropped_slow: get(&self.pages_dropped_slow),
            frames_built: get(&self.frames_built),
            messages_sent: get(&self.messages_sent),
            bytes_sent: get(&self.bytes_sent),
            page_messages_ignored: get(&self.page_messages_ignored),
            replica_frame,
        }
    }
}

#[derive(Clone)]
struct App {
    viewer: Arc<ViewerHandle>,
    frames: watch::Receiver<Option<Arc<FeedFrame>>>,
    counters: Arc<WebCounters>,
    max_pages: u64,
}

/// A running gateway: its address and counters. Dropping it does not stop it; call [`WebGateway::run`].
pub struct WebGateway {
    listener: tokio::net::TcpListener,
    router: Router,
    feed: FeedTask,
    counters: Arc<WebCounters>,
    viewer: Arc<ViewerHandle>,
}

struct FeedTask {
    viewer: Arc<ViewerHandle>,
    frames: watch::Sender<Option<Arc<FeedFrame>>>,
    counters: Arc<WebCounters>,
    period: Duration,
}

impl FeedTask {
    async fn run(self) {
        let mut builder = FeedBuilder::new();
        let mut ticks = tokio::time::interval(self.period);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        loop {
            ticks.tick().await;
            if self.frames.is_closed() {
                return;
            }
            let stats = self.viewer.server_stats();
            let frame = self
                .viewer
                .with_replica(|replica| builder.build(replica, stats.as_ref()));
            if let Some(frame) = frame {
                self.counters.frames_built.fetch_add(1, Ordering::Relaxed);
                self.frames.send_replace(Some(frame));
            }
        }
    }
}

impl WebGateway {
    /// Check the page's files, bind the listener and build the routes. Serving starts with [`Self::run`].
    pub async fn bind(config: WebConfig, viewer: Arc<ViewerHandle>) -> Result<Self, WebError> {
        if !(config.rate_hz > 0.0 && config.rate_hz <= 240.0) {
            return Err(WebError::Rate(config.rate_hz));
        }
        let page = config.web_root.join("static/index.html");
        let three = config
            .web_root
            .join("node_modules/three/build/three.module.js");
        if !page.is_file() {
            return Err(WebError::Missing {
                path: page,
                hint: "pass --web-root the viewer/web folder of a Sinew checkout",
            });
        }
        if !three.is_file() {
            return Err(WebError::Missing {
                path: three,
                hint: "three.js is not installed: run `npm ci --prefix viewer/web` (the README's set-up does)",
            });
        }
        let listener = tokio::net::TcpListener::bind(config.listen)
            .await
            .map_err(|source| WebError::Listen {
                addr: config.listen,
                source,
            })?;
        let counters = Arc::new(WebCounters::default());
        let (sender, frames) = watch::channel(None);
        let app = App {
            viewer: Arc::clone(&viewer),
            frames,
            counters: Arc::clone(&counters),
            max_pages: config.max_pages,
        };
        let router = Router::new()
            .route_service("/", ServeFile::new(page))
            .nest_service("/static", ServeDir::new(config.web_root.join("static")))
            .nest_service(
                "/vendor/three",
                ServeDir::new(config.web_root.join("node_modules/three")),
            )
            .route("/feed", get(open_feed))
            .route("/stats.json", get(stats_json))
            .with_state(app);
        Ok(Self {
            listener,
            router,
            feed: FeedTask {
                viewer: Arc::clone(&viewer),
                frames: sender,
                counters: Arc::clone(&counters),
                period: Duration::from_secs_f64(1.0 / config.rate_hz),
            },
            counters,
            viewer,
        })
    }

    /// Where it listens.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Serve until `shutdown` completes.
    pub async fn run(self, shutdown: impl std::future::Future<Output = ()> + Send + 'static) {
        let feed = tokio::spawn(self.feed.run());
        let served = axum::serve(self.listener, self.router)
            .with_graceful_shutdown(shutdown)
            .await;
        if let Err(e) = served {
            tracing::error!("sinew-web stopped serving: {e}");
        }
        feed.abort();
    }

    /// The counters now.
    pub fn counters(&self) -> Arc<WebCounters> {
        Arc::clone(&self.counters)
    }

    /// The counters with the replica's frame.
    pub fn stats(&self) -> WebStats {
        stats_of(&self.counters, &self.viewer)
    }
}

fn stats_of(counters: &WebCounters, viewer: &ViewerHandle) -> WebStats {
    let frame = viewer.with_replica(|r| r.frame());
    counters.snapshot(frame)
}

async fn stats_json(State(app): State<App>) -> Json<WebStats> {
    Json(stats_of(&app.counters, &app.viewer))
}

async fn open_feed(State(app): State<App>, upgrade: WebSocketUpgrade) -> Response {
    // Claim a place before upgrading; give it back if over the limit.
    let open = app.counters.pages_open.fetch_add(1, Ordering::AcqRel);
    if open >= app.max_pages {
        app.counters.pages_open.fetch_sub(1, Ordering::AcqRel);
        app.counters.pages_refused.fetch_add(1, Ordering::Relaxed);
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("sinew-web serves at most {} pages at once", app.max_pages),
        )
            .into_response();
    }
    app.counters.pages_served.fetch_add(1, Ordering::Relaxed);
    upgrade.on_upgrade(move |socket| async move {
        feed_page(socket, &app).await;
        app.counters.pages_open.fetch_sub(1, Ordering::AcqRel);
    })
}

/// Send one page what it lacks whenever a frame is built, until it closes or stalls.
async fn feed_page(mut socket: WebSocket, app: &App) {
    let mut frames = app.frames.clone();
    let mut cursor = FeedCursor::new();
    // The newest frame at once: a page opened late catches up without waiting for a change.
    let mut pending = frames.borrow_and_update().clone();
    loop {
        if let Some(frame) = pending.take() {
            for message in cursor.messages_for(&frame) {
                let bytes = message.len() as u64;
                match tokio::time::timeout(SEND_TIMEOUT, socket.send(Message::Binary(message)))
                    .await
                {
                    Ok(Ok(())) => {
                        app.counters.messages_sent.fetch_add(1, Ordering::Relaxed);
                        app.counters.bytes_sent.fetch_add(bytes, Ordering::Relaxed);
                    }
                    Ok(Err(_)) => return,
                    Err(_) => {
                        app.counters
                            .pages_dropped_slow
                            .fetch_add(1, Ordering::Relaxed);
                        return;
                    }
                }
            }
        }
        tokio::select! {
            changed = frames.changed() => {
                if changed.is_err() {
                    return; // the gateway is stopping
                }
                pending = frames.borrow_and_update().clone();
            }
            incoming = socket.recv() => match incoming {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                // Read-only: whatever a page sends is counted and dropped (pings are answered by axum).
                Some(Ok(_)) => {
                    app.counters.page_messages_ignored.fetch_add(1, Ordering::Relaxed);
                }
            },
        }
    }
}
