//! The server process's wiring: zenoh session, inbound callbacks, the 1 kHz sim thread, the publish thread.
//!
//! Threads:
//! - `sinew-sim` (dedicated, 1 kHz, spin_sleep paced): newest pose per device from latest-value mailboxes ->
//!   [`crate::sim::Sim::step`] -> one [`sinew_protocol::ForceCommand`] per bound device. No locks held across
//!   a tick (only `try_lock` hand-offs), no logging in the tick.
//! - `sinew-publish` (~60 Hz): mesh deltas of changed vertices, tool states, stats at 1 Hz.
//! - zenoh's own threads run the callbacks: decode, count rejects, store into mailboxes; the snapshot
//!   queryable answers from the publish thread's replication state.
//!
//! Must not: do physics here (that is [`crate::sim`]).

pub mod access_refusals;
mod device_slots;
mod inbound;
mod keepalive;
mod publish_loop;
mod session;
mod sim_loop;
pub mod step_threads;
pub mod tick_cost;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::{EmulationConfig, Throttle};
use sinew_protocol::{InstanceId, Role, ServerStats, keys::SceneKeys};
use thiserror::Error;
use zenoh::Wait;

pub use crate::replication::{FrameExchange, ReplicationState};
pub use device_slots::{DeviceSlot, DeviceSlots};
pub use publish_loop::{exercise_stats, training_stats};
pub use session::open_session;
pub use sim_loop::{DeviceReport, LiveTraining, ReplayProgress, SimReport};

use crate::scene::World;
use crate::sim::Sim;

/// Why the server could not start.
#[derive(Debug, Error)]
pub enum ServerError {
    /// The world could not become a simulation.
    #[error(transparent)]
    Build(#[from] crate::sim::SimBuildError),
    /// A zenoh operation failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// An id cannot be a key segment.
    #[error(transparent)]
    Key(#[from] sinew_protocol::keys::KeyError),
    /// A thread could not be spawned.
    #[error("spawning thread: {0}")]
    Thread(String),
    /// The recording could not start (nothing was started).
    #[error(transparent)]
    Record(#[from] crate::recording::RecordError),
    /// A replay was asked for with a bad speed, or while recording.
    #[error("cannot publish the replay: {0}")]
    Replay(String),
    /// Another server is already live for this scene.
    #[error(
        "another server is already live for scene `{scene}` ({found}): refusing to start a second one. \
         Stop it first, or give this server another scene"
    )]
    AnotherServer {
        /// The scene.
        scene: String,
        /// The presence keys found.
        found: String,
    },
}

impl From<zenoh::Error> for ServerError {
    fn from(e: zenoh::Error) -> Self {
        ServerError::Zenoh(e.to_string())
    }
}

/// How to run the server.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// zenoh endpoints (default: peer, listen on tcp/127.0.0.1:7447, no multicast scouting).
    pub network: NetworkOptions,
    /// Participant id for the presence token.
    pub server_id: String,
    /// spin_sleep native accuracy for the sim thread, ns (0 = plain sleep; tests share two cores). The sim
    /// thread spins less when its scheduling allows (`protocol::rt::realtime`).
    pub spin_native_accuracy_ns: u32,
    /// Ask for SCHED_FIFO and locked memory for the sim thread (`--realtime`); refused quietly (and reported)
    /// where the process may not have them.
    pub realtime: bool,
    /// Emulated delay, jitter and loss on the force commands this server publishes (`--emulate-*`).
    pub emulation: EmulationConfig,
    /// Fault drill: the sim thread panics at this tick, as a bug in the simulation would (`--fault-panic-at-tick`,
    /// hidden). `None` in every normal run.
    pub panic_at_tick: Option<u64>,
    /// Record every tick's inputs and force commands, with the world, to this MCAP file (`--record`).
    pub record: Option<std::path::PathBuf>,
    /// Run a recording instead of the devices (`sinew replay --publish`): its ticks' inputs drive the tissue,
    /// no force is sent to anyone, and the sim thread stops after the last tick.
    pub replay: Option<ReplayFeed>,
}

