//! zenoh TCP vs UDP links for 1 kHz pose/force streams on a real path with delay, jitter and loss.
//!
//! Each cell builds a [`NetnsLab`] (RTT 100 ms: 50 ms each way, the given jitter and loss both ways) and runs
//! this binary twice inside it: `--side echo` in the server namespace (listens; echoes each 60-byte pose as a
//! 200-byte "force") and `--side ping` in the device namespace (connects; publishes poses at 1 kHz with
//! `Pacer` and measures the echoes). Transports: `tcp` (one TCP link), `udp` (one UDP link) and `both` (one
//! transport holding a TCP and a UDP link, `transport/unicast/max_links` 2). Every pose and force publisher
//! is best effort, congestion drop, express, as the real roles' are; with `both`, zenoh routes best-effort
//! messages over the UDP link and reliable ones (declarations) over TCP, which the relay's per-protocol
//! frame counters confirm (column "UDP frames"); the pinging side also polls `SessionInfo::links` to see
//! when each link joined the transport.
//!
//! A gap is the time between consecutive echoes at the pinging side; over 50 ms is the hapticserver's
//! silence rule (no force command for 50 ms ramps the force to zero). The bench also counts how often the
//! echo starts at all on a lossy UDP-only transport, where declarations travel unreliably.
//!
//! Run (root; the `sinew-netem` binary is built with the bench):
//! `cargo bench -p sinew-testkit --bench netns_transport -- --seconds 20 --trials 8`
//! (`--only tcp|udp|both` restricts the transports; `--skip-trials`, `--skip-table`; `--no-realtime` and
//! `--relay-spin-ns N` change how the relay waits; `--open-timeout-ms N` sets zenoh's link handshake timeout;
//! `--tcp-cc cubic` the lab's TCP congestion control (default: the host's, `bbr` here); `--verbose` prints the
//! relay's counters per cell).

#![allow(clippy::unwrap_used, clippy::expect_used)] // bench code: a failed setup should panic loudly

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::{LatencyHistogram, Pacer};
use sinew_testkit::netem::DEFAULT_SPIN_NS;
use sinew_testkit::netns::{LabConfig, NetnsLab, wait_output};
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Reliability};

const POSE_BYTES: usize = 60;
const FORCE_BYTES: usize = 200;
const PORT: u16 = 7447;
const SILENCE_MS: f64 = 50.0;
const POSE_KEY: &str = "sinew/netns/pose";
const FORCE_KEY: &str = "sinew/netns/force";

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Transport {
    Tcp,
    Udp,
    Both,
}

impl Transport {
    const ALL: [Transport; 3] = [Transport::Tcp, Transport::Udp, Transport::Both];

    fn name(self) -> &'static str {
        match self {
            Transport::Tcp => "tcp",
            Transport::Udp => "udp",
            Transport::Both => "both",
        }
    }

    fn parse(name: &str) -> Transport {
        Transport::ALL
            .into_iter()
            .find(|t| t.name() == name)
            .unwrap_or_else(|| panic!("unknown transport `{name}` (tcp, udp, both)"))
    }

    fn label(self) -> &'static str {
        match self {
            Transport::Tcp => "TCP only",
            Transport::Udp => "UDP only",
            Transport::Both => "TCP + UDP (multilink)",
        }
    }

    fn endpoints(self, ip: &str) -> Vec<String> {
        let tcp = format!("tcp/{ip}:{PORT}");
        let udp = format!("udp/{ip}:{PORT}");
        match self {
            Transport::Tcp => vec![tcp],
            Transport::Udp => vec![udp],
            Transport::Both => vec![tcp, udp],
        }
    }

    /// A zenoh config file for this transport: peer, no scouting, no default listeners, two links per
    /// transport for `both`, and the link handshake timeout (`None`: zenoh's default, 10 s).
    fn config_file(self, open_timeout_ms: Option<u64>) -> PathBuf {
        let path = std::env::temp_dir().join(format!(
            "sinew-netns-{}-{}.json5",
            std::process::id(),
            self.name()
        ));
        let max_links = if self == Transport::Both { 2 } else { 1 };
        let timeouts = open_timeout_ms.map_or(String::new(), |ms| {
            format!("open_timeout: {ms}, accept_timeout: {ms},")
        });
        std::fs::write(
            &path,
            format!(
                "{{ mode: \"peer\", listen: {{ endpoints: [] }}, connect: {{ endpoints: [] }}, \
                 scouting: {{ multicast: {{ enabled: false }}, gossip: {{ enabled: false }} }}, \
                 transport: {{ unicast: {{ {timeouts} max_links: {max_links} }} }} }}"
            ),
        )
        .unwrap();
        path
    }
}

