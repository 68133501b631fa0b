//! Recording and bit-exact replay (issue "Training sessions"): a two-surgeon session over real zenoh on
//! loopback is recorded by the server, then re-run from the file through the simulation on virtual time;
//! every force command and the final tissue must come out identical to the bit. Damaged files give errors or
//! a replay of what precedes the damage, never a panic; an unwritable path is refused at start.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::path::PathBuf;
use std::time::Duration;

use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_server::node::{ServerConfig, ServerError, ServerNode, SimReport};
use sinew_server::recording::{ReadError, ReplayOutcome, read_recording, replay, replay_observed};
use sinew_server::training::{MetricsConfig, SessionObserver};
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, load_shipped_world, record_two_surgeons, serial,
    start_sim_device, surgeon_scripts, wait_until,
};
use sinew_testkit::netns::role_binary;

/// Byte offset of the first chunk's compressed records (MCAP: magic, then records of opcode u8, length u64;
/// a chunk (0x06) has start, end, uncompressed size (u64 each), CRC (u32), compression (u32-length string),
/// records length (u64), then the records).
fn first_chunk_records(bytes: &[u8]) -> usize {
    let mut at = 8;
    loop {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if bytes[at] == 0x06 {
            let body = at + 9;
            let name_len =
                u32::from_le_bytes(bytes[body + 28..body + 32].try_into().unwrap()) as usize;
            return body + 32 + name_len + 8;
        }
        at += 9 + len;
    }
}

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("sinew-{}-{name}", std::process::id()))
}

fn config(endpoint: &str, record: Option<PathBuf>) -> ServerConfig {
    ServerConfig {
        network: NetworkOptions {
            listen: with_udp_twin(endpoint),
            ..NetworkOptions::default()
        },
        spin_native_accuracy_ns: 0,
        record,
        ..ServerConfig::default()
    }
}

/// Record about three seconds of the demo's two surgeons; returns the file and the sim thread's final report.
fn record_session(name: &str) -> (PathBuf, SimReport) {
    let path = temp(name);
    let (summary, report) = record_two_surgeons(&path, Duration::from_secs(3)).unwrap();
    println!("recorded: {summary:?}");
    assert!(summary.error.is_none(), "{summary:?}");
    assert!(summary.final_state);
    assert_eq!(summary.dropped, 0, "the queue dropped ticks: {summary:?}");
    assert!(summary.ticks > 2000, "{summary:?}");
    (path, report)
}

