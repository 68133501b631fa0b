//! Regression tests for the defects a hand-written client (Python, from the source alone) found on the wire
//! (issue "Labs and sites"). Each client here is raw zenoh plus the codec, as WIRE.md describes it: its own
//! instance id, an optional presence token, a hello, poses at 1 kHz, a force subscriber.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::{DevicePose, ForceCommand, InstanceId, ParticipantHello, Role, decode_from};
use sinew_server::node::{ServerHandle, open_session};
use sinew_testkit::harness::{Pacing, serial, start_pad_server, wait_until};
use zenoh::Wait;

/// A raw client for device `left` of the pad, pressing 3 mm (device z = 1 mm) while it runs.
struct RawDevice {
    instance: InstanceId,
    stop: Arc<AtomicBool>,
    forces: Arc<AtomicU64>,
    /// Poses published.
    sent: Arc<AtomicU64>,
    last_force: Arc<Mutex<Option<ForceCommand>>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RawDevice {
    fn start(endpoint: &str, tool: &str, token: bool) -> Self {
        Self::start_numbering(endpoint, tool, token, |n| n)
    }

    /// [`Self::start`], sending its `n`-th pose (from 1) with `seq = seq_of(n)`.
    fn start_numbering(endpoint: &str, tool: &str, token: bool, seq_of: fn(u64) -> u64) -> Self {
        let instance = InstanceId::random();
        let session = open_session(&NetworkOptions {
            connect: vec![endpoint.to_owned()],
            ..NetworkOptions::default()
        })
        .unwrap();
        let forces = Arc::new(AtomicU64::new(0));
        let last_force = Arc::new(Mutex::new(None));
        let (count, last) = (forces.clone(), last_force.clone());
        let subscriber = session
            .declare_subscriber("sinew/pad/device/left/force")
            .callback(move |sample| {
                if let Ok((_, command)) = decode_from::<ForceCommand>(&sample.payload().to_bytes())
                    && command.device_instance == instance.0
                {
                    count.fetch_add(1, Ordering::Relaxed);
                    *last.lock().unwrap() = Some(command);
                }
            })
            .wait()
            .unwrap();
        let token = token.then(|| {
            session
                .liveliness()
                .declare_token("sinew/pad/presence/haptic/left")
                .wait()
                .unwrap()
        });
        let hello = encode_to_vec(
            instance,
            &ParticipantHello {
                participant_id: "left".into(),
                role: Role::Haptic,
                device_model: "raw".into(),
                max_force_n: 3.3,
                tool: tool.into(),
            },
        );
        let stop = Arc::new(AtomicBool::new(false));
        let running = stop.clone();
        let sent = Arc::new(AtomicU64::new(0));
        let published = sent.clone();
        let thread = std::thread::spawn(move || {
            let _subscriber = subscriber;
            let _token = token;
            let poses = session
                .declare_publisher("sinew/pad/device/left/pose")
                .wait()
                .unwrap();
            let start = Instant::now();
            let mut last_hello = None::<Instant>;
            let mut seq = 0;
            while !running.load(Ordering::Acquire) {
                if last_hello.is_none_or(|t| t.elapsed() >= Duration::from_millis(500)) {
                    session
                        .put("sinew/pad/hello/haptic/left", hello.clone())
                        .wait()
                        .unwrap();
                    last_hello = Some(Instant::now());
                }
                seq += 1;
                let pose = DevicePose {
                    seq: seq_of(seq),
                    device_time_ns: start.elapsed().as_nanos() as u64,
                    position_mm: [0.0, 0.0, 1.0],
                    orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
                    ..DevicePose::default()
                };
                poses.put(encode_to_vec(instance, &pose)).wait().unwrap();
                published.fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(1));
            }
            let _ = session.close().wait();
        });
        Self {
            instance,
            stop,
            forces,
            sent,
            last_force,
            thread: Some(thread),
        }
    }

    fn forces(&self) -> u64 {
        self.forces.load(Ordering::Relaxed)
    }

    fn pressing_force_n(&self) -> f32 {
        self.last_force
            .lock()
            .unwrap()
            .map_or(0.0, |c| c.force_n[2])
    }

    fn stop(mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(thread) = self.thread.take() {
            thread.join().unwrap();
        }
    }
}

fn left(server: &ServerHandle) -> sinew_protocol::DeviceStats {
    server
        .stats()
        .devices
        .into_iter()
        .find(|d| d.device_id == "left")
        .unwrap()
}

