//! `hapticserver`: serve one haptic device to a Sinew scene.
//!
//! Owns: flag parsing, logging setup and the status line; everything else is the `hapticserver` library.
//! Must not: contain loop, safety or device logic.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Parser, ValueEnum};
use hapticserver::{
    Device, HandPreset, HapticConfig, HapticServer, ModePolicy, ScriptKind, ScriptOptions,
    SimDevice, parse_vec3_mm, sim_device::sim_device_model,
};
use sinew_protocol::network::NetworkOptions;

/// Device backends this build can drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum DeviceKind {
    /// A simulated hand holding a stylus, following --script.
    Sim,
    /// A recorded hand: plays --replay-trace (a `--trace-csv` file), then holds its last position.
    Replay,
    /// A 3D Systems Touch / Phantom through the vendor's OpenHaptics HD library (libHD.so): --libhd,
    /// --hd-device. Untested on hardware.
    #[cfg(feature = "openhaptics")]
    Openhaptics,
}

/// `--phase-align` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum OnOff {
    On,
    Off,
}

/// `--passivity` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum PassivityArg {
    /// Observer only.
    Observe,
    /// Observer and controller.
    Control,
}

/// Serve one haptic device (pose out at 1 kHz, force in) to a Sinew scene over zenoh.
#[derive(Debug, Parser)]
#[command(name = "hapticserver", version)]
struct Args {
    /// Device backend: `sim` (a scripted hand), `replay` (a recorded one; `sinew play-device` plays a
    /// session recording) or, in builds with the `openhaptics` feature, `openhaptics`.
    #[arg(long, value_enum, default_value = "sim")]
    device: DeviceKind,
    /// Device id: the key segment in sinew/<scene>/device/<id>/...
    #[arg(long, default_value = "left")]
    id: String,
    /// Tool to drive (empty: whichever tool the world binds to this device id).
    #[arg(long, default_value = "")]
    tool: String,
    /// Scene name.
    #[arg(long, default_value = "pad")]
    scene: String,
    /// Simulated hand script: hold, press, press-stroke, grasp-pull, cauterize, cut-line or snip-line.
    #[arg(long, default_value = "press")]
    script: ScriptKind,
    /// Press depth below the surface point, mm (negative: above it).
    #[arg(long, allow_negative_numbers = true)]
    depth_mm: Option<f32>,
    /// Surface point to press at (or hold), device frame, mm: x,y,z.
    #[arg(long, value_parser = parse_vec3_mm, allow_hyphen_values = true)]
    at_mm: Option<[f32; 3]>,
    /// Starting height above the surface point, mm (default 20).
    #[arg(long)]
    approach_mm: Option<f32>,
    /// Time the descent from the starting height takes, s (default 2).
    #[arg(long)]
    descend_s: Option<f32>,
    /// Stroke length, mm: `press-stroke`'s amplitude, `cauterize`'s burn, `cut-line`'s line and `snip-line`'s
    /// line of bites (default 10).
    #[arg(long)]
    stroke_mm: Option<f32>,
    /// `grasp-pull`: time at depth before the jaws close, s (default 0.3).
    #[arg(long)]
    settle_s: Option<f32>,
    /// `grasp-pull`: the pull after the jaws close, device frame, mm: x,y,z (default: straight up by the
    /// depth + 5 mm), made over 1 s.
    #[arg(long, value_parser = parse_vec3_mm, allow_hyphen_values = true)]
    pull_mm: Option<[f32; 3]>,
    /// `grasp-pull`: time held after the pull before the jaws open, s (default 2).
    #[arg(long)]
    hold_s: Option<f32>,
    /// The simulated hand waits still at the script's start, jaws open, until this long after the process
    /// started, s (time for the scene to come up over a slow link; devices started together with the same
    /// delay move together).
    #[arg(long)]
    start_delay_s: Option<f64>,
    /// zenoh endpoints and mode. Give the server's TCP and UDP endpoints: one transport with two links,
    /// reliable messages on TCP, poses and forces on UDP (a lost packet never holds later forces).
    #[command(flatten)]
    network: sinew_protocol::cli::NetworkArgs,
    /// Loop rate, Hz.
    #[arg(long, default_value_t = 1000)]
    rate_hz: u32,
    /// Run the device loop as a real-time thread (SCHED_FIFO, locked memory) where the process may (root, or
    /// CAP_SYS_NICE and an RLIMIT_RTPRIO allowance); the first status line says what it was given.
    #[arg(long)]
    realtime: bool,
    /// Pacer spin accuracy, ns (0 = plain sleep).
    #[arg(long, default_value_t = hapticserver::haptic_config::DEFAULT_SPIN_ACCURACY_NS)]
    spin_ns: u32,
    /// Passivity: `observe` (account and report the port's energy) or `control` (also remove force while the
    /// loop is active; blocks energy another surgeon sends through the tissue).
    #[arg(long, value_enum, default_value_t = PassivityArg::Observe)]
    passivity: PassivityArg,
    /// Stop after this many seconds (default: run until killed).
    #[arg(long)]
    duration_s: Option<f64>,
    /// How to render forces: `direct` (the streamed force; right on a LAN), `moderated` (the local model
    /// against the current position every tick; for distant servers) or `auto` (moderated above a 4 ms
    /// round trip, direct below 2.5 ms).
    #[arg(long, default_value = "auto")]
    mode: ModePolicy,
    /// Phase alignment while rendering directly: `on` (default) shifts the loop's phase, in steps of at most
    /// 10 us, until its poses reach the server just before its ticks (one device period of round trip);
    /// `off` leaves the phase alone.
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    phase_align: OnOff,
    /// The pose wait at the server that phase alignment settles at, us (a margin against jitter; below the
    /// loop period).
    #[arg(long, default_value_t = hapticserver::phase_align::DEFAULT_TARGET_WAIT_US)]
    phase_target_us: f32,
    /// Simulated operator: grip (default), light, nominal or firm.
    #[arg(long, default_value = "grip")]
    hand: HandPreset,
    /// Emulated distance on what this role publishes.
    #[command(flatten)]
    emulation: sinew_protocol::cli::EmulationArgs,
    /// Fault drill: make the device loop panic at this tick, as a bug in it would.
    #[arg(long, hide = true)]
    fault_panic_at_tick: Option<u64>,
    /// Mounting rotation of the device, degrees about the scene's fixed x, then y, then z axes: `180,0,0` for
    /// a device mounted upside down (a reach-in display), `90,0,0` for a Touch on a desk (its +y is up) in a
    /// scene whose +z is up. Poses are rotated into the scene, forces back into the device.
    #[arg(long, allow_hyphen_values = true, value_parser = |t: &str| hapticserver::calibration::parse_vec3("--mount-rotation-deg", t))]
    mount_rotation_deg: Option<[f32; 3]>,
    /// Mounting offset, mm, added after the rotation (the scene's device origin is the world file's
    /// `device_origin_in_world_mm` for the tool).
    #[arg(long, allow_hyphen_values = true, value_parser = |t: &str| hapticserver::calibration::parse_vec3("--mount-offset-mm", t))]
    mount_offset_mm: Option<[f32; 3]>,
    /// libHD to open for `--device openhaptics` (default: libHD.so, libHD.so.3.4, libHD.so.3.0 on the
    /// loader's path).
    #[cfg(feature = "openhaptics")]
    #[arg(long)]
    libhd: Option<std::path::PathBuf>,
    /// Device name for `--device openhaptics`, as configured in the vendor's setup tool (default: the
    /// default device).
    #[cfg(feature = "openhaptics")]
    #[arg(long)]
    hd_device: Option<String>,
    /// The trace to play with `--device replay` (written by `--trace-csv`; scene frame, so no mount flags).
    #[arg(long)]
    replay_trace: Option<std::path::PathBuf>,
    /// Write every tick (time, position, velocity, force, mode) to this CSV file when the server stops.
    #[arg(long)]
    trace_csv: Option<std::path::PathBuf>,
}

