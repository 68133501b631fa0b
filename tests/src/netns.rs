//! A network-namespace lab: a server side and a device side joined by a real path with delay, jitter and
//! loss, so cross-process tests and benches can run roles on two "machines".
//!
//! Owns: [`NetnsLab`] (three namespaces per lab: server side `10.X.0.1/24`, device side `10.X.0.2/24`, and a
//! relay namespace holding the peers of both veth pairs, where `sinew-netem` ([`crate::netem`]) bridges them;
//! with [`LabConfig::second_site`], a fourth: a second device site `10.X.1.2/24` reaching the server side's
//! second address `10.X.1.1/24` over a path of its own, bridged by a second relay in the same namespace),
//! starting commands inside the server or device namespace, and tearing everything down on drop, panics
//! included. Also [`role_binary`] (where `cargo test --workspace --release` put a workspace binary) and
//! [`wait_output`] (wait for a child with a timeout).
//!
//! Names start with [`NAMESPACE_PREFIX`] and carry the creating process id, so labs of concurrent test
//! processes never collide and [`NetnsLab::new`] can remove those left by crashed runs (their process is gone).
//!
//! Must not: touch the root namespace's interfaces or routes, or kill any process outside the lab's
//! namespaces. Needs root and iproute2 ([`NetnsLab::available`]).

use std::ffi::OsStr;
use std::net::Ipv4Addr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use sinew_protocol::rt::EmulationConfig;

use crate::netem::{ScriptedDrop, format_direction};

/// Every lab namespace's name starts with this, then `<pid>-<n>-{srv,dev,rly}`.
pub const NAMESPACE_PREFIX: &str = "sinewlab-";

/// The lab side's interface name in the server and device namespaces.
pub const LAB_INTERFACE: &str = "eth0";

/// The relay's interfaces: towards the server side and towards the device side.
pub const RELAY_INTERFACES: [&str; 2] = ["tosrv", "todev"];

/// The second site's path ([`LabConfig::second_site`]): the server side's second interface, and the second
/// relay's interfaces towards the server side and towards the second site.
pub const SECOND_SITE_SERVER_INTERFACE: &str = "eth1";
/// See [`SECOND_SITE_SERVER_INTERFACE`].
pub const SECOND_RELAY_INTERFACES: [&str; 2] = ["tosrv2", "todev2"];

/// SCHED_FIFO priority of the relay when [`LabConfig::relay_realtime`] (above the roles, which run SCHED_OTHER).
const RELAY_PRIORITY: &str = "50";

/// How long [`NetnsLab::new`] waits for the relay to report that it is bridging.
const RELAY_START_TIMEOUT: Duration = Duration::from_secs(5);

/// The path between the two sides: one emulation per direction (RTT = the sum of the two delays).
#[derive(Debug, Clone, PartialEq)]
pub struct LabConfig {
    /// Frames from the server side to the device side.
    pub server_to_device: EmulationConfig,
    /// Frames from the device side to the server side.
    pub device_to_server: EmulationConfig,
    /// Run the relay with real-time priority (`chrt -f`, when `chrt` is present), so frames leave on time
    /// while the roles keep both cores busy.
    pub relay_realtime: bool,
    /// spin_sleep native accuracy of the relay's send threads, ns (`sinew-netem --spin-ns`).
    pub relay_spin_ns: u32,
    /// TCP congestion control in the server and device namespaces (`net.ipv4.tcp_congestion_control`, e.g.
    /// `cubic`); `None` keeps what new namespaces inherit from the host (`bbr` on these machines). The kernel
    /// lets a namespace pick only algorithms in the host's `net.ipv4.tcp_allowed_congestion_control` (`reno bbr`
    /// here; the lab does not widen it).
    pub tcp_congestion_control: Option<&'static str>,
    /// Scripted loss on top of `server_to_device`: frames dropped by their ordinal among the TCP or UDP
    /// frames of that direction (a handshake's reply, say).
    pub drops_to_device: Vec<ScriptedDrop>,
    /// Scripted loss on top of `device_to_server`.
    pub drops_to_server: Vec<ScriptedDrop>,
    /// A second device site with its own path to the server side (two surgeons at two sites): `None` for the
    /// usual two sides.
    pub second_site: Option<SitePath>,
}

