//! Bindings to the OpenHaptics HD API (libHD), written from the vendor's documented headers (OpenHaptics 3.0:
//! hdDefines.h, hdDevice.h, hdScheduler.h) and opened at run time.
//!
//! Owns: the C types and the constants this backend uses (numeric values as in hdDefines.h), and [`HdApi`],
//! the loaded library with a table of its function pointers. Every call into the library goes through here.
//!
//! ABI: on x86-64 Linux the headers' `HDAPIENTRY`/`HDCALLBACK` (`__attribute__((stdcall))`) are ignored by
//! the compiler, so every function is plain C (`extern "C"`). `HHD`, `HDenum`, `HDerror` are `unsigned int`;
//! `HDSchedulerHandle` is `unsigned long`; `HDErrorInfo` is returned by value.
//!
//! Must not: decide forces or hold state of its own; [`super::servo`] owns the servo loop's logic.
#![allow(unsafe_code)] // FFI: every unsafe block says why it is sound

use std::ffi::{CStr, c_char, c_int, c_uint, c_ulong, c_ushort, c_void};
use std::path::{Path, PathBuf};

use super::OpenHapticsError;

/// Device handle (`HHD`).
pub type Hhd = c_uint;
/// Parameter name or capability (`HDenum`).
pub type HdEnum = c_uint;
/// Error code (`HDerror`).
pub type HdError = c_uint;
/// Scheduler callback handle (`HDSchedulerHandle`).
pub type HdSchedulerHandle = c_ulong;
/// What a scheduler callback returns (`HDCallbackCode`).
pub type HdCallbackCode = c_uint;
/// A scheduler callback (`HDSchedulerCallback`).
pub type HdSchedulerCallback = unsafe extern "C" fn(user_data: *mut c_void) -> HdCallbackCode;

/// `HDErrorInfo`: the newest error on the library's error stack.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HdErrorInfo {
    /// `HD_SUCCESS` when the stack is empty.
    pub error_code: HdError,
    /// The driver's own code.
    pub internal_error_code: c_int,
    /// The device it concerns.
    pub hhd: Hhd,
}

/// No error.
pub const HD_SUCCESS: HdError = 0x0000;
/// A device fault (a servo frame failed).
pub const HD_DEVICE_FAULT: HdError = 0x0300;
/// The device was already initialised.
pub const HD_DEVICE_ALREADY_INITIATED: HdError = 0x0301;
/// Communication with the device failed.
pub const HD_COMM_ERROR: HdError = 0x0302;
/// The motors are too warm (force output was limited).
pub const HD_WARM_MOTORS: HdError = 0x0200;
/// The force exceeded the device's maximum.
pub const HD_EXCEEDED_MAX_FORCE: HdError = 0x0201;
/// The stylus moved faster than the device allows with force on.
pub const HD_EXCEEDED_MAX_VELOCITY: HdError = 0x0203;
/// Device handle that failed to open.
pub const HD_INVALID_HANDLE: Hhd = 0xFFFF_FFFF;