fn build_device(args: &Args) -> Result<Box<dyn Device>> {
    if args.device != DeviceKind::Replay && args.replay_trace.is_some() {
        bail!("--replay-trace needs --device replay");
    }
    match args.device {
        DeviceKind::Replay => {
            let Some(path) = &args.replay_trace else {
                bail!(
                    "--device replay needs --replay-trace FILE (a hapticserver --trace-csv file)"
                );
            };
            if args.mount_rotation_deg.is_some() || args.mount_offset_mm.is_some() {
                bail!(
                    "a replayed trace is in the scene frame already: drop --mount-rotation-deg/--mount-offset-mm"
                );
            }
            Ok(Box::new(hapticserver::ReplayDevice::from_trace_csv(path)?))
        }
        #[cfg(feature = "openhaptics")]
        DeviceKind::Openhaptics => {
            let device = hapticserver::openhaptics::OpenHapticsDevice::open(
                &hapticserver::openhaptics::OpenHapticsConfig {
                    library: args.libhd.clone(),
                    device_name: args.hd_device.clone(),
                },
            )?;
            tracing::info!(
                "OpenHaptics device `{}` open through {} (peak {} N)",
                device.model().name,
                device.library_path().display(),
                device.model().max_force_n
            );
            Ok(Box::new(device))
        }
        DeviceKind::Sim => {
            let grasp_only = [
                ("--settle-s", args.settle_s.is_some()),
                ("--pull-mm", args.pull_mm.is_some()),
                ("--hold-s", args.hold_s.is_some()),
            ];
            if let Some((flag, _)) = grasp_only
                .iter()
                .find(|(_, given)| *given && args.script != ScriptKind::GraspPull)
            {
                bail!("{flag} is for --script grasp-pull (not {})", args.script);
            }
            if let Some(delay_s) = args.start_delay_s
                && !(0.0..=3600.0).contains(&delay_s)
            {
                bail!("--start-delay-s {delay_s} must be a number of seconds in [0, 3600]");
            }
            let start_at =
                Instant::now() + Duration::from_secs_f64(args.start_delay_s.unwrap_or(0.0));
            let mut options = ScriptOptions::default();
            if let Some(depth_mm) = args.depth_mm {
                options.depth_mm = depth_mm;
            }
            if let Some(at_mm) = args.at_mm {
                options.at_mm = at_mm;
            }
            options.approach_mm = args.approach_mm.unwrap_or(options.approach_mm);
            options.descend_s = args.descend_s.unwrap_or(options.descend_s);
            options.stroke_mm = args.stroke_mm.unwrap_or(options.stroke_mm);
            options.settle_s = args.settle_s.unwrap_or(options.settle_s);
            options.pull_mm = args.pull_mm.or(options.pull_mm);
            options.hold_s = args.hold_s.unwrap_or(options.hold_s);
            let script = args
                .script
                .build(&options)
                .with_context(|| format!("building the `{}` script", args.script))?;
            Ok(Box::new(
                SimDevice::with_params(script, args.hand.params(), sim_device_model())
                    .with_start_at(start_at),
            ))
        }
    }
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .init();
    sinew_protocol::rt::panic_report::install_deferred_backtrace_hook();
    let args = Args::parse();
    if let Some(duration_s) = args.duration_s
        && !(0.0..=1e7).contains(&duration_s)
    {
        bail!("--duration-s {duration_s} must be a number of seconds in [0, 1e7]");
    }

    let mut config = HapticConfig::new(&args.scene, &args.id, build_device(&args)?);
    config.tool = args.tool.clone();
    config.mount = hapticserver::WorldFromDevice::from_degrees(
        args.mount_rotation_deg.unwrap_or([0.0; 3]),
        args.mount_offset_mm.unwrap_or([0.0; 3]),
    )?;
    config.loop_rate_hz = args.rate_hz;
    config.spin_accuracy_ns = args.spin_ns;
    config.realtime = args.realtime;
    config.mode = args.mode;
    config.phase_align = args.phase_align == OnOff::On;
    // Checked by HapticServer::start (below the loop period), which names it.
    config.phase_target_us = args.phase_target_us;
    config.emulation = args.emulation.config().map_err(anyhow::Error::msg)?;
    config.panic_at_tick = args.fault_panic_at_tick;
    if args.trace_csv.is_some() {
        // Up to an hour at 1 kHz would be 3.6 M samples; cap at the run's length (or 10 minutes).
        let seconds = args.duration_s.unwrap_or(600.0).min(3600.0);
        config.trace_ticks = (seconds * f64::from(args.rate_hz)).ceil() as usize + 1000;
    }
    config.passivity = match args.passivity {
        PassivityArg::Observe => hapticserver::PassivityMode::Observe,
        PassivityArg::Control => hapticserver::PassivityMode::Control,
    };
    config.network = args.network.options(NetworkOptions::device_default());
    let mut handle = HapticServer::start(config).with_context(|| {
        format!(
            "starting hapticserver `{}` in scene `{}`",
            args.id, args.scene
        )
    })?;

    // Ctrl-C / SIGTERM: leave the loop and stop through the ramp to zero, never by dropping the motor's force.
    let interrupted = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = interrupted.clone();
    ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::Release))
        .context("installing the Ctrl-C handler")?;

    let started = Instant::now();
    let deadline = args
        .duration_s
        .map(|s| started + Duration::from_secs_f64(s));
    let mut next_status = started + Duration::from_secs(1);
    let mut told_scheduling = false;
    loop {
        let now = Instant::now();
        if !told_scheduling && let Some(grant) = handle.report().realtime {
            println!("device loop: {grant}");
            told_scheduling = true;
        }
        if deadline.is_some_and(|deadline| now >= deadline)
            || interrupted.load(std::sync::atomic::Ordering::Acquire)
        {
            break;
        }
        if !handle.is_running() {
            let why = handle
                .report()
                .loop_failure
                .unwrap_or_else(|| "no reason recorded".to_owned());
            let _ = handle.stop();
            if let Some(backtrace) = sinew_protocol::rt::panic_report::take_deferred_backtrace()
                .filter(|b| b.status() == std::backtrace::BacktraceStatus::Captured)
            {
                eprintln!("stack backtrace of the panic:\n{backtrace}");
            }
            bail!("the device loop of `{}` ended unexpectedly: {why}", args.id);
        }
        if now >= next_status {
            println!("{}", handle.report());
            next_status += Duration::from_secs(1);
        }
        let wake = deadline.map_or(next_status, |deadline| deadline.min(next_status));
        std::thread::sleep(
            wake.saturating_duration_since(Instant::now())
                .min(Duration::from_millis(50)),
        );
    }
    handle.stop().context("stopping the hapticserver")?;
    println!("final: {}", handle.report());
    if let Some(path) = &args.trace_csv {
        let trace = handle.take_trace();
        let mut file = std::io::BufWriter::new(
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
        );
        trace
            .write_csv(&mut file)
            .with_context(|| format!("writing {}", path.display()))?;
        println!(
            "trace: {} ticks written to {}",
            trace.samples().len(),
            path.display()
        );
    }
    Ok(())
}
