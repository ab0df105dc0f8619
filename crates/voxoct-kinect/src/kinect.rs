//! Live Kinect v1 through libfreenect's synchronous wrapper (feature `freenect`).
//!
//! This module is the only place of the crate with `unsafe` code: a thin wrapper over
//! `libfreenect-sys`, every block with its `// SAFETY:` argument.

use std::time::{Duration, Instant};

use voxoct_depth::{DepthFrame, Intrinsics};

use crate::{DepthSource, KinectDepth, SourceError};

/// Frame size of the Kinect v1 depth stream in the medium resolution the sync API uses.
const WIDTH: u32 = 640;
const HEIGHT: u32 = 480;

/// How [`KinectSource::open_with`] opens the device.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct KinectOptions {
    /// Which depth stream to read (default: millimetres converted by the device's own
    /// calibration).
    pub depth: KinectDepth,
    /// Let libfreenect print its own messages (log level `FREENECT_LOG_INFO`) while it looks
    /// for the device; by default only fatal ones (`FREENECT_LOG_FATAL`), so a missing Kinect
    /// is reported by our one-line [`SourceError::NoKinect`] alone.
    pub verbose: bool,
}

/// A live Kinect v1, read through `libfreenect_sync` in one of the [`KinectDepth`] formats,
/// always delivered as millimetre frames (depth along the optical axis, 0 = no reading).
///
/// # Opening, and libfreenect's messages
/// [`KinectSource::open_with`] first probes for the device through a libfreenect context of
/// its own (`freenect_init`, `freenect_num_devices`, `freenect_open_device`, closed again at
/// once) whose log level it sets with `freenect_set_log_level` — quiet unless
/// [`KinectOptions::verbose`]. The synchronous wrapper keeps its own context private, so its
/// log level cannot be set; the probe means it is only asked for a device that is there,
/// and its "Failed to open camera subdevice…" and "Error: Invalid index" lines no longer
/// surround our error when there is none. Then it grabs one frame (which is discarded) to
/// start the stream: **opening consumes one frame**.
///
/// # Under the fakenect library
/// Loaded with `LD_LIBRARY_PATH=/usr/lib/<triple>/fakenect` and `FAKENECT_PATH=DIR`, the
/// same calls replay a recording (see [`crate::FakenectWriter`]). libfreenect 0.5's fakenect
/// serves only [`KinectDepth::Raw`] (asking for millimetres or registered depth aborts the
/// process in an assertion); it reads one `INDEX.txt` line per runloop turn, sleeping to
/// reproduce the recorded frame gaps whether or not anyone grabs, and the synchronous wrapper
/// keeps only the newest frame — a consumer slower than the recording loses frames. At the
/// end of `INDEX.txt` (libfreenect 0.5) the runloop prints "Warning: No more lines", ends and
/// frees the device's buffers, and a later grab crashes the process (seen: a segmentation
/// fault) or waits for ever; libfreenect 0.6+ starts the recording again instead
/// (unless `FAKENECT_LOOP=0`). A recording for a live scan therefore holds the opening frame,
/// the scan's frames, and a few frames more.
///
/// libfreenect_sync keeps one global runloop thread for all devices: [`DepthSource::shutdown`]
/// (also run on drop) calls `freenect_sync_stop`, which closes every Kinect the process
/// opened through it. Use one `KinectSource` per device index.
///
/// # Timeouts
/// `freenect_sync_get_depth` blocks until the device delivers a frame (every 33 ms while it
/// streams) and cannot be interrupted: the `timeout` of [`DepthSource::grab`] cannot cut a
/// wait short. What it does: a frame that took longer than `timeout` to arrive is discarded
/// and [`SourceError::Timeout`] returned, so a caller notices a stalled stream after the fact.
/// A device unplugged mid-stream can block the call indefinitely (a libfreenect limitation).
#[derive(Debug)]
pub struct KinectSource {
    index: i32,
    depth: KinectDepth,
    intrinsics: Intrinsics,
    running: bool,
}

impl KinectSource {
    /// Opens Kinect number `index` (0 = the first) in millimetre mode, quietly, and waits for
    /// its first depth frame: [`KinectSource::open_with`] with the default options.
    ///
    /// # Errors
    /// As [`KinectSource::open_with`].
    pub fn open(index: i32) -> Result<Self, SourceError> {
        Self::open_with(index, KinectOptions::default())
    }