/// Buttons, bitmask (`HDint`).
pub const HD_CURRENT_BUTTONS: HdEnum = 0x2000;
/// Stylus tip position, 3 doubles, mm.
pub const HD_CURRENT_POSITION: HdEnum = 0x2050;
/// Stylus tip velocity, 3 doubles, mm/s (smoothed by the driver).
pub const HD_CURRENT_VELOCITY: HdEnum = 0x2051;
/// End-effector transform, 16 doubles, column-major (translation at 12, 13, 14).
pub const HD_CURRENT_TRANSFORM: HdEnum = 0x2052;
/// Model name (`hdGetString`).
pub const HD_DEVICE_MODEL_TYPE: HdEnum = 0x2501;
/// Usable workspace, 6 doubles: min x, y, z, max x, y, z, mm.
pub const HD_USABLE_WORKSPACE_DIMENSIONS: HdEnum = 0x2551;
/// Calibration styles the device supports, bitmask (`HDint`).
pub const HD_CALIBRATION_STYLE: HdEnum = 0x2555;
/// Peak force, N.
pub const HD_NOMINAL_MAX_FORCE: HdEnum = 0x2603;
/// Force the device can hold continuously, N.
pub const HD_NOMINAL_MAX_CONTINUOUS_FORCE: HdEnum = 0x2604;
/// The force to render, 3 doubles, N (set inside a frame; applied at `hdEndFrame`).
pub const HD_CURRENT_FORCE: HdEnum = 0x2700;
/// Capability: force output (off after `hdInitDevice`).
pub const HD_FORCE_OUTPUT: HdEnum = 0x4000;
/// Capability: the driver clamps forces to its nominal maximum.
pub const HD_MAX_FORCE_CLAMPING: HdEnum = 0x4001;
/// Calibration is current.
pub const HD_CALIBRATION_OK: HdEnum = 0x5000;
/// Calibration can be updated by the library (`hdUpdateCalibration`).
pub const HD_CALIBRATION_NEEDS_UPDATE: HdEnum = 0x5001;
/// Calibration needs the user (the stylus in its inkwell).
pub const HD_CALIBRATION_NEEDS_MANUAL_INPUT: HdEnum = 0x5002;
/// Calibration style: reset encoders with the arm held in its reset pose.
pub const HD_CALIBRATION_ENCODER_RESET: c_int = 1;
/// Calibration style: automatic.
pub const HD_CALIBRATION_AUTO: c_int = 2;
/// Calibration style: the stylus placed in the inkwell.
pub const HD_CALIBRATION_INKWELL: c_int = 4;
/// Callback return: do not call again.
pub const HD_CALLBACK_DONE: HdCallbackCode = 0;
/// Callback return: call again next servo tick.
pub const HD_CALLBACK_CONTINUE: HdCallbackCode = 1;
/// The highest scheduler priority (`USHRT_MAX`).
pub const HD_MAX_SCHEDULER_PRIORITY: c_ushort = c_ushort::MAX;

/// The library names tried when no path is given, in order (3.4 and 3.0 installs name their sonames so).
pub const LIBRARY_CANDIDATES: [&str; 3] = ["libHD.so", "libHD.so.3.4", "libHD.so.3.0"];

/// The functions this backend calls, as loaded from libHD. Plain function pointers (`Copy`), valid while the
/// [`HdApi`] that loaded them is alive.
#[derive(Clone, Copy)]
pub struct HdFns {
    init_device: unsafe extern "C" fn(*const c_char) -> Hhd,
    disable_device: unsafe extern "C" fn(Hhd),
    begin_frame: unsafe extern "C" fn(Hhd),
    end_frame: unsafe extern "C" fn(Hhd),
    get_error: unsafe extern "C" fn() -> HdErrorInfo,
    get_error_string: unsafe extern "C" fn(HdError) -> *const c_char,
    enable: unsafe extern "C" fn(HdEnum),
    get_doublev: unsafe extern "C" fn(HdEnum, *mut f64),
    get_integerv: unsafe extern "C" fn(HdEnum, *mut c_int),
    get_string: unsafe extern "C" fn(HdEnum) -> *const c_char,
    set_doublev: unsafe extern "C" fn(HdEnum, *const f64),
    check_calibration: unsafe extern "C" fn() -> HdEnum,
    update_calibration: unsafe extern "C" fn(HdEnum),
    start_scheduler: unsafe extern "C" fn(),
    stop_scheduler: unsafe extern "C" fn(),
    schedule_asynchronous:
        unsafe extern "C" fn(HdSchedulerCallback, *mut c_void, c_ushort) -> HdSchedulerHandle,
    unschedule: unsafe extern "C" fn(HdSchedulerHandle),
}

impl std::fmt::Debug for HdFns {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("HdFns")
    }
}

/// The loaded library and its functions.
#[derive(Debug)]
pub struct HdApi {
    fns: HdFns,
    path: PathBuf,
    // Keeps the code the pointers in `fns` point into mapped; dropped last.
    _library: libloading::Library,
}

