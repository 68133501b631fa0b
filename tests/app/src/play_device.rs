//! `sinew play-device`: a surgeon's recorded hand, played into a live scene as a device.
//!
//! Owns: reading a session recording together with its world ([`read_with_world`]), pulling one device's pose
//! stream out of it ([`recorded_hand`]: each pose once, timed by the device's own clock, in the device
//! frame) and serving it through a real hapticserver ([`play`]). The device has no motor: the forces it is
//! sent go nowhere, and its report says what they were.
//!
//! Must not: change the recording, or drive a device id the recording does not hold.

use std::path::Path;

use anyhow::Context;
use hapticserver::{HapticConfig, HapticHandle, HapticServer, ReplayDevice, ReplaySample};
use sinew_protocol::network::NetworkOptions;
use sinew_server::recording::{Recording, read_recording};
use sinew_server::world::World;

/// Read a session recording and load the world it carries (written out to a scratch folder and removed).
pub fn read_with_world(file: &Path) -> anyhow::Result<(Recording, World)> {
    let recording = read_recording(file)?;
    let dir = std::env::temp_dir().join(format!(
        "sinew-recorded-world-{}-{}",
        std::process::id(),
        fastrand::u64(..)
    ));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let world = recording.load_world(&dir);
    let _ = std::fs::remove_dir_all(&dir);
    Ok((recording, world?))
}

/// The poses device `device_id` drove its tool with in `recording` (the ticks it was usable on), each once
/// (by sequence number), timed by the device's clock (s), in the device frame.
pub fn recorded_hand(
    recording: &Recording,
    world: &World,
    device_id: &str,
) -> anyhow::Result<Vec<ReplaySample>> {
    let Some(tool) = world.tools.iter().position(|t| t.device_id == device_id) else {
        let ids: Vec<&str> = world.tools.iter().map(|t| t.device_id.as_str()).collect();
        anyhow::bail!(
            "{}: no device `{device_id}` in this recording (it holds {})",
            recording.path.display(),
            ids.join(", ")
        );
    };
    let mut samples = Vec::new();
    let mut last_seq = None;
    for tick in &recording.ticks {
        // Only poses that drove the tool: a pose the server did not act on (a device refused, or leaving:
        // a hapticserver shutting down lets its hand sink as it stops rendering) would leave the played hand
        // somewhere the recorded one never pressed.
        let Some(pose) = tick
            .devices
            .get(tool)
            .filter(|d| d.usable)
            .and_then(|d| d.pose)
        else {
            continue;
        };
        if last_seq.is_some_and(|seq| pose.seq <= seq) {
            continue;
        }
        last_seq = Some(pose.seq);
        samples.push(ReplaySample {
            t_s: pose.device_time_ns as f64 * 1e-9,
            reading: hapticserver::DeviceReading {
                position_mm: pose.position_mm,
                orientation_xyzw: pose.orientation_xyzw,
                linear_velocity_mm_s: pose.linear_velocity_mm_s,
                buttons: pose.buttons,
                jaw_angle_rad: pose.jaw_angle_rad,
            },
        });
    }
    anyhow::ensure!(
        !samples.is_empty(),
        "{}: device `{device_id}` drove its tool with no pose in this recording",
        recording.path.display()
    );
    Ok(samples)
}

/// A recorded hand being played: the hapticserver and the flag raised after its last pose.
#[derive(Debug)]
pub struct Playing {
    /// The hapticserver serving it.
    pub handle: HapticHandle,
    /// Raised once the last pose has been played (the device then holds it).
    pub finished: std::sync::Arc<std::sync::atomic::AtomicBool>,
    /// Length of the stream, s.
    pub duration_s: f64,
}

/// Play device `device_id` of the recording `file` into the scene the recording was made in, as a
/// hapticserver on `network`, rendering as `mode` says.
pub fn play(
    file: &Path,
    device_id: &str,
    network: NetworkOptions,
    mode: hapticserver::ModePolicy,
) -> anyhow::Result<Playing> {
    let (recording, world) = read_with_world(file)?;
    let samples = recorded_hand(&recording, &world, device_id)?;
    let device = ReplayDevice::new(&file.display().to_string(), samples)?;
    let finished = device.finished();
    let duration_s = device.duration_s();
    let mut config = HapticConfig::new(&world.scene, device_id, Box::new(device));
    config.network = network;
    config.mode = mode;
    let handle = HapticServer::start(config)
        .with_context(|| format!("starting the replay device `{device_id}`"))?;
    Ok(Playing {
        handle,
        finished,
        duration_s,
    })
}
