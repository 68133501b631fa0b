//! sinew: the application. The `sinew` binary a user runs (`sinew demo`, `replay`, `report`, `info`,
//! `play-device`, `certs`) and the library behind it, wiring the three roles together through their public APIs.
//!
//! Owns: [`demo`] (the live demo with its per-second lines and final summary), [`loopback`] (starting a server,
//! simulated hapticservers and viewers in one process on a loopback zenoh endpoint, each with its own real
//! zenoh session, and measuring the viewer's replica against the server), [`report`] (`sinew report`: a
//! recording's training report), [`play_device`] (`sinew play-device`: a recorded hand played into a live
//! scene), [`debrief`] (`sinew replay --publish` and `--png-every`: the instructor's debrief of a recording),
//! [`certs`] (`sinew certs`: a lab's CA and role certificates), [`drill`] (the roles' loops joined on virtual
//! time through emulated links: the latency drills' engine, and the demo's rehearsal of a stitch),
//! [`stitch_plan`], [`stitch_hand_off_plan`] and [`stitch_draw_plan`] (the simulated surgeons' pose paths
//! for one scripted stitch: the pass, the hand-off, the draw), [`stitch_script`] (those paths, each stage
//! rehearsed before the next is planned, as the surgeons' scripts) and [`figure_font`] (the font figures use).
//! Must not: contain role logic (everything here calls the role crates' public APIs), or depend on the test
//! kit (`sinew-testkit`, which depends on this crate; `.ci/check-dependency-direction` checks it).
#![warn(missing_docs)]

pub mod certs;
pub mod debrief;
pub mod demo;
pub mod drill;
pub mod figure_font;
pub mod loopback;
pub mod play_device;
pub mod report;
pub mod stitch_draw_plan;
pub mod stitch_hand_off_plan;
pub mod stitch_plan;
pub mod stitch_script;
