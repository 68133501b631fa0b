//! hapticserver: serves one haptic device to a Sinew scene over zenoh.
//!
//! Owns, in three folders by idea: the device and its backends ([`device`]: the trait, the simulated and the
//! recorded hand, OpenHaptics behind a feature, the mounting calibration); the force path ([`force`]: the inbox,
//! the local-model renderer and the mode switch, passivity, safety, phase alignment); the process around the
//! loop ([`process`]: configuration, zenoh session, threads and handle, the server watch, report, trace,
//! stillness). The 1 kHz loop body that joins them is [`haptic_loop`].
//!
//! Data flow: device --read--> [`haptic_loop::HapticLoop::tick`] --DevicePose, 1 kHz--> server;
//! server --ForceCommand--> zenoh callback --> [`force_inbox::ForceInbox`] (latest-value mailbox) -->
//! tick --> render (streamed force, or the local model at the current position) --> [`passivity::Passivity`] -->
//! [`safety::ForceSafety`] --> device (safety is last: nothing changes a force after its clamp, rate limit and
//! silence ramp).
//!
//! Must not: depend on the server crate or run physics of the scene; the only force that reaches a motor is
//! one that went through [`safety::ForceSafety`].
#![warn(missing_docs)]

pub mod clock;
pub mod device;
pub mod error;
pub mod force;
pub mod haptic_loop;
pub mod process;

// The crate's flat module paths (`hapticserver::safety`, `hapticserver::sim_device`, ...), kept for its users.
#[cfg(feature = "openhaptics")]
pub use device::openhaptics;
pub use device::{calibration, hand_model, hand_script, replay_device, sim_device};
pub use force::{force_inbox, passivity, phase_align, render, render_mode, safety};
pub use process::{
    haptic_config, haptic_server, report, server_watch, stillness, trace, zenoh_session,
};

pub use calibration::{CalibratedDevice, CalibrationError, WorldFromDevice};
pub use device::{Device, DeviceError, DeviceModel, DeviceReading};
pub use error::HapticError;
pub use force_inbox::DecodeRejects;
pub use hand_model::{HandModel, HandParams, HandPreset, HandTarget};
pub use hand_script::{
    CUT_LINE_HEIGHT_MM, HandScript, SNIP_LINE_HEIGHT_MM, SNIP_PERIOD_S, SNIP_STEP_MM, ScriptError,
    ScriptGrip, ScriptKind, ScriptOptions, parse_vec3_mm,
};
pub use haptic_config::HapticConfig;
pub use haptic_server::{HapticHandle, HapticServer};
pub use passivity::{Passivity, PassivityCounters, PassivityMode};
pub use phase_align::{PhaseAligner, PhaseConfig, PhaseCounters};
pub use render_mode::{ModePolicy, ModeSwitch};
pub use replay_device::{ReplayDevice, ReplayError, ReplaySample};
pub use report::HapticReport;
pub use safety::{ForceSafety, SafetyConfig, SafetyCounters};
pub use sim_device::SimDevice;
pub use stillness::{Stillness, StillnessFigures};
pub use trace::{Trace, TraceSample};
