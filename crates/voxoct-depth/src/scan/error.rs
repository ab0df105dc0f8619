//! The error of the recorded-scan directory.

use std::path::PathBuf;

use crate::FrameError;

/// What can go wrong reading or writing a recorded-scan directory, its `scan.toml` or a
/// scanner configuration file.
///
/// Errors about files name the file; errors about `scan.toml` or a scanner
/// configuration name the key by its dotted path (`sensor.fx`, `snapshot[2].angle_deg`).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScanError {
    /// An I/O operation on a file failed.
    ///
    /// How to fix: check that the path exists and is readable (or writable).
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// A TOML file that does not parse.
    #[error("{}: {message}", path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line and column).
        message: String,
    },

    /// A required key is missing.
    ///
    /// How to fix: add the key; SCAN_FORMAT.md lists every required key.
    #[error("{}: missing key `{key}`", path.display())]
    MissingKey {
        /// The file.
        path: PathBuf,
        /// Dotted path of the key.
        key: String,
    },

    /// A key holds a value of the wrong type.
    #[error("{}: key `{key}` must be {expected}, found {found}", path.display())]
    WrongType {
        /// The file.
        path: PathBuf,
        /// Dotted path of the key.
        key: String,
        /// What was expected.
        expected: &'static str,
        /// The TOML type found.
        found: &'static str,
    },

    /// A key holds a value of the right type but outside its valid range.
    #[error("{}: key `{key}`: {reason}", path.display())]
    InvalidValue {
        /// The file.
        path: PathBuf,
        /// Dotted path of the key.
        key: String,
        /// Why the value is refused.
        reason: String,
    },

    /// `format` is not `voxoct-scan`.
    #[error("{}: format is `{found}`, expected `voxoct-scan`", path.display())]
    WrongFormat {
        /// The file.
        path: PathBuf,
        /// The format found.
        found: String,
    },

    /// An unsupported version of a file format.
    ///
    /// How to fix: convert the file with the tool that wrote it, or upgrade voxoct.
    #[error("{}: version {found} is not supported (this build reads version {supported})", path.display())]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// Version found.
        found: i64,
        /// Version this build reads.
        supported: u32,
    },

    /// A scan manifest without any `[[snapshot]]`.
    #[error("{}: the scan has no `[[snapshot]]`", path.display())]
    NoSnapshots {
        /// The file.
        path: PathBuf,
    },

    /// A PNG frame that does not decode or encode.
    #[error("{}: PNG: {message}", path.display())]
    Png {
        /// The frame file.
        path: PathBuf,
        /// The decoder's message.
        message: String,
    },

    /// A settings or manifest file that is not a regular file, or too large to be one.
    ///
    /// How to fix: name the TOML file itself (not a device or FIFO).
    #[error("{}: {reason}", path.display())]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },

    /// A frame file of the wrong size, bit depth or colour type.
    ///
    /// How to fix: frames are 16-bit greyscale PNGs of the sensor's width and height.
    #[error("{}: {reason}", path.display())]
    BadFrameFile {
        /// The frame file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },

    /// A manifest and the frames given to write disagree.
    #[error("scan to write: {reason}")]
    ScanMismatch {
        /// What disagrees.
        reason: String,
    },

    /// A frame to write, or a frame read, that the frame checks refuse.
    #[error(transparent)]
    Frame(#[from] FrameError),
}

impl ScanError {
    /// An [`ScanError::Io`] for `path`.
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    /// A [`ScanError::WrongType`] with another description of what was found.
    pub(crate) fn with_found(self, found: &'static str) -> Self {
        match self {
            Self::WrongType {
                path,
                key,
                expected,
                ..
            } => Self::WrongType {
                path,
                key,
                expected,
                found,
            },
            e => e,
        }
    }
}
