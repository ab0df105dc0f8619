//! Output files of the command-line tools: checked before any work, written all or nothing.
//!
//! A run names its outputs first ([`Outputs::add`], one call per flag). Each is checked at
//! once, before any frame is read:
//!
//! - two flags naming the same file (also through `..`, `./`, symlinks or hard links) are
//!   refused, naming both flags;
//! - a missing directory, a parent that is a file, a path that names a directory, an
//!   unwritable directory and a read-only file are refused;
//! - a regular file (or a path that does not exist yet) gets its temporary file now, next
//!   to the target, so a directory that cannot take it fails here and not after the work.
//!
//! Then [`Outputs::write`] fills each output, and [`Outputs::commit`] publishes them all:
//!
//! - a **regular file** is replaced atomically: the temporary file is synced, given the old
//!   file's permissions, and renamed over it; a **symlink** is followed and its target is
//!   replaced the same way (the link stays a link);
//! - anything that is **not a regular file** (a device such as `/dev/null`, a FIFO,
//!   `/dev/stdout`) is written to directly, never replaced; `-` is standard output;
//! - nothing is published until every output has been written, so a failing side output
//!   leaves every existing file as it was. Errors name the flag and the user's path, never
//!   the temporary file.
//!
//! Temporary files are removed when the [`Outputs`] is dropped, and — once a program has
//! called [`remove_temporary_files_on_signal`] — when it is stopped with Ctrl-C, `SIGTERM`
//! or `SIGHUP`.
//!
//! ```
//! use voxoct::output::Outputs;
//! let dir = tempfile::tempdir()?;
//! let mut outputs = Outputs::new();
//! let a = outputs.add("--out", &dir.path().join("a.txt"))?;
//! // The same file under another spelling is refused, naming both flags.
//! let same = dir.path().join(".").join("a.txt");
//! assert!(outputs.add("--stats", &same).unwrap_err().to_string().contains("--out"));
//! outputs.write(a, |w| w.write_all(b"hello"))?;
//! outputs.commit()?;
//! assert_eq!(std::fs::read(dir.path().join("a.txt"))?, b"hello");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

/// What can go wrong with an output. Every variant names the flag and the user's path.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// Two flags name the same file.
    ///
    /// How to fix: give each output its own file.
    #[error(
        "{flag} {path} is the same file as {other_flag} {other_path}; give each output its own file"
    )]
    SameFile {
        /// The later flag.
        flag: String,
        /// Its path.
        path: PathBuf,
        /// The earlier flag naming the same file.
        other_flag: String,
        /// The earlier flag's path.
        other_path: PathBuf,
    },
    /// The path is empty or names a directory.
    ///
    /// How to fix: name a file, such as `scan.stl`.
    #[error("{flag} {path}: {reason}")]
    NotAFile {
        /// The flag.
        flag: String,
        /// Its path.
        path: PathBuf,
        /// Why it is not a file name.
        reason: String,
    },
    /// The directory of the output is missing, not a directory, or not writable.
    ///
    /// How to fix: create the directory, or choose one you may write to.
    #[error("{flag} {path}: {reason}")]
    Directory {
        /// The flag.
        flag: String,
        /// Its path.
        path: PathBuf,
        /// What is wrong with the directory.
        reason: String,
    },
    /// The output exists and is read-only: it is not replaced.
    ///
    /// How to fix: make it writable (`chmod u+w`) if you mean to replace it, or choose another path.
    #[error("{flag} {path} is read-only; not replacing it (make it writable to allow this)")]
    ReadOnly {
        /// The flag.
        flag: String,
        /// Its path.
        path: PathBuf,
    },
    /// Writing, syncing or renaming failed.
    #[error("{flag} {path}: cannot write: {source}{note}")]
    Write {
        /// The flag.
        flag: String,
        /// Its path.
        path: PathBuf,
        /// What the other outputs became (empty when nothing was replaced).
        note: String,
        /// The I/O error.
        #[source]
        source: io::Error,
    },
    /// An output was never written before [`Outputs::commit`] (a bug in the caller).
    #[error("{flag} {path}: nothing was written")]
    NotWritten {
        /// The flag.
        flag: String,
        /// Its path.
        path: PathBuf,
    },
}

