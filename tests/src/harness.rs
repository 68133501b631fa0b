//! Starting roles on loopback and measuring across them. Every role gets its own zenoh session (peer mode,
//! multicast scouting off); the server listens, the others connect.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use hapticserver::sim_device::sim_device_model;
use hapticserver::{HandPreset, HandScript, HapticConfig, HapticHandle, HapticServer, SimDevice};
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_server::node::{ServerConfig, ServerHandle, ServerNode};
use sinew_server::world::{World, load_world};
use sinew_viewer::{ViewerClient, ViewerConfig, ViewerHandle};

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

/// Pacing for the 1 kHz loops: spin-sleep for the demo, plain sleep for tests on shared cores.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// spin_sleep with 100 us native accuracy.
    Spin,
    /// Plain sleep (no spinning).
    Sleep,
    /// spin_sleep, and real-time scheduling (SCHED_FIFO, locked memory) where the process may have it: the
    /// loops then spin only their last 20 us.
    Realtime,
}

impl Pacing {
    fn native_accuracy_ns(self) -> u32 {
        match self {
            Pacing::Spin | Pacing::Realtime => 100_000,
            Pacing::Sleep => 0,
        }
    }

    fn realtime(self) -> bool {
        self == Pacing::Realtime
    }
}

/// Start a server listening on `endpoint`.
pub fn start_server(world: World, endpoint: &str, pacing: Pacing) -> anyhow::Result<ServerHandle> {
    start_server_emulated(world, endpoint, pacing, Default::default())
}

/// [`start_server`] with emulated delay, jitter and loss on the force commands it publishes. It listens on
/// `endpoint` and, when that is TCP, on its UDP twin (the product's multilink default).
pub fn start_server_emulated(
    world: World,
    endpoint: &str,
    pacing: Pacing,
    emulation: sinew_protocol::rt::EmulationConfig,
) -> anyhow::Result<ServerHandle> {
    start_server_recording(world, endpoint, pacing, emulation, None)
}

/// [`start_server_emulated`], recording the session into `record` (MCAP) when given.
pub fn start_server_recording(
    world: World,
    endpoint: &str,
    pacing: Pacing,
    emulation: sinew_protocol::rt::EmulationConfig,
    record: Option<std::path::PathBuf>,
) -> anyhow::Result<ServerHandle> {
    let config = ServerConfig {
        emulation,
        record,
        network: NetworkOptions {
            listen: with_udp_twin(endpoint),
            ..NetworkOptions::default()
        },
        server_id: "server".into(),
        spin_native_accuracy_ns: pacing.native_accuracy_ns(),
        realtime: pacing.realtime(),
        ..ServerConfig::default()
    };
    ServerNode::start(world, config).context("starting the server")
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

/// Start a hapticserver for device `id` with a simulated hand following `script`, connecting to `endpoint`.
pub fn start_sim_device(
    scene: &str,
    id: &str,
    script: HandScript,
    endpoint: &str,
    pacing: Pacing,
) -> anyhow::Result<HapticHandle> {
    start_sim_device_emulated(
        scene,
        id,
        script,
        endpoint,
        pacing,
        SimDeviceSetup::default(),
    )
}

/// How a simulated hapticserver runs beyond its script: render mode, emulated network on its poses, hand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimDeviceSetup {
    /// Direct, moderated or auto.
    pub mode: hapticserver::ModePolicy,
    /// Delay, jitter and loss on the poses it publishes.
    pub emulation: sinew_protocol::rt::EmulationConfig,
    /// The simulated operator.
    pub hand: HandPreset,
    /// Align the loop's phase with the server's tick while rendering directly (the default).
    pub phase_align: bool,
}

impl Default for SimDeviceSetup {
    fn default() -> Self {
        Self {
            mode: hapticserver::ModePolicy::default(),
            emulation: sinew_protocol::rt::EmulationConfig::default(),
            hand: HandPreset::Grip,
            phase_align: true,
        }
    }
}

/// [`start_sim_device`] with a [`SimDeviceSetup`]. It
/// connects to `endpoint` and its UDP twin (multilink: poses and forces on UDP).
pub fn start_sim_device_emulated(
    scene: &str,
    id: &str,
    script: HandScript,
    endpoint: &str,
    pacing: Pacing,
    setup: SimDeviceSetup,
) -> anyhow::Result<HapticHandle> {
    let device = SimDevice::with_params(script, setup.hand.params(), sim_device_model());
    let mut config = HapticConfig::new(scene, id, Box::new(device));
    config.network = NetworkOptions {
        connect: with_udp_twin(endpoint),
        ..NetworkOptions::default()
    };
    config.spin_accuracy_ns = pacing.native_accuracy_ns();
    config.realtime = pacing.realtime();
    config.mode = setup.mode;
    config.emulation = setup.emulation;
    config.phase_align = setup.phase_align;
    HapticServer::start(config).with_context(|| format!("starting hapticserver `{id}`"))
}

/// Start a viewer connecting to `endpoint`.
pub fn start_viewer(scene: &str, id: &str, endpoint: &str) -> anyhow::Result<ViewerHandle> {
    let mut config = ViewerConfig::new(scene, id);
    config.network = NetworkOptions {
        connect: vec![endpoint.to_owned()],
        ..NetworkOptions::default()
    };
    ViewerClient::start(config).with_context(|| format!("starting viewer `{id}`"))
}

