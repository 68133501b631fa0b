//! The device-loop thread of a running hapticserver: paced ticks until stopped, then a ramp to zero (unless
//! killed) and a final zero force; a panicking tick is caught and its force ramped out. Also where its poses
//! go ([`PoseOutlet`]: straight to zenoh, or through the emulated network).
//!
//! Owns: [`DeviceLoop`], everything the thread owns, moved into it by [`super::HapticServer::start`].
//!
//! Must not: do any per-tick work itself (that is [`crate::haptic_loop`]), use a tokio timer, or wait on a
//! lock (reports are published with `try_lock`; the report is locked only before and after ticking).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use sinew_protocol::rt::realtime::{self, RealtimeRequest};
use sinew_protocol::rt::{DelayedSender, Pacer};
use zenoh::Wait;
use zenoh::pubsub::Publisher;

use super::lock_report;
use crate::clock::MonotonicClock;
use crate::haptic_loop::HapticLoop;
use crate::report::HapticReport;
use crate::trace::Trace;

/// Where poses go: straight to zenoh, or through the emulated network first.
pub(super) enum PoseOutlet {
    Direct(Publisher<'static>),
    Delayed(DelayedSender),
}

impl PoseOutlet {
    fn send(&mut self, bytes: &[u8]) -> bool {
        match self {
            PoseOutlet::Direct(publisher) => publisher.put(bytes).wait().is_ok(),
            PoseOutlet::Delayed(sender) => {
                sender.send(bytes);
                true
            }
        }
    }
}

/// Everything the device-loop thread owns.
pub(super) struct DeviceLoop {
    pub(super) haptic: HapticLoop,
    pub(super) outlet: PoseOutlet,
    pub(super) trace: Arc<Mutex<Trace>>,
    pub(super) clock: MonotonicClock,
    pub(super) period: Duration,
    pub(super) spin_accuracy_ns: u32,
    pub(super) realtime: bool,
    pub(super) report_every_ticks: u64,
    pub(super) wind_down_ticks: u64,
    pub(super) report: Arc<Mutex<HapticReport>>,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) abrupt: Arc<AtomicBool>,
    pub(super) panic_at_tick: Option<u64>,
}

impl DeviceLoop {
    /// The thread body: paced ticks until stopped, then a ramp to zero (unless killed) and a final zero force.
    ///
    /// A panic in a tick is caught here: the motor's last force is ramped to zero over the safety ramp time,
    /// written straight to the device (nothing else of the loop runs again), the failure goes into the report
    /// (`loop_failure`), and the thread ends; the process must then exit non-zero.
    pub(super) fn run(mut self) {
        lock_report(&self.report).running = true;
        let grant = realtime::configure_this_thread(if self.realtime {
            RealtimeRequest::Fifo {
                priority: realtime::DEVICE_LOOP_PRIORITY,
            }
        } else {
            RealtimeRequest::Normal
        });
        let mut pacer = Pacer::new(self.period, grant.spin_window_ns(self.spin_accuracy_ns));
        lock_report(&self.report).realtime = Some(grant);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            self.tick_until_stopped(&mut pacer);
        }));
        if let Err(payload) = outcome {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".to_owned());
            self.haptic.ramp_out(self.wind_down_ticks, || {
                pacer.wait();
            });
            if let Ok(mut trace) = self.trace.lock() {
                *trace = self.haptic.take_trace();
            }
            let mut report = lock_report(&self.report);
            self.haptic.write_report(&mut report);
            report.loop_failure = Some(format!(
                "the device loop panicked: {message} (force ramped to zero over {} ticks)",
                self.wind_down_ticks
            ));
            report.running = false;
            return;
        }
        let outlet = &mut self.outlet;
        let mut publish = |bytes: &[u8]| outlet.send(bytes);
        if !self.abrupt.load(Ordering::Acquire) {
            self.haptic.begin_shutdown();
            for _ in 0..self.wind_down_ticks {
                if self.haptic.rendered_force_n() == [0.0; 3] {
                    break;
                }
                let interval = pacer.wait();
                self.haptic
                    .tick(self.clock.now_ns(), interval, &mut publish);
            }
        }
        self.haptic.write_zero_force();
        if let Ok(mut trace) = self.trace.lock() {
            *trace = self.haptic.take_trace();
        }
        let mut report = lock_report(&self.report);
        self.haptic.write_report(&mut report);
        report.running = false;
    }
}

impl DeviceLoop {
    fn tick_until_stopped(&mut self, pacer: &mut Pacer) {
        let outlet = &mut self.outlet;
        let mut publish = |bytes: &[u8]| outlet.send(bytes);
        while !self.stop.load(Ordering::Acquire) {
            let interval = pacer.wait();
            self.haptic.set_overruns(pacer.overruns());
            assert!(
                self.panic_at_tick != Some(self.haptic.ticks()),
                "fault drill: panic at tick {} (--fault-panic-at-tick)",
                self.haptic.ticks()
            );
            self.haptic
                .tick(self.clock.now_ns(), interval, &mut publish);
            pacer.shift_ns(self.haptic.take_phase_shift_ns());
            if self.haptic.ticks().is_multiple_of(self.report_every_ticks) {
                self.haptic.try_publish_report(&self.report);
            }
        }
    }
}