/// One planned output; returned by [`Outputs::add`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputId(usize);

/// Where an output's bytes go.
#[derive(Debug)]
enum Target {
    /// Standard output (`-`).
    Stdout,
    /// A regular file or a new one, replaced through `temp` (the target with symlinks
    /// followed).
    Replace {
        target: PathBuf,
        temp: PathBuf,
        /// The permissions and owner of the file being replaced.
        old: Option<fs::Metadata>,
    },
    /// Not a regular file (device, FIFO, socket): written directly at commit.
    Direct { target: PathBuf },
}

#[derive(Debug)]
struct Planned {
    flag: String,
    path: PathBuf,
    /// Identity for the same-file check: the canonical path of the target.
    key: PathBuf,
    /// Device and inode when the target exists (hard links).
    inode: Option<(u64, u64)>,
    target: Target,
    /// Bytes for a direct or stdout target; `Some(empty)` once a replaced file is written.
    written: Option<Vec<u8>>,
}

/// The outputs of one run: planned and checked up front, written, then committed together.
#[derive(Debug, Default)]
pub struct Outputs {
    planned: Vec<Planned>,
}

impl Outputs {
    /// No outputs yet.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Plans the output `path` of `flag` and checks it (see the module docs); for a regular
    /// file this creates its temporary file next to it.
    ///
    /// # Errors
    /// [`OutputError::SameFile`], [`OutputError::NotAFile`], [`OutputError::Directory`],
    /// [`OutputError::ReadOnly`].
    pub fn add(&mut self, flag: &str, path: &Path) -> Result<OutputId, OutputError> {
        let planned = plan(flag, path)?;
        for p in &self.planned {
            let same_inode = p.inode.is_some() && p.inode == planned.inode;
            if p.key == planned.key || same_inode {
                if let Target::Replace { temp, .. } = &planned.target {
                    remove_temp(temp);
                }
                return Err(OutputError::SameFile {
                    flag: flag.to_owned(),
                    path: path.to_owned(),
                    other_flag: p.flag.clone(),
                    other_path: p.path.clone(),
                });
            }
        }
        self.planned.push(planned);
        Ok(OutputId(self.planned.len() - 1))
    }

    /// The path the user gave for `id`.
    #[must_use]
    pub fn path(&self, id: OutputId) -> &Path {
        &self.planned[id.0].path
    }

    /// Whether `id` is standard output.
    #[must_use]
    pub fn is_stdout(&self, id: OutputId) -> bool {
        matches!(self.planned[id.0].target, Target::Stdout)
    }

