//! The one error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong between raw frames and triangles.
///
/// Errors about files name the file; errors about `scan.toml` or a scanner
/// configuration name the key by its dotted path (`sensor.fx`, `snapshot[2].angle_deg`);
/// errors about snapshot files name the byte offset.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DepthError {
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

    /// A filter was given no frames.
    #[error("no frames to filter")]
    NoFrames,

    /// A frame's `data` does not hold `width * height` values.
    ///
    /// How to fix: build frames with [`crate::DepthFrame::empty`] or keep `data.len()` in step.
    #[error("frame {index}: {len} values for a {width}x{height} frame")]
    MalformedFrame {
        /// Index of the frame among the filter's input (0 for a single frame).
        index: usize,
        /// Values found.
        len: usize,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },

    /// Frames of one snapshot (or a frame and the intrinsics) disagree on the size.
    #[error("frame {index} is {found_w}x{found_h}, expected {expected_w}x{expected_h}")]
    FrameSizeMismatch {
        /// Index of the offending frame (0 for a single frame).
        index: usize,
        /// Expected width.
        expected_w: u32,
        /// Expected height.
        expected_h: u32,
        /// Width found.
        found_w: u32,
        /// Height found.
        found_h: u32,
    },

    /// Frames of one snapshot disagree on the depth unit, or the unit is not a positive number.
    #[error("frame {index} has depth unit {found} m, expected {expected} m")]
    UnitMismatch {
        /// Index of the offending frame.
        index: usize,
        /// Unit of the first frame (or the configured one).
        expected: f32,
        /// Unit found.
        found: f32,
    },

    /// A filter name that is not known.
    ///
    /// How to fix: use one of the names listed in the message, joined by `+`.
    #[error("unknown filter `{name}`; valid filters: {valid}")]
    UnknownFilter {
        /// The name given.
        name: String,
        /// The valid names, comma separated.
        valid: &'static str,
    },

    /// A filter chain that names known filters but does not make sense.
    #[error("filter chain `{chain}`: {reason}")]
    BadFilterChain {
        /// The chain as given.
        chain: String,
        /// What is wrong with it.
        reason: String,
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

    /// A snapshot file that does not start with the snapshot magic.
    #[error("not a voxoct snapshot file (magic {found:02x?} at byte 0)")]
    SnapshotMagic {
        /// The first bytes found.
        found: [u8; 8],
    },

    /// A snapshot file of a version this build does not read.
    #[error(
        "snapshot file version {found} is not supported (this build reads version {supported})"
    )]
    SnapshotVersion {
        /// Version found.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },

    /// A snapshot file that ends early.
    ///
    /// How to fix: the file was cut short (a full disk, an interrupted copy); write it again.
    #[error("snapshot file truncated: {what} expected at byte {offset}")]
    SnapshotTruncated {
        /// Byte offset where the missing part starts.
        offset: u64,
        /// What was expected there.
        what: &'static str,
    },

    /// A snapshot file whose header holds an impossible value.
    #[error("snapshot file: bad header field `{field}` at byte {offset}: {reason}")]
    SnapshotHeader {
        /// The field.
        field: &'static str,
        /// Its byte offset.
        offset: u64,
        /// Why it is refused.
        reason: String,
    },

    /// Reading or writing a snapshot stream failed.
    #[error("snapshot stream at byte {offset}: {source}")]
    SnapshotIo {
        /// Byte offset.
        offset: u64,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// An error inside a named file (wraps a stream-level error such as a snapshot one).
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// The error.
        #[source]
        source: Box<DepthError>,
    },

    /// A parameter passed by the caller is out of range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Why it is refused.
        reason: String,
    },
}

impl DepthError {
    /// An [`DepthError::Io`] for `path`.
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }

    /// The innermost error: unwraps [`DepthError::InFile`].
    #[must_use]
    pub fn root(&self) -> &DepthError {
        match self {
            Self::InFile { source, .. } => source.root(),
            e => e,
        }
    }
}