/// A second site's path to the server side: one emulation per direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SitePath {
    /// Frames from the server side to the second site.
    pub server_to_site: EmulationConfig,
    /// Frames from the second site to the server side.
    pub site_to_server: EmulationConfig,
}

impl LabConfig {
    /// The same delay, jitter and loss both ways (seeds `seed` and `seed + 1`).
    pub fn symmetric(delay_ms: f64, jitter_ms: f64, loss: f64, seed: u64) -> Self {
        let one_way = EmulationConfig {
            delay_ms,
            jitter_ms,
            loss,
            seed,
        };
        Self {
            server_to_device: one_way,
            device_to_server: EmulationConfig {
                seed: seed.wrapping_add(1),
                ..one_way
            },
            relay_realtime: true,
            relay_spin_ns: crate::netem::DEFAULT_SPIN_NS,
            tcp_congestion_control: None,
            drops_to_device: Vec::new(),
            drops_to_server: Vec::new(),
            second_site: None,
        }
    }

    /// The same lab with a second device site whose path is like the first's (seeds shifted by 2).
    pub fn with_second_site(mut self) -> Self {
        let shifted = |config: EmulationConfig| EmulationConfig {
            seed: config.seed.wrapping_add(2),
            ..config
        };
        self.second_site = Some(SitePath {
            server_to_site: shifted(self.server_to_device),
            site_to_server: shifted(self.device_to_server),
        });
        self
    }
}

/// One relay's bridge: its two interfaces in the relay namespace (`a` towards the server side) and what
/// each direction does to frames.
struct RelaySpec {
    interfaces: [&'static str; 2],
    a_to_b: EmulationConfig,
    b_to_a: EmulationConfig,
    drops_a_to_b: Vec<ScriptedDrop>,
    drops_b_to_a: Vec<ScriptedDrop>,
}

/// The relay's option for `drops` (nothing when there are none).
fn scripted_drops(option: &str, drops: &[ScriptedDrop]) -> Vec<String> {
    if drops.is_empty() {
        return Vec::new();
    }
    let list: Vec<String> = drops.iter().map(ScriptedDrop::to_string).collect();
    vec![option.to_owned(), list.join(",")]
}

/// What can go wrong building or using a lab.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    /// Not root, or no `ip`.
    #[error("network namespace lab unavailable: {0}")]
    Unavailable(String),
    /// A setup command failed.
    #[error("`{command}` failed ({status}): {stderr}")]
    Command {
        /// The command line.
        command: String,
        /// Exit status.
        status: String,
        /// Its standard error.
        stderr: String,
    },
    /// A process could not be started or waited for.
    #[error("{what}: {source}")]
    Io {
        /// What was being done.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The relay exited or never reported that it was bridging.
    #[error("the relay `sinew-netem` did not start: {0}")]
    Relay(String),
    /// A workspace binary is not built.
    #[error(
        "{name} not found at {path} (build it: `cargo test --workspace --release --no-run` or `cargo build --release --workspace`)"
    )]
    MissingBinary {
        /// Binary name.
        name: String,
        /// Where it was looked for.
        path: PathBuf,
    },
    /// A child did not finish in time (it has been killed).
    #[error("`{command}` did not finish within {timeout:?} (killed); output so far: {output}")]
    Timeout {
        /// The command.
        command: String,
        /// The limit.
        timeout: Duration,
        /// Its standard output and error so far.
        output: String,
    },
    /// The second site was asked of a lab built without one.
    #[error("this lab has no second site (build it with LabConfig::with_second_site)")]
    NoSecondSite,
}