/// A recording's ticks to publish, at a speed.
#[derive(Debug, Clone)]
pub struct ReplayFeed {
    /// The recorded ticks, from tick 0 (the world must be the recording's).
    pub ticks: Vec<crate::recording::TickMessage>,
    /// Simulated seconds per wall second (1: as recorded); at most [`MAX_REPLAY_SPEED`].
    pub speed: f64,
}

/// The fastest a published replay may be asked to run (it runs as fast as the tick allows).
pub const MAX_REPLAY_SPEED: f64 = 64.0;

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            network: NetworkOptions::server_default(),
            server_id: "server".into(),
            spin_native_accuracy_ns: 100_000,
            realtime: false,
            emulation: EmulationConfig::default(),
            panic_at_tick: None,
            record: None,
            replay: None,
        }
    }
}

/// State shared between the threads and callbacks of one server.
#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) world: World,
    pub(crate) keys: SceneKeys,
    pub(crate) slots: DeviceSlots,
    pub(crate) frames: FrameExchange,
    pub(crate) replication: std::sync::Mutex<ReplicationState>,
    pub(crate) report: std::sync::Mutex<SimReport>,
    pub(crate) rejects: inbound::RejectCounters,
    pub(crate) stop: AtomicBool,
    /// Set once when a server thread failed (a panic in the sim thread): what happened. The process must stop.
    pub(crate) failure: std::sync::OnceLock<String>,
    /// This run of the server: the sender of everything it publishes.
    pub(crate) instance: InstanceId,
    /// Its presence id.
    pub(crate) server_id: String,
    /// Hellos from ids no tool binds: logged at most every 10 s.
    pub(crate) unknown_hello_log: Throttle,
    /// Other servers heard publishing for this scene.
    pub(crate) foreign_servers: inbound::ForeignServers,
    /// Ticks run so far (the recording's clock for what it hears on the wire).
    pub(crate) ticks_run: std::sync::atomic::AtomicU64,
    /// The sim thread's scheduling, set once when it starts.
    pub(crate) realtime: std::sync::OnceLock<sinew_protocol::rt::realtime::RealtimeGrant>,
}

/// Starts a server.
#[derive(Debug)]
pub struct ServerNode;