impl HdApi {
    /// Open libHD: `path` if given, else the first of [`LIBRARY_CANDIDATES`] the dynamic loader finds.
    pub fn load(path: Option<&Path>) -> Result<Self, OpenHapticsError> {
        let candidates: Vec<PathBuf> = match path {
            Some(path) => vec![path.to_owned()],
            None => LIBRARY_CANDIDATES.iter().map(PathBuf::from).collect(),
        };
        let mut tried = Vec::new();
        for candidate in candidates {
            // SAFETY: opening a shared library runs its initialisers; libHD's are the vendor's (or the test
            // fake's) and take no arguments from us.
            match unsafe { libloading::Library::new(&candidate) } {
                Ok(library) => return Self::bind(library, candidate),
                Err(e) => tried.push(format!("{}: {e}", candidate.display())),
            }
        }
        Err(OpenHapticsError::Library {
            message: format!(
                "could not open libHD (install OpenHaptics, or give --libhd PATH): {}",
                tried.join("; ")
            ),
        })
    }

    fn bind(library: libloading::Library, path: PathBuf) -> Result<Self, OpenHapticsError> {
        macro_rules! symbol {
            ($name:literal) => {{
                // SAFETY: the symbol is declared with the prototype in the vendor's headers (see the module
                // doc); the pointer is copied out and used only while `library` stays loaded.
                let symbol = unsafe { library.get(concat!($name, "\0").as_bytes()) }.map_err(|e| {
                    OpenHapticsError::Library {
                        message: format!("{}: missing {}: {e}", path.display(), $name),
                    }
                })?;
                *symbol
            }};
        }
        let fns = HdFns {
            init_device: symbol!("hdInitDevice"),
            disable_device: symbol!("hdDisableDevice"),
            begin_frame: symbol!("hdBeginFrame"),
            end_frame: symbol!("hdEndFrame"),
            get_error: symbol!("hdGetError"),
            get_error_string: symbol!("hdGetErrorString"),
            enable: symbol!("hdEnable"),
            get_doublev: symbol!("hdGetDoublev"),
            get_integerv: symbol!("hdGetIntegerv"),
            get_string: symbol!("hdGetString"),
            set_doublev: symbol!("hdSetDoublev"),
            check_calibration: symbol!("hdCheckCalibration"),
            update_calibration: symbol!("hdUpdateCalibration"),
            start_scheduler: symbol!("hdStartScheduler"),
            stop_scheduler: symbol!("hdStopScheduler"),
            schedule_asynchronous: symbol!("hdScheduleAsynchronous"),
            unschedule: symbol!("hdUnschedule"),
        };
        Ok(Self {
            fns,
            path,
            _library: library,
        })
    }

    /// The functions (valid while `self` lives).
    pub fn fns(&self) -> HdFns {
        self.fns
    }

    /// Where the library was found.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

// Each wrapper below is sound because the pointer came from the loaded library with the vendor's prototype,
// and every pointer argument points at a buffer of the size the vendor documents for that parameter.
impl HdFns {
    /// `hdInitDevice(name)`; `None` opens the default device.
    pub fn init_device(&self, name: Option<&CStr>) -> Hhd {
        // SAFETY: a NUL-terminated string or NULL (HD_DEFAULT_DEVICE), read during the call only.
        unsafe { (self.init_device)(name.map_or(std::ptr::null(), CStr::as_ptr)) }
    }

    /// `hdDisableDevice`.
    pub fn disable_device(&self, hhd: Hhd) {
        // SAFETY: see the impl comment.
        unsafe { (self.disable_device)(hhd) }
    }

    /// `hdBeginFrame`.
    pub fn begin_frame(&self, hhd: Hhd) {
        // SAFETY: see the impl comment.
        unsafe { (self.begin_frame)(hhd) }
    }

    /// `hdEndFrame`.
    pub fn end_frame(&self, hhd: Hhd) {
        // SAFETY: see the impl comment.
        unsafe { (self.end_frame)(hhd) }
    }

    /// `hdGetError`: pops the newest error (`HD_SUCCESS` when none).
    pub fn get_error(&self) -> HdErrorInfo {
        // SAFETY: see the impl comment.
        unsafe { (self.get_error)() }
    }

