//! Starting the three roles in one process on a loopback endpoint, as `sinew demo` does: a server, simulated
//! hapticservers with scripted hands, and viewers, each with its own zenoh session (peer mode, multicast
//! scouting off); the server listens, the others connect. Also the demo's two surgeons' scripts and the
//! viewer replica's error against the server's true mesh.
//!
//! Owns: [`Pacing`], [`start_server`] and its emulating and recording variants, [`start_sim_device`] /
//! [`start_sim_device_emulated`] with [`SimDeviceSetup`], [`start_viewer`], [`surgeon_scripts`] /
//! [`surgeon_scripts_for`] and [`replica_error`]. The test kit (`sinew-testkit`'s `harness`) re-exports these
//! for the integration tests and benches.

use std::time::{Duration, Instant};

use anyhow::Context as _;
use hapticserver::sim_device::sim_device_model;
use hapticserver::{HandPreset, HandScript, HapticConfig, HapticHandle, HapticServer, SimDevice};
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_server::node::{ServerConfig, ServerHandle, ServerNode};
use sinew_server::world::World;
use sinew_viewer::{ViewerClient, ViewerConfig, ViewerHandle};

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
    let network = NetworkOptions {
        listen: with_udp_twin(endpoint),
        ..NetworkOptions::default()
    };
    start_server_networked(world, network, pacing, emulation, record)
}

/// A server on any network layout: `network` says its mode, endpoints and certificate (a router's client,
/// the site's router itself, mutual TLS). [`start_server_recording`] is this listening on loopback.
pub fn start_server_networked(
    world: World,
    network: NetworkOptions,
    pacing: Pacing,
    emulation: sinew_protocol::rt::EmulationConfig,
    record: Option<std::path::PathBuf>,
) -> anyhow::Result<ServerHandle> {
    let config = ServerConfig {
        emulation,
        record,
        network,
        server_id: "server".into(),
        spin_native_accuracy_ns: pacing.native_accuracy_ns(),
        realtime: pacing.realtime(),
        ..ServerConfig::default()
    };
    ServerNode::start(world, config).context("starting the server")
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
    let network = NetworkOptions {
        connect: with_udp_twin(endpoint),
        ..NetworkOptions::default()
    };
    start_sim_device_networked(scene, id, script, network, pacing, setup)
}

/// A simulated hapticserver on any network layout (`network`: its mode, endpoints and certificate).
/// [`start_sim_device_emulated`] is this connecting to a server on loopback.
pub fn start_sim_device_networked(
    scene: &str,
    id: &str,
    script: HandScript,
    network: NetworkOptions,
    pacing: Pacing,
    setup: SimDeviceSetup,
) -> anyhow::Result<HapticHandle> {
    let device = SimDevice::with_params(script, setup.hand.params(), sim_device_model());
    let mut config = HapticConfig::new(scene, id, Box::new(device));
    config.network = network;
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
/// device origin (hinge 6 mm above the surface, `SNIP_PERIOD_S`, 0.8 s, a snip).
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
        snip_s: hapticserver::SNIP_PERIOD_S,
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
            // The scripted stitch comes with the suture world (docs/suturing.md, step 7); until then a needle
            // driver presses as a probe does.
            Some(InstrumentSpec::Probe) | Some(InstrumentSpec::NeedleDriver(_)) | None => otherwise,
        }
    };
    (pick("left", -6.0, left), pick("right", 6.0, right))
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
