//! A seeded Ethernet bridge with one-way delay, jitter and Bernoulli loss per direction: the network path of
//! the namespace lab ([`crate::netns`]), run as the `sinew-netem` binary in the lab's relay namespace.
//!
//! Owns: [`Bridge`] (two AF_PACKET raw sockets, one per interface; per direction a receive thread that asks a
//! [`DelayLine`] whether each frame is lost or when it is due, and a send thread that holds each frame until
//! it is due, then sends it out of the other interface), the per-direction spec syntax ([`parse_direction`],
//! [`format_direction`]) and the transport-checksum repair that frames captured on a veth need
//! ([`fix_transport_checksum`]).
//!
//! Every frame is bridged, ARP included. A direction is FIFO like one network path: jitter shows as
//! bunching, never as reordering. Frames larger than [`MAX_FRAME_BYTES`] (GSO super-frames: the lab sets
//! `gso_max_segs 1` on its veths so there are none) are dropped and counted.
//!
//! Must not: look above the transport header, allocate per frame once warm (frame buffers are recycled), or
//! block a receive thread on a send (a full queue drops the frame and counts it).

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use pnet_datalink::{Channel, Config, DataLinkReceiver, DataLinkSender, NetworkInterface};
use sinew_protocol::rt::{DelayLine, EmulationConfig, LatencyHistogram};

/// Largest frame bridged, bytes: a 1500-byte MTU plus the Ethernet header and one VLAN tag.
pub const MAX_FRAME_BYTES: usize = 1518;

/// Frames one direction can hold in flight (4 s at 2 kHz).
pub const QUEUE_CAPACITY: usize = 8192;

/// Default spin_sleep native accuracy of the send threads, ns: sleep until this long before a frame is due,
/// then spin (yielding). With the lab's real-time relay, send lateness p99 was 4-80 us on these machines.
pub const DEFAULT_SPIN_NS: u32 = 100_000;

/// How long a receive thread blocks before it checks the stop flag.
const POLL: Duration = Duration::from_millis(50);

/// What can go wrong setting up a bridge or reading its options.
#[derive(Debug, thiserror::Error)]
pub enum NetemError {
    /// No interface of that name in this namespace.
    #[error("no network interface `{0}` in this namespace")]
    NoInterface(String),
    /// The AF_PACKET socket could not be opened (not root, or the interface vanished).
    #[error("opening an AF_PACKET socket on `{interface}`: {source}")]
    Socket {
        /// Interface name.
        interface: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// pnet returned a channel type other than Ethernet.
    #[error("`{0}` did not give an Ethernet channel")]
    NotEthernet(String),
    /// A thread could not be started.
    #[error("starting thread `{name}`: {source}")]
    Thread {
        /// Thread name.
        name: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A direction spec did not parse.
    #[error(
        "direction spec `{spec}`: {reason} (expected e.g. `delay=50,jitter=20,loss=0.05,seed=7`)"
    )]
    BadSpec {
        /// The spec as given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A scripted drop did not parse.
    #[error("scripted drop `{spec}`: {reason} (expected `tcp:N` or `udp:N`, N >= 1)")]
    BadDrop {
        /// The drop as given.
        spec: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// Parse a direction spec `delay=MS,jitter=MS,loss=P,seed=N` (any subset, any order; missing keys keep
/// [`EmulationConfig::default`]). The result is validated.
pub fn parse_direction(spec: &str) -> Result<EmulationConfig, NetemError> {
    let bad = |reason: String| NetemError::BadSpec {
        spec: spec.to_owned(),
        reason,
    };
    let mut config = EmulationConfig::default();
    for part in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| bad(format!("`{part}` is not key=value")))?;
        let number = |value: &str| {
            value
                .trim()
                .parse::<f64>()
                .map_err(|e| bad(format!("`{key}`: `{value}` is not a number ({e})")))
        };
        match key.trim() {
            "delay" => config.delay_ms = number(value)?,
            "jitter" => config.jitter_ms = number(value)?,
            "loss" => config.loss = number(value)?,
            "seed" => {
                config.seed = value
                    .trim()
                    .parse()
                    .map_err(|e| bad(format!("`seed`: `{value}` ({e})")))?;
            }
            other => {
                return Err(bad(format!(
                    "unknown key `{other}` (known: delay, jitter, loss, seed)"
                )));
            }
        }
    }
    config.validate().map_err(bad)?;
    Ok(config)
}

/// The spec [`parse_direction`] reads back as `config`.
pub fn format_direction(config: &EmulationConfig) -> String {
    format!(
        "delay={},jitter={},loss={},seed={}",
        config.delay_ms, config.jitter_ms, config.loss, config.seed
    )
}

/// Transport protocol of a frame, as far as the bridge counts them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// IPv4 or IPv6 carrying TCP.
    Tcp,
    /// IPv4 or IPv6 carrying UDP.
    Udp,
    /// Anything else (ARP, ICMP, fragments, ...).
    Other,
}

