//! The recorder: an MCAP file written on its own thread from what the sim thread hands over.
//!
//! Owns: the file, its channels and attachments, the bounded queue from the sim thread ([`RecorderTap`]) and
//! the counts of what was written and dropped. The sim thread only ever calls [`RecorderTap::offer`], which
//! copies a fixed-size [`TickRecord`] into a preallocated queue or counts it as dropped: it never blocks and
//! never allocates. Must not: stop the session. A write error (a full disk) stops the recording, once, with a
//! log line; the server runs on.
//!
//! The file holds, all stamped with simulated time:
//! - `/sinew/ticks` (postcard, [`TickMessage`](super::TickMessage)): every tick's inputs and force commands,
//!   exactly (replay);
//! - `/sinew/<device>/pose` and `/sinew/<device>/force` (JSON, with JSON schemas): the same, for Foxglove;
//! - `/sinew/final_state` (postcard, [`FinalState`]): every node position when the recording ended;
//! - what the scene published, as published ([`super::wire_tap`]): each zenoh key its own channel
//!   (`x-sinew-wire`: envelope and postcard body), with JSON views of tool states (`/sinew/tools`), stats with
//!   every device's round trip (`/sinew/stats`) and participant presence (`/sinew/presence`);
//! - attachments: the world file and every mesh file it names, so a recording replays on its own;
//! - metadata `sinew`: recording format, kind (`session`, or `wire` for `sinew-recorder`'s files, which hold
//!   only what was published), protocol version, scene, tick rate.
//!
//! Here: the handles (the sim thread's [`RecorderTap`], the owner's [`Recorder`]) and what they share with
//! the writer thread. The file's layout (metadata and channels) is in `layout`; the writer thread's loop
//! and what it writes per item in `writer_thread`.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;

use thiserror::Error;

use super::queue::{Item, WIRE_QUEUE, WireSink};
use super::tick_record::{FinalState, MAX_RECORDED_TOOLS, TickRecord};
use super::world_files::world_files;
use crate::scene::World;

mod layout;
mod writer_thread;

use layout::open_file;
use writer_thread::write_loop;

/// Ticks the queue holds (a quarter second at 1 kHz) before it drops.
pub const QUEUE_TICKS: usize = 256;

/// Why a recording could not start.
#[derive(Debug, Error)]
pub enum RecordError {
    /// The file could not be created.
    #[error("cannot record to `{path}`: {message}")]
    Create {
        /// The path asked for.
        path: PathBuf,
        /// The system's reason.
        message: String,
    },
    /// A file the world names could not be read into the recording.
    #[error("cannot record the world file `{path}` into the recording: {message}")]
    WorldFile {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The world has more tools than a record holds.
    #[error("cannot record a world with {tools} tools: a recording holds at most {max}")]
    TooManyTools {
        /// Tools in the world.
        tools: usize,
        /// The most a record holds.
        max: usize,
    },
    /// Writing the start of the file failed.
    #[error("cannot record to `{path}`: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The MCAP writer's reason.
        message: String,
    },
}

/// The sim thread's end of the recorder.
#[derive(Debug)]
pub struct RecorderTap {
    queue: SyncSender<Item>,
    dropped: Arc<AtomicU64>,
    /// Spare boxes: each record travels in one and comes back, so the queue carries a pointer, not 8 tools'
    /// worth of commands, and the sim thread never allocates.
    #[allow(clippy::vec_box)]
    boxes: Vec<Box<TickRecord>>,
    returned: Receiver<Box<TickRecord>>,
}

impl RecorderTap {
    /// Hand a tick over, or count it as dropped when the queue is full. Never blocks; no allocation (the
    /// records travel in boxes the writer hands back).
    pub fn offer(&mut self, record: &TickRecord) {
        while let Ok(spare) = self.returned.try_recv() {
            self.boxes.push(spare);
        }
        let Some(mut slot) = self.boxes.pop() else {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        };
        *slot = *record;
        match self.queue.try_send(Item::Tick(slot)) {
            Ok(()) => {}
            Err(
                TrySendError::Full(Item::Tick(slot)) | TrySendError::Disconnected(Item::Tick(slot)),
            ) => {
                self.boxes.push(slot);
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
            Err(_) => {}
        }
    }

    /// The session ended: hand over the final tissue state (blocking: the loop has stopped).
    pub fn finish(self, state: FinalState) {
        let _ = self.queue.send(Item::Final(state));
    }
}

/// What a recording wrote.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RecordSummary {
    /// The file.
    pub path: PathBuf,
    /// Ticks written.
    pub ticks: u64,
    /// Ticks dropped because the queue was full.
    pub dropped: u64,
    /// The final state was written.
    pub final_state: bool,
    /// Why the recording stopped early (a write failed), if it did.
    pub error: Option<String>,
    /// Wire messages and presence changes written.
    pub wire_items: u64,
    /// Wire messages and presence changes dropped because the writer fell behind (set by the tap's owner).
    pub wire_dropped: u64,
}

/// The recorder thread's handle.
#[derive(Debug)]
pub struct Recorder {
    thread: Option<JoinHandle<RecordSummary>>,
    dropped: Arc<AtomicU64>,
    failed: Arc<AtomicBool>,
    queue: SyncSender<Item>,
    wire_in_flight: Arc<AtomicUsize>,
}

/// A session recording (`sinew-server --record`): tick inputs, the world, and the wire.
pub const KIND_SESSION: &str = "session";
/// A recording of what was published only (`sinew-recorder`): not replayable.
pub const KIND_WIRE: &str = "wire";