/// The demo's two surgeons: left presses 5 mm and strokes +-8 mm along x every 2 s; right presses 4 mm and
/// holds. Device frame (the pad surface is z = 0 at each device's origin).
pub fn surgeon_scripts() -> (HandScript, HandScript) {
    let left = HandScript::PressAndStroke {
        at_mm: [0.0, 0.0, 0.0],
        depth_mm: 5.0,
        approach_mm: 15.0,
        descend_s: 1.0,
        stroke_mm: 8.0,
        stroke_period_s: 2.0,
    };
    let right = HandScript::Press {
        at_mm: [0.0, 0.0, 0.0],
        depth_mm: 4.0,
        approach_mm: 15.0,
        descend_s: 1.0,
    };
    (left, right)
}

/// The scripts of the two demo surgeons for `world`: [`surgeon_scripts`], except that a tool that is a grasper
/// gets a grasp-and-pull (press 1.5 mm, close, pull 8 mm up and 6 mm outward, left to -x and right to +x, hold
/// 2 s, open): coordinated pulling with two graspers; a cautery tool burns a 12 mm line (0.5 mm in, current
/// on for 2 s); and a scalpel draws its edge 40 mm along +y from 20 mm before its device origin (origin 1.5 mm
/// above the surface, over 2 s); scissors snip a 30 mm line of 10 bites 3 mm apart along +y from 12 mm before the
/// device origin (hinge 6 mm above the surface, 0.4 s a snip).
pub fn surgeon_scripts_for(world: &sinew_server::world::World) -> (HandScript, HandScript) {
    let (left, right) = surgeon_scripts();
    let pull = |outward_mm: f32| HandScript::GraspPull {
        at_mm: [0.0, 0.0, 0.0],
        depth_mm: 1.5,
        approach_mm: 15.0,
        descend_s: 1.0,
        settle_s: 0.3,
        pull_mm: [outward_mm, 0.0, 8.0],
        pull_s: 1.0,
        hold_s: 2.0,
    };
    let burn = HandScript::Cauterize {
        at_mm: [-6.0, 0.0, 0.0],
        depth_mm: 0.5,
        approach_mm: 10.0,
        descend_s: 1.0,
        stroke_mm: 12.0,
        stroke_s: 2.0,
    };
    let cut = HandScript::CutLine {
        at_mm: [0.0, -20.0, 0.0],
        height_mm: hapticserver::CUT_LINE_HEIGHT_MM,
        approach_mm: 10.0,
        descend_s: 1.0,
        line_mm: [0.0, 40.0, 0.0],
        line_s: 2.0,
    };
    // Snips 3 mm apart along y from y = -12 mm, 10 of them: a 30 mm line of bites.
    let snip = HandScript::SnipLine {
        at_mm: [0.0, -12.0, 0.0],
        height_mm: hapticserver::SNIP_LINE_HEIGHT_MM,
        approach_mm: 14.0,
        descend_s: 1.0,
        step_mm: [0.0, hapticserver::SNIP_STEP_MM, 0.0],
        snips: 10,
        snip_s: 0.4,
    };
    let pick = |device: &str, outward_mm: f32, otherwise: HandScript| {
        use sinew_server::world::InstrumentSpec;
        let instrument = world
            .tools
            .iter()
            .find(|t| t.device_id == device)
            .map(|t| t.instrument);
        match instrument {
            Some(InstrumentSpec::Grasper(_)) => pull(outward_mm),
            Some(InstrumentSpec::Cautery(_)) => burn.clone(),
            Some(InstrumentSpec::Scalpel(_)) => cut.clone(),
            Some(InstrumentSpec::Scissors(_)) => snip.clone(),
            Some(InstrumentSpec::Probe) | None => otherwise,
        }
    };
    (pick("left", -6.0, left), pick("right", 6.0, right))
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

/// How far a viewer's replica of one object is from the server's true mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplicaError {
    /// Frame both sides were compared at.
    pub frame: u64,
    /// Largest distance between a replica vertex and the server's true position, mm.
    pub max_error_mm: f32,
    /// The quantization bound it must stay within, mm.
    pub bound_mm: f32,
}

/// Wait until the viewer's replica of `object` is at the frame of the server's last published delta, then
/// compare every vertex with the server's true positions at that frame. None if they never line up.
pub fn replica_error(
    server: &ServerHandle,
    viewer: &ViewerHandle,
    object: usize,
    timeout: Duration,
) -> Option<ReplicaError> {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        let (frame, truth) = server.published_positions(object)?;
        let compared = viewer.with_replica(|replica| {
            let o = replica.objects().get(object)?;
            if o.frame() != frame || o.vertex_count() != truth.len() {
                return None;
            }
            let max_error_mm = o
                .positions_mm_iter()
                .zip(&truth)
                .map(|(r, t)| {
                    ((r[0] - t[0]).powi(2) + (r[1] - t[1]).powi(2) + (r[2] - t[2]).powi(2)).sqrt()
                })
                .fold(0.0f32, f32::max);
            Some(ReplicaError {
                frame,
                max_error_mm,
                bound_mm: o.max_error_mm(),
            })
        });
        if compared.is_some() {
            return compared;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    None
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
