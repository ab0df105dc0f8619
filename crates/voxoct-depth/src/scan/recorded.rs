//! [`RecordedScan`]: a whole recorded scan in memory.

use std::fs;
use std::path::{Path, PathBuf};

use super::file::default_memory_limit;
use super::frames::{check_sensor_frame, read_png_frame_sized, write_png_frame};
use super::{MANIFEST_FILE, ScanError, ScanManifest};
use crate::atomic::write_atomic;
use crate::{DepthFrame, FrameError, ScannerConfig};

/// A recorded scan read into memory: the manifest and every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedScan {
    /// The scan directory.
    pub dir: PathBuf,
    /// Its manifest.
    pub manifest: ScanManifest,
    /// `frames[k]` are the frames of snapshot `k`, in manifest order, with the sensor's
    /// size and `unit_m = depth_unit_m`.
    pub frames: Vec<Vec<DepthFrame>>,
}

impl RecordedScan {
    /// Reads and validates `dir/scan.toml` and every frame it lists (in parallel with
    /// the `parallel` feature). Errors name the key or the file at fault.
    ///
    /// Every frame path must stay inside `dir` once the symlinks in it are resolved, and
    /// name a regular file; each PNG's header is compared with the sensor's size before
    /// its pixels are decoded; and the scan is refused when its frames would take more
    /// than [`default_memory_limit`] (see [`RecordedScan::open_limited`]).
    pub fn open(dir: impl AsRef<Path>) -> Result<Self, ScanError> {
        Self::open_limited(dir, default_memory_limit())
    }

    /// [`RecordedScan::open`] with the frames' memory limited to `max_bytes`.
    pub fn open_limited(dir: impl AsRef<Path>, max_bytes: u64) -> Result<Self, ScanError> {
        let dir = dir.as_ref();
        let manifest = ScanManifest::load(dir.join(MANIFEST_FILE))?;
        Self::from_manifest(dir, manifest, max_bytes)
    }

    /// [`RecordedScan::open_limited`] with `dir/scan.toml` already read (by
    /// [`ScanManifest::load`]): reads and checks the frames it lists.
    pub fn from_manifest(
        dir: impl AsRef<Path>,
        manifest: ScanManifest,
        max_bytes: u64,
    ) -> Result<Self, ScanError> {
        let dir = dir.as_ref();
        let mpath = dir.join(MANIFEST_FILE);
        let i = manifest.sensor.intrinsics;
        let count: u64 = manifest
            .snapshots
            .iter()
            .map(|s| s.frames.len() as u64)
            .sum();
        let need = count * u64::from(i.width) * u64::from(i.height) * 2;
        if need > max_bytes {
            return Err(ScanError::InvalidValue {
                path: mpath,
                key: "snapshot".into(),
                reason: format!(
                    "{count} frames of {}x{} need {need} bytes of memory, more than the {max_bytes} \
                     allowed",
                    i.width, i.height
                ),
            });
        }
        let root = dir.canonicalize().map_err(|e| ScanError::io(dir, e))?;
        let jobs: Vec<PathBuf> = manifest
            .snapshots
            .iter()
            .flat_map(|s| s.frames.iter().map(|f| dir.join(f)))
            .collect();
        let sensor = manifest.sensor;
        let load = |p: &PathBuf| {
            let real = p.canonicalize().map_err(|e| ScanError::io(p, e))?;
            if !real.starts_with(&root) {
                return Err(ScanError::BadFrameFile {
                    path: p.clone(),
                    reason: "leaves the scan directory through a symbolic link".into(),
                });
            }
            read_png_frame_sized(&real, sensor.depth_unit_m, Some((i.width, i.height))).map_err(
                |e| match e {
                    ScanError::BadFrameFile { reason, .. } => ScanError::BadFrameFile {
                        path: p.clone(),
                        reason,
                    },
                    ScanError::Png { message, .. } => ScanError::Png {
                        path: p.clone(),
                        message,
                    },
                    e => e,
                },
            )
        };
        #[cfg(feature = "parallel")]
        let loaded: Vec<DepthFrame> = {
            use rayon::prelude::*;
            jobs.par_iter().map(load).collect::<Result<_, _>>()?
        };
        #[cfg(not(feature = "parallel"))]
        let loaded: Vec<DepthFrame> = jobs.iter().map(load).collect::<Result<_, _>>()?;
        let mut it = loaded.into_iter();
        let frames = manifest
            .snapshots
            .iter()
            .map(|s| it.by_ref().take(s.frames.len()).collect())
            .collect();
        Ok(Self {
            dir: dir.to_owned(),
            manifest,
            frames,
        })
    }

    /// Writes a scan directory: every frame at its manifest path (directories created as
    /// needed), then `scan.toml` atomically. `frames[k]` must match snapshot `k`'s list, and
    /// every frame the sensor's size and unit.
    pub fn write(
        dir: impl AsRef<Path>,
        manifest: &ScanManifest,
        frames: &[Vec<DepthFrame>],
    ) -> Result<(), ScanError> {
        let dir = dir.as_ref();
        if manifest.snapshots.is_empty() {
            return Err(ScanError::NoSnapshots {
                path: dir.join(MANIFEST_FILE),
            });
        }
        if frames.len() != manifest.snapshots.len() {
            return Err(ScanError::ScanMismatch {
                reason: format!(
                    "{} snapshots in the manifest, {} frame lists given",
                    manifest.snapshots.len(),
                    frames.len()
                ),
            });
        }
        for (k, (s, fr)) in manifest.snapshots.iter().zip(frames).enumerate() {
            if s.frames.len() != fr.len() {
                return Err(ScanError::ScanMismatch {
                    reason: format!(
                        "snapshot {k}: {} frame files in the manifest, {} frames given",
                        s.frames.len(),
                        fr.len()
                    ),
                });
            }
            for f in fr {
                check_sensor_frame(&manifest.sensor, k, f)?;
            }
        }
        // Render the manifest first: a bad path fails before any file is written.
        let text = manifest.to_toml_string()?;
        fs::create_dir_all(dir).map_err(|e| ScanError::io(dir, e))?;
        for (s, fr) in manifest.snapshots.iter().zip(frames) {
            for (p, f) in s.frames.iter().zip(fr) {
                let path = dir.join(p);
                if let Some(parent) = path.parent() {
                    fs::create_dir_all(parent).map_err(|e| ScanError::io(parent, e))?;
                }
                write_png_frame(&path, f)?;
            }
        }
        let mpath = dir.join(MANIFEST_FILE);
        write_atomic(&mpath, text.as_bytes()).map_err(|e| ScanError::io(&mpath, e))
    }

    /// Replaces the sensor, rig and clip settings by `config` (a `--config` override).
    /// The frames take the new depth unit; the size must stay the frames' size.
    pub fn apply_config(&mut self, config: &ScannerConfig) -> Result<(), ScanError> {
        let i = config.sensor.intrinsics;
        let m = self.manifest.sensor.intrinsics;
        if (i.width, i.height) != (m.width, m.height) {
            return Err(FrameError::FrameSizeMismatch {
                index: 0,
                expected_w: i.width,
                expected_h: i.height,
                found_w: m.width,
                found_h: m.height,
            }
            .into());
        }
        self.manifest.sensor = config.sensor;
        self.manifest.rig = config.rig;
        self.manifest.clip = config.clip;
        for f in self.frames.iter_mut().flatten() {
            f.unit_m = config.sensor.depth_unit_m;
        }
        Ok(())
    }

    /// Number of snapshots.
    #[must_use]
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether the scan has no snapshot (never true for an opened scan).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }
}
