/*
 * A fake OpenHaptics HD library (libHD.so) for tests: it implements the calls Sinew's `openhaptics` backend
 * makes, with the vendor's numeric constants and C types (OpenHaptics 3.0 hdDefines.h, hdDevice.h,
 * hdScheduler.h), and a servo thread that runs scheduled callbacks at 1 kHz as hdStartScheduler does.
 *
 * What it models: one device; an error stack of one entry (hdGetError pops it); frames (state may be set only
 * inside hdBeginFrame/hdEndFrame, one frame per servo tick); force output off until hdEnable(HD_FORCE_OUTPUT);
 * calibration status and styles; a scripted stylus position set by the test. What it records: the force the
 * "motors" rendered at every servo tick (zero while force output is off), for the test to check.
 *
 * Test controls (not part of the HD API) are the fakehd_* functions at the end. Built by tests/openhaptics.rs
 * with `cc -shared -fPIC -pthread`. Not a driver: it never touches hardware.
 */
#include <math.h>
#include <pthread.h>
#include <stddef.h>
#include <string.h>
#include <time.h>

typedef unsigned int HHD;
typedef unsigned int HDerror;
typedef unsigned int HDenum;
typedef int HDint;
typedef double HDdouble;
typedef unsigned char HDboolean;
typedef unsigned short HDushort;
typedef unsigned long HDulong;
typedef const char *HDstring;
typedef unsigned int HDCallbackCode;
typedef unsigned long HDSchedulerHandle;
typedef HDCallbackCode (*HDSchedulerCallback)(void *pUserData);
typedef struct {
    HDerror errorCode;
    int internalErrorCode;
    HHD hHD;
} HDErrorInfo;

#define HD_SUCCESS 0x0000
#define HD_INVALID_ENUM 0x0100
#define HD_INVALID_VALUE 0x0101
#define HD_INVALID_OPERATION 0x0102
#define HD_BAD_HANDLE 0x0104
#define HD_DEVICE_FAULT 0x0300
#define HD_DEVICE_ALREADY_INITIATED 0x0301
#define HD_ILLEGAL_BEGIN 0x0400
#define HD_ILLEGAL_END 0x0401
#define HD_SCHEDULER_FULL 0x0501

#define HD_CURRENT_BUTTONS 0x2000
#define HD_CURRENT_POSITION 0x2050
#define HD_CURRENT_VELOCITY 0x2051
#define HD_CURRENT_TRANSFORM 0x2052
#define HD_DEVICE_MODEL_TYPE 0x2501
#define HD_USABLE_WORKSPACE_DIMENSIONS 0x2551
#define HD_CALIBRATION_STYLE 0x2555
#define HD_NOMINAL_MAX_FORCE 0x2603
#define HD_NOMINAL_MAX_CONTINUOUS_FORCE 0x2604
#define HD_CURRENT_FORCE 0x2700
#define HD_FORCE_OUTPUT 0x4000
#define HD_MAX_FORCE_CLAMPING 0x4001
#define HD_CALIBRATION_OK 0x5000
#define HD_CALIBRATION_NEEDS_UPDATE 0x5001
#define HD_CALIBRATION_NEEDS_MANUAL_INPUT 0x5002
#define HD_CALIBRATION_ENCODER_RESET 1
#define HD_CALIBRATION_AUTO 2
#define HD_CALIBRATION_INKWELL 4
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1
#define HD_INVALID_HANDLE 0xFFFFFFFFu

#define FORCE_LOG_CAPACITY 200000
#define MAX_CALLBACKS 8

