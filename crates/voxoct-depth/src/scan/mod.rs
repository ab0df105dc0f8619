//! The recorded-scan directory (format `voxoct-scan`, version 1; SCAN_FORMAT.md): a
//! `scan.toml` manifest and 16-bit PNG depth frames, and the scanner configuration file.
//! Feature `scan-dir` (on by default).
//!
//! - [`RecordedScan`]: a scan read into memory ([`RecordedScan::open`]) or written whole
//!   ([`RecordedScan::write`]);
//! - [`ScanWriter`]: a scan written snapshot by snapshot while it is captured;
//! - [`ScanManifest`], [`SnapshotEntry`]: the contents of `scan.toml`;
//!   [`set_rig_in_manifest_text`] edits its `[rig]` in place;
//! - the TOML methods of [`crate::ScannerConfig`] (`from_file`, `from_toml_str`,
//!   `to_toml_string`);
//! - [`read_png_frame`], [`read_png_frame_sized`], [`write_png_frame`]: one frame file;
//! - [`ScanError`]: every error here names the file, and the key for TOML.

mod config;
mod error;
mod file;
mod frames;
mod manifest;
mod read;
mod recorded;
mod writer;

pub use error::ScanError;
pub use file::{MAX_SETTINGS_BYTES, default_memory_limit};
pub use frames::{read_png_frame, read_png_frame_sized, write_png_frame};
pub use manifest::{ScanManifest, SnapshotEntry, set_rig_in_manifest_text};
pub use recorded::RecordedScan;
pub use writer::ScanWriter;

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
