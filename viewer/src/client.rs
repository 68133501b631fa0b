//! The networked viewer: a zenoh session that keeps a [`SceneReplica`] in sync with the server.
//!
//! Owns: the viewer's zenoh session, its presence token, its subscriptions (mesh deltas, tool states, server
//! stats, server presence) and the sync worker thread `sinew-viewer-sync`, which queries the snapshot on join
//! (retrying with backoff until a server answers), after every gap, and when a server (re)joins.
//!
//! Threads: zenoh callbacks decode outside the lock, then update the shared `SyncState` under one mutex for a
//! few microseconds; they never block and never call zenoh. Only the worker thread issues (blocking) snapshot
//! queries. Readers copy the replica ([`ViewerHandle::replica`]) or borrow it briefly
//! ([`ViewerHandle::with_replica`]).
//!
//! Must not: write to the scene (a viewer only reads), depend on the server crate, or render.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use sinew_protocol::keys::SceneKeys;
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::JoinedServer;
use sinew_protocol::{
    DecodeError, MeshDelta, Message, Role, SceneSnapshot, ServerStats, ToolStates, decode_from,
};
use zenoh::Wait;
use zenoh::sample::{Sample, SampleKind};

use crate::error::ViewerError;
use crate::network_config::zenoh_config;
use crate::replica::SceneReplica;
use crate::sync_state::SyncState;
use crate::viewer_stats::ViewerStats;

/// First wait between failed snapshot queries.
const BACKOFF_MIN: Duration = Duration::from_millis(100);
/// Longest wait between failed snapshot queries.
const BACKOFF_MAX: Duration = Duration::from_secs(2);
/// The worker wakes at least this often to refresh rates and check for stop.
const WORKER_TICK: Duration = Duration::from_millis(100);

/// What a viewer joins and how.
#[derive(Debug, Clone)]
pub struct ViewerConfig {
    /// Scene name (the `<scene>` key segment).
    pub scene: String,
    /// This viewer's participant id (its presence key segment).
    pub viewer_id: String,
    /// zenoh endpoints and config file.
    pub network: NetworkOptions,
    /// How long one snapshot query waits for a reply.
    pub snapshot_timeout: Duration,
    /// Deltas kept while a snapshot is pending; the oldest are dropped beyond this.
    pub delta_buffer_capacity: usize,
}

impl ViewerConfig {
    /// Defaults: connect to the default endpoint, 2 s per snapshot query, 4096 buffered deltas.
    pub fn new(scene: impl Into<String>, viewer_id: impl Into<String>) -> Self {
        Self {
            scene: scene.into(),
            viewer_id: viewer_id.into(),
            network: NetworkOptions::client_default(),
            snapshot_timeout: Duration::from_secs(2),
            delta_buffer_capacity: 4096,
        }
    }
}

/// Starts viewers.
#[derive(Debug, Clone, Copy)]
pub struct ViewerClient;

