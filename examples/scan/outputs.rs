//! The run's outputs, checked before any frame is read (see `voxoct::output`), and the
//! `--record-to` directory's rules.

use std::path::{Path, PathBuf};

use voxoct::depth::scan::{MANIFEST_FILE, ScanManifest};
use voxoct::output::{OutputId, Outputs};

use crate::Args;

/// The planned outputs of a scan.
pub struct Planned {
    /// All of them, committed together.
    pub outputs: Outputs,
    /// `--out`.
    pub out: OutputId,
    /// `--stats`.
    pub stats: Option<OutputId>,
    /// `--preview`.
    pub preview: Option<OutputId>,
}

/// Checks `--out`, `--stats`, `--preview` and `--record-to` before any work.
pub fn plan(args: &Args) -> Result<Planned, String> {
    let mut outputs = Outputs::new();
    let out = outputs.add("--out", &args.out).map_err(|e| e.to_string())?;
    let stats = args
        .stats
        .as_deref()
        .map(|p| outputs.add("--stats", p))
        .transpose()
        .map_err(|e| e.to_string())?;
    let preview = args
        .preview
        .as_deref()
        .map(|p| outputs.add("--preview", p))
        .transpose()
        .map_err(|e| e.to_string())?;
    if let Some(dir) = &args.record_to {
        check_record_to(dir, args)?;
    }
    Ok(Planned {
        outputs,
        out,
        stats,
        preview,
    })
}

/// A `--record-to` directory must be new or empty; with `--force`, one that holds a
/// recorded scan is replaced (its frames are removed when the new scan is written).
fn check_record_to(dir: &Path, args: &Args) -> Result<(), String> {
    let shown = dir.display();
    if let Some(input) = args.input.as_deref().or(args.fakenect.as_deref())
        && let (Ok(a), Ok(b)) = (dir.canonicalize(), input.canonicalize())
        && a == b
    {
        return Err(format!(
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
                return Err(format!(
                    "--record-to {shown}: the directory {} does not exist",
                    parent.display()
                ));
            }
            Ok(())
        }
        Err(e) => Err(format!("--record-to {shown}: {e}")),
        Ok(m) if !m.is_dir() => Err(format!("--record-to {shown} exists and is not a directory")),
        Ok(_) => {
            let entries = std::fs::read_dir(dir)
                .map_err(|e| format!("--record-to {shown}: {e}"))?
                .count();
            if entries == 0 {
                return Ok(());
            }
            let manifest = dir.join(MANIFEST_FILE);
            if !manifest.is_file() {
                return Err(format!(
                    "--record-to {shown} is not empty and holds no recorded scan; choose a new or \
                     empty directory"
                ));
            }
            if !args.force {
                return Err(format!(
                    "--record-to {shown} already holds a recorded scan; choose a new directory, or \
                     add --force to replace it (its frames are removed)"
                ));
            }
            ScanManifest::load(&manifest).map(drop).map_err(|e| {
                format!("--record-to {shown}: not replacing a scan that cannot be read ({e})")
            })
        }
    }
}

/// With `--force`: removes the recorded scan in `dir` (its manifest and the frame files it
/// lists inside the directory), so that the new scan's frames are all that remain.
pub fn clear_record_to(dir: &Path) -> Result<(), String> {
    let manifest_path = dir.join(MANIFEST_FILE);
    if !manifest_path.is_file() {
        return Ok(());
    }
    let err = |e: &dyn std::fmt::Display| format!("--record-to {} --force: {e}", dir.display());
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
