//! The OpenHaptics servo loop's side of the backend: what runs in libHD's 1 kHz scheduler thread, and the
//! lock-free mailboxes that join it to the hapticserver's own loop.
//!
//! Owns: [`SeqCell`] (a single-writer seqlock of f64 words: the latest-value mailbox in each direction),
//! [`ForceFollower`] (the servo-side force filter: it follows the loop's latest command, clamped to the
//! device's peak and rate-limited, and ramps to zero by itself when commands stop coming: a stalled or dead
//! hapticserver loop never leaves a force on the motors) and [`ServoShared`] with [`servo_callback`], the
//! scheduler callback: one frame per servo tick (read position, velocity, transform and buttons; check
//! calibration once a second; render the followed force; pop the error stack; publish the sample).
//!
//! Must not: allocate, lock, log or unwind in the callback. The hapticserver's [`crate::safety::ForceSafety`]
//! stays the force authority; the follower is a second, simpler guard at the motors.

use std::ffi::{c_int, c_void};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering, fence};

use super::hd_api::HD_CALIBRATION_AUTO;
use super::hd_api::{
    HD_CALIBRATION_INKWELL, HD_CALIBRATION_NEEDS_UPDATE, HD_CALIBRATION_OK, HD_CALLBACK_CONTINUE,
    HD_CALLBACK_DONE, HD_CURRENT_BUTTONS, HD_CURRENT_POSITION, HD_CURRENT_TRANSFORM,
    HD_CURRENT_VELOCITY, HD_SUCCESS, HdCallbackCode, HdFns, Hhd,
};

/// How often the servo loop asks for the calibration status, servo ticks (once a second, as the vendor's
/// calibration example does).
pub const CALIBRATION_CHECK_TICKS: u64 = 1000;

/// The fault code recorded when the callback itself failed (a bug caught before it could unwind into C).
pub const CALLBACK_PANIC_FAULT: u32 = 0xDEAD;

/// A single-writer seqlock of `N` f64 words: the writer never waits, a reader retries a torn read a bounded
/// number of times.
#[derive(Debug)]
pub struct SeqCell<const N: usize> {
    seq: AtomicU64,
    words: [AtomicU64; N],
}

impl<const N: usize> Default for SeqCell<N> {
    fn default() -> Self {
        Self {
            seq: AtomicU64::new(0),
            words: std::array::from_fn(|_| AtomicU64::new(0)),
        }
    }
}

impl<const N: usize> SeqCell<N> {
    /// Publish `values`. Only one thread may write a given cell.
    pub fn write(&self, values: &[f64; N]) {
        let seq = self.seq.load(Ordering::Relaxed);
        self.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
        fence(Ordering::Release);
        for (word, value) in self.words.iter().zip(values) {
            word.store(value.to_bits(), Ordering::Relaxed);
        }
        self.seq.store(seq.wrapping_add(2), Ordering::Release);
    }

    /// The latest values, or None before the first write (or if every retry was torn, which needs the
    /// writer to write 16 times during one read).
    pub fn read(&self) -> Option<[f64; N]> {
        for _ in 0..16 {
            let before = self.seq.load(Ordering::Acquire);
            if before == 0 {
                return None;
            }
            if !before.is_multiple_of(2) {
                std::hint::spin_loop();
                continue;
            }
            let mut out = [0.0f64; N];
            for (value, word) in out.iter_mut().zip(&self.words) {
                *value = f64::from_bits(word.load(Ordering::Relaxed));
            }
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == before {
                return Some(out);
            }
        }
        None
    }
}

/// The servo-side force filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceFollower {
    /// Largest force magnitude rendered, N.
    pub max_force_n: f64,
    /// Largest change per servo tick, N (rate limit times the servo period).
    pub max_step_n: f64,
    /// Servo ticks without a new command before the follower ramps to zero by itself.
    pub stale_ticks: u64,
    out_n: [f64; 3],
    last_write: u64,
    last_fresh_tick: u64,
}

impl ForceFollower {
    /// A follower at rest.
    pub fn new(max_force_n: f64, max_step_n: f64, stale_ticks: u64) -> Self {
        Self {
            max_force_n,
            max_step_n,
            stale_ticks,
            out_n: [0.0; 3],
            last_write: 0,
            last_fresh_tick: 0,
        }
    }