static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static int initialized;
static HDErrorInfo last_error;
static int in_frame;
static int force_output;
static int clamping;
static double position_mm[3];
static double velocity_mm_s[3];
static double transform[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
static int buttons;
static double nominal_max_force_n = 3.3;
static double workspace_mm[6] = {-80, -60, -35, 80, 60, 35};
static HDenum calibration = HD_CALIBRATION_OK;
static int calibration_styles = HD_CALIBRATION_AUTO;
static unsigned long calibration_updates;
static double frame_force[3];
static double force_log[FORCE_LOG_CAPACITY][3];
static unsigned long force_log_len;
static unsigned long servo_ticks;
static int servo_paused;
static HDerror pending_servo_error;

static HDSchedulerCallback callbacks[MAX_CALLBACKS];
static void *callback_data[MAX_CALLBACKS];
static pthread_t servo_thread;
static volatile int scheduler_running;

static void set_error(HDerror code) {
    if (last_error.errorCode == HD_SUCCESS) {
        last_error.errorCode = code;
        last_error.internalErrorCode = (int)code;
        last_error.hHD = 0;
    }
}

HHD hdInitDevice(HDstring config_name) {
    pthread_mutex_lock(&lock);
    HHD handle = 0;
    if (config_name != NULL && strcmp(config_name, "missing") == 0) {
        set_error(HD_DEVICE_FAULT);
        handle = HD_INVALID_HANDLE;
    } else if (initialized) {
        set_error(HD_DEVICE_ALREADY_INITIATED);
        handle = HD_INVALID_HANDLE;
    } else {
        initialized = 1;
    }
    pthread_mutex_unlock(&lock);
    return handle;
}

void hdDisableDevice(HHD hhd) {
    pthread_mutex_lock(&lock);
    if (hhd != 0 || !initialized) set_error(HD_BAD_HANDLE);
    initialized = 0;
    force_output = 0;
    pthread_mutex_unlock(&lock);
}

void hdMakeCurrentDevice(HHD hhd) { (void)hhd; }

HDErrorInfo hdGetError(void) {
    pthread_mutex_lock(&lock);
    HDErrorInfo e = last_error;
    last_error.errorCode = HD_SUCCESS;
    last_error.internalErrorCode = 0;
    pthread_mutex_unlock(&lock);
    return e;
}

HDstring hdGetErrorString(HDerror code) {
    switch (code) {
    case HD_SUCCESS: return "No error";
    case HD_DEVICE_FAULT: return "Device fault";
    case HD_DEVICE_ALREADY_INITIATED: return "Device already initiated";
    case HD_ILLEGAL_BEGIN: return "Illegal begin frame";
    case HD_ILLEGAL_END: return "Illegal end frame";
    case HD_INVALID_ENUM: return "Invalid enumerant";
    case HD_BAD_HANDLE: return "Invalid handle";
    default: return "Unknown error";
    }
}

void hdBeginFrame(HHD hhd) {
    pthread_mutex_lock(&lock);
    if (hhd != 0 || !initialized) set_error(HD_BAD_HANDLE);
    else if (in_frame) set_error(HD_ILLEGAL_BEGIN);
    else {
        in_frame = 1;
        frame_force[0] = frame_force[1] = frame_force[2] = 0.0;
    }
    pthread_mutex_unlock(&lock);
}

void hdEndFrame(HHD hhd) {
    pthread_mutex_lock(&lock);
    if (hhd != 0 || !in_frame) set_error(HD_ILLEGAL_END);
    else {
        in_frame = 0;
        double f[3] = {0, 0, 0};
        if (force_output) {
            memcpy(f, frame_force, sizeof f);
            double norm = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
            if (clamping && norm > nominal_max_force_n) {
                for (int i = 0; i < 3; i++) f[i] *= nominal_max_force_n / norm;
            }
        }
        if (force_log_len < FORCE_LOG_CAPACITY) {
            memcpy(force_log[force_log_len], f, sizeof f);
            force_log_len++;
        }
        if (pending_servo_error != HD_SUCCESS) {
            set_error(pending_servo_error);
            pending_servo_error = HD_SUCCESS;
        }
    }
    pthread_mutex_unlock(&lock);
}

void hdEnable(HDenum cap) {
    pthread_mutex_lock(&lock);
    if (cap == HD_FORCE_OUTPUT) force_output = 1;
    else if (cap == HD_MAX_FORCE_CLAMPING) clamping = 1;
    else set_error(HD_INVALID_ENUM);
    pthread_mutex_unlock(&lock);
}

void hdDisable(HDenum cap) {
    pthread_mutex_lock(&lock);
    if (cap == HD_FORCE_OUTPUT) force_output = 0;
    else if (cap == HD_MAX_FORCE_CLAMPING) clamping = 0;
    else set_error(HD_INVALID_ENUM);
    pthread_mutex_unlock(&lock);
}

void hdGetDoublev(HDenum pname, HDdouble *params) {
    pthread_mutex_lock(&lock);
    switch (pname) {
    case HD_CURRENT_POSITION: memcpy(params, position_mm, 3 * sizeof(double)); break;
    case HD_CURRENT_VELOCITY: memcpy(params, velocity_mm_s, 3 * sizeof(double)); break;
    case HD_CURRENT_TRANSFORM:
        memcpy(params, transform, 16 * sizeof(double));
        params[12] = position_mm[0];
        params[13] = position_mm[1];
        params[14] = position_mm[2];
        break;
    case HD_NOMINAL_MAX_FORCE: params[0] = nominal_max_force_n; break;
    case HD_NOMINAL_MAX_CONTINUOUS_FORCE: params[0] = nominal_max_force_n / 3.0; break;
    case HD_USABLE_WORKSPACE_DIMENSIONS: memcpy(params, workspace_mm, 6 * sizeof(double)); break;
    case HD_CURRENT_FORCE: memcpy(params, frame_force, 3 * sizeof(double)); break;
    default: set_error(HD_INVALID_ENUM);
    }
    pthread_mutex_unlock(&lock);
}

void hdGetIntegerv(HDenum pname, HDint *params) {
    pthread_mutex_lock(&lock);
    switch (pname) {
    case HD_CURRENT_BUTTONS: params[0] = buttons; break;
    case HD_CALIBRATION_STYLE: params[0] = calibration_styles; break;
    default: set_error(HD_INVALID_ENUM);
    }
    pthread_mutex_unlock(&lock);
}

HDstring hdGetString(HDenum pname) {
    if (pname == HD_DEVICE_MODEL_TYPE) return "Fake Touch";
    pthread_mutex_lock(&lock);
    set_error(HD_INVALID_ENUM);
    pthread_mutex_unlock(&lock);
    return NULL;
}

void hdSetDoublev(HDenum pname, const HDdouble *params) {
    pthread_mutex_lock(&lock);
    if (pname != HD_CURRENT_FORCE) set_error(HD_INVALID_ENUM);
    else if (!in_frame) set_error(HD_INVALID_OPERATION);
    else memcpy(frame_force, params, 3 * sizeof(double));
    pthread_mutex_unlock(&lock);
}

HDenum hdCheckCalibration(void) {
    pthread_mutex_lock(&lock);
    HDenum c = calibration;
    pthread_mutex_unlock(&lock);
    return c;
}

void hdUpdateCalibration(HDenum style) {
    pthread_mutex_lock(&lock);
    if (!(style & calibration_styles)) set_error(HD_INVALID_VALUE);
    else {
        calibration_updates++;
        if (calibration == HD_CALIBRATION_NEEDS_UPDATE) calibration = HD_CALIBRATION_OK;
    }
    pthread_mutex_unlock(&lock);
}

static void *servo_main(void *unused) {
    (void)unused;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    while (scheduler_running) {
        next.tv_nsec += 1000000;
        if (next.tv_nsec >= 1000000000) {
            next.tv_nsec -= 1000000000;
            next.tv_sec++;
        }
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
        pthread_mutex_lock(&lock);
        int paused = servo_paused;
        pthread_mutex_unlock(&lock);
        if (paused) continue;
        for (int i = 0; i < MAX_CALLBACKS; i++) {
            pthread_mutex_lock(&lock);
            HDSchedulerCallback cb = callbacks[i];
            void *data = callback_data[i];
            pthread_mutex_unlock(&lock);
            if (cb == NULL) continue;
            if (cb(data) == HD_CALLBACK_DONE) {
                pthread_mutex_lock(&lock);
                callbacks[i] = NULL;
                pthread_mutex_unlock(&lock);
            }
        }
        pthread_mutex_lock(&lock);
        servo_ticks++;
        pthread_mutex_unlock(&lock);
    }
    return NULL;
}

void hdStartScheduler(void) {
    if (scheduler_running) {
        pthread_mutex_lock(&lock);
        set_error(HD_INVALID_OPERATION);
        pthread_mutex_unlock(&lock);
        return;
    }
    scheduler_running = 1;
    pthread_create(&servo_thread, NULL, servo_main, NULL);
}

void hdStopScheduler(void) {
    if (!scheduler_running) return;
    scheduler_running = 0;
    pthread_join(servo_thread, NULL);
}

HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback cb, void *data, HDushort priority) {
    (void)priority;
    pthread_mutex_lock(&lock);
    for (int i = 0; i < MAX_CALLBACKS; i++) {
        if (callbacks[i] == NULL) {
            callbacks[i] = cb;
            callback_data[i] = data;
            pthread_mutex_unlock(&lock);
            return (HDSchedulerHandle)i;
        }
    }
    set_error(HD_SCHEDULER_FULL);
    pthread_mutex_unlock(&lock);
    return (HDSchedulerHandle)-1;
}

