//! STL writers: binary, ASCII, and STL file output.

use std::io::{BufWriter, Write};
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};
use voxoct_core::glam::Vec3;

use crate::StlError;

/// The two STL encodings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StlFormat {
    /// 80-byte header, `u32` count, 50 bytes per triangle (what slicers prefer).
    #[default]
    Binary,
    /// Human-readable `solid … endsolid` text.
    Ascii,
}

/// Bytes per binary triangle record.
pub const BINARY_TRIANGLE_BYTES: usize = 50;
/// Bytes of the binary header plus the triangle count.
pub const BINARY_HEADER_BYTES: usize = 84;

const HEADER: &[u8] = b"voxoct binary STL";
/// Triangles encoded per `write_all` call.
const CHUNK: usize = 1024;

/// The one input check of every writer: a finite positive scale, every index in range.
pub(crate) fn check_input(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(StlError::InvalidArgument {
            name: "scale",
            value: f64::from(scale),
            reason: "must be finite and positive (file units per metre: 1000 for millimetres)",
        });
    }
    for (t, tri) in triangles.iter().enumerate() {
        for &index in tri {
            if index as usize >= vertices.len() {
                return Err(StlError::IndexOutOfRange {
                    triangle: t,
                    index,
                    vertex_count: vertices.len(),
                });
            }
        }
    }
    Ok(())
}

/// The scaled corners and the unit facet normal (from the winding, zero when degenerate).
#[inline]
fn facet(vertices: &[Vec3], tri: &[u32; 3], scale: f32) -> (Vec3, [Vec3; 3]) {
    let p = [
        vertices[tri[0] as usize] * scale,
        vertices[tri[1] as usize] * scale,
        vertices[tri[2] as usize] * scale,
    ];
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
    (n, p)
}

/// Writes an indexed mesh as binary STL, coordinates multiplied by `scale`
/// (1000 writes a mesh in metres as millimetres).
///
/// Facet normals are computed from the winding (counter-clockwise seen from outside).
///
/// # Errors
/// [`StlError::InvalidArgument`], [`StlError::IndexOutOfRange`],
/// [`StlError::TooManyTriangles`], or the writer's [`StlError::Io`].
pub fn write_binary<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    check_input(vertices, triangles, scale)?;
    encode_binary(w, vertices, triangles, scale)
}

/// [`write_binary`] without the input check (the caller made it).
pub(crate) fn encode_binary<W: Write>(
    mut w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    let count = u32::try_from(triangles.len()).map_err(|_| StlError::TooManyTriangles {
        count: triangles.len(),
    })?;
    let mut header = [0u8; BINARY_HEADER_BYTES];
    header[..HEADER.len()].copy_from_slice(HEADER);
    LittleEndian::write_u32(&mut header[80..84], count);
    w.write_all(&header)?;

    let mut buf = vec![0u8; CHUNK.min(triangles.len().max(1)) * BINARY_TRIANGLE_BYTES];
    for chunk in triangles.chunks(CHUNK) {
        let bytes = &mut buf[..chunk.len() * BINARY_TRIANGLE_BYTES];
        for (tri, rec) in chunk
            .iter()
            .zip(bytes.chunks_exact_mut(BINARY_TRIANGLE_BYTES))
        {
            let (n, p) = facet(vertices, tri, scale);
            let floats = [
                n.x, n.y, n.z, p[0].x, p[0].y, p[0].z, p[1].x, p[1].y, p[1].z, p[2].x, p[2].y,
                p[2].z,
            ];
            LittleEndian::write_f32_into(&floats, &mut rec[..48]);
            rec[48] = 0;
            rec[49] = 0;
        }
        w.write_all(bytes)?;
    }
    w.flush()?;
    Ok(())
}

/// Writes an indexed mesh as ASCII STL (solid name `voxoct`), coordinates multiplied by `scale`.
///
/// Numbers are written in Rust's shortest round-trip notation, so reading the file back
/// gives the same `f32` bits.
///
/// # Errors
/// [`StlError::InvalidArgument`], [`StlError::IndexOutOfRange`], or the writer's [`StlError::Io`].
pub fn write_ascii<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    check_input(vertices, triangles, scale)?;
    encode_ascii(w, vertices, triangles, scale)
}

/// [`write_ascii`] without the input check (the caller made it).
pub(crate) fn encode_ascii<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    let mut w = BufWriter::with_capacity(1 << 16, w);
    writeln!(w, "solid voxoct")?;
    for tri in triangles {
        let (n, p) = facet(vertices, tri, scale);
        writeln!(w, "  facet normal {:e} {:e} {:e}", n.x, n.y, n.z)?;
        writeln!(w, "    outer loop")?;
        for v in p {
            writeln!(w, "      vertex {:e} {:e} {:e}", v.x, v.y, v.z)?;
        }
        writeln!(w, "    endloop")?;
        writeln!(w, "  endfacet")?;
    }
    writeln!(w, "endsolid voxoct")?;
    w.flush()?;
    Ok(())
}

/// Writes `format` to `w`.
///
/// # Errors
/// As [`write_binary`] and [`write_ascii`].
pub fn write<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    format: StlFormat,
    scale: f32,
) -> Result<(), StlError> {
    check_input(vertices, triangles, scale)?;
    encode(w, vertices, triangles, format, scale)
}

/// [`write()`] without the input check (the caller made it).
pub(crate) fn encode<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    format: StlFormat,
    scale: f32,
) -> Result<(), StlError> {
    match format {
        StlFormat::Binary => encode_binary(w, vertices, triangles, scale),
        StlFormat::Ascii => encode_ascii(w, vertices, triangles, scale),
    }
}

/// Writes an STL file atomically with [`write_atomic`](crate::write_atomic): into a
/// temporary file in the same directory, synced, then renamed over `path`. On any error
/// the temporary file is removed and `path` is untouched, so there is never a partly
/// written file at `path`; a symbolic link, directory or device at `path` is refused.
///
/// # Errors
/// As [`write()`], or the refusal of [`write_atomic`](crate::write_atomic) as
/// [`StlError::Io`], wrapped in [`StlError::File`] naming `path`.
pub fn write_file(
    path: impl AsRef<Path>,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    format: StlFormat,
    scale: f32,
) -> Result<(), StlError> {
    crate::write_mesh_file(
        path,
        crate::MeshFormat::Stl,
        crate::MeshRef::new(vertices, triangles),
        &crate::WriteOptions { scale, stl: format },
    )
}
