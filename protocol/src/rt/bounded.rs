//! Bounded teardown: run a step that may block on the network (undeclaring, closing a zenoh session) on its
//! own thread, and stop waiting for it after a deadline.
//!
//! A role must exit within a second of SIGTERM whatever the network does. zenoh's close waits for the peer
//! to acknowledge, and a reliable put blocks on a full queue; during a partition both wait for the lease
//! (10 s). The force is ramped to zero before any of this runs, so giving up on a goodbye the network cannot
//! carry loses nothing: the peers notice by their lease, as they would a crash.

use std::sync::mpsc;
use std::time::Duration;

/// Run `step` on a thread named `name` and wait at most `timeout` for it. Returns whether it finished; if it
/// did not, it is left to finish (or to die with the process).
pub fn finish_within(name: &str, timeout: Duration, step: impl FnOnce() + Send + 'static) -> bool {
    let (done_tx, done_rx) = mpsc::channel();
    let spawned = std::thread::Builder::new()
        .name(name.to_owned())
        .spawn(move || {
            step();
            let _ = done_tx.send(());
        });
    match spawned {
        Ok(_) => done_rx.recv_timeout(timeout).is_ok(),
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quick_step_finishes_and_a_stuck_one_is_left_behind() {
        assert!(finish_within("quick", Duration::from_secs(5), || {}));
        let (_hold, wait) = mpsc::channel::<()>();
        assert!(!finish_within(
            "stuck",
            Duration::from_millis(20),
            move || {
                let _ = wait.recv_timeout(Duration::from_secs(2));
            }
        ));
    }
}
