//! sinew: the system crate. Wires the three roles together for the demo (`sinew demo`) and for the
//! workspace-level end-to-end tests in `tests/tests/`.
//!
//! Owns: [`certs`] (`sinew certs`: a lab's CA and role certificates), [`harness`] (start a server, simulated
//! hapticservers and viewers on a loopback zenoh endpoint, each
//! with its own real zenoh session, and measure across them), [`demo`] (the live demo with its per-second
//! lines and final summary), [`drill`] (latency drills on virtual time: the real server tick and device loops
//! joined by emulated links), [`scenarios`] (the latency-moderated mode's acceptance runs on the drill,
//! shared by the tests and the `latency_table` bench), [`netns`] (a lab of network namespaces joined by a real
//! path with delay, jitter and loss), [`netem`] (the packet bridge on that path, the `sinew-netem` binary),
//! [`report`] (`sinew report`: a recording's training report), [`play_device`] (`sinew play-device`: a
//! recorded hand played into a live scene), [`debrief`] (`sinew replay --publish` and
//! `--png-every`: the instructor's debrief of a recording), [`fuzz`] (generated bad input for the decoders, the
//! world loader and the recording reader), [`hertz`] (a sphere pressed into a block, against Hertz's answer) and
//! [`figure_font`] (the font figures use).
//! Must not: contain role logic; everything here calls the role crates' public APIs.
#![warn(missing_docs)]

pub mod certs;
pub mod debrief;
pub mod demo;
pub mod drill;
pub mod figure_font;
pub mod fuzz;
pub mod harness;
pub mod hertz;
pub mod netem;
pub mod netns;
pub mod play_device;
pub mod report;
pub mod scenarios;