/// `--key value` arguments of a side process.
fn arg<'a>(args: &'a [String], key: &str) -> Option<&'a str> {
    args.iter()
        .position(|a| a == key)
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
}

fn num(args: &[String], key: &str, default: f64) -> f64 {
    arg(args, key).map_or(default, |v| v.parse().unwrap())
}

fn open(args: &[String], listen: bool) -> zenoh::Session {
    let transport = Transport::parse(arg(args, "--transport").unwrap());
    let endpoints = transport.endpoints(arg(args, "--ip").unwrap());
    let config_file = PathBuf::from(arg(args, "--zenoh-config").unwrap());
    let options = NetworkOptions {
        config_file: Some(config_file),
        listen: if listen { endpoints.clone() } else { vec![] },
        connect: if listen { vec![] } else { endpoints },
        ..NetworkOptions::default()
    };
    sinew_server::node::open_session(&options).unwrap()
}

/// `--side echo`: echo every pose as a force until `--seconds` run out (or SIGTERM).
fn echo_side(args: &[String]) {
    let session = open(args, true);
    let force = session
        .declare_publisher(FORCE_KEY)
        .congestion_control(CongestionControl::Drop)
        .express(true)
        .reliability(Reliability::BestEffort)
        .wait()
        .unwrap();
    let echoed = Arc::new(AtomicU64::new(0));
    let counter = echoed.clone();
    let _subscriber = session
        .declare_subscriber(POSE_KEY)
        .callback(move |sample| {
            let pose = sample.payload().to_bytes();
            let mut bytes = [0u8; FORCE_BYTES];
            let n = pose.len().min(16);
            bytes[..n].copy_from_slice(&pose[..n]);
            let _ = force.put(&bytes[..]).wait();
            counter.fetch_add(1, Ordering::Relaxed);
        })
        .wait()
        .unwrap();
    std::thread::sleep(Duration::from_secs_f64(num(args, "--seconds", 60.0)));
    println!("echoed {}", echoed.load(Ordering::Relaxed));
}

/// What the pinging side measured.
#[derive(Debug, Clone, Default)]
struct PingResult {
    started: bool,
    first_echo_ms: f64,
    sent: u64,
    received: u64,
    rtt_p50_ms: f64,
    rtt_p99_ms: f64,
    rtt_max_ms: f64,
    gaps: u64,
    longest_gap_ms: f64,
    window_s: f64,
    /// When zenoh first listed a TCP / UDP link in the transport, ms since the side started (NaN: never).
    tcp_link_ms: f64,
    udp_link_ms: f64,
    /// Times a link that had been listed disappeared.
    links_lost: u64,
}

impl PingResult {
    fn to_line(&self) -> String {
        format!(
            "result started={} first_echo_ms={:.1} sent={} received={} rtt_p50_ms={:.2} rtt_p99_ms={:.2} \
             rtt_max_ms={:.2} gaps={} longest_gap_ms={:.1} window_s={:.2} tcp_link_ms={:.0} udp_link_ms={:.0} \
             links_lost={}",
            u8::from(self.started),
            self.first_echo_ms,
            self.sent,
            self.received,
            self.rtt_p50_ms,
            self.rtt_p99_ms,
            self.rtt_max_ms,
            self.gaps,
            self.longest_gap_ms,
            self.window_s,
            self.tcp_link_ms,
            self.udp_link_ms,
            self.links_lost
        )
    }

