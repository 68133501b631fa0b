//! A device mounted upside down (a reach-in display) presses the pad through its mounting calibration, over
//! real zenoh: its poses are rotated into the scene, the server dents the pad where the scene says, and the
//! force reaches the motors rotated back into the device's own frame, in direct and in moderated rendering.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

use std::sync::{Arc, Mutex};
use std::time::Duration;

use hapticserver::sim_device::sim_device_model;
use hapticserver::{
    Device, DeviceError, DeviceModel, DeviceReading, HandPreset, HandScript, HapticServer,
    ModePolicy, SimDevice, WorldFromDevice,
};
use sinew_protocol::rt::LatestValue;
use sinew_testkit::harness::{
    Pacing, deepest_dent_mm, pad_device_config, serial, start_pad_server, wait_device_active,
    wait_until,
};

/// A simulated device that also tells the test what its motors were last told, in its own frame.
struct MotorSpy {
    inner: SimDevice,
    motor_force_n: Arc<Mutex<[f32; 3]>>,
}

impl Device for MotorSpy {
    fn model(&self) -> DeviceModel {
        self.inner.model()
    }
    fn read(&mut self, dt_s: f32) -> Result<DeviceReading, DeviceError> {
        self.inner.read(dt_s)
    }
    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError> {
        if let Ok(mut slot) = self.motor_force_n.try_lock() {
            *slot = force_n;
        }
        self.inner.write_force(force_n)
    }
}

fn norm(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn press_upside_down(mode: ModePolicy) {
    let (endpoint, server) = start_pad_server(Pacing::Sleep).unwrap();
    let mount = WorldFromDevice::from_degrees([180.0, 0.0, 0.0], [0.0; 3]).unwrap();
    // Targets in the device's own frame: 15 mm above the pad in the scene is 15 mm along the device's -z.
    let target = Arc::new(LatestValue::new());
    target.store(mount.point_to_hardware([0.0, 0.0, 15.0]));
    let motor_force_n = Arc::new(Mutex::new([0.0f32; 3]));
    let device = MotorSpy {
        inner: SimDevice::with_params(
            HandScript::Follow(target.clone()),
            HandPreset::Grip.params(),
            sim_device_model(),
        ),
        motor_force_n: motor_force_n.clone(),
    };
    let mut config = pad_device_config("left", Box::new(device), &endpoint);
    config.mount = mount;
    config.mode = mode;
    config.spin_accuracy_ns = 0;
    let mut left = HapticServer::start(config).unwrap();
    assert!(
        wait_device_active(&server, "left", Duration::from_secs(10)),
        "device active on the server"
    );
    // The hand is 5 mm below the pad surface in the scene: +5 mm along the device's own z.
    let press_hardware = mount.point_to_hardware([0.0, 0.0, -5.0]);
    assert!((press_hardware[2] - 5.0).abs() < 1e-4, "{press_hardware:?}");
    target.store(press_hardware);
    let mut last = [0.0f32; 3];
    let settled = wait_until(Duration::from_secs(15), || {
        std::thread::sleep(Duration::from_millis(100));
        let now = left.report().last_rendered_force_n;
        let still = norm([now[0] - last[0], now[1] - last[1], now[2] - last[2]]) < 0.02;
        last = now;
        still && now[2] > 0.2
    });
    let report = left.report();
    assert!(settled, "{mode:?}: no steady push: {report}");
    // The scene saw the press where the mount put it: a dent under the device origin, the stylus above its
    // target (the tissue holds it), the force along the scene's +z.
    assert!(deepest_dent_mm(&server) > 1.0, "{mode:?}: no dent");
    let scene_force = report.last_rendered_force_n;
    assert!(
        scene_force[2] > 0.95 * norm(scene_force),
        "{mode:?}: force {scene_force:?} not along the pad normal"
    );
    assert!(
        report.last_position_mm[2] < 0.0 && report.last_position_mm[2] > -5.0 + 0.5,
        "{mode:?}: stylus at {:?} (scene frame)",
        report.last_position_mm
    );
    // The motors push along the device's own -z (the scene's +z upside down), with the same magnitude.
    let motor = *motor_force_n.lock().unwrap();
    assert!(
        motor[2] < 0.0 && -motor[2] > 0.95 * norm(motor),
        "{mode:?}: motor force {motor:?} not along the device's -z"
    );
    assert!(
        (norm(motor) - norm(scene_force)).abs() < 0.05,
        "{mode:?}: motor {motor:?} and scene {scene_force:?} differ in magnitude"
    );
    left.stop().unwrap();
    drop(server);
}

#[test]
fn an_upside_down_device_presses_the_pad_and_feels_it_along_its_own_minus_z_when_rendering_directly()
 {
    let _serial = serial();
    press_upside_down(ModePolicy::Direct);
}

#[test]
fn an_upside_down_device_renders_the_local_model_in_the_scene_frame_and_feels_it_along_its_own_minus_z()
 {
    let _serial = serial();
    press_upside_down(ModePolicy::Moderated);
}
