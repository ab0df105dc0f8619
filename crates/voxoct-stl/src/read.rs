//! STL reader with robust binary/ASCII detection, and vertex welding.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};
use voxoct_core::Triangle;
use voxoct_core::glam::Vec3;

use crate::StlError;
use crate::write::{BINARY_HEADER_BYTES, BINARY_TRIANGLE_BYTES};

/// Reads an STL (binary or ASCII, detected from the content) into triangles, in file units.
///
/// Detection: a file whose length is exactly `84 + 50 * count` (count at byte offset 80) is
/// binary even when its header begins with `solid` (many exporters do that); otherwise a file
/// that begins with `solid` and whose first kilobyte is text is parsed as ASCII; anything else
/// is binary and its length is checked against the count.
///
/// Facet normals in the file are ignored: the winding defines the orientation.
///
/// # Errors
/// [`StlError::TooShort`], [`StlError::Truncated`], [`StlError::CountMismatch`],
/// [`StlError::NonFinite`], [`StlError::NonFiniteAscii`], [`StlError::Syntax`], or
/// [`StlError::Io`].
pub fn read<R: Read>(mut r: R) -> Result<Vec<Triangle>, StlError> {
    let mut bytes = Vec::new();
    r.read_to_end(&mut bytes)?;
    parse(&bytes)
}

/// Reads the STL file at `path` (see [`read`]); every error names the file.
///
/// # Errors
/// As [`read`], wrapped in [`StlError::File`].
pub fn read_file(path: impl AsRef<Path>) -> Result<Vec<Triangle>, StlError> {
    let path = path.as_ref();
    std::fs::read(path)
        .map_err(StlError::from)
        .and_then(|bytes| parse(&bytes))
        .map_err(|e| e.in_file(path))
}

/// Parses STL bytes (see [`read`]).
///
/// # Errors
/// As [`read`].
pub fn parse(bytes: &[u8]) -> Result<Vec<Triangle>, StlError> {
    let len = bytes.len() as u64;
    let binary_count =
        (bytes.len() >= BINARY_HEADER_BYTES).then(|| LittleEndian::read_u32(&bytes[80..84]));
    if let Some(count) = binary_count
        && expected_len(count) == len
    {
        return parse_binary(bytes, count);
    }
    if looks_ascii(bytes) {
        return parse_ascii(bytes);
    }
    match binary_count {
        None => Err(StlError::TooShort { len }),
        Some(count) => {
            let expected_len = expected_len(count);
            if len < expected_len {
                Err(StlError::Truncated {
                    count,
                    expected_len,
                    actual_len: len,
                    first_missing: (len - BINARY_HEADER_BYTES as u64)
                        / BINARY_TRIANGLE_BYTES as u64,
                })
            } else {
                Err(StlError::CountMismatch {
                    count,
                    expected_len,
                    actual_len: len,
                })
            }
        }
    }
}

fn expected_len(count: u32) -> u64 {
    BINARY_HEADER_BYTES as u64 + BINARY_TRIANGLE_BYTES as u64 * u64::from(count)
}

/// `solid` (after optional whitespace) and the first kilobyte is printable text.
fn looks_ascii(bytes: &[u8]) -> bool {
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let rest = &bytes[start..];
    rest.starts_with(b"solid")
        && rest
            .iter()
            .take(1024)
            .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace())
}

fn parse_binary(bytes: &[u8], count: u32) -> Result<Vec<Triangle>, StlError> {
    let mut out = Vec::with_capacity(count as usize);
    let mut f = [0f32; 9];
    for (i, rec) in bytes[BINARY_HEADER_BYTES..]
        .chunks_exact(BINARY_TRIANGLE_BYTES)
        .enumerate()
    {
        LittleEndian::read_f32_into(&rec[12..48], &mut f);
        if !f.iter().all(|x| x.is_finite()) {
            return Err(StlError::NonFinite {
                triangle: i as u64,
                offset: (BINARY_HEADER_BYTES + i * BINARY_TRIANGLE_BYTES) as u64,
            });
        }
        out.push(Triangle::new(
            Vec3::new(f[0], f[1], f[2]),
            Vec3::new(f[3], f[4], f[5]),
            Vec3::new(f[6], f[7], f[8]),
        ));
    }
    Ok(out)
}

/// Whitespace-separated tokens with their 1-based line numbers.
struct Tokens<'a> {
    text: &'a str,
    pos: usize,
    line: usize,
}