    /// Opens Kinect number `index` (0 = the first) reading `options.depth`, and waits for its
    /// first depth frame (consumed; see the type's docs).
    ///
    /// # Errors
    /// [`SourceError::NoKinect`] when no device answers (libfreenect returns quickly then, it
    /// does not hang); [`SourceError::FreenectUnavailable`] when libfreenect was not found at
    /// build time; [`SourceError::Config`] for a negative index, or for a mode other than
    /// [`KinectDepth::Raw`] while `FAKENECT_PATH` is set (libfreenect 0.5's fakenect library
    /// would abort the process).
    pub fn open_with(index: i32, options: KinectOptions) -> Result<Self, SourceError> {
        if index < 0 {
            return Err(SourceError::Config {
                field: "index",
                message: format!("device index {index} is negative"),
            });
        }
        if options.depth != KinectDepth::Raw && std::env::var_os("FAKENECT_PATH").is_some() {
            return Err(SourceError::Config {
                field: "depth",
                message: format!(
                    "FAKENECT_PATH is set, so libfreenect's fakenect library is meant to answer, \
                     and libfreenect 0.5's serves only raw 11-bit depth (asking for {} aborts \
                     the process); use raw depth (scan --kinect-depth raw)",
                    options.depth
                ),
            });
        }
        sys::probe(index, options.verbose)?;
        let mut source = Self {
            index,
            depth: options.depth,
            intrinsics: Intrinsics::KINECT_V1,
            running: true,
        };
        match source.grab_frame() {
            Ok(_) => Ok(source),
            Err(SourceError::Device { code, .. }) => {
                source.stop();
                Err(SourceError::NoKinect { index, code })
            }
            Err(e) => {
                source.stop();
                Err(e)
            }
        }
    }

    /// Whether libfreenect was found when this crate was built (without it, [`KinectSource::open`]
    /// always returns [`SourceError::FreenectUnavailable`]).
    #[must_use]
    pub fn library_available() -> bool {
        libfreenect_sys::AVAILABLE
    }

    /// Replaces the nominal intrinsics (f = 580 px) by calibrated ones of the same size.
    ///
    /// # Errors
    /// [`SourceError::Config`] when the size is not 640×480.
    pub fn with_intrinsics(mut self, intrinsics: Intrinsics) -> Result<Self, SourceError> {
        if (intrinsics.width, intrinsics.height) != (WIDTH, HEIGHT) {
            return Err(SourceError::Config {
                field: "intrinsics",
                message: "the Kinect v1 depth stream is 640x480".into(),
            });
        }
        self.intrinsics = intrinsics;
        Ok(self)
    }

    /// The device index.
    #[must_use]
    pub fn index(&self) -> i32 {
        self.index
    }

    /// The depth stream being read.
    #[must_use]
    pub fn depth_mode(&self) -> KinectDepth {
        self.depth
    }

    /// Asks the tilt motor to pitch to `deg` degrees from the horizon (positive = UP, the
    /// device's convention; about −31…31). Returns before the motor has finished moving.
    ///
    /// # Errors
    /// [`SourceError::Device`] when libfreenect reports an error.
    pub fn set_motor_tilt_deg(&mut self, deg: i32) -> Result<(), SourceError> {
        self.set_tilt(deg)
    }

    fn stop(&mut self) {
        if self.running {
            self.running = false;
            sys::stop();
        }
    }
}

impl Drop for KinectSource {
    fn drop(&mut self) {
        self.stop();
    }
}

impl DepthSource for KinectSource {
    fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// Blocks until the next frame; see the type's docs for what `timeout` can do.
    fn grab(&mut self, timeout: Duration) -> Result<DepthFrame, SourceError> {
        let start = Instant::now();
        let frame = self.grab_frame()?;
        if start.elapsed() > timeout {
            return Err(SourceError::Timeout(timeout));
        }
        Ok(frame)
    }

    /// The motor's tilt as pitch DOWN in degrees (the negated device angle), `None` when the
    /// state cannot be read.
    fn tilt_deg(&mut self) -> Option<f32> {
        self.tilt().map(|deg| -(deg as f32))
    }

    fn shutdown(&mut self) -> Result<(), SourceError> {
        self.stop();
        Ok(())
    }
}

#[cfg(not(freenect_missing))]
#[allow(unsafe_code)]
mod sys {
    use std::ffi::c_void;
    use std::ptr;

    use libfreenect_sys as ffi;

    use super::{HEIGHT, KinectSource, WIDTH};
    use crate::fakenect::raw_disparity_to_mm;
    use crate::{KinectDepth, SourceError};
    use voxoct_depth::DepthFrame;

    /// Looks for device `index` through a context of our own, at a log level we choose, and
    /// releases it again (see `KinectSource`'s docs).
    pub(super) fn probe(index: i32, verbose: bool) -> Result<(), SourceError> {
        let mut ctx: *mut ffi::freenect_context = ptr::null_mut();
        // SAFETY: the out-pointer is valid for writes; a null USB context asks libfreenect to
        // make its own.
        let code = unsafe { ffi::freenect_init(&raw mut ctx, ptr::null_mut()) };
        if code < 0 || ctx.is_null() {
            return Err(SourceError::NoKinect {
                index,
                code: if code < 0 { code } else { -1 },
            });
        }
        let level = if verbose {
            ffi::FREENECT_LOG_INFO
        } else {
            ffi::FREENECT_LOG_FATAL
        };
        // SAFETY: `ctx` is the live context freenect_init just returned; it is shut down
        // exactly once below and not used afterwards.
        let result = unsafe {
            ffi::freenect_set_log_level(ctx, level);
            let count = ffi::freenect_num_devices(ctx);
            if count <= index {
                Err(SourceError::NoKinect {
                    index,
                    code: count.min(0),
                })
            } else {
                let mut dev: *mut ffi::freenect_device = ptr::null_mut();
                let code = ffi::freenect_open_device(ctx, &raw mut dev, index);
                if code != 0 || dev.is_null() {
                    Err(SourceError::NoKinect {
                        index,
                        code: if code == 0 { -1 } else { code },
                    })
                } else {
                    ffi::freenect_close_device(dev);
                    Ok(())
                }
            }
        };
        // SAFETY: see above; no device of `ctx` is left open.
        unsafe { ffi::freenect_shutdown(ctx) };
        result
    }