impl Recorder {
    /// Create `path`, write the world into it, and start the writer thread. Fails (and creates nothing more)
    /// when the path cannot be written, a world file cannot be read, or the world has too many tools.
    pub fn start(path: &Path, world: &World) -> Result<(Recorder, RecorderTap), RecordError> {
        if world.tools.len() > MAX_RECORDED_TOOLS {
            return Err(RecordError::TooManyTools {
                tools: world.tools.len(),
                max: MAX_RECORDED_TOOLS,
            });
        }
        let files = world_files(&world.source)
            .map_err(|(path, message)| RecordError::WorldFile { path, message })?;
        let mut metadata = BTreeMap::new();
        metadata.insert("kind".to_owned(), KIND_SESSION.to_owned());
        metadata.insert("tick_hz".to_owned(), world.tick_hz.to_string());
        metadata.insert(
            "world_file".to_owned(),
            files.first().map(|f| f.name.clone()).unwrap_or_default(),
        );
        let mut out = open_file(path, &world.scene, metadata)?;
        for file in &files {
            out.attach(&mcap::Attachment {
                log_time: 0,
                create_time: 0,
                name: file.name.clone(),
                media_type: file.media_type.to_owned(),
                data: std::borrow::Cow::Borrowed(&file.data),
            })
            .map_err(write_error(path))?;
        }
        let channels = Channels::add(&mut out, Some(world)).map_err(write_error(path))?;
        let tick_ns = (1e9 / world.tick_hz).round() as u64;
        let (give_back, returned) = sync_channel(QUEUE_TICKS + 1);
        let recorder = Self::spawn(path, out, channels, tick_ns, Some(give_back))?;
        let boxes = (0..QUEUE_TICKS)
            .map(|_| Box::new(TickRecord::new(0, &[], &[], &[])))
            .collect();
        let tap = RecorderTap {
            queue: recorder.queue.clone(),
            dropped: recorder.dropped.clone(),
            boxes,
            returned,
        };
        Ok((recorder, tap))
    }

    /// Create `path` for a recording of what scene `scene` publishes, and start the writer thread
    /// (`sinew-recorder`): hand it items through [`Self::wire_sink`].
    pub fn start_wire(path: &Path, scene: &str) -> Result<Recorder, RecordError> {
        let mut metadata = BTreeMap::new();
        metadata.insert("kind".to_owned(), KIND_WIRE.to_owned());
        let mut out = open_file(path, scene, metadata)?;
        let channels = Channels::add(&mut out, None).map_err(write_error(path))?;
        Self::spawn(path, out, channels, 0, None)
    }

    fn spawn(
        path: &Path,
        out: mcap::Writer<BufWriter<File>>,
        channels: Channels,
        tick_ns: u64,
        give_back: Option<SyncSender<Box<TickRecord>>>,
    ) -> Result<Recorder, RecordError> {
        // Room for every tick box, every wire item and the final state: neither kind crowds the other out.
        let (queue, items) = sync_channel(QUEUE_TICKS + WIRE_QUEUE + 2);
        let dropped = Arc::new(AtomicU64::new(0));
        let failed = Arc::new(AtomicBool::new(false));
        let wire_in_flight = Arc::new(AtomicUsize::new(0));
        let summary = RecordSummary {
            path: path.to_owned(),
            ..RecordSummary::default()
        };
        let thread = {
            let dropped = dropped.clone();
            let failed = failed.clone();
            let in_flight = wire_in_flight.clone();
            std::thread::Builder::new()
                .name("sinew-mcap-writer".into())
                .spawn(move || {
                    let shared = WriterShared {
                        dropped: &dropped,
                        failed: &failed,
                        wire_in_flight: &in_flight,
                    };
                    write_loop(out, channels, items, give_back, tick_ns, summary, &shared)
                })
                .map_err(|e| RecordError::Create {
                    path: path.to_owned(),
                    message: format!("spawning the recorder thread: {e}"),
                })?
        };
        Ok(Recorder {
            thread: Some(thread),
            dropped,
            failed,
            queue,
            wire_in_flight,
        })
    }

    /// A new hand-off for a wire tap into this recording.
    pub fn wire_sink(&self) -> WireSink {
        WireSink::new(self.queue.clone(), self.wire_in_flight.clone())
    }

    /// Ticks dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// A write failed and the recording stopped.
    pub fn failed(&self) -> bool {
        self.failed.load(Ordering::Relaxed)
    }

    /// Finish the file and wait for it (after the tap was finished or dropped; wire items handed over later
    /// are not written).
    pub fn join(mut self) -> RecordSummary {
        let _ = self.queue.send(Item::End);
        self.thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default()
    }
}

fn write_error(path: &Path) -> impl Fn(mcap::McapError) -> RecordError + '_ {
    move |e| RecordError::Write {
        path: path.to_owned(),
        message: describe(&e),
    }
}

/// An error with its causes (mcap's I/O error hides the system's reason, such as "No space left on device").
fn describe(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        text.push_str(": ");
        text.push_str(&cause.to_string());
        source = cause.source();
    }
    text
}

/// Channel ids.
struct Channels {
    ticks: u16,
    final_state: u16,
    events: u16,
    tools_json: u16,
    stats_json: u16,
    presence_json: u16,
    /// One channel per zenoh key heard, added as keys appear.
    wire: BTreeMap<String, u16>,
    /// Per tool: its device id.
    device_ids: Vec<String>,
    /// Per tool: (pose, force) JSON channels.
    devices: Vec<(u16, u16)>,
}

/// The counters the writer thread shares with its handle.
struct WriterShared<'a> {
    dropped: &'a AtomicU64,
    failed: &'a AtomicBool,
    wire_in_flight: &'a AtomicUsize,
}
