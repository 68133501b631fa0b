//! Fault drills (issue "Safe under faults", item 1): a 1 kHz thread panics while a hand holds its probe in the
//! tissue, and nothing lives on as a zombie.
//! - The server's sim thread: the server sends the device an explicit zero (the device's rate limit makes it a
//!   ramp, well before the 50 ms silence rule would), then the process exits non-zero, naming the panic.
//! - A hapticserver's device loop: the motor's last force is ramped to zero over the safety ramp time, written
//!   straight to the device, then the process exits non-zero, naming the panic.
//!
//! Real processes and sessions: the role binaries are made to panic by their hidden fault-drill flag
//! `--fault-panic-at-tick`; the other side runs in-process, over zenoh on loopback.

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code

use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use hapticserver::{Device, DeviceError, DeviceModel, DeviceReading, HapticServer, SimDevice};
use sinew_protocol::network::udp_twin;
use sinew_testkit::drill::max_force_step;
use sinew_testkit::harness::{
    Pacing, free_loopback_endpoint, pad_device_config, spawn_pad_server_process, start_pad_server,
    wait_until,
};
use sinew_testkit::netns::{role_binary, wait_output};
use sinew_testkit::scenarios::press;

fn norm(f: [f32; 3]) -> f32 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

#[test]
fn a_panicking_sim_thread_zeroes_its_devices_and_the_server_exits_non_zero() {
    let endpoint = free_loopback_endpoint().unwrap();
    // 4 s of ticks: the device joins, presses (1 s) and holds before the panic.
    let server =
        spawn_pad_server_process(&endpoint, &["--fault-panic-at-tick", "4000"], true).unwrap();
    let device = SimDevice::new(press(4.0, 1.0));
    let mut config = pad_device_config("left", Box::new(device), &endpoint);
    config.trace_ticks = 60_000;
    let mut device = HapticServer::start(config).expect("starting the hapticserver");

    let output = wait_output(server, Duration::from_secs(40)).expect("the server never exited");
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    // Let the device run on past the panic for a while, then stop it.
    let ticks_then = device.report().ticks;
    assert!(wait_until(Duration::from_secs(20), || {
        device.report().ticks >= ticks_then + 300
    }));
    device.stop().unwrap();
    let report = device.report();
    let trace = device.take_trace();
    let samples = trace.samples();

    assert!(
        !output.status.success(),
        "the server exited successfully after its sim thread panicked: {}\n{stdout}",
        output.status
    );
    assert!(
        stderr.contains("the simulation thread panicked")
            && stderr.contains("fault drill: panic at tick 4000")
            && stderr.contains("1 device(s) sent an explicit zero force"),
        "the exit does not say what happened:\n{stderr}"
    );

    // The hold before the panic, then zero reached by the server's explicit command (not by the silence
    // rule), stepping no more than the safety rate limit allows, and zero for good.
    let held = samples
        .iter()
        .rposition(|s| norm(s.force_n) > 0.3)
        .unwrap_or_else(|| panic!("never held the probe in the tissue: {report:?}"));
    let zero = held
        + samples[held..]
            .iter()
            .position(|s| norm(s.force_n) == 0.0)
            .expect("the force never reached zero");
    assert!(
        !samples[zero].stale,
        "zero came from the silence rule, not from the server's explicit zero ({:.3} s)",
        samples[zero].t_s
    );
    let steps = max_force_step(samples, samples[held].t_s + 1e-6, samples[zero].t_s + 1e-6);
    // 200 N/s at 1 kHz, with room for a tick that came late.
    assert!(steps <= 0.45, "the force fell {steps:.3} N in one tick");
    if let Some(s) = samples[zero..].iter().find(|s| norm(s.force_n) != 0.0) {
        panic!(
            "{:?} N rendered at {:.3} s after the zero",
            s.force_n, s.t_s
        );
    }
    assert!(
        samples.len() - zero > 200,
        "too little trace after the zero"
    );
    println!(
        "held {:.2} N until {:.3} s, zero at {:.3} s by the server's command; server said:\n{}",
        norm(samples[held].force_n),
        samples[held].t_s,
        samples[zero].t_s,
        stderr
            .lines()
            .filter(|l| !l.starts_with(' '))
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// The simulated device, with every force written to its motor recorded.
struct RecordingDevice {
    inner: SimDevice,
    writes: Arc<Mutex<Vec<[f32; 3]>>>,
}

impl Device for RecordingDevice {
    fn model(&self) -> DeviceModel {
        self.inner.model()
    }

    fn read(&mut self, dt_s: f32) -> Result<DeviceReading, DeviceError> {
        self.inner.read(dt_s)
    }

    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError> {
        if let Ok(mut writes) = self.writes.lock() {
            writes.push(force_n);
        }
        self.inner.write_force(force_n)
    }
}

#[test]
fn a_panicking_device_loop_ramps_its_motor_to_zero_and_says_why() {
    let (endpoint, mut server) = start_pad_server(Pacing::Sleep).unwrap();
    let writes = Arc::new(Mutex::new(Vec::with_capacity(10_000)));
    let device = RecordingDevice {
        inner: SimDevice::new(press(4.0, 1.0)),
        writes: writes.clone(),
    };
    let mut config = pad_device_config("left", Box::new(device), &endpoint);
    config.panic_at_tick = Some(3000);
    let mut handle = HapticServer::start(config).unwrap();
    assert!(
        wait_until(Duration::from_secs(30), || !handle.is_running()),
        "the device loop never stopped"
    );
    let report = handle.report();
    let _ = handle.stop();
    server.stop();
    let failure = report.loop_failure.clone().unwrap_or_default();
    assert!(
        failure.contains("the device loop panicked")
            && failure.contains("fault drill: panic at tick 3000"),
        "the report does not say what happened: {report:?}"
    );
    let writes = writes.lock().unwrap().clone();
    assert!(writes.len() >= 3000, "{} writes", writes.len());
    // Ticks 1-3000 wrote one force each (the 3000th held the probe in the tissue); the panic came before
    // tick 3001, and every write after it is the ramp.
    let held = norm(writes[2999]);
    assert!(
        held > 0.2,
        "not pressing when the loop panicked: {held:.3} N"
    );
    let ramp: Vec<f32> = writes[3000..].iter().map(|f| norm(*f)).collect();
    assert_eq!(
        ramp.last().copied(),
        Some(0.0),
        "the last force written is not zero"
    );
    assert!(
        ramp.len() <= 30,
        "the ramp took {} writes (the safety ramp is 20 ms)",
        ramp.len()
    );
    let mut previous = held;
    for (k, f) in ramp.iter().enumerate() {
        assert!(
            *f <= previous && previous - f <= 0.1 * held + 1e-6,
            "write {k} of the ramp: {f:.4} N after {previous:.4} N (held {held:.3} N)"
        );
        previous = *f;
    }
    println!(
        "held {held:.3} N; ramp {:?}; {failure}",
        ramp.iter().map(|f| format!("{f:.3}")).collect::<Vec<_>>()
    );
}

#[test]
fn the_hapticserver_process_exits_non_zero_when_its_loop_panics() {
    let (endpoint, mut server) = start_pad_server(Pacing::Sleep).unwrap();
    let child = Command::new(role_binary("hapticserver").unwrap())
        .args(["--id", "left", "--script", "press", "--duration-s", "20"])
        .args([
            "--connect",
            &endpoint,
            "--connect",
            &udp_twin(&endpoint).unwrap(),
        ])
        .args(["--fault-panic-at-tick", "1500"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let output = wait_output(child, Duration::from_secs(30)).unwrap();
    server.stop();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success(),
        "exited {}: {stderr}",
        output.status
    );
    assert!(
        stderr.contains("the device loop of `left` ended unexpectedly: the device loop panicked")
            && stderr.contains("fault drill: panic at tick 1500"),
        "{stderr}"
    );
}