/// Where the transport header of an IP frame is: (kind, transport offset, transport length, pseudo-header
/// sum). `None` for non-IP frames, fragments and truncated headers.
fn transport_of(frame: &[u8]) -> Option<(FrameKind, usize, usize, u32)> {
    let ethertype = u16::from_be_bytes([*frame.get(12)?, *frame.get(13)?]);
    let kind = |protocol: u8| match protocol {
        6 => FrameKind::Tcp,
        17 => FrameKind::Udp,
        _ => FrameKind::Other,
    };
    match ethertype {
        0x0800 => {
            let ip = frame.get(14..34)?;
            let header_len = usize::from(ip[0] & 0x0f) * 4;
            let total_len = usize::from(u16::from_be_bytes([ip[2], ip[3]]));
            let fragment = u16::from_be_bytes([ip[6], ip[7]]);
            if ip[0] >> 4 != 4 || header_len < 20 || total_len < header_len {
                return None;
            }
            if fragment & 0x3fff != 0 {
                return None; // a fragment: the checksum covers the reassembled datagram
            }
            let start = 14 + header_len;
            let len = total_len - header_len;
            frame.get(start..start + len)?;
            let mut sum = ones_complement_sum(&ip[12..20], 0);
            sum += u32::from(ip[9]) + len as u32;
            Some((kind(ip[9]), start, len, sum))
        }
        0x86dd => {
            let ip = frame.get(14..54)?;
            let len = usize::from(u16::from_be_bytes([ip[4], ip[5]]));
            frame.get(54..54 + len)?;
            let mut sum = ones_complement_sum(&ip[8..40], 0);
            sum += u32::from(ip[6]) + len as u32;
            Some((kind(ip[6]), 54, len, sum))
        }
        _ => None,
    }
}

/// Kind of an Ethernet frame's transport (for the bridge's counters). Never panics on short frames.
pub fn frame_kind(frame: &[u8]) -> FrameKind {
    transport_of(frame).map_or(FrameKind::Other, |(kind, ..)| kind)
}

fn ones_complement_sum(bytes: &[u8], mut sum: u32) -> u32 {
    let mut chunks = bytes.chunks_exact(2);
    for pair in &mut chunks {
        sum += u32::from(u16::from_be_bytes([pair[0], pair[1]]));
    }
    if let [last] = chunks.remainder() {
        sum += u32::from(*last) << 8;
    }
    sum
}

fn fold(mut sum: u32) -> u16 {
    while sum > 0xffff {
        sum = (sum & 0xffff) + (sum >> 16);
    }
    sum as u16
}

/// Recompute the TCP or UDP checksum of an unfragmented IPv4 or IPv6 frame in place; returns whether it
/// changed.
///
/// Why: a veth offloads transmit checksums, so a frame captured on the relay side carries only the partial
/// (pseudo-header) sum, and a frame injected through AF_PACKET is checked in full by the receiver. Frames
/// with a correct checksum are left bit-identical. An IPv4 UDP checksum of 0 (none) is left alone. Never
/// panics on malformed frames (they pass unchanged); no allocation.
pub fn fix_transport_checksum(frame: &mut [u8]) -> bool {
    let Some((kind, start, len, pseudo)) = transport_of(frame) else {
        return false;
    };
    let field = match kind {
        FrameKind::Tcp if len >= 20 => start + 16,
        FrameKind::Udp if len >= 8 => start + 6,
        _ => return false,
    };
    let ipv4 = frame[12] == 0x08;
    if kind == FrameKind::Udp && ipv4 && frame[field] == 0 && frame[field + 1] == 0 {
        return false;
    }
    let before = [frame[field], frame[field + 1]];
    frame[field] = 0;
    frame[field + 1] = 0;
    let mut checksum = !fold(ones_complement_sum(&frame[start..start + len], pseudo));
    if kind == FrameKind::Udp && checksum == 0 {
        checksum = 0xffff;
    }
    frame[field..field + 2].copy_from_slice(&checksum.to_be_bytes());
    before != checksum.to_be_bytes()
}

