//! File access shared by the scan directory's readers and writers: bounded reads of
//! settings files, frame paths that stay inside the directory, atomic replacement.

use std::fs;
use std::path::Path;

use super::ScanError;

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
pub(crate) fn read_settings_text(path: &Path, pipes: bool) -> Result<String, ScanError> {
    use std::io::Read;
    let meta = fs::metadata(path).map_err(|e| ScanError::io(path, e))?;
    let refuse = |reason: String| ScanError::BadFile {
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
        .map_err(|e| ScanError::io(path, e))?;
    if text.len() as u64 > MAX_SETTINGS_BYTES {
        return Err(refuse(format!(
            "larger than the {MAX_SETTINGS_BYTES} bytes a settings file may have"
        )));
    }
    Ok(text)
}

/// Whether `p` is a relative path that stays inside its directory when read lexically
/// (no root, no prefix, no `..` above the start).
pub(crate) fn stays_inside(p: &Path) -> bool {
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