fn io_error(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> LabError {
    let what = what.into();
    move |source| LabError::Io { what, source }
}

fn describe(command: &Command) -> String {
    std::iter::once(command.get_program())
        .chain(command.get_args())
        .map(OsStr::to_string_lossy)
        .collect::<Vec<_>>()
        .join(" ")
}

/// Run a setup command to completion; an unsuccessful exit is an error carrying its stderr.
fn run(command: &mut Command) -> Result<String, LabError> {
    let output = command
        .stdin(Stdio::null())
        .output()
        .map_err(io_error(format!("running `{}`", describe(command))))?;
    if !output.status.success() {
        return Err(LabError::Command {
            command: describe(command),
            status: output.status.to_string(),
            stderr: String::from_utf8_lossy(&output.stderr).trim().to_owned(),
        });
    }
    Ok(String::from_utf8_lossy(&output.stdout).into_owned())
}

fn ip(args: &[&str]) -> Result<String, LabError> {
    run(Command::new("ip").args(args))
}

/// Namespaces whose name starts with [`NAMESPACE_PREFIX`].
fn lab_namespaces() -> Vec<String> {
    ip(&["netns", "list"])
        .unwrap_or_default()
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .filter(|name| name.starts_with(NAMESPACE_PREFIX))
        .map(str::to_owned)
        .collect()
}

/// Process ids inside namespace `ns` (`ip netns pids`).
fn pids_in(ns: &str) -> Vec<u32> {
    ip(&["netns", "pids", ns])
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|pid| pid.parse().ok())
        .collect()
}

fn signal(signal: &str, pids: &[u32]) {
    if pids.is_empty() {
        return;
    }
    let _ = Command::new("kill")
        .arg(signal)
        .args(pids.iter().map(u32::to_string))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
}

/// End every process in `namespaces` (SIGTERM, then SIGKILL after `grace`) and delete the namespaces (their
/// veths go with them).
fn tear_down(namespaces: &[String], grace: Duration) {
    let all = |namespaces: &[String]| -> Vec<u32> {
        namespaces.iter().flat_map(|ns| pids_in(ns)).collect()
    };
    signal("-TERM", &all(namespaces));
    let deadline = Instant::now() + grace;
    while !all(namespaces).is_empty() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    signal("-KILL", &all(namespaces));
    for ns in namespaces {
        let _ = ip(&["netns", "del", ns]);
    }
}

/// The workspace binary `name` next to the running test or bench: `target/<profile>/deps/<test>` ->
/// `target/<profile>/<name>`. An error naming the missing path if it is not built.
pub fn role_binary(name: &str) -> Result<PathBuf, LabError> {
    let exe = std::env::current_exe().map_err(io_error("locating the running executable"))?;
    let dir = exe.parent().unwrap_or(Path::new("."));
    let profile_dir = if dir.file_name() == Some(OsStr::new("deps")) {
        dir.parent().unwrap_or(dir)
    } else {
        dir
    };
    let path = profile_dir.join(name);
    if path.is_file() {
        Ok(path)
    } else {
        Err(LabError::MissingBinary {
            name: name.to_owned(),
            path,
        })
    }
}

/// Wait for `child` with a limit, reading its stdout and stderr meanwhile (so a chatty child never blocks on
/// a full pipe). On timeout the child is killed and the error carries what it printed.
pub fn wait_output(mut child: Child, timeout: Duration) -> Result<Output, LabError> {
    fn drain(
        pipe: Option<impl std::io::Read + Send + 'static>,
    ) -> std::thread::JoinHandle<Vec<u8>> {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_end(&mut bytes);
            }
            bytes
        })
    }
    let stdout = drain(child.stdout.take());
    let stderr = drain(child.stderr.take());
    let deadline = Instant::now() + timeout;
    let status = loop {
        match child.try_wait().map_err(io_error("waiting for a child"))? {
            Some(status) => break Some(status),
            None if Instant::now() >= deadline => break None,
            None => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    if status.is_none() {
        let _ = child.kill();
        let _ = child.wait();
    }
    let stdout = stdout.join().unwrap_or_default();
    let stderr = stderr.join().unwrap_or_default();
    match status {
        Some(status) => Ok(Output {
            status,
            stdout,
            stderr,
        }),
        None => Err(LabError::Timeout {
            command: format!("pid {}", child.id()),
            timeout,
            output: format!(
                "{}{}",
                String::from_utf8_lossy(&stdout),
                String::from_utf8_lossy(&stderr)
            ),
        }),
    }
}

static LABS: AtomicU32 = AtomicU32::new(0);

/// Which side of the lab a command runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The server's namespace (`10.X.0.1`).
    Server,
    /// The device's namespace (`10.X.0.2`).
    Device,
    /// The second device site's namespace (`10.X.1.2`), when the lab has one.
    SecondDevice,
}

