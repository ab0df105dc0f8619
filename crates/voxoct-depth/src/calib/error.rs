//! The error of calibration.

use crate::FrameError;

/// What can go wrong while calibrating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibError {
    /// Filtering or back-projecting the frames failed.
    #[error(transparent)]
    Frame(#[from] FrameError),

    /// Too few points to fit.
    ///
    /// How to fix: check that the starting rig is within a few centimetres and degrees, and
    /// that the scan shows the platform (for the plane) or an object (for the axis).
    #[error("{what}: {found} usable points, at least {needed} needed")]
    TooFewPoints {
        /// What was being fitted.
        what: &'static str,
        /// Points found.
        found: usize,
        /// Points needed.
        needed: usize,
    },

    /// RANSAC found no plane with enough inliers.
    ///
    /// How to fix: scan the empty platform, or raise [`super::RansacOptions::threshold_m`] for a
    /// noisy sensor.
    #[error("no plane found: the best candidate has {inliers} inliers of {points} points")]
    NoPlane {
        /// Inliers of the best candidate.
        inliers: usize,
        /// Points tried.
        points: usize,
    },

    /// The axis needs snapshots at two or more angles, with overlapping views.
    ///
    /// How to fix: calibrate on a scan over a full turn with at most 90° between snapshots.
    #[error("axis calibration: {reason}")]
    Snapshots {
        /// What is missing.
        reason: String,
    },

    /// An option out of range (the same name as the other crates' `InvalidArgument`).
    #[error("invalid argument `{name}`: {reason}")]
    InvalidArgument {
        /// The option.
        name: &'static str,
        /// Why it is refused.
        reason: String,
    },
}
