//! The one error type of voxoct-stl.

use std::path::PathBuf;

/// Everything that can go wrong reading or writing an STL file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StlError {
    /// An I/O error from the underlying reader or writer.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),

    /// An error while reading or writing the file at `path`.
    #[error("{}: {source}", path.display())]
    File {
        /// The file that was read or written.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: Box<StlError>,
    },

    /// The input is shorter than the 84-byte binary header and is not ASCII STL.
    ///
    /// How to fix: the file is empty or cut off; export it again.
    #[error("file is {len} bytes: too short for a binary STL header (84 bytes) and not ASCII STL")]
    TooShort {
        /// Length of the input in bytes.
        len: u64,
    },

    /// A binary file whose header announces more triangles than the file holds.
    ///
    /// How to fix: the file was cut off (interrupted copy or export); export it again.
    #[error(
        "truncated binary STL: header announces {count} triangles ({expected_len} bytes) but the \
         file has {actual_len} bytes; triangle {first_missing} starts past the end"
    )]
    Truncated {
        /// Triangle count from the header (byte offset 80).
        count: u32,
        /// File length the count implies: `84 + 50 * count`.
        expected_len: u64,
        /// Actual length.
        actual_len: u64,
        /// Index of the first triangle that is not complete.
        first_missing: u64,
    },

    /// A binary file longer than its triangle count implies.
    ///
    /// How to fix: the writer put a wrong count at byte offset 80; re-export the file.
    #[error(
        "binary STL triangle count {count} disagrees with the file length: expected {expected_len} \
         bytes, found {actual_len}"
    )]
    CountMismatch {
        /// Triangle count from the header (byte offset 80).
        count: u32,
        /// File length the count implies: `84 + 50 * count`.
        expected_len: u64,
        /// Actual length.
        actual_len: u64,
    },

    /// A binary triangle with a NaN or infinite coordinate.
    #[error("binary STL triangle {triangle} (byte offset {offset}) has a non-finite coordinate")]
    NonFinite {
        /// Index of the triangle.
        triangle: u64,
        /// Byte offset of the triangle's record.
        offset: u64,
    },

    /// An ASCII vertex with a NaN or infinite coordinate.
    #[error("ASCII STL line {line}: non-finite coordinate in triangle {triangle}")]
    NonFiniteAscii {
        /// 1-based line number.
        line: usize,
        /// Index of the triangle.
        triangle: u64,
    },

    /// An ASCII file that does not follow the STL grammar.
    ///
    /// How to fix: the named line is malformed; check the exporter or edit the line.
    #[error("ASCII STL line {line}: expected {expected}, found {found:?}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// What the grammar allows there.
        expected: &'static str,
        /// What the file holds (`""` at the end of the file).
        found: String,
    },

    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, but there are only {vertex_count}")]
    IndexOutOfRange {
        /// Index of the triangle.
        triangle: usize,
        /// The bad vertex index.
        index: u32,
        /// Number of vertices given.
        vertex_count: usize,
    },

    /// A scale that is not finite and positive.
    ///
    /// How to fix: use 1000.0 to write a mesh in metres as millimetres, 1.0 to keep units.
    #[error("scale {scale} is not finite and positive")]
    InvalidScale {
        /// The scale given.
        scale: f32,
    },

    /// The path is not a regular file (a directory, a device such as `/dev/zero`, a FIFO).
    ///
    /// How to fix: name the STL file itself.
    #[error("not a regular file ({kind}); an STL model is a file")]
    NotAFile {
        /// What is there instead.
        kind: &'static str,
    },

    /// The input is larger than [`crate::MAX_FILE_BYTES`].
    ///
    /// How to fix: simplify the model (fewer triangles) before scanning it.
    #[error("{len} bytes is more than the {max} bytes an STL may have here; simplify the model")]
    TooLarge {
        /// Length of the input in bytes (at least this many).
        len: u64,
        /// The limit.
        max: u64,
    },

    /// More triangles than a binary STL can count (`u32::MAX`).
    #[error("{count} triangles do not fit in a binary STL (at most 4294967295)")]
    TooManyTriangles {
        /// Number of triangles given.
        count: usize,
    },
}

impl StlError {
    /// Wraps `self` with the path of the file it concerns.
    #[must_use]
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        Self::File {
            path: path.into(),
            source: Box::new(self),
        }
    }

    /// The error without any [`StlError::File`] wrapping.
    #[must_use]
    pub fn root(&self) -> &StlError {
        match self {
            Self::File { source, .. } => source.root(),
            other => other,
        }
    }
}
