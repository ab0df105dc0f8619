//! The one error type of every depth source.

use std::path::PathBuf;

/// What can go wrong while opening a depth source, loading a model or grabbing a frame.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SourceError {
    /// A file could not be read.
    ///
    /// How to fix: check that the path exists and is readable.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },

    /// A file or directory could not be written (fakenect recordings).
    ///
    /// How to fix: check that the parent directory exists and is writable, and that the disk
    /// is not full.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },

    /// An OBJ file has a line that cannot be understood.
    ///
    /// How to fix: the line number points at the offending `v` or `f` statement; only
    /// `v x y z` and `f a b c ...` (with `a`, `a/b`, `a//c`, `a/b/c` and negative indices)
    /// are read, everything else is ignored.
    #[error("{path}:{line}: {message}")]
    Obj {
        /// The OBJ file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },

    /// A model file (STL, PLY or 3MF) could not be decoded.
    #[error("cannot load model {path}: {source}")]
    Stl {
        /// The model file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: voxoct_stl::StlError,
    },

    /// A model file's extension is not one of `.stl`, `.3mf`, `.ply`, `.obj`.
    ///
    /// How to fix: convert the model to one of them, or rename it if the extension is wrong.
    #[error(
        "{path}: unknown model format (expected {})",
        voxoct_stl::MeshFormat::SUPPORTED
    )]
    UnknownModelFormat {
        /// The model file.
        path: PathBuf,
    },

    /// A model has no triangles, or a coordinate that is not finite, or no height.
    #[error("model {what} is unusable: {message}")]
    BadModel {
        /// The file or built-in name.
        what: String,
        /// What is wrong with it.
        message: String,
    },

    /// A configuration value is out of range (the field is named).
    ///
    /// How to fix: see the field's documentation for the allowed range.
    #[error("invalid configuration: {field}: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// Why it is rejected.
        message: String,
    },

    /// A line of a fakenect `INDEX.txt` is malformed.
    ///
    /// How to fix: every line must be a bare file name such as
    /// `d-1294356874.123456-123456789.pgm`, with no directory part.
    #[error("{path}:{line}: {message}")]
    FakenectIndex {
        /// The `INDEX.txt` file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },

    /// A fakenect depth file has an unexpected header.
    ///
    /// How to fix: a depth file must start with `P5 640 480 65535` and one whitespace
    /// character, as libfreenect's `record` tool writes it.
    #[error("{path}: bad depth header at byte {offset}: {message}")]
    FakenectHeader {
        /// The `.pgm` file.
        path: PathBuf,
        /// Byte offset where the problem was found.
        offset: usize,
        /// What is wrong with it.
        message: String,
    },

    /// A fakenect depth file ends before all pixels were read.
    #[error("{path}: truncated depth file: {expected} bytes of pixels expected, {found} present")]
    FakenectShort {
        /// The `.pgm` file.
        path: PathBuf,
        /// Pixel bytes expected after the header.
        expected: usize,
        /// Pixel bytes present.
        found: usize,
    },

    /// Every frame of a recording has been served.
    ///
    /// How to fix: open the recording again, or use `FakenectSource::looping` to serve it
    /// round and round.
    #[error("end of recording {dir} after {frames} depth frames")]
    EndOfRecording {
        /// The recording directory.
        dir: PathBuf,
        /// How many depth frames it holds.
        frames: usize,
    },

    /// No Kinect v1 answered at the given index.
    ///
    /// How to fix: check the USB cable and the Kinect's own power supply (the sensor needs
    /// its 12 V adapter on a plain USB port), `lsusb` should list `045e:02ae`; on Linux the
    /// user also needs permission on the device (udev rule from libfreenect).
    #[error(
        "no Kinect v1 found at index {index}: check USB and power (the Kinect needs its own \
         12 V adapter), and that `lsusb` lists 045e:02ae (libfreenect returned {code})"
    )]
    NoKinect {
        /// Device index that was asked for.
        index: i32,
        /// The libfreenect return code.
        code: i32,
    },

    /// libfreenect was not found when voxoct-kinect was built, so no live Kinect can be used.
    ///
    /// How to fix: `apt-get install libfreenect-dev`, then rebuild (set
    /// `LIBFREENECT_REQUIRED=1` to make a missing library a build error).
    #[error(
        "libfreenect was not available at build time; install libfreenect-dev and rebuild \
         with the `freenect` feature"
    )]
    FreenectUnavailable,

    /// A libfreenect call on an opened device failed.
    #[error("libfreenect call {call} failed with code {code}")]
    Device {
        /// The C function.
        call: &'static str,
        /// Its return code.
        code: i32,
    },

    /// No frame arrived within the timeout.
    #[error("no depth frame within {0:?}")]
    Timeout(std::time::Duration),
}
