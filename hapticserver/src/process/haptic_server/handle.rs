//! The handle of a running hapticserver: what it serves, its report and trace, and how it ends.
//!
//! Owns: [`HapticHandle`], built by [`super::HapticServer::start`]: the zenoh objects and the two threads of
//! one server, stopped gracefully ([`HapticHandle::stop`]: the force ramps to zero first, then the goodbyes,
//! within [`CLOSE_TIMEOUT`]) or abruptly ([`HapticHandle::kill`]), and stopped on drop.
//!
//! Must not: let a stop wait on the network before the force is at zero, or wait on it longer than
//! [`CLOSE_TIMEOUT`].

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;

use super::{CLOSE_TIMEOUT, lock_report};
use crate::clock::MonotonicClock;
use crate::error::HapticError;
use crate::force_inbox::ForceInbox;
use crate::report::HapticReport;
use crate::trace::Trace;

/// A running hapticserver. Dropping it stops it (see [`HapticHandle::stop`]).
pub struct HapticHandle {
    pub(super) device_id: String,
    pub(super) pose_key: String,
    pub(super) force_key: String,
    pub(super) session: Option<zenoh::Session>,
    pub(super) token: Option<LivelinessToken>,
    pub(super) subscriber: Option<Subscriber<()>>,
    pub(super) watch_subscribers: Vec<Subscriber<()>>,
    pub(super) loop_thread: Option<JoinHandle<()>>,
    pub(super) hello_thread: Option<JoinHandle<()>>,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) abrupt: Arc<AtomicBool>,
    pub(super) report: Arc<Mutex<HapticReport>>,
    pub(super) inbox: Arc<ForceInbox>,
    pub(super) trace: Arc<Mutex<Trace>>,
    pub(super) clock: MonotonicClock,
}

impl std::fmt::Debug for HapticHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HapticHandle")
            .field("device_id", &self.device_id)
            .field("pose_key", &self.pose_key)
            .field("force_key", &self.force_key)
            .field("running", &self.is_running())
            .finish_non_exhaustive()
    }
}

impl HapticHandle {
    /// The device id served.
    pub fn device_id(&self) -> &str {
        &self.device_id
    }

    /// The key poses are published on.
    pub fn pose_key(&self) -> &str {
        &self.pose_key
    }

    /// The key force commands are read from.
    pub fn force_key(&self) -> &str {
        &self.force_key
    }

    /// Now on the loop's clock, s: the time base of the trace's `t_s` and of the silence rule (so a test can
    /// say when, on that clock, something happened outside the loop).
    pub fn clock_s(&self) -> f64 {
        crate::clock::ns_to_s(self.clock.now_ns())
    }

    /// Whether the device loop thread is still running.
    pub fn is_running(&self) -> bool {
        self.loop_thread
            .as_ref()
            .is_some_and(|thread| !thread.is_finished())
    }

    /// The latest report (published by the loop about every 100 ms; final after stop), with the inbox
    /// counters read now.
    pub fn report(&self) -> HapticReport {
        let mut report = lock_report(&self.report).clone();
        report.forces_received = self.inbox.received();
        report.decode_rejects = self.inbox.rejects();
        report.forces_from_other_server = self.inbox.server().foreign();
        report.forces_for_other_instance = self.inbox.for_other_instance();
        report
    }

    /// The trace the loop recorded (`HapticConfig::trace_ticks`), available once the loop has stopped
    /// (empty before).
    pub fn take_trace(&self) -> Trace {
        self.trace
            .lock()
            .map(|mut t| std::mem::take(&mut *t))
            .unwrap_or_default()
    }

    /// Stop gracefully: the loop ignores further commands, ramps the force to zero within the safety ramp
    /// time, writes zero, and ends. Only then the goodbyes: the hello thread ends, the subscribers and
    /// presence token are undeclared and the session closed, all within [`CLOSE_TIMEOUT`]: when the network
    /// cannot carry them (a partition), they are abandoned with a warning and the server notices by its lease.
    /// Idempotent. Returns the first failure, after attempting every step.
    pub fn stop(&mut self) -> Result<(), HapticError> {
        self.stop.store(true, Ordering::Release);
        let mut first_error = None;
        // The force first: the loop never waits on the network.
        if let Some(thread) = self.loop_thread.take() {
            thread.thread().unpark();
            if thread.join().is_err() {
                first_error.get_or_insert(HapticError::Panicked {
                    name: format!("hapticserver-{} device loop", self.device_id),
                });
            }
        }
        let hello = self.hello_thread.take();
        let subscriber = self.subscriber.take();
        let watch_subscribers = std::mem::take(&mut self.watch_subscribers);
        let token = self.token.take();
        let session = self.session.take();
        if hello.is_none() && subscriber.is_none() && token.is_none() && session.is_none() {
            return first_error.map_or(Ok(()), Err);
        }
        let errors: Arc<Mutex<Vec<HapticError>>> = Arc::default();
        let teardown_errors = errors.clone();
        let device_id = self.device_id.clone();
        let finished = sinew_protocol::rt::finish_within(
            &format!("hapticserver-{}-close", self.device_id),
            CLOSE_TIMEOUT,
            move || {
                let push = |e| {
                    if let Ok(mut errors) = teardown_errors.lock() {
                        errors.push(e);
                    }
                };
                if let Some(thread) = hello {
                    thread.thread().unpark();
                    if thread.join().is_err() {
                        push(HapticError::Panicked {
                            name: format!("hapticserver-{device_id} watch"),
                        });
                    }
                }
                if let Some(subscriber) = subscriber
                    && let Err(err) = subscriber.undeclare().wait()
                {
                    push(HapticError::zenoh("undeclaring the force subscriber")(err));
                }
                drop(watch_subscribers);
                if let Some(token) = token
                    && let Err(err) = token.undeclare().wait()
                {
                    push(HapticError::zenoh("undeclaring the presence token")(err));
                }
                if let Some(session) = session
                    && let Err(err) = session.close().wait()
                {
                    tracing::warn!(device = %device_id, %err, "the zenoh session did not close cleanly (server unreachable?)");
                }
            },
        );
        if !finished {
            tracing::warn!(
                device = %self.device_id,
                "force at zero; zenoh could not say goodbye within {} ms (server unreachable?): the server \
                 will notice by its lease",
                CLOSE_TIMEOUT.as_millis()
            );
        }
        if let Ok(mut errors) = errors.lock()
            && !errors.is_empty()
        {
            first_error.get_or_insert(errors.remove(0));
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Stop abruptly, as a crash would look to the network: the loop ends at once (no ramp; the device gets
    /// zero force) and every zenoh object is dropped without undeclaring first.
    pub fn kill(mut self) {
        self.abrupt.store(true, Ordering::Release);
        self.stop.store(true, Ordering::Release);
        for thread in [self.hello_thread.take(), self.loop_thread.take()]
            .into_iter()
            .flatten()
        {
            thread.thread().unpark();
            // A panicked thread is already gone, which is all a kill wants.
            let _ = thread.join();
        }
        drop(self.subscriber.take());
        self.watch_subscribers.clear();
        drop(self.token.take());
        drop(self.session.take());
    }
}

impl Drop for HapticHandle {
    fn drop(&mut self) {
        if let Err(err) = self.stop() {
            tracing::warn!(device = %self.device_id, %err, "hapticserver did not stop cleanly");
        }
    }
}
