//! Everything needed to start one hapticserver.
//!
//! Owns: [`HapticConfig`] and its defaults (scene "pad", 1 kHz, 100 us spin accuracy, device safety limits,
//! the client network default). Must not: open anything (that is [`crate::haptic_server`]).

use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::EmulationConfig;

use crate::device::Device;
use crate::safety::SafetyConfig;

/// Default loop rate, Hz.
pub const DEFAULT_LOOP_RATE_HZ: u32 = 1000;
/// Default spin accuracy for the pacer, ns (spin the last 100 us before each deadline).
pub const DEFAULT_SPIN_ACCURACY_NS: u32 = 100_000;
/// Default scene.
pub const DEFAULT_SCENE: &str = "pad";

/// Configuration of one hapticserver.
pub struct HapticConfig {
    /// Scene name (a key segment).
    pub scene: String,
    /// Device id (a key segment), e.g. "left".
    pub device_id: String,
    /// Tool the device asks to drive; empty = whichever tool the world binds to this device id.
    pub tool: String,
    /// zenoh endpoints.
    pub network: NetworkOptions,
    /// The device to serve.
    pub device: Box<dyn Device>,
    /// Where the device's own frame sits in the wire frame (`--mount-rotation-deg`, `--mount-offset-mm`);
    /// identity by default. Readings are mapped through it and forces mapped back.
    pub mount: crate::calibration::WorldFromDevice,
    /// Loop rate, Hz.
    pub loop_rate_hz: u32,
    /// Pacer spin accuracy, ns: 0 = plain sleep only (tests on shared cores), 100_000 for a real device. The
    /// loop spins less when its scheduling allows (`protocol::rt::realtime`).
    pub spin_accuracy_ns: u32,
    /// Ask for SCHED_FIFO and locked memory for the device loop (`--realtime`); refused quietly (and
    /// reported) where the process may not have them.
    pub realtime: bool,
    /// Safety limits; `None` = the device's own limits with default timing. Always tightened to the device's
    /// limits at start, never loosened.
    pub safety: Option<SafetyConfig>,
    /// Passivity observer only (default), or observer and controller, while rendering directly (the
    /// controller is always on while the local model is rendered).
    pub passivity: crate::passivity::PassivityMode,
    /// Direct, moderated or auto (default).
    pub mode: crate::render_mode::ModePolicy,
    /// Shift the loop's phase so poses arrive just before the server's ticks while rendering directly
    /// (default on; `--phase-align off` for the comparison).
    pub phase_align: bool,
    /// The pose wait at the server the alignment settles at, us (`--phase-target-us`, default 150): the
    /// margin that keeps a jittered pose ahead of the server's tick.
    pub phase_target_us: f32,
    /// Emulated delay, jitter and loss on the poses this hapticserver publishes (`--emulate-*`).
    pub emulation: EmulationConfig,
    /// Record this many ticks of trace (0 = none); [`crate::HapticHandle::take_trace`] returns it after stop.
    pub trace_ticks: usize,
    /// Fault drill: the device loop panics at this tick, as a bug in it would (`--fault-panic-at-tick`,
    /// hidden). `None` in every normal run.
    pub panic_at_tick: Option<u64>,
}

impl std::fmt::Debug for HapticConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HapticConfig")
            .field("scene", &self.scene)
            .field("device_id", &self.device_id)
            .field("tool", &self.tool)
            .field("network", &self.network)
            .field("device", &self.device.model().name)
            .field("mount", &self.mount)
            .field("loop_rate_hz", &self.loop_rate_hz)
            .field("spin_accuracy_ns", &self.spin_accuracy_ns)
            .field("realtime", &self.realtime)
            .field("safety", &self.safety)
            .field("passivity", &self.passivity)
            .field("mode", &self.mode)
            .field("phase_align", &self.phase_align)
            .field("phase_target_us", &self.phase_target_us)
            .field("emulation", &self.emulation)
            .field("trace_ticks", &self.trace_ticks)
            .field("panic_at_tick", &self.panic_at_tick)
            .finish()
    }
}

impl HapticConfig {
    /// Defaults for serving `device` as `device_id` in `scene`.
    pub fn new(scene: &str, device_id: &str, device: Box<dyn Device>) -> Self {
        Self {
            scene: scene.to_owned(),
            device_id: device_id.to_owned(),
            tool: String::new(),
            network: NetworkOptions::device_default(),
            device,
            mount: crate::calibration::WorldFromDevice::identity(),
            loop_rate_hz: DEFAULT_LOOP_RATE_HZ,
            spin_accuracy_ns: DEFAULT_SPIN_ACCURACY_NS,
            realtime: false,
            safety: None,
            passivity: crate::passivity::PassivityMode::Observe,
            mode: crate::render_mode::ModePolicy::default(),
            phase_align: true,
            phase_target_us: crate::phase_align::DEFAULT_TARGET_WAIT_US,
            emulation: EmulationConfig::default(),
            trace_ticks: 0,
            panic_at_tick: None,
        }
    }
}
