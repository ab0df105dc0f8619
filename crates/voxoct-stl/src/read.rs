//! STL reader with robust binary/ASCII detection, and vertex welding.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian};
use voxoct_core::Triangle;
use voxoct_core::glam::Vec3;

use crate::StlError;
use crate::write::{BINARY_HEADER_BYTES, BINARY_TRIANGLE_BYTES};

/// The largest STL input read: 1 GiB (a binary STL of 21 million triangles).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Reads an STL (binary or ASCII, detected from the content) into triangles, in file units.
///
/// Detection is by structure, never by the header's bytes: a file whose length is exactly
/// `84 + 50 * count` (count at byte offset 80) is binary even when its header begins with
/// `solid` or holds `COLOR=` (many exporters do that); otherwise a file that begins with
/// `solid`, whose first line may hold any name (UTF-8 or not), and whose next word is
/// `facet` or `endsolid` is ASCII; anything else is binary and its length is checked
/// against the count. At most [`MAX_FILE_BYTES`] are read.
///
/// Facet normals in the file are ignored: the winding defines the orientation.
///
/// # Errors
/// [`StlError::TooShort`], [`StlError::Truncated`], [`StlError::CountMismatch`],
/// [`StlError::NonFinite`], [`StlError::NonFiniteAscii`], [`StlError::Syntax`], or
/// [`StlError::Io`].
pub fn read<R: Read>(r: R) -> Result<Vec<Triangle>, StlError> {
    let mut bytes = Vec::new();
    r.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(StlError::FileTooLarge {
            len: bytes.len() as u64,
            max: MAX_FILE_BYTES,
        });
    }
    parse(&bytes)
}

/// Reads the STL file at `path` (see [`read`]); every error names the file. Only a regular
/// file (symlinks followed) of at most [`MAX_FILE_BYTES`] is read.
///
/// # Errors
/// As [`read`], and [`StlError::NotAFile`] or [`StlError::FileTooLarge`], wrapped in
/// [`StlError::File`].
pub fn read_file(path: impl AsRef<Path>) -> Result<Vec<Triangle>, StlError> {
    let path = path.as_ref();
    (|| {
        // Within MAX_FILE_BYTES once checked: read whole, sized by the file's length.
        check_mesh_file(path)?;
        parse(&std::fs::read(path)?)
    })()
    .map_err(|e| e.in_file(path))
}

/// Refuses what a mesh file cannot be: anything but a regular file (symlinks followed) —
/// a directory, a device such as `/dev/zero`, a FIFO that would block — or a file larger
/// than [`MAX_FILE_BYTES`]. Every mesh reader of the workspace checks this first.
///
/// # Errors
/// [`StlError::Io`] (the path cannot be examined), [`StlError::NotAFile`],
/// [`StlError::FileTooLarge`]; not wrapped in [`StlError::File`].
pub fn check_mesh_file(path: &Path) -> Result<(), StlError> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a directory"
        } else {
            "a device, FIFO or socket"
        };
        return Err(StlError::NotAFile { kind });
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(StlError::FileTooLarge {
            len: meta.len(),
            max: MAX_FILE_BYTES,
        });
    }
    Ok(())
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

/// The structure of an ASCII STL: `solid` (after optional whitespace), a first line with
/// any name, then `facet` or `endsolid` as the next word.
fn looks_ascii(bytes: &[u8]) -> bool {
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let rest = &bytes[start..];
    if !(rest.len() >= 5 && rest[..5].eq_ignore_ascii_case(b"solid")) {
        return false;
    }
    // "solid" must be a whole word ("solidworks…" is a binary header).
    if rest.get(5).is_some_and(|b| !b.is_ascii_whitespace()) {
        return false;
    }
    let Some(eol) = rest.iter().position(|&b| b == b'\n') else {
        return false;
    };
    let after = &rest[eol + 1..];
    let word_start = after
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(after.len());
    let word: Vec<u8> = after[word_start..]
        .iter()
        .take_while(|b| !b.is_ascii_whitespace())
        .take(16)
        .map(u8::to_ascii_lowercase)
        .collect();
    word == b"facet" || word == b"endsolid"
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
    // Names (after `solid` and `endsolid`) may be in any encoding; the grammar is ASCII,
    // so a lossy decoding keeps every number and keyword.
    let text = String::from_utf8_lossy(bytes);
    let mut tok = Tokens {
        text: &text,
        pos: 0,
        line: 1,
    };
    tok.expect("solid")?;
    tok.skip_line();
    let mut out = Vec::new();
    loop {
        match tok.next() {
            Some((t, _)) if t.eq_ignore_ascii_case("endsolid") => {
                // Some exporters write one `solid … endsolid` block per part.
                tok.skip_line();
                match tok.next() {
                    None => break,
                    Some((t, _)) if t.eq_ignore_ascii_case("solid") => {
                        tok.skip_line();
                        continue;
                    }
                    Some((t, line)) => {
                        return Err(StlError::Syntax {
                            line,
                            expected: "solid or the end of the file",
                            found: t.to_owned(),
                        });
                    }
                }
            }
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
