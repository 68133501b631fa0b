//! What the system benches (`tests/benches/`) share: their `--name value` arguments, microseconds from a
//! histogram, an encoded pose's size, and raw zenoh ping-pong (the baseline every round trip is a ratio to).
//!
//! Owns: [`arg`], [`us`], [`encoded_pose_len`], [`ping_pong`], [`round_trips_since`]. Must not: print tables (each bench has its
//! own).

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sinew_protocol::DevicePose;
use sinew_protocol::codec::encode_to_vec;
use sinew_protocol::network::NetworkOptions;
use sinew_protocol::rt::{LatencyHistogram, Pacer};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

/// The number after `name` on the command line, or `default`. Panics on a value that is not a number (a
/// bench's own flag, given by hand).
pub fn arg(name: &str, default: f64) -> f64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map_or(default, |s| {
            s.parse()
                .unwrap_or_else(|_| panic!("{name} takes a number, got {s}"))
        })
}

/// Percentile `p` of `h`, microseconds.
pub fn us(h: &LatencyHistogram, p: f64) -> f64 {
    h.percentile_ns(p) as f64 / 1000.0
}

/// The size of an encoded pose (a typical one: a large sequence number and device time, a round trip).
pub fn encoded_pose_len() -> usize {
    encode_to_vec(
        sinew_protocol::InstanceId(1),
        &DevicePose {
            seq: 123_456,
            device_time_ns: 12_345_678_901,
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            round_trip_us: 1500,
            ..DevicePose::default()
        },
    )
    .len()
}

/// Raw zenoh ping-pong at 1 kHz for `seconds`: session `a` publishes `payload_len` bytes on `ping_key`,
/// session `b` echoes them on `pong_key` (express, dropped under congestion, as poses and forces are). The
/// round trips, after `settle` for the declarations to travel (longer through a router).
pub fn ping_pong(
    seconds: f64,
    a: &NetworkOptions,
    b: &NetworkOptions,
    keys: (&str, &str),
    payload_len: usize,
    settle: Duration,
) -> anyhow::Result<LatencyHistogram> {
    let (ping_key, pong_key) = (keys.0.to_owned(), keys.1.to_owned());
    let zenoh_error = |e: zenoh::Error| anyhow::anyhow!("{e}");
    let a = sinew_server::node::open_session(a).map_err(zenoh_error)?;
    let b = sinew_server::node::open_session(b).map_err(zenoh_error)?;
    let pong = b
        .declare_publisher(pong_key.clone())
        .congestion_control(CongestionControl::Drop)
        .express(true)
        .wait()
        .map_err(zenoh_error)?;
    let _echo = b
        .declare_subscriber(ping_key.clone())
        .callback(move |sample| {
            let _ = pong.put(sample.payload().to_bytes().as_ref()).wait();
        })
        .wait()
        .map_err(zenoh_error)?;
    let start = Instant::now();
    let histogram = Arc::new(Mutex::new(LatencyHistogram::new()));
    let h = histogram.clone();
    let _receiver = a
        .declare_subscriber(pong_key)
        .callback(move |sample| {
            let bytes = sample.payload().to_bytes();
            if let Some(sent) = bytes.get(..8).and_then(|b| <[u8; 8]>::try_from(b).ok()) {
                let now_ns = start.elapsed().as_nanos() as u64;
                if let Ok(mut h) = h.lock() {
                    h.record_ns(now_ns.saturating_sub(u64::from_le_bytes(sent)));
                }
            }
        })
        .wait()
        .map_err(zenoh_error)?;
    let ping = a
        .declare_publisher(ping_key)
        .congestion_control(CongestionControl::Drop)
        .express(true)
        .wait()
        .map_err(zenoh_error)?;
    std::thread::sleep(settle);
    let lock_error = |_| anyhow::anyhow!("the ping-pong histogram's lock was poisoned");
    histogram.lock().map_err(lock_error)?.reset();
    let mut pacer = Pacer::new(Duration::from_millis(1), 100_000);
    let mut payload = vec![0u8; payload_len.max(8)];
    let until = Instant::now() + Duration::from_secs_f64(seconds);
    while Instant::now() < until {
        pacer.wait();
        payload[..8].copy_from_slice(&(start.elapsed().as_nanos() as u64).to_le_bytes());
        ping.put(payload.as_slice()).wait().map_err(zenoh_error)?;
    }
    std::thread::sleep(Duration::from_millis(50));
    Ok(histogram.lock().map_err(lock_error)?.clone())
}

/// Per device, its id and its rendered and wire round trips between two reports (`settled`, then `after`, in
/// the same device order).
pub fn round_trips_since(
    after: &[hapticserver::HapticReport],
    settled: &[hapticserver::HapticReport],
) -> Vec<(String, LatencyHistogram, LatencyHistogram)> {
    after
        .iter()
        .zip(settled)
        .map(|(a, s)| {
            (
                a.device_id.clone(),
                a.round_trip.since(&s.round_trip),
                a.wire_round_trip.since(&s.wire_round_trip),
            )
        })
        .collect()
}