    fn from_output(output: &str) -> Option<PingResult> {
        let line = output.lines().find(|l| l.starts_with("result "))?;
        let field = |key: &str| -> f64 {
            line.split_whitespace()
                .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN)
        };
        Some(PingResult {
            started: field("started") == 1.0,
            first_echo_ms: field("first_echo_ms"),
            sent: field("sent") as u64,
            received: field("received") as u64,
            rtt_p50_ms: field("rtt_p50_ms"),
            rtt_p99_ms: field("rtt_p99_ms"),
            rtt_max_ms: field("rtt_max_ms"),
            gaps: field("gaps") as u64,
            longest_gap_ms: field("longest_gap_ms"),
            window_s: field("window_s"),
            tcp_link_ms: field("tcp_link_ms"),
            udp_link_ms: field("udp_link_ms"),
            links_lost: field("links_lost") as u64,
        })
    }
}

/// One echo as seen by the pinging side: pose sequence number and arrival time (ns since the side started).
#[derive(Debug, Clone, Copy)]
struct Arrival {
    seq: u64,
    sent_ns: u64,
    at_ns: u64,
}

/// Watches which links zenoh lists in its transports (polled every 20 ms on a thread): when each protocol
/// first appeared, and how often a listed link went away.
#[derive(Debug, Default)]
struct LinkWatch {
    tcp_ms: Option<f64>,
    udp_ms: Option<f64>,
    lost: u64,
}

fn watch_links(
    session: zenoh::Session,
    start: Instant,
    done: Arc<AtomicU64>,
) -> std::thread::JoinHandle<LinkWatch> {
    std::thread::spawn(move || {
        let mut watch = LinkWatch::default();
        let mut previous = (false, false);
        while done.load(Ordering::Relaxed) == 0 {
            let (mut tcp, mut udp) = (false, false);
            for link in session.info().links().wait() {
                let dst = link.dst().as_str().to_owned();
                tcp |= dst.starts_with("tcp/");
                udp |= dst.starts_with("udp/");
            }
            let ms = start.elapsed().as_secs_f64() * 1000.0;
            if tcp && watch.tcp_ms.is_none() {
                watch.tcp_ms = Some(ms);
            }
            if udp && watch.udp_ms.is_none() {
                watch.udp_ms = Some(ms);
            }
            watch.lost += u64::from(previous.0 && !tcp) + u64::from(previous.1 && !udp);
            previous = (tcp, udp);
            std::thread::sleep(Duration::from_millis(20));
        }
        watch
    })
}