impl ViewerClient {
    /// Open a zenoh session, announce presence, subscribe, and start the sync worker. Returns at once: the
    /// snapshot arrives in the background (see [`ViewerHandle::wait_for_snapshot`]); the server may start
    /// later than the viewer.
    pub fn start(config: ViewerConfig) -> Result<ViewerHandle, ViewerError> {
        let keys = SceneKeys::new(&config.scene)?;
        let presence_key = keys.presence(Role::Viewer, &config.viewer_id)?;
        let zenoh_config = zenoh_config(&config.network)?;
        let session = zenoh::open(zenoh_config)
            .wait()
            .map_err(|e| ViewerError::zenoh("opening session", e))?;
        let shared = Arc::new(Shared {
            state: Mutex::new(SyncState::new(config.delta_buffer_capacity)),
            wake_worker: Condvar::new(),
            snapshot_ready: Condvar::new(),
            stop: AtomicBool::new(false),
            server: JoinedServer::new(),
            epoch: Instant::now(),
        });

        let mut handle = ViewerHandle {
            shared: Arc::clone(&shared),
            worker: None,
            subscribers: Vec::new(),
            token: None,
            session: Some(session.clone()),
            keys: keys.clone(),
            config: config.clone(),
        };
        // From here on, an early return drops `handle`, which undeclares what was declared and closes the session.

        let token = session
            .liveliness()
            .declare_token(&presence_key)
            .wait()
            .map_err(|e| {
                ViewerError::zenoh(format!("declaring presence token {presence_key}"), e)
            })?;
        handle.token = Some(token);

        // Subscribe before the first snapshot query, so no delta published after the snapshot is missed.
        let deltas_key = keys.all_mesh_deltas();
        let for_deltas = Arc::clone(&shared);
        let subscriber = session
            .declare_subscriber(&deltas_key)
            .callback(move |sample: Sample| {
                let payload = sample.payload().to_bytes();
                let Some(decoded) = for_deltas.admit::<MeshDelta>(&payload) else {
                    return;
                };
                let wake = for_deltas.lock().on_delta(payload.len(), decoded);
                if wake {
                    for_deltas.wake_worker.notify_all();
                }
            })
            .wait()
            .map_err(|e| ViewerError::zenoh(format!("subscribing to {deltas_key}"), e))?;
        handle.subscribers.push(subscriber);

        let tools_key = keys.tools();
        let for_tools = Arc::clone(&shared);
        let subscriber = session
            .declare_subscriber(&tools_key)
            .callback(move |sample: Sample| {
                let payload = sample.payload().to_bytes();
                let Some(decoded) = for_tools.admit::<ToolStates>(&payload) else {
                    return;
                };
                for_tools.lock().on_tools(payload.len(), decoded);
            })
            .wait()
            .map_err(|e| ViewerError::zenoh(format!("subscribing to {tools_key}"), e))?;
        handle.subscribers.push(subscriber);

        let stats_key = keys.stats();
        let for_stats = Arc::clone(&shared);
        let subscriber = session
            .declare_subscriber(&stats_key)
            .callback(move |sample: Sample| {
                let payload = sample.payload().to_bytes();
                let Some(decoded) = for_stats.admit::<ServerStats>(&payload) else {
                    return;
                };
                for_stats.lock().on_server_stats(payload.len(), decoded);
            })
            .wait()
            .map_err(|e| ViewerError::zenoh(format!("subscribing to {stats_key}"), e))?;
        handle.subscribers.push(subscriber);

        let servers_key = keys.all_presence(Role::Server);
        let for_presence = Arc::clone(&shared);
        let presence_keys = keys.clone();
        let subscriber = session
            .liveliness()
            .declare_subscriber(&servers_key)
            .history(true)
            .callback(move |sample: Sample| {
                let key = sample.key_expr().as_str();
                let Some(server_id) = presence_keys.presence_id_of(Role::Server, key) else {
                    return;
                };
                let alive = sample.kind() == SampleKind::Put;
                if !alive {
                    // The joined server left: the next server heard is followed at once.
                    for_presence.server.release();
                }
                let wake = for_presence.lock().on_server_presence(server_id, alive);
                if wake {
                    for_presence.wake_worker.notify_all();
                }
            })
            .wait()
            .map_err(|e| {
                ViewerError::zenoh(format!("watching server presence {servers_key}"), e)
            })?;
        handle.subscribers.push(subscriber);

        let worker = SyncWorker {
            shared,
            session,
            snapshot_key: keys.snapshot(),
            query_timeout: config.snapshot_timeout,
        };
        let name = "sinew-viewer-sync";
        let join = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(move || worker.run())
            .map_err(|source| ViewerError::Thread { name, source })?;
        handle.worker = Some(join);
        tracing::info!(
            scene = %config.scene,
            viewer_id = %config.viewer_id,
            "viewer started; querying {}",
            keys.snapshot()
        );
        Ok(handle)
    }
}

/// What the callbacks, the worker and the handle share.
#[derive(Debug)]
struct Shared {
    state: Mutex<SyncState>,
    wake_worker: Condvar,
    snapshot_ready: Condvar,
    stop: AtomicBool,
    /// The server this viewer follows; messages from any other live server for the scene are dropped.
    server: JoinedServer,
    epoch: Instant,
}

impl Shared {
    /// Decode a payload; `None` if it comes from a server other than the joined one (dropped, counted).
    fn admit<M: Message>(&self, payload: &[u8]) -> Option<Result<M, DecodeError>> {
        match decode_from::<M>(payload) {
            Ok((from, msg)) => {
                let now_ns = self.epoch.elapsed().as_nanos() as u64;
                self.server
                    .admit(from, now_ns)
                    .admitted()
                    .then_some(Ok(msg))
            }
            Err(err) => Some(Err(err)),
        }
    }

    fn lock(&self) -> MutexGuard<'_, SyncState> {
        // Nothing panics while holding the lock; if something ever did, the state is still consistent
        // (every SyncState method leaves it valid), so keep going.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn stopping(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }
}