    /// Writes the contents of output `id` with `fill` (into its temporary file, or into
    /// memory for a device, FIFO or standard output). Nothing is visible at the path until
    /// [`Outputs::commit`].
    ///
    /// # Errors
    /// [`OutputError::Write`], naming the flag and the user's path.
    pub fn write(
        &mut self,
        id: OutputId,
        fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> Result<(), OutputError> {
        let p = &mut self.planned[id.0];
        let err = |source: io::Error| OutputError::Write {
            flag: p.flag.clone(),
            path: p.path.clone(),
            note: String::new(),
            source,
        };
        match &p.target {
            Target::Replace { temp, .. } => {
                let file = OpenOptions::new()
                    .write(true)
                    .truncate(true)
                    .open(temp)
                    .map_err(err)?;
                let mut w = BufWriter::new(file);
                fill(&mut w).map_err(err)?;
                let file = w.into_inner().map_err(|e| err(e.into_error()))?;
                file.sync_all().map_err(err)?;
                p.written = Some(Vec::new());
            }
            Target::Stdout | Target::Direct { .. } => {
                let mut bytes = Vec::new();
                fill(&mut bytes).map_err(err)?;
                p.written = Some(bytes);
            }
        }
        Ok(())
    }

    /// Publishes every output: renames each temporary file over its target (keeping the
    /// old file's permissions), then writes the direct and standard-output ones.
    ///
    /// # Errors
    /// [`OutputError::NotWritten`] before anything is replaced when an output was not
    /// written; [`OutputError::Write`] naming the output that failed and, in its note,
    /// those already published.
    pub fn commit(mut self) -> Result<(), OutputError> {
        if let Some(p) = self.planned.iter().find(|p| p.written.is_none()) {
            return Err(OutputError::NotWritten {
                flag: p.flag.clone(),
                path: p.path.clone(),
            });
        }
        // Permissions first: a failure here still leaves every old file in place.
        for p in &self.planned {
            if let Target::Replace {
                temp,
                old: Some(meta),
                ..
            } = &p.target
            {
                fs::set_permissions(temp, meta.permissions()).map_err(|source| {
                    OutputError::Write {
                        flag: p.flag.clone(),
                        path: p.path.clone(),
                        note: String::new(),
                        source,
                    }
                })?;
                #[cfg(unix)]
                {
                    use std::os::unix::fs::MetadataExt;
                    // Keep the owner where we may (as root); otherwise the file is ours.
                    let _ = std::os::unix::fs::chown(temp, Some(meta.uid()), Some(meta.gid()));
                }
            }
        }
        let mut done: Vec<String> = Vec::new();
        let planned = std::mem::take(&mut self.planned);
        let mut failure = None;
        // Devices, FIFOs and standard output first: they cannot be undone, but a failure
        // there still leaves every regular file as it was.
        let mut order: Vec<&Planned> = planned
            .iter()
            .filter(|p| !matches!(p.target, Target::Replace { .. }))
            .collect();
        order.extend(
            planned
                .iter()
                .filter(|p| matches!(p.target, Target::Replace { .. })),
        );
        for p in order {
            let result = match &p.target {
                Target::Replace { target, temp, .. } => replace_with(target, temp),
                Target::Direct { target } => OpenOptions::new()
                    .write(true)
                    .open(target)
                    .and_then(|mut f| f.write_all(p.written.as_deref().unwrap_or_default())),
                Target::Stdout => {
                    let mut out = io::stdout().lock();
                    out.write_all(p.written.as_deref().unwrap_or_default())
                        .and_then(|()| out.flush())
                }
            };
            match result {
                Ok(()) => done.push(format!("{} {}", p.flag, p.path.display())),
                Err(source) => {
                    let note = if done.is_empty() {
                        String::new()
                    } else {
                        format!(" (already written: {})", done.join(", "))
                    };
                    failure = Some(OutputError::Write {
                        flag: p.flag.clone(),
                        path: p.path.clone(),
                        note,
                        source,
                    });
                    break;
                }
            }
        }
        for p in &planned {
            if let Target::Replace { temp, .. } = &p.target {
                remove_temp(temp);
            }
        }
        failure.map_or(Ok(()), Err)
    }
}

impl Drop for Outputs {
    fn drop(&mut self) {
        for p in &self.planned {
            if let Target::Replace { temp, .. } = &p.target {
                remove_temp(temp);
            }
        }
    }
}

/// Checks one output and decides how it will be written.
fn plan(flag: &str, path: &Path) -> Result<Planned, OutputError> {
    let not_a_file = |reason: &str| OutputError::NotAFile {
        flag: flag.to_owned(),
        path: path.to_owned(),
        reason: reason.to_owned(),
    };
    if path.as_os_str().is_empty() {
        return Err(not_a_file("an empty path; name a file"));
    }
    if path.as_os_str() == "-" {
        return Ok(Planned {
            flag: flag.to_owned(),
            path: path.to_owned(),
            key: PathBuf::from("-"),
            inode: None,
            target: Target::Stdout,
            written: None,
        });
    }
    let text = path.as_os_str().as_encoded_bytes();
    if text.ends_with(b"/")
        || matches!(
            path.components().next_back(),
            Some(Component::ParentDir | Component::CurDir | Component::RootDir)
        )
    {
        return Err(not_a_file(
            "names a directory; name a file such as scan.stl",
        ));
    }
    let dir_err = |reason: String| OutputError::Directory {
        flag: flag.to_owned(),
        path: path.to_owned(),
        reason,
    };
    // What is there now, symlinks followed by the system (also `/proc/self/fd/N`).
    let (key, inode, kind) = match fs::metadata(path) {
        Ok(m) if m.is_dir() => {
            return Err(not_a_file("is a directory; name a file such as scan.stl"));
        }
        Ok(m) if m.is_file() => {
            if m.permissions().readonly() {
                return Err(OutputError::ReadOnly {
                    flag: flag.to_owned(),
                    path: path.to_owned(),
                });
            }
            let target = fs::canonicalize(path)
                .map_err(|e| dir_err(format!("cannot resolve the path: {e}")))?;
            let (parent, name) = split(&target)
                .ok_or_else(|| not_a_file("names a directory; name a file such as scan.stl"))?;
            let temp = create_temp(&parent, &name).map_err(|e| {
                dir_err(format!("cannot create a file in {}: {e}", parent.display()))
            })?;
            let kind = Target::Replace {
                target: target.clone(),
                temp,
                old: Some(m.clone()),
            };
            (target, inode_of(&m), kind)
        }
        Ok(m) => {
            // A device, FIFO or socket: written to, never replaced.
            let key = fs::canonicalize(path).unwrap_or_else(|_| path.to_owned());
            let kind = Target::Direct {
                target: path.to_owned(),
            };
            (key, inode_of(&m), kind)
        }
        Err(_) => {
            // Nothing there yet (or a dangling symlink: the file it names is created).
            let target = follow_links(path).map_err(dir_err)?;
            let (parent, name) = split(&target)
                .ok_or_else(|| not_a_file("names a directory; name a file such as scan.stl"))?;
            let canonical_parent = match fs::canonicalize(&parent) {
                Ok(p) if p.is_dir() => p,
                Ok(_) => {
                    return Err(dir_err(format!("{} is not a directory", parent.display())));
                }
                Err(e) if e.kind() == io::ErrorKind::NotFound => {
                    return Err(dir_err(format!(
                        "the directory {} does not exist",
                        parent.display()
                    )));
                }
                Err(e) if e.raw_os_error() == Some(20) => {
                    return Err(dir_err(format!("{} is not a directory", parent.display())));
                }
                Err(e) => {
                    return Err(dir_err(format!("cannot reach {}: {e}", parent.display())));
                }
            };
            let temp = create_temp(&parent, &name).map_err(|e| {
                dir_err(format!("cannot create a file in {}: {e}", parent.display()))
            })?;
            let kind = Target::Replace {
                target,
                temp,
                old: None,
            };
            (canonical_parent.join(&name), None, kind)
        }
    };
    Ok(Planned {
        flag: flag.to_owned(),
        path: path.to_owned(),
        key,
        inode,
        target: kind,
        written: None,
    })
}

/// The directory (`.` for a bare name) and the file name of `target`.
fn split(target: &Path) -> Option<(PathBuf, std::ffi::OsString)> {
    let name = target.file_name()?.to_owned();
    let parent = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_owned(),
        _ => PathBuf::from("."),
    };
    Some((parent, name))
}

