//! The mesh formats, chosen by file extension or name, and the writers and readers behind
//! one interface.

use std::fmt;
use std::io::Write;
use std::path::Path;
use std::str::FromStr;

use voxoct_core::glam::Vec3;

use crate::write::check_input;
use crate::{StlError, StlFormat, obj, ply, threemf};

/// A mesh file format that voxoct writes and reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// STL (binary or ASCII, see [`StlFormat`]): triangles only, no unit.
    Stl,
    /// 3MF (3D Manufacturing Format): a ZIP package with an XML model that carries its unit;
    /// the default project format of PrusaSlicer, Bambu Studio and Cura.
    ThreeMf,
    /// Binary little-endian PLY with vertex normals and, when known, a per-vertex `hits`
    /// property (how many depth triangles met the octree leaves around the vertex).
    Ply,
    /// Wavefront OBJ: `v`, `vn` and `f` statements.
    Obj,
}

impl MeshFormat {
    /// Every format, in the order of [`MeshFormat::SUPPORTED`].
    pub const ALL: [Self; 4] = [Self::Stl, Self::ThreeMf, Self::Ply, Self::Obj];

    /// The supported extensions, for messages.
    pub const SUPPORTED: &'static str = ".stl, .3mf, .ply, .obj";

    /// The file extension (lower case, without the dot).
    #[must_use]
    pub fn extension(self) -> &'static str {
        match self {
            Self::Stl => "stl",
            Self::ThreeMf => "3mf",
            Self::Ply => "ply",
            Self::Obj => "obj",
        }
    }

    /// The format of a file extension or format name (case-insensitive, with or without a
    /// leading dot).
    #[must_use]
    pub fn from_extension(ext: &str) -> Option<Self> {
        let ext = ext.strip_prefix('.').unwrap_or(ext);
        Self::ALL
            .into_iter()
            .find(|f| f.extension().eq_ignore_ascii_case(ext))
    }

    /// The format named by `path`'s extension.
    ///
    /// # Errors
    /// [`StlError::UnknownFormat`] when the extension is missing or not supported.
    pub fn from_path(path: &Path) -> Result<Self, StlError> {
        let ext = path.extension().map(|e| e.to_string_lossy().into_owned());
        ext.as_deref()
            .and_then(Self::from_extension)
            .ok_or_else(|| StlError::UnknownFormat {
                name: ext.unwrap_or_default(),
            })
    }
}

impl fmt::Display for MeshFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.extension())
    }
}

impl FromStr for MeshFormat {
    type Err = StlError;

    fn from_str(s: &str) -> Result<Self, StlError> {
        Self::from_extension(s).ok_or_else(|| StlError::UnknownFormat { name: s.to_owned() })
    }
}

/// A borrowed indexed mesh to write: positions (metres, or whatever unit `scale` maps to
/// the file's), outward-wound triangles, and optional per-vertex hit counts.
#[derive(Debug, Clone, Copy, Default)]
pub struct MeshRef<'a> {
    /// Vertex positions.
    pub vertices: &'a [Vec3],
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: &'a [[u32; 3]],
    /// Per-vertex hit counts (one per vertex), written by the PLY writer as the `hits`
    /// property; ignored by the other formats.
    pub hits: Option<&'a [u32]>,
}

impl<'a> MeshRef<'a> {
    /// A mesh without hit counts.
    #[must_use]
    pub fn new(vertices: &'a [Vec3], triangles: &'a [[u32; 3]]) -> Self {
        Self {
            vertices,
            triangles,
            hits: None,
        }
    }

    /// Checks indices, the scale and the length of the per-vertex data.
    pub(crate) fn check(&self, scale: f32) -> Result<(), StlError> {
        check_input(self.vertices, self.triangles, scale)?;
        if let Some(h) = self.hits
            && h.len() != self.vertices.len()
        {
            return Err(StlError::VertexDataLength {
                what: "hits",
                len: h.len(),
                vertex_count: self.vertices.len(),
            });
        }
        Ok(())
    }
}

/// How [`write_mesh`] writes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriteOptions {
    /// File units per unit of the mesh: 1000 writes a mesh in metres as millimetres (the
    /// default; what slicers assume), 1 keeps metres. 3MF records the unit this implies.
    pub scale: f32,
    /// Binary or ASCII, for [`MeshFormat::Stl`].
    pub stl: StlFormat,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self {
            scale: 1000.0,
            stl: StlFormat::Binary,
        }
    }
}

/// Writes `mesh` in `format` to `w`, streaming (the caller's writer should be buffered;
/// the writers encode in chunks).
///
/// # Errors
/// [`StlError::InvalidArgument`], [`StlError::IndexOutOfRange`],
/// [`StlError::VertexDataLength`], format limits ([`StlError::TooManyTriangles`],
/// [`StlError::No3mfUnit`]), or the writer's [`StlError::Io`] / [`StlError::Zip`].
pub fn write_mesh<W: Write>(
    w: W,
    format: MeshFormat,
    mesh: MeshRef<'_>,
    opts: &WriteOptions,
) -> Result<(), StlError> {
    mesh.check(opts.scale)?;
    match format {
        MeshFormat::Stl => {
            crate::write::encode(w, mesh.vertices, mesh.triangles, opts.stl, opts.scale)
        }
        MeshFormat::ThreeMf => threemf::write_3mf(w, mesh.vertices, mesh.triangles, opts.scale),
        MeshFormat::Ply => ply::write_ply(w, mesh, opts.scale),
        MeshFormat::Obj => obj::write_obj(w, mesh.vertices, mesh.triangles, opts.scale),
    }
}