void hdUnschedule(HDSchedulerHandle handle) {
    pthread_mutex_lock(&lock);
    if (handle < MAX_CALLBACKS) callbacks[handle] = NULL;
    pthread_mutex_unlock(&lock);
}

/* ---- Test controls (not HD API) ---- */

void fakehd_reset(void) {
    pthread_mutex_lock(&lock);
    memset(position_mm, 0, sizeof position_mm);
    memset(velocity_mm_s, 0, sizeof velocity_mm_s);
    buttons = 0;
    nominal_max_force_n = 3.3;
    calibration = HD_CALIBRATION_OK;
    calibration_styles = HD_CALIBRATION_AUTO;
    calibration_updates = 0;
    force_log_len = 0;
    servo_paused = 0;
    pending_servo_error = HD_SUCCESS;
    last_error.errorCode = HD_SUCCESS;
    pthread_mutex_unlock(&lock);
}

void fakehd_set_position(double x, double y, double z) {
    pthread_mutex_lock(&lock);
    position_mm[0] = x;
    position_mm[1] = y;
    position_mm[2] = z;
    pthread_mutex_unlock(&lock);
}

void fakehd_set_buttons(int b) {
    pthread_mutex_lock(&lock);
    buttons = b;
    pthread_mutex_unlock(&lock);
}

