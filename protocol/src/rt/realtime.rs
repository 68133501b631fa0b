//! Real-time scheduling for a 1 kHz loop thread, where the process may have it.
//!
//! Owns: [`configure_this_thread`] and what it was given ([`RealtimeGrant`]). Every 1 kHz loop calls it once,
//! first thing on its own thread:
//! - the thread's timer slack becomes 1 ns (`PR_SET_TIMERSLACK`; Linux's default is 50 us, which a sleeping
//!   loop pays on every wake: with 1 ns a loop needs to spin only the last tens of microseconds);
//! - with [`RealtimeRequest::Fifo`], the thread asks for `SCHED_FIFO` at the given priority (it then preempts
//!   every normal thread the moment its sleep ends, and other processes' builds or renderers no longer
//!   delay it), and the process locks its memory (`mlockall(MCL_CURRENT | MCL_FUTURE)`: no page fault in a
//!   tick), once per process.
//!
//! Refusals are not errors: a process without `CAP_SYS_NICE` (or an `RLIMIT_RTPRIO` allowance) runs at normal
//! priority, and the grant says why, so the role can report it at start. Only the loop threads ask: a multi-rate
//! object's step thread or zenoh's runtime stay normal, so a real-time loop never starves the threads that feed
//! it (the kernel's real-time throttling, 95% of each second by default, is the last guard).
//!
//! Must not: be called on a thread that does long compute (a multi-rate step) with `Fifo`.

use std::fmt;

/// What a loop thread asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RealtimeRequest {
    /// Normal scheduling (the timer slack is still tightened).
    #[default]
    Normal,
    /// `SCHED_FIFO` at this priority (1-99), and locked memory.
    Fifo {
        /// The real-time priority.
        priority: u8,
    },
}

/// Priority of a device loop: above the server's tick, whose ticks are long; a device tick is a few
/// microseconds, and its timing is what the hand feels.
pub const DEVICE_LOOP_PRIORITY: u8 = 81;
/// Priority of the server's sim tick.
pub const SIM_LOOP_PRIORITY: u8 = 80;

/// What the thread was given.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RealtimeGrant {
    /// The real-time priority the thread runs at (`None`: normal scheduling).
    pub fifo_priority: Option<u8>,
    /// The process's memory is locked.
    pub memory_locked: bool,
    /// The thread's timer slack was set to 1 ns.
    pub tight_timer_slack: bool,
    /// Why a request was refused, if it was (the OS's message).
    pub refused: Option<String>,
}

impl RealtimeGrant {
    /// The spin window a pacer of this thread needs before each deadline, ns: short when the thread wakes
    /// as a real-time thread or with a tight timer slack, `fallback_ns` otherwise. Never longer than
    /// `fallback_ns` (0 stays 0: plain sleep).
    pub fn spin_window_ns(&self, fallback_ns: u32) -> u32 {
        let window = if self.fifo_priority.is_some() {
            REALTIME_SPIN_NS
        } else if self.tight_timer_slack {
            TIGHT_SLACK_SPIN_NS
        } else {
            fallback_ns
        };
        window.min(fallback_ns)
    }
}

/// Spin window of a `SCHED_FIFO` loop, ns: its wake-up latency is a few microseconds.
pub const REALTIME_SPIN_NS: u32 = 20_000;
/// Spin window of a normal loop with a 1 ns timer slack, ns.
pub const TIGHT_SLACK_SPIN_NS: u32 = 50_000;

impl fmt::Display for RealtimeGrant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.fifo_priority {
            Some(p) => write!(f, "SCHED_FIFO priority {p}")?,
            None => write!(f, "normal scheduling")?,
        }
        write!(
            f,
            ", memory {}, timer slack {}",
            if self.memory_locked {
                "locked"
            } else {
                "not locked"
            },
            if self.tight_timer_slack {
                "1 ns"
            } else {
                "default"
            }
        )?;
        if let Some(why) = &self.refused {
            write!(f, " (real time refused: {why})")?;
        }
        Ok(())
    }
}

/// Configure the calling thread as a 1 kHz loop (see the module doc) and say what it was given.
pub fn configure_this_thread(request: RealtimeRequest) -> RealtimeGrant {
    os::configure(request)
}

/// Pin the calling thread to CPU `cpu` (the tissue step's workers: a spinning worker that migrates loses its
/// caches and steals a core the scheduler gave someone else). Err with the OS's reason (a CPU outside the
/// process's allowed set, say), and the thread keeps running where it was.
pub fn pin_this_thread(cpu: usize) -> Result<(), String> {
    os::pin(cpu)
}

#[cfg(target_os = "linux")]
#[allow(unsafe_code)] // FFI into libc: each block says why it is sound
mod os {
    use std::sync::OnceLock;

    use super::{RealtimeGrant, RealtimeRequest};

