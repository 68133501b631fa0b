//! The instructor's debrief (issue "Training sessions"): a recorded two-surgeon session is republished on
//! real zenoh for a viewer to watch, with every force command reproduced and none sent to anyone, and is
//! written out as PNG frames with the instructor's overlay.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use sinew::debrief::{FrameOptions, PublishOptions, publish, write_frames};
use sinew_protocol::network::{NetworkOptions, with_udp_twin};
use sinew_server::node::{ReplayFeed, ServerConfig, ServerError, ServerNode, open_session};
use sinew_server::recording::{Recording, read_recording};
use sinew_server::world::World;
use sinew_testkit::harness::{free_loopback_endpoint, record_two_surgeons, serial, start_viewer};
use sinew_viewer::scene_view::BACKGROUND_RGB;
use zenoh::Wait;

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("sinew-{}-{name}", std::process::id()))
}

fn recorded(name: &str, seconds: f64) -> (PathBuf, Recording, World) {
    let path = temp(name);
    let (summary, _) = record_two_surgeons(&path, Duration::from_secs_f64(seconds)).unwrap();
    assert!(
        summary.error.is_none() && summary.dropped == 0,
        "{summary:?}"
    );
    let recording = read_recording(&path).unwrap();
    let dir = temp(&format!("{name}-world"));
    std::fs::create_dir_all(&dir).unwrap();
    let world = recording.load_world(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    (path, recording, world)
}

#[test]
fn a_published_replay_is_watched_by_a_viewer_and_sends_no_force() {
    let _serial = serial();
    let (path, recording, world) = recorded("debrief-publish.mcap", 1.5);
    let endpoint = free_loopback_endpoint().unwrap();

    // A device listening on the recorded ids must hear nothing from a replay.
    let listener = open_session(&NetworkOptions {
        connect: vec![endpoint.clone()],
        ..NetworkOptions::default()
    })
    .unwrap();
    let forces_heard = Arc::new(AtomicU64::new(0));
    let heard = forces_heard.clone();
    let _forces = listener
        .declare_subscriber("sinew/pad/device/*/force")
        .callback(move |_| {
            heard.fetch_add(1, Ordering::Relaxed);
        })
        .wait()
        .unwrap();

    // ... and it does hear the scene, so the silence above means something.
    let tools_heard = Arc::new(AtomicU64::new(0));
    let heard = tools_heard.clone();
    let _tools = listener
        .declare_subscriber("sinew/pad/tools")
        .callback(move |_| {
            heard.fetch_add(1, Ordering::Relaxed);
        })
        .wait()
        .unwrap();

    let viewer_endpoint = endpoint.clone();
    let watcher = std::thread::spawn(move || {
        // Join while the replay runs, and keep the largest tool force and the contacts seen.
        std::thread::sleep(Duration::from_millis(300));
        let viewer = start_viewer("pad", "debrief-viewer", &viewer_endpoint).unwrap();
        assert!(viewer.wait_for_snapshot(Duration::from_secs(5)));
        let mut peak_force_n = 0.0f32;
        let mut saw_contact = false;
        let mut saw_training = false;
        // Stats come once a second: watch until they carried the touches, or 5 s (the replay's 1.3 s and its
        // linger; a fixed 1.5 s window could hold no stats message at all on a loaded machine).
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while std::time::Instant::now() < deadline
            && !(saw_training && saw_contact && peak_force_n > 0.5)
        {
            std::thread::sleep(Duration::from_millis(10));
            viewer.with_replica(|replica| {
                for tool in &replica.tool_states().tools {
                    let f = tool.force_n.iter().map(|c| c * c).sum::<f32>().sqrt();
                    peak_force_n = peak_force_n.max(f);
                    saw_contact |= tool.in_contact && tool.active;
                }
            });
            if let Some(stats) = viewer.server_stats() {
                saw_training |= stats
                    .devices
                    .iter()
                    .any(|d| d.training.contacts > 0 && d.force_limit_n > 0.0);
            }
        }
        (peak_force_n, saw_contact, saw_training)
    });

    let mut lines = 0;
    let done = publish(
        &recording,
        world,
        &PublishOptions {
            endpoint,
            speed: 1.0,
            // Long enough for a stats message after the last tick (they come once a second).
            linger: Duration::from_millis(1500),
        },
        |_, _| lines += 1,
    )
    .unwrap();
    let (peak_force_n, saw_contact, saw_training) = watcher.join().unwrap();
    println!(
        "published replay: {done:?}; viewer saw peak tool force {peak_force_n:.2} N, contact {saw_contact}, training {saw_training}; forces heard {}",
        forces_heard.load(Ordering::Relaxed)
    );
    assert!(done.finished);
    assert_eq!(done.ticks_done, recording.ticks.len() as u64);
    // Every force the recording holds was compared (each device's from the tick it joined: on a loaded
    // machine a device joins late, and a 1.5 s recording held 526 device-ticks of force where an idle one
    // holds over 2000), and there were enough to mean something (0.2 s of one device at least).
    let recorded_forces = recording.recorded_forces();
    assert!(
        recorded_forces > 200,
        "the recording holds {recorded_forces} forces"
    );
    assert!(
        done.forces_compared >= recorded_forces,
        "{done:?} of {recorded_forces} recorded"
    );
    assert_eq!(done.force_mismatches, 0, "{done:?}");
    assert!(lines >= 1);
    assert!(
        saw_contact && peak_force_n > 0.5,
        "the viewer watched the surgeons press the pad"
    );
    assert!(
        saw_training,
        "the stats carried each surgeon's touches and force limit"
    );
    assert!(
        tools_heard.load(Ordering::Relaxed) > 30,
        "the listener heard {} tool states",
        tools_heard.load(Ordering::Relaxed)
    );
    assert_eq!(
        forces_heard.load(Ordering::Relaxed),
        0,
        "a replay sent force commands"
    );
    let _ = listener.close().wait();
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_replay_refuses_a_bad_speed_or_being_recorded() {
    let world = sinew_testkit::harness::load_shipped_world("pad.toml").unwrap();
    for speed in [0.0, -1.0, f64::NAN, f64::INFINITY, 1000.0] {
        let config = ServerConfig {
            replay: Some(ReplayFeed {
                ticks: Vec::new(),
                speed,
            }),
            ..ServerConfig::default()
        };
        let err = ServerNode::start(world.clone(), config).unwrap_err();
        assert!(
            matches!(err, ServerError::Replay(_)) && err.to_string().contains("speed"),
            "{speed}: {err}"
        );
    }
    let endpoint = free_loopback_endpoint().unwrap();
    let config = ServerConfig {
        network: NetworkOptions {
            listen: with_udp_twin(&endpoint),
            ..NetworkOptions::default()
        },
        replay: Some(ReplayFeed {
            ticks: Vec::new(),
            speed: 1.0,
        }),
        record: Some(temp("never.mcap")),
        ..ServerConfig::default()
    };
    let err = ServerNode::start(world, config).unwrap_err();
    assert!(err.to_string().contains("not recorded again"), "{err}");
    assert!(!temp("never.mcap").exists());
}

#[test]
fn debrief_frames_show_the_session_with_the_overlay() {
    let _serial = serial();
    let (path, recording, world) = recorded("debrief-frames.mcap", 1.5);
    let out = temp("debrief-frames");
    let every = 400;
    let summary = write_frames(
        &recording,
        &world,
        &FrameOptions {
            every_ticks: every,
            out: out.clone(),
            width: 400,
            height: 300,
        },
    )
    .unwrap();
    assert!(summary.outcome.exact(), "{:?}", summary.outcome);
    let expected = recording.ticks.len() as u64 / every;
    assert_eq!(summary.files.len() as u64, expected);
    let images: Vec<image::RgbImage> = summary
        .files
        .iter()
        .map(|f| image::open(f).unwrap().to_rgb8())
        .collect();
    for (file, image) in summary.files.iter().zip(&images) {
        assert_eq!(image.dimensions(), (400, 300), "{}", file.display());
        // The overlay's text in the top-left band.
        let text = (10..60)
            .flat_map(|y| (10..200).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                image
                    .get_pixel(x, y)
                    .0
                    .iter()
                    .zip(BACKGROUND_RGB)
                    .any(|(&c, b)| c.abs_diff(b) > 40)
            })
            .count();
        assert!(text > 200, "{}: {text} text pixels", file.display());
    }
    // The surgeons press and one strokes: the frames are not all alike.
    let changed = images[0]
        .pixels()
        .zip(images[images.len() - 1].pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0).any(|(&x, y)| x.abs_diff(y) > 12))
        .count();
    assert!(
        changed > 500,
        "the first and last frames differ in {changed} pixels"
    );
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_file(&path);
}
