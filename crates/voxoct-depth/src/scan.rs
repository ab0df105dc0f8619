//! The recorded-scan directory (`voxoct-scan`, version 1; see SCAN_FORMAT.md) and the
//! scanner configuration file.

use std::fs;
use std::io::{BufReader, BufWriter};
use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Serialize;
use toml::{Table, Value};

use crate::error::DepthError;
use crate::filter::check_frame;
use crate::snapshot::write_atomic;
use crate::types::{ClipBox, DepthFrame, Intrinsics, Rig};

/// The `format` value of a recorded scan.
pub const SCAN_FORMAT: &str = "voxoct-scan";
/// The `version` this build reads and writes.
pub const SCAN_VERSION: u32 = 1;
/// The manifest's file name inside a scan directory.
pub const MANIFEST_FILE: &str = "scan.toml";
/// Largest `|angle_deg|` accepted in a manifest (ten turns).
pub const MAX_ABS_ANGLE_DEG: f32 = 3600.0;
/// Largest frame width or height accepted in a manifest.
pub const MAX_FRAME_SIDE: u32 = 16384;

/// The memory a program should allow itself by default: half the machine's memory, and no
/// more than three quarters of the process's address-space limit (`ulimit -v`). Linux
/// figures; 8 GiB where they cannot be read.
#[must_use]
pub fn default_memory_limit() -> u64 {
    let meminfo = fs::read_to_string("/proc/meminfo").unwrap_or_default();
    let total = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemTotal:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        .map_or(16 << 30, |kb| kb * 1024);
    let limits = fs::read_to_string("/proc/self/limits").unwrap_or_default();
    let address_space = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))
        .and_then(|l| l.split_whitespace().nth(3))
        .and_then(|v| v.parse::<u64>().ok())
        .unwrap_or(u64::MAX);
    (total / 2).min(address_space / 4 * 3)
}

/// The largest `scan.toml` or settings file read: 16 MiB (a manifest of 100 000 frames is
/// about 4 MiB).
pub const MAX_SETTINGS_BYTES: u64 = 16 << 20;

/// Reads a settings or manifest file of at most [`MAX_SETTINGS_BYTES`], so that
/// `/dev/zero` cannot exhaust memory; unless `pipes` it must be a regular file (symlinks
/// followed), so that a FIFO in a scan directory cannot hang the reader.
fn read_settings_text(path: &Path, pipes: bool) -> Result<String, DepthError> {
    use std::io::Read;
    let meta = fs::metadata(path).map_err(|e| DepthError::io(path, e))?;
    let refuse = |reason: String| DepthError::BadFile {
        path: path.to_owned(),
        reason,
    };
    if meta.is_dir() || !(meta.is_file() || pipes) {
        return Err(refuse(
            "not a regular file (a directory, device or FIFO)".into(),
        ));
    }
    let mut text = String::new();
    fs::File::open(path)
        .and_then(|f| f.take(MAX_SETTINGS_BYTES + 1).read_to_string(&mut text))
        .map_err(|e| DepthError::io(path, e))?;
    if text.len() as u64 > MAX_SETTINGS_BYTES {
        return Err(refuse(format!(
            "larger than the {MAX_SETTINGS_BYTES} bytes a settings file may have"
        )));
    }
    Ok(text)
}

/// Whether `p` is a relative path that stays inside its directory when read lexically
/// (no root, no prefix, no `..` above the start).
fn stays_inside(p: &Path) -> bool {
    use std::path::Component;
    let mut depth = 0i64;
    for c in p.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => {
                depth -= 1;
                if depth < 0 {
                    return false;
                }
            }
            Component::RootDir | Component::Prefix(_) => return false,
        }
    }
    depth > 0
}

/// The `[sensor]` table: intrinsics and the depth unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorConfig {
    /// Image size, focal lengths and principal point.
    pub intrinsics: Intrinsics,
    /// Metres per stored depth value (0.001 = millimetres).
    pub depth_unit_m: f32,
}

