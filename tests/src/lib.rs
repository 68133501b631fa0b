//! sinew-testkit: the test lab. Drives the roles and the `sinew` application for the workspace-level
//! integration tests in `tests/tests/`, the benches in `tests/benches/` and the examples in `tests/examples/`.
//!
//! Owns: [`harness`] (start a server, simulated hapticservers and viewers on a loopback zenoh endpoint, each
//! with its own real zenoh session, and measure across them; the starters are the application's
//! `sinew::loopback`, re-exported), [`drill`] (latency drills on virtual time: the real server tick and device
//! loops joined by emulated links; the application's `sinew::drill`, re-exported), [`scenarios`] (the latency-moderated mode's acceptance runs on the drill,
//! shared by the tests and the `latency_table` bench), [`netns`] (a lab of network namespaces joined by a real
//! path with delay, jitter and loss), [`lab_run`] (roles as processes in that lab, and reading what they print
//! and trace), [`netem`] (the packet bridge on that path, the `sinew-netem` binary),
//! [`fuzz`] (generated bad input for the decoders, the world loader and the recording reader) and [`hertz`] (a
//! sphere pressed into a block, against Hertz's answer), [`zenohd`] (zenoh's own router), [`bench_support`] (what the system
//! benches share) and [`web_page`] (`sinew-web`
//! and the instructor's page in headless chromium).
//! Must not: contain role logic; everything here calls the role crates' and the application's public APIs.
#![warn(missing_docs)]

pub use sinew::drill;
pub mod bench_support;
pub mod fidelity;
pub mod fuzz;
pub mod harness;
pub mod hertz;
pub mod lab_run;
pub mod netem;
pub mod netns;
pub mod scenarios;
pub mod web_page;
pub mod zenohd;