impl ServerNode {
    /// Build the sim, open zenoh, declare everything, start the threads.
    pub fn start(world: World, config: ServerConfig) -> Result<ServerHandle, ServerError> {
        if let Some(feed) = &config.replay {
            if !(feed.speed.is_finite() && feed.speed > 0.0 && feed.speed <= MAX_REPLAY_SPEED) {
                return Err(ServerError::Replay(format!(
                    "speed {} is not in (0, {MAX_REPLAY_SPEED}]",
                    feed.speed
                )));
            }
            if config.record.is_some() {
                return Err(ServerError::Replay(
                    "a replay is not recorded again (its recording already exists)".to_owned(),
                ));
            }
        }
        let mut sim = Sim::new(&world)?;
        // Multi-rate objects step on threads of their own (a replay's too: the result is the same to the bit).
        let mut spawn_failed = None;
        sim.set_step_runners(|object| match step_threads::ThreadRunner::spawn(object) {
            Ok(runner) => Box::new(runner),
            Err(err) => {
                spawn_failed = Some(err.to_string());
                Box::new(crate::multirate::InlineRunner::default())
            }
        });
        if let Some(err) = spawn_failed {
            return Err(ServerError::Thread(err));
        }
        // The tissue passes spread over pinned workers beside the tick (the same bits on any count).
        let threads = world
            .tissue_threads
            .unwrap_or_else(crate::world::default_tissue_threads);
        let tissue = if threads > 1 {
            let pool = sinew_parallel::WorkerPool::new(
                threads,
                Some(sinew_protocol::rt::realtime::pin_this_thread),
            )
            .map_err(|e| ServerError::Thread(e.to_string()))?;
            let report = pool.report().to_string();
            sim.set_chunk_runner(Some(std::sync::Arc::new(pool)));
            report
        } else {
            "1 tissue thread (the tick's own)".to_owned()
        };
        tracing::info!("tissue passes: {tissue}");
        for object in &sim.objects {
            if let Some(lane) = object.step_lane() {
                tracing::info!(
                    "object `{}` steps at {:.0} Hz (every {} ticks) on thread sinew-step-{}; the tick renders it \
                     through its local model in between",
                    object.name,
                    world.tick_hz / f64::from(lane.ticks_per_step()),
                    lane.ticks_per_step(),
                    object.name
                );
            }
        }
        // Before zenoh: an unwritable path is refused with nothing started.
        let recording = match &config.record {
            Some(path) => Some(crate::recording::Recorder::start(path, &world)?),
            None => None,
        };
        match tick_cost::estimate(&world) {
            Ok(cost) => match tick_cost::verdict(&world.scene, &cost) {
                // Tight is not a warning: the shipped pad is, and a normal run prints nothing to act on.
                tick_cost::Verdict::Fits(line) | tick_cost::Verdict::Tight(line) => {
                    tracing::info!("{line}")
                }
                tick_cost::Verdict::TooBig(line) => tracing::warn!("{line}"),
            },
            Err(err) => tracing::warn!(%err, "could not estimate the tick cost"),
        }
        let keys = SceneKeys::new(&world.scene)?;
        // With TLS, the roles' certificates say who may publish what: the server enforces it on all it hears.
        let mut network = config.network.clone();
        if network.tls.is_some() && network.access_control.is_none() {
            let device_ids: Vec<String> = world.tools.iter().map(|t| t.device_id.clone()).collect();
            network.access_control = Some(sinew_protocol::security::access_control_json5(
                &world.scene,
                &device_ids,
            ));
        }
        let session = open_session(&network)?;
        let asked = std::time::Instant::now();
        let mut found = session::live_servers(&session, &keys)?;
        tracing::debug!(
            ms = asked.elapsed().as_millis(),
            "asked for other live servers"
        );
        if !found.is_empty() {
            // It may have just died: a silent death (a kill on QUIC links) leaves it present until its lease
            // at the router or peers ends.
            tracing::info!(
                found = %found.join(", "),
                "another server is live for scene `{}`: waiting up to {:?} for it to leave",
                world.scene,
                session::DEPARTURE_WAIT
            );
            while !found.is_empty() && asked.elapsed() < session::DEPARTURE_WAIT {
                std::thread::sleep(std::time::Duration::from_millis(250));
                found = session::live_servers(&session, &keys)?;
            }
        }
        if !found.is_empty() {
            let _ = session.close().wait();
            return Err(ServerError::AnotherServer {
                scene: world.scene.clone(),
                found: found.join(", "),
            });
        }
        let instance = InstanceId::random();
        let shared = Arc::new(Shared {
            keys: keys.clone(),
            slots: DeviceSlots::new(&sim),
            frames: FrameExchange::new(&sim),
            replication: std::sync::Mutex::new(ReplicationState::new(&world, &sim)),
            report: std::sync::Mutex::new(SimReport::new(sim.tools.len())),
            rejects: inbound::RejectCounters::new(),
            stop: AtomicBool::new(false),
            failure: std::sync::OnceLock::new(),
            realtime: std::sync::OnceLock::new(),
            instance,
            server_id: config.server_id.clone(),
            unknown_hello_log: Throttle::new(10_000_000_000),
            foreign_servers: inbound::ForeignServers::new(instance),
            ticks_run: std::sync::atomic::AtomicU64::new(0),
            world,
        });
        let token = session
            .liveliness()
            .declare_token(keys.presence(Role::Server, &config.server_id)?)
            .wait()?;
        let inbound = inbound::declare(&session, &shared)?;
        let (recorder, tap) = match recording {
            Some((recorder, tap)) => (Some(recorder), Some(tap)),
            None => (None, None),
        };
        // What the scene publishes (deltas, tool states, stats, hellos, presence) goes into the recording too,
        // stamped with the tick it was heard at.
        let wire_tap = match &recorder {
            Some(recorder) => {
                let ticks = shared.clone();
                let tick_ns = (1e9 / shared.world.tick_hz).round() as u64;
                Some(crate::recording::WireTap::start(
                    &session,
                    &keys,
                    crate::recording::TapScope {
                        poses_and_forces: false,
                    },
                    Arc::new(move || {
                        ticks
                            .ticks_run
                            .load(Ordering::Relaxed)
                            .saturating_mul(tick_ns)
                    }),
                    recorder.wire_sink(),
                )?)
            }
            None => None,
        };
        let sim_thread = sim_loop::spawn(
            &session,
            shared.clone(),
            sim,
            sim_loop::SimThreadOptions {
                spin_native_accuracy_ns: config.spin_native_accuracy_ns,
                realtime: config.realtime,
                emulation: config.emulation,
                panic_at_tick: config.panic_at_tick,
                recorder: tap,
                replay: config.replay,
            },
        )?;
        let publish_thread = publish_loop::spawn(&session, shared.clone())?;
        Ok(ServerHandle {
            shared,
            session: Some(session),
            sim_thread: Some(sim_thread),
            publish_thread: Some(publish_thread),
            inbound: Some(inbound),
            token: Some(token),
            recorder,
            wire_tap,
            record_summary: None,
            tissue,
        })
    }
}

