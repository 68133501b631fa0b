//! The supervision thread of a running hapticserver: the hello, and the watch of the server it follows.
//!
//! Owns: [`Supervision`], everything the thread owns, moved into it by [`super::HapticServer::start`]; it
//! sends the hello every [`HELLO_PERIOD`] (and at once when a server appears), steps the
//! [`ServerWatch`] every [`WATCH_PERIOD`], logs what the watch says and writes the report's link and standing.
//!
//! Must not: touch the device or the force (that is the device-loop thread), or block on the network (the
//! hello publisher drops when congested).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use sinew_protocol::ServerStats;
use zenoh::Wait;
use zenoh::pubsub::Publisher;

use super::{HELLO_PERIOD, lock_report};
use crate::clock::MonotonicClock;
use crate::force_inbox::ForceInbox;
use crate::report::HapticReport;
use crate::server_watch::{Say, ServerWatch, WATCH_PERIOD};

/// The supervision thread: the hello every [`HELLO_PERIOD`], and the server watch every [`WATCH_PERIOD`]
/// (its log lines and the report's link and standing).
pub(super) struct Supervision {
    pub(super) hello_publisher: Publisher<'static>,
    pub(super) hello_bytes: Vec<u8>,
    pub(super) hello_now: Arc<AtomicBool>,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) watch: ServerWatch,
    pub(super) inbox: Arc<ForceInbox>,
    pub(super) latest_stats: Arc<Mutex<Option<ServerStats>>>,
    pub(super) report: Arc<Mutex<HapticReport>>,
    pub(super) clock: MonotonicClock,
}

impl Supervision {
    /// Until stopped (woken by `unpark`).
    pub(super) fn run(mut self) {
        let mut next_hello = Instant::now();
        while !self.stop.load(Ordering::Acquire) {
            let now = Instant::now();
            if now >= next_hello || self.hello_now.swap(false, Ordering::AcqRel) {
                if let Err(err) = self.hello_publisher.put(self.hello_bytes.as_slice()).wait() {
                    tracing::debug!(%err, "hello not published");
                }
                next_hello = now + HELLO_PERIOD;
            }
            let stats = self.latest_stats.lock().ok().and_then(|mut s| s.take());
            for say in self
                .watch
                .step(self.clock.now_ns(), self.inbox.server(), stats.as_ref())
            {
                match say {
                    Say::Info(line) => tracing::info!("{line}"),
                    Say::Warn(line) => tracing::warn!("{line}"),
                    Say::Error(line) => tracing::error!("{line}"),
                }
            }
            {
                let mut report = lock_report(&self.report);
                report.server_link = self.watch.link();
                if report.standing != *self.watch.standing() {
                    report.standing = self.watch.standing().clone();
                }
            }
            std::thread::park_timeout(WATCH_PERIOD);
        }
    }
}