    /// The force to render at servo tick `tick`, given the newest command and how many commands the loop
    /// has written so far. `allowed` false (stopping, a fault, calibration pending) ramps to zero. Returns
    /// the force and whether the command was stale.
    pub fn step(
        &mut self,
        tick: u64,
        command_n: [f64; 3],
        writes: u64,
        allowed: bool,
    ) -> ([f64; 3], bool) {
        if writes != self.last_write {
            self.last_write = writes;
            self.last_fresh_tick = tick;
        }
        let stale = writes == 0 || tick.saturating_sub(self.last_fresh_tick) > self.stale_ticks;
        let usable = allowed && !stale && command_n.iter().all(|c| c.is_finite());
        let mut target = if usable { command_n } else { [0.0; 3] };
        let norm = target.iter().map(|c| c * c).sum::<f64>().sqrt();
        if norm > self.max_force_n {
            let scale = self.max_force_n / norm;
            target.iter_mut().for_each(|c| *c *= scale);
        }
        let delta: [f64; 3] = std::array::from_fn(|i| target[i] - self.out_n[i]);
        let change = delta.iter().map(|c| c * c).sum::<f64>().sqrt();
        let scale = if change > self.max_step_n {
            self.max_step_n / change
        } else {
            1.0
        };
        for (out, d) in self.out_n.iter_mut().zip(delta) {
            *out += d * scale;
        }
        (self.out_n, stale)
    }

    /// The force rendered last, N.
    pub fn out_n(&self) -> [f64; 3] {
        self.out_n
    }

    /// The state carried between servo ticks: force (3), last write count, last fresh tick.
    fn state(&self) -> [f64; FOLLOWER_WORDS] {
        [
            self.out_n[0],
            self.out_n[1],
            self.out_n[2],
            self.last_write as f64,
            self.last_fresh_tick as f64,
        ]
    }

    /// This follower's limits with a carried state.
    fn with_state(mut self, state: &[f64; FOLLOWER_WORDS]) -> Self {
        self.out_n = [state[0], state[1], state[2]];
        self.last_write = state[3] as u64;
        self.last_fresh_tick = state[4] as u64;
        self
    }
}

/// Words of the follower's carried state.
const FOLLOWER_WORDS: usize = 5;

/// Words of a servo sample: position (3), velocity (3), rotation (9, column-major), buttons, servo tick.
pub const SAMPLE_WORDS: usize = 17;
/// Words of a force command: force (3), write count.
pub const COMMAND_WORDS: usize = 4;

/// State shared by the servo callback and the device. Lives in an `Arc` the device holds until the scheduler
/// has stopped.
#[derive(Debug)]
pub struct ServoShared {
    fns: HdFns,
    hhd: Hhd,
    calibration_style: c_int,
    /// Latest sample (servo thread writes).
    pub sample: SeqCell<SAMPLE_WORDS>,
    /// Latest force command (device thread writes).
    pub command: SeqCell<COMMAND_WORDS>,
    /// Set by the device to stop: the callback ramps to zero, then returns DONE.
    pub stop: AtomicBool,
    /// Set by the callback once it has ramped to zero after `stop`.
    pub stopped: AtomicBool,
    /// The first HD error seen in the servo loop (0 = none); latched: force stays off until restart.
    pub fault: AtomicU32,
    /// The latest calibration status (`HD_CALIBRATION_*`).
    pub calibration: AtomicU32,
    /// Servo ticks run.
    pub ticks: AtomicU64,
    /// Servo ticks on which the command was stale (the hapticserver loop had stopped writing).
    pub stale_ticks: AtomicU64,
    /// Calibration updates requested.
    pub calibration_updates: AtomicU64,
    // The follower's limits; its state is carried between callbacks in `follower_state` (written by the
    // servo thread only, so its own reads are never torn; diagnostics read the rendered force from it).
    follower: ForceFollower,
    follower_state: SeqCell<FOLLOWER_WORDS>,
    last_command: SeqCell<COMMAND_WORDS>,
}

