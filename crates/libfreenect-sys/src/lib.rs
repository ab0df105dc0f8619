//! Raw FFI bindings to the system **libfreenect** and **libfreenect_sync** (Kinect v1,
//! OpenKinect project; Debian package `libfreenect-dev`, 0.5.x).
//!
//! Only what a depth scanner needs is declared: the synchronous depth grab, the tilt state and
//! its angle in degrees, setting the tilt, and stopping the synchronous runloop; and, from the
//! core library, a context of one's own (`freenect_init`, `freenect_set_log_level`,
//! `freenect_num_devices`, `freenect_open_device`, `freenect_close_device`,
//! `freenect_shutdown`) to probe for a device quietly — the synchronous wrapper keeps its own
//! context private, so its log level cannot be set. The types
//! mirror `/usr/include/libfreenect.h` and `/usr/include/libfreenect_sync.h`; their layout is
//! checked at compile time against the C layout (`freenect_raw_tilt_state` is 12 bytes).
//!
//! # Linking
//! `build.rs` finds libfreenect with pkg-config and links `freenect_sync` next to it (its
//! `.pc` file names only `-lfreenect`). When pkg-config cannot find libfreenect, the crate
//! still builds — with a `cargo:warning` — but declares no foreign functions and
//! [`AVAILABLE`] is `false`; set `LIBFREENECT_REQUIRED=1` to turn that into a build error.
//!
//! # Safety
//! Every function here is `unsafe` to call: pointers must be valid as the C documentation
//! says. The buffers returned by `freenect_sync_get_depth` belong to the library and stay
//! valid only until the next call for the same device or `freenect_sync_stop`. Use the safe
//! wrapper in `voxoct-kinect` (feature `freenect`) instead of calling these directly.
//!
//! ```
//! use libfreenect_sys::*;
//! // The depth formats keep their C values; millimetres is format 5.
//! assert_eq!(FREENECT_DEPTH_MM, 5);
//! assert_eq!(FREENECT_DEPTH_RAW_NO_VALUE, 2047);
//! // Log levels: a new context logs warnings and worse.
//! assert_eq!(FREENECT_LOG_WARNING, 2);
//! // The tilt state has the C layout: three i16, one i8, a 32-bit enum at offset 8.
//! assert_eq!(std::mem::size_of::<freenect_raw_tilt_state>(), 12);
//! // Whether the library was found when this crate was built.
//! println!("libfreenect available: {AVAILABLE}");
//! ```
#![allow(unsafe_code)]
#![allow(non_camel_case_types)]

use std::ffi::{c_int, c_uint};

/// Whether libfreenect was found at build time (the foreign functions exist only then).
pub const AVAILABLE: bool = !cfg!(freenect_missing);

/// `freenect_depth_format` (a C enum forced to 32 bits by `FREENECT_DEPTH_DUMMY`).
pub type freenect_depth_format = c_uint;
/// 11-bit raw disparity in one `uint16_t` per pixel; 2047 = no reading.
pub const FREENECT_DEPTH_11BIT: freenect_depth_format = 0;
/// 10-bit raw disparity in one `uint16_t` per pixel.
pub const FREENECT_DEPTH_10BIT: freenect_depth_format = 1;
/// 11-bit raw disparity, bit-packed.
pub const FREENECT_DEPTH_11BIT_PACKED: freenect_depth_format = 2;
/// 10-bit raw disparity, bit-packed.
pub const FREENECT_DEPTH_10BIT_PACKED: freenect_depth_format = 3;
/// Depth in millimetres, registered (aligned) to the 640×480 RGB image.
pub const FREENECT_DEPTH_REGISTERED: freenect_depth_format = 4;
/// Depth in millimetres along the optical axis, in the depth camera's own image; 0 = no reading.
pub const FREENECT_DEPTH_MM: freenect_depth_format = 5;

/// Largest value of a `FREENECT_DEPTH_MM` / `FREENECT_DEPTH_REGISTERED` pixel.
pub const FREENECT_DEPTH_MM_MAX_VALUE: u16 = 10000;
/// "No reading" in the millimetre formats.
pub const FREENECT_DEPTH_MM_NO_VALUE: u16 = 0;
/// Exclusive upper bound of a raw (10/11-bit) pixel value.
pub const FREENECT_DEPTH_RAW_MAX_VALUE: u16 = 2048;
/// "No reading" in the raw formats.
pub const FREENECT_DEPTH_RAW_NO_VALUE: u16 = 2047;
/// Raw accelerometer counts per g (`FREENECT_COUNTS_PER_G`).
pub const FREENECT_COUNTS_PER_G: c_int = 819;

/// `freenect_loglevel` (a C enum): how much the library prints to stderr for a context.
pub type freenect_loglevel = c_uint;
/// Only crashing, non-recoverable errors.
pub const FREENECT_LOG_FATAL: freenect_loglevel = 0;
/// Major errors (for example "Failed to open camera subdevice or it is not disabled.").
pub const FREENECT_LOG_ERROR: freenect_loglevel = 1;
/// Warnings: the level of a new context.
pub const FREENECT_LOG_WARNING: freenect_loglevel = 2;
/// Important messages.
pub const FREENECT_LOG_NOTICE: freenect_loglevel = 3;
/// Normal messages.
pub const FREENECT_LOG_INFO: freenect_loglevel = 4;
/// Development messages.
pub const FREENECT_LOG_DEBUG: freenect_loglevel = 5;