#[test]
fn a_recorded_two_surgeon_session_replays_bit_for_bit_and_damage_is_told() {
    let _serial = serial();
    let (path, live) = record_session("session.mcap");
    let size = std::fs::metadata(&path).unwrap().len();
    let recording = read_recording(&path).unwrap();
    assert!(recording.damage.is_none(), "{:?}", recording.damage);
    assert_eq!(recording.files[0].0, "pad.toml");
    assert!(
        recording
            .files
            .iter()
            .any(|(name, _)| name == "meshes/pad.obj")
    );
    let dir = temp("replay-world");
    std::fs::create_dir_all(&dir).unwrap();
    let world = recording.load_world(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);

    let started = std::time::Instant::now();
    let outcome = replay(&recording, &world).unwrap();
    let wall_s = started.elapsed().as_secs_f64();
    println!(
        "replay: {outcome:?}; {size} bytes for {:.2} s ({:.0} kB/min); replayed at {:.1}x real time",
        outcome.sim_s,
        size as f64 / 1e3 / (outcome.sim_s / 60.0),
        outcome.sim_s / wall_s
    );
    assert!(outcome.forces_compared > 2000, "{outcome:?}");
    let exact_bytes: usize = recording
        .ticks
        .iter()
        .map(|t| postcard::to_allocvec(t).unwrap().len())
        .sum();
    println!(
        "exact channel: {exact_bytes} bytes uncompressed ({} per tick)",
        exact_bytes / recording.ticks.len()
    );
    // The session really touched the tissue: some recorded force is well above zero.
    let strongest = recording
        .ticks
        .iter()
        .flat_map(|t| t.devices.iter())
        .filter_map(|d| d.force)
        .map(|f| f.force_n.iter().map(|c| c * c).sum::<f32>().sqrt())
        .fold(0.0f32, f32::max);
    assert!(
        strongest > 0.5,
        "the strongest recorded force is {strongest} N"
    );
    assert!(outcome.exact(), "{outcome:?}");
    check_report(&path, &outcome, &live);

    // The live session's training events are in the file, and the replay derives the same ones.
    let mut observer =
        SessionObserver::new(world.tools.len(), MetricsConfig::new(1.0 / world.tick_hz));
    let mut replayed_events = Vec::new();
    replay_observed(&recording, &world, |view| {
        observer.observe(
            view,
            |e| replayed_events.push((e.tick, e.tool, e.kind.name().to_owned())),
            |_, _| {},
        );
    })
    .unwrap();
    println!("events: {:?}", recording.events);
    for tool in 0..2u8 {
        assert!(
            recording
                .events
                .iter()
                .any(|(_, t, kind)| *t == tool && kind == "contact_begin"),
            "tool {tool} has no contact in {:?}",
            recording.events
        );
    }
    assert_eq!(recording.events, replayed_events);

    // A replay on a different world diverges, and says so: the comparison can fail.
    let mut stiffer = world.clone();
    stiffer.objects[0].material.stiffness_n_per_mm *= 1.01;
    let diverged = replay(&recording, &stiffer).unwrap();
    assert!(!diverged.exact());
    assert!(diverged.force_mismatches > 0 && diverged.first_mismatch.is_some());

    // Truncated to 60%: what precedes the cut replays exactly; the damage is named.
    let bytes = std::fs::read(&path).unwrap();
    let cut = temp("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let partial = read_recording(&cut).unwrap();
    let damage = partial.damage.clone().expect("the cut is reported");
    println!("truncated: {damage}");
    assert!(partial.ticks.len() > 100 && partial.ticks.len() < recording.ticks.len());
    let salvaged = replay(&partial, &world).unwrap();
    assert_eq!(salvaged.force_mismatches, 0, "{salvaged:?}");
    assert!(!salvaged.final_compared);

    // 64 scrambled bytes in the middle: an error, or a salvage that replays exactly, never a panic. The middle
    // may fall in a chunk (its CRC fails: damage, a shorter salvage) or in the message index records between
    // chunks, which reading does not use (then every tick reads, and the whole replay is still exact).
    let mut corrupt = bytes.clone();
    let at = corrupt.len() / 2;
    for b in &mut corrupt[at..at + 64] {
        *b ^= 0x5a;
    }
    let corrupt_path = temp("corrupt.mcap");
    std::fs::write(&corrupt_path, &corrupt).unwrap();
    match read_recording(&corrupt_path) {
        Ok(r) => {
            let outcome = replay(&r, &world).unwrap();
            println!("corrupt: damage {:?}, {outcome:?}", r.damage);
            assert_eq!(outcome.force_mismatches, 0);
            if r.damage.is_none() && r.ticks.len() == recording.ticks.len() {
                assert!(outcome.exact(), "undamaged reading, inexact replay");
            }
        }
        Err(e) => println!("corrupt: {e}"),
    }
    // A scrambled chunk is damage, found by its CRC: scramble inside the first chunk's compressed records.
    let chunk_at = first_chunk_records(&bytes);
    let mut in_chunk = bytes.clone();
    for b in &mut in_chunk[chunk_at + 100..chunk_at + 164] {
        *b ^= 0x5a;
    }
    std::fs::write(&corrupt_path, &in_chunk).unwrap();
    match read_recording(&corrupt_path) {
        Ok(r) => {
            let damage = r.damage.clone().expect("a scrambled chunk is damage");
            println!("scrambled chunk: {damage}");
            assert!(r.ticks.len() < recording.ticks.len());
        }
        Err(e) => println!("scrambled chunk: {e}"),
    }

    // Not a recording at all.
    let text = temp("not.mcap");
    std::fs::write(&text, b"scene = \"pad\"\n").unwrap();
    let err = read_recording(&text).unwrap_err();
    assert!(matches!(err, ReadError::NotARecording { .. }), "{err}");
    assert!(err.to_string().contains("not.mcap"), "{err}");
    let refused = std::process::Command::new(role_binary("sinew").unwrap())
        .arg("report")
        .arg(&text)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && stderr.contains("not.mcap"),
        "{stderr}"
    );

    for file in [&path, &cut, &corrupt_path, &text] {
        let _ = std::fs::remove_file(file);
    }
}

#[test]
fn an_unwritable_recording_path_is_refused_before_anything_starts() {
    let _serial = serial();
    let endpoint = free_loopback_endpoint().unwrap();
    let path = PathBuf::from("/nonexistent-dir/session.mcap");
    let err = ServerNode::start(
        load_shipped_world("pad.toml").unwrap(),
        config(&endpoint, Some(path)),
    )
    .unwrap_err();
    assert!(matches!(err, ServerError::Record(_)), "{err}");
    assert!(
        err.to_string().contains("/nonexistent-dir/session.mcap"),
        "{err}"
    );
    // Nothing was left listening: a server can start on the same endpoint at once.
    let mut server = ServerNode::start(
        load_shipped_world("pad.toml").unwrap(),
        config(&endpoint, None),
    )
    .unwrap();
    server.stop();
}