/// `--side ping`: publish poses at 1 kHz, wait for the first echo (`--start-timeout-s`), then measure for
/// `--seconds` and print one `result ...` line.
fn ping_side(args: &[String]) {
    let start = Instant::now();
    let now_ns = move || start.elapsed().as_nanos() as u64;
    let seconds = num(args, "--seconds", 20.0);
    let start_timeout = Duration::from_secs_f64(num(args, "--start-timeout-s", 15.0));
    let session = open(args, false);
    let watching = Arc::new(AtomicU64::new(0));
    let watcher = watch_links(session.clone(), start, watching.clone());
    let arrivals = Arc::new(Mutex::new(Vec::<Arrival>::with_capacity(
        (seconds * 1000.0) as usize + 20_000,
    )));
    let sink = arrivals.clone();
    let _subscriber = session
        .declare_subscriber(FORCE_KEY)
        .callback(move |sample| {
            let bytes = sample.payload().to_bytes();
            if bytes.len() < 16 {
                return;
            }
            let seq = u64::from_le_bytes(bytes[..8].try_into().unwrap());
            let sent_ns = u64::from_le_bytes(bytes[8..16].try_into().unwrap());
            sink.lock().unwrap().push(Arrival {
                seq,
                sent_ns,
                at_ns: now_ns(),
            });
        })
        .wait()
        .unwrap();
    let pose = session
        .declare_publisher(POSE_KEY)
        .congestion_control(CongestionControl::Drop)
        .express(true)
        .reliability(Reliability::BestEffort)
        .wait()
        .unwrap();
    let mut pacer = Pacer::new(Duration::from_millis(1), 100_000);
    let mut seq = 0u64;
    let mut payload = [0u8; POSE_BYTES];
    let mut publish = |seq: &mut u64| {
        pacer.wait();
        payload[..8].copy_from_slice(&seq.to_le_bytes());
        payload[8..16].copy_from_slice(&now_ns().to_le_bytes());
        let _ = pose.put(&payload[..]).wait();
        *seq += 1;
    };
    let mut result = PingResult::default();
    let finish = |result: &mut PingResult| {
        watching.store(1, Ordering::Relaxed);
        let watch = watcher.join().unwrap();
        result.tcp_link_ms = watch.tcp_ms.unwrap_or(f64::NAN);
        result.udp_link_ms = watch.udp_ms.unwrap_or(f64::NAN);
        result.links_lost = watch.lost;
        println!("{}", result.to_line());
    };
    while arrivals.lock().unwrap().is_empty() && start.elapsed() < start_timeout {
        publish(&mut seq);
    }
    let Some(first) = arrivals.lock().unwrap().first().copied() else {
        finish(&mut result);
        return;
    };
    result.started = true;
    result.first_echo_ms = first.at_ns as f64 / 1e6;
    // Let the stream settle (a TCP link's first second ramps its window), then measure.
    let settle_until = start.elapsed() + Duration::from_secs(1);
    while start.elapsed() < settle_until {
        publish(&mut seq);
    }
    let window_start_ns = now_ns();
    let first_seq = seq;
    let window = Duration::from_secs_f64(seconds);
    let window_start = Instant::now();
    while window_start.elapsed() < window {
        publish(&mut seq);
    }
    let window_end_ns = now_ns();
    let last_seq = seq;
    // Late echoes of the window's poses (RTT, jitter, retransmissions).
    std::thread::sleep(Duration::from_millis(1500));
    let arrivals = arrivals.lock().unwrap().clone();

    let mut rtt = LatencyHistogram::new();
    let mut seen = vec![false; (last_seq - first_seq) as usize];
    for a in arrivals
        .iter()
        .filter(|a| (first_seq..last_seq).contains(&a.seq))
    {
        let index = (a.seq - first_seq) as usize;
        if !seen[index] {
            seen[index] = true;
            rtt.record_ns(a.at_ns.saturating_sub(a.sent_ns));
        }
    }
    // Gaps between consecutive echoes (any pose) over the window, counting the silence up to its end.
    let mut previous = arrivals
        .iter()
        .rev()
        .find(|a| a.at_ns < window_start_ns)
        .map_or(window_start_ns, |a| a.at_ns);
    let mut gaps = Vec::new();
    for a in arrivals
        .iter()
        .filter(|a| (window_start_ns..window_end_ns).contains(&a.at_ns))
    {
        gaps.push(a.at_ns - previous);
        previous = a.at_ns;
    }
    gaps.push(window_end_ns - previous);
    let ms = |ns: u64| ns as f64 / 1e6;
    result.sent = last_seq - first_seq;
    result.received = seen.iter().filter(|s| **s).count() as u64;
    result.rtt_p50_ms = ms(rtt.percentile_ns(50.0));
    result.rtt_p99_ms = ms(rtt.percentile_ns(99.0));
    result.rtt_max_ms = ms(rtt.max_ns());
    result.gaps = gaps.iter().filter(|g| ms(**g) > SILENCE_MS).count() as u64;
    result.longest_gap_ms = gaps.iter().copied().map(ms).fold(0.0, f64::max);
    result.window_s = ms(window_end_ns - window_start_ns) / 1000.0;
    finish(&mut result);
}

/// Frames the relay forwarded: (tcp, udp) summed over both directions, from its report.
fn relay_frames(report: &str) -> (u64, u64) {
    let after = |line: &str, key: &str| -> u64 {
        line.split(key)
            .nth(1)
            .and_then(|rest| {
                rest.trim_start()
                    .split(|c: char| !c.is_ascii_digit())
                    .next()
            })
            .and_then(|n| n.parse().ok())
            .unwrap_or(0)
    };
    report
        .lines()
        .filter(|l| l.contains("forwarded"))
        .fold((0, 0), |(tcp, udp), l| {
            (tcp + after(l, "(tcp "), udp + after(l, " udp "))
        })
}

/// The relay's send lateness over both directions: (worst p99, max), us.
fn relay_lateness(report: &str) -> (f64, f64) {
    let after = |line: &str, key: &str| -> f64 {
        line.split("lateness")
            .nth(1)
            .and_then(|rest| rest.split(key).nth(1))
            .and_then(|rest| rest.split_whitespace().next())
            .and_then(|n| n.parse().ok())
            .unwrap_or(f64::NAN)
    };
    report
        .lines()
        .filter(|l| l.contains("lateness"))
        .fold((0.0, 0.0), |(p99, max): (f64, f64), l| {
            (p99.max(after(l, " p99 ")), max.max(after(l, " max ")))
        })
}

