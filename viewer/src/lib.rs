//! sinew-viewer: a thin client that replicates a Sinew scene from mesh deltas and draws it.
//!
//! Owns: the scene replica and its delta rules ([`replica`]), the zenoh client that keeps it in sync
//! ([`client`], with its shared state machine in `sync_state`), the viewer's counters ([`viewer_stats`]), and
//! drawing: offscreen PNG ([`render`]) and an interactive window ([`window`]), both through [`scene_view`], with
//! the instructor's overlay ([`instructor_overlay`]) over either; and the browser gateway `sinew-web`: the feed
//! a page reads ([`web_feed`], tools as primitives from [`tool_parts`]) and its HTTP and WebSocket side
//! ([`web_server`]).
//!
//! Must not: depend on the server crate, write to the scene, or run physics. The replica is plain data and is
//! usable (and tested) without zenoh or a GPU.
#![warn(missing_docs)]

mod bounded_queue;
pub mod camera_framing;
pub mod client;
pub mod error;
pub mod hole_view;
pub mod instructor_overlay;
pub mod network_config;
mod rate_meter;
pub mod render;
pub mod replica;
pub mod scene_view;
mod sync_state;
// The unit tests build snapshots and deltas with the integration tests' builders: one file for both.
#[cfg(test)]
#[path = "../tests/common/fixtures.rs"]
mod test_fixtures;
pub mod thread_view;
pub mod tool_parts;
pub mod viewer_stats;
pub mod web_feed;
pub mod web_server;
pub mod window;

pub use camera_framing::{CameraFraming, frame_replica};
pub use client::{ViewerClient, ViewerConfig, ViewerHandle};
pub use error::ViewerError;
pub use instructor_overlay::{ForceArrow, InstructorOverlay};
pub use render::{
    RenderStats, SceneFrame, render_frames, render_image, render_image_framed, render_png,
    render_png_with_overlay, render_sequence,
};
pub use replica::{DeltaOutcome, ReplicaError, ReplicaObject, SceneReplica};
pub use viewer_stats::{DecodeErrorCounts, ViewerStats};
pub use window::{display_available, run_window, run_window_until};