/// Three namespaces, two veth pairs and a relay; see the module doc. Dropping it ends every process in its
/// namespaces and deletes them.
#[derive(Debug)]
pub struct NetnsLab {
    server_ns: String,
    device_ns: String,
    relay_ns: String,
    /// The second device site's namespace, when [`LabConfig::second_site`].
    second_ns: Option<String>,
    subnet: u8,
    config: LabConfig,
    relay: Option<Child>,
    relay_log: PathBuf,
    second_relay: Option<Child>,
    second_relay_log: PathBuf,
    children: Vec<u32>,
}

impl NetnsLab {
    /// `Ok` if a lab can be built here (root, `ip` with netns support); else the reason, for tests to print
    /// when they skip.
    pub fn available() -> Result<(), String> {
        let uid = Command::new("id")
            .arg("-u")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
            .map_err(|e| format!("cannot run `id -u`: {e}"))?;
        if uid != "0" {
            return Err(format!(
                "needs root to create network namespaces (uid is {uid})"
            ));
        }
        ip(&["netns", "list"])
            .map(|_| ())
            .map_err(|e| format!("`ip netns` (iproute2) is not usable: {e}"))
    }

    /// Build a lab with `config` on its path and start the relay. Removes labs left by crashed runs first.
    /// Needs the `sinew-netem` binary ([`role_binary`]).
    pub fn new(config: LabConfig) -> Result<Self, LabError> {
        Self::available().map_err(LabError::Unavailable)?;
        let second = config.second_site.iter().flat_map(|path| {
            [
                path.server_to_site.validate(),
                path.site_to_server.validate(),
            ]
        });
        for problem in [
            config.server_to_device.validate(),
            config.device_to_server.validate(),
        ]
        .into_iter()
        .chain(second)
        {
            problem.map_err(|e| LabError::Relay(format!("bad lab config: {e}")))?;
        }
        let netem = role_binary("sinew-netem")?;
        Self::remove_stale();
        let pid = std::process::id();
        let n = LABS.fetch_add(1, Ordering::Relaxed);
        // Addresses live only inside the lab's namespaces; X differs per lab of this process anyway.
        let subnet = u8::try_from(1 + (pid.wrapping_mul(7).wrapping_add(n)) % 254).unwrap_or(1);
        let name = |role: &str| format!("{NAMESPACE_PREFIX}{pid}-{n}-{role}");
        let mut lab = Self {
            server_ns: name("srv"),
            device_ns: name("dev"),
            relay_ns: name("rly"),
            second_ns: config.second_site.map(|_| name("dv2")),
            subnet,
            config,
            relay: None,
            relay_log: std::env::temp_dir().join(format!("{}.log", name("netem"))),
            second_relay: None,
            second_relay_log: std::env::temp_dir().join(format!("{}.log", name("netem2"))),
            children: Vec::new(),
        };
        // From here on, Drop removes whatever was created.
        lab.build_network()?;
        let first = RelaySpec {
            interfaces: RELAY_INTERFACES,
            a_to_b: lab.config.server_to_device,
            b_to_a: lab.config.device_to_server,
            drops_a_to_b: lab.config.drops_to_device.clone(),
            drops_b_to_a: lab.config.drops_to_server.clone(),
        };
        lab.relay = Some(lab.start_relay(&netem, &first, &lab.relay_log)?);
        if let Some(path) = lab.config.second_site {
            let second = RelaySpec {
                interfaces: SECOND_RELAY_INTERFACES,
                a_to_b: path.server_to_site,
                b_to_a: path.site_to_server,
                drops_a_to_b: Vec::new(),
                drops_b_to_a: Vec::new(),
            };
            lab.second_relay = Some(lab.start_relay(&netem, &second, &lab.second_relay_log)?);
        }
        Ok(lab)
    }