#[cfg(unix)]
fn inode_of(m: &fs::Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn inode_of(_: &fs::Metadata) -> Option<(u64, u64)> {
    None
}

/// `path` with its symlinks followed (also dangling ones: the file they point to is created).
fn follow_links(path: &Path) -> Result<PathBuf, String> {
    let mut p = path.to_owned();
    for _ in 0..40 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let link = fs::read_link(&p).map_err(|e| format!("cannot read the link: {e}"))?;
                p = match p.parent() {
                    Some(dir) if link.is_relative() => dir.join(link),
                    _ => link,
                };
            }
            _ => return Ok(p),
        }
    }
    Err("too many levels of symbolic links".into())
}

/// Longest message [`terminal_safe`] keeps, in characters.
pub const MAX_MESSAGE_CHARS: usize = 2000;

/// `message` made safe to print: control characters other than newline and tab (NUL, ESC
/// sequences from a file name) are shown escaped (`\u{1b}`), and a message longer than
/// [`MAX_MESSAGE_CHARS`] is cut, saying how much was left out.
#[must_use]
pub fn terminal_safe(message: &str) -> String {
    let mut out = String::with_capacity(message.len().min(4 * MAX_MESSAGE_CHARS));
    for (n, c) in message.chars().enumerate() {
        if n == MAX_MESSAGE_CHARS {
            let rest = message.chars().count() - n;
            out.push_str(&format!("… ({rest} more characters left out)"));
            break;
        }
        if c.is_control() && c != '\n' && c != '\t' {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out
}

/// Temporary files to remove on a signal.
static TEMPORARY: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Makes temporary names unique within the process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Creates a new, empty hidden temporary file next to the target, registered for removal.
fn create_temp(dir: &Path, name: &std::ffi::OsStr) -> io::Result<PathBuf> {
    let mut registry = TEMPORARY.lock().unwrap_or_else(PoisonError::into_inner);
    loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let temp = dir.join(format!(
            ".{}.{}-{n}.voxoct-tmp",
            name.to_string_lossy(),
            std::process::id()
        ));
        match OpenOptions::new().write(true).create_new(true).open(&temp) {
            Ok(f) => {
                drop::<File>(f);
                registry.push(temp.clone());
                return Ok(temp);
            }
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
    }
}

fn forget_temp(temp: &Path) {
    TEMPORARY
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .retain(|t| t != temp);
}

fn remove_temp(temp: &Path) {
    let mut registry = TEMPORARY.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(i) = registry.iter().position(|t| t == temp) {
        registry.swap_remove(i);
        let _ = fs::remove_file(temp);
    }
}

/// Replaces `target` by the synced temporary file `temp` (same directory) and makes the
/// rename durable.
///
/// Not `voxoct_stl::write_atomic`, which writes and renames in one call: a run's outputs are
/// all or nothing, so their temporaries are written first and renamed together at the end,
/// and the tools follow symlinks and write into devices where that one refuses them.
fn replace_with(target: &Path, temp: &Path) -> io::Result<()> {
    fs::rename(temp, target)?;
    forget_temp(temp);
    sync_parent(target);
    Ok(())
}

/// Makes a rename durable: syncs the directory that holds `target` (best effort).
fn sync_parent(target: &Path) {
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Removes this process's temporary output files and exits when it receives `SIGINT`
/// (Ctrl-C), `SIGTERM` or `SIGHUP`, with status 128 + the signal's number (130 for
/// Ctrl-C), as a shell reports a program killed by the signal. Existing outputs stay as
/// they were. Call it once, early in `main`.
///
/// # Errors
/// The I/O error of installing the handlers.
#[cfg(unix)]
pub fn remove_temporary_files_on_signal() -> io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("voxoct-signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                // Held until exit: no new temporary file can appear meanwhile.
                let registry = TEMPORARY.lock().unwrap_or_else(PoisonError::into_inner);
                for t in registry.iter() {
                    let _ = fs::remove_file(t);
                }
                std::process::exit(128 + signal);
            }
        })?;
    Ok(())
}

