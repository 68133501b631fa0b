//! The threads multi-rate objects step on: one `sinew-step-<object>` thread per object with `step_hz`.
//!
//! Owns: [`ThreadRunner`], the [`StepRunner`] the live server gives each multi-rate object. The sim thread
//! sends a job (`launch`) and takes it back a step period later (`collect`); in between the job runs here, on
//! the other core, while the 1 kHz tick goes on. The channels are bounded to one job, which the sim thread
//! never exceeds (it collects before it launches), so `launch` never blocks and, once warm, nothing allocates;
//! `collect` blocks only when the step is late, and counts it ([`StepCounters`], with the steps' run times). A panic in a
//! step ends its thread: `collect` then returns None and the sim freezes that object (see
//! [`crate::multirate::StepLane::collect`]).
//!
//! Must not: decide anything about the step (the job is the same code inline or here, so a replay agrees
//! to the bit).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, sync_channel};
use std::thread::JoinHandle;
use std::time::Instant;

use crate::multirate::{StepJob, StepRunner};

/// How an object's steps went on its thread, counted as they run (relaxed atomics: read them from anywhere).
#[derive(Debug, Default)]
pub struct StepCounters {
    /// Steps run.
    pub steps: AtomicU64,
    /// Time spent running them, ns.
    pub busy_ns: AtomicU64,
    /// The longest, ns.
    pub longest_ns: AtomicU64,
    /// Steps the tick had to wait for (still running when their hand-off came).
    pub late: AtomicU64,
}

/// Runs an object's steps on a thread of its own.
#[derive(Debug)]
pub struct ThreadRunner {
    to_worker: Option<SyncSender<Box<StepJob>>>,
    from_worker: Receiver<Box<StepJob>>,
    worker: Option<JoinHandle<()>>,
    counters: Arc<StepCounters>,
}

impl ThreadRunner {
    /// Spawn `sinew-step-<object>`.
    pub fn spawn(object: &str) -> std::io::Result<Self> {
        let (to_worker, jobs) = sync_channel::<Box<StepJob>>(1);
        let (done, from_worker) = sync_channel::<Box<StepJob>>(1);
        let counters = Arc::new(StepCounters::default());
        let counted = counters.clone();
        let worker = std::thread::Builder::new()
            .name(format!("sinew-step-{object}"))
            .spawn(move || {
                while let Ok(mut job) = jobs.recv() {
                    let started = Instant::now();
                    job.run();
                    let ns = started.elapsed().as_nanos() as u64;
                    counted.steps.fetch_add(1, Ordering::Relaxed);
                    counted.busy_ns.fetch_add(ns, Ordering::Relaxed);
                    counted.longest_ns.fetch_max(ns, Ordering::Relaxed);
                    if done.send(job).is_err() {
                        break;
                    }
                }
            })?;
        Ok(Self {
            to_worker: Some(to_worker),
            from_worker,
            worker: Some(worker),
            counters,
        })
    }

    /// The step counters, shared with whoever reports them.
    pub fn counters(&self) -> Arc<StepCounters> {
        self.counters.clone()
    }
}

impl StepRunner for ThreadRunner {
    fn launch(&mut self, job: Box<StepJob>) {
        if let Some(to_worker) = &self.to_worker {
            // Never full: the one job in flight was collected before this one leaves. A dead worker drops it,
            // and `collect` says so.
            let _ = to_worker.try_send(job);
        }
    }

    fn collect(&mut self) -> Option<Box<StepJob>> {
        match self.from_worker.try_recv() {
            Ok(job) => Some(job),
            Err(TryRecvError::Empty) => {
                self.counters.late.fetch_add(1, Ordering::Relaxed);
                self.from_worker.recv().ok()
            }
            Err(TryRecvError::Disconnected) => None,
        }
    }
}

impl Drop for ThreadRunner {
    fn drop(&mut self) {
        // Closing the job channel ends the worker's loop once its step (if any) is done.
        self.to_worker = None;
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}
