//! Reading TOML tables with errors that name the key by its dotted path.

use std::path::Path;

use glam::Vec3;
use toml::{Table, Value};

use super::{MAX_FRAME_SIDE, ScanError};
use crate::{ClipBox, Intrinsics, Rig, ScannerConfig, SensorConfig};

// ---- TOML reading with key paths ----

/// Reading context: the file, for errors.
pub(crate) struct Ctx<'a> {
    pub(crate) path: &'a Path,
}

impl Ctx<'_> {
    pub(crate) fn parse(&self, text: &str) -> Result<Table, ScanError> {
        text.parse::<Table>().map_err(|e| ScanError::Toml {
            path: self.path.to_owned(),
            message: e.to_string(),
        })
    }

    pub(crate) fn missing(&self, key: &str) -> ScanError {
        ScanError::MissingKey {
            path: self.path.to_owned(),
            key: key.to_owned(),
        }
    }

    pub(crate) fn wrong(&self, key: &str, expected: &'static str, v: &Value) -> ScanError {
        ScanError::WrongType {
            path: self.path.to_owned(),
            key: key.to_owned(),
            expected,
            found: v.type_str(),
        }
    }

    pub(crate) fn invalid(&self, key: &str, reason: String) -> ScanError {
        ScanError::InvalidValue {
            path: self.path.to_owned(),
            key: key.to_owned(),
            reason,
        }
    }

    pub(crate) fn table<'t>(&self, t: &'t Table, key: &str) -> Result<&'t Table, ScanError> {
        match t.get(key) {
            None => Err(self.missing(key)),
            Some(Value::Table(t)) => Ok(t),
            Some(v) => Err(self.wrong(key, "a table", v)),
        }
    }

    /// A finite number (integer or float) at `prefix.key`.
    pub(crate) fn num(&self, t: &Table, prefix: &str, key: &str) -> Result<f32, ScanError> {
        let full = format!("{prefix}.{key}");
        let v = t.get(key).ok_or_else(|| self.missing(&full))?;
        self.value_num(v, &full)
    }

    pub(crate) fn value_num(&self, v: &Value, full: &str) -> Result<f32, ScanError> {
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

    pub(crate) fn positive(&self, t: &Table, prefix: &str, key: &str) -> Result<f32, ScanError> {
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

    pub(crate) fn side(&self, t: &Table, prefix: &str, key: &str) -> Result<u32, ScanError> {
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

    pub(crate) fn vec3(&self, t: &Table, prefix: &str, key: &str) -> Result<Vec3, ScanError> {
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

    pub(crate) fn config(&self, t: &Table) -> Result<ScannerConfig, ScanError> {
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
