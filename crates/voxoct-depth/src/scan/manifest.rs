//! `scan.toml`: the manifest of a recorded scan, read, written and edited in place.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Serialize;

use super::file::{read_settings_text, stays_inside};
use super::read::Ctx;
use super::{MAX_ABS_ANGLE_DEG, SCAN_FORMAT, SCAN_VERSION, ScanError};
use crate::atomic::write_atomic;
use crate::{ClipBox, Rig, ScannerConfig, SensorConfig};
use toml::Value;

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
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ScanError> {
        let path = path.as_ref();
        let text = read_settings_text(path, false)?;
        Self::from_toml_str(&text, path)
    }

    /// Parses and validates manifest text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &Path) -> Result<Self, ScanError> {
        let cx = Ctx { path: origin };
        let t = cx.parse(text)?;
        match t.get("format") {
            None => return Err(cx.missing("format")),
            Some(Value::String(s)) if s == SCAN_FORMAT => {}
            Some(Value::String(s)) => {
                return Err(ScanError::WrongFormat {
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
                return Err(ScanError::UnsupportedVersion {
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
                return Err(ScanError::NoSnapshots {
                    path: origin.to_owned(),
                });
            }
            Some(Value::Array(a)) => a,
            Some(v) => return Err(cx.wrong("snapshot", "an array of tables `[[snapshot]]`", v)),
        };
        if list.is_empty() {
            return Err(ScanError::NoSnapshots {
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
    pub fn to_toml_string(&self) -> Result<String, ScanError> {
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
                            .ok_or_else(|| ScanError::ScanMismatch {
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
            .collect::<Result<_, ScanError>>()?;
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
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), ScanError> {
        let path = path.as_ref();
        let text = self.to_toml_string()?;
        write_atomic(path, text.as_bytes()).map_err(|e| ScanError::io(path, e))
    }
}

// ---- TOML editing ----

/// `text` (a `scan.toml`) with `[rig]`'s `tilt_deg` and `sensor_position_m` set to `rig`,
/// and nothing else changed: comments, unknown keys, the order and the formatting of every
/// other value stay as they were (a format-preserving edit). `origin` names the file in
/// errors.
///
/// # Errors
/// [`ScanError::Toml`] when `text` is not TOML; the errors of [`ScanManifest::from_toml_str`]
/// when the edited text is not a valid manifest.
pub fn set_rig_in_manifest_text(text: &str, rig: &Rig, origin: &Path) -> Result<String, ScanError> {
    use toml_edit::{Array, DocumentMut, Item, Table as EditTable, Value as EditValue};
    let mut doc: DocumentMut = text
        .parse()
        .map_err(|e: toml_edit::TomlError| ScanError::Toml {
            path: origin.to_owned(),
            message: e.to_string(),
        })?;
    if !doc.contains_key("rig") {
        doc.insert("rig", Item::Table(EditTable::new()));
    }
    let table = doc["rig"]
        .as_table_like_mut()
        .ok_or_else(|| ScanError::WrongType {
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
pub(crate) fn f64_of(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(f64::from(x))
}

fn v3(v: Vec3) -> [f64; 3] {
    v.to_array().map(f64_of)
}

#[derive(Serialize)]
pub(crate) struct RawSensor {
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
pub(crate) struct RawRig {
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
pub(crate) struct RawClip {
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

pub(crate) fn to_toml<T: Serialize>(raw: &T) -> Result<String, ScanError> {
    toml::to_string(raw).map_err(|e| ScanError::ScanMismatch {
        reason: format!("cannot render TOML: {e}"),
    })
}