/// Wait until `device` has been pressing long enough to feel the pad.
fn feels_the_pad(device: &RawDevice) -> bool {
    wait_until(Duration::from_secs(10), || {
        device.forces() > 200 && device.pressing_force_n() > 0.2
    })
}

#[test]
fn a_device_that_rejoins_without_a_token_gets_forces() {
    let _serial = serial();
    let (endpoint, mut server) = start_pad_server(Pacing::Sleep).unwrap();
    let first = RawDevice::start(&endpoint, "", true);
    assert!(feels_the_pad(&first), "the first device never felt the pad");
    first.stop();
    // A new run of the device, without a presence token this time (a driver that forgot it).
    let again = RawDevice::start(&endpoint, "", false);
    assert!(
        feels_the_pad(&again),
        "a device rejoining without a token got {} forces ({} N): {:?}",
        again.forces(),
        again.pressing_force_n(),
        left(&server)
    );
    assert_eq!(left(&server).holder_instance, again.instance.0);
    again.stop();
    server.stop();
}

#[test]
fn a_wrong_tool_hello_does_not_block_a_later_correct_device() {
    let _serial = serial();
    let (endpoint, mut server) = start_pad_server(Pacing::Sleep).unwrap();
    let wrong = RawDevice::start(&endpoint, "scalpel", true);
    assert!(wait_until(Duration::from_secs(10), || {
        let stats = server.stats();
        stats.rejected.wrong_tool > 100
    }));
    let stats = left(&server);
    assert_eq!(stats.wrong_tool_instance, wrong.instance.0);
    assert_eq!(stats.wrong_tool_asked, "scalpel");
    assert_eq!(wrong.forces(), 0, "a refused device got forces");
    wrong.stop();
    let right = RawDevice::start(&endpoint, "left-probe", true);
    assert!(
        feels_the_pad(&right),
        "the correct device after a wrong-tool one got {} forces: {:?}",
        right.forces(),
        left(&server)
    );
    right.stop();
    server.stop();
}

#[test]
fn device_stats_active_means_a_tool_driven_by_fresh_poses() {
    let _serial = serial();
    let (endpoint, mut server) = start_pad_server(Pacing::Sleep).unwrap();
    assert!(!left(&server).active, "active before any pose");
    let device = RawDevice::start(&endpoint, "", true);
    assert!(feels_the_pad(&device));
    assert!(left(&server).active);
    device.stop();
    // Its token went with it: released at once, so inactive within the report's 100-tick refresh.
    assert!(
        wait_until(Duration::from_secs(2), || !left(&server).active),
        "still active after the device left: {:?}",
        left(&server)
    );
    server.stop();
}

/// WIRE.md, "Sequence numbers" and DeviceStats: the server never checks `seq`. A device whose poses count
/// down is answered (each command echoes the lower `seq`), presses the pad, and nothing is counted as a reject;
/// `poses_received` goes on counting across the instances that hold the id (it is never reset).
#[test]
fn poses_counting_down_are_answered_and_refused_nowhere_and_poses_received_spans_instances() {
    let _serial = serial();
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    let down = RawDevice::start_numbering(&endpoint, "left-probe", true, |n| 1_000_000 - n);
    assert!(feels_the_pad(&down), "a device counting down got no force");
    let echoed = down
        .last_force
        .lock()
        .unwrap()
        .map(|c| c.echo_pose_seq)
        .unwrap();
    assert!(echoed < 1_000_000 && echoed > 900_000, "echoed {echoed}");
    assert_eq!(
        server.stats().rejected,
        Default::default(),
        "a reject was counted"
    );
    down.stop();
    assert!(wait_until(Duration::from_secs(5), || !left(&server).active));
    let first = left(&server).poses_received;
    assert!(first > 100, "{first} poses received");

    let next = RawDevice::start(&endpoint, "left-probe", true);
    assert!(feels_the_pad(&next), "the next instance got no force");
    let sent = next.sent.clone();
    next.stop();
    let sent = sent.load(Ordering::Relaxed);
    // The stats are published once a second: wait for the count to settle. A count that restarted with the
    // new instance would end at most at what it sent.
    let mut last = 0;
    assert!(wait_until(Duration::from_secs(5), || {
        std::thread::sleep(Duration::from_millis(1200));
        let now = left(&server).poses_received;
        let settled = now == last;
        last = now;
        settled
    }));
    assert!(
        last > sent + first / 2,
        "poses_received restarted with the new instance: {first}, then {last} after it sent {sent}"
    );
}