    /// The process's mlockall outcome (once per process).
    static MEMORY_LOCK: OnceLock<Result<(), String>> = OnceLock::new();

    pub(super) fn configure(request: RealtimeRequest) -> RealtimeGrant {
        // SAFETY: prctl(PR_SET_TIMERSLACK, n) takes plain integers, touches only the calling thread's timer
        // slack, and reads no memory of ours.
        let slack = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) };
        let mut grant = RealtimeGrant {
            tight_timer_slack: slack == 0,
            ..RealtimeGrant::default()
        };
        let RealtimeRequest::Fifo { priority } = request else {
            return grant;
        };
        let priority = priority.clamp(1, 99);
        let param = libc::sched_param {
            sched_priority: libc::c_int::from(priority),
        };
        // SAFETY: pthread_self() is always valid for the calling thread; `param` is a live, initialised
        // sched_param the call only reads.
        let rc =
            unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
        if rc != 0 {
            grant.refused = Some(format!(
                "SCHED_FIFO: {}",
                std::io::Error::from_raw_os_error(rc)
            ));
            return grant;
        }
        grant.fifo_priority = Some(priority);
        let locked = MEMORY_LOCK.get_or_init(|| {
            // SAFETY: mlockall takes flags only and changes no memory contents.
            let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
            if rc == 0 {
                Ok(())
            } else {
                Err(format!("mlockall: {}", std::io::Error::last_os_error()))
            }
        });
        match locked {
            Ok(()) => grant.memory_locked = true,
            Err(why) => grant.refused = Some(why.clone()),
        }
        grant
    }

    pub(super) fn pin(cpu: usize) -> Result<(), String> {
        if cpu >= libc::CPU_SETSIZE as usize {
            return Err(format!("CPU {cpu} is beyond the CPU set's size"));
        }
        // SAFETY: cpu_set_t is plain bits, valid when zeroed; CPU_SET writes inside it (cpu checked above);
        // sched_setaffinity(0, ..) reads the set for the calling thread and writes none of our memory.
        let rc = unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
        };
        if rc == 0 {
            Ok(())
        } else {
            Err(format!(
                "pin to CPU {cpu}: {}",
                std::io::Error::last_os_error()
            ))
        }
    }
}

#[cfg(not(target_os = "linux"))]
mod os {
    use super::{RealtimeGrant, RealtimeRequest};

    pub(super) fn configure(request: RealtimeRequest) -> RealtimeGrant {
        RealtimeGrant {
            refused: matches!(request, RealtimeRequest::Fifo { .. })
                .then(|| "real-time scheduling is implemented for Linux only".to_owned()),
            ..RealtimeGrant::default()
        }
    }

    pub(super) fn pin(_cpu: usize) -> Result<(), String> {
        Err("pinning threads is implemented for Linux only".to_owned())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)] // test code

    use super::*;

    #[test]
    fn a_normal_loop_gets_a_tight_timer_slack_and_no_priority() {
        let grant = std::thread::spawn(|| configure_this_thread(RealtimeRequest::Normal))
            .join()
            .unwrap();
        assert!(grant.tight_timer_slack, "{grant}");
        assert_eq!(grant.fifo_priority, None);
        assert_eq!(grant.refused, None);
        assert_eq!(grant.spin_window_ns(100_000), TIGHT_SLACK_SPIN_NS);
        assert_eq!(grant.spin_window_ns(0), 0);
    }

    #[test]
    fn a_thread_pins_to_an_allowed_cpu_and_is_refused_an_impossible_one() {
        let (pinned, refused) =
            std::thread::spawn(|| (pin_this_thread(0), pin_this_thread(1 << 20)))
                .join()
                .unwrap();
        assert_eq!(pinned, Ok(()));
        assert!(refused.unwrap_err().contains("CPU 1048576"));
    }

    #[test]
    fn a_fifo_request_is_granted_or_refused_with_the_reason() {
        // Root here (and in CI) may use SCHED_FIFO; an unprivileged run is refused with the OS's reason.
        // Either way the thread keeps running and the grant says which.
        // The thread ends at once, so no real-time thread outlives the test.
        let grant =
            std::thread::spawn(|| configure_this_thread(RealtimeRequest::Fifo { priority: 10 }))
                .join()
                .unwrap();
        match grant.fifo_priority {
            Some(p) => {
                assert_eq!(p, 10);
                assert_eq!(grant.spin_window_ns(100_000), REALTIME_SPIN_NS);
                assert!(
                    grant.to_string().starts_with("SCHED_FIFO priority 10"),
                    "{grant}"
                );
            }
            None => {
                let why = grant.refused.clone().unwrap();
                assert!(why.contains("SCHED_FIFO"), "{why}");
                assert!(grant.to_string().contains("real time refused"), "{grant}");
            }
        }
    }
}
