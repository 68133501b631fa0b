//! Real-time primitives shared by every role: no I/O, no zenoh.
//!
//! - [`LatestValue`]: single-slot mailbox from a zenoh callback to a hot loop.
//! - [`LatencyHistogram`]: fixed-size, allocation-free percentile recorder.
//! - [`Pacer`]: fixed-rate loop pacing with spin_sleep, counting overruns instead of bursting to catch up.
//! - [`DelayLine`], [`DelayedSender`]: in-process network emulation (delay, jitter, seeded loss).
//! - [`JoinedServer`]: which server instance a client follows when two are live for one scene.
//! - [`Throttle`]: log a lasting condition once, then at most once a period with a count.
//! - [`finish_within`]: a teardown step that may block on the network, abandoned after a deadline.
//! - [`realtime`]: a 1 kHz loop thread's scheduling: 1 ns timer slack, and SCHED_FIFO with locked memory where
//!   the process may have them.
//! - [`panic_report`]: the role binaries' panic hook, which defers the backtrace so the 1 kHz threads'
//!   supervisors zero the force first.

mod bounded;
mod delay_line;
mod joined_server;
mod latency_histogram;
mod latest_value;
mod pacer;
mod throttle;

pub use bounded::finish_within;
pub use delay_line::{
    DelayLine, DelayedSender, DelayedSenderCounters, EmulationConfig, MAX_DELAYED_MESSAGE_BYTES,
};
pub use joined_server::{Admission, JoinedServer};
pub use latency_histogram::LatencyHistogram;
pub use latest_value::LatestValue;
pub use pacer::Pacer;
pub use throttle::Throttle;
pub mod panic_report;
pub mod realtime;