impl ServoShared {
    /// Shared state for device `hhd`.
    pub fn new(fns: HdFns, hhd: Hhd, calibration_style: c_int, follower: ForceFollower) -> Self {
        Self {
            fns,
            hhd,
            calibration_style,
            sample: SeqCell::default(),
            command: SeqCell::default(),
            stop: AtomicBool::new(false),
            stopped: AtomicBool::new(false),
            fault: AtomicU32::new(0),
            calibration: AtomicU32::new(HD_CALIBRATION_OK),
            ticks: AtomicU64::new(0),
            stale_ticks: AtomicU64::new(0),
            calibration_updates: AtomicU64::new(0),
            follower,
            follower_state: SeqCell::default(),
            last_command: SeqCell::default(),
        }
    }

    /// The device handle.
    pub fn hhd(&self) -> Hhd {
        self.hhd
    }

    /// The force the servo loop rendered last, N.
    pub fn rendered_force_n(&self) -> [f64; 3] {
        self.follower_state
            .read()
            .map_or([0.0; 3], |s| [s[0], s[1], s[2]])
    }

    /// One servo tick. Returns the callback code.
    fn tick(&self) -> HdCallbackCode {
        let fns = &self.fns;
        let tick = self.ticks.fetch_add(1, Ordering::Relaxed) + 1;
        fns.begin_frame(self.hhd);
        let position = fns.get_doubles::<3>(HD_CURRENT_POSITION);
        let velocity = fns.get_doubles::<3>(HD_CURRENT_VELOCITY);
        let transform = fns.get_doubles::<16>(HD_CURRENT_TRANSFORM);
        let buttons = fns.get_integer(HD_CURRENT_BUTTONS);
        let calibration = if tick == 1 || tick.is_multiple_of(CALIBRATION_CHECK_TICKS) {
            let status = fns.check_calibration();
            self.calibration.store(status, Ordering::Release);
            status
        } else {
            self.calibration.load(Ordering::Relaxed)
        };
        let stopping = self.stop.load(Ordering::Acquire);
        let allowed = !stopping
            && self.fault.load(Ordering::Relaxed) == 0
            && calibration == HD_CALIBRATION_OK;
        // The newest command; a torn read (the loop writing right now) keeps the previous one.
        let command = match self.command.read() {
            Some(command) => {
                self.last_command.write(&command);
                command
            }
            None => self.last_command.read().unwrap_or([0.0; COMMAND_WORDS]),
        };
        let mut follower = match self.follower_state.read() {
            Some(state) => self.follower.with_state(&state),
            None => self.follower,
        };
        let (force_n, stale) = follower.step(
            tick,
            [command[0], command[1], command[2]],
            command[3] as u64,
            allowed,
        );
        self.follower_state.write(&follower.state());
        if stale && allowed {
            self.stale_ticks.fetch_add(1, Ordering::Relaxed);
        }
        fns.set_force(force_n);
        fns.end_frame(self.hhd);
        let error = fns.get_error();
        if error.error_code != HD_SUCCESS {
            let _ = self.fault.compare_exchange(
                0,
                error.error_code,
                Ordering::AcqRel,
                Ordering::Relaxed,
            );
        }
        // Calibration the library can do by itself: outside the frame, as the vendor's example does.
        if calibration == HD_CALIBRATION_NEEDS_UPDATE
            && (self.calibration_style == HD_CALIBRATION_AUTO
                || self.calibration_style == HD_CALIBRATION_INKWELL)
            && !stopping
        {
            fns.update_calibration(self.calibration_style);
            self.calibration_updates.fetch_add(1, Ordering::Relaxed);
            let _ = fns.get_error();
            self.calibration
                .store(fns.check_calibration(), Ordering::Release);
        }
        let r = &transform;
        self.sample.write(&[
            position[0],
            position[1],
            position[2],
            velocity[0],
            velocity[1],
            velocity[2],
            r[0],
            r[1],
            r[2],
            r[4],
            r[5],
            r[6],
            r[8],
            r[9],
            r[10],
            f64::from(buttons),
            tick as f64,
        ]);
        if stopping && force_n == [0.0; 3] {
            self.stopped.store(true, Ordering::Release);
            return HD_CALLBACK_DONE;
        }
        HD_CALLBACK_CONTINUE
    }

    /// After a panic in [`Self::tick`]: latch a fault and render zero in a frame of its own.
    fn fail_safe(&self) {
        let _ = self.fault.compare_exchange(
            0,
            CALLBACK_PANIC_FAULT,
            Ordering::AcqRel,
            Ordering::Relaxed,
        );
        self.fns.begin_frame(self.hhd);
        self.fns.set_force([0.0; 3]);
        self.fns.end_frame(self.hhd);
        let _ = self.fns.get_error();
        self.stopped.store(true, Ordering::Release);
    }
}

