//! Atomic file replacement: the one implementation of the workspace.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Bytes of the write buffer [`write_atomic`] puts in front of the temporary file.
const BUFFER_BYTES: usize = 1 << 20;

/// Writes a file so that `path` holds either its old contents or the complete new ones,
/// never a partial file.
///
/// `fill` writes the contents into a buffered temporary file created beside `path`
/// (`.NAME.PID-N.tmp`, in the same directory so that the rename cannot cross file
/// systems). When `fill` succeeds, the buffer is flushed, the file is synced to disk
/// (`fsync`), given the permissions of the file it replaces (if any) and renamed over
/// `path`; then the directory is synced so that the rename itself survives a power cut
/// (best effort: a file system that cannot sync a directory does not make the write
/// fail). When anything fails — `fill` returns an error or panics, the disk is full,
/// the rename is refused — the temporary file is removed and `path` is untouched.
///
/// Only a regular file is ever replaced. If `path` exists and is a symbolic link (even
/// one to a regular file), a directory, a device, a FIFO or a socket, nothing is written
/// and the error is an [`io::Error`] of kind [`io::ErrorKind::InvalidInput`] whose
/// message names the path and what is there. (Between that check and the rename another
/// process could put something else at `path`; the rename then replaces that entry, as
/// `rename(2)` does.)
///
/// The error type is the caller's: anything an [`io::Error`] converts into, so `fill` may
/// return the caller's own error (e.g. [`StlError`](crate::StlError)) or plain
/// [`io::Result`]. The I/O errors of this function do not repeat `path` except for the
/// refusal above: wrap them with the path as the caller's errors do.
///
/// # Errors
/// The error of `fill`, or the [`io::Error`] of creating, writing, syncing or renaming
/// the temporary file, or the refusal to replace a non-regular file.
///
/// # Example
/// ```
/// use std::io::Write;
///
/// let dir = std::env::temp_dir().join(format!("voxoct-doc-atomic-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// let path = dir.join("notes.txt");
/// voxoct_stl::write_atomic(&path, |w| writeln!(w, "first"))?;
/// // A failing writer leaves the old contents in place, and no temporary file.
/// let failed: std::io::Result<()> = voxoct_stl::write_atomic(&path, |w| {
///     write!(w, "half")?;
///     Err(std::io::Error::other("interrupted"))
/// });
/// assert!(failed.is_err());
/// assert_eq!(std::fs::read_to_string(&path)?, "first\n");
/// assert_eq!(std::fs::read_dir(&dir)?.count(), 1);
/// // A directory is never replaced.
/// let refused: std::io::Result<()> = voxoct_stl::write_atomic(&dir, |w| writeln!(w, "x"));
/// assert_eq!(refused.unwrap_err().kind(), std::io::ErrorKind::InvalidInput);
/// # std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), std::io::Error>(())
/// ```
pub fn write_atomic<E: From<io::Error>>(
    path: impl AsRef<Path>,
    fill: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
) -> Result<(), E> {
    let path = path.as_ref();
    let old = existing_regular_file(path)?;
    let (mut temp, file) = TempFile::create(path)?;
    let mut w = BufWriter::with_capacity(BUFFER_BYTES, file);
    fill(&mut w)?;
    let file = w.into_inner().map_err(io::IntoInnerError::into_error)?;
    file.sync_all()?;
    if let Some(meta) = old {
        file.set_permissions(meta.permissions())?;
    }
    drop(file);
    fs::rename(&temp.path, path)?;
    temp.renamed = true;
    sync_dir(&parent_dir(path));
    Ok(())
}

/// The metadata of the regular file at `path`, `None` when nothing is there, or the
/// refusal to replace anything else.
fn existing_regular_file(path: &Path) -> io::Result<Option<fs::Metadata>> {
    let meta = match fs::symlink_metadata(path) {
        Ok(meta) => meta,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e),
    };
    let ft = meta.file_type();
    if ft.is_file() {
        return Ok(Some(meta));
    }
    let kind = if ft.is_symlink() {
        "a symbolic link"
    } else if ft.is_dir() {
        "a directory"
    } else {
        special_kind(&ft)
    };
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!(
            "refusing to replace {}: it is {kind}, not a regular file",
            path.display()
        ),
    ))
}

#[cfg(unix)]
fn special_kind(ft: &fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_block_device() {
        "a block device"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_fifo() {
        "a FIFO"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &fs::FileType) -> &'static str {
    "a special file"
}

/// The directory that holds `path` (`.` for a bare file name).
fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_owned(),
        _ => PathBuf::from("."),
    }
}

/// Syncs a directory so that a rename in it is durable; best effort (not every platform
/// or file system can open or sync a directory).
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A temporary file beside the destination, removed on drop unless renamed.
struct TempFile {
    path: PathBuf,
    renamed: bool,
}