    pub(super) fn stop() {
        // SAFETY: freenect_sync_stop takes no arguments and is a no-op when the runloop is
        // not running.
        unsafe { ffi::freenect_sync_stop() };
    }

    impl KinectSource {
        pub(super) fn grab_frame(&mut self) -> Result<DepthFrame, SourceError> {
            let format = match self.depth {
                KinectDepth::Mm => ffi::FREENECT_DEPTH_MM,
                KinectDepth::Raw => ffi::FREENECT_DEPTH_11BIT,
                KinectDepth::Registered => ffi::FREENECT_DEPTH_REGISTERED,
            };
            let mut data: *mut c_void = ptr::null_mut();
            let mut timestamp = 0u32;
            // SAFETY: both out-pointers are valid for writes for the duration of the call;
            // the format is a valid `freenect_depth_format`.
            let code = unsafe {
                ffi::freenect_sync_get_depth(&raw mut data, &raw mut timestamp, self.index, format)
            };
            let n = (WIDTH * HEIGHT) as usize;
            if code != 0 || data.is_null() || !data.cast::<u16>().is_aligned() {
                return Err(SourceError::Device {
                    call: "freenect_sync_get_depth",
                    code: if code == 0 { -1 } else { code },
                });
            }
            // SAFETY: on success libfreenect_sync hands out its own buffer of one
            // medium-resolution (640×480) frame of `uint16_t` (all three formats asked for
            // are one `uint16_t` per pixel), checked non-null and aligned above; it stays
            // valid until the next call for this index, and we copy it out before returning.
            let pixels = unsafe { std::slice::from_raw_parts(data.cast::<u16>().cast_const(), n) };
            let mut frame = DepthFrame::empty(WIDTH, HEIGHT, 0.001);
            if self.depth == KinectDepth::Raw {
                for (out, &raw) in frame.data.iter_mut().zip(pixels) {
                    *out = raw_disparity_to_mm(raw);
                }
            } else {
                for (out, &mm) in frame.data.iter_mut().zip(pixels) {
                    *out = if mm > ffi::FREENECT_DEPTH_MM_MAX_VALUE {
                        0
                    } else {
                        mm
                    };
                }
            }
            Ok(frame)
        }

        pub(super) fn tilt(&mut self) -> Option<f64> {
            let mut state: *mut ffi::freenect_raw_tilt_state = ptr::null_mut();
            // SAFETY: the out-pointer is valid for writes during the call.
            let code = unsafe { ffi::freenect_sync_get_tilt_state(&raw mut state, self.index) };
            if code != 0 || state.is_null() {
                return None;
            }
            // SAFETY: on success `state` points to the library's tilt state for this device,
            // valid until the next sync call; freenect_get_tilt_degs only reads it.
            Some(unsafe { ffi::freenect_get_tilt_degs(state) })
        }

        pub(super) fn set_tilt(&mut self, deg: i32) -> Result<(), SourceError> {
            // SAFETY: plain integer arguments.
            let code = unsafe { ffi::freenect_sync_set_tilt_degs(deg, self.index) };
            if code == 0 {
                Ok(())
            } else {
                Err(SourceError::Device {
                    call: "freenect_sync_set_tilt_degs",
                    code,
                })
            }
        }
    }
}

/// Without libfreenect at build time every call reports that it is unavailable.
#[cfg(freenect_missing)]
mod sys {
    use super::KinectSource;
    use crate::SourceError;
    use voxoct_depth::DepthFrame;

    pub(super) fn probe(_index: i32, _verbose: bool) -> Result<(), SourceError> {
        Err(SourceError::FreenectUnavailable)
    }

    pub(super) fn stop() {}

    impl KinectSource {
        pub(super) fn grab_frame(&mut self) -> Result<DepthFrame, SourceError> {
            Err(SourceError::FreenectUnavailable)
        }

        pub(super) fn tilt(&mut self) -> Option<f64> {
            None
        }

        pub(super) fn set_tilt(&mut self, _deg: i32) -> Result<(), SourceError> {
            Err(SourceError::FreenectUnavailable)
        }
    }
}
