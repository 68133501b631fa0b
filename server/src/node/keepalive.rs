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
//! The two clocks would add up when the sim runs between half and seven eighths of real time: the keepalive
//! fires 8 ms after the last message and the heartbeat, due by sim time, follows it a fraction of a millisecond
//! later, up to twice the messages of either alone (a loaded run of `tests/moderated_over_zenoh.rs` went past
//! its 150 a second, 2026-12-07). So the node holds a heartbeat that would follow the last message to its
//! device by less than [`HEARTBEAT_MERGE_WINDOW`] of wall time ([`Keepalive::hold`]), and the keepalive, when
//! due, sends the held heartbeat (new sequence number, news to the device) instead of repeating the old
//! command. Messages to a still hand are then at least 6 ms apart and, with the keepalive's 8, alternate gaps
//! average at least 7 ms: at most the heartbeat's 143 a second, at any sim speed. A change is never held.
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

/// A heartbeat that would reach its device less than this wall time after the last message is held for the
/// keepalive (the module doc): under the 7 ms heartbeat, so at real-time pace heartbeats go out as the tick
/// makes them.
pub const HEARTBEAT_MERGE_WINDOW: Duration = Duration::from_millis(6);

/// What the keepalive sends when due.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KeepaliveSend {
    /// The last command again, same sequence number: a sign of life only.
    Repeat(ForceCommand),
    /// A heartbeat the tick made and the node held: news to the device.
    Held(ForceCommand),
}

/// Per device: the last command published and when, and a heartbeat held back.
#[derive(Debug, Clone)]
pub struct Keepalive {
    last: Vec<Option<(ForceCommand, Instant)>>,
    held: Vec<Option<ForceCommand>>,
}

impl Keepalive {
    /// For `devices` devices, none sent to yet.
    pub fn new(devices: usize) -> Self {
        Self {
            last: vec![None; devices],
            held: vec![None; devices],
        }
    }

    /// `command` went to `device` at `at` (any held heartbeat is superseded).
    pub fn sent(&mut self, device: usize, command: &ForceCommand, at: Instant) {
        if let Some(slot) = self.last.get_mut(device) {
            *slot = Some((*command, at));
        }
        if let Some(held) = self.held.get_mut(device) {
            *held = None;
        }
    }

    /// Whether the tick's heartbeat `command` should wait for the keepalive: `device` heard from the server
    /// less than [`HEARTBEAT_MERGE_WINDOW`] ago. If so it is held (replacing an older held one) and false is
    /// never returned for it; the caller publishes only when this returns false.
    pub fn hold(&mut self, device: usize, command: &ForceCommand, now: Instant) -> bool {
        let recent = self
            .last
            .get(device)
            .and_then(|slot| slot.as_ref())
            .is_some_and(|(_, at)| now.saturating_duration_since(*at) < HEARTBEAT_MERGE_WINDOW);
        match self.held.get_mut(device) {
            Some(held) if recent => {
                *held = Some(*command);
                true
            }
            _ => false,
        }
    }

    /// What to send `device` now, if its last message is [`KEEPALIVE_AFTER`] old (and counts it as sent now):
    /// the held heartbeat if there is one, else the last command again. None when it is fresher or none was
    /// sent.
    pub fn due(&mut self, device: usize, now: Instant) -> Option<KeepaliveSend> {
        let (command, at) = self.last.get_mut(device)?.as_mut()?;
        if now.saturating_duration_since(*at) < KEEPALIVE_AFTER {
            return None;
        }
        *at = now;
        Some(match self.held.get_mut(device).and_then(Option::take) {
            Some(held) => {
                *command = held;
                KeepaliveSend::Held(held)
            }
            None => KeepaliveSend::Repeat(*command),
        })
    }

