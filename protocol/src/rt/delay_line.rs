//! In-process network emulation: delay, jitter and seeded loss on what a role publishes.
//!
//! Owns: [`EmulationConfig`] (the `--emulate-delay-ms`, `--emulate-jitter-ms`, `--emulate-loss` options),
//! [`DelayLine`] (the pure decision per message: dropped, or due at a time) and [`DelayedSender`] (a named
//! thread that holds each message until it is due, then hands it to a sink, e.g. a zenoh `put`).
//!
//! The link is FIFO, like one network path: each message's delay is drawn uniformly in `delay +- jitter`
//! (never below zero) and a message never overtakes the one before it, so jitter shows as bunching, not
//! reordering. Loss is Bernoulli with a seeded generator, so a run is repeatable.
//!
//! Must not: know what the bytes mean, or block the caller: [`DelayedSender::send`] copies into a bounded
//! queue and, when that is full, drops the message and counts it.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Delay, jitter and loss to apply to one outbound stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmulationConfig {
    /// One-way delay added to every message, ms (>= 0).
    pub delay_ms: f64,
    /// Each message's delay varies uniformly by up to this much either way, ms (>= 0).
    pub jitter_ms: f64,
    /// Probability that a message is lost, 0..1.
    pub loss: f64,
    /// Seed of the loss and jitter draws.
    pub seed: u64,
}

impl Default for EmulationConfig {
    fn default() -> Self {
        Self {
            delay_ms: 0.0,
            jitter_ms: 0.0,
            loss: 0.0,
            seed: 1,
        }
    }
}

impl EmulationConfig {
    /// No delay, no jitter, no loss: messages go straight out.
    pub fn is_off(&self) -> bool {
        self.delay_ms == 0.0 && self.jitter_ms == 0.0 && self.loss == 0.0
    }

    /// Check every field; the error names the option.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("--emulate-delay-ms", self.delay_ms, (0.0..=10_000.0)),
            ("--emulate-jitter-ms", self.jitter_ms, (0.0..=10_000.0)),
            ("--emulate-loss", self.loss, (0.0..=1.0)),
        ];
        for (option, value, range) in checks {
            if !(value.is_finite() && range.contains(&value)) {
                return Err(format!(
                    "{option} {value} is out of range {}..={}",
                    range.start(),
                    range.end()
                ));
            }
        }
        Ok(())
    }
}

/// The per-message decision of one emulated link.
#[derive(Debug, Clone)]
pub struct DelayLine {
    config: EmulationConfig,
    rng: fastrand::Rng,
    last_due_ns: u64,
    passed: u64,
    lost: u64,
}

impl DelayLine {
    /// A link with `config` (assumed validated).
    pub fn new(config: EmulationConfig) -> Self {
        Self {
            rng: fastrand::Rng::with_seed(config.seed),
            config,
            last_due_ns: 0,
            passed: 0,
            lost: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &EmulationConfig {
        &self.config
    }

    /// A message handed to the link at `now_ns`: `None` if it is lost, else the time it arrives. Due times
    /// never decrease (FIFO). Real-time safe: no allocation, never panics.
    pub fn schedule(&mut self, now_ns: u64) -> Option<u64> {
        if self.config.loss > 0.0 && self.rng.f64() < self.config.loss {
            self.lost += 1;
            return None;
        }
        let jitter_ms = if self.config.jitter_ms > 0.0 {
            (self.rng.f64() * 2.0 - 1.0) * self.config.jitter_ms
        } else {
            0.0
        };
        let delay_ns = ((self.config.delay_ms + jitter_ms).max(0.0) * 1e6) as u64;
        let due_ns = now_ns.saturating_add(delay_ns).max(self.last_due_ns);
        self.last_due_ns = due_ns;
        self.passed += 1;
        Some(due_ns)
    }

    /// Messages that got through so far.
    pub fn passed(&self) -> u64 {
        self.passed
    }

    /// Messages lost so far.
    pub fn lost(&self) -> u64 {
        self.lost
    }
}

/// Largest message a [`DelayedSender`] carries, bytes (a force command with a full local model is ~200).
pub const MAX_DELAYED_MESSAGE_BYTES: usize = 512;

/// Messages a [`DelayedSender`] can hold in flight (2 s at 1 kHz).
pub const DELAYED_QUEUE_CAPACITY: usize = 2048;

struct Packet {
    due: Instant,
    len: usize,
    bytes: [u8; MAX_DELAYED_MESSAGE_BYTES],
}

/// Counters of a [`DelayedSender`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DelayedSenderCounters {
    /// Handed to the sink.
    pub delivered: u64,
    /// Lost on purpose (the emulated loss).
    pub lost: u64,
    /// Dropped because the queue was full or the message too large.
    pub overflowed: u64,
}

#[derive(Debug, Default)]
struct SharedCounters {
    delivered: AtomicU64,
    lost: AtomicU64,
    overflowed: AtomicU64,
}

/// Holds each message until its emulated arrival time, then passes it to a sink on a named thread.
pub struct DelayedSender {
    line: DelayLine,
    tx: Option<SyncSender<Packet>>,
    thread: Option<JoinHandle<()>>,
    stop: Arc<AtomicBool>,
    counters: Arc<SharedCounters>,
}

impl std::fmt::Debug for DelayedSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DelayedSender")
            .field("config", self.line.config())
            .field("counters", &self.counters())
            .finish()
    }
}

