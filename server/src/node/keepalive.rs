//! The live server's keepalive: a device hears from it at least every [`KEEPALIVE_AFTER`] of wall time, even
//! when the sim runs slower than real time.
//!
//! Owns: [`Keepalive`], per device the last command published and when. The tick's own stream
//! (`server_tick::model_stream`) sends a device that renders the local model a heartbeat every 7 ms of
//! *simulated* time. These shared machines sometimes slow every thread of a process five- to tenfold for tens of
//! milliseconds (ticks of 4-10 ms in runs of three to seven, in the tick bench alone, with no steal counted; a
//! fixed loop of Python arithmetic shows the same): 7 ms of sim time then took 25-40 ms of wall time, and with a
//! path's jitter the device's 50 ms silence rule fired while the server lived (`tests/moderated_over_zenoh.rs`,
//! 2026-11-28). The rule runs on the device's wall clock, so the keepalive runs on the server's: a tick that
//! sends a device nothing re-sends its last command unchanged, same sequence number, once [`KEEPALIVE_AFTER`]
//! has passed since the last one. A device takes a repeated sequence number as a sign of life only (it renders
//! nothing new from it and measures no round trip: `hapticserver::haptic_loop`). At real-time pace the heartbeat
//! comes first and the keepalive never fires.
//!
//! It lives in the node, outside the deterministic tick: recordings, replays and the golden traces hold the
//! tick's own commands only. A device whose tool is inactive (gone, its poses stale) gets no keepalive: the
//! silence is the truth then.
//!
//! Must not: allocate after construction.

use std::time::{Duration, Instant};

use sinew_protocol::ForceCommand;

/// Wall time after the last message to a device at which a tick re-sends it: a little over the 7 ms
/// heartbeat, so at real-time pace the heartbeat always comes first. Through a slowed sim the device then hears
/// from the server every 8 ms plus one tick, so one lost message and +-10 ms of jitter stay inside its 50 ms
/// rule for ticks of up to 7 ms.
pub const KEEPALIVE_AFTER: Duration = Duration::from_millis(8);

/// Per device: the last command published and when.
#[derive(Debug, Clone)]
pub struct Keepalive {
    last: Vec<Option<(ForceCommand, Instant)>>,
}

impl Keepalive {
    /// For `devices` devices, none sent to yet.
    pub fn new(devices: usize) -> Self {
        Self {
            last: vec![None; devices],
        }
    }

    /// `command` went to `device` at `at`.
    pub fn sent(&mut self, device: usize, command: &ForceCommand, at: Instant) {
        if let Some(slot) = self.last.get_mut(device) {
            *slot = Some((*command, at));
        }
    }

    /// The command to re-send to `device` now, if its last one is [`KEEPALIVE_AFTER`] old (and counts it as
    /// sent now); None when it is fresher or none was sent.
    pub fn due(&mut self, device: usize, now: Instant) -> Option<ForceCommand> {
        let (command, at) = self.last.get_mut(device)?.as_mut()?;
        if now.saturating_duration_since(*at) < KEEPALIVE_AFTER {
            return None;
        }
        *at = now;
        Some(*command)
    }

    /// `device`'s tool went inactive: nothing to keep alive until the tick sends it a command again.
    pub fn forget(&mut self, device: usize) {
        if let Some(slot) = self.last.get_mut(device) {
            *slot = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn command(seq: u64) -> ForceCommand {
        ForceCommand {
            seq,
            force_n: [0.0, 0.0, 1.0],
            ..ForceCommand::default()
        }
    }

    #[test]
    fn a_command_is_repeated_unchanged_once_it_is_8_ms_old_and_then_every_8_ms() {
        let start = Instant::now();
        let at = |ms: u64| start + Duration::from_millis(ms);
        let mut keepalive = Keepalive::new(2);
        assert_eq!(keepalive.due(0, at(100)), None, "nothing sent yet");
        keepalive.sent(0, &command(41), at(0));
        assert_eq!(keepalive.due(0, at(7)), None);
        assert_eq!(keepalive.due(0, at(8)), Some(command(41)));
        assert_eq!(keepalive.due(0, at(12)), None, "the re-send counts as sent");
        assert_eq!(keepalive.due(0, at(16)), Some(command(41)));
        // A new command from the tick restarts the clock; the other device is untouched.
        keepalive.sent(0, &command(42), at(17));
        assert_eq!(keepalive.due(0, at(24)), None);
        assert_eq!(keepalive.due(0, at(25)), Some(command(42)));
        assert_eq!(keepalive.due(1, at(100)), None);
    }

    #[test]
    fn an_inactive_device_gets_no_keepalive_and_an_unknown_one_is_ignored() {
        let start = Instant::now();
        let mut keepalive = Keepalive::new(1);
        keepalive.sent(0, &command(1), start);
        keepalive.forget(0);
        assert_eq!(keepalive.due(0, start + Duration::from_secs(1)), None);
        keepalive.sent(5, &command(1), start);
        keepalive.forget(5);
        assert_eq!(keepalive.due(5, start + Duration::from_secs(1)), None);
    }
}
