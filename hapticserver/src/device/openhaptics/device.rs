//! [`OpenHapticsDevice`]: a 3D Systems Touch / Phantom (any device libHD drives) as a [`Device`].
//!
//! Owns: opening the device (library, `hdInitDevice`, limits, workspace, calibration style, force output and
//! the driver's own clamping on, the servo callback scheduled at the highest priority), the device-thread
//! half of the mailboxes, and the orderly close (the servo loop ramps to zero, then the scheduler stops and
//! the device is disabled). Frames: the driver's (a Touch: +x right, +y up, +z toward the user), mm, mm/s, N;
//! give `--mount-rotation-deg 90,0,0` to put its +y up along a scene's +z.
//!
//! Timing: libHD's servo thread runs at 1 kHz on its own clock; the hapticserver loop reads the newest
//! sample and writes the newest command, so a force reaches the motors within one servo tick of being
//! computed (at most 1 ms more than a loop paced by the servo itself would give).
//!
//! Must not: render anything that did not pass the servo follower; block in `read` or `write_force`.

use std::ffi::CString;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

use super::OpenHapticsError;
use super::hd_api::{
    HD_CALIBRATION_AUTO, HD_CALIBRATION_ENCODER_RESET, HD_CALIBRATION_INKWELL,
    HD_CALIBRATION_NEEDS_MANUAL_INPUT, HD_CALIBRATION_NEEDS_UPDATE, HD_CALIBRATION_OK,
    HD_CALIBRATION_STYLE, HD_DEVICE_MODEL_TYPE, HD_FORCE_OUTPUT, HD_INVALID_HANDLE,
    HD_MAX_FORCE_CLAMPING, HD_NOMINAL_MAX_FORCE, HD_SUCCESS, HD_USABLE_WORKSPACE_DIMENSIONS, HdApi,
    HdSchedulerHandle,
};
use super::servo::{ForceFollower, ServoShared, servo_callback};
use crate::device::{Device, DeviceError, DeviceModel, DeviceReading};

/// The rate limit the servo follower applies, N/s (the hapticserver's safety default).
pub const DEFAULT_FORCE_RATE_N_PER_S: f64 = 200.0;
/// How long the servo follower holds the last command before ramping to zero by itself, ms.
pub const DEFAULT_STALE_MS: u32 = 20;
/// The most force a device may announce and still be trusted, N (a bad driver value is refused).
pub const MAX_PLAUSIBLE_FORCE_N: f64 = 50.0;

/// How to open the device.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct OpenHapticsConfig {
    /// libHD to open; None tries the usual names on the loader's path.
    pub library: Option<PathBuf>,
    /// Device name as configured in the vendor's setup tool; None opens the default device.
    pub device_name: Option<String>,
}

/// An open OpenHaptics device.
#[derive(Debug)]
pub struct OpenHapticsDevice {
    shared: Arc<ServoShared>,
    handle: HdSchedulerHandle,
    model: DeviceModel,
    writes: u64,
    last: Option<DeviceReading>,
    closed: bool,
    // Declared last: dropped after the scheduler has stopped (see Drop).
    api: HdApi,
}

/// The calibration style to use: the vendor prefers auto, then inkwell, then encoder reset.
fn choose_style(supported: i32) -> Option<i32> {
    [
        HD_CALIBRATION_AUTO,
        HD_CALIBRATION_INKWELL,
        HD_CALIBRATION_ENCODER_RESET,
    ]
    .into_iter()
    .find(|style| supported & style != 0)
}

