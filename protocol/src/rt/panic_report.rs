//! The role processes' panic hook: the message and place of a panic are printed at once, and its backtrace is
//! captured unresolved and printed later, by whoever handles the failure.
//!
//! Owns: that hook and the captured backtrace. Why: the default hook resolves the backtrace's symbols on the
//! panicking thread before unwinding starts (about 100 ms with `RUST_BACKTRACE=1`), and only the unwinding
//! reaches the 1 kHz threads' supervisors: the server's sends its devices an explicit zero, a hapticserver's
//! ramps its motor to zero. With this hook they act within a tick of the panic; the backtrace comes after.

use std::backtrace::Backtrace;
use std::sync::Mutex;

static DEFERRED: Mutex<Option<Backtrace>> = Mutex::new(None);

/// Install the hook (process-wide; for the role binaries, not for embedders).
pub fn install_deferred_backtrace_hook() {
    std::panic::set_hook(Box::new(|info| {
        let thread = std::thread::current();
        let payload = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".to_owned());
        let location = info.location().map_or_else(String::new, |l| {
            format!(" at {}:{}:{}", l.file(), l.line(), l.column())
        });
        eprintln!(
            "thread '{}' panicked{location}:\n{payload}",
            thread.name().unwrap_or("<unnamed>")
        );
        if let Ok(mut slot) = DEFERRED.try_lock() {
            // Unresolved: cheap to capture; resolved when printed.
            *slot = Some(Backtrace::capture());
        }
    }));
}

/// The backtrace of the last panic the hook saw, if any (and if `RUST_BACKTRACE` asked for one).
pub fn take_deferred_backtrace() -> Option<Backtrace> {
    DEFERRED.lock().ok()?.take()
}