/// The `sinew-viewer-sync` thread: snapshot queries with backoff, rates.
struct SyncWorker {
    shared: Arc<Shared>,
    session: zenoh::Session,
    snapshot_key: String,
    query_timeout: Duration,
}

/// Why a snapshot query produced nothing usable.
enum FetchFailure {
    /// The viewer is stopping.
    Stopped,
    /// The query could not be sent, or ended without a usable reply (the reason says which).
    Failed(String),
}

impl SyncWorker {
    fn run(self) {
        let mut backoff = BACKOFF_MIN;
        let mut failures_in_a_row = 0u32;
        while !self.shared.stopping() {
            self.shared.lock().update_rates(Instant::now());
            if !self.shared.lock().needs_snapshot() {
                let guard = self.shared.lock();
                let _unused = self
                    .shared
                    .wake_worker
                    .wait_timeout_while(guard, WORKER_TICK, |s| {
                        !s.needs_snapshot() && !self.shared.stopping()
                    })
                    .unwrap_or_else(PoisonError::into_inner);
                continue;
            }
            self.shared.lock().on_snapshot_query();
            let started = Instant::now();
            let in_sync = match self.fetch_snapshot() {
                Ok(snapshot) => {
                    let frame = snapshot.frame;
                    let in_sync = self
                        .shared
                        .lock()
                        .install_snapshot(snapshot, started.elapsed());
                    self.shared.snapshot_ready.notify_all();
                    tracing::info!(
                        frame,
                        fetch_ms = started.elapsed().as_secs_f64() * 1e3,
                        in_sync,
                        "snapshot installed"
                    );
                    in_sync
                }
                Err(FetchFailure::Stopped) => break,
                Err(FetchFailure::Failed(reason)) => {
                    self.shared.lock().on_snapshot_failed();
                    if failures_in_a_row == 0 {
                        tracing::info!(key = %self.snapshot_key, %reason, "no snapshot yet; retrying with backoff");
                    } else {
                        tracing::debug!(key = %self.snapshot_key, %reason, "no snapshot yet");
                    }
                    failures_in_a_row += 1;
                    false
                }
            };
            if in_sync {
                backoff = BACKOFF_MIN;
                failures_in_a_row = 0;
                continue;
            }
            self.sleep_backoff(backoff);
            backoff = (backoff * 2).min(BACKOFF_MAX);
        }
    }

    /// Wait `backoff`, or less if stopping or a server just appeared.
    fn sleep_backoff(&self, backoff: Duration) {
        let deadline = Instant::now() + backoff;
        let mut guard = self.shared.lock();
        loop {
            if self.shared.stopping() || guard.take_retry_now() {
                return;
            }
            let now = Instant::now();
            if now >= deadline {
                return;
            }
            guard = self
                .shared
                .wake_worker
                .wait_timeout(guard, (deadline - now).min(WORKER_TICK))
                .unwrap_or_else(PoisonError::into_inner)
                .0;
            guard.update_rates(Instant::now());
        }
    }

    /// One snapshot query: the first reply that decodes wins. Blocks up to the query timeout (plus a margin),
    /// checking for stop every tick.
    fn fetch_snapshot(&self) -> Result<SceneSnapshot, FetchFailure> {
        let replies = self
            .session
            .get(&self.snapshot_key)
            .timeout(self.query_timeout)
            .wait()
            .map_err(|e| FetchFailure::Failed(format!("query not sent: {e}")))?;
        let deadline = Instant::now() + self.query_timeout + Duration::from_millis(500);
        let mut last_problem = None;
        loop {
            if self.shared.stopping() {
                return Err(FetchFailure::Stopped);
            }
            match replies.recv_timeout(WORKER_TICK) {
                Ok(Some(reply)) => match reply.result() {
                    Ok(sample) => {
                        let payload = sample.payload().to_bytes();
                        let Some(decoded) = self.shared.admit::<SceneSnapshot>(&payload) else {
                            last_problem = Some("a reply from another live server".to_owned());
                            continue;
                        };
                        self.shared
                            .lock()
                            .on_snapshot_payload(payload.len(), &decoded);
                        match decoded {
                            Ok(snapshot) => return Ok(snapshot),
                            Err(err) => last_problem = Some(format!("undecodable reply: {err}")),
                        }
                    }
                    Err(err) => {
                        let text = err.payload().try_to_string().map(|s| s.into_owned());
                        last_problem = Some(format!("error reply: {}", text.unwrap_or_default()));
                    }
                },
                Ok(None) => {
                    self.shared.lock().update_rates(Instant::now());
                    if Instant::now() >= deadline {
                        return Err(FetchFailure::Failed(last_problem.unwrap_or_else(|| {
                            format!("no reply within {:?}", self.query_timeout)
                        })));
                    }
                }
                // All replies are in (the query finished or timed out).
                Err(_) => {
                    return Err(FetchFailure::Failed(last_problem.unwrap_or_else(|| {
                        "no snapshot queryable answered (is the server running and reachable?)"
                            .to_owned()
                    })));
                }
            }
        }
    }
}

