//! The force path, from a command to the motor: the inbox a zenoh callback fills ([`force_inbox`]), the renderer
//! of the server's local model ([`render`]) and the choice between it and the streamed force ([`render_mode`]),
//! the passivity observer and controller ([`passivity`]), device-side safety, always last ([`safety`]), and the
//! alignment of the loop's phase with the server's tick ([`phase_align`]). The loop body that runs them in
//! order is [`crate::haptic_loop`].
//!
//! Must not: touch zenoh or a device.

pub mod force_inbox;
pub mod passivity;
pub mod phase_align;
pub mod render;
pub mod render_mode;
pub mod safety;
