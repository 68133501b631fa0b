//! The viewer library's error type.
//!
//! Owns: every way a viewer operation can fail (bad ids, zenoh, GPU, display, image files), each with enough
//! context to act on. Must not: log, retry or exit; callers decide.

use std::path::PathBuf;

use sinew_protocol::keys::KeyError;
use thiserror::Error;

/// Why a viewer operation failed.
#[derive(Debug, Error)]
pub enum ViewerError {
    /// A scene or participant id cannot be a key segment.
    #[error(transparent)]
    Key(#[from] KeyError),
    /// zenoh refused an operation (config, open, declare, query).
    #[error("zenoh: {context}: {detail}")]
    Zenoh {
        /// What the viewer was doing.
        context: String,
        /// zenoh's message.
        detail: String,
    },
    /// No GPU adapter (not even a CPU one such as Mesa lavapipe) could be opened.
    #[error(
        "no GPU adapter for offscreen rendering ({detail}); install a Vulkan driver, e.g. `apt-get install libvulkan1 mesa-vulkan-drivers` for Mesa lavapipe"
    )]
    NoGpuAdapter {
        /// What the renderer reported.
        detail: String,
    },
    /// The renderer failed for another reason.
    #[error("rendering failed: {0}")]
    Render(String),
    /// Interactive mode needs a display server.
    #[error(
        "no display: neither DISPLAY nor WAYLAND_DISPLAY is set; use --png FILE or --headless instead of --window"
    )]
    NoDisplay,
    /// The window could not be opened or crashed.
    #[error("window: {0}")]
    Window(String),
    /// Requested image size is unusable.
    #[error("image size {width}x{height} is out of range (1..=16384 per side)")]
    BadImageSize {
        /// Requested width, pixels.
        width: u32,
        /// Requested height, pixels.
        height: u32,
    },
    /// Writing an image failed.
    #[error("cannot write image {path}: {source}")]
    Image {
        /// Destination file.
        path: PathBuf,
        /// What the encoder or the file system reported.
        source: image::ImageError,
    },
    /// Spawning a thread failed.
    #[error("cannot spawn thread {name}: {source}")]
    Thread {
        /// Thread name.
        name: &'static str,
        /// OS error.
        source: std::io::Error,
    },
}

impl ViewerError {
    /// Wrap a zenoh error with what the viewer was doing.
    pub(crate) fn zenoh(context: impl Into<String>, err: impl std::fmt::Display) -> Self {
        ViewerError::Zenoh {
            context: context.into(),
            detail: err.to_string(),
        }
    }
}

/// The text of a panic payload (kiss3d reports GPU and window failures by panicking).
pub(crate) fn panic_detail(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_owned()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panicked without a message".to_owned()
    }
}