/// One bridge: interfaces and the emulation applied in each direction.
#[derive(Debug, Clone, PartialEq)]
pub struct BridgeConfig {
    /// First interface.
    pub interface_a: String,
    /// Second interface.
    pub interface_b: String,
    /// Applied to frames received on `interface_a` and sent out of `interface_b`.
    pub a_to_b: EmulationConfig,
    /// Applied to frames received on `interface_b` and sent out of `interface_a`.
    pub b_to_a: EmulationConfig,
    /// spin_sleep native accuracy of the send threads, ns (0: plain sleep).
    pub spin_ns: u32,
    /// Scripted loss on top of the emulation, per direction (`a->b`, `b->a`): frames dropped (and counted
    /// as lost) by their ordinal among the direction's TCP or UDP frames.
    pub drops: [Vec<ScriptedDrop>; 2],
}

/// Counters of one direction, read while the bridge runs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DirectionCounters {
    /// Frames read from the input interface.
    pub received: u64,
    /// Frames sent out of the output interface.
    pub forwarded: u64,
    /// Frames dropped by the emulated loss.
    pub lost: u64,
    /// Frames larger than [`MAX_FRAME_BYTES`], dropped.
    pub oversize: u64,
    /// Frames dropped because the in-flight queue was full.
    pub overflowed: u64,
    /// Sends the kernel refused.
    pub send_errors: u64,
    /// Forwarded frames carrying TCP.
    pub tcp_forwarded: u64,
    /// Forwarded frames carrying UDP.
    pub udp_forwarded: u64,
    /// Frames whose TCP/UDP checksum was incomplete (transmit offload) and has been completed.
    pub checksums_fixed: u64,
}

#[derive(Debug, Default)]
struct SharedCounters {
    received: AtomicU64,
    forwarded: AtomicU64,
    lost: AtomicU64,
    oversize: AtomicU64,
    overflowed: AtomicU64,
    send_errors: AtomicU64,
    tcp_forwarded: AtomicU64,
    udp_forwarded: AtomicU64,
    checksums_fixed: AtomicU64,
}

impl SharedCounters {
    fn snapshot(&self) -> DirectionCounters {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        DirectionCounters {
            received: get(&self.received),
            forwarded: get(&self.forwarded),
            lost: get(&self.lost),
            oversize: get(&self.oversize),
            overflowed: get(&self.overflowed),
            send_errors: get(&self.send_errors),
            tcp_forwarded: get(&self.tcp_forwarded),
            udp_forwarded: get(&self.udp_forwarded),
            checksums_fixed: get(&self.checksums_fixed),
        }
    }
}

fn bump(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

/// Final figures of one direction.
#[derive(Debug, Clone)]
pub struct DirectionReport {
    /// `a->b` or `b->a` with the interface names.
    pub name: String,
    /// The emulation applied.
    pub config: EmulationConfig,
    /// Counters at stop.
    pub counters: DirectionCounters,
    /// How late each forwarded frame left after its due time.
    pub lateness: LatencyHistogram,
}

impl fmt::Display for DirectionReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.counters;
        write!(
            f,
            "{name} [{spec}]: received {rx} forwarded {fwd} (tcp {tcp} udp {udp}) lost {lost} oversize {big} \
             overflowed {over} send_errors {err} checksums_fixed {fixed} lateness p50 {p50:.1} us p99 {p99:.1} us \
             max {max:.1} us",
            name = self.name,
            spec = format_direction(&self.config),
            rx = c.received,
            fwd = c.forwarded,
            tcp = c.tcp_forwarded,
            udp = c.udp_forwarded,
            lost = c.lost,
            big = c.oversize,
            over = c.overflowed,
            err = c.send_errors,
            fixed = c.checksums_fixed,
            p50 = self.lateness.percentile_ns(50.0) as f64 / 1000.0,
            p99 = self.lateness.percentile_ns(99.0) as f64 / 1000.0,
            max = self.lateness.max_ns() as f64 / 1000.0,
        )
    }
}

/// Final figures of a bridge, one line per direction.
#[derive(Debug, Clone)]
pub struct BridgeReport {
    /// `a->b` then `b->a`.
    pub directions: [DirectionReport; 2],
}

