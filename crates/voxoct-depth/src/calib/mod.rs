//! Rig calibration from recorded scans: the platform plane and the turntable axis.
//!
//! - [`calibrate`]: the whole calibration of a [`crate::ScannerConfig`]'s rig from the
//!   filtered snapshots of a scan ([`CalibSnapshot`]), options in [`CalibOptions`];
//!   [`calibrate_with_platform`] takes the tilt and height from a scan of the empty platform;
//! - its two steps, [`calibrate_platform`] ([`PlatformOptions`], [`PlatformFit`],
//!   [`RansacOptions`], [`PlaneFit`]) and [`calibrate_axis`] ([`AxisOptions`]);
//! - [`alignment_residual`]: how much the snapshots disagree under a rig;
//! - [`CalibError`].
//!
//! The rig ([`Rig`]) has four numbers: the tilt and the sensor position `(x, y, z)` in the
//! platform frame. Two measurements recover them:
//!
//! 1. **The platform plane** ([`calibrate_platform`]): the platform's top is the plane
//!    `y = 0` of the platform frame. Its points (picked near `y = 0` under the starting
//!    rig, so the floor and the object's upper part stay out) are fitted by RANSAC, then by
//!    least squares on the inliers ([`fit_plane_ransac`]). The plane's normal in the camera
//!    frame is the tilt (and the roll, which the rig model takes as 0 and is only
//!    reported); its distance to the optical centre is the sensor height `y`. An empty
//!    platform is best, but the turntable disk around an object works too.
//! 2. **The turntable axis** ([`calibrate_axis`]): with a wrong `x` or `z` the snapshots,
//!    turned into the common frame, disagree. The disagreement is measured between every
//!    pair of snapshots at most [`AxisOptions::max_pair_angle_deg`] apart: each sampled
//!    point of one snapshot is taken into the other's camera frame, projected to a pixel
//!    (projective association), and its distance to the plane of that pixel (normal from
//!    the pixel grid) goes through the robust Geman–McClure loss. A [`nelder_mead`]
//!    minimiser runs on it from coarse to fine (the loss's scale shrinks from 6 to 1 mm).
//!
//! What is observable: `x` and `z` from the disagreement; the tilt from the plane and
//! (weakly, through the axis's inclination) from the disagreement — [`AxisOptions::free_tilt`]
//! adds it to the minimisation; `y` **only** from the plane, since a shift along the axis
//! changes no snapshot's agreement with another. The roll is assumed 0.
//!
//! The sensor's `z` is the weakest of the three: between snapshots 45° apart a shift of the
//! axis along the line of sight moves the object mostly sideways, which only surfaces seen
//! obliquely and the object's outline reveal. Points within three pixels of a depth edge
//! are left out all the same (flying pixels there sit behind the surface, a bias `z` would
//! absorb), so the object should cover a good part of the frame.
//!
//! Measured (`tests/calibration.rs` at the workspace root, simulated Kinect v1 scans of 8
//! snapshots × 3 frames, start off by up to ±10 mm and ±2°): sensor position within 0.3 mm,
//! tilt within 0.03°; on the bunny scan (8 × 10 frames), within 0.2 mm and 0.02°, in about
//! 3 s on one core.
//!
//! Keep the clip box generous while calibrating: a wrong rig moves the object, so the
//! axis step widens the scan's clip box by [`AxisOptions::margin_m`] and adds the platform
//! top, whose disagreement under a wrong tilt also helps.

mod axis;
mod error;
mod optimise;
mod plane;

pub use axis::{
    AxisOptions, CalibOptions, Calibration, RESIDUAL_CAP_M, alignment_residual, calibrate,
    calibrate_axis, calibrate_with_platform,
};
pub use error::CalibError;
pub use plane::{PlaneFit, PlatformFit, PlatformOptions, RansacOptions, calibrate_platform};

use crate::DepthFrame;
#[cfg(feature = "scan-dir")]
use crate::{FrameError, filter::FilterChain, scan::RecordedScan};

/// One filtered snapshot to calibrate on: the turntable angle and the filtered frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibSnapshot {
    /// Turntable angle, degrees.
    pub angle_deg: f32,
    /// The snapshot's frames filtered into one (use [`DepthFrame::unit_m`]).
    pub frame: DepthFrame,
}

impl CalibSnapshot {
    /// Every snapshot of a recorded scan, filtered by `chain`. Feature `scan-dir`.
    #[cfg(feature = "scan-dir")]
    pub fn from_scan(scan: &RecordedScan, chain: &FilterChain) -> Result<Vec<Self>, FrameError> {
        scan.manifest
            .snapshots
            .iter()
            .zip(&scan.frames)
            .map(|(s, frames)| {
                Ok(Self {
                    angle_deg: s.angle_deg,
                    frame: chain.apply(frames)?,
                })
            })
            .collect()
    }
}