/// Writes `mesh` to the file at `path` atomically with [`write_atomic`](crate::write_atomic)
/// (a temporary file in the same directory, synced and renamed; never a partly written
/// file at `path`; a symbolic link, directory or device at `path` is refused).
///
/// # Errors
/// As [`write_mesh`], or the refusal of [`write_atomic`](crate::write_atomic) as
/// [`StlError::Io`], wrapped in [`StlError::File`] naming `path`.
pub fn write_mesh_file(
    path: impl AsRef<Path>,
    format: MeshFormat,
    mesh: MeshRef<'_>,
    opts: &WriteOptions,
) -> Result<(), StlError> {
    let path = path.as_ref();
    crate::write_atomic(path, |w| write_mesh(w, format, mesh, opts))
        .map_err(|e: StlError| e.in_file(path))
}

/// An indexed mesh read from a file, in the file's units.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadMesh {
    /// Vertex positions, file units.
    pub vertices: Vec<Vec3>,
    /// Triangles as indices into `vertices` (polygons are fan-triangulated).
    pub triangles: Vec<[u32; 3]>,
    /// Metres per file unit when the file states its unit (3MF), `None` otherwise.
    pub metres_per_unit: Option<f64>,
}

/// Most vertices or triangles any reader accepts (a hostile file cannot make a reader
/// allocate more than a few GB): 200 million.
pub const MAX_ELEMENTS: u64 = 200_000_000;

/// Reads a mesh from `bytes` in `format`. STL soups are welded (identical coordinates are
/// one vertex, see [`crate::weld`]).
///
/// # Errors
/// The format's parse errors ([`StlError::Syntax`], [`StlError::Ply`], [`StlError::Obj`],
/// [`StlError::ThreeMf`], [`StlError::Zip`], ...), [`StlError::TooLarge`] past
/// [`MAX_ELEMENTS`] or a 3MF model that inflates past its limit, and
/// [`StlError::IndexOutOfRange`] for an index past the vertices.
pub fn read_mesh(bytes: &[u8], format: MeshFormat) -> Result<ReadMesh, StlError> {
    let mesh = match format {
        MeshFormat::Stl => {
            let (vertices, triangles) = crate::weld(&crate::parse(bytes)?);
            ReadMesh {
                vertices,
                triangles,
                metres_per_unit: None,
            }
        }
        MeshFormat::Obj => {
            let text = std::str::from_utf8(bytes).map_err(|e| StlError::Obj {
                line: 1 + bytes[..e.valid_up_to()]
                    .iter()
                    .filter(|&&b| b == b'\n')
                    .count(),
                message: "invalid UTF-8".into(),
            })?;
            let (vertices, triangles) = obj::parse_obj(text)?;
            ReadMesh {
                vertices,
                triangles,
                metres_per_unit: None,
            }
        }
        MeshFormat::Ply => ply::parse_ply(bytes)?,
        MeshFormat::ThreeMf => threemf::read_3mf(std::io::Cursor::new(bytes))?,
    };
    Ok(mesh)
}

/// Reads the mesh file at `path`, the format chosen by its extension (see [`read_mesh`]).
///
/// # Errors
/// [`StlError::UnknownFormat`], or as [`read_mesh`]; every error names the file.
pub fn read_mesh_file(path: impl AsRef<Path>) -> Result<ReadMesh, StlError> {
    let path = path.as_ref();
    (|| {
        let format = MeshFormat::from_path(path)?;
        crate::check_mesh_file(path)?;
        if format == MeshFormat::ThreeMf {
            // The ZIP reader seeks: no need to hold the compressed file in memory.
            let file = std::io::BufReader::new(std::fs::File::open(path)?);
            return threemf::read_3mf(file);
        }
        read_mesh(&std::fs::read(path)?, format)
    })()
    .map_err(|e: StlError| e.in_file(path))
}

/// Appends the decimal digits of `v` (what `write!("{v}")` gives, without the formatting
/// machinery: the text writers spend most of their time on triangle indices).
#[inline]
pub(crate) fn push_u64(buf: &mut Vec<u8>, mut v: u64) {
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    buf.extend_from_slice(&digits[i..]);
}

/// Which axis of a mesh file points up: a file written for printing or read as slicers and
/// CAD tools write it has +Z up; voxoct's own platform frame (SCAN_FORMAT.md) has +Y up.
/// Going from one to the other is a proper rotation about the x axis (no mirroring).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpAxis {
    /// +Z up: what slicers, viewers and CAD tools expect (the default). Files voxoct writes
    /// this way stand with their base on z = 0, centred in x and y.
    #[default]
    Z,
    /// +Y up: the platform frame itself, unchanged (and many graphics tools' convention).
    Y,
}

#[cfg(test)]
mod tests {
    use super::push_u64;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn push_u64_writes_what_display_writes(v in any::<u64>()) {
            let mut buf = b"x".to_vec();
            push_u64(&mut buf, v);
            prop_assert_eq!(buf, format!("x{v}").into_bytes());
        }
    }

    #[test]
    fn push_u64_edges() {
        for v in [0, 9, 10, 99, 100, u64::from(u32::MAX), u64::MAX] {
            let mut buf = Vec::new();
            push_u64(&mut buf, v);
            assert_eq!(buf, v.to_string().into_bytes());
        }
    }
}
