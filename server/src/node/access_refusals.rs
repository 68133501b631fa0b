//! Counting what zenoh's access control and TLS refuse, so a server's stats show each refusal.
//!
//! Owns: the process-wide counts of messages zenoh's access control denied and of TLS connections its
//! listener refused, and the `tracing` layer that feeds them. zenoh 1.10 drops a denied message inside its router before any subscriber sees it and exposes no
//! counter without its `stats` feature (which would meter every message of the haptic path); it does report
//! each decision as a TRACE event of one module. The layer listens to that module alone and counts the
//! decisions that say "unauthorized" (ingress and egress), one per message. zenoh also evaluates every
//! message kind for a key when it caches that key's permissions (right after "caching permissions for
//! `key`", on the same thread, for the same key): those evaluations are not messages and are not counted.
//! Likewise a TLS handshake the listener refuses (a peer whose certificate the lab's CA did not sign, or none)
//! is an event of zenoh's QUIC link module (secured sessions run TLS 1.3 inside QUIC): a WARN ending in the hint
//! zenoh gives for every failed accept, or an ERROR `Cannot accept QUIC connection` when the handshake passed
//! but the link could not be made. A process runs one server, so one count serves it.
//!
//! Install: [`layer`] into the process's subscriber (`sinew-server` does), or [`install_for_tests`] where a
//! process has none. Cost: one short formatting of each access decision on zenoh's receive path, only while
//! access control is on (without it zenoh makes no decisions and emits nothing).
//!
//! Must not: log, or hold anything beyond the count.

use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};

use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::Layer;
use tracing_subscriber::filter::{Filtered, Targets};
use tracing_subscriber::layer::Context;

/// The module whose TRACE events are zenoh's access decisions.
pub const ACCESS_CONTROL_TARGET: &str = "zenoh::net::routing::interceptor::access_control";

/// The module whose WARN and ERROR events include a refused QUIC (TLS 1.3) accept.
pub const SECURE_LINK_TARGET: &str = "zenoh_link_commons::quic::unicast";

/// What zenoh 1.10 appends to every failed QUIC accept (zenoh-link-commons `QuicAcceptor::accept_task`).
const HANDSHAKE_FAILED: &[u8] = b"Hint: increase the system open file limit";

/// How zenoh 1.10 begins the error of an accepted QUIC connection it could not turn into a link.
const LINK_REFUSED: &[u8] = b"Cannot accept QUIC connection";

static REFUSALS: AtomicU64 = AtomicU64::new(0);
static TLS_REFUSALS: AtomicU64 = AtomicU64::new(0);

/// Messages zenoh's access control has refused in this process so far.
pub fn refusals() -> u64 {
    REFUSALS.load(Ordering::Relaxed)
}

/// TLS connections the process's listeners refused (or failed to accept) so far.
pub fn tls_refusals() -> u64 {
    TLS_REFUSALS.load(Ordering::Relaxed)
}

/// The counting layer.
#[derive(Debug, Clone, Copy, Default)]
pub struct RefusalCounter;

/// An event's message, formatted into a fixed buffer (no allocation; 512 bytes hold zenoh's one-line
/// decisions and errors).
struct Message {
    buf: [u8; 512],
    len: usize,
}

impl Default for Message {
    fn default() -> Self {
        Self {
            buf: [0; 512],
            len: 0,
        }
    }
}

impl Message {
    fn text(&self) -> &[u8] {
        &self.buf[..self.len]
    }

    fn contains(&self, needle: &[u8]) -> bool {
        self.text().windows(needle.len()).any(|w| w == needle)
    }

    /// FNV-1a of the key a decision is about (after its last " on "), or of the key being cached (between
    /// backticks after "caching permissions for").
    fn key_hash(&self) -> u64 {
        let text = self.text();
        let key = if let Some(start) = find(text, b"caching permissions for `") {
            let rest = &text[start + b"caching permissions for `".len()..];
            &rest[..rest.iter().position(|&b| b == b'`').unwrap_or(rest.len())]
        } else {
            match rfind(text, b" on ") {
                Some(at) => &text[at + 4..],
                None => &[][..],
            }
        };
        key.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        })
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

fn rfind(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).rposition(|w| w == needle)
}

thread_local! {
    /// The key whose permissions this thread is caching (its hash; 0: none).
    static CACHING: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

impl Write for Message {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let room = self.buf.len() - self.len;
        let take = s.len().min(room);
        self.buf[self.len..self.len + take].copy_from_slice(&s.as_bytes()[..take]);
        self.len += take;
        Ok(())
    }
}

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.len = 0;
            let _ = write!(self, "{value:?}");
        }
    }
}