impl TempFile {
    /// Creates a new, empty temporary file beside `dest`.
    fn create(dest: &Path) -> io::Result<(Self, File)> {
        let name = dest
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "out".to_owned());
        let dir = parent_dir(dest);
        loop {
            let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
            let path = dir.join(format!(".{name}.{}-{n}.tmp", std::process::id()));
            // `create_new`: never open (or follow a link to) an existing file.
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok((
                        Self {
                            path,
                            renamed: false,
                        },
                        file,
                    ));
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
                Err(e) => return Err(e),
            }
        }
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.renamed {
            // Best effort: the file may already be gone.
            let _ = fs::remove_file(&self.path);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_a_new_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        write_atomic(&path, |w| w.write_all(b"hello")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"hello");
        assert_eq!(entries(dir.path()), ["a.bin"]);
    }

    #[test]
    fn replaces_a_regular_file_and_keeps_its_permissions() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        fs::write(&path, b"old contents").unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
        }
        write_atomic(&path, |w| w.write_all(b"new")).unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert_eq!(entries(dir.path()), ["a.bin"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o640);
        }
    }

    #[test]
    fn a_failing_fill_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        fs::write(&path, b"old").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(&[7u8; 3 * BUFFER_BYTES])?; // past the buffer: bytes reach the disk
            Err(io::Error::other("stop"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "stop");
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()), ["a.bin"]);

        // Nothing at all when there was no file before.
        let fresh = dir.path().join("b.bin");
        assert!(write_atomic(&fresh, |_| Err(io::Error::other("stop"))).is_err());
        assert_eq!(entries(dir.path()), ["a.bin"]);
    }

    #[test]
    fn a_panicking_fill_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        let caught = std::panic::catch_unwind(|| {
            let _ = write_atomic(&path, |w| -> io::Result<()> {
                w.write_all(b"partial")?;
                panic!("fill panicked");
            });
        });
        assert!(caught.is_err());
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn the_callers_error_type_passes_through() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.stl");
        let err = write_atomic(&path, |_| {
            Err(crate::StlError::InvalidArgument {
                name: "scale",
                value: 0.0,
                reason: "test",
            })
        })
        .unwrap_err();
        assert!(matches!(
            err,
            crate::StlError::InvalidArgument { name: "scale", .. }
        ));
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn refuses_a_directory() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("sub");
        fs::create_dir(&sub).unwrap();
        let err = write_atomic(&sub, |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("a directory"), "{err}");
        assert!(sub.is_dir());
        assert_eq!(entries(dir.path()), ["sub"]);
    }

    #[cfg(unix)]
    #[test]
    fn refuses_a_symlink_even_to_a_regular_file() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.stl");
        fs::write(&target, b"target").unwrap();
        let link = dir.path().join("link.stl");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let mut called = false;
        let err = write_atomic(&link, |w| {
            called = true;
            w.write_all(b"x")
        })
        .unwrap_err();
        assert!(!called);
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert!(err.to_string().contains("link.stl"), "{err}");
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read(&target).unwrap(), b"target");
        assert_eq!(entries(dir.path()), ["link.stl", "target.stl"]);

        // A dangling link too: it is not a regular file.
        let dangling = dir.path().join("dangling.stl");
        std::os::unix::fs::symlink(dir.path().join("nowhere"), &dangling).unwrap();
        assert!(write_atomic(&dangling, |w| w.write_all(b"x")).is_err());
        assert!(!dir.path().join("nowhere").exists());
    }

    #[cfg(unix)]
    #[test]
    fn refuses_a_device() {
        let err = write_atomic("/dev/null", |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("character device"), "{err}");
        assert!(
            fs::metadata("/dev/null")
                .map(|m| !m.file_type().is_file())
                .unwrap()
        );
    }

    #[cfg(unix)]
    #[test]
    fn refuses_a_socket() {
        let dir = tempfile::tempdir().unwrap();
        let sock = dir.path().join("s.sock");
        let _listener = std::os::unix::net::UnixListener::bind(&sock).unwrap();
        let err = write_atomic(&sock, |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("a socket"), "{err}");
        assert_eq!(entries(dir.path()), ["s.sock"]);
    }

    #[cfg(unix)]
    #[test]
    fn refuses_a_fifo() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("f");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            return; // no mkfifo here: the device and socket tests cover special files
        }
        let err = write_atomic(&fifo, |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("a FIFO"), "{err}");
        assert_eq!(entries(dir.path()), ["f"]);
    }

    #[test]
    fn a_missing_directory_is_an_error_and_creates_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/a.stl");
        let err = write_atomic(&path, |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn a_bare_file_name_is_written_in_the_current_directory() {
        assert_eq!(parent_dir(Path::new("a.stl")), Path::new("."));
        assert_eq!(parent_dir(Path::new("d/a.stl")), Path::new("d"));
    }
}