/// `sinew report` on the recording: the files are written, the figures have each participant's colour, the
/// metrics describe the scripted session (left presses and strokes, right presses and holds), and the time per
/// skill state adds up to the session.
#[test]
fn a_disk_that_fills_stops_the_recording_not_the_session() {
    let _serial = serial();
    let endpoint = free_loopback_endpoint().unwrap();
    // A device that is full from the start: refused at start, by name.
    let err = ServerNode::start(
        load_shipped_world("pad.toml").unwrap(),
        config(&endpoint, Some(PathBuf::from("/dev/full"))),
    )
    .unwrap_err();
    assert!(matches!(err, ServerError::Record(_)), "{err}");
    assert!(err.to_string().contains("/dev/full"), "{err}");

    // A disk that fills during the session: a 512 kB tmpfs (the world's files take 210 kB of it). Needs root,
    // as the network-namespace lab does.
    let dir = temp("full-disk");
    std::fs::create_dir_all(&dir).unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=512k", "tmpfs"])
        .arg(&dir)
        .status()
        .unwrap();
    assert!(
        mounted.success(),
        "mounting a small tmpfs needs root (CI runs as root)"
    );
    let path = dir.join("session.mcap");
    let mut server = ServerNode::start(
        load_shipped_world("pad.toml").unwrap(),
        config(&endpoint, Some(path)),
    )
    .unwrap();
    let (left_script, _) = surgeon_scripts();
    let left = start_sim_device("pad", "left", left_script, &endpoint, Pacing::Sleep).unwrap();
    assert!(wait_until(Duration::from_secs(10), || server
        .stats()
        .devices[0]
        .active));
    // 300 kB of recording fills in about a second at this rate; then the session must go on for another two.
    std::thread::sleep(Duration::from_secs(2));
    let before = server.stats();
    std::thread::sleep(Duration::from_secs(1));
    let after = server.stats();
    assert!(
        after.ticks > before.ticks + 500,
        "the session stopped ticking"
    );
    assert!(
        after.devices[0].forces_sent > before.devices[0].forces_sent + 300,
        "the device stopped getting forces"
    );
    assert!(server.failure().is_none());
    drop(left);
    server.stop();
    let _ = std::process::Command::new("umount").arg(&dir).status();
    let _ = std::fs::remove_dir_all(&dir);
    let summary = server.record_summary().cloned().unwrap();
    println!("recording to a filling disk: {summary:?}");
    assert!(summary.ticks > 100, "{summary:?}");
    let error = summary.error.expect("the failed write is reported");
    assert!(error.contains("space"), "{error}");
}

fn check_report(path: &std::path::Path, outcome: &ReplayOutcome, live: &SimReport) {
    let out = temp("report");
    let run = std::process::Command::new(role_binary("sinew").unwrap())
        .arg("report")
        .arg(path)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    println!("{stdout}");
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["bit_exact"], true);
    assert_eq!(json["ticks"], outcome.ticks);
    let people = json["participants"].as_array().unwrap();
    assert_eq!(people.len(), 2);
    let metric = |p: usize, key: &str| people[p]["metrics"][key].as_f64().unwrap();
    for (p, device) in ["left", "right"].iter().enumerate() {
        assert_eq!(people[p]["device"], *device);
        assert!(metric(p, "contacts") >= 1.0, "{device} never touched");
        assert!(metric(p, "contact_time_s") > 1.0, "{device}");
        let peak = metric(p, "peak_force_n");
        assert!(peak > 0.5 && peak <= 3.3 + 1e-4, "{device}: peak {peak}");
        let in_states: f64 = people[p]["time_in_state_s"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_f64().unwrap())
            .sum();
        assert!(
            (in_states - outcome.sim_s).abs() < 1e-6,
            "{device}: {in_states} s in states"
        );
        // The live training view the server kept while the session ran is what the replay measured, exactly.
        let seen = live.devices[p].training;
        println!("{device} live: {seen:?}");
        assert_eq!(seen.contacts as f64, metric(p, "contacts"), "{device}");
        assert_eq!(seen.contact_time_s, metric(p, "contact_time_s"), "{device}");
        assert_eq!(seen.path_length_mm, metric(p, "path_length_mm"), "{device}");
        assert_eq!(seen.peak_force_n, metric(p, "peak_force_n"), "{device}");
    }
    // Left strokes +-8 mm along x while right holds still: left's tip travels much further.
    assert!(
        metric(0, "path_length_mm") > 2.0 * metric(1, "path_length_mm"),
        "left {} mm, right {} mm",
        metric(0, "path_length_mm"),
        metric(1, "path_length_mm")
    );
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(
        summary.contains("left (") && summary.contains("right ("),
        "{summary}"
    );
    // Each figure has both participants' colours (left blue, right red).
    for figure in ["force.png", "path_top.png", "states.png"] {
        let image = image::open(out.join(figure)).unwrap().to_rgb8();
        let has = |rgb: [u8; 3]| image.pixels().filter(|p| p.0 == rgb).count();
        let (blue, red) = (has([31, 119, 180]), has([214, 39, 40]));
        assert!(
            blue > 50 && red > 50,
            "{figure}: {blue} blue, {red} red pixels"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}
