//! The OpenHaptics backend against a fake libHD (tests/fake_libhd/fake_hd.c, built here with the system C
//! compiler): the same calls, constants and servo thread a real libHD has, and a log of every force the
//! "motors" rendered. The force-safety rules are checked on that log: clamp to the device's peak, a limited
//! rate of change, a ramp to zero when the server goes quiet and when the hapticserver's own loop stops,
//! nothing non-finite; and faults and calibration keep the motors at zero. Untested on hardware.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly
#![allow(unsafe_code)] // the fake's test controls are C functions

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use hapticserver::openhaptics::{OpenHapticsConfig, OpenHapticsDevice};
use hapticserver::{Device, DeviceError, HapticServer};
use sinew_testkit::harness::{
    Pacing, pad_device_config, serial, start_pad_server, wait_device_active, wait_until,
};

const HD_DEVICE_FAULT: u32 = 0x0300;
const HD_CALIBRATION_OK: u32 = 0x5000;
const HD_CALIBRATION_NEEDS_UPDATE: u32 = 0x5001;
const HD_CALIBRATION_NEEDS_MANUAL_INPUT: u32 = 0x5002;
const HD_CALIBRATION_AUTO: i32 = 2;
const HD_CALIBRATION_INKWELL: i32 = 4;
/// The servo follower's and the hapticserver's rate limit, 200 N/s, per 1 ms servo tick.
const MAX_STEP_N: f64 = 0.2 + 1e-9;

/// Build the fake once per test binary.
fn fake_library() -> &'static Path {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("sinew-fake-libhd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("libHD.so");
        let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("fake_libhd/fake_hd.c");
        let status = std::process::Command::new("cc")
            .args([
                "-shared", "-fPIC", "-O2", "-pthread", "-Wall", "-Werror", "-o",
            ])
            .arg(&out)
            .arg(&source)
            .arg("-lm")
            .status()
            .expect("running cc (the fake libHD is C)");
        assert!(status.success(), "building the fake libHD failed");
        out
    })
}

/// The fake's test controls.
struct Fake {
    library: libloading::Library,
}

impl Fake {
    fn open() -> Self {
        let library = unsafe { libloading::Library::new(fake_library()) }.unwrap();
        let fake = Self { library };
        fake.call0("fakehd_reset");
        fake
    }
    fn call0(&self, name: &str) {
        let f: libloading::Symbol<unsafe extern "C" fn()> =
            unsafe { self.library.get(name.as_bytes()) }.unwrap();
        unsafe { f() }
    }
    fn set_position(&self, p: [f64; 3]) {
        let f: libloading::Symbol<unsafe extern "C" fn(f64, f64, f64)> =
            unsafe { self.library.get(b"fakehd_set_position") }.unwrap();
        unsafe { f(p[0], p[1], p[2]) }
    }
    fn set_buttons(&self, b: i32) {
        let f: libloading::Symbol<unsafe extern "C" fn(i32)> =
            unsafe { self.library.get(b"fakehd_set_buttons") }.unwrap();
        unsafe { f(b) }
    }
    fn set_nominal_max_force(&self, n: f64) {
        let f: libloading::Symbol<unsafe extern "C" fn(f64)> =
            unsafe { self.library.get(b"fakehd_set_nominal_max_force") }.unwrap();
        unsafe { f(n) }
    }
    fn set_calibration(&self, status: u32, styles: i32) {
        let f: libloading::Symbol<unsafe extern "C" fn(u32, i32)> =
            unsafe { self.library.get(b"fakehd_set_calibration") }.unwrap();
        unsafe { f(status, styles) }
    }
    fn inject_servo_error(&self, code: u32) {
        let f: libloading::Symbol<unsafe extern "C" fn(u32)> =
            unsafe { self.library.get(b"fakehd_inject_servo_error") }.unwrap();
        unsafe { f(code) }
    }
    fn count(&self, name: &str) -> u64 {
        let f: libloading::Symbol<unsafe extern "C" fn() -> u64> =
            unsafe { self.library.get(name.as_bytes()) }.unwrap();
        unsafe { f() }
    }
    fn flag(&self, name: &str) -> bool {
        let f: libloading::Symbol<unsafe extern "C" fn() -> i32> =
            unsafe { self.library.get(name.as_bytes()) }.unwrap();
        unsafe { f() != 0 }
    }
    /// Every force the motors rendered, one per servo tick, oldest first.
    fn force_log(&self) -> Vec<[f64; 3]> {
        let f: libloading::Symbol<unsafe extern "C" fn(*mut f64, u64) -> u64> =
            unsafe { self.library.get(b"fakehd_force_log") }.unwrap();
        let mut flat = vec![0.0f64; 3 * 200_000];
        let n = unsafe { f(flat.as_mut_ptr(), 200_000) } as usize;
        flat[..3 * n]
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect()
    }
}

