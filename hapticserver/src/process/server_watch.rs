//! What this device knows of the server, and the log lines a lab engineer reads: found, lost, regained,
//! refused.
//!
//! Owns: [`ServerWatch`], stepped every [`WATCH_PERIOD`] by the hapticserver's supervision thread (never the
//! device loop). It reads the joined server ([`sinew_protocol::rt::JoinedServer`], fed by the force and stats
//! callbacks) and the latest stats from that server, and says each change once: no server yet, server found,
//! server lost, server regained, and this device's standing with it (holding its tool; refused because
//! another hapticserver holds the id; refused because it asked for another tool; an id no tool binds). A
//! condition that lasts is repeated at most every [`REPEAT_PERIOD`], with how long it has lasted.
//!
//! Must not: touch the force path (the silence rule in [`crate::safety`] ramps the force, whatever is logged).

use std::time::Duration;

use sinew_protocol::rt::JoinedServer;
use sinew_protocol::{InstanceId, ServerStats};

/// How often the supervision thread steps the watch.
pub const WATCH_PERIOD: Duration = Duration::from_millis(100);
/// How often a lasting condition is logged again.
pub const REPEAT_PERIOD: Duration = Duration::from_secs(5);
/// A joined server silent this long is lost (forces stop at 90/s or more; stats come at 1 Hz).
pub const LOST_AFTER: Duration = Duration::from_secs(1);
/// How long a starting device waits for a server before it says none is there.
pub const NONE_AFTER: Duration = Duration::from_secs(2);

/// The link to the server.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Link {
    /// No server heard since the start.
    NotFound,
    /// Following this server.
    Joined(InstanceId),
    /// The server went away at `since_ns` (it was `was`).
    Lost {
        /// The server that was followed.
        was: InstanceId,
        /// When it was declared lost, ns.
        since_ns: u64,
    },
}

/// This device's standing with the server, from the server's stats.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Standing {
    /// No stats yet.
    Unknown,
    /// This device holds its id and drives its tool.
    Holding {
        /// The tool.
        tool: String,
    },
    /// Bound, but not held by anyone yet (no pose arrived).
    Waiting,
    /// Another hapticserver holds this device id: poses refused.
    Duplicate {
        /// The holder.
        holder: InstanceId,
    },
    /// This device asked for another tool than the world binds to its id: poses refused.
    WrongTool {
        /// Asked for.
        asked: String,
        /// Bound.
        bound: String,
    },
    /// No tool of the scene is bound to this id.
    NotBound {
        /// The ids the scene binds.
        bound: Vec<String>,
    },
}

impl Standing {
    /// From `stats` for the device `device_id`, instance `own`.
    pub fn from_stats(stats: &ServerStats, device_id: &str, own: InstanceId) -> Self {
        let Some(d) = stats.devices.iter().find(|d| d.device_id == device_id) else {
            return Standing::NotBound {
                bound: stats.devices.iter().map(|d| d.device_id.clone()).collect(),
            };
        };
        if d.wrong_tool_instance == own.0 {
            return Standing::WrongTool {
                asked: d.wrong_tool_asked.clone(),
                bound: d.tool.clone(),
            };
        }
        if d.holder_instance == own.0 {
            return Standing::Holding {
                tool: d.tool.clone(),
            };
        }
        if d.holder_instance != 0 && d.last_refused_instance == own.0 {
            return Standing::Duplicate {
                holder: InstanceId(d.holder_instance),
            };
        }
        Standing::Waiting
    }

    /// Whether the server refuses this device.
    pub fn refused(&self) -> bool {
        matches!(
            self,
            Standing::Duplicate { .. } | Standing::WrongTool { .. } | Standing::NotBound { .. }
        )
    }
}

impl std::fmt::Display for Standing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Standing::Unknown => write!(f, "unknown"),
            Standing::Holding { tool } => write!(f, "drives tool `{tool}`"),
            Standing::Waiting => write!(f, "bound, waiting"),
            Standing::Duplicate { holder } => {
                write!(f, "REFUSED: id held by another hapticserver ({holder})")
            }
            Standing::WrongTool { asked, bound } => {
                write!(
                    f,
                    "REFUSED: asked for tool `{asked}`, the world binds `{bound}`"
                )
            }
            Standing::NotBound { bound } => {
                write!(
                    f,
                    "REFUSED: no tool bound to this id (bound: {})",
                    bound.join(", ")
                )
            }
        }
    }
}