impl OpenHapticsDevice {
    /// Open the device and start its servo loop (force output on, rendering zero until commanded).
    pub fn open(config: &OpenHapticsConfig) -> Result<Self, OpenHapticsError> {
        let api = HdApi::load(config.library.as_deref())?;
        let fns = api.fns();
        let name = config
            .device_name
            .as_deref()
            .map(CString::new)
            .transpose()
            .map_err(|_| OpenHapticsError::Config {
                message: "the device name has a NUL byte".to_owned(),
            })?;
        let hhd = fns.init_device(name.as_deref());
        let error = fns.get_error();
        if hhd == HD_INVALID_HANDLE || error.error_code != HD_SUCCESS {
            return Err(OpenHapticsError::Hd {
                during: "hdInitDevice",
                code: error.error_code,
                message: fns.error_string(error.error_code),
            });
        }
        let fail = |during: &'static str, code: u32, message: String| {
            fns.disable_device(hhd);
            OpenHapticsError::Hd {
                during,
                code,
                message,
            }
        };
        let [max_force_n] = fns.get_doubles::<1>(HD_NOMINAL_MAX_FORCE);
        let workspace = fns.get_doubles::<6>(HD_USABLE_WORKSPACE_DIMENSIONS);
        let model_type = fns
            .get_string(HD_DEVICE_MODEL_TYPE)
            .unwrap_or_else(|| "unknown".to_owned());
        let styles = fns.get_integer(HD_CALIBRATION_STYLE);
        let error = fns.get_error();
        if error.error_code != HD_SUCCESS {
            return Err(fail(
                "reading the device's limits",
                error.error_code,
                fns.error_string(error.error_code),
            ));
        }
        if !(max_force_n.is_finite() && max_force_n > 0.0 && max_force_n <= MAX_PLAUSIBLE_FORCE_N) {
            return Err(fail(
                "reading HD_NOMINAL_MAX_FORCE",
                0,
                format!(
                    "the driver reports {max_force_n} N, outside (0, {MAX_PLAUSIBLE_FORCE_N}] N"
                ),
            ));
        }
        let workspace_ok = workspace.iter().all(|c| c.is_finite())
            && (0..3).all(|i| workspace[i] < workspace[i + 3]);
        let (workspace_min_mm, workspace_max_mm) = if workspace_ok {
            (
                [
                    workspace[0] as f32,
                    workspace[1] as f32,
                    workspace[2] as f32,
                ],
                [
                    workspace[3] as f32,
                    workspace[4] as f32,
                    workspace[5] as f32,
                ],
            )
        } else {
            ([-150.0; 3], [150.0; 3])
        };
        let style = choose_style(styles).ok_or_else(|| {
            fail(
                "reading HD_CALIBRATION_STYLE",
                0,
                format!("the device supports no known calibration style (bits {styles:#x})"),
            )
        })?;
        // Encoder reset is done before the scheduler starts, with the arm in its reset pose (vendor order).
        if style == HD_CALIBRATION_ENCODER_RESET
            && fns.check_calibration() == HD_CALIBRATION_NEEDS_UPDATE
        {
            fns.update_calibration(style);
            let _ = fns.get_error();
        }
        fns.enable(HD_FORCE_OUTPUT);
        fns.enable(HD_MAX_FORCE_CLAMPING);
        let error = fns.get_error();
        if error.error_code != HD_SUCCESS {
            return Err(fail(
                "enabling force output",
                error.error_code,
                fns.error_string(error.error_code),
            ));
        }
        let follower = ForceFollower::new(
            max_force_n,
            DEFAULT_FORCE_RATE_N_PER_S * 1e-3,
            u64::from(DEFAULT_STALE_MS),
        );
        let shared = Arc::new(ServoShared::new(fns, hhd, style, follower));
        // SAFETY: `shared` is kept alive by `Self` until Drop has stopped the scheduler and unscheduled it.
        #[allow(unsafe_code)]
        let handle = unsafe {
            fns.schedule_asynchronous(servo_callback, Arc::as_ptr(&shared).cast_mut().cast())
        };
        fns.start_scheduler();
        let error = fns.get_error();
        if error.error_code != HD_SUCCESS {
            fns.stop_scheduler();
            fns.unschedule(handle);
            return Err(fail(
                "starting the scheduler",
                error.error_code,
                fns.error_string(error.error_code),
            ));
        }
        let model = DeviceModel {
            name: format!("openhaptics:{model_type}"),
            max_force_n: max_force_n as f32,
            max_force_rate_n_per_s: DEFAULT_FORCE_RATE_N_PER_S as f32,
            workspace_min_mm,
            workspace_max_mm,
        };
        Ok(Self {
            shared,
            handle,
            model,
            writes: 0,
            last: None,
            closed: false,
            api,
        })
    }

    /// Servo ticks run so far.
    pub fn servo_ticks(&self) -> u64 {
        self.shared.ticks.load(Ordering::Relaxed)
    }

    /// Servo ticks on which the hapticserver's command was stale and the follower ramped out by itself.
    pub fn stale_servo_ticks(&self) -> u64 {
        self.shared.stale_ticks.load(Ordering::Relaxed)
    }

    /// The force the servo loop rendered last, N (driver frame).
    pub fn servo_force_n(&self) -> [f64; 3] {
        self.shared.rendered_force_n()
    }

    /// Calibration updates the servo loop asked the library for.
    pub fn calibration_updates(&self) -> u64 {
        self.shared.calibration_updates.load(Ordering::Relaxed)
    }

    /// The library that was opened.
    pub fn library_path(&self) -> &std::path::Path {
        self.api.path()
    }

    /// Ramp the motors to zero, stop the servo loop and disable the device (also done on drop). Waits at
    /// most `timeout` for the ramp.
    pub fn close(&mut self, timeout: Duration) {
        if self.closed {
            return;
        }
        self.closed = true;
        self.shared.stop.store(true, Ordering::Release);
        let started = Instant::now();
        while !self.shared.stopped.load(Ordering::Acquire) && started.elapsed() < timeout {
            std::thread::sleep(Duration::from_millis(1));
        }
        let fns = self.api.fns();
        fns.stop_scheduler();
        fns.unschedule(self.handle);
        fns.disable_device(self.shared_hhd());
        let _ = fns.get_error();
    }

    fn shared_hhd(&self) -> u32 {
        self.shared.hhd()
    }
}

