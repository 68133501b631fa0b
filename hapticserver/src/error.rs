//! The hapticserver's error type.
//!
//! Owns: [`HapticError`], every way starting or stopping a hapticserver can fail, each naming what was being
//! done. Must not: be produced inside a tick (the loop counts faults in its report instead).

use sinew_protocol::keys::KeyError;
use thiserror::Error;

use crate::device::DeviceError;
use crate::safety::SafetyConfigError;

/// Why a hapticserver could not start or stop cleanly.
#[derive(Debug, Error)]
pub enum HapticError {
    /// A scene or device id cannot be a key segment.
    #[error(transparent)]
    Key(#[from] KeyError),
    /// The safety limits are out of domain.
    #[error(transparent)]
    Safety(#[from] SafetyConfigError),
    /// The device failed.
    #[error("device: {0}")]
    Device(#[from] DeviceError),
    /// The loop rate is out of range.
    #[error("loop rate {rate_hz} Hz is invalid: must be between 1 and 20000")]
    LoopRate {
        /// The rate given.
        rate_hz: u32,
    },
    /// The phase alignment's target wait is out of range.
    #[error(
        "phase target {target_us} us is invalid: must be in [0, {period_us}) us, the loop period"
    )]
    PhaseTarget {
        /// The target given, us.
        target_us: f32,
        /// The loop period, us.
        period_us: f32,
    },
    /// A zenoh call failed.
    #[error("zenoh: {what}: {detail}")]
    Zenoh {
        /// What was being done, e.g. "declaring the pose publisher on sinew/pad/device/left/pose".
        what: String,
        /// zenoh's message.
        detail: String,
    },
    /// An `--emulate-*` option is out of range.
    #[error("network emulation: {reason}")]
    Emulation {
        /// Which option, and why.
        reason: String,
    },
    /// A thread could not be spawned.
    #[error("could not spawn thread {name}: {source}")]
    Thread {
        /// Thread name.
        name: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A thread panicked (a bug: the loop is written never to panic).
    #[error("thread {name} panicked")]
    Panicked {
        /// Thread name.
        name: String,
    },
}

impl HapticError {
    /// A closure turning a zenoh error into [`HapticError::Zenoh`] with context.
    pub fn zenoh(what: impl Into<String>) -> impl FnOnce(zenoh::Error) -> HapticError {
        let what = what.into();
        move |err| HapticError::Zenoh {
            what,
            detail: err.to_string(),
        }
    }
}