    fn build_network(&self) -> Result<(), LabError> {
        for ns in self.namespaces() {
            ip(&["netns", "add", ns])?;
            // IPv4 only: no link-local IPv6 chatter on the emulated path (best effort; fine if IPv6 is absent).
            let _ = run(Command::new("ip").args([
                "netns",
                "exec",
                ns,
                "sysctl",
                "-qw",
                "net.ipv6.conf.all.disable_ipv6=1",
                "net.ipv6.conf.default.disable_ipv6=1",
            ]));
            ip(&["-n", ns, "link", "set", "lo", "up"])?;
        }
        let mut sides = vec![
            (
                &self.server_ns,
                LAB_INTERFACE,
                RELAY_INTERFACES[0],
                self.server_ip(),
            ),
            (
                &self.device_ns,
                LAB_INTERFACE,
                RELAY_INTERFACES[1],
                self.device_ip(),
            ),
        ];
        if let Some(second_ns) = &self.second_ns {
            sides.push((
                &self.server_ns,
                SECOND_SITE_SERVER_INTERFACE,
                SECOND_RELAY_INTERFACES[0],
                self.server_ip_for_second_site(),
            ));
            sides.push((
                second_ns,
                LAB_INTERFACE,
                SECOND_RELAY_INTERFACES[1],
                self.second_site_ip(),
            ));
        }
        for (ns, interface, relay_end, address) in sides {
            ip(&[
                "-n",
                &self.relay_ns,
                "link",
                "add",
                relay_end,
                "type",
                "veth",
                "peer",
                "name",
                interface,
                "netns",
                ns,
            ])?;
            // One segment per skb: the relay reads whole frames of at most the MTU (no TSO super-frames).
            for (in_ns, interface) in [(ns.as_str(), interface), (&self.relay_ns, relay_end)] {
                ip(&["-n", in_ns, "link", "set", interface, "gso_max_segs", "1"])?;
                ip(&["-n", in_ns, "link", "set", interface, "up"])?;
            }
            ip(&[
                "-n",
                ns,
                "addr",
                "add",
                &format!("{address}/24"),
                "dev",
                interface,
            ])?;
            if let Some(algorithm) = self.config.tcp_congestion_control {
                run(Command::new("ip").args([
                    "netns",
                    "exec",
                    ns,
                    "sysctl",
                    "-qw",
                    &format!("net.ipv4.tcp_congestion_control={algorithm}"),
                ]))?;
            }
        }
        Ok(())
    }