impl fmt::Display for BridgeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", self.directions[0])?;
        write!(f, "{}", self.directions[1])
    }
}

struct Queued {
    due: Instant,
    frame: Vec<u8>,
}

struct Direction {
    name: String,
    config: EmulationConfig,
    counters: Arc<SharedCounters>,
    receive: Option<JoinHandle<()>>,
    send: Option<JoinHandle<LatencyHistogram>>,
}

/// A running bridge: four named threads (receive and send per direction). Stop it with [`Bridge::stop`];
/// dropping it stops it too.
pub struct Bridge {
    stop: Arc<AtomicBool>,
    directions: Vec<Direction>,
}

impl fmt::Debug for Bridge {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bridge")
            .field("directions", &self.counters())
            .finish()
    }
}

/// The two halves of one interface's AF_PACKET socket.
type Channels = (Box<dyn DataLinkSender>, Box<dyn DataLinkReceiver>);

fn open(interface: &str) -> Result<Channels, NetemError> {
    let found: NetworkInterface = pnet_datalink::interfaces()
        .into_iter()
        .find(|i| i.name == interface)
        .ok_or_else(|| NetemError::NoInterface(interface.to_owned()))?;
    let config = Config {
        // Room for a GSO super-frame, so one is seen whole and counted as oversize, not truncated.
        read_buffer_size: 65_536,
        write_buffer_size: 65_536,
        read_timeout: Some(POLL),
        write_timeout: Some(Duration::from_millis(100)),
        promiscuous: true,
        ..Config::default()
    };
    match pnet_datalink::channel(&found, config) {
        Ok(Channel::Ethernet(tx, rx)) => Ok((tx, rx)),
        Ok(_) => Err(NetemError::NotEthernet(interface.to_owned())),
        Err(source) => Err(NetemError::Socket {
            interface: interface.to_owned(),
            source,
        }),
    }
}

/// One scripted loss: the `ordinal`-th (from 1) frame of `kind` in a direction. Written `tcp:N` or `udp:N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScriptedDrop {
    /// TCP or UDP.
    pub kind: FrameKind,
    /// Which frame of that kind, from 1.
    pub ordinal: u64,
}

impl std::str::FromStr for ScriptedDrop {
    type Err = NetemError;

    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        let bad = |reason: &str| NetemError::BadDrop {
            spec: spec.to_owned(),
            reason: reason.to_owned(),
        };
        let (kind, ordinal) = spec.trim().split_once(':').ok_or_else(|| bad("no `:`"))?;
        let kind = match kind {
            "tcp" => FrameKind::Tcp,
            "udp" => FrameKind::Udp,
            other => return Err(bad(&format!("unknown kind `{other}`"))),
        };
        let ordinal: u64 = ordinal
            .parse()
            .map_err(|_| bad("the ordinal is not a whole number"))?;
        if ordinal == 0 {
            return Err(bad("ordinals count from 1"));
        }
        Ok(Self { kind, ordinal })
    }
}

impl fmt::Display for ScriptedDrop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.kind {
            FrameKind::Tcp => "tcp",
            FrameKind::Udp => "udp",
            FrameKind::Other => "other",
        };
        write!(f, "{kind}:{}", self.ordinal)
    }
}

/// What one direction does to a frame: the seeded delay line, then the scripted drops.
struct Path {
    line: DelayLine,
    drops: Vec<ScriptedDrop>,
    tcp_seen: u64,
    udp_seen: u64,
}

impl Path {
    /// When `frame`, received at `now_ns`, is due out; `None`: lost.
    fn schedule(&mut self, frame: &[u8], now_ns: u64) -> Option<u64> {
        let kind = frame_kind(frame);
        let seen = match kind {
            FrameKind::Tcp => &mut self.tcp_seen,
            FrameKind::Udp => &mut self.udp_seen,
            FrameKind::Other => &mut 0,
        };
        *seen += 1;
        let ordinal = *seen;
        let scripted_drop = kind != FrameKind::Other
            && self
                .drops
                .iter()
                .any(|d| d.kind == kind && d.ordinal == ordinal);
        // The line draws for every frame, so a scripted drop leaves the seeded draws of the rest unchanged.
        self.line.schedule(now_ns).filter(|_| !scripted_drop)
    }
}