/// Opaque `freenect_context` (a library context: its USB session and log level).
#[repr(C)]
pub struct freenect_context {
    _private: [u8; 0],
}

/// Opaque `freenect_device` (one opened Kinect).
#[repr(C)]
pub struct freenect_device {
    _private: [u8; 0],
}

/// `freenect_tilt_status_code` (a C enum).
pub type freenect_tilt_status_code = c_uint;
/// The tilt motor is stopped.
pub const TILT_STATUS_STOPPED: freenect_tilt_status_code = 0x00;
/// The tilt motor has reached its movement limit.
pub const TILT_STATUS_LIMIT: freenect_tilt_status_code = 0x01;
/// The tilt motor is moving.
pub const TILT_STATUS_MOVING: freenect_tilt_status_code = 0x04;

/// Data from the tilt motor and the accelerometer (`freenect_raw_tilt_state`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct freenect_raw_tilt_state {
    /// Raw accelerometer, x axis (see [`FREENECT_COUNTS_PER_G`]).
    pub accelerometer_x: i16,
    /// Raw accelerometer, y axis.
    pub accelerometer_y: i16,
    /// Raw accelerometer, z axis.
    pub accelerometer_z: i16,
    /// Raw tilt motor encoder (half degrees).
    pub tilt_angle: i8,
    /// State of the tilt motor (`TILT_STATUS_*`).
    pub tilt_status: freenect_tilt_status_code,
}

// Layout as compiled by gcc for x86_64 and aarch64 from libfreenect.h.
const _: () = {
    assert!(std::mem::size_of::<freenect_raw_tilt_state>() == 12);
    assert!(std::mem::align_of::<freenect_raw_tilt_state>() == 4);
    assert!(std::mem::offset_of!(freenect_raw_tilt_state, tilt_angle) == 6);
    assert!(std::mem::offset_of!(freenect_raw_tilt_state, tilt_status) == 8);
};

#[cfg(not(freenect_missing))]
unsafe extern "C" {
    /// Grabs the latest depth frame of device `index` in format `fmt`, starting the
    /// synchronous runloop (and opening the device) on first use. Blocks until a frame
    /// arrives. `*depth` then points to a library-owned 640×480 buffer. Returns non-zero on
    /// error (for example when no device is attached).
    pub fn freenect_sync_get_depth(
        depth: *mut *mut std::ffi::c_void,
        timestamp: *mut u32,
        index: c_int,
        fmt: freenect_depth_format,
    ) -> c_int;

    /// Asks device `index` to tilt to `angle` degrees from the horizon (about −31…31).
    /// Returns non-zero on error.
    pub fn freenect_sync_set_tilt_degs(angle: c_int, index: c_int) -> c_int;

    /// Points `*state` to an updated, library-owned tilt state of device `index`. Returns
    /// non-zero on error.
    pub fn freenect_sync_get_tilt_state(
        state: *mut *mut freenect_raw_tilt_state,
        index: c_int,
    ) -> c_int;

    /// Stops the synchronous runloop and closes every device it opened.
    pub fn freenect_sync_stop();

    /// The tilt of a tilt state in degrees from the horizon (positive = up).
    pub fn freenect_get_tilt_degs(state: *mut freenect_raw_tilt_state) -> f64;

    /// Creates a library context in `*ctx` (`usb_ctx` may be null: the library makes its own
    /// USB session). Returns a negative value on failure, leaving `*ctx` null. Under the
    /// fakenect library this reads `FAKENECT_PATH` (and exits the process when it is unset).
    pub fn freenect_init(ctx: *mut *mut freenect_context, usb_ctx: *mut std::ffi::c_void) -> c_int;

    /// Closes every device still open on `ctx` and frees it.
    pub fn freenect_shutdown(ctx: *mut freenect_context) -> c_int;

    /// Sets how much the library prints for `ctx` (`FREENECT_LOG_*`).
    pub fn freenect_set_log_level(ctx: *mut freenect_context, level: freenect_loglevel);

    /// Number of Kinect devices on the bus (negative on a USB error).
    pub fn freenect_num_devices(ctx: *mut freenect_context) -> c_int;

    /// Opens device `index` of `ctx` into `*dev`. Returns non-zero on failure.
    pub fn freenect_open_device(
        ctx: *mut freenect_context,
        dev: *mut *mut freenect_device,
        index: c_int,
    ) -> c_int;

    /// Closes a device opened with `freenect_open_device`.
    pub fn freenect_close_device(dev: *mut freenect_device) -> c_int;

    /// The motor status of a tilt state.
    pub fn freenect_get_tilt_status(
        state: *mut freenect_raw_tilt_state,
    ) -> freenect_tilt_status_code;
}

#[cfg(all(test, not(freenect_missing)))]
mod tests {
    use super::*;

    #[test]
    fn tilt_degrees_of_a_state_come_from_the_encoder() {
        // freenect_get_tilt_degs is pure: half degrees from the encoder.
        let mut s = freenect_raw_tilt_state {
            tilt_angle: 20,
            ..Default::default()
        };
        // SAFETY: `s` is a valid, exclusively borrowed tilt state for the whole call.
        let deg = unsafe { freenect_get_tilt_degs(&raw mut s) };
        assert!((deg - 10.0).abs() < 1e-9, "{deg}");
    }
}