/// Relay and zenoh options shared by every cell.
#[derive(Debug, Clone, Copy)]
struct RelayOptions {
    realtime: bool,
    spin_ns: u32,
    /// zenoh `transport/unicast/open_timeout` and `accept_timeout`, ms (None: default).
    open_timeout_ms: Option<u64>,
    /// TCP congestion control in the lab (None: the host's).
    tcp_congestion_control: Option<&'static str>,
}

/// One run of both sides in a fresh lab: the ping result (None if the side failed) and the relay's report.
fn run_cell(
    exe: &Path,
    transport: Transport,
    mut config: LabConfig,
    relay: RelayOptions,
    seconds: f64,
    start_timeout_s: f64,
) -> (Option<PingResult>, String) {
    config.relay_realtime = relay.realtime;
    config.relay_spin_ns = relay.spin_ns;
    config.tcp_congestion_control = relay.tcp_congestion_control;
    let mut lab = NetnsLab::new(config).unwrap();
    let zenoh_config = transport.config_file(relay.open_timeout_ms);
    let ip = lab.server_ip().to_string();
    let side = |name: &str, run_s: f64| {
        let mut command = Command::new(exe);
        command
            .args(["--side", name, "--transport", transport.name(), "--ip", &ip])
            .arg("--zenoh-config")
            .arg(&zenoh_config)
            .args(["--seconds", &run_s.to_string()])
            .args(["--start-timeout-s", &start_timeout_s.to_string()])
            .env("RUST_LOG", "error");
        command
    };
    let echo = lab
        .spawn_in_server_ns(&side("echo", start_timeout_s + seconds + 10.0))
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let ping = lab.spawn_in_device_ns(&side("ping", seconds)).unwrap();
    let output = wait_output(
        ping,
        Duration::from_secs_f64(start_timeout_s + seconds + 30.0),
    );
    let report = lab.stop_relay().unwrap_or_default();
    drop(echo);
    drop(lab);
    let _ = std::fs::remove_file(zenoh_config);
    let result = match output {
        Ok(output) => PingResult::from_output(&String::from_utf8_lossy(&output.stdout)),
        Err(e) => {
            eprintln!("ping side failed: {e}");
            None
        }
    };
    (result, report)
}

fn seconds_or_never(ms: f64) -> String {
    if ms.is_finite() {
        format!("{:.1} s", ms / 1000.0)
    } else {
        "never".into()
    }
}