fn receive_loop(
    mut rx: Box<dyn DataLinkReceiver>,
    mut path: Path,
    origin: Instant,
    queue: SyncSender<Queued>,
    recycled: Receiver<Vec<u8>>,
    counters: Arc<SharedCounters>,
    stop: Arc<AtomicBool>,
) {
    while !stop.load(Ordering::Acquire) {
        let frame = match rx.next() {
            Ok(frame) => frame,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                tracing::warn!("receive error: {e}");
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        bump(&counters.received);
        if frame.len() > MAX_FRAME_BYTES {
            bump(&counters.oversize);
            continue;
        }
        let now = Instant::now();
        let now_ns = u64::try_from(now.duration_since(origin).as_nanos()).unwrap_or(u64::MAX);
        let Some(due_ns) = path.schedule(frame, now_ns) else {
            bump(&counters.lost);
            continue;
        };
        let mut buffer = recycled
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(MAX_FRAME_BYTES));
        buffer.clear();
        buffer.extend_from_slice(frame);
        if fix_transport_checksum(&mut buffer) {
            bump(&counters.checksums_fixed);
        }
        let queued = Queued {
            due: origin + Duration::from_nanos(due_ns),
            frame: buffer,
        };
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = queue.try_send(queued) {
            bump(&counters.overflowed);
        }
    }
}

fn send_loop(
    mut tx: Box<dyn DataLinkSender>,
    queue: Receiver<Queued>,
    recycle: SyncSender<Vec<u8>>,
    spin_ns: u32,
    counters: Arc<SharedCounters>,
    stop: Arc<AtomicBool>,
) -> LatencyHistogram {
    let sleeper = spin_sleep::SpinSleeper::new(spin_ns)
        .with_spin_strategy(spin_sleep::SpinStrategy::YieldThread);
    let mut lateness = LatencyHistogram::new();
    while !stop.load(Ordering::Acquire) {
        let queued = match queue.recv_timeout(POLL) {
            Ok(queued) => queued,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => break,
        };
        let now = Instant::now();
        if queued.due > now {
            sleeper.sleep(queued.due - now);
        }
        lateness.record(Instant::now().saturating_duration_since(queued.due));
        match tx.send_to(&queued.frame, None) {
            Some(Ok(())) => {
                bump(&counters.forwarded);
                match frame_kind(&queued.frame) {
                    FrameKind::Tcp => bump(&counters.tcp_forwarded),
                    FrameKind::Udp => bump(&counters.udp_forwarded),
                    FrameKind::Other => {}
                }
            }
            Some(Err(_)) | None => bump(&counters.send_errors),
        }
        let _ = recycle.try_send(queued.frame);
    }
    lateness
}

impl Bridge {
    /// Open both interfaces and start bridging.
    pub fn start(config: &BridgeConfig) -> Result<Self, NetemError> {
        let (tx_a, rx_a) = open(&config.interface_a)?;
        let (tx_b, rx_b) = open(&config.interface_b)?;
        let stop = Arc::new(AtomicBool::new(false));
        let origin = Instant::now();
        let mut bridge = Self {
            stop: stop.clone(),
            directions: Vec::with_capacity(2),
        };
        let plan = [
            (
                format!("{}->{}", config.interface_a, config.interface_b),
                "netem-ab",
                config.a_to_b,
                rx_a,
                tx_b,
            ),
            (
                format!("{}->{}", config.interface_b, config.interface_a),
                "netem-ba",
                config.b_to_a,
                rx_b,
                tx_a,
            ),
        ];
        for ((name, thread, emulation, rx, tx), drops) in plan.into_iter().zip(config.drops.clone())
        {
            let counters = Arc::new(SharedCounters::default());
            let (queue_tx, queue_rx) = sync_channel(QUEUE_CAPACITY);
            let (recycle_tx, recycle_rx) = sync_channel(QUEUE_CAPACITY);
            let spawn_error = |name: String| {
                move |source| NetemError::Thread {
                    name: name.clone(),
                    source,
                }
            };
            let (c, s) = (counters.clone(), stop.clone());
            let spin_ns = config.spin_ns;
            let send = std::thread::Builder::new()
                .name(format!("{thread}-send"))
                .spawn(move || send_loop(tx, queue_rx, recycle_tx, spin_ns, c, s))
                .map_err(spawn_error(format!("{thread}-send")))?;
            let (c, s) = (counters.clone(), stop.clone());
            let path = Path {
                line: DelayLine::new(emulation),
                drops,
                tcp_seen: 0,
                udp_seen: 0,
            };
            let receive = std::thread::Builder::new()
                .name(format!("{thread}-recv"))
                .spawn(move || receive_loop(rx, path, origin, queue_tx, recycle_rx, c, s))
                .map_err(spawn_error(format!("{thread}-recv")))?;
            bridge.directions.push(Direction {
                name,
                config: emulation,
                counters,
                receive: Some(receive),
                send: Some(send),
            });
        }
        Ok(bridge)
    }