    /// Start one `sinew-netem` in the relay namespace as `spec` says, logging to `log`; returned once it
    /// reports that it is bridging.
    fn start_relay(
        &self,
        netem: &Path,
        spec: &RelaySpec,
        log_path: &Path,
    ) -> Result<Child, LabError> {
        let log = std::fs::File::create(log_path)
            .map_err(io_error(format!("creating {}", log_path.display())))?;
        let log_err = log
            .try_clone()
            .map_err(io_error("duplicating the relay log handle"))?;
        let mut command = Command::new("ip");
        command.args(["netns", "exec", &self.relay_ns]);
        if self.config.relay_realtime && Command::new("chrt").arg("--version").output().is_ok() {
            command.args(["chrt", "-f", RELAY_PRIORITY]);
        }
        command
            .arg(netem)
            .arg("--spin-ns")
            .arg(self.config.relay_spin_ns.to_string())
            .args(["--a", spec.interfaces[0], "--b", spec.interfaces[1]])
            .arg("--a-to-b")
            .arg(format_direction(&spec.a_to_b))
            .arg("--b-to-a")
            .arg(format_direction(&spec.b_to_a))
            .args(scripted_drops("--drop-a-to-b", &spec.drops_a_to_b))
            .args(scripted_drops("--drop-b-to-a", &spec.drops_b_to_a))
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(log_err);
        let mut child = command
            .spawn()
            .map_err(io_error(format!("starting `{}`", describe(&command))))?;
        let deadline = Instant::now() + RELAY_START_TIMEOUT;
        loop {
            let text = std::fs::read_to_string(log_path).unwrap_or_default();
            if text.contains("bridging") {
                return Ok(child);
            }
            if let Some(status) = child.try_wait().ok().flatten() {
                return Err(LabError::Relay(format!("exited ({status}): {text}")));
            }
            if Instant::now() >= deadline {
                let _ = child.kill();
                let _ = child.wait();
                return Err(LabError::Relay(format!(
                    "no `bridging` line within {RELAY_START_TIMEOUT:?}: {text}"
                )));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Delete namespaces with [`NAMESPACE_PREFIX`] whose creating process is gone (a crashed or killed run),
    /// ending the processes left inside them. Returns how many were removed.
    pub fn remove_stale() -> usize {
        let stale: Vec<String> = lab_namespaces()
            .into_iter()
            .filter(|name| {
                let pid = name[NAMESPACE_PREFIX.len()..]
                    .split('-')
                    .next()
                    .and_then(|pid| pid.parse::<u32>().ok());
                pid.is_none_or(|pid| !Path::new(&format!("/proc/{pid}")).exists())
            })
            .collect();
        tear_down(&stale, Duration::from_millis(500));
        stale.len()
    }

    /// Every namespace name with [`NAMESPACE_PREFIX`] on this machine (for tests that check the cleanup).
    pub fn existing_lab_namespaces() -> Vec<String> {
        lab_namespaces()
    }

    /// The lab's namespaces: server side, device side, relay, and the second site's if it has one.
    pub fn namespaces(&self) -> Vec<&str> {
        let mut all = vec![
            self.server_ns.as_str(),
            self.device_ns.as_str(),
            self.relay_ns.as_str(),
        ];
        all.extend(self.second_ns.as_deref());
        all
    }

    /// The namespace of `side`.
    /// [`LabError::NoSecondSite`] for [`Side::SecondDevice`] in a lab without one.
    pub fn namespace(&self, side: Side) -> Result<&str, LabError> {
        match side {
            Side::Server => Ok(&self.server_ns),
            Side::Device => Ok(&self.device_ns),
            Side::SecondDevice => self.second_ns.as_deref().ok_or(LabError::NoSecondSite),
        }
    }

    /// The server side's address, `10.X.0.1`.
    pub fn server_ip(&self) -> Ipv4Addr {
        Ipv4Addr::new(10, self.subnet, 0, 1)
    }

    /// The device side's address, `10.X.0.2`.
    pub fn device_ip(&self) -> Ipv4Addr {
        Ipv4Addr::new(10, self.subnet, 0, 2)
    }

    /// The server side's address on the second site's path, `10.X.1.1`.
    pub fn server_ip_for_second_site(&self) -> Ipv4Addr {
        Ipv4Addr::new(10, self.subnet, 1, 1)
    }

    /// The second site's address, `10.X.1.2`.
    pub fn second_site_ip(&self) -> Ipv4Addr {
        Ipv4Addr::new(10, self.subnet, 1, 2)
    }

    /// The path's configuration.
    pub fn config(&self) -> &LabConfig {
        &self.config
    }

    /// Start `command` (program, arguments, environment and working directory; its stdio settings are not
    /// readable and are replaced) inside the server namespace via `ip netns exec`. stdin is null, stdout and
    /// stderr are piped: read them, or use [`wait_output`]. The lab ends it on drop if it still runs.
    pub fn spawn_in_server_ns(&mut self, command: &Command) -> Result<Child, LabError> {
        self.spawn_in(Side::Server, command)
    }

    /// [`NetnsLab::spawn_in_server_ns`] in the device namespace.
    pub fn spawn_in_device_ns(&mut self, command: &Command) -> Result<Child, LabError> {
        self.spawn_in(Side::Device, command)
    }

    /// [`NetnsLab::spawn_in_server_ns`] on either side.
    pub fn spawn_in(&mut self, side: Side, command: &Command) -> Result<Child, LabError> {
        let mut inside = Command::new("ip");
        inside
            .args(["netns", "exec", self.namespace(side)?])
            .arg(command.get_program())
            .args(command.get_args());
        for (key, value) in command.get_envs() {
            match value {
                Some(value) => inside.env(key, value),
                None => inside.env_remove(key),
            };
        }
        if let Some(dir) = command.get_current_dir() {
            inside.current_dir(dir);
        }
        inside
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let child = inside
            .spawn()
            .map_err(io_error(format!("starting `{}`", describe(&inside))))?;
        self.children.push(child.id());
        Ok(child)
    }

    /// Cut the path at `side`: that side's veth end in the relay namespace goes down, so no frame crosses in
    /// either direction (a network partition; the processes keep running).
    pub fn cut(&self, side: Side) -> Result<(), LabError> {
        let end = match side {
            Side::Server => RELAY_INTERFACES[0],
            Side::Device => RELAY_INTERFACES[1],
            Side::SecondDevice => SECOND_RELAY_INTERFACES[1],
        };
        ip(&["-n", &self.relay_ns, "link", "set", end, "down"]).map(|_| ())
    }

    /// Process ids of the children started so far (some may have exited).
    pub fn children(&self) -> &[u32] {
        &self.children
    }

    /// Stop the relays (SIGTERM) and return what they printed: per relay the `bridging` line and one counter
    /// line per direction (`received .. forwarded .. lost ..`, send lateness percentiles); the second site's
    /// relay after the first's. The paths are down afterwards.
    pub fn stop_relay(&mut self) -> Result<String, LabError> {
        let relays: Vec<Child> = self
            .relay
            .take()
            .into_iter()
            .chain(self.second_relay.take())
            .collect();
        if !relays.is_empty() {
            signal("-TERM", &pids_in(&self.relay_ns));
        }
        for mut relay in relays {
            let deadline = Instant::now() + Duration::from_secs(3);
            while relay.try_wait().ok().flatten().is_none() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(10));
            }
            let _ = relay.kill();
            let _ = relay.wait();
        }
        let mut text = std::fs::read_to_string(&self.relay_log)
            .map_err(io_error(format!("reading {}", self.relay_log.display())))?;
        if self.second_ns.is_some() {
            text += &std::fs::read_to_string(&self.second_relay_log).map_err(io_error(format!(
                "reading {}",
                self.second_relay_log.display()
            )))?;
        }
        Ok(text)
    }
}

impl Drop for NetnsLab {
    fn drop(&mut self) {
        let namespaces: Vec<String> = self.namespaces().into_iter().map(str::to_owned).collect();
        tear_down(&namespaces, Duration::from_secs(2));
        for mut relay in self
            .relay
            .take()
            .into_iter()
            .chain(self.second_relay.take())
        {
            let _ = relay.kill();
            let _ = relay.wait();
        }
        let _ = std::fs::remove_file(&self.relay_log);
        let _ = std::fs::remove_file(&self.second_relay_log);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_config_differs_only_in_seed() {
        let config = LabConfig::symmetric(20.0, 5.0, 0.05, 9);
        assert_eq!(config.server_to_device.delay_ms, 20.0);
        assert_eq!(config.device_to_server.jitter_ms, 5.0);
        assert_eq!(config.device_to_server.loss, 0.05);
        assert_ne!(config.server_to_device.seed, config.device_to_server.seed);
    }

    #[test]
    fn a_missing_binary_is_named_with_its_path() {
        let error = role_binary("no-such-sinew-role").unwrap_err().to_string();
        assert!(error.contains("no-such-sinew-role"), "{error}");
        assert!(error.contains("cargo"), "{error}");
    }
}