impl<S: Subscriber> Layer<S> for RefusalCounter {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let mut message = Message::default();
        event.record(&mut message);
        if event.metadata().target() == SECURE_LINK_TARGET {
            if message.contains(HANDSHAKE_FAILED) || message.text().starts_with(LINK_REFUSED) {
                TLS_REFUSALS.fetch_add(1, Ordering::Relaxed);
            }
            return;
        }
        if message.contains(b"caching permissions for") {
            CACHING.with(|c| c.set(message.key_hash()));
            return;
        }
        let cached = message.text().starts_with(b"Using cached result");
        if !cached {
            if !message.contains(b"authoriz") {
                return;
            }
            let key = message.key_hash();
            let caching = CACHING.with(|c| c.get());
            if caching == key {
                // One of the evaluations of a permission cache, not a message.
                return;
            }
            CACHING.with(|c| c.set(0));
        }
        if message.contains(b"unauthorized") {
            REFUSALS.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The layer, filtered to zenoh's access-control module at TRACE: add it beside the process's own
/// (`registry().with(fmt_layer.with_filter(env)).with(layer())`).
pub fn layer<S>() -> Filtered<RefusalCounter, Targets, S>
where
    S: Subscriber + for<'a> tracing_subscriber::registry::LookupSpan<'a>,
{
    RefusalCounter.with_filter(
        Targets::new()
            .with_target(ACCESS_CONTROL_TARGET, Level::TRACE)
            .with_target(SECURE_LINK_TARGET, Level::WARN),
    )
}

/// What the default log leaves out of zenoh's access-control interceptor: its one WARN, `Transport returned
/// multiple network interfaces, current ACL logic might incorrectly apply filters`, which a server with access
/// rules prints for every QUIC link it dials (the link's socket is bound to every interface). Sinew's rules
/// name no interface, so there is nothing to act on; the module's errors still show.
pub const QUIET_ACCESS_CONTROL_WARNING: &str =
    "zenoh::net::routing::interceptor::access_control=error";

/// The process's subscriber for a role that runs a server: the log (`RUST_LOG`, else `default_filter` with
/// [`QUIET_ACCESS_CONTROL_WARNING`]) and, beside it, the refusal counter (which needs zenoh's TRACE decisions
/// the log filters out).
pub fn init_log_with_counter(default_filter: &str) {
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    let env = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| format!("{default_filter},{QUIET_ACCESS_CONTROL_WARNING}").into());
    tracing_subscriber::registry()
        .with(tracing_subscriber::fmt::layer().with_filter(env))
        .with(layer())
        .init();
}

/// For a process with no subscriber of its own (a test binary): install one that only counts. Does nothing
/// if a subscriber is already set (then that one must carry [`layer`]).
/// With `SINEW_TEST_LOG` set (an `EnvFilter` such as `zenoh=debug`), it also logs to stderr.
pub fn install_for_tests() {
    use tracing_subscriber::layer::SubscriberExt;
    let log = std::env::var("SINEW_TEST_LOG").ok().map(|filter| {
        tracing_subscriber::fmt::layer()
            .with_writer(std::io::stderr)
            .with_filter(tracing_subscriber::EnvFilter::new(filter))
    });
    let subscriber = tracing_subscriber::registry().with(layer()).with(log);
    let _ = tracing::subscriber::set_global_default(subscriber);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_unauthorized_decisions_of_the_access_module_count() {
        use tracing_subscriber::layer::SubscriberExt;
        let subscriber = tracing_subscriber::registry().with(layer());
        let before = refusals();
        tracing::subscriber::with_default(subscriber, || {
            tracing::trace!(
                target: "zenoh::net::routing::interceptor::access_control",
                "Using cached result: {} is unauthorized to {} on {}",
                "abc",
                "Put (ingress)",
                "sinew/pad/device/left/pose"
            );
            tracing::trace!(
                target: "zenoh::net::routing::interceptor::access_control",
                "Using cached result: {} is authorized to {} on {}",
                "abc",
                "Put (ingress)",
                "sinew/pad/device/left/pose"
            );
            tracing::trace!(target: "zenoh::other", "abc is unauthorized to Put");
            // Building a key's permission cache evaluates every kind: none of those is a message.
            tracing::trace!(
                target: "zenoh::net::routing::interceptor::access_control",
                "ACL (ingress): caching permissions for `{}` ...",
                "sinew/pad/stats"
            );
            for kind in ["Query", "Put (ingress)", "Delete (ingress)"] {
                tracing::trace!(
                    target: "zenoh::net::routing::interceptor::access_control",
                    "{} on {} is unauthorized to {} on {}",
                    "abc",
                    "CertCommonName(observer)",
                    kind,
                    "sinew/pad/stats"
                );
            }
            // A message on another key is a decision again.
            tracing::trace!(
                target: "zenoh::net::routing::interceptor::access_control",
                "{} on {} is unauthorized to {} on {}",
                "abc",
                "CertCommonName(observer)",
                "Put (ingress)",
                "sinew/pad/device/left/pose"
            );
        });
        assert_eq!(refusals() - before, 2);
        let subscriber = tracing_subscriber::registry().with(layer());
        let before = tls_refusals();
        tracing::subscriber::with_default(subscriber, || {
            tracing::warn!(
                target: "zenoh_link_commons::quic::unicast",
                "{} Hint: increase the system open file limit.",
                "QUIC acceptor failed: ConnectionClosed(received fatal alert: UnknownCA)"
            );
            tracing::error!(
                target: "zenoh_link_commons::quic::unicast",
                "Cannot accept QUIC connection: {}",
                "no certificate"
            );
            tracing::warn!(target: "zenoh_link_commons::quic::unicast", "Unable to set DSCP");
        });
        assert_eq!(tls_refusals() - before, 2);
    }
}