impl Default for SensorConfig {
    /// Kinect v1 intrinsics, millimetre units.
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::KINECT_V1,
            depth_unit_m: 0.001,
        }
    }
}

/// The settings of a scanner: the `[sensor]`, `[rig]` and `[clip]` tables, either in a
/// scan's manifest or in a file of their own (which overrides a recorded or live scan's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScannerConfig {
    /// `[sensor]`.
    pub sensor: SensorConfig,
    /// `[rig]`.
    pub rig: Rig,
    /// `[clip]`.
    pub clip: ClipBox,
}

impl Default for ScannerConfig {
    /// The example of SCAN_FORMAT.md: Kinect v1, tilt 19.65°, sensor at (0, 0.30, 0.7) m,
    /// clip box ±0.15 m wide, 3 mm to 0.40 m high.
    fn default() -> Self {
        Self {
            sensor: SensorConfig::default(),
            rig: Rig {
                tilt_deg: 19.65,
                sensor_position_m: Vec3::new(0.0, 0.30, 0.7),
            },
            clip: ClipBox {
                min: Vec3::new(-0.15, 0.003, -0.15),
                max: Vec3::new(0.15, 0.40, 0.15),
            },
        }
    }
}

impl ScannerConfig {
    /// Reads a configuration file (TOML with `[sensor]`, `[rig]`, `[clip]`; other keys,
    /// such as a scan manifest's `[[snapshot]]`, are ignored).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, DepthError> {
        let path = path.as_ref();
        // A pipe is allowed here (`--config <(…)`): it is the user's own choice.
        let text = read_settings_text(path, true)?;
        Self::from_toml_str(&text, path)
    }

    /// Parses a configuration from TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &Path) -> Result<Self, DepthError> {
        let cx = Ctx { path: origin };
        let table = cx.parse(text)?;
        cx.config(&table)
    }

    /// The configuration as TOML text (the three tables).
    pub fn to_toml_string(&self) -> Result<String, DepthError> {
        #[derive(Serialize)]
        struct Raw {
            sensor: RawSensor,
            rig: RawRig,
            clip: RawClip,
        }
        let raw = Raw {
            sensor: RawSensor::from(&self.sensor),
            rig: RawRig::from(&self.rig),
            clip: RawClip::from(&self.clip),
        };
        to_toml(&raw)
    }
}

/// One `[[snapshot]]`: a turntable angle and the frames taken there.
#[derive(Debug, Clone, PartialEq)]
pub struct SnapshotEntry {
    /// Turntable angle, degrees.
    pub angle_deg: f32,
    /// Frame files, relative to the scan directory.
    pub frames: Vec<PathBuf>,
}

/// The contents of `scan.toml`.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanManifest {
    /// `[sensor]`.
    pub sensor: SensorConfig,
    /// `[rig]`.
    pub rig: Rig,
    /// `[clip]`.
    pub clip: ClipBox,
    /// The `[[snapshot]]` list, in capture order.
    pub snapshots: Vec<SnapshotEntry>,
}

impl ScanManifest {
    /// A manifest without snapshots for the given scanner settings.
    #[must_use]
    pub fn new(config: ScannerConfig) -> Self {
        Self {
            sensor: config.sensor,
            rig: config.rig,
            clip: config.clip,
            snapshots: Vec::new(),
        }
    }

    /// The scanner settings part.
    #[must_use]
    pub fn config(&self) -> ScannerConfig {
        ScannerConfig {
            sensor: self.sensor,
            rig: self.rig,
            clip: self.clip,
        }
    }

