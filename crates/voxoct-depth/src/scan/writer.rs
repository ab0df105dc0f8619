//! [`ScanWriter`]: a scan directory written snapshot by snapshot as a capture runs.

use std::fs;
use std::path::{Path, PathBuf};

use super::frames::{check_sensor_frame, write_png_frame};
use super::{MANIFEST_FILE, MAX_ABS_ANGLE_DEG, ScanError, ScanManifest, SnapshotEntry};
use crate::{DepthFrame, FrameError, ScannerConfig};

/// Writes a scan directory snapshot by snapshot, as a capture runs: each
/// [`ScanWriter::add_snapshot`] writes its frames as `frames/sNNN_fMM.png` and rewrites
/// `scan.toml` atomically, so an interrupted capture leaves a readable scan of the
/// snapshots taken so far.
#[derive(Debug)]
pub struct ScanWriter {
    dir: PathBuf,
    manifest: ScanManifest,
}

impl ScanWriter {
    /// Creates `dir` (and `dir/frames`) for a scan with these settings.
    pub fn create(dir: impl AsRef<Path>, config: ScannerConfig) -> Result<Self, ScanError> {
        let dir = dir.as_ref().to_owned();
        let frames = dir.join("frames");
        fs::create_dir_all(&frames).map_err(|e| ScanError::io(&frames, e))?;
        Ok(Self {
            dir,
            manifest: ScanManifest::new(config),
        })
    }

    /// Writes one snapshot's frames and the updated manifest.
    pub fn add_snapshot(&mut self, angle_deg: f32, frames: &[DepthFrame]) -> Result<(), ScanError> {
        if !(angle_deg.is_finite() && angle_deg.abs() <= MAX_ABS_ANGLE_DEG) {
            return Err(FrameError::InvalidArgument {
                name: "angle_deg",
                reason: format!("{angle_deg} is not within ±{MAX_ABS_ANGLE_DEG}°"),
            }
            .into());
        }
        if frames.is_empty() {
            return Err(FrameError::NoFrames.into());
        }
        let k = self.manifest.snapshots.len();
        for f in frames {
            check_sensor_frame(&self.manifest.sensor, k, f)?;
        }
        let mut names = Vec::with_capacity(frames.len());
        for (j, f) in frames.iter().enumerate() {
            let rel = PathBuf::from(format!("frames/s{k:03}_f{j:02}.png"));
            write_png_frame(&self.dir.join(&rel), f)?;
            names.push(rel);
        }
        self.manifest.snapshots.push(SnapshotEntry {
            angle_deg,
            frames: names,
        });
        self.manifest.save(self.dir.join(MANIFEST_FILE))
    }

    /// The manifest so far.
    #[must_use]
    pub fn manifest(&self) -> &ScanManifest {
        &self.manifest
    }

    /// The scan directory.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Ends the scan; errors when no snapshot was added (the directory would not be a scan).
    pub fn finish(self) -> Result<ScanManifest, ScanError> {
        if self.manifest.snapshots.is_empty() {
            return Err(ScanError::NoSnapshots {
                path: self.dir.join(MANIFEST_FILE),
            });
        }
        Ok(self.manifest)
    }
}
