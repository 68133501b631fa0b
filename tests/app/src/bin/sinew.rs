//! `sinew`: the launcher. `sinew demo` runs a server, two simulated surgeons and a viewer in one go.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Parser, Subcommand};
use sinew::demo::{DemoOptions, run_demo};
use sinew_protocol::network::DEFAULT_ENDPOINT;

/// Sinew: networked haptic surgical simulation.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Server + two simulated hapticservers + a viewer over zenoh on loopback, with live figures.
    Demo {
        /// World file.
        #[arg(long, default_value = "worlds/pad.toml")]
        world: PathBuf,
        /// How long to run, seconds.
        #[arg(long, default_value_t = 10.0)]
        duration_s: f64,
        /// The server's TCP endpoint; it also listens on the same port over UDP, where the devices send poses
        /// and get forces (multilink), and the viewer connects to TCP alone.
        #[arg(long, default_value = DEFAULT_ENDPOINT)]
        listen: String,
        /// Open the viewer window (needs a display).
        #[arg(long)]
        window: bool,
        /// Write a PNG of the viewer's replica at the end.
        #[arg(long)]
        png: Option<PathBuf>,
        /// Emulate a distant server: this round trip (ms) between the devices and the server, half on the
        /// poses and half on the forces. Feel (or read in the summary) what distance does to each mode.
        #[arg(long, default_value_t = 0.0)]
        rtt_ms: f64,
        /// How the devices render forces: direct, moderated or auto.
        #[arg(long, default_value = "auto")]
        mode: hapticserver::ModePolicy,
        /// The simulated surgeons' hand: grip (default), light, nominal or firm. The light hand is the
        /// hardest for stability: try `--rtt-ms 100 --hand light` with `--mode direct`, then `moderated`.
        #[arg(long, default_value = "grip")]
        hand: hapticserver::HandPreset,
        /// Record the session into this MCAP file (then `sinew replay FILE`, `sinew report FILE`).
        #[arg(long)]
        record: Option<PathBuf>,
        /// Run the sim tick and the device loops as real-time threads (SCHED_FIFO, locked memory) where the
        /// process may; the summary says what they were given.
        #[arg(long)]
        realtime: bool,
        /// Threads for the server's tissue passes instead of the world's `[sim] threads` (default: every core
        /// but two); the same results on any count.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=64))]
        tissue_threads: Option<u16>,
    },
    /// Re-run a recording (`sinew-server --record FILE`) through the simulation on virtual time and check that
    /// every force command and the final tissue come out bit for bit as recorded. With `--publish`, replay it
    /// on zenoh for viewers to watch (the instructor's debrief); with `--png-every N`, write a frame with the
    /// instructor's overlay every N ticks.
    Replay {
        /// The recording (MCAP).
        file: PathBuf,
        /// Republish the session on zenoh as its scene, paced at `--speed`, for any viewer
        /// (`sinew-viewer --scene SCENE --connect ENDPOINT`). No force is sent to any device.
        #[arg(long, conflicts_with = "png_every")]
        publish: bool,
        /// Simulated seconds per wall second when publishing (1 = as recorded).
        #[arg(long, default_value_t = 1.0, requires = "publish")]
        speed: f64,
        /// Where the published replay listens (TCP, and UDP on the same port).
        #[arg(long, default_value = DEFAULT_ENDPOINT, requires = "publish")]
        listen: String,
        /// Keep publishing the final state this long after the replay ends, seconds.
        #[arg(long, default_value_t = 2.0, requires = "publish")]
        linger_s: f64,
        /// Write a PNG with the instructor's overlay every N ticks (offline; no zenoh).
        #[arg(long)]
        png_every: Option<u64>,
        /// Where the frames go (default: the recording's name with `-frames`).
        #[arg(long, requires = "png_every")]
        out: Option<PathBuf>,
        /// Frame width, pixels.
        #[arg(long, default_value_t = 1024, requires = "png_every")]
        width: u32,
        /// Frame height, pixels.
        #[arg(long, default_value_t = 768, requires = "png_every")]
        height: u32,
    },
    /// Play one surgeon's recorded hand into a live scene as a device (a hapticserver with no motor): the
    /// poses it sent, on its own clock, then its last position held until `--hold-s` passes. Start a server on
    /// the recording's world first (`sinew-server --world ...`).
    PlayDevice {
        /// The recording (MCAP, `sinew-server --record` or `sinew demo --record`).
        file: PathBuf,
        /// Which device of the recording to play (its id, e.g. `left`).
        #[arg(long)]
        device: String,
        /// How long to hold the last position after the stream ends, seconds.
        #[arg(long, default_value_t = 1.0)]
        hold_s: f64,
        /// How the device renders forces (they go nowhere; its report says what they were).
        #[arg(long, default_value = "auto")]
        mode: hapticserver::ModePolicy,
        /// zenoh endpoints and mode (as the hapticserver takes them).
        #[command(flatten)]
        network: sinew_protocol::cli::NetworkArgs,
    },
    /// Make a scene's certificates for mutual TLS: one per role (server, observer, and a device per --device)
    /// in OUT/SCENE/, each naming its role and scene as its common name (`device-left@pad`), signed by the
    /// lab's CA (OUT/ca.pem: made the first time, reused for each scene added); the site router's certificate
    /// and its zenohd.json5, rewritten with the access rules of every scene in OUT. Give each role its three
    /// files (--tls-ca OUT/ca.pem --tls-cert OUT/SCENE/ROLE.pem --tls-key OUT/SCENE/ROLE-key.pem); keep
    /// ca-key.pem offline.
    Certs {
        /// The lab's folder (created; an existing CA is reused, never replaced).
        #[arg(long, default_value = "sinew-certs")]
        out: PathBuf,
        /// A device id to make a certificate for (repeatable).
        #[arg(long = "device", value_name = "ID", default_values_t = ["left".to_owned(), "right".to_owned()])]
        devices: Vec<String>,
        /// Another name or address the roles are reached at, beside localhost and the loopback addresses
        /// (repeatable): a site's DNS name or IP.
        #[arg(long = "host", value_name = "NAME")]
        hosts: Vec<String>,
        /// The scene to issue certificates for (one lab's router can carry several: run again with another).
        #[arg(long, default_value = "pad")]
        scene: String,
        /// Where the lab's zenohd listens (repeatable; QUIC endpoints).
        #[arg(long = "router-listen", value_name = "ENDPOINT", default_values_t = ["quic/0.0.0.0:7447".to_owned()])]
        router_listen: Vec<String>,
    },
    /// What a recording holds: its metadata, messages per topic, ticks, presence changes, damage. Reads
    /// `sinew-recorder`'s files too.
    Info {
        /// The recording (MCAP).
        file: PathBuf,
    },
    /// A training report of a recording: replays it with the training layer watching and writes
    /// report.json (metrics, time per skill state, events per participant), force.png, path_top.png,
    /// states.png and summary.txt into a directory.
    Report {
        /// The recording (MCAP).
        file: PathBuf,
        /// Where to write the report (default: the recording's name with `-report`).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

fn main() -> anyhow::Result<()> {
    // The log, and the counter of what access control refuses (a demo's server reports it in its stats).
    sinew_server::node::access_refusals::init_log_with_counter("warn");
    match Args::parse().command {
        Command::Demo {
            world,
            duration_s,
            listen,
            window,
            png,
            rtt_ms,
            mode,
            hand,
            record,
            realtime,
            tissue_threads,
        } => {
            anyhow::ensure!(
                duration_s.is_finite() && duration_s > 0.0,
                "--duration-s must be positive"
            );
            run_demo(&DemoOptions {
                world,
                endpoint: listen,
                duration: Duration::from_secs_f64(duration_s),
                window,
                png,
                rtt_ms,
                mode,
                hand,
                record,
                realtime,
                tissue_threads: tissue_threads.map(usize::from),
            })?;
        }
        Command::Replay {
            file,
            publish,
            speed,
            listen,
            linger_s,
            png_every,
            out,
            width,
            height,
        } => {
            if publish {
                anyhow::ensure!(
                    linger_s.is_finite() && linger_s >= 0.0,
                    "--linger-s must be zero or positive"
                );
                publish_replay(&file, speed, listen, Duration::from_secs_f64(linger_s))?;
            } else if let Some(every_ticks) = png_every {
                let options = sinew::debrief::FrameOptions {
                    every_ticks,
                    out: out.unwrap_or_else(|| sinew::debrief::default_frames_dir(&file)),
                    width,
                    height,
                };
                replay_frames(&file, &options)?;
            } else {
                replay(&file)?;
            }
        }
        Command::PlayDevice {
            file,
            device,
            hold_s,
            mode,
            network,
        } => play_device(&file, &device, hold_s, mode, &network)?,
        Command::Certs {
            out,
            devices,
            hosts,
            scene,
            router_listen,
        } => {
            let certs = sinew::certs::make_lab_certs(&out, &scene, &devices, &hosts)?;
            let router = sinew::certs::write_router_config(&out, &router_listen)?;
            let scenes: Vec<String> = sinew::certs::lab_scenes(&out)?
                .into_iter()
                .map(|s| s.scene)
                .collect();
            println!(
                "CA: {} (its key ca-key.pem signs new certificates: keep it offline)",
                certs.ca.display()
            );
            for (name, files) in &certs.roles {
                println!(
                    "{name} of `{scene}`: --tls-ca {} --tls-cert {} --tls-key {}",
                    files.ca.display(),
                    files.cert.display(),
                    files.key.display()
                );
            }
            println!(
                "router (scenes {}, listening on {}): zenohd -c {}",
                scenes.join(", "),
                router_listen.join(", "),
                router.display()
            );
        }
        Command::Info { file } => info(&file)?,
        Command::Report { file, out } => {
            let out = out.unwrap_or_else(|| {
                let stem = file
                    .file_stem()
                    .map_or("session".into(), |s| s.to_string_lossy().into_owned());
                file.with_file_name(format!("{stem}-report"))
            });
            let report = sinew::report::write_report(&file, &out)?;
            print!("{}", sinew::report::summary(&report));
            println!("report written to {}", out.display());
        }
    }
    Ok(())
}

fn info(file: &std::path::Path) -> anyhow::Result<()> {
    let recording = sinew_server::recording::survey(file)?;
    println!(
        "{}: a Sinew recording of kind `{}`",
        file.display(),
        recording.kind()
    );
    for (key, value) in &recording.metadata {
        println!("  {key}: {value}");
    }
    for (name, data) in &recording.files {
        println!("  attached: {name} ({} bytes)", data.len());
    }
    println!(
        "  ticks: {}{}",
        recording.ticks.len(),
        if recording.final_state.is_some() {
            ", with the final tissue state"
        } else {
            ""
        }
    );
    println!("  messages per topic:");
    for (topic, count) in &recording.topic_counts {
        println!("    {topic}: {count}");
    }
    for (time_ns, key, joined) in &recording.presence {
        println!(
            "  {:.3} s: {key} {}",
            *time_ns as f64 * 1e-9,
            if *joined { "joined" } else { "left" }
        );
    }
    if let Some(damage) = &recording.damage {
        println!("  damaged: {damage}");
    }
    Ok(())
}

/// [`sinew::play_device::read_with_world`], warning about damage (what precedes it is used).
fn read_with_world(
    file: &std::path::Path,
) -> anyhow::Result<(
    sinew_server::recording::Recording,
    sinew_server::world::World,
)> {
    let (recording, world) = sinew::play_device::read_with_world(file)?;
    if let Some(damage) = &recording.damage {
        eprintln!(
            "warning: {}: {damage}; replaying what precedes it",
            file.display()
        );
    }
    Ok((recording, world))
}

fn publish_replay(
    file: &std::path::Path,
    speed: f64,
    listen: String,
    linger: Duration,
) -> anyhow::Result<()> {
    let (recording, world) = read_with_world(file)?;
    println!(
        "replaying {} as scene `{}` on {listen} at {speed}x: watch with `sinew-viewer --scene {} --connect {listen}`",
        file.display(),
        world.scene,
        world.scene
    );
    let options = sinew::debrief::PublishOptions {
        endpoint: listen,
        speed,
        linger,
    };
    let done = sinew::debrief::publish(&recording, world, &options, |p, stats| {
        let score = stats
            .and_then(|s| s.exercise.as_ref())
            .map(|e| format!(", exercise score {:.0}", e.score))
            .unwrap_or_default();
        println!(
            "tick {}/{}: {} force commands compared, {} differing{score}",
            p.ticks_done, p.ticks_total, p.forces_compared, p.force_mismatches
        );
    })?;
    anyhow::ensure!(
        done.force_mismatches == 0 && done.ticks_done == done.ticks_total,
        "the published replay differed from the recording ({} of {} commands, {} of {} ticks re-run)",
        done.force_mismatches,
        done.forces_compared,
        done.ticks_done,
        done.ticks_total
    );
    println!("published replay finished: every force command as recorded");
    Ok(())
}

fn play_device(
    file: &std::path::Path,
    device: &str,
    hold_s: f64,
    mode: hapticserver::ModePolicy,
    network: &sinew_protocol::cli::NetworkArgs,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        hold_s.is_finite() && (0.0..=3600.0).contains(&hold_s),
        "--hold-s must be in [0, 3600] seconds"
    );
    let network = network.options(sinew_protocol::network::NetworkOptions::device_default());
    let mut playing = sinew::play_device::play(file, device, network, mode)?;
    println!(
        "playing `{device}` from {} ({:.1} s of poses)",
        file.display(),
        playing.duration_s
    );
    let started = std::time::Instant::now();
    let mut next_status = Duration::from_secs(1);
    let mut finished_at = None;
    loop {
        std::thread::sleep(Duration::from_millis(20));
        if !playing.handle.is_running() {
            let why = playing.handle.report().loop_failure.unwrap_or_default();
            anyhow::bail!("the replay device's loop ended unexpectedly: {why}");
        }
        let elapsed = started.elapsed();
        if elapsed >= next_status {
            println!("{}", playing.handle.report());
            next_status += Duration::from_secs(1);
        }
        if finished_at.is_none() && playing.finished.load(std::sync::atomic::Ordering::Acquire) {
            finished_at = Some(elapsed);
        }
        if finished_at.is_some_and(|at| (elapsed - at).as_secs_f64() >= hold_s) {
            break;
        }
    }
    playing.handle.stop()?;
    println!("final: {}", playing.handle.report());
    Ok(())
}