fn driver(args: &[String]) {
    if let Err(reason) = NetnsLab::available() {
        println!("SKIP netns_transport: {reason}");
        return;
    }
    let exe = std::env::current_exe().unwrap();
    let seconds = num(args, "--seconds", 20.0);
    let trials = num(args, "--trials", 8.0) as u64;
    // Long enough to see a UDP link join after one failed handshake (zenoh's open timeout is 10 s).
    let trial_seconds = num(args, "--trial-seconds", 12.0);
    let relay = RelayOptions {
        realtime: !args.iter().any(|a| a == "--no-realtime"),
        spin_ns: num(args, "--relay-spin-ns", f64::from(DEFAULT_SPIN_NS)) as u32,
        open_timeout_ms: arg(args, "--open-timeout-ms").map(|v| v.parse().unwrap()),
        // Leaked once: the lab config wants a `&'static str`.
        tcp_congestion_control: arg(args, "--tcp-cc").map(|cc| &*cc.to_owned().leak()),
    };
    let tcp_cc = relay.tcp_congestion_control.map_or_else(
        || {
            std::fs::read_to_string("/proc/sys/net/ipv4/tcp_congestion_control")
                .map_or("?".into(), |cc| format!("{} (host default)", cc.trim()))
        },
        str::to_owned,
    );
    let transports: Vec<Transport> = match arg(args, "--only") {
        Some(name) => vec![Transport::parse(name)],
        None => Transport::ALL.to_vec(),
    };
    let mut cells = Vec::new();
    for &transport in &transports {
        for (loss, jitter_ms) in [(0.0, 0.0), (0.01, 0.0), (0.05, 0.0), (0.01, 20.0)] {
            cells.push((transport, loss, jitter_ms));
        }
    }
    if !args.iter().any(|a| a == "--skip-table") {
        println!(
            "RTT 100 ms (50 ms each way), loss and jitter both ways, {seconds} s per cell after the first echo \
             + 1 s, 60-byte poses at 1 kHz echoed as 200-byte forces; TCP congestion control {tcp_cc}; {relay:?}"
        );
        println!();
        println!(
            "| transport | loss | jitter | RTT p50 | RTT p99 | RTT max | gaps > 50 ms per min | longest gap | \
             delivered | first echo | TCP link | UDP link | UDP frames | relay late p99 / max |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for (i, &(transport, loss, jitter_ms)) in cells.iter().enumerate() {
            let config = LabConfig::symmetric(50.0, jitter_ms, loss, 100 + 2 * i as u64);
            let (result, report) = run_cell(&exe, transport, config, relay, seconds, 15.0);
            let (tcp, udp) = relay_frames(&report);
            let udp_share = 100.0 * udp as f64 / (tcp + udp).max(1) as f64;
            let (late_p99, late_max) = relay_lateness(&report);
            let head = format!(
                "| {} | {:.0}% | +-{:.0} ms |",
                transport.label(),
                loss * 100.0,
                jitter_ms
            );
            let tail = format!("{udp_share:.1}% | {late_p99:.0} / {late_max:.0} us |");
            match result {
                Some(r) if r.started => println!(
                    "{head} {:.1} ms | {:.1} ms | {:.1} ms | {:.1} | {:.0} ms | {:.2}% | {:.1} s | {} | {} | {tail}",
                    r.rtt_p50_ms,
                    r.rtt_p99_ms,
                    r.rtt_max_ms,
                    r.gaps as f64 / (r.window_s / 60.0),
                    r.longest_gap_ms,
                    100.0 * r.received as f64 / r.sent.max(1) as f64,
                    r.first_echo_ms / 1000.0,
                    seconds_or_never(r.tcp_link_ms),
                    seconds_or_never(r.udp_link_ms),
                ),
                Some(r) => println!(
                    "{head} no echo in 15 s | | | | | 0% | never | {} | {} | {tail}",
                    seconds_or_never(r.tcp_link_ms),
                    seconds_or_never(r.udp_link_ms),
                ),
                None => println!("{head} ping side failed | | | | | | | | | {tail}"),
            }
            if args.iter().any(|a| a == "--verbose") {
                eprintln!("{report}");
            }
        }
    }
    if !args.iter().any(|a| a == "--skip-trials") {
        println!();
        println!(
            "Does the echo start at 5% loss (RTT 100 ms), and when does the UDP link join? {trials} trials per \
             transport, a fresh lab each, 15 s to the first echo, then {trial_seconds} s more:"
        );
        println!();
        println!(
            "| transport | echo started | first echo after (each trial) | UDP link after (each trial) |"
        );
        println!("|---|---|---|---|");
        for &transport in transports.iter().filter(|t| **t != Transport::Tcp) {
            let mut started = 0;
            let mut firsts = Vec::new();
            let mut udp_links = Vec::new();
            for trial in 0..trials {
                let config = LabConfig::symmetric(50.0, 0.0, 0.05, 1000 + 2 * trial);
                let (result, _) = run_cell(&exe, transport, config, relay, trial_seconds, 15.0);
                match result {
                    Some(r) => {
                        started += u64::from(r.started);
                        firsts.push(if r.started {
                            seconds_or_never(r.first_echo_ms)
                        } else {
                            "never".into()
                        });
                        udp_links.push(seconds_or_never(r.udp_link_ms));
                    }
                    None => firsts.push("failed".into()),
                }
            }
            println!(
                "| {} | {started}/{trials} | {} | {} |",
                transport.label(),
                firsts.join(", "),
                udp_links.join(", ")
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match arg(&args, "--side") {
        Some("echo") => echo_side(&args),
        Some("ping") => ping_side(&args),
        Some(other) => panic!("unknown side `{other}` (echo, ping)"),
        None => driver(&args),
    }
}
