//! Starting roles on loopback and measuring across them, for the integration tests and benches. Every role
//! gets its own zenoh session (peer mode, multicast scouting off); the server listens, the others connect.
//!
//! The role starters the demo also uses (servers, simulated devices, viewers, the surgeons' scripts, the
//! replica's error) are the application's `sinew::loopback`, re-exported here; this module adds what only
//! tests need: the shipped worlds, free ports, recorded sessions, role processes, waiting and serializing.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use hapticserver::HapticConfig;
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_server::node::{ServerConfig, ServerHandle, ServerNode};
use sinew_server::world::{World, load_world};

pub use sinew::loopback::{
    Pacing, ReplicaError, SimDeviceSetup, replica_error, start_server, start_server_emulated,
    start_server_networked, start_server_recording, start_sim_device, start_sim_device_emulated,
    start_sim_device_networked, start_viewer, surgeon_scripts, surgeon_scripts_for,
};

/// The repository's `worlds/` directory (from this crate's manifest, so tests work from any directory).
pub fn worlds_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds")
}

/// Load `worlds/<name>`.
pub fn load_shipped_world(name: &str) -> anyhow::Result<World> {
    let path = worlds_dir().join(name);
    load_world(&path).with_context(|| format!("loading {}", path.display()))
}

/// A loopback TCP endpoint on a port the OS just reported free for TCP and for UDP (the server also listens
/// on the UDP twin, see [`start_server_emulated`]).
pub fn free_loopback_endpoint() -> anyhow::Result<String> {
    for _ in 0..20 {
        let listener = std::net::TcpListener::bind("127.0.0.1:0")?;
        let port = listener.local_addr()?.port();
        if std::net::UdpSocket::bind(("127.0.0.1", port)).is_ok() {
            return Ok(format!("tcp/127.0.0.1:{port}"));
        }
    }
    anyhow::bail!("no loopback port free for both TCP and UDP in 20 tries")
}

/// Record `duration` of the demo's two surgeons on the shipped pad (left presses and strokes, right presses
/// and holds; real zenoh on loopback, the server recording into `path`); returns what the recorder wrote and
/// the sim thread's final report (with the training layer's live view).
pub fn record_two_surgeons(
    path: &Path,
    duration: Duration,
) -> anyhow::Result<(
    sinew_server::recording::RecordSummary,
    sinew_server::node::SimReport,
)> {
    record_two_surgeons_in("pad.toml", path, duration)
}

/// [`record_two_surgeons`] on the shipped world `world_name` (left and right devices, each with its
/// [`surgeon_scripts_for`] script: a grasper grasps and pulls).
pub fn record_two_surgeons_in(
    world_name: &str,
    path: &Path,
    duration: Duration,
) -> anyhow::Result<(
    sinew_server::recording::RecordSummary,
    sinew_server::node::SimReport,
)> {
    let world = load_shipped_world(world_name)?;
    let scene = world.scene.clone();
    let (left_script, right_script) = surgeon_scripts_for(&world);
    let endpoint = free_loopback_endpoint()?;
    let config = ServerConfig {
        network: NetworkOptions {
            listen: with_udp_twin(&endpoint),
            ..NetworkOptions::default()
        },
        spin_native_accuracy_ns: 0,
        record: Some(path.to_owned()),
        ..ServerConfig::default()
    };
    let mut server = ServerNode::start(world, config).context("starting the recording server")?;
    let left = start_sim_device(&scene, "left", left_script, &endpoint, Pacing::Sleep)?;
    let right = start_sim_device(&scene, "right", right_script, &endpoint, Pacing::Sleep)?;
    anyhow::ensure!(
        wait_until(Duration::from_secs(10), || {
            server.stats().devices.iter().all(|d| d.active)
        }),
        "the two devices did not drive their tools within 10 s"
    );
    std::thread::sleep(duration);
    drop(left);
    drop(right);
    server.stop();
    let summary = server
        .record_summary()
        .cloned()
        .context("the server wrote no recording summary")?;
    let report = server
        .sim_report()
        .context("the sim thread left no report")?;
    Ok((summary, report))
}

/// Start a server on the shipped `worlds/pad.toml`, listening on a fresh loopback port; returns that endpoint
/// (for the other roles to connect to) and the server.
pub fn start_pad_server(pacing: Pacing) -> anyhow::Result<(String, ServerHandle)> {
    let endpoint = free_loopback_endpoint()?;
    let server = start_server(load_shipped_world("pad.toml")?, &endpoint, pacing)?;
    Ok((endpoint, server))
}

/// Poll `condition` every 10 ms until it holds or `timeout` passes. Returns whether it held.
pub fn wait_until(timeout: Duration, mut condition: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    loop {
        if condition() {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A role process that is killed when dropped, however the test ends.
#[derive(Debug)]
pub struct KillOnDrop(pub std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The `sinew-server` binary on `worlds/pad.toml`, listening on `endpoint` and its UDP twin, with `extra`
/// arguments; its output discarded unless `piped`.
pub fn spawn_pad_server_process(
    endpoint: &str,
    extra: &[&str],
    piped: bool,
) -> anyhow::Result<std::process::Child> {
    let binary = crate::netns::role_binary("sinew-server")?;
    let output = || {
        if piped {
            std::process::Stdio::piped()
        } else {
            std::process::Stdio::null()
        }
    };
    let mut command = std::process::Command::new(binary);
    command.arg("--world").arg(worlds_dir().join("pad.toml"));
    for listen in with_udp_twin(endpoint) {
        command.args(["--listen", &listen]);
    }
    command
        .args(extra)
        .stdout(output())
        .stderr(output())
        .spawn()
        .context("starting sinew-server")
}

/// A hapticserver config for device `id` in scene `pad`, driving `device` and connecting to `endpoint` and its
/// UDP twin (the multilink default).
pub fn pad_device_config(
    id: &str,
    device: Box<dyn hapticserver::Device>,
    endpoint: &str,
) -> HapticConfig {
    let mut config = HapticConfig::new("pad", id, device);
    config.network = NetworkOptions {
        connect: with_udp_twin(endpoint),
        ..NetworkOptions::default()
    };
    config
}

/// One scenario at a time within a test binary (each runs several 1 kHz loops; two cores are shared): hold the
/// guard for the test's length. A test that panicked releases it poisoned, which the next one ignores.
pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Wait up to `timeout` until the server says device `id` drives its tool. Returns whether it did.
pub fn wait_device_active(
    server: &sinew_server::node::ServerHandle,
    id: &str,
    timeout: Duration,
) -> bool {
    wait_until(timeout, || {
        server
            .stats()
            .devices
            .iter()
            .any(|d| d.device_id == id && d.active)
    })
}

/// Deepest point of object 0 below its rest plane z = 0, mm, from the server's latest frame (the pad's dent).
pub fn deepest_dent_mm(server: &sinew_server::node::ServerHandle) -> f32 {
    server
        .latest_positions(0)
        .unwrap_or_default()
        .iter()
        .map(|p| -p[2])
        .fold(0.0, f32::max)
}