fn replay_frames(
    file: &std::path::Path,
    options: &sinew::debrief::FrameOptions,
) -> anyhow::Result<()> {
    let (recording, world) = read_with_world(file)?;
    let summary = sinew::debrief::write_frames(&recording, &world, options)?;
    println!(
        "{} frames of {} ticks written to {} ({}x{}, one every {} ticks)",
        summary.files.len(),
        summary.outcome.ticks,
        options.out.display(),
        options.width,
        options.height,
        options.every_ticks
    );
    anyhow::ensure!(
        summary.outcome.exact(),
        "the replay is not bit-exact ({} force commands differ): the frames may not show the session",
        summary.outcome.force_mismatches
    );
    Ok(())
}

fn replay(file: &std::path::Path) -> anyhow::Result<()> {
    use anyhow::Context;
    let (recording, world) = read_with_world(file)?;
    let started = std::time::Instant::now();
    let outcome = sinew_server::recording::replay(&recording, &world)
        .with_context(|| format!("building the recorded world of {}", file.display()))?;
    let wall_s = started.elapsed().as_secs_f64();
    println!(
        "{}: scene `{}`, {} ticks ({:.3} s simulated) replayed in {:.3} s ({:.1}x real time)",
        file.display(),
        world.scene,
        outcome.ticks,
        outcome.sim_s,
        wall_s,
        outcome.sim_s / wall_s.max(1e-9)
    );
    println!(
        "force commands compared: {}, differing: {}",
        outcome.forces_compared, outcome.force_mismatches
    );
    if let Some(first) = &outcome.first_mismatch {
        println!("first difference: {first}");
    }
    if let Some(tick) = outcome.stopped_at_gap {
        println!("the recording is missing tick {tick} (dropped or damaged): replay stopped there");
    }
    if outcome.final_compared {
        println!(
            "final tissue: {} coordinates differ",
            outcome.final_mismatches
        );
    } else {
        println!("final tissue: not compared (the recording has no final state for this tick)");
    }
    anyhow::ensure!(
        outcome.exact(),
        "the replay is not bit-exact: the simulation is not deterministic for this recording"
    );
    println!("bit-exact: every force command and the final tissue are identical");
    Ok(())
}