fn open_device() -> OpenHapticsDevice {
    OpenHapticsDevice::open(&OpenHapticsConfig {
        library: Some(fake_library().to_owned()),
        device_name: None,
    })
    .unwrap()
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The safety rules every rendered force obeys: finite, within `max_n`, changing by at most 0.2 N per tick.
fn check_log(log: &[[f64; 3]], max_n: f64) {
    let mut previous = [0.0; 3];
    for (tick, f) in log.iter().enumerate() {
        assert!(f.iter().all(|c| c.is_finite()), "tick {tick}: {f:?}");
        assert!(
            norm(*f) <= max_n + 1e-9,
            "tick {tick}: {f:?} above {max_n} N"
        );
        let step = norm([f[0] - previous[0], f[1] - previous[1], f[2] - previous[2]]);
        assert!(
            step <= MAX_STEP_N,
            "tick {tick}: {previous:?} -> {f:?}, a step of {step} N"
        );
        previous = *f;
    }
}

/// Write `force` every millisecond for `duration` (as the hapticserver loop would).
fn command_for(device: &mut OpenHapticsDevice, force: [f32; 3], duration: Duration) {
    let started = Instant::now();
    while started.elapsed() < duration {
        let _ = device.read(0.001);
        let _ = device.write_force(force);
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn the_backend_reads_the_stylus_in_the_drivers_units_and_renders_zero_before_any_command() {
    let _serial = serial();
    let fake = Fake::open();
    fake.set_position([12.5, -3.0, 40.0]);
    fake.set_buttons(1);
    let mut device = open_device();
    let model = device.model();
    assert_eq!(model.name, "openhaptics:Fake Touch");
    assert!((model.max_force_n - 3.3).abs() < 1e-6);
    assert_eq!(model.workspace_min_mm, [-80.0, -60.0, -35.0]);
    assert!(fake.flag("fakehd_force_output_enabled") && fake.flag("fakehd_scheduler_running"));
    assert!(wait_until(Duration::from_secs(2), || device
        .read(0.001)
        .is_ok()));
    let reading = device.read(0.001).unwrap();
    assert_eq!(reading.position_mm, [12.5, -3.0, 40.0]);
    assert_eq!(reading.buttons, 1);
    assert_eq!(reading.orientation_xyzw, [0.0, 0.0, 0.0, 1.0]);
    std::thread::sleep(Duration::from_millis(50));
    let log = fake.force_log();
    assert!(log.len() > 20, "{} servo ticks", log.len());
    assert!(
        log.iter().all(|f| *f == [0.0; 3]),
        "a force before any command"
    );
    drop(device);
    assert!(!fake.flag("fakehd_initialized") && !fake.flag("fakehd_scheduler_running"));
    // The library refuses a second open while one is held; the error says so.
    let _held = open_device();
    let err = OpenHapticsDevice::open(&OpenHapticsConfig {
        library: Some(fake_library().to_owned()),
        device_name: None,
    })
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("hdInitDevice") && err.contains("0x0301"),
        "{err}"
    );
}

#[test]
fn the_servo_loop_clamps_limits_the_rate_and_ramps_to_zero_by_itself_when_the_loop_stops_writing() {
    let _serial = serial();
    let fake = Fake::open();
    fake.set_nominal_max_force(1.0);
    let mut device = open_device();
    // 2.5 N asked of a 1 N device: the motors ramp up at 200 N/s and stop at 1 N.
    command_for(&mut device, [0.0, 0.0, 2.5], Duration::from_millis(150));
    let held = fake.force_log().len();
    // The hapticserver's loop stops (a stall or a crash): nothing is written any more.
    std::thread::sleep(Duration::from_millis(100));
    let log = fake.force_log();
    check_log(&log, 1.0);
    assert!(
        log[..held].iter().any(|f| (f[2] - 1.0).abs() < 1e-9),
        "never reached the 1 N clamp"
    );
    let last = log.last().unwrap();
    assert_eq!(
        *last, [0.0; 3],
        "still rendering {last:?} 100 ms after the last command"
    );
    // Held at most 20 ms (the stale limit) plus a 5 ms ramp, not dropped in one step.
    let zero_at = log.iter().rposition(|f| *f != [0.0; 3]).unwrap() + 1;
    assert!(
        zero_at - held <= 20 + 5 + 3,
        "zero {} ticks after the last command",
        zero_at - held
    );
    assert!(device.stale_servo_ticks() > 0);
}

#[test]
fn a_non_finite_command_is_refused_and_the_motors_ramp_to_zero() {
    let _serial = serial();
    let fake = Fake::open();
    let mut device = open_device();
    command_for(&mut device, [0.0, 0.8, 0.0], Duration::from_millis(50));
    assert_eq!(
        device.write_force([f32::NAN, 0.0, 0.0]),
        Err(DeviceError::NonFiniteForce)
    );
    command_for(
        &mut device,
        [f32::INFINITY, 0.0, 0.0],
        Duration::from_millis(30),
    );
    let log = fake.force_log();
    check_log(&log, 3.3);
    assert_eq!(*log.last().unwrap(), [0.0; 3]);
}

#[test]
fn a_device_fault_latches_force_off_and_reads_fail_with_its_code() {
    let _serial = serial();
    let fake = Fake::open();
    let mut device = open_device();
    command_for(&mut device, [0.5, 0.0, 0.0], Duration::from_millis(50));
    fake.inject_servo_error(HD_DEVICE_FAULT);
    command_for(&mut device, [0.5, 0.0, 0.0], Duration::from_millis(50));
    match device.read(0.001) {
        Err(DeviceError::Fault { code, during }) => {
            assert_eq!(code, HD_DEVICE_FAULT as i32);
            assert!(during.contains("servo loop"), "{during}");
        }
        other => panic!("expected a fault, read {other:?}"),
    }
    let log = fake.force_log();
    check_log(&log, 3.3);
    assert_eq!(
        *log.last().unwrap(),
        [0.0; 3],
        "force kept on after a fault"
    );
}

#[test]
fn calibration_is_updated_by_the_library_or_waits_for_the_inkwell_with_the_motors_at_zero() {
    let _serial = serial();
    let fake = Fake::open();
    // A device that can calibrate itself is calibrated as it starts.
    fake.set_calibration(HD_CALIBRATION_NEEDS_UPDATE, HD_CALIBRATION_AUTO);
    let mut device = open_device();
    assert!(wait_until(Duration::from_secs(2), || device
        .read(0.001)
        .is_ok()));
    assert!(device.calibration_updates() >= 1 && fake.count("fakehd_calibration_updates") >= 1);
    drop(device);

    // One that needs the user: no pose, no force, until the stylus has been in the inkwell.
    let fake = Fake::open();
    fake.set_calibration(HD_CALIBRATION_NEEDS_MANUAL_INPUT, HD_CALIBRATION_INKWELL);
    let mut device = open_device();
    command_for(&mut device, [0.0, 0.0, 1.0], Duration::from_millis(100));
    match device.read(0.001) {
        Err(DeviceError::Fault { during, .. }) => assert!(during.contains("inkwell"), "{during}"),
        other => panic!("expected the inkwell request, read {other:?}"),
    }
    assert!(
        fake.force_log().iter().all(|f| *f == [0.0; 3]),
        "force while uncalibrated"
    );
    fake.set_calibration(HD_CALIBRATION_OK, HD_CALIBRATION_INKWELL);
    // The servo loop checks once a second.
    let started = Instant::now();
    let mut calibrated = false;
    while started.elapsed() < Duration::from_secs(3) && !calibrated {
        command_for(&mut device, [0.0, 0.0, 1.0], Duration::from_millis(20));
        calibrated = device.read(0.001).is_ok();
    }
    assert!(calibrated, "never calibrated");
    command_for(&mut device, [0.0, 0.0, 1.0], Duration::from_millis(30));
    let log = fake.force_log();
    check_log(&log, 3.3);
    assert!(
        log.last().unwrap()[2] > 0.9,
        "force did not follow after calibration"
    );
}

#[test]
fn a_touch_pressing_the_pad_over_zenoh_feels_it_clamped_to_its_peak_and_let_go_when_the_server_dies()
 {
    let _serial = serial();
    let fake = Fake::open();
    // A small device: the pad pushes back harder than 0.6 N at 5 mm.
    fake.set_nominal_max_force(0.6);
    fake.set_position([0.0, 0.0, 15.0]);
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    let mut config = pad_device_config("left", Box::new(open_device()), &endpoint);
    config.spin_accuracy_ns = 0;
    let mut left = HapticServer::start(config).unwrap();
    assert!(
        wait_device_active(&server, "left", Duration::from_secs(10)),
        "device active on the server"
    );
    fake.set_position([0.0, 0.0, -5.0]);
    assert!(
        wait_until(Duration::from_secs(10), || fake
            .force_log()
            .last()
            .is_some_and(|f| (norm(*f) - 0.6).abs() < 1e-6)),
        "the motors never reached the device's peak: last {:?}",
        fake.force_log().last()
    );
    let pressing = *fake.force_log().last().unwrap();
    assert!(
        pressing[2] > 0.95 * 0.6,
        "not along the pad normal: {pressing:?}"
    );
    // The server dies: the force ramps to zero (the hapticserver's silence rule), with no step.
    let before = fake.force_log().len();
    drop(server);
    assert!(
        wait_until(Duration::from_secs(5), || fake.force_log().last()
            == Some(&[0.0; 3])),
        "still rendering after the server died"
    );
    let log = fake.force_log();
    check_log(&log, 0.6);
    let zero_at = log.iter().rposition(|f| *f != [0.0; 3]).unwrap() + 1;
    println!(
        "zero {} servo ticks after the server was dropped",
        zero_at - before
    );
    left.stop().unwrap();
    assert!(!fake.flag("fakehd_initialized") && !fake.flag("fakehd_scheduler_running"));
    assert!(fake.count("fakehd_servo_ticks") > 100);
}