/// A running server. Dropping it stops the threads and closes the session.
pub struct ServerHandle {
    shared: Arc<Shared>,
    session: Option<zenoh::Session>,
    sim_thread: Option<JoinHandle<()>>,
    publish_thread: Option<JoinHandle<()>>,
    inbound: Option<inbound::Inbound>,
    token: Option<zenoh::liveliness::LivelinessToken>,
    recorder: Option<crate::recording::Recorder>,
    wire_tap: Option<crate::recording::WireTap>,
    record_summary: Option<crate::recording::RecordSummary>,
    tissue: String,
}

/// How long [`ServerHandle::stop`] waits for the publish thread and zenoh's goodbyes once the sim has stopped.
pub const CLOSE_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(500);

impl std::fmt::Debug for ServerHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServerHandle")
            .field("scene", &self.shared.world.scene)
            .finish()
    }
}

impl ServerHandle {
    /// The threads the tissue passes run on (`[sim] threads`), and where the workers were pinned.
    pub fn tissue_threads(&self) -> &str {
        &self.tissue
    }

    /// Current stats (the same content the 1 Hz stats message carries).
    pub fn stats(&self) -> ServerStats {
        publish_loop::build_stats(&self.shared)
    }

    /// The live tick's compute time since start (a copy of the sim thread's histogram, at most 100 ticks old).
    pub fn tick_time(&self) -> sinew_protocol::rt::LatencyHistogram {
        self.shared
            .report
            .lock()
            .map(|r| r.tick_time.clone())
            .unwrap_or_default()
    }

    /// What the sim thread reported last (at most 100 ticks old; final once stopped): per device its
    /// counters and the training layer's live view, and the exercise's running score.
    pub fn sim_report(&self) -> Option<SimReport> {
        self.shared.report.lock().ok().map(|r| r.clone())
    }

    /// A published replay's progress (None: a live session). `finished` once the last recorded tick ran.
    pub fn replay_progress(&self) -> Option<ReplayProgress> {
        self.shared.report.lock().ok().and_then(|r| r.replay)
    }

    /// This run's instance id (the sender in every message it publishes).
    pub fn instance(&self) -> InstanceId {
        self.shared.instance
    }

    /// What the recording wrote, once [`Self::stop`] has finished it (None without `record`).
    pub fn record_summary(&self) -> Option<&crate::recording::RecordSummary> {
        self.record_summary.as_ref()
    }

    /// Ticks the recording dropped so far because its queue was full (0 without `record`).
    pub fn record_dropped(&self) -> u64 {
        self.recorder
            .as_ref()
            .map_or(0, crate::recording::Recorder::dropped)
    }

    /// The scene name.
    pub fn scene(&self) -> &str {
        &self.shared.world.scene
    }

    /// For object `object`: the frame of its last published delta, and the true (unquantized) positions at
    /// that frame, mm. What a replica holding that frame should match within the quantum.
    pub fn published_positions(&self, object: usize) -> Option<(u64, Vec<[f32; 3]>)> {
        let replication = self.shared.replication.lock().ok()?;
        let o = replication.objects.get(object)?;
        Some((o.last_frame(), o.sent_true_mm().to_vec()))
    }

