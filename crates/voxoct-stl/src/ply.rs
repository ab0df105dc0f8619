//! PLY (Stanford polygon file): binary little-endian writer with vertex normals and an
//! optional per-vertex `hits` property, and a reader for ASCII and binary PLY.

use std::io::Write;

use byteorder::{BigEndian, ByteOrder, LittleEndian};
use voxoct_core::glam::Vec3;

use crate::StlError;
use crate::format::{MAX_ELEMENTS, MeshRef, ReadMesh};
use voxoct_core::vertex_normals;

/// Vertices or faces encoded per `write_all` call.
const CHUNK: usize = 4096;
/// Bytes of a face record: a `uchar` count of 3 and three `uint` indices.
const FACE_BYTES: usize = 1 + 3 * 4;
/// Longest header the reader accepts.
const MAX_HEADER_BYTES: usize = 64 * 1024;

/// Writes binary little-endian PLY: per vertex `x y z` (times `scale`) and the unit
/// area-weighted normal `nx ny nz` as `float`, then `hits` as `uint` when `mesh.hits` is
/// given; per face a `uchar` count of 3 and three `uint` `vertex_indices`, counter-clockwise
/// seen from outside.
///
/// Input is checked by [`crate::write_mesh`]; this writer assumes valid indices and lengths.
pub(crate) fn write_ply<W: Write>(mut w: W, mesh: MeshRef<'_>, scale: f32) -> Result<(), StlError> {
    let MeshRef {
        vertices,
        triangles,
        hits,
    } = mesh;
    let mut header = String::new();
    header.push_str("ply\nformat binary_little_endian 1.0\n");
    header.push_str("comment written by voxoct\n");
    header.push_str(&format!("comment file units per metre: {scale}\n"));
    if hits.is_some() {
        header.push_str(
            "comment hits: depth triangles that met the octree leaves around the vertex \
             (a confidence: more is surer)\n",
        );
    }
    header.push_str(&format!("element vertex {}\n", vertices.len()));
    for p in ["x", "y", "z", "nx", "ny", "nz"] {
        header.push_str(&format!("property float {p}\n"));
    }
    if hits.is_some() {
        header.push_str("property uint hits\n");
    }
    header.push_str(&format!("element face {}\n", triangles.len()));
    header.push_str("property list uchar uint vertex_indices\nend_header\n");
    w.write_all(header.as_bytes())?;

    let normals = vertex_normals(vertices, triangles);
    let vbytes = if hits.is_some() { 28 } else { 24 };
    let mut buf = vec![0u8; CHUNK * vbytes.max(FACE_BYTES)];
    for (k, chunk) in vertices.chunks(CHUNK).enumerate() {
        let base = k * CHUNK;
        let bytes = &mut buf[..chunk.len() * vbytes];
        for (j, (v, rec)) in chunk.iter().zip(bytes.chunks_exact_mut(vbytes)).enumerate() {
            let p = *v * scale;
            let n = normals[base + j];
            LittleEndian::write_f32_into(&[p.x, p.y, p.z, n.x, n.y, n.z], &mut rec[..24]);
            if let Some(h) = hits {
                LittleEndian::write_u32(&mut rec[24..28], h[base + j]);
            }
        }
        w.write_all(bytes)?;
    }
    for chunk in triangles.chunks(CHUNK) {
        let bytes = &mut buf[..chunk.len() * FACE_BYTES];
        for (t, rec) in chunk.iter().zip(bytes.chunks_exact_mut(FACE_BYTES)) {
            rec[0] = 3;
            LittleEndian::write_u32_into(t, &mut rec[1..]);
        }
        w.write_all(bytes)?;
    }
    w.flush()?;
    Ok(())
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar(String, Scalar),
    List(String, Scalar, Scalar),
}

impl Property {
    fn name(&self) -> &str {
        match self {
            Self::Scalar(n, _) | Self::List(n, _, _) => n,
        }
    }

    /// Smallest number of body bytes (binary) or tokens (ASCII) one value takes.
    fn min_size(&self, binary: bool) -> usize {
        match (self, binary) {
            (Self::Scalar(_, t), true) => t.size(),
            (Self::List(_, c, _), true) => c.size(),
            (_, false) => 1,
        }
    }
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

fn ply_err(message: impl Into<String>) -> StlError {
    StlError::Ply {
        message: message.into(),
    }
}

/// The body of a PLY file: binary bytes or ASCII tokens.
enum Body<'a> {
    Binary {
        bytes: &'a [u8],
        pos: usize,
        big: bool,
        start: usize,
    },
    Ascii {
        tokens: std::str::SplitAsciiWhitespace<'a>,
    },
}