    /// Reads and validates a `scan.toml`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DepthError> {
        let path = path.as_ref();
        let text = read_settings_text(path, false)?;
        Self::from_toml_str(&text, path)
    }

    /// Parses and validates manifest text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &Path) -> Result<Self, DepthError> {
        let cx = Ctx { path: origin };
        let t = cx.parse(text)?;
        match t.get("format") {
            None => return Err(cx.missing("format")),
            Some(Value::String(s)) if s == SCAN_FORMAT => {}
            Some(Value::String(s)) => {
                return Err(DepthError::WrongFormat {
                    path: origin.to_owned(),
                    found: s.clone(),
                });
            }
            Some(v) => return Err(cx.wrong("format", "a string", v)),
        }
        match t.get("version") {
            None => return Err(cx.missing("version")),
            Some(Value::Integer(v)) if *v == i64::from(SCAN_VERSION) => {}
            Some(Value::Integer(v)) => {
                return Err(DepthError::UnsupportedVersion {
                    path: origin.to_owned(),
                    found: *v,
                    supported: SCAN_VERSION,
                });
            }
            Some(v) => return Err(cx.wrong("version", "an integer", v)),
        }
        let config = cx.config(&t)?;
        let list = match t.get("snapshot") {
            None => {
                return Err(DepthError::NoSnapshots {
                    path: origin.to_owned(),
                });
            }
            Some(Value::Array(a)) => a,
            Some(v) => return Err(cx.wrong("snapshot", "an array of tables `[[snapshot]]`", v)),
        };
        if list.is_empty() {
            return Err(DepthError::NoSnapshots {
                path: origin.to_owned(),
            });
        }
        let mut snapshots = Vec::with_capacity(list.len());
        for (i, item) in list.iter().enumerate() {
            let key = format!("snapshot[{i}]");
            let Value::Table(s) = item else {
                return Err(cx.wrong(&key, "a table", item));
            };
            let angle_deg = cx.num(s, &key, "angle_deg")?;
            if angle_deg.abs() > MAX_ABS_ANGLE_DEG {
                return Err(cx.invalid(
                    &format!("{key}.angle_deg"),
                    format!("{angle_deg}° is outside ±{MAX_ABS_ANGLE_DEG}°"),
                ));
            }
            let fkey = format!("{key}.frames");
            let frames = match s.get("frames") {
                None => return Err(cx.missing(&fkey)),
                Some(Value::Array(a)) => a,
                Some(v) => return Err(cx.wrong(&fkey, "an array of file names", v)),
            };
            if frames.is_empty() {
                return Err(cx.invalid(&fkey, "a snapshot needs at least one frame".into()));
            }
            let frames = frames
                .iter()
                .enumerate()
                .map(|(j, f)| match f {
                    Value::String(p) if !p.is_empty() && stays_inside(Path::new(p)) => {
                        Ok(PathBuf::from(p))
                    }
                    Value::String(p) if !p.is_empty() => Err(cx.invalid(
                        &format!("{fkey}[{j}]"),
                        format!(
                            "{p:?} is not a relative path inside the scan directory; frame \
                             paths are relative to the directory of scan.toml"
                        ),
                    )),
                    Value::String(_) => {
                        Err(cx.invalid(&format!("{fkey}[{j}]"), "empty file name".into()))
                    }
                    v => Err(cx.wrong(&format!("{fkey}[{j}]"), "a file name (string)", v)),
                })
                .collect::<Result<Vec<_>, _>>()?;
            snapshots.push(SnapshotEntry { angle_deg, frames });
        }
        Ok(Self {
            snapshots,
            ..Self::new(config)
        })
    }

    /// The manifest as TOML text.
    pub fn to_toml_string(&self) -> Result<String, DepthError> {
        #[derive(Serialize)]
        struct Raw {
            format: &'static str,
            version: u32,
            sensor: RawSensor,
            rig: RawRig,
            clip: RawClip,
            snapshot: Vec<RawSnapshot>,
        }
        #[derive(Serialize)]
        struct RawSnapshot {
            angle_deg: f64,
            frames: Vec<String>,
        }
        let snapshot = self
            .snapshots
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let frames = s
                    .frames
                    .iter()
                    .map(|p| {
                        p.to_str()
                            .map(str::to_owned)
                            .ok_or_else(|| DepthError::ScanMismatch {
                                reason: format!(
                                    "snapshot {i}: frame path {} is not valid UTF-8",
                                    p.display()
                                ),
                            })
                    })
                    .collect::<Result<_, _>>()?;
                Ok(RawSnapshot {
                    angle_deg: f64_of(s.angle_deg),
                    frames,
                })
            })
            .collect::<Result<_, DepthError>>()?;
        to_toml(&Raw {
            format: SCAN_FORMAT,
            version: SCAN_VERSION,
            sensor: RawSensor::from(&self.sensor),
            rig: RawRig::from(&self.rig),
            clip: RawClip::from(&self.clip),
            snapshot,
        })
    }

    /// Writes the manifest to `path` atomically.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), DepthError> {
        let path = path.as_ref();
        let text = self.to_toml_string()?;
        write_atomic(path, |f| {
            use std::io::Write;
            f.write_all(text.as_bytes())
                .map_err(|e| DepthError::io(path, e))
        })
    }
}

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
    pub fn open(dir: impl AsRef<Path>) -> Result<Self, DepthError> {
        Self::open_limited(dir, default_memory_limit())
    }

    /// [`RecordedScan::open`] with the frames' memory limited to `max_bytes`.
    pub fn open_limited(dir: impl AsRef<Path>, max_bytes: u64) -> Result<Self, DepthError> {
        let dir = dir.as_ref();
        let mpath = dir.join(MANIFEST_FILE);
        let manifest = ScanManifest::load(&mpath)?;
        let i = manifest.sensor.intrinsics;
        let count: u64 = manifest
            .snapshots
            .iter()
            .map(|s| s.frames.len() as u64)
            .sum();
        let need = count * u64::from(i.width) * u64::from(i.height) * 2;
        if need > max_bytes {
            return Err(DepthError::InvalidValue {
                path: mpath,
                key: "snapshot".into(),
                reason: format!(
                    "{count} frames of {}x{} need {need} bytes of memory, more than the {max_bytes} \
                     allowed",
                    i.width, i.height
                ),
            });
        }
        let root = dir.canonicalize().map_err(|e| DepthError::io(dir, e))?;
        let jobs: Vec<PathBuf> = manifest
            .snapshots
            .iter()
            .flat_map(|s| s.frames.iter().map(|f| dir.join(f)))
            .collect();
        let sensor = manifest.sensor;
        let load = |p: &PathBuf| {
            let real = p.canonicalize().map_err(|e| DepthError::io(p, e))?;
            if !real.starts_with(&root) {
                return Err(DepthError::BadFrameFile {
                    path: p.clone(),
                    reason: "leaves the scan directory through a symbolic link".into(),
                });
            }
            read_png_frame_sized(&real, sensor.depth_unit_m, Some((i.width, i.height))).map_err(
                |e| match e {
                    DepthError::BadFrameFile { reason, .. } => DepthError::BadFrameFile {
                        path: p.clone(),
                        reason,
                    },
                    DepthError::Png { message, .. } => DepthError::Png {
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
    ) -> Result<(), DepthError> {
        let dir = dir.as_ref();
        if manifest.snapshots.is_empty() {
            return Err(DepthError::NoSnapshots {
                path: dir.join(MANIFEST_FILE),
            });
        }
        if frames.len() != manifest.snapshots.len() {
            return Err(DepthError::ScanMismatch {
                reason: format!(
                    "{} snapshots in the manifest, {} frame lists given",
                    manifest.snapshots.len(),
                    frames.len()
                ),
            });
        }
        for (k, (s, fr)) in manifest.snapshots.iter().zip(frames).enumerate() {
            if s.frames.len() != fr.len() {
                return Err(DepthError::ScanMismatch {
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
        fs::create_dir_all(dir).map_err(|e| DepthError::io(dir, e))?;
        for (s, fr) in manifest.snapshots.iter().zip(frames) {
            for (p, f) in s.frames.iter().zip(fr) {
                let path = dir.join(p);
                if let Some(parent) = path.parent() {
                    fs::create_dir_all(parent).map_err(|e| DepthError::io(parent, e))?;
                }
                write_png_frame(&path, f)?;
            }
        }
        let mpath = dir.join(MANIFEST_FILE);
        write_atomic(&mpath, |f| {
            use std::io::Write;
            f.write_all(text.as_bytes())
                .map_err(|e| DepthError::io(&mpath, e))
        })
    }

    /// Replaces the sensor, rig and clip settings by `config` (a `--config` override).
    /// The frames take the new depth unit; the size must stay the frames' size.
    pub fn apply_config(&mut self, config: &ScannerConfig) -> Result<(), DepthError> {
        let i = config.sensor.intrinsics;
        let m = self.manifest.sensor.intrinsics;
        if (i.width, i.height) != (m.width, m.height) {
            return Err(DepthError::FrameSizeMismatch {
                index: 0,
                expected_w: i.width,
                expected_h: i.height,
                found_w: m.width,
                found_h: m.height,
            });
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
    pub fn create(dir: impl AsRef<Path>, config: ScannerConfig) -> Result<Self, DepthError> {
        let dir = dir.as_ref().to_owned();
        let frames = dir.join("frames");
        fs::create_dir_all(&frames).map_err(|e| DepthError::io(&frames, e))?;
        Ok(Self {
            dir,
            manifest: ScanManifest::new(config),
        })
    }

    /// Writes one snapshot's frames and the updated manifest.
    pub fn add_snapshot(
        &mut self,
        angle_deg: f32,
        frames: &[DepthFrame],
    ) -> Result<(), DepthError> {
        if !(angle_deg.is_finite() && angle_deg.abs() <= MAX_ABS_ANGLE_DEG) {
            return Err(DepthError::InvalidParameter {
                name: "angle_deg",
                reason: format!("{angle_deg} is not within ±{MAX_ABS_ANGLE_DEG}°"),
            });
        }
        if frames.is_empty() {
            return Err(DepthError::NoFrames);
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
    pub fn finish(self) -> Result<ScanManifest, DepthError> {
        if self.manifest.snapshots.is_empty() {
            return Err(DepthError::NoSnapshots {
                path: self.dir.join(MANIFEST_FILE),
            });
        }
        Ok(self.manifest)
    }
}

/// Reads a 16-bit greyscale PNG depth frame; `unit_m` becomes the frame's unit.
/// Errors name the file: missing, not a PNG, another bit depth or colour type.
pub fn read_png_frame(path: &Path, unit_m: f32) -> Result<DepthFrame, DepthError> {
    read_png_frame_sized(path, unit_m, None)
}

/// [`read_png_frame`] that refuses, before decoding any pixel, a PNG whose header is not
/// `expected` = (width, height); and that opens only regular files (a FIFO would block).
pub fn read_png_frame_sized(
    path: &Path,
    unit_m: f32,
    expected: Option<(u32, u32)>,
) -> Result<DepthFrame, DepthError> {
    let meta = fs::metadata(path).map_err(|e| DepthError::io(path, e))?;
    if !meta.is_file() {
        return Err(DepthError::BadFrameFile {
            path: path.to_owned(),
            reason: "not a regular file (a directory, device or FIFO)".into(),
        });
    }
    let file = fs::File::open(path).map_err(|e| DepthError::io(path, e))?;
    let png_err = |e: png::DecodingError| DepthError::Png {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let mut dec = png::Decoder::new(BufReader::new(file));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec.read_info().map_err(png_err)?;
    let info = reader.info();
    let (w, h) = (info.width, info.height);
    if let Some((ew, eh)) = expected
        && (w, h) != (ew, eh)
    {
        return Err(DepthError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("frame is {w}x{h}, the sensor is {ew}x{eh}"),
        });
    }
    if w > MAX_FRAME_SIDE || h > MAX_FRAME_SIDE {
        return Err(DepthError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("{w}x{h} is larger than {MAX_FRAME_SIDE} pixels a side"),
        });
    }
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(DepthError::BadFrameFile {
            path: path.to_owned(),
            reason: format!(
                "{}-bit {:?} PNG; a depth frame is a 16-bit greyscale PNG",
                info.bit_depth as u8, info.color_type
            ),
        });
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| DepthError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("{w}x{h} is too large"),
        })?;
    let mut buf = vec![0u8; size];
    reader.next_frame(&mut buf).map_err(png_err)?;
    let n = w as usize * h as usize;
    if buf.len() < 2 * n {
        return Err(DepthError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("{} bytes of pixels for {w}x{h}", buf.len()),
        });
    }
    let data = buf[..2 * n]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    Ok(DepthFrame {
        width: w,
        height: h,
        unit_m,
        data,
    })
}

/// Writes a frame as a 16-bit greyscale PNG (not atomically; the manifest, written last,
/// is what makes a scan).
pub fn write_png_frame(path: &Path, frame: &DepthFrame) -> Result<(), DepthError> {
    check_frame(0, frame)?;
    let png_err = |e: png::EncodingError| DepthError::Png {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let file = fs::File::create(path).map_err(|e| DepthError::io(path, e))?;
    let mut enc = png::Encoder::new(BufWriter::new(file), frame.width, frame.height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Sixteen);
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header().map_err(png_err)?;
    let bytes: Vec<u8> = frame.data.iter().flat_map(|d| d.to_be_bytes()).collect();
    w.write_image_data(&bytes).map_err(png_err)?;
    w.finish().map_err(png_err)
}

fn check_sensor_frame(
    sensor: &SensorConfig,
    snapshot: usize,
    f: &DepthFrame,
) -> Result<(), DepthError> {
    check_frame(0, f)?;
    let i = sensor.intrinsics;
    if (f.width, f.height) != (i.width, i.height) {
        return Err(DepthError::ScanMismatch {
            reason: format!(
                "snapshot {snapshot}: a {}x{} frame for a {}x{} sensor",
                f.width, f.height, i.width, i.height
            ),
        });
    }
    #[allow(clippy::float_cmp)]
    if f.unit_m != sensor.depth_unit_m {
        return Err(DepthError::ScanMismatch {
            reason: format!(
                "snapshot {snapshot}: a frame in units of {} m for a sensor in {} m",
                f.unit_m, sensor.depth_unit_m
            ),
        });
    }
    Ok(())
}

// ---- TOML editing ----

/// `text` (a `scan.toml`) with `[rig]`'s `tilt_deg` and `sensor_position_m` set to `rig`,
/// and nothing else changed: comments, unknown keys, the order and the formatting of every
/// other value stay as they were (a format-preserving edit). `origin` names the file in
/// errors.
///
/// # Errors
/// [`DepthError::Toml`] when `text` is not TOML; the errors of [`ScanManifest::from_toml_str`]
/// when the edited text is not a valid manifest.
pub fn set_rig_in_manifest_text(
    text: &str,
    rig: &Rig,
    origin: &Path,
) -> Result<String, DepthError> {
    use toml_edit::{Array, DocumentMut, Item, Table as EditTable, Value as EditValue};
    let mut doc: DocumentMut =
        text.parse()
            .map_err(|e: toml_edit::TomlError| DepthError::Toml {
                path: origin.to_owned(),
                message: e.to_string(),
            })?;
    if !doc.contains_key("rig") {
        doc.insert("rig", Item::Table(EditTable::new()));
    }
    let table = doc["rig"]
        .as_table_like_mut()
        .ok_or_else(|| DepthError::WrongType {
            path: origin.to_owned(),
            key: "rig".into(),
            expected: "a table",
            found: "another value",
        })?;
    // A new value keeps the old one's surrounding spaces and comments.
    let mut set = |key: &str, mut v: EditValue| {
        if let Some(old) = table.get(key).and_then(Item::as_value) {
            let decor = old.decor().clone();
            *v.decor_mut() = decor;
        }
        table.insert(key, Item::Value(v));
    };
    set("tilt_deg", EditValue::from(f64_of(rig.tilt_deg)));
    let mut position = Array::new();
    for x in v3(rig.sensor_position_m) {
        position.push(x);
    }
    set("sensor_position_m", EditValue::Array(position));
    let out = doc.to_string();
    ScanManifest::from_toml_str(&out, origin)?;
    Ok(out)
}

// ---- TOML writing ----

/// An f32 as the f64 with the same shortest decimal form (so 0.001 prints as 0.001).
fn f64_of(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(f64::from(x))
}

fn v3(v: Vec3) -> [f64; 3] {
    v.to_array().map(f64_of)
}

#[derive(Serialize)]
struct RawSensor {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    depth_unit_m: f64,
}

impl From<&SensorConfig> for RawSensor {
    fn from(s: &SensorConfig) -> Self {
        let i = s.intrinsics;
        Self {
            width: i.width,
            height: i.height,
            fx: f64_of(i.fx),
            fy: f64_of(i.fy),
            cx: f64_of(i.cx),
            cy: f64_of(i.cy),
            depth_unit_m: f64_of(s.depth_unit_m),
        }
    }
}

#[derive(Serialize)]
struct RawRig {
    tilt_deg: f64,
    sensor_position_m: [f64; 3],
}

impl From<&Rig> for RawRig {
    fn from(r: &Rig) -> Self {
        Self {
            tilt_deg: f64_of(r.tilt_deg),
            sensor_position_m: v3(r.sensor_position_m),
        }
    }
}

#[derive(Serialize)]
struct RawClip {
    min_m: [f64; 3],
    max_m: [f64; 3],
}

impl From<&ClipBox> for RawClip {
    fn from(c: &ClipBox) -> Self {
        Self {
            min_m: v3(c.min),
            max_m: v3(c.max),
        }
    }
}

fn to_toml<T: Serialize>(raw: &T) -> Result<String, DepthError> {
    toml::to_string(raw).map_err(|e| DepthError::ScanMismatch {
        reason: format!("cannot render TOML: {e}"),
    })
}

// ---- TOML reading with key paths ----

/// Reading context: the file, for errors.
struct Ctx<'a> {
    path: &'a Path,
}

impl Ctx<'_> {
    fn parse(&self, text: &str) -> Result<Table, DepthError> {
        text.parse::<Table>().map_err(|e| DepthError::Toml {
            path: self.path.to_owned(),
            message: e.to_string(),
        })
    }

    fn missing(&self, key: &str) -> DepthError {
        DepthError::MissingKey {
            path: self.path.to_owned(),
            key: key.to_owned(),
        }
    }

    fn wrong(&self, key: &str, expected: &'static str, v: &Value) -> DepthError {
        DepthError::WrongType {
            path: self.path.to_owned(),
            key: key.to_owned(),
            expected,
            found: v.type_str(),
        }
    }

    fn invalid(&self, key: &str, reason: String) -> DepthError {
        DepthError::InvalidValue {
            path: self.path.to_owned(),
            key: key.to_owned(),
            reason,
        }
    }

    fn table<'t>(&self, t: &'t Table, key: &str) -> Result<&'t Table, DepthError> {
        match t.get(key) {
            None => Err(self.missing(key)),
            Some(Value::Table(t)) => Ok(t),
            Some(v) => Err(self.wrong(key, "a table", v)),
        }
    }

    /// A finite number (integer or float) at `prefix.key`.
    fn num(&self, t: &Table, prefix: &str, key: &str) -> Result<f32, DepthError> {
        let full = format!("{prefix}.{key}");
        let v = t.get(key).ok_or_else(|| self.missing(&full))?;
        self.value_num(v, &full)
    }

    fn value_num(&self, v: &Value, full: &str) -> Result<f32, DepthError> {
        let (wide, x) = match v {
            Value::Float(x) => (*x, *x as f32),
            Value::Integer(i) => (*i as f64, *i as f32),
            v => return Err(self.wrong(full, "a number", v)),
        };
        if wide.is_finite()
            && (x.is_infinite() || (x != 0.0 && !x.is_normal()) || (x == 0.0 && wide != 0.0))
        {
            return Err(self.invalid(
                full,
                format!(
                    "{wide} is out of range: values are 32-bit floats, whose magnitude must be 0 \
                     or between about 1.2e-38 and 3.4e38"
                ),
            ));
        }
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.invalid(full, format!("must be a finite number, got {v}")))
        }
    }

    fn positive(&self, t: &Table, prefix: &str, key: &str) -> Result<f32, DepthError> {
        let x = self.num(t, prefix, key)?;
        if x > 0.0 {
            Ok(x)
        } else {
            Err(self.invalid(
                &format!("{prefix}.{key}"),
                format!("must be positive, got {x}"),
            ))
        }
    }

    fn side(&self, t: &Table, prefix: &str, key: &str) -> Result<u32, DepthError> {
        let full = format!("{prefix}.{key}");
        match t.get(key) {
            None => Err(self.missing(&full)),
            Some(Value::Integer(i)) if (1..=i64::from(MAX_FRAME_SIDE)).contains(i) => Ok(*i as u32),
            Some(Value::Integer(i)) => {
                Err(self.invalid(&full, format!("{i} is outside 1..={MAX_FRAME_SIDE}")))
            }
            Some(v) => Err(self.wrong(&full, "an integer", v)),
        }
    }

    fn vec3(&self, t: &Table, prefix: &str, key: &str) -> Result<Vec3, DepthError> {
        let full = format!("{prefix}.{key}");
        match t.get(key) {
            None => Err(self.missing(&full)),
            Some(Value::Array(a)) if a.len() == 3 => {
                let mut out = [0f32; 3];
                for (i, v) in a.iter().enumerate() {
                    out[i] = self.value_num(v, &format!("{full}[{i}]"))?;
                }
                Ok(Vec3::from_array(out))
            }
            Some(v @ Value::Array(_)) => Err(self
                .wrong(&full, "an array of 3 numbers", v)
                .with_found("an array of another length")),
            Some(v) => Err(self.wrong(&full, "an array of 3 numbers", v)),
        }
    }

    fn config(&self, t: &Table) -> Result<ScannerConfig, DepthError> {
        let s = self.table(t, "sensor")?;
        let p = "sensor";
        let intrinsics = Intrinsics {
            width: self.side(s, p, "width")?,
            height: self.side(s, p, "height")?,
            fx: self.positive(s, p, "fx")?,
            fy: self.positive(s, p, "fy")?,
            cx: self.num(s, p, "cx")?,
            cy: self.num(s, p, "cy")?,
        };
        let depth_unit_m = self.positive(s, p, "depth_unit_m")?;

        let r = self.table(t, "rig")?;
        let tilt_deg = self.num(r, "rig", "tilt_deg")?;
        if tilt_deg.abs() >= 90.0 {
            return Err(self.invalid("rig.tilt_deg", format!("{tilt_deg}° is not within ±90°")));
        }
        let rig = Rig {
            tilt_deg,
            sensor_position_m: self.vec3(r, "rig", "sensor_position_m")?,
        };

        let c = self.table(t, "clip")?;
        let clip = ClipBox {
            min: self.vec3(c, "clip", "min_m")?,
            max: self.vec3(c, "clip", "max_m")?,
        };
        for axis in 0..3 {
            if clip.min[axis] > clip.max[axis] {
                return Err(self.invalid(
                    "clip",
                    format!(
                        "min_m[{axis}] = {} is greater than max_m[{axis}] = {}",
                        clip.min[axis], clip.max[axis]
                    ),
                ));
            }
        }
        Ok(ScannerConfig {
            sensor: SensorConfig {
                intrinsics,
                depth_unit_m,
            },
            rig,
            clip,
        })
    }
}

impl DepthError {
    fn with_found(self, found: &'static str) -> Self {
        match self {
            Self::WrongType {
                path,
                key,
                expected,
                ..
            } => Self::WrongType {
                path,
                key,
                expected,
                found,
            },
            e => e,
        }
    }
}
