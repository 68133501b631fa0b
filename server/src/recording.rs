//! Recordings: every tick's inputs and outputs written to an MCAP file off the sim thread, and replay of that
//! file through the same deterministic core, bit for bit (issue "Training sessions").
//!
//! The determinism contract: [`crate::server_tick::ServerTick::step`] is a pure function of the world, the
//! tick's poses (with their ages, which are the only wall-clock input and are recorded) and the devices'
//! announced force limits. Nothing in it reads a clock, a random source, thread timing or a hash map's
//! iteration order, and dt is fixed. So re-running the recorded inputs from the world's rest state gives
//! every force command and the final tissue bit for bit ([`replay`]).
//!
//! - [`writer`]: the recorder thread and the sim thread's tap into it;
//! - [`reader`]: reads a recording back, with its world, tolerating a truncated or damaged end;
//! - [`replay`]: re-runs it and compares; [`debrief`]: the replayed scene as a viewer would hold it;
//! - [`tick_record`], [`json_view`], [`world_files`]: what is recorded, its Foxglove view, the world's files;
//! - [`wire_tap`]: what the scene publishes, heard on zenoh, into the same file (and `sinew-recorder`'s);
//! - [`queue`]: what travels to the writer thread, from the tick and from the tap.

pub mod debrief;
pub mod json_view;
pub mod queue;
pub mod reader;
pub mod replay;
pub mod tick_record;
pub mod wire_tap;
pub mod world_files;
pub mod writer;

pub use debrief::DebriefFrames;
pub use queue::{WireItem, WireSink};
pub use reader::{ReadError, Recording, read_recording, survey};
pub use replay::{ReplayOutcome, replay, replay_inspected, replay_observed};
pub use tick_record::{
    DeviceTick, FinalState, MAX_RECORDED_TOOLS, MAX_TICK_EVENTS, TickMessage, TickRecord,
};
pub use wire_tap::{TapScope, WireTap};
pub use writer::{KIND_SESSION, KIND_WIRE, RecordError, RecordSummary, Recorder, RecorderTap};

/// Version of the recording layout (channels and their payloads). A reader refuses other versions.
pub const FORMAT_VERSION: u32 = 1;

/// Topic of the exact per-tick records.
pub const TOPIC_TICKS: &str = "/sinew/ticks";

/// Topic of the training events (JSON, a view: replay derives them again).
pub const TOPIC_EVENTS: &str = "/sinew/events";

/// Topic of the final tissue state.
pub const TOPIC_FINAL: &str = "/sinew/final_state";

/// Topic of the tool states' JSON view (the exact messages are on their own zenoh key's channel).
pub const TOPIC_TOOLS: &str = "/sinew/tools";

/// Topic of the server stats' JSON view (every device's round trip, mode, training view; the live score).
pub const TOPIC_STATS: &str = "/sinew/stats";

/// Topic of participant presence changes (JSON).
pub const TOPIC_PRESENCE: &str = "/sinew/presence";

/// Message encoding of the channels that hold what was published, as published (one channel per zenoh key).
pub const WIRE_ENCODING: &str = "x-sinew-wire";

/// Message encoding of the exact channels (postcard of [`TickMessage`] and [`FinalState`]).
pub const TICKS_ENCODING: &str = "x-sinew-postcard";