/// A running viewer. Dropping it stops the worker and closes the session.
pub struct ViewerHandle {
    shared: Arc<Shared>,
    worker: Option<JoinHandle<()>>,
    subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
    token: Option<zenoh::liveliness::LivelinessToken>,
    session: Option<zenoh::Session>,
    keys: SceneKeys,
    config: ViewerConfig,
}

impl std::fmt::Debug for ViewerHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewerHandle")
            .field("config", &self.config)
            .field("running", &self.worker.is_some())
            .finish_non_exhaustive()
    }
}

impl ViewerHandle {
    /// A copy of the replica (allocates; see [`Self::with_replica`] to avoid the copy).
    pub fn replica(&self) -> SceneReplica {
        self.shared.lock().replica().clone()
    }

    /// Run `f` on the replica under the lock. Keep `f` short: zenoh callbacks wait while it runs.
    pub fn with_replica<R>(&self, f: impl FnOnce(&SceneReplica) -> R) -> R {
        f(self.shared.lock().replica())
    }

    /// Counters, rates and replica position.
    pub fn stats(&self) -> ViewerStats {
        let mut stats = self.shared.lock().stats();
        stats.from_other_server = self.shared.server.foreign();
        stats
    }

    /// The latest server stats, if any arrived.
    pub fn server_stats(&self) -> Option<ServerStats> {
        self.shared.lock().server_stats().cloned()
    }

    /// Block until a snapshot has been applied, or `timeout` passes. Returns whether one was.
    pub fn wait_for_snapshot(&self, timeout: Duration) -> bool {
        let guard = self.shared.lock();
        let (guard, _) = self
            .shared
            .snapshot_ready
            .wait_timeout_while(guard, timeout, |s| {
                !s.replica().has_snapshot() && !self.shared.stopping()
            })
            .unwrap_or_else(PoisonError::into_inner);
        guard.replica().has_snapshot()
    }

    /// The scene's key expressions.
    pub fn keys(&self) -> &SceneKeys {
        &self.keys
    }

    /// The configuration this viewer started with.
    pub fn config(&self) -> &ViewerConfig {
        &self.config
    }

    /// Stop the worker, undeclare subscriptions and presence, close the session. Idempotent.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        self.shared.wake_worker.notify_all();
        self.shared.snapshot_ready.notify_all();
        if let Some(worker) = self.worker.take()
            && worker.join().is_err()
        {
            tracing::error!("sinew-viewer-sync thread panicked");
        }
        let subscribers = std::mem::take(&mut self.subscribers);
        let token = self.token.take();
        let Some(session) = self.session.take() else {
            return;
        };
        // Within half a second whatever the network does (a partition would hold zenoh's close for its lease).
        let finished = sinew_protocol::rt::finish_within(
            "sinew-viewer-close",
            Duration::from_millis(500),
            move || {
                drop(subscribers);
                drop(token);
                if let Err(err) = session.close().wait() {
                    tracing::warn!(%err, "closing zenoh session");
                }
            },
        );
        if !finished {
            tracing::warn!("zenoh could not say goodbye within 500 ms (server unreachable?)");
        }
    }
}

impl Drop for ViewerHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handle_can_be_shared_across_threads() {
        fn assert_send_sync<T: Send + Sync>() {}
        assert_send_sync::<ViewerHandle>();
    }

    #[test]
    fn bad_ids_are_refused_before_opening_zenoh() {
        let err = ViewerClient::start(ViewerConfig::new("pad", "a b")).unwrap_err();
        assert!(matches!(err, ViewerError::Key(_)), "{err}");
        let err = ViewerClient::start(ViewerConfig::new("", "v")).unwrap_err();
        assert!(matches!(err, ViewerError::Key(_)), "{err}");
    }
}