impl Body<'_> {
    fn remaining(&self) -> usize {
        match self {
            Body::Binary { bytes, pos, .. } => bytes.len() - pos,
            Body::Ascii { .. } => usize::MAX,
        }
    }

    fn scalar(&mut self, ty: Scalar, what: &dyn Fn() -> String) -> Result<f64, StlError> {
        match self {
            Body::Binary {
                bytes,
                pos,
                big,
                start,
            } => {
                let n = ty.size();
                let Some(b) = bytes.get(*pos..*pos + n) else {
                    return Err(ply_err(format!(
                        "file ends inside {} (byte offset {})",
                        what(),
                        *start + *pos
                    )));
                };
                *pos += n;
                let v = match (ty, *big) {
                    (Scalar::I8, _) => f64::from(b[0] as i8),
                    (Scalar::U8, _) => f64::from(b[0]),
                    (Scalar::I16, false) => f64::from(LittleEndian::read_i16(b)),
                    (Scalar::I16, true) => f64::from(BigEndian::read_i16(b)),
                    (Scalar::U16, false) => f64::from(LittleEndian::read_u16(b)),
                    (Scalar::U16, true) => f64::from(BigEndian::read_u16(b)),
                    (Scalar::I32, false) => f64::from(LittleEndian::read_i32(b)),
                    (Scalar::I32, true) => f64::from(BigEndian::read_i32(b)),
                    (Scalar::U32, false) => f64::from(LittleEndian::read_u32(b)),
                    (Scalar::U32, true) => f64::from(BigEndian::read_u32(b)),
                    (Scalar::F32, false) => f64::from(LittleEndian::read_f32(b)),
                    (Scalar::F32, true) => f64::from(BigEndian::read_f32(b)),
                    (Scalar::F64, false) => LittleEndian::read_f64(b),
                    (Scalar::F64, true) => BigEndian::read_f64(b),
                };
                Ok(v)
            }
            Body::Ascii { tokens } => {
                let t = tokens
                    .next()
                    .ok_or_else(|| ply_err(format!("file ends inside {}", what())))?;
                t.parse::<f64>()
                    .map_err(|_| ply_err(format!("bad number {t:?} in {}", what())))
            }
        }
    }
}

/// A list length or index: a non-negative integer that fits in `u32`.
fn as_index(v: f64, what: &dyn Fn() -> String) -> Result<u32, StlError> {
    if v.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(ply_err(format!("{} is {v}, not a vertex index", what())))
    }
}

fn parse_header(text: &str) -> Result<(Encoding, Vec<Element>), StlError> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end()));
    match lines.next() {
        Some((_, "ply")) => {}
        _ => return Err(ply_err("the file does not begin with \"ply\"")),
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    for (line, l) in lines {
        let words: Vec<&str> = l.split_whitespace().collect();
        let bad = |m: &str| ply_err(format!("header line {line} ({l:?}): {m}"));
        match words.as_slice() {
            ["format", f, "1.0"] => {
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Little,
                    "binary_big_endian" => Encoding::Big,
                    _ => return Err(bad("unknown format")),
                });
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count: u64 = count.parse().map_err(|_| bad("bad element count"))?;
                elements.push(Element {
                    name: (*name).to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", c, t, name] => {
                let (Some(c), Some(t)) = (Scalar::parse(c), Scalar::parse(t)) else {
                    return Err(bad("unknown property type"));
                };
                if matches!(c, Scalar::F32 | Scalar::F64) {
                    return Err(bad("a list count must be an integer type"));
                }
                let e = elements
                    .last_mut()
                    .ok_or_else(|| bad("property before any element"))?;
                e.properties.push(Property::List((*name).to_owned(), c, t));
            }
            ["property", t, name] => {
                let t = Scalar::parse(t).ok_or_else(|| bad("unknown property type"))?;
                let e = elements
                    .last_mut()
                    .ok_or_else(|| bad("property before any element"))?;
                e.properties.push(Property::Scalar((*name).to_owned(), t));
            }
            ["end_header"] => {
                let encoding = encoding.ok_or_else(|| ply_err("the header has no format line"))?;
                return Ok((encoding, elements));
            }
            _ => return Err(bad("not a PLY header statement")),
        }
    }
    Err(ply_err("the header has no end_header line"))
}

