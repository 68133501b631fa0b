//! The OpenHaptics backend (feature `openhaptics`): a 3D Systems Touch / Phantom, or any device the vendor's
//! HD library drives, served as a [`crate::Device`].
//!
//! Owns: the HD bindings ([`hd_api`], libHD opened at run time), the servo loop's callback and the mailboxes
//! to it ([`servo`]), and the device ([`device`]). Layers of force safety, outermost first: the hapticserver's
//! [`crate::safety::ForceSafety`] (clamp, rate limit, ramp to zero when the server goes quiet, NaN refused);
//! the servo follower (clamp to the device's peak, rate limit, ramp to zero when the hapticserver's loop stops
//! writing, on a fault, while calibration is pending, and on close); the driver's own clamping
//! (`HD_MAX_FORCE_CLAMPING`).
//!
//! Tested against a fake libHD (tests/fake_libhd/fake_hd.c, built by tests/openhaptics.rs); untested on
//! hardware.

pub mod device;
pub mod hd_api;
pub mod servo;

pub use device::{OpenHapticsConfig, OpenHapticsDevice};

/// Why the device could not be opened.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OpenHapticsError {
    /// libHD could not be opened, or lacks a function.
    #[error("OpenHaptics: {message}")]
    Library {
        /// What was tried and why it failed.
        message: String,
    },
    /// An HD call reported an error.
    #[error("OpenHaptics: {during}: error 0x{code:04x}: {message}")]
    Hd {
        /// The step that failed.
        during: &'static str,
        /// The HD error code (0 for a value the driver returned that we refuse).
        code: u32,
        /// hdGetErrorString's text, or what is wrong.
        message: String,
    },
    /// The configuration is unusable.
    #[error("OpenHaptics: {message}")]
    Config {
        /// What is wrong.
        message: String,
    },
}
