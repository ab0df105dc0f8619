//! The scanner configuration file: `[sensor]`, `[rig]` and `[clip]` as TOML.

use std::path::Path;

use serde::Serialize;

use super::ScanError;
use super::file::read_settings_text;
use super::manifest::{RawClip, RawRig, RawSensor, to_toml};
use super::read::Ctx;
use crate::ScannerConfig;

impl ScannerConfig {
    /// Reads a configuration file (TOML with `[sensor]`, `[rig]`, `[clip]`; other keys,
    /// such as a scan manifest's `[[snapshot]]`, are ignored).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, ScanError> {
        let path = path.as_ref();
        // A pipe is allowed here (`--config <(…)`): it is the user's own choice.
        let text = read_settings_text(path, true)?;
        Self::from_toml_str(&text, path)
    }

    /// Parses a configuration from TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &Path) -> Result<Self, ScanError> {
        let cx = Ctx { path: origin };
        let table = cx.parse(text)?;
        cx.config(&table)
    }

    /// The configuration as TOML text (the three tables).
    pub fn to_toml_string(&self) -> Result<String, ScanError> {
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
