//! hapticserver: serves one haptic device to a Sinew scene over zenoh.
//!
//! Owns: the device abstraction ([`device`]), its mounting calibration ([`calibration`]) and its backends (the simulated hand: [`sim_device`],
//! [`hand_model`], [`hand_script`]), device-side force safety ([`safety`]), the 1 kHz loop body
//! ([`haptic_loop`]) and the process around it ([`haptic_server`]: zenoh declarations, threads, handle,
//! [`report`], with the last second's [`stillness`]), and the latency-moderated renderer of the server's
//! local models ([`render`]), and the alignment of the loop's phase with the server's tick ([`phase_align`]).
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

pub mod calibration;
pub mod clock;
pub mod device;
pub mod error;
pub mod force_inbox;
pub mod hand_model;
pub mod hand_script;
pub mod haptic_config;
pub mod haptic_loop;
pub mod haptic_server;
#[cfg(feature = "openhaptics")]
pub mod openhaptics;
pub mod passivity;
pub mod phase_align;
pub mod render;
pub mod render_mode;
pub mod replay_device;
pub mod report;
pub mod safety;
pub mod server_watch;
pub mod sim_device;
pub mod stillness;
pub mod trace;
pub mod zenoh_session;

pub use calibration::{CalibratedDevice, CalibrationError, WorldFromDevice};
pub use device::{Device, DeviceError, DeviceModel, DeviceReading};
pub use error::HapticError;
pub use force_inbox::DecodeRejects;
pub use hand_model::{HandModel, HandParams, HandPreset, HandTarget};
pub use hand_script::{
    CUT_LINE_HEIGHT_MM, HandScript, SNIP_LINE_HEIGHT_MM, SNIP_STEP_MM, ScriptError, ScriptGrip,
    ScriptKind, ScriptOptions, parse_vec3_mm,
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
