//! Wavefront OBJ: writer (`v` / `vn` / `f`, 1-based) and reader (`v` and `f`).

use std::io::{BufWriter, Write};

use voxoct_core::glam::Vec3;

use crate::StlError;
use crate::format::push_u64;
use voxoct_core::vertex_normals;

/// Writes an indexed mesh as OBJ: one `v` and one `vn` (area-weighted vertex normal) per
/// vertex, one `f a//a b//b c//c` per triangle (1-based, counter-clockwise seen from
/// outside). Coordinates are multiplied by `scale` and written in Rust's shortest
/// round-trip notation, so reading them back gives the same `f32` bits.
///
/// Input is checked by [`crate::write_mesh`]; this writer assumes valid indices.
pub(crate) fn write_obj<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    let mut w = BufWriter::with_capacity(1 << 16, w);
    writeln!(
        w,
        "# voxoct mesh: {} vertices, {} triangles, {} file units per metre",
        vertices.len(),
        triangles.len(),
        scale
    )?;
    for v in vertices {
        let p = *v * scale;
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for n in vertex_normals(vertices, triangles) {
        writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    let mut line = Vec::with_capacity(1 << 16);
    for chunk in triangles.chunks(1024) {
        line.clear();
        for t in chunk {
            line.push(b'f');
            for i in t.map(|i| u64::from(i) + 1) {
                line.push(b' ');
                push_u64(&mut line, i);
                line.extend_from_slice(b"//");
                push_u64(&mut line, i);
            }
            line.push(b'\n');
        }
        w.write_all(&line)?;
    }
    w.flush()?;
    Ok(())
}

/// Parses Wavefront OBJ text: `v x y z [w]` and `f` statements (polygons are
/// fan-triangulated; `a`, `a/b`, `a//c`, `a/b/c` forms; negative indices count back from the
/// last vertex read); every other statement is ignored.
///
/// # Errors
/// [`StlError::Obj`] naming the line: a bad or non-finite number, a face with fewer than
/// three vertices, an index of 0 or out of range.
pub fn parse_obj(text: &str) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), StlError> {
    let err = |line: usize, message: String| StlError::Obj { line, message };
    let mut vertices: Vec<Vec3> = Vec::new();
    // Faces keep their line so that a forward reference can be checked at the end.
    let mut faces: Vec<(usize, Vec<i64>)> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut words = content.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut c = [0.0f32; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let w = words.next().ok_or_else(|| {
                        err(line, format!("vertex has {k} coordinates, 3 expected"))
                    })?;
                    *slot = w
                        .parse::<f32>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| err(line, format!("bad vertex coordinate {w:?}")))?;
                }
                vertices.push(Vec3::from_array(c));
            }
            Some("f") => {
                let mut idx = Vec::new();
                for w in words {
                    let first = w.split('/').next().unwrap_or("");
                    let k: i64 = first
                        .parse()
                        .map_err(|_| err(line, format!("bad face index {w:?}")))?;
                    let k = match k {
                        0 => return Err(err(line, "face index 0 (OBJ counts from 1)".into())),
                        k if k < 0 => {
                            let r = vertices.len() as i64 + k;
                            if r < 0 {
                                return Err(err(
                                    line,
                                    format!(
                                        "relative face index {k} points before the first vertex \
                                         ({} read so far)",
                                        vertices.len()
                                    ),
                                ));
                            }
                            r
                        }
                        k => k - 1,
                    };
                    idx.push(k);
                }
                if idx.len() < 3 {
                    return Err(err(
                        line,
                        format!("face has {} vertices, at least 3 expected", idx.len()),
                    ));
                }
                faces.push((line, idx));
            }
            _ => {}
        }
    }
    let n = vertices.len() as i64;
    let mut indices = Vec::new();
    for (line, f) in faces {
        if let Some(&bad) = f.iter().find(|&&k| k >= n || k > i64::from(u32::MAX)) {
            return Err(err(
                line,
                format!("face index {} but the file has {n} vertices", bad + 1),
            ));
        }
        for k in 1..f.len() - 1 {
            indices.push([f[0] as u32, f[k] as u32, f[k + 1] as u32]);
        }
    }
    Ok((vertices, indices))
}
