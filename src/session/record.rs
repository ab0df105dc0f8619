//! Recording what a session acquired, and the rules of the directory it goes to.

use std::path::{Path, PathBuf};

use voxoct_depth::scan::{MANIFEST_FILE, ScanError, ScanManifest, ScanWriter};

use super::{Acquired, SessionError, input};

/// Writes what was acquired as a recorded-scan directory (frames as 16-bit PNG, then
/// `scan.toml`, rewritten atomically after each snapshot).
///
/// # Errors
/// [`SessionError::Input`] for `--record-to`.
pub fn record(acquired: &Acquired, dir: &Path) -> Result<(), SessionError> {
    let err = |e: ScanError| input("--record-to", format!("--record-to {}: {e}", dir.display()));
    let mut writer = ScanWriter::create(dir, acquired.config).map_err(err)?;
    for s in &acquired.snapshots {
        writer.add_snapshot(s.angle_deg, &s.frames).map_err(err)?;
    }
    writer.finish().map(drop).map_err(err)
}

/// Checks a directory to record into before any work: it must be new (in an existing
/// directory) or empty, and not the directory `input` reads from; one that holds a readable
/// recorded scan is accepted with `force` (then [`clear_recorded_scan`] removes it).
///
/// # Errors
/// [`SessionError::Input`] for `--record-to`, saying what to do instead.
pub fn check_record_dir(
    dir: &Path,
    input_dir: Option<&Path>,
    force: bool,
) -> Result<(), SessionError> {
    let shown = dir.display();
    let refuse = |message: String| Err(input("--record-to", message));
    if let Some(from) = input_dir
        && let (Ok(a), Ok(b)) = (dir.canonicalize(), from.canonicalize())
        && a == b
    {
        return refuse(format!(
            "--record-to {shown} is the directory the frames are read from; choose another"
        ));
    }
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let parent = match dir.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            if !parent.is_dir() {
                return refuse(format!(
                    "--record-to {shown}: the directory {} does not exist",
                    parent.display()
                ));
            }
            Ok(())
        }
        Err(e) => refuse(format!("--record-to {shown}: {e}")),
        Ok(m) if !m.is_dir() => {
            refuse(format!("--record-to {shown} exists and is not a directory"))
        }
        Ok(_) => {
            let entries = std::fs::read_dir(dir)
                .map_err(|e| input("--record-to", format!("--record-to {shown}: {e}")))?
                .count();
            if entries == 0 {
                return Ok(());
            }
            let manifest = dir.join(MANIFEST_FILE);
            if !manifest.is_file() {
                return refuse(format!(
                    "--record-to {shown} is not empty and holds no recorded scan; choose a new or \
                     empty directory"
                ));
            }
            if !force {
                return refuse(format!(
                    "--record-to {shown} already holds a recorded scan; choose a new directory, or \
                     add --force to replace it (its frames are removed)"
                ));
            }
            ScanManifest::load(&manifest).map(drop).map_err(|e| {
                input(
                    "--record-to",
                    format!("--record-to {shown}: not replacing a scan that cannot be read ({e})"),
                )
            })
        }
    }
}

/// Removes the recorded scan in `dir` (its manifest and the frame files it lists inside
/// the directory, then their emptied subdirectories), so that a new scan's frames are all
/// that remain. Nothing to do when `dir` holds no manifest.
///
/// # Errors
/// [`SessionError::Input`] for `--record-to`.
pub fn clear_recorded_scan(dir: &Path) -> Result<(), SessionError> {
    let manifest_path = dir.join(MANIFEST_FILE);
    if !manifest_path.is_file() {
        return Ok(());
    }
    let err = |e: &dyn std::fmt::Display| {
        input(
            "--record-to",
            format!("--record-to {} --force: {e}", dir.display()),
        )
    };
    let manifest = ScanManifest::load(&manifest_path).map_err(|e| err(&e))?;
    let root = dir.canonicalize().map_err(|e| err(&e))?;
    let mut dirs: Vec<PathBuf> = Vec::new();
    for rel in manifest.snapshots.iter().flat_map(|s| &s.frames) {
        let path = dir.join(rel);
        // Only files inside the scan directory are removed.
        if let Ok(real) = path.canonicalize()
            && real.starts_with(&root)
            && real.is_file()
        {
            std::fs::remove_file(&real).map_err(|e| err(&e))?;
            if let Some(p) = real.parent() {
                dirs.push(p.to_owned());
            }
        }
    }
    std::fs::remove_file(&manifest_path).map_err(|e| err(&e))?;
    dirs.sort();
    dirs.dedup();
    for d in dirs.iter().rev().filter(|d| **d != root) {
        let _ = std::fs::remove_dir(d); // only when empty
    }
    Ok(())
}