    /// `hdGetErrorString`, copied (allocates: not for the servo loop).
    pub fn error_string(&self, code: HdError) -> String {
        // SAFETY: see the impl comment; the returned string is static in the library, or NULL.
        let text = unsafe { (self.get_error_string)(code) };
        if text.is_null() {
            return format!("error 0x{code:04x}");
        }
        // SAFETY: non-NULL, NUL-terminated, owned by the library.
        unsafe { CStr::from_ptr(text) }
            .to_string_lossy()
            .into_owned()
    }

    /// `hdEnable`.
    pub fn enable(&self, cap: HdEnum) {
        // SAFETY: see the impl comment.
        unsafe { (self.enable)(cap) }
    }

    /// `hdGetDoublev` into `out` (`N` must be the parameter's documented count).
    pub fn get_doubles<const N: usize>(&self, pname: HdEnum) -> [f64; N] {
        let mut out = [0.0f64; N];
        // SAFETY: `out` holds the N doubles the vendor documents for `pname` (callers pass 1, 3, 6 or 16).
        unsafe { (self.get_doublev)(pname, out.as_mut_ptr()) };
        out
    }

    /// `hdGetIntegerv` of a one-integer parameter.
    pub fn get_integer(&self, pname: HdEnum) -> c_int {
        let mut out: c_int = 0;
        // SAFETY: one integer, as documented for the parameters we read (buttons, calibration style).
        unsafe { (self.get_integerv)(pname, &mut out) };
        out
    }

    /// `hdGetString`, copied (allocates).
    pub fn get_string(&self, pname: HdEnum) -> Option<String> {
        // SAFETY: see the impl comment.
        let text = unsafe { (self.get_string)(pname) };
        if text.is_null() {
            return None;
        }
        // SAFETY: non-NULL, NUL-terminated, owned by the library.
        Some(
            unsafe { CStr::from_ptr(text) }
                .to_string_lossy()
                .into_owned(),
        )
    }

    /// `hdSetDoublev(HD_CURRENT_FORCE, force)`.
    pub fn set_force(&self, force_n: [f64; 3]) {
        // SAFETY: three doubles, as documented for HD_CURRENT_FORCE; read during the call only.
        unsafe { (self.set_doublev)(HD_CURRENT_FORCE, force_n.as_ptr()) }
    }

    /// `hdCheckCalibration`.
    pub fn check_calibration(&self) -> HdEnum {
        // SAFETY: see the impl comment.
        unsafe { (self.check_calibration)() }
    }

    /// `hdUpdateCalibration(style)`.
    pub fn update_calibration(&self, style: c_int) {
        // SAFETY: see the impl comment (styles are small positive bit flags).
        unsafe { (self.update_calibration)(style.unsigned_abs()) }
    }

    /// `hdStartScheduler`.
    pub fn start_scheduler(&self) {
        // SAFETY: see the impl comment.
        unsafe { (self.start_scheduler)() }
    }

    /// `hdStopScheduler`: returns after the servo thread has stopped calling callbacks.
    pub fn stop_scheduler(&self) {
        // SAFETY: see the impl comment.
        unsafe { (self.stop_scheduler)() }
    }

    /// `hdScheduleAsynchronous(callback, user_data, HD_MAX_SCHEDULER_PRIORITY)`.
    ///
    /// # Safety
    /// `user_data` must stay valid for `callback` until the scheduler is stopped or the callback unscheduled.
    pub unsafe fn schedule_asynchronous(
        &self,
        callback: HdSchedulerCallback,
        user_data: *mut c_void,
    ) -> HdSchedulerHandle {
        // SAFETY: the caller keeps `user_data` alive as this function's contract says.
        unsafe { (self.schedule_asynchronous)(callback, user_data, HD_MAX_SCHEDULER_PRIORITY) }
    }

    /// `hdUnschedule`.
    pub fn unschedule(&self, handle: HdSchedulerHandle) {
        // SAFETY: see the impl comment.
        unsafe { (self.unschedule)(handle) }
    }
}