    /// The worst-case replica error for `object`, mm (half a quantum per axis plus f32 rounding, along the diagonal).
    pub fn quantum_error_mm(&self, object: usize) -> Option<f32> {
        let replication = self.shared.replication.lock().ok()?;
        replication
            .objects
            .get(object)
            .map(|o| o.bounds().max_error_mm())
    }

    /// The latest sim positions handed to the publisher, mm (for tests and diagnostics).
    pub fn latest_positions(&self, object: usize) -> Option<Vec<[f32; 3]>> {
        self.shared.frames.latest_positions(object)
    }

    /// The latest burn levels (0-255 per node) handed to the publisher (for tests and diagnostics).
    pub fn latest_burn(&self, object: usize) -> Option<Vec<u8>> {
        self.shared
            .frames
            .with_frame(|frame| frame.burn.get(object).cloned())
            .flatten()
    }

    /// The latest connectivity of an object handed to the publisher: its topology version (cuts and tears so
    /// far), surface triangles and vertex count (for tests and diagnostics).
    pub fn latest_topology(&self, object: usize) -> Option<(u32, Vec<[u32; 3]>, usize)> {
        self.shared
            .frames
            .with_frame(|frame| {
                let topology = frame.topology.get(object)?;
                let vertices = frame.positions_mm.get(object)?.len();
                Some((topology.version, topology.triangles.clone(), vertices))
            })
            .flatten()
    }

    /// Why the server can no longer run, once a thread of it failed (the sim thread panicked; its devices were
    /// sent an explicit zero force first). A process embedding the server must stop when this is `Some`.
    pub fn failure(&self) -> Option<&str> {
        self.shared.failure.get().map(String::as_str)
    }

    /// The sim thread's scheduling (None until the thread has started).
    pub fn realtime(&self) -> Option<&sinew_protocol::rt::realtime::RealtimeGrant> {
        self.shared.realtime.get()
    }

    /// Stop the sim thread, then the publish thread, the declarations and the session, the latter within
    /// [`CLOSE_TIMEOUT`]: a reliable put or a close the network cannot carry (a partition) is abandoned with a
    /// warning, and the clients notice by their lease and silence rules. Idempotent.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        if let Some(thread) = self.sim_thread.take() {
            let _ = thread.join();
        }
        // The sim thread handed over its last tick and the final state (or dropped its tap in a panic): the
        // writer finishes the file.
        let wire_dropped = self
            .wire_tap
            .take()
            .map_or(0, crate::recording::WireTap::stop);
        if let Some(recorder) = self.recorder.take() {
            let mut summary = recorder.join();
            summary.wire_dropped = wire_dropped;
            match &summary.error {
                None => tracing::info!(
                    file = %summary.path.display(),
                    ticks = summary.ticks,
                    dropped = summary.dropped,
                    wire = summary.wire_items,
                    wire_dropped = summary.wire_dropped,
                    final_state = summary.final_state,
                    "recording finished"
                ),
                Some(error) => tracing::error!(
                    file = %summary.path.display(),
                    ticks = summary.ticks,
                    "recording ended early: {error}"
                ),
            }
            self.record_summary = Some(summary);
        }
        let publish = self.publish_thread.take();
        let inbound = self.inbound.take();
        let token = self.token.take();
        let session = self.session.take();
        if publish.is_none() && session.is_none() {
            return;
        }
        let finished = sinew_protocol::rt::finish_within("sinew-close", CLOSE_TIMEOUT, move || {
            if let Some(thread) = publish {
                let _ = thread.join();
            }
            drop(inbound);
            if let Some(token) = token {
                let _ = token.undeclare().wait();
            }
            if let Some(session) = session {
                let _ = session.close().wait();
            }
        });
        if !finished {
            tracing::warn!(
                "zenoh could not say goodbye within {} ms (clients unreachable?): they will notice by their lease",
                CLOSE_TIMEOUT.as_millis()
            );
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        self.stop();
    }
}
