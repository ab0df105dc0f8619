//! Atomic file replacement for the crate's writers (scan manifests, PNG images).

use std::fs;
use std::path::Path;

/// Writes `bytes` to `path` atomically: into a temporary file next to it, which is then
/// synced, given the old file's permissions and renamed over `path`. A symlink is followed
/// (its target is replaced, the link stays); a path that exists and is not a regular file
/// (a device, a FIFO) is written to directly, never replaced.
///
/// Not `voxoct_stl::write_atomic`: that one refuses symlinks and devices (a library writing
/// mesh files must not replace what it did not create), while the tools promise to follow a
/// symlink and to write into a device (`calibrate --write` on a linked `scan.toml`,
/// `inspect --out /dev/stdout`); and voxoct-depth does not depend on voxoct-stl.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let original = path;
    let resolved;
    let mut old_permissions = None;
    let path = match fs::metadata(original) {
        Ok(m) if !m.is_file() && !m.is_dir() => {
            let mut f = fs::OpenOptions::new().write(true).open(original)?;
            return f.write_all(bytes);
        }
        Ok(m) if m.is_file() => {
            old_permissions = Some(m.permissions());
            resolved = fs::canonicalize(original)?;
            resolved.as_path()
        }
        _ => original,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        if let Some(p) = old_permissions {
            fs::set_permissions(&tmp, p)?;
        }
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}