/// One log line the watch wants said.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Say {
    /// Informational.
    Info(String),
    /// Something the user should act on or know is wrong.
    Warn(String),
    /// A refusal.
    Error(String),
}

/// The watch's state.
#[derive(Debug)]
pub struct ServerWatch {
    device_id: String,
    own: InstanceId,
    link: Link,
    standing: Standing,
    last_link_log_ns: Option<u64>,
    last_standing_log_ns: Option<u64>,
}

impl ServerWatch {
    /// For device `device_id`, instance `own`.
    pub fn new(device_id: &str, own: InstanceId) -> Self {
        Self {
            device_id: device_id.to_owned(),
            own,
            link: Link::NotFound,
            standing: Standing::Unknown,
            last_link_log_ns: None,
            last_standing_log_ns: None,
        }
    }

    /// The link now.
    pub fn link(&self) -> Link {
        self.link
    }

    /// The standing now.
    pub fn standing(&self) -> &Standing {
        &self.standing
    }

    /// One step at `now_ns` (the clock the callbacks stamp `server` with), with the latest stats from the
    /// joined server if any arrived since the last step. Returns what to log.
    pub fn step(
        &mut self,
        now_ns: u64,
        server: &JoinedServer,
        stats: Option<&ServerStats>,
    ) -> Vec<Say> {
        let mut say = Vec::new();
        let current = server.current();
        let silent_ns = now_ns.saturating_sub(server.last_heard_ns());
        let repeat_due = |last: Option<u64>| {
            last.is_none_or(|last| now_ns.saturating_sub(last) >= REPEAT_PERIOD.as_nanos() as u64)
        };
        let id = &self.device_id;
        match self.link {
            Link::NotFound => {
                if !current.is_none() {
                    say.push(Say::Info(format!(
                        "{id}: server found (instance {current}) {:.1} s after start",
                        now_ns as f64 / 1e9
                    )));
                    self.link = Link::Joined(current);
                    self.last_link_log_ns = Some(now_ns);
                } else if now_ns >= NONE_AFTER.as_nanos() as u64
                    && repeat_due(self.last_link_log_ns)
                {
                    say.push(Say::Warn(format!(
                        "{id}: no server heard for this scene {:.0} s after start (is it running, and are the \
                         endpoints right?): the force stays zero",
                        now_ns as f64 / 1e9
                    )));
                    self.last_link_log_ns = Some(now_ns);
                }
            }
            Link::Joined(was) => {
                if current.is_none() || silent_ns >= LOST_AFTER.as_nanos() as u64 {
                    say.push(Say::Warn(format!(
                        "{id}: server lost (instance {was}, silent {:.0} ms): force ramped to zero; waiting for it",
                        silent_ns.min(now_ns) as f64 / 1e6
                    )));
                    self.link = Link::Lost {
                        was,
                        since_ns: now_ns,
                    };
                    self.last_link_log_ns = Some(now_ns);
                    self.standing = Standing::Unknown;
                } else if current != was {
                    say.push(Say::Info(format!(
                        "{id}: now following server instance {current} (instance {was} went quiet)"
                    )));
                    self.link = Link::Joined(current);
                }
            }
            Link::Lost { was, since_ns } => {
                if !current.is_none() && silent_ns < LOST_AFTER.as_nanos() as u64 {
                    let run = if current == was {
                        "the same run"
                    } else {
                        "a new run"
                    };
                    say.push(Say::Info(format!(
                        "{id}: server regained after {:.2} s (instance {current}, {run})",
                        (now_ns - since_ns) as f64 / 1e9
                    )));
                    self.link = Link::Joined(current);
                    self.last_link_log_ns = Some(now_ns);
                } else if repeat_due(self.last_link_log_ns) {
                    say.push(Say::Warn(format!(
                        "{id}: still no server ({:.0} s): the force stays zero",
                        (now_ns - since_ns) as f64 / 1e9
                    )));
                    self.last_link_log_ns = Some(now_ns);
                }
            }
        }
        if let Some(stats) = stats {
            let standing = Standing::from_stats(stats, &self.device_id, self.own);
            let changed = standing != self.standing;
            if changed || (standing.refused() && repeat_due(self.last_standing_log_ns)) {
                let line = format!("{id}: {standing}");
                say.push(match &standing {
                    Standing::Duplicate { .. } => Say::Error(format!(
                        "{line}: this device's poses are ignored and it renders no force; start it with another \
                         --id, or stop the other one"
                    )),
                    Standing::WrongTool { .. } | Standing::NotBound { .. } => Say::Error(format!(
                        "{line}: this device's poses are ignored and it renders no force"
                    )),
                    _ => Say::Info(line),
                });
                self.last_standing_log_ns = Some(now_ns);
                self.standing = standing;
            }
        }
        say
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sinew_protocol::DeviceStats;

    const S: u64 = 1_000_000_000;
    const ME: InstanceId = InstanceId(7);

    fn stats(holder: u64, refused: u64) -> ServerStats {
        ServerStats {
            devices: vec![DeviceStats {
                device_id: "left".into(),
                tool: "probe".into(),
                holder_instance: holder,
                last_refused_instance: refused,
                ..DeviceStats::default()
            }],
            ..ServerStats::default()
        }
    }

    #[test]
    fn none_found_lost_and_regained_are_each_said_once_then_at_most_every_five_seconds() {
        let server = JoinedServer::new();
        let mut watch = ServerWatch::new("left", ME);
        assert!(watch.step(S, &server, None).is_empty());
        assert!(matches!(
            watch.step(2 * S, &server, None)[..],
            [Say::Warn(_)]
        ));
        assert!(watch.step(3 * S, &server, None).is_empty());
        assert!(matches!(
            watch.step(7 * S, &server, None)[..],
            [Say::Warn(_)]
        ));
        server.admit(InstanceId(0x5e), 8 * S);
        assert!(matches!(
            watch.step(8 * S, &server, None)[..],
            [Say::Info(_)]
        ));
        assert!(watch.step(8 * S + S / 2, &server, None).is_empty());
        let lost = watch.step(9 * S, &server, None);
        assert!(
            matches!(&lost[..], [Say::Warn(line)] if line.contains("server lost")),
            "{lost:?}"
        );
        assert!(watch.step(10 * S, &server, None).is_empty());
        server.release();
        server.admit(InstanceId(0x5f), 11 * S);
        let back = watch.step(11 * S, &server, None);
        assert!(
            matches!(&back[..], [Say::Info(line)] if line.contains("a new run")),
            "{back:?}"
        );
    }

    #[test]
    fn a_refusal_is_said_when_it_starts_and_repeated_while_it_lasts() {
        let server = JoinedServer::new();
        server.admit(InstanceId(0x5e), 0);
        let mut watch = ServerWatch::new("left", ME);
        watch.step(0, &server, None);
        let refused = stats(3, ME.0);
        let said = watch.step(S / 10, &server, Some(&refused));
        assert!(
            matches!(&said[..], [Say::Error(l)] if l.contains("held by another")),
            "{said:?}"
        );
        server.heard(S);
        assert!(watch.step(S, &server, Some(&refused)).is_empty());
        server.heard(6 * S);
        assert_eq!(watch.step(6 * S, &server, Some(&refused)).len(), 1);
        let holding = watch.step(6 * S, &server, Some(&stats(ME.0, 0)));
        assert!(matches!(&holding[..], [Say::Info(l)] if l.contains("drives tool `probe`")));
        let mut other = stats(ME.0, 0);
        other.devices[0].device_id = "right".into();
        let unbound = watch.step(6 * S, &server, Some(&other));
        assert!(
            matches!(&unbound[..], [Say::Error(l)] if l.contains("bound: right")),
            "{unbound:?}"
        );
    }
}
