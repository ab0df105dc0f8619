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
//! ARCHITECTURE.md (section voxoct-depth, "Calibration") explains the method and what
//! is observable.

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