    /// Counters of `a->b` and `b->a` so far.
    pub fn counters(&self) -> Vec<DirectionCounters> {
        self.directions
            .iter()
            .map(|d| d.counters.snapshot())
            .collect()
    }

    /// Stop the threads (frames still in flight are dropped, as on a link that goes down) and report.
    pub fn stop(mut self) -> BridgeReport {
        let mut reports = self.halt();
        let second = reports.pop();
        let first = reports.pop();
        let empty = |name: &str| DirectionReport {
            name: name.to_owned(),
            config: EmulationConfig::default(),
            counters: DirectionCounters::default(),
            lateness: LatencyHistogram::new(),
        };
        BridgeReport {
            directions: [
                first.unwrap_or_else(|| empty("a->b")),
                second.unwrap_or_else(|| empty("b->a")),
            ],
        }
    }

    fn halt(&mut self) -> Vec<DirectionReport> {
        self.stop.store(true, Ordering::Release);
        self.directions
            .iter_mut()
            .map(|d| {
                if let Some(receive) = d.receive.take() {
                    let _ = receive.join();
                }
                let lateness = d
                    .send
                    .take()
                    .and_then(|send| send.join().ok())
                    .unwrap_or_default();
                DirectionReport {
                    name: d.name.clone(),
                    config: d.config,
                    counters: d.counters.snapshot(),
                    lateness,
                }
            })
            .collect()
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        self.halt();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame: Ethernet + IPv4 (no options) + `transport`, protocol `protocol`.
    fn ipv4_frame(protocol: u8, transport: &[u8]) -> Vec<u8> {
        let mut frame = vec![0u8; 14];
        frame[12] = 0x08;
        let total = 20 + transport.len();
        let mut ip = [0u8; 20];
        ip[0] = 0x45;
        ip[2..4].copy_from_slice(&(total as u16).to_be_bytes());
        ip[6] = 0x40; // don't fragment
        ip[8] = 64;
        ip[9] = protocol;
        ip[12..16].copy_from_slice(&[10, 7, 0, 1]);
        ip[16..20].copy_from_slice(&[10, 7, 0, 2]);
        frame.extend_from_slice(&ip);
        frame.extend_from_slice(transport);
        frame.extend_from_slice(&[0xee; 6]); // Ethernet padding past the IP length
        frame
    }

    /// RFC 1071 check: the sum over pseudo-header and segment, checksum included, folds to 0xffff.
    fn verifies(frame: &[u8]) -> bool {
        let (_, start, len, pseudo) = transport_of(frame).unwrap();
        fold(ones_complement_sum(&frame[start..start + len], pseudo)) == 0xffff
    }

    fn udp_segment(payload: &[u8]) -> Vec<u8> {
        let mut udp = vec![0u8; 8];
        udp[0..2].copy_from_slice(&7447u16.to_be_bytes());
        udp[2..4].copy_from_slice(&40000u16.to_be_bytes());
        udp[4..6].copy_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
        udp[6..8].copy_from_slice(&[0x12, 0x34]); // a partial (pseudo-header) sum, as offload leaves it
        udp.extend_from_slice(payload);
        udp
    }

    #[test]
    fn a_partial_udp_checksum_is_completed_and_a_correct_one_kept() {
        for len in [0usize, 1, 59, 200] {
            let payload: Vec<u8> = (0..len).map(|i| (i * 37 % 251) as u8).collect();
            let mut frame = ipv4_frame(17, &udp_segment(&payload));
            assert!(!verifies(&frame));
            assert!(fix_transport_checksum(&mut frame));
            assert!(verifies(&frame), "payload {len}");
            let fixed = frame.clone();
            assert!(!fix_transport_checksum(&mut frame));
            assert_eq!(frame, fixed, "a correct checksum is left bit-identical");
            assert_eq!(&frame[frame.len() - 6..], &[0xee; 6], "padding untouched");
        }
    }

    #[test]
    fn tcp_checksum_over_ipv4_and_ipv6() {
        let mut tcp = vec![0u8; 20];
        tcp[12] = 0x50;
        tcp.extend_from_slice(b"hello, tissue");
        let mut frame = ipv4_frame(6, &tcp);
        assert!(fix_transport_checksum(&mut frame));
        assert!(verifies(&frame));
        assert_eq!(frame_kind(&frame), FrameKind::Tcp);

        let mut v6 = vec![0u8; 14];
        v6[12] = 0x86;
        v6[13] = 0xdd;
        let mut ip = [0u8; 40];
        ip[0] = 0x60;
        ip[4..6].copy_from_slice(&(tcp.len() as u16).to_be_bytes());
        ip[6] = 6;
        ip[8] = 0xfd;
        ip[39] = 2;
        v6.extend_from_slice(&ip);
        v6.extend_from_slice(&tcp);
        assert!(fix_transport_checksum(&mut v6));
        assert!(verifies(&v6));
    }

    #[test]
    fn fragments_arp_zero_udp_checksum_and_truncated_frames_pass_unchanged() {
        let mut fragment = ipv4_frame(17, &udp_segment(&[1, 2, 3]));
        fragment[14 + 6] = 0x20; // more fragments
        let before = fragment.clone();
        assert!(!fix_transport_checksum(&mut fragment));
        assert_eq!(fragment, before);
        assert_eq!(frame_kind(&fragment), FrameKind::Other);

        let mut no_checksum = ipv4_frame(17, &udp_segment(&[1, 2, 3]));
        no_checksum[14 + 20 + 6] = 0;
        no_checksum[14 + 20 + 7] = 0;
        assert!(!fix_transport_checksum(&mut no_checksum));

        let mut arp = vec![0xffu8; 42];
        arp[12] = 0x08;
        arp[13] = 0x06;
        assert!(!fix_transport_checksum(&mut arp));
        assert_eq!(frame_kind(&arp), FrameKind::Other);

        let whole = ipv4_frame(6, &[0u8; 20]);
        for cut in 0..whole.len() - 6 {
            let mut truncated = whole[..cut].to_vec();
            let before = truncated.clone();
            assert!(!fix_transport_checksum(&mut truncated), "cut at {cut}");
            assert_eq!(truncated, before);
        }
    }

    #[test]
    fn scripted_drops_parse_print_and_hit_only_their_frame() {
        let drop: ScriptedDrop = "udp:2".parse().unwrap();
        assert_eq!(
            drop,
            ScriptedDrop {
                kind: FrameKind::Udp,
                ordinal: 2
            }
        );
        assert_eq!(drop.to_string(), "udp:2");
        for bad in ["udp", "icmp:1", "tcp:0", "tcp:x"] {
            let message = bad.parse::<ScriptedDrop>().unwrap_err().to_string();
            assert!(message.contains(bad), "{message}");
        }
        let mut path = Path {
            line: DelayLine::new(EmulationConfig::default()),
            drops: vec![drop],
            tcp_seen: 0,
            udp_seen: 0,
        };
        let udp = ipv4_frame(17, &udp_segment(&[1, 2, 3]));
        let tcp = ipv4_frame(6, &[0u8; 20]);
        let kept: Vec<bool> = [&udp, &tcp, &udp, &udp]
            .iter()
            .map(|frame| path.schedule(frame, 0).is_some())
            .collect();
        assert_eq!(kept, [true, true, false, true]);
    }

    #[test]
    fn direction_specs_round_trip_and_bad_ones_are_named() {
        let config = parse_direction("delay=50, jitter=20,loss=0.05,seed=7").unwrap();
        assert_eq!(
            config,
            EmulationConfig {
                delay_ms: 50.0,
                jitter_ms: 20.0,
                loss: 0.05,
                seed: 7
            }
        );
        assert_eq!(parse_direction(&format_direction(&config)).unwrap(), config);
        assert_eq!(parse_direction("").unwrap(), EmulationConfig::default());
        for (bad, needle) in [
            ("delay=fast", "delay"),
            ("loss=2", "--emulate-loss"),
            ("latency=3", "unknown key `latency`"),
            ("delay", "not key=value"),
            ("seed=-1", "seed"),
        ] {
            let message = parse_direction(bad).unwrap_err().to_string();
            assert!(message.contains(needle), "{bad}: {message}");
        }
    }
}