void fakehd_set_nominal_max_force(double n) {
    pthread_mutex_lock(&lock);
    nominal_max_force_n = n;
    pthread_mutex_unlock(&lock);
}

void fakehd_set_calibration(unsigned int status, int styles) {
    pthread_mutex_lock(&lock);
    calibration = status;
    calibration_styles = styles;
    pthread_mutex_unlock(&lock);
}

unsigned long fakehd_calibration_updates(void) {
    pthread_mutex_lock(&lock);
    unsigned long n = calibration_updates;
    pthread_mutex_unlock(&lock);
    return n;
}

/* The next servo frame ends with this error, as a device fault would. */
void fakehd_inject_servo_error(unsigned int code) {
    pthread_mutex_lock(&lock);
    pending_servo_error = code;
    pthread_mutex_unlock(&lock);
}

/* Copy up to max rendered forces (x, y, z per servo tick, oldest first) into out; returns how many. */
unsigned long fakehd_force_log(double *out, unsigned long max) {
    pthread_mutex_lock(&lock);
    unsigned long n = force_log_len < max ? force_log_len : max;
    memcpy(out, force_log, n * 3 * sizeof(double));
    pthread_mutex_unlock(&lock);
    return n;
}

unsigned long fakehd_servo_ticks(void) {
    pthread_mutex_lock(&lock);
    unsigned long n = servo_ticks;
    pthread_mutex_unlock(&lock);
    return n;
}

int fakehd_initialized(void) {
    pthread_mutex_lock(&lock);
    int i = initialized;
    pthread_mutex_unlock(&lock);
    return i;
}

int fakehd_scheduler_running(void) { return scheduler_running; }

int fakehd_force_output_enabled(void) {
    pthread_mutex_lock(&lock);
    int f = force_output;
    pthread_mutex_unlock(&lock);
    return f;
}