/// Without Unix signals there is nothing to install.
///
/// # Errors
/// Never.
#[cfg(not(unix))]
pub fn remove_temporary_files_on_signal() -> io::Result<()> {
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leftovers(dir: &Path) -> Vec<String> {
        fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains("voxoct-tmp"))
            .collect()
    }

    #[test]
    fn same_file_through_dots_and_symlinks_is_refused_naming_both_flags() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        fs::create_dir(d.join("sub")).unwrap();
        let mut o = Outputs::new();
        o.add("--out", &d.join("x.stl")).unwrap();
        let e = o.add("--stats", &d.join("sub/../x.stl")).unwrap_err();
        assert!(
            e.to_string().contains("--out") && e.to_string().contains("--stats"),
            "{e}"
        );
        std::os::unix::fs::symlink("x.stl", d.join("link.stl")).unwrap();
        let e = o.add("--preview", &d.join("link.stl")).unwrap_err();
        assert!(e.to_string().contains("--out"), "{e}");
        drop(o);
        assert!(leftovers(d).is_empty());
    }

    #[test]
    fn missing_directory_parent_file_and_directory_target_are_refused_up_front() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        fs::write(d.join("file"), b"x").unwrap();
        let mut o = Outputs::new();
        let e = o.add("--out", &d.join("nodir/x.stl")).unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
        let e = o.add("--out", &d.join("file/x.stl")).unwrap_err();
        assert!(e.to_string().contains("not a directory"), "{e}");
        let e = o.add("--out", &d.join("newdir/")).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
        let e = o.add("--out", d).unwrap_err();
        assert!(e.to_string().contains("directory"), "{e}");
    }

    #[test]
    fn symlink_target_is_replaced_and_the_link_kept() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        fs::write(d.join("target.stl"), b"old").unwrap();
        std::os::unix::fs::symlink("target.stl", d.join("link.stl")).unwrap();
        let mut o = Outputs::new();
        let id = o.add("--out", &d.join("link.stl")).unwrap();
        o.write(id, |w| w.write_all(b"new")).unwrap();
        o.commit().unwrap();
        assert!(
            fs::symlink_metadata(d.join("link.stl"))
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read(d.join("target.stl")).unwrap(), b"new");
        assert!(leftovers(d).is_empty());
    }

    #[test]
    fn a_device_is_written_to_not_replaced() {
        let mut o = Outputs::new();
        let id = o.add("--out", Path::new("/dev/null")).unwrap();
        o.write(id, |w| w.write_all(b"into the void")).unwrap();
        o.commit().unwrap();
        let m = fs::metadata("/dev/null").unwrap();
        assert!(!m.is_file());
    }

    #[test]
    fn nothing_is_replaced_when_one_output_fails_and_permissions_are_kept() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        fs::write(d.join("a"), b"old a").unwrap();
        fs::set_permissions(d.join("a"), fs::Permissions::from_mode(0o640)).unwrap();
        let mut o = Outputs::new();
        let a = o.add("--out", &d.join("a")).unwrap();
        let b = o.add("--stats", &d.join("b")).unwrap();
        o.write(a, |w| w.write_all(b"new a")).unwrap();
        let e = o
            .write(b, |_| Err(io::Error::other("disk full")))
            .unwrap_err();
        assert!(
            e.to_string().contains("--stats") && !e.to_string().contains("voxoct-tmp"),
            "{e}"
        );
        drop(o);
        assert_eq!(fs::read(d.join("a")).unwrap(), b"old a");
        assert!(!d.join("b").exists());
        assert!(leftovers(d).is_empty());

        let mut o = Outputs::new();
        let a = o.add("--out", &d.join("a")).unwrap();
        o.write(a, |w| w.write_all(b"new a")).unwrap();
        o.commit().unwrap();
        let mode = fs::metadata(d.join("a")).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o640);
    }

    #[test]
    fn messages_are_escaped_and_cut() {
        assert_eq!(terminal_safe("a\u{1b}[31mb\0c"), "a\\u{1b}[31mb\\u{0}c");
        let long = "x".repeat(200_000);
        let cut = terminal_safe(&long);
        assert!(
            cut.len() < 2100 && cut.contains("198000 more characters"),
            "{}",
            cut.len()
        );
    }

    #[test]
    fn a_read_only_file_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ro.toml");
        fs::write(&p, b"x").unwrap();
        fs::set_permissions(&p, fs::Permissions::from_mode(0o444)).unwrap();
        let e = Outputs::new().add("--write", &p).unwrap_err();
        assert!(matches!(e, OutputError::ReadOnly { .. }), "{e}");
    }
}