impl Drop for OpenHapticsDevice {
    fn drop(&mut self) {
        // 3.3 N at 200 N/s ramps out in 16.5 ms; 100 ms covers a slow servo thread.
        self.close(Duration::from_millis(100));
    }
}

impl Device for OpenHapticsDevice {
    fn model(&self) -> DeviceModel {
        self.model.clone()
    }

    fn read(&mut self, _dt_s: f32) -> Result<DeviceReading, DeviceError> {
        let fault = self.shared.fault.load(Ordering::Acquire);
        if fault != 0 {
            return Err(DeviceError::Fault {
                code: fault as i32,
                during: "the servo loop (force output stays off until the hapticserver restarts)",
            });
        }
        match self.shared.calibration.load(Ordering::Acquire) {
            HD_CALIBRATION_OK => {}
            HD_CALIBRATION_NEEDS_MANUAL_INPUT => {
                return Err(DeviceError::Fault {
                    code: HD_CALIBRATION_NEEDS_MANUAL_INPUT as i32,
                    during: "calibration: put the stylus in its inkwell",
                });
            }
            other => {
                return Err(DeviceError::Fault {
                    code: other as i32,
                    during: "calibration: updating",
                });
            }
        }
        let Some(s) = self.shared.sample.read() else {
            return self.last.ok_or(DeviceError::NotConnected);
        };
        // Column-major rotation: s[6..9] is the first column.
        let matrix = Matrix3::new(s[6], s[9], s[12], s[7], s[10], s[13], s[8], s[11], s[14]);
        let rotation = Rotation3::from_matrix_eps(&matrix, 1e-9, 8, Rotation3::identity());
        let q = UnitQuaternion::from_rotation_matrix(&rotation);
        let reading = DeviceReading {
            position_mm: [s[0] as f32, s[1] as f32, s[2] as f32],
            orientation_xyzw: [q.i as f32, q.j as f32, q.k as f32, q.w as f32],
            linear_velocity_mm_s: [s[3] as f32, s[4] as f32, s[5] as f32],
            buttons: s[15] as u32,
            jaw_angle_rad: 0.0,
        };
        if !reading.is_finite() {
            return Err(DeviceError::NonFiniteReading { field: "pose" });
        }
        self.last = Some(reading);
        Ok(reading)
    }

    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError> {
        self.writes += 1;
        let (f, result) = crate::device::finite_or_zero(force_n);
        self.shared.command.write(&[
            f64::from(f[0]),
            f64::from(f[1]),
            f64::from(f[2]),
            self.writes as f64,
        ]);
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calibration_style_follows_the_vendor_preference() {
        assert_eq!(choose_style(7), Some(HD_CALIBRATION_AUTO));
        assert_eq!(choose_style(5), Some(HD_CALIBRATION_INKWELL));
        assert_eq!(choose_style(1), Some(HD_CALIBRATION_ENCODER_RESET));
        assert_eq!(choose_style(0), None);
    }

    #[test]
    fn a_missing_library_is_a_clear_error() {
        let err = OpenHapticsDevice::open(&OpenHapticsConfig {
            library: Some("/nonexistent/libHD.so".into()),
            device_name: None,
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("could not open libHD") && err.contains("/nonexistent/libHD.so"),
            "{err}"
        );
    }
}
