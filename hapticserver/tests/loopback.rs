//! A hapticserver with a simulated device against a real zenoh peer session on loopback: poses stream with
//! increasing seq, echoed forces are rendered (after the rate limit) and measured as round trips, the hello
//! announces the device, and silence ramps the force to exactly zero.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::net::TcpListener;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use hapticserver::{HandScript, HapticConfig, HapticReport, HapticServer, SimDevice};
use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::keys::SceneKeys;
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::LatestValue;
use sinew_protocol::{DevicePose, ForceCommand, ParticipantHello, Role, decode};
use zenoh::Wait;

const TIMEOUT: Duration = Duration::from_secs(10);

fn free_endpoint() -> anyhow::Result<String> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    let port = listener.local_addr()?.port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

fn open(network: &NetworkOptions) -> anyhow::Result<zenoh::Session> {
    let mut config = zenoh::Config::default();
    for (key, value) in network.config_entries() {
        config
            .insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("{key} = {value}: {e}"))?;
    }
    zenoh::open(config)
        .wait()
        .map_err(|e| anyhow::anyhow!("open: {e}"))
}

/// Poll `check` every 5 ms until it holds or TIMEOUT passes; `tick` runs on every poll (e.g. publishing).
fn wait_until(what: &str, mut tick: impl FnMut(), mut check: impl FnMut() -> bool) {
    let deadline = Instant::now() + TIMEOUT;
    while !check() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        tick();
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn norm(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

#[test]
fn hapticserver_streams_poses_renders_echoed_forces_and_ramps_down_on_silence() {
    let endpoint = free_endpoint().unwrap();
    let test_session = open(&NetworkOptions {
        listen: vec![endpoint.clone()],
        ..NetworkOptions::default()
    })
    .unwrap();
    let keys = SceneKeys::new("looptest").unwrap();

    // Poses: keep the newest, count them, count any seq that does not increase.
    let latest_pose = Arc::new(LatestValue::<DevicePose>::new());
    let poses = Arc::new(AtomicU64::new(0));
    let seq_faults = Arc::new(AtomicU64::new(0));
    let last_seq = Arc::new(AtomicU64::new(0));
    let _pose_sub = {
        let (latest_pose, poses, seq_faults, last_seq) = (
            latest_pose.clone(),
            poses.clone(),
            seq_faults.clone(),
            last_seq.clone(),
        );
        test_session
            .declare_subscriber(keys.device_pose("left").unwrap())
            .callback(move |sample: zenoh::sample::Sample| {
                let pose = decode::<DevicePose>(&sample.payload().to_bytes()).unwrap();
                if pose.seq <= last_seq.swap(pose.seq, Ordering::SeqCst) {
                    seq_faults.fetch_add(1, Ordering::SeqCst);
                }
                poses.fetch_add(1, Ordering::SeqCst);
                latest_pose.store(pose);
            })
            .wait()
            .unwrap()
    };
    let hello = Arc::new(LatestValue::<(f32, bool)>::new());
    let _hello_sub = {
        let hello = hello.clone();
        test_session
            .declare_subscriber(keys.hello(Role::Haptic, "left").unwrap())
            .callback(move |sample: zenoh::sample::Sample| {
                let msg = decode::<ParticipantHello>(&sample.payload().to_bytes()).unwrap();
                let as_expected = msg.participant_id == "left"
                    && msg.role == Role::Haptic
                    && msg.device_model == "sim-hand"
                    && msg.tool == "probe";
                hello.store((msg.max_force_n, as_expected));
            })
            .wait()
            .unwrap()
    };

    let device = SimDevice::new(HandScript::Hold {
        position_mm: [0.0; 3],
    });
    let mut config = HapticConfig::new("looptest", "left", Box::new(device));
    config.tool = "probe".to_owned();
    config.network = NetworkOptions {
        connect: vec![endpoint],
        ..NetworkOptions::default()
    };
    config.spin_accuracy_ns = 0;
    let mut handle = HapticServer::start(config).unwrap();
    assert!(handle.is_running());

    // (a) Poses arrive with increasing seq; the hello announces the device.
    wait_until("100 poses", || {}, || poses.load(Ordering::SeqCst) >= 100);
    assert_eq!(
        seq_faults.load(Ordering::SeqCst),
        0,
        "pose seq went backwards"
    );
    wait_until("the hello", || {}, || hello.peek().is_some());
    let (max_force_n, hello_ok) = hello.peek().unwrap();
    assert!(hello_ok && (max_force_n - 3.3).abs() < 1e-6);

    // (b) Echoed force commands are rendered and their round trips measured.
    let force_publisher = test_session
        .declare_publisher(keys.device_force("left").unwrap())
        .congestion_control(zenoh::qos::CongestionControl::Drop)
        .express(true)
        .wait()
        .unwrap();
    let commanded = [0.0, 0.0, 1.0];
    let mut command_seq = 0u64;
    let mut answered_seq = 0u64;
    let last_sent = std::cell::Cell::new(Instant::now());
    let mut answer = || {
        if let Some(pose) = latest_pose.peek()
            && pose.seq != answered_seq
        {
            answered_seq = pose.seq;
            command_seq += 1;
            let command = ForceCommand {
                seq: command_seq,
                echo_pose_seq: pose.seq,
                echo_device_time_ns: pose.device_time_ns,
                force_n: commanded,
                in_contact: true,
                device_instance: handle.report().instance.0,
                ..ForceCommand::default()
            };
            force_publisher
                .put(encode_to_vec(sinew_protocol::InstanceId(1), &command))
                .wait()
                .unwrap();
            last_sent.set(Instant::now());
        }
    };
    let rendered = |r: &HapticReport| {
        let f = r.last_rendered_force_n;
        norm([
            f[0] - commanded[0],
            f[1] - commanded[1],
            f[2] - commanded[2],
        ]) < 1e-4
    };
    wait_until(
        "the commanded force to be rendered with a round trip measured",
        &mut answer,
        || {
            let r = handle.report();
            rendered(&r) && r.round_trip.count() > 0 && r.last_round_trip_us > 0
        },
    );
    // The 1 N upward push moves the held stylus up toward 1 N / 0.4 N/mm = 2.5 mm.
    wait_until("the force to push the stylus up", &mut answer, || {
        handle.report().last_position_mm[2] > 1.5
    });
    let report = handle.report();
    assert!(report.max_rendered_force_n <= 3.3 + 1e-5);
    assert!(report.forces_received > 0);
    assert_eq!(report.decode_rejects.total(), 0);
    assert!(rendered(&report), "{report}");

    // (c) Silence: the force ramps to exactly zero (stale 50 ms after the last arrival, zero 20 ms later).
    wait_until(
        "the force to ramp to zero",
        || {},
        || {
            let r = handle.report();
            r.last_rendered_force_n == [0.0; 3] && r.safety.stale_events >= 1
        },
    );
    // The last command arrived after it was sent, so the force held at least 50 ms past the send.
    assert!(
        last_sent.get().elapsed() >= Duration::from_millis(50),
        "force dropped before the commands went stale"
    );

    handle.stop().unwrap();
    let final_report = handle.report();
    assert!(!final_report.running);
    assert!(!handle.is_running());
    assert_eq!(final_report.last_rendered_force_n, [0.0; 3]);
    let poses_at_stop = poses.load(Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(100));
    assert!(
        poses.load(Ordering::SeqCst) <= poses_at_stop + 1,
        "poses after stop"
    );
}

#[test]
fn bad_ids_and_rates_are_refused_before_opening_anything() {
    let device = || {
        Box::new(SimDevice::new(HandScript::Hold {
            position_mm: [0.0; 3],
        }))
    };
    let err = HapticServer::start(HapticConfig::new("pad", "a/b", device())).unwrap_err();
    assert!(err.to_string().contains("a/b"), "{err}");
    let mut config = HapticConfig::new("pad", "left", device());
    config.loop_rate_hz = 0;
    assert!(HapticServer::start(config).is_err());
}
