//! The one error type of voxoct-stl.

use std::path::PathBuf;

/// Everything that can go wrong reading or writing a mesh file (STL, 3MF, PLY, OBJ).
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

    /// An argument out of its domain: `name` is the parameter as the signature spells it
    /// (`"scale"`: not finite and positive); the same pattern as
    /// `voxoct_core::OctreeError::InvalidArgument` and
    /// `voxoct_mesh::MeshError::InvalidArgument`.
    ///
    /// How to fix: use scale 1000.0 to write a mesh in metres as millimetres, 1.0 to keep
    /// units.
    #[error("invalid `{name}` = {value}: {reason}")]
    InvalidArgument {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What the value must be.
        reason: &'static str,
    },

    /// The path is not a regular file (a directory, a device such as `/dev/zero`, a FIFO).
    ///
    /// How to fix: name the STL file itself.
    #[error("not a regular file ({kind}); a mesh model is a file")]
    NotAFile {
        /// What is there instead.
        kind: &'static str,
    },

    /// The input is larger than [`crate::MAX_FILE_BYTES`].
    ///
    /// How to fix: simplify the model (fewer triangles) before scanning it.
    #[error("{len} bytes is more than the {max} bytes an STL may have here; simplify the model")]
    FileTooLarge {
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

    /// A file name or `--format` value that names no supported mesh format.
    ///
    /// How to fix: use one of the listed extensions (or `--format`).
    #[error(
        "unknown mesh format {name:?}: supported formats are {}",
        crate::MeshFormat::SUPPORTED
    )]
    UnknownFormat {
        /// The extension or name given (`""` when the file name has no extension).
        name: String,
    },

    /// A scale for which the 3MF format has no unit.
    ///
    /// How to fix: write 3MF with `scale` 1000 (millimetres) or 1 (metres).
    #[error(
        "3MF has no unit for scale {scale} (file units per metre): use 1e6 (micron), 1000 \
         (millimeter), 100 (centimeter), 39.37 (inch), 3.28 (foot) or 1 (meter)"
    )]
    No3mfUnit {
        /// The scale given.
        scale: f32,
    },

    /// The ZIP container of a 3MF file could not be written or read.
    #[error("3MF container: {0}")]
    Zip(#[from] zip::result::ZipError),

    /// A 3MF file whose package or model does not follow the 3MF core specification.
    ///
    /// How to fix: the named part is malformed; re-export the file from its application.
    #[error("3MF {part}: {message}")]
    ThreeMf {
        /// The package part (e.g. `3D/3dmodel.model`).
        part: String,
        /// What is wrong with it.
        message: String,
    },

    /// A PLY file that does not follow the PLY format (header or body).
    ///
    /// How to fix: the file is cut off or not PLY; export it again.
    #[error("PLY: {message}")]
    Ply {
        /// What is wrong, with the element/line/byte offset where known.
        message: String,
    },

    /// A Wavefront OBJ file with a malformed statement.
    #[error("OBJ line {line}: {message}")]
    Obj {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },

    /// A file that declares or holds more than a reader accepts (a hostile or corrupt file).
    #[error("{what}: {count} is more than the limit {limit}")]
    TooLarge {
        /// What was counted (e.g. "3MF vertices").
        what: &'static str,
        /// The count found or declared.
        count: u64,
        /// The limit.
        limit: u64,
    },

    /// Per-vertex values whose length is not the vertex count.
    #[error("{what} has {len} values for {vertex_count} vertices")]
    VertexDataLength {
        /// Which values (e.g. "hits").
        what: &'static str,
        /// Their number.
        len: usize,
        /// The number of vertices.
        vertex_count: usize,
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