impl DelayedSender {
    /// Start the thread `name`, which calls `sink` with each message once it is due.
    pub fn start(
        name: &str,
        config: EmulationConfig,
        mut sink: impl FnMut(&[u8]) + Send + 'static,
    ) -> std::io::Result<Self> {
        let (tx, rx): (SyncSender<Packet>, Receiver<Packet>) = sync_channel(DELAYED_QUEUE_CAPACITY);
        let stop = Arc::new(AtomicBool::new(false));
        let counters = Arc::new(SharedCounters::default());
        let thread_stop = stop.clone();
        let thread_counters = counters.clone();
        let thread = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(move || {
                let sleeper = spin_sleep::SpinSleeper::new(50_000)
                    .with_spin_strategy(spin_sleep::SpinStrategy::YieldThread);
                while !thread_stop.load(Ordering::Acquire) {
                    let packet = match rx.recv_timeout(Duration::from_millis(50)) {
                        Ok(packet) => packet,
                        Err(RecvTimeoutError::Timeout) => continue,
                        Err(RecvTimeoutError::Disconnected) => break,
                    };
                    let now = Instant::now();
                    if packet.due > now {
                        sleeper.sleep(packet.due - now);
                    }
                    sink(&packet.bytes[..packet.len]);
                    thread_counters.delivered.fetch_add(1, Ordering::Relaxed);
                }
            })?;
        Ok(Self {
            line: DelayLine::new(config),
            tx: Some(tx),
            thread: Some(thread),
            stop,
            counters,
        })
    }

    /// Queue `bytes` for delivery after the emulated delay (or lose it). Copies into a preallocated-size
    /// packet; never blocks; a full queue or an oversized message is dropped and counted.
    pub fn send(&mut self, bytes: &[u8]) {
        let now = Instant::now();
        // The line works on ns from an arbitrary origin; only differences matter, so use 0 = now.
        let Some(delay_ns) = self.line.schedule_relative(now) else {
            self.counters.lost.fetch_add(1, Ordering::Relaxed);
            return;
        };
        if bytes.len() > MAX_DELAYED_MESSAGE_BYTES {
            self.counters.overflowed.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let mut packet = Packet {
            due: now + Duration::from_nanos(delay_ns),
            len: bytes.len(),
            bytes: [0; MAX_DELAYED_MESSAGE_BYTES],
        };
        packet.bytes[..bytes.len()].copy_from_slice(bytes);
        let Some(tx) = &self.tx else { return };
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = tx.try_send(packet) {
            self.counters.overflowed.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Counters so far.
    pub fn counters(&self) -> DelayedSenderCounters {
        DelayedSenderCounters {
            delivered: self.counters.delivered.load(Ordering::Relaxed),
            lost: self.counters.lost.load(Ordering::Relaxed),
            overflowed: self.counters.overflowed.load(Ordering::Relaxed),
        }
    }

    /// Stop the thread; messages still in flight are dropped (as a link that goes down would).
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Release);
        self.tx = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for DelayedSender {
    fn drop(&mut self) {
        self.stop();
    }
}

impl DelayLine {
    /// [`DelayLine::schedule`] on the wall clock: the delay to wait from `now`, ns, or `None` if lost.
    fn schedule_relative(&mut self, now: Instant) -> Option<u64> {
        let origin = *EPOCH.get_or_init(Instant::now);
        let now_ns = u64::try_from(now.saturating_duration_since(origin).as_nanos()).ok()?;
        self.schedule(now_ns).map(|due_ns| due_ns - now_ns)
    }
}

static EPOCH: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delay_jitter_and_loss_follow_the_config_and_the_seed() {
        let config = EmulationConfig {
            delay_ms: 50.0,
            jitter_ms: 10.0,
            loss: 0.05,
            seed: 7,
        };
        let mut a = DelayLine::new(config);
        let mut b = DelayLine::new(config);
        let mut last_due = 0;
        let mut lost = 0;
        for tick in 0..100_000u64 {
            let now_ns = tick * 1_000_000;
            let due = a.schedule(now_ns);
            assert_eq!(due, b.schedule(now_ns), "same seed, same draws");
            match due {
                None => lost += 1,
                Some(due_ns) => {
                    assert!(due_ns >= last_due, "FIFO");
                    assert!(due_ns >= now_ns + 40_000_000 && due_ns <= now_ns + 70_000_000);
                    last_due = due_ns;
                }
            }
        }
        let rate = f64::from(lost) / 100_000.0;
        assert!((rate - 0.05).abs() < 0.005, "loss rate {rate}");
        assert_eq!(a.lost(), u64::from(lost as u32));
    }

    #[test]
    fn bad_options_are_named() {
        let bad = EmulationConfig {
            loss: 1.5,
            ..EmulationConfig::default()
        };
        assert!(bad.validate().unwrap_err().contains("--emulate-loss"));
        let bad = EmulationConfig {
            delay_ms: f64::NAN,
            ..EmulationConfig::default()
        };
        assert!(bad.validate().unwrap_err().contains("--emulate-delay-ms"));
        assert!(EmulationConfig::default().is_off());
    }

    #[test]
    fn the_sender_delivers_after_the_delay_in_order() {
        let received = Arc::new(std::sync::Mutex::new(Vec::new()));
        let sink_received = received.clone();
        let start = Instant::now();
        let mut sender = DelayedSender::start(
            "delay-test",
            EmulationConfig {
                delay_ms: 30.0,
                ..EmulationConfig::default()
            },
            move |bytes| {
                sink_received
                    .lock()
                    .unwrap()
                    .push((bytes[0], start.elapsed()));
            },
        )
        .unwrap();
        for i in 0..5u8 {
            sender.send(&[i]);
        }
        std::thread::sleep(Duration::from_millis(300));
        let got = received.lock().unwrap().clone();
        assert_eq!(got.iter().map(|g| g.0).collect::<Vec<_>>(), [0, 1, 2, 3, 4]);
        assert!(got[0].1 >= Duration::from_millis(30), "{got:?}");
        assert_eq!(sender.counters().delivered, 5);
        sender.stop();
    }
}