/// Parses a PLY file (ASCII, binary little- or big-endian): the `vertex` element's `x y z`
/// and the `face` element's `vertex_indices` (or `vertex_index`) lists, polygons
/// fan-triangulated; other elements and properties are skipped.
///
/// Hostile sizes: the header is at most 64 KiB, and an element count is checked against
/// the bytes that follow (each record takes at least its fixed bytes) and against
/// [`MAX_ELEMENTS`] before anything is allocated.
///
/// # Errors
/// [`StlError::Ply`] for a malformed header or body (with the byte offset where it ended),
/// non-finite coordinates, or an index past the vertices; [`StlError::TooLarge`].
pub fn parse_ply(bytes: &[u8]) -> Result<ReadMesh, StlError> {
    let head = &bytes[..bytes.len().min(MAX_HEADER_BYTES)];
    // The body starts after the end of the `end_header` line.
    let mut body_start = None;
    let mut pos = 0;
    while pos < head.len() {
        let line_end = head[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|i| pos + i);
        if head[pos..line_end.unwrap_or(head.len())].trim_ascii() == b"end_header" {
            body_start = Some(line_end.map_or(head.len(), |e| e + 1));
            break;
        }
        match line_end {
            Some(e) => pos = e + 1,
            None => break,
        }
    }
    let body_start =
        body_start.ok_or_else(|| ply_err("no end_header line within the first 64 KiB"))?;
    let header = std::str::from_utf8(&bytes[..body_start])
        .map_err(|_| ply_err("the header is not ASCII text"))?;
    let (encoding, elements) = parse_header(header)?;
    let rest = &bytes[body_start..];
    let mut body = match encoding {
        Encoding::Ascii => Body::Ascii {
            tokens: std::str::from_utf8(rest)
                .map_err(|_| ply_err("the ASCII body is not text"))?
                .split_ascii_whitespace(),
        },
        Encoding::Little | Encoding::Big => Body::Binary {
            bytes: rest,
            pos: 0,
            big: encoding == Encoding::Big,
            start: body_start,
        },
    };
    let binary = encoding != Encoding::Ascii;
    let body_len = rest.len() as u64;

    let mut mesh = ReadMesh::default();
    let mut saw_vertex = false;
    for e in &elements {
        let min_record: u64 = e.properties.iter().map(|p| p.min_size(binary) as u64).sum();
        let is_vertex = e.name == "vertex";
        let is_face = e.name == "face";
        if e.count > MAX_ELEMENTS && (is_vertex || is_face) {
            return Err(StlError::TooLarge {
                what: if is_vertex {
                    "PLY vertices"
                } else {
                    "PLY faces"
                },
                count: e.count,
                limit: MAX_ELEMENTS,
            });
        }
        // ASCII: every value is at least one character and one separator.
        let per = if binary { min_record } else { 2 * min_record };
        if e.count.saturating_mul(per) > (body.remaining() as u64).min(body_len) {
            return Err(ply_err(format!(
                "element {} declares {} records of at least {per} bytes, more than the {} \
                 bytes that follow",
                e.name,
                e.count,
                body.remaining().min(rest.len())
            )));
        }
        let coord = |name: &str| e.properties.iter().position(|p| p.name() == name);
        let xyz = if is_vertex {
            saw_vertex = true;
            let (Some(x), Some(y), Some(z)) = (coord("x"), coord("y"), coord("z")) else {
                return Err(ply_err("the vertex element has no x, y and z properties"));
            };
            mesh.vertices.reserve(e.count as usize);
            Some([x, y, z])
        } else {
            None
        };
        let list = if is_face {
            let i = coord("vertex_indices")
                .or_else(|| coord("vertex_index"))
                .ok_or_else(|| ply_err("the face element has no vertex_indices list"))?;
            if !matches!(e.properties[i], Property::List(..)) {
                return Err(ply_err("the face element's vertex_indices is not a list"));
            }
            mesh.triangles.reserve(e.count as usize);
            Some(i)
        } else {
            None
        };
        let mut poly: Vec<u32> = Vec::new();
        for r in 0..e.count {
            let mut p = [0.0f64; 3];
            for (k, prop) in e.properties.iter().enumerate() {
                let what = || format!("{} {r} property {}", e.name, prop.name());
                match prop {
                    Property::Scalar(_, t) => {
                        let v = body.scalar(*t, &what)?;
                        if let Some(xyz) = xyz
                            && let Some(a) = xyz.iter().position(|&i| i == k)
                        {
                            p[a] = v;
                        }
                    }
                    Property::List(_, c, t) => {
                        let n = as_index(body.scalar(*c, &what)?, &|| {
                            format!("the length of {}", what())
                        })?;
                        let keep = list == Some(k);
                        if keep {
                            poly.clear();
                        }
                        for _ in 0..n {
                            let v = body.scalar(*t, &what)?;
                            if keep {
                                poly.push(as_index(v, &what)?);
                            }
                        }
                        if keep {
                            if poly.len() < 3 {
                                return Err(ply_err(format!(
                                    "face {r} has {} vertices, at least 3 expected",
                                    poly.len()
                                )));
                            }
                            for j in 1..poly.len() - 1 {
                                mesh.triangles.push([poly[0], poly[j], poly[j + 1]]);
                            }
                        }
                    }
                }
            }
            if xyz.is_some() {
                let v = Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32);
                if !v.is_finite() {
                    return Err(ply_err(format!("vertex {r} is not finite")));
                }
                mesh.vertices.push(v);
            }
        }
        if mesh.triangles.len() as u64 > MAX_ELEMENTS {
            return Err(StlError::TooLarge {
                what: "PLY triangles",
                count: mesh.triangles.len() as u64,
                limit: MAX_ELEMENTS,
            });
        }
    }
    if !saw_vertex {
        return Err(ply_err("no vertex element"));
    }
    let n = mesh.vertices.len();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(StlError::IndexOutOfRange {
                triangle: t,
                index,
                vertex_count: n,
            });
        }
    }
    Ok(mesh)
}
