//! The error of the frame → triangle stages: filtering, back-projection, carving.

/// A frame, a set of frames or a parameter that the frame → triangle stages cannot use.
///
/// Nothing here reads a file: errors of the recorded-scan directory are
/// [`crate::scan::ScanError`], of calibration [`crate::calib::CalibError`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FrameError {
    /// A filter was given no frames.
    #[error("no frames to filter")]
    NoFrames,

    /// A frame's `data` does not hold `width * height` values.
    ///
    /// How to fix: build frames with [`crate::DepthFrame::empty`] or keep `data.len()` in step.
    #[error("frame {index}: {len} values for a {width}x{height} frame")]
    MalformedFrame {
        /// Index of the frame among the filter's input (0 for a single frame).
        index: usize,
        /// Values found.
        len: usize,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },

    /// Frames of one snapshot (or a frame and the intrinsics) disagree on the size.
    #[error("frame {index} is {found_w}x{found_h}, expected {expected_w}x{expected_h}")]
    FrameSizeMismatch {
        /// Index of the offending frame (0 for a single frame).
        index: usize,
        /// Expected width.
        expected_w: u32,
        /// Expected height.
        expected_h: u32,
        /// Width found.
        found_w: u32,
        /// Height found.
        found_h: u32,
    },

    /// Frames of one snapshot disagree on the depth unit, or the unit is not a positive number.
    #[error("frame {index} has depth unit {found} m, expected {expected} m")]
    UnitMismatch {
        /// Index of the offending frame.
        index: usize,
        /// Unit of the first frame (or the configured one).
        expected: f32,
        /// Unit found.
        found: f32,
    },

    /// An argument passed by the caller is out of range (the same name as the other
    /// crates' `InvalidArgument`).
    #[error("invalid argument `{name}`: {reason}")]
    InvalidArgument {
        /// Parameter name.
        name: &'static str,
        /// Why it is refused.
        reason: String,
    },
}