impl<'a> Tokens<'a> {
    fn next(&mut self) -> Option<(&'a str, usize)> {
        let bytes = self.text.as_bytes();
        while self.pos < bytes.len() && bytes[self.pos].is_ascii_whitespace() {
            if bytes[self.pos] == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        if self.pos >= bytes.len() {
            return None;
        }
        let start = self.pos;
        while self.pos < bytes.len() && !bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        Some((&self.text[start..self.pos], self.line))
    }

    /// Skips to the end of the current line.
    fn skip_line(&mut self) {
        let bytes = self.text.as_bytes();
        while self.pos < bytes.len() && bytes[self.pos] != b'\n' {
            self.pos += 1;
        }
    }

    fn expect(&mut self, word: &'static str) -> Result<usize, StlError> {
        match self.next() {
            Some((t, line)) if t.eq_ignore_ascii_case(word) => Ok(line),
            Some((t, line)) => Err(StlError::Syntax {
                line,
                expected: word,
                found: t.to_owned(),
            }),
            None => Err(StlError::Syntax {
                line: self.line,
                expected: word,
                found: String::new(),
            }),
        }
    }

    fn number(&mut self) -> Result<(f32, usize), StlError> {
        match self.next() {
            Some((t, line)) => t
                .parse::<f32>()
                .map(|x| (x, line))
                .map_err(|_| StlError::Syntax {
                    line,
                    expected: "a number",
                    found: t.to_owned(),
                }),
            None => Err(StlError::Syntax {
                line: self.line,
                expected: "a number",
                found: String::new(),
            }),
        }
    }
}

fn parse_ascii(bytes: &[u8]) -> Result<Vec<Triangle>, StlError> {
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let line = 1 + bytes[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            return Err(StlError::Syntax {
                line,
                expected: "UTF-8 text",
                found: "invalid UTF-8".to_owned(),
            });
        }
    };
    let mut tok = Tokens {
        text,
        pos: 0,
        line: 1,
    };
    tok.expect("solid")?;
    tok.skip_line();
    let mut out = Vec::new();
    loop {
        match tok.next() {
            Some((t, _)) if t.eq_ignore_ascii_case("endsolid") => break,
            Some((t, _)) if t.eq_ignore_ascii_case("facet") => {}
            Some((t, line)) => {
                return Err(StlError::Syntax {
                    line,
                    expected: "facet or endsolid",
                    found: t.to_owned(),
                });
            }
            None => {
                return Err(StlError::Syntax {
                    line: tok.line,
                    expected: "facet or endsolid",
                    found: String::new(),
                });
            }
        }
        tok.expect("normal")?;
        for _ in 0..3 {
            tok.number()?;
        }
        tok.expect("outer")?;
        tok.expect("loop")?;
        let mut v = [Vec3::ZERO; 3];
        for p in &mut v {
            tok.expect("vertex")?;
            let (x, line) = tok.number()?;
            let (y, _) = tok.number()?;
            let (z, _) = tok.number()?;
            *p = Vec3::new(x, y, z);
            if !p.is_finite() {
                return Err(StlError::NonFiniteAscii {
                    line,
                    triangle: out.len() as u64,
                });
            }
        }
        tok.expect("endloop")?;
        tok.expect("endfacet")?;
        out.push(Triangle::new(v[0], v[1], v[2]));
    }
    Ok(out)
}

/// Bits of a coordinate with `-0.0` folded onto `0.0` (they are the same point).
#[inline]
fn key(p: Vec3) -> [u32; 3] {
    let b = |x: f32| if x == 0.0 { 0 } else { x.to_bits() };
    [b(p.x), b(p.y), b(p.z)]
}

/// Welds a triangle soup into an indexed mesh: corners with identical `f32` bits (with `-0.0`
/// equal to `0.0`) become one vertex, numbered in order of first appearance.
#[must_use]
pub fn weld(triangles: &[Triangle]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut map: HashMap<[u32; 3], u32> = HashMap::with_capacity(triangles.len() / 2 + 1);
    let mut vertices = Vec::with_capacity(triangles.len() / 2 + 1);
    let mut indexed = Vec::with_capacity(triangles.len());
    for t in triangles {
        let mut tri = [0u32; 3];
        for (slot, &p) in tri.iter_mut().zip(&t.v) {
            *slot = *map.entry(key(p)).or_insert_with(|| {
                vertices.push(p);
                (vertices.len() - 1) as u32
            });
        }
        indexed.push(tri);
    }
    (vertices, indexed)
}

/// Multiplies every coordinate by `scale` (e.g. 0.001 to bring a millimetre file to metres).
pub fn scale_triangles(triangles: &mut [Triangle], scale: f32) {
    for t in triangles {
        for p in &mut t.v {
            *p *= scale;
        }
    }
}