/// The scheduler callback: `user_data` is the device's [`ServoShared`].
///
/// # Safety
/// `user_data` must point at a live `ServoShared` until the scheduler has stopped (the device guarantees it:
/// it stops the scheduler before dropping its `Arc`).
#[allow(unsafe_code)]
pub unsafe extern "C" fn servo_callback(user_data: *mut c_void) -> HdCallbackCode {
    // SAFETY: the caller's contract above.
    let shared = unsafe { &*(user_data as *const ServoShared) };
    // Never unwind into C: a panic latches a fault, zeroes the force and ends the callback.
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| shared.tick())) {
        Ok(code) => code,
        Err(_) => {
            shared.fail_safe();
            HD_CALLBACK_DONE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seq_cell_reads_what_was_written() {
        let cell = SeqCell::<3>::default();
        assert_eq!(cell.read(), None);
        cell.write(&[1.0, 2.0, 3.0]);
        assert_eq!(cell.read(), Some([1.0, 2.0, 3.0]));
        cell.write(&[4.0, f64::NAN, 6.0]);
        let read = cell.read().unwrap();
        assert!(read[1].is_nan() && read[2] == 6.0);
    }

    #[test]
    fn seq_cell_is_never_torn_across_threads() {
        use std::sync::atomic::AtomicBool;
        let cell = std::sync::Arc::new(SeqCell::<4>::default());
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let writer = {
            let (cell, stop) = (cell.clone(), stop.clone());
            std::thread::spawn(move || {
                let mut i = 1u64;
                while !stop.load(Ordering::Relaxed) {
                    let v = i as f64;
                    cell.write(&[v, v, v, v]);
                    i += 1;
                }
                i
            })
        };
        // Read while the writer writes, until enough reads succeeded (or 5 s passed on a stalled machine).
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        let mut reads = 0;
        while reads < 20_000 && std::time::Instant::now() < deadline {
            if let Some(values) = cell.read() {
                assert!(values.iter().all(|&v| v == values[0]), "torn: {values:?}");
                reads += 1;
            }
        }
        stop.store(true, Ordering::Relaxed);
        let writes = writer.join().unwrap();
        assert!(reads > 0 && writes > 1, "{reads} reads, {writes} writes");
    }

    #[test]
    fn follower_clamps_limits_rate_and_ramps_out_when_commands_stop() {
        let mut f = ForceFollower::new(1.0, 0.2, 5);
        // 3 N asked: clamped to 1 N, reached in 0.2 N steps.
        let mut out = [0.0; 3];
        for tick in 1..=5 {
            out = f.step(tick, [0.0, 0.0, 3.0], tick, true).0;
            assert!(
                (out[2] - 0.2 * tick as f64).abs() < 1e-12,
                "{tick}: {out:?}"
            );
        }
        assert!((out[2] - 1.0).abs() < 1e-12);
        // The loop stops writing (write count frozen at 5): held for 5 ticks, then a ramp to zero.
        for tick in 6..=10 {
            let (out, stale) = f.step(tick, [0.0, 0.0, 3.0], 5, true);
            assert!(!stale && (out[2] - 1.0).abs() < 1e-12, "{tick}");
        }
        let (out, stale) = f.step(11, [0.0, 0.0, 3.0], 5, true);
        assert!(stale && (out[2] - 0.8).abs() < 1e-12);
        for tick in 12..=20 {
            f.step(tick, [0.0, 0.0, 3.0], 5, true);
        }
        assert_eq!(f.out_n(), [0.0; 3]);
        // A non-finite command, or a fault, ramps to zero the same way.
        let mut f = ForceFollower::new(1.0, 0.2, 5);
        for tick in 1..=5 {
            f.step(tick, [0.0, 0.6, 0.0], tick, true);
        }
        let (out, _) = f.step(6, [f64::NAN, 0.0, 0.0], 6, true);
        assert!((out[1] - 0.4).abs() < 1e-12, "{out:?}");
        let (out, _) = f.step(7, [0.0, 0.6, 0.0], 7, false);
        assert!((out[1] - 0.2).abs() < 1e-12, "{out:?}");
    }
}