    /// `device`'s tool went inactive: nothing to keep alive until the tick sends it a command again.
    pub fn forget(&mut self, device: usize) {
        if let Some(slot) = self.last.get_mut(device) {
            *slot = None;
        }
        if let Some(held) = self.held.get_mut(device) {
            *held = None;
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
        assert_eq!(
            keepalive.due(0, at(8)),
            Some(KeepaliveSend::Repeat(command(41)))
        );
        assert_eq!(keepalive.due(0, at(12)), None, "the re-send counts as sent");
        assert_eq!(
            keepalive.due(0, at(16)),
            Some(KeepaliveSend::Repeat(command(41)))
        );
        // A new command from the tick restarts the clock; the other device is untouched.
        keepalive.sent(0, &command(42), at(17));
        assert_eq!(keepalive.due(0, at(24)), None);
        assert_eq!(
            keepalive.due(0, at(25)),
            Some(KeepaliveSend::Repeat(command(42)))
        );
        assert_eq!(keepalive.due(1, at(100)), None);
    }

    #[test]
    fn a_heartbeat_close_behind_the_last_message_waits_for_the_keepalive_and_goes_out_as_news() {
        let start = Instant::now();
        let at = |ms: f64| start + Duration::from_secs_f64(ms * 1e-3);
        let mut keepalive = Keepalive::new(1);
        keepalive.sent(0, &command(1), at(0.0));
        // 7 ms after the last message (real-time pace): the heartbeat goes out at once.
        assert!(!keepalive.hold(0, &command(2), at(7.0)));
        keepalive.sent(0, &command(2), at(7.0));
        // The sim slowed: the keepalive repeated at 15, the next heartbeat comes 0.2 ms behind it and is held.
        assert_eq!(
            keepalive.due(0, at(15.0)),
            Some(KeepaliveSend::Repeat(command(2)))
        );
        assert!(keepalive.hold(0, &command(3), at(15.2)));
        assert_eq!(keepalive.due(0, at(20.0)), None);
        // A newer heartbeat replaces the held one; the keepalive sends it as news when due.
        assert!(keepalive.hold(0, &command(4), at(19.0)));
        assert_eq!(
            keepalive.due(0, at(23.0)),
            Some(KeepaliveSend::Held(command(4)))
        );
        // ... and repeats it after that.
        assert_eq!(
            keepalive.due(0, at(31.0)),
            Some(KeepaliveSend::Repeat(command(4)))
        );
        // A held heartbeat is dropped when the tick sends anything else first.
        assert!(keepalive.hold(0, &command(5), at(32.0)));
        keepalive.sent(0, &command(6), at(33.0));
        assert_eq!(
            keepalive.due(0, at(41.0)),
            Some(KeepaliveSend::Repeat(command(6)))
        );
        // Nothing was ever sent to an unknown device: nothing to hold against.
        assert!(!keepalive.hold(3, &command(1), at(41.0)));
    }

    #[test]
    fn messages_to_a_still_hand_are_no_more_than_the_heartbeat_s_at_any_sim_speed() {
        // A 1 kHz tick loop whose sim runs at `speed` of real time sends a heartbeat every 7 ms of sim time;
        // the node holds and keeps alive. Count what leaves in 2 s of wall time.
        for speed in [1.0, 0.95, 0.87, 0.8, 0.7, 0.6, 0.5, 0.35, 0.2] {
            let start = Instant::now();
            let mut keepalive = Keepalive::new(1);
            let (mut published, mut seq, mut last_heartbeat_sim_ms) = (0u32, 0u64, f64::MIN);
            let mut longest_gap_ms = 0.0f64;
            let mut last_publish_ms = 0.0f64;
            let tick_wall_ms = 1.0 / speed;
            let mut k = 0u32;
            loop {
                let wall_ms = f64::from(k) * tick_wall_ms;
                if wall_ms > 2000.0 {
                    break;
                }
                let now = start + Duration::from_secs_f64(wall_ms * 1e-3);
                let sim_ms = f64::from(k);
                k += 1;
                let mut publish = false;
                if sim_ms - last_heartbeat_sim_ms >= 7.0 - 0.1 {
                    last_heartbeat_sim_ms = sim_ms;
                    seq += 1;
                    let heartbeat = command(seq);
                    if !keepalive.hold(0, &heartbeat, now) {
                        keepalive.sent(0, &heartbeat, now);
                        publish = true;
                    }
                } else if keepalive.due(0, now).is_some() {
                    publish = true;
                }
                if publish {
                    published += 1;
                    longest_gap_ms = longest_gap_ms.max(wall_ms - last_publish_ms);
                    last_publish_ms = wall_ms;
                }
            }
            let per_s = f64::from(published) / 2.0;
            assert!(per_s <= 144.0, "at {speed}x: {per_s} messages a second");
            // The keepalive's promise stands: a message at least every 8 ms plus one tick.
            assert!(
                longest_gap_ms <= 8.0 + tick_wall_ms + 1e-6,
                "at {speed}x: a {longest_gap_ms:.2} ms silence"
            );
        }
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
