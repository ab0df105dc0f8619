//! 3MF (3D Manufacturing Format, core specification 1.x): a ZIP package of
//! `[Content_Types].xml`, `_rels/.rels` and the model part `3D/3dmodel.model`, whose XML
//! holds the mesh and states its unit.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, BufWriter, Read, Seek, Write};

use quick_xml::events::{BytesStart, Event};
use voxoct_core::glam::Vec3;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipArchive, ZipWriter};

use crate::StlError;
use crate::format::{MAX_ELEMENTS, ReadMesh, push_u64};

/// The 3MF core namespace (the model part's default namespace).
pub const CORE_NAMESPACE: &str = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02";
/// The relationship type of the package's 3D model part.
pub const MODEL_RELATIONSHIP_TYPE: &str =
    "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel";
/// The content type of the model part (extension `.model`).
pub const MODEL_CONTENT_TYPE: &str = "application/vnd.ms-package.3dmanufacturing-3dmodel+xml";
/// The content type of relationship parts (extension `.rels`).
pub const RELS_CONTENT_TYPE: &str = "application/vnd.openxmlformats-package.relationships+xml";
/// Where the writer puts the model part.
pub const MODEL_PATH: &str = "3D/3dmodel.model";

/// Most bytes the reader inflates from one part (a ZIP bomb stops here): 16 GiB.
const MAX_PART_BYTES: u64 = 16 << 30;
/// Most bytes of the `_rels/.rels` part.
const MAX_RELS_BYTES: u64 = 1 << 20;
/// Deepest nesting of components.
const MAX_COMPONENT_DEPTH: usize = 32;

/// The 3MF units and their length in metres.
const UNITS: [(&str, f64); 6] = [
    ("micron", 1e-6),
    ("millimeter", 1e-3),
    ("centimeter", 1e-2),
    ("inch", 0.0254),
    ("foot", 0.3048),
    ("meter", 1.0),
];

/// The 3MF unit whose length is `1 / scale` metres (relative tolerance 1e-6).
fn unit_for_scale(scale: f32) -> Result<&'static str, StlError> {
    let per_unit = 1.0 / f64::from(scale);
    UNITS
        .iter()
        .find(|(_, m)| (per_unit / m - 1.0).abs() < 1e-6)
        .map(|(name, _)| *name)
        .ok_or(StlError::No3mfUnit { scale })
}

/// `s` with the five XML special characters replaced by entities (for attribute values and
/// text).
#[must_use]
pub fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

fn content_types() -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <Types xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\">\n \
         <Default Extension=\"rels\" ContentType=\"{RELS_CONTENT_TYPE}\"/>\n \
         <Default Extension=\"model\" ContentType=\"{MODEL_CONTENT_TYPE}\"/>\n\
         </Types>\n"
    )
}

fn relationships() -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\">\n \
         <Relationship Target=\"/{MODEL_PATH}\" Id=\"rel0\" Type=\"{MODEL_RELATIONSHIP_TYPE}\"/>\n\
         </Relationships>\n"
    )
}

/// Writes a 3MF package with one object of type `model` holding the mesh (coordinates
/// times `scale`, the unit that scale implies) and one build item placing it unchanged.
/// Streams: the model XML is deflated as it is produced (the ZIP uses data descriptors, so
/// `w` need not seek).
///
/// Input is checked by [`crate::write_mesh`]; this writer assumes valid indices.
pub(crate) fn write_3mf<W: Write>(
    w: W,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    scale: f32,
) -> Result<(), StlError> {
    let unit = unit_for_scale(scale)?;
    let mut zip = ZipWriter::new_stream(w);
    // Level 1: the XML of a scan compresses about 4:1 even so, at several times the speed.
    let opts = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .compression_level(Some(1));
    zip.start_file("[Content_Types].xml", opts)?;
    zip.write_all(content_types().as_bytes())?;
    zip.start_file("_rels/.rels", opts)?;
    zip.write_all(relationships().as_bytes())?;
    // A streamed entry must announce ZIP64 up front: do so when the XML may pass 4 GiB.
    let estimate = 100 * vertices.len() as u64 + 70 * triangles.len() as u64 + 4096;
    zip.start_file(MODEL_PATH, opts.large_file(estimate >= u64::from(u32::MAX)))?;
    {
        let mut x = BufWriter::with_capacity(1 << 16, &mut zip);
        write!(
            x,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
             <model unit=\"{unit}\" xml:lang=\"en-US\" xmlns=\"{CORE_NAMESPACE}\">\n \
             <metadata name=\"Application\">{}</metadata>\n \
             <resources>\n  \
             <object id=\"1\" type=\"model\" name=\"{}\">\n   \
             <mesh>\n    \
             <vertices>\n",
            xml_escape(concat!("voxoct ", env!("CARGO_PKG_VERSION"))),
            xml_escape("scan"),
        )?;
        for v in vertices {
            let p = *v * scale;
            // `{}` is the shortest decimal that reads back to the same f32, never exponent
            // notation: valid ST_Number.
            writeln!(
                x,
                "     <vertex x=\"{}\" y=\"{}\" z=\"{}\"/>",
                p.x, p.y, p.z
            )?;
        }
        x.write_all(b"    </vertices>\n    <triangles>\n")?;
        let mut line = Vec::with_capacity(1 << 16);
        for chunk in triangles.chunks(1024) {
            line.clear();
            for &[a, b, c] in chunk {
                line.extend_from_slice(b"     <triangle v1=\"");
                push_u64(&mut line, a.into());
                line.extend_from_slice(b"\" v2=\"");
                push_u64(&mut line, b.into());
                line.extend_from_slice(b"\" v3=\"");
                push_u64(&mut line, c.into());
                line.extend_from_slice(b"\"/>\n");
            }
            x.write_all(&line)?;
        }
        x.write_all(
            b"    </triangles>\n   </mesh>\n  </object>\n </resources>\n \
              <build>\n  <item objectid=\"1\"/>\n </build>\n</model>\n",
        )?;
        x.flush()?;
    }
    let mut inner = zip.finish()?.into_inner();
    inner.flush()?;
    Ok(())
}

/// A 3MF affine transform, row-vector convention: `p' = (x, y, z, 1) · M` with `M` 4 × 3,
/// stored as the specification writes it (`m00 m01 m02 m10 … m32`).
type Transform = [f64; 12];
const IDENTITY: Transform = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];

fn apply(m: &Transform, p: Vec3) -> Vec3 {
    let (x, y, z) = (f64::from(p.x), f64::from(p.y), f64::from(p.z));
    Vec3::new(
        (x * m[0] + y * m[3] + z * m[6] + m[9]) as f32,
        (x * m[1] + y * m[4] + z * m[7] + m[10]) as f32,
        (x * m[2] + y * m[5] + z * m[8] + m[11]) as f32,
    )
}

fn determinant(m: &Transform) -> f64 {
    m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
        + m[2] * (m[3] * m[7] - m[4] * m[6])
}

/// One `<object>`: a mesh or components (or both, tolerated).
#[derive(Default)]
struct Object {
    kind: String,
    vertices: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    components: Vec<(u64, Transform)>,
}

fn model_err(part: &str, message: impl Into<String>) -> StlError {
    StlError::ThreeMf {
        part: part.to_owned(),
        message: message.into(),
    }
}

/// The attributes of an element, by local name, values unescaped.
fn attributes(e: &BytesStart<'_>, part: &str) -> Result<HashMap<String, String>, StlError> {
    let mut out = HashMap::new();
    for a in e.attributes() {
        let a = a.map_err(|err| model_err(part, format!("bad attribute: {err}")))?;
        let key = String::from_utf8_lossy(a.key.local_name().as_ref()).into_owned();
        let value = a
            .unescape_value()
            .map_err(|err| model_err(part, format!("bad attribute {key}: {err}")))?;
        out.insert(key, value.into_owned());
    }
    Ok(out)
}

fn number<T: std::str::FromStr>(
    attrs: &HashMap<String, String>,
    key: &str,
    element: &str,
    part: &str,
) -> Result<T, StlError> {
    let v = attrs
        .get(key)
        .ok_or_else(|| model_err(part, format!("<{element}> without the {key} attribute")))?;
    v.trim().parse().map_err(|_| {
        model_err(
            part,
            format!("<{element}> {key}={v:?} is not a valid number"),
        )
    })
}

fn transform(
    attrs: &HashMap<String, String>,
    element: &str,
    part: &str,
) -> Result<Transform, StlError> {
    let Some(t) = attrs.get("transform") else {
        return Ok(IDENTITY);
    };
    let values: Vec<f64> = t
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|_| model_err(part, format!("<{element}> transform {t:?} is not numbers")))?;
    let m: Transform = values.try_into().map_err(|_| {
        model_err(
            part,
            format!("<{element}> transform {t:?} has not 12 numbers"),
        )
    })?;
    if m.iter().any(|x| !x.is_finite()) {
        return Err(model_err(
            part,
            format!("<{element}> transform is not finite"),
        ));
    }
    Ok(m)
}

/// Reads a part of at most `limit` bytes into a string.
fn read_part<R: Read + Seek>(
    zip: &mut ZipArchive<R>,
    name: &str,
    limit: u64,
) -> Result<Option<String>, StlError> {
    let file = match zip.by_name(name) {
        Ok(f) => f,
        Err(zip::result::ZipError::FileNotFound) => return Ok(None),
        Err(e) => return Err(e.into()),
    };
    let mut s = String::new();
    file.take(limit + 1)
        .read_to_string(&mut s)
        .map_err(|e| model_err(name, format!("cannot read: {e}")))?;
    if s.len() as u64 > limit {
        return Err(StlError::TooLarge {
            what: "3MF relationships bytes",
            count: s.len() as u64,
            limit,
        });
    }
    Ok(Some(s))
}

/// The model part named by the package's 3D-model relationship (`3D/3dmodel.model` when
/// the package has no `_rels/.rels`).
fn model_part<R: Read + Seek>(zip: &mut ZipArchive<R>) -> Result<String, StlError> {
    let Some(rels) = read_part(zip, "_rels/.rels", MAX_RELS_BYTES)? else {
        return Ok(MODEL_PATH.to_owned());
    };
    let mut reader = quick_xml::Reader::from_str(&rels);
    loop {
        match reader.read_event() {
            Ok(Event::Start(e) | Event::Empty(e)) if e.local_name().as_ref() == b"Relationship" => {
                let a = attributes(&e, "_rels/.rels")?;
                if a.get("Type").map(String::as_str) == Some(MODEL_RELATIONSHIP_TYPE)
                    && let Some(target) = a.get("Target")
                {
                    return Ok(target.trim_start_matches('/').to_owned());
                }
            }
            Ok(Event::Eof) => {
                return Err(model_err(
                    "_rels/.rels",
                    "no relationship of the 3D model type",
                ));
            }
            Ok(_) => {}
            Err(e) => return Err(model_err("_rels/.rels", format!("bad XML: {e}"))),
        }
    }
}

/// Reads a 3MF package: the meshes of every build item (components resolved, item and
/// component transforms applied, a mirroring transform's triangles re-wound so they stay
/// outward), objects of type `model` or `solidsupport`, in the model's unit
/// ([`ReadMesh::metres_per_unit`] is always set).
///
/// Hostile sizes: the model part is parsed as it inflates, stops at 16 GiB, and the total of
/// vertices and triangles (after components are expanded) is limited to [`MAX_ELEMENTS`].
///
/// # Errors
/// [`StlError::Zip`] for a broken container, [`StlError::ThreeMf`] for a missing part,
/// malformed XML, a missing attribute, an index out of range or an unknown object id or
/// unit, [`StlError::TooLarge`].
pub fn read_3mf<R: Read + Seek>(r: R) -> Result<ReadMesh, StlError> {
    let mut zip = ZipArchive::new(r)?;
    let part = model_part(&mut zip)?;
    let file = match zip.by_name(&part) {
        Ok(f) => f,
        Err(zip::result::ZipError::FileNotFound) => {
            return Err(model_err(&part, "the package has no such part"));
        }
        Err(e) => return Err(e.into()),
    };
    let mut limited = BufReader::with_capacity(1 << 16, file.take(MAX_PART_BYTES + 1));
    let mesh = parse_model(&mut limited, &part);
    if limited.get_ref().limit() == 0 {
        // Inflated past the limit: whatever was parsed is a cut-off model.
        return Err(StlError::TooLarge {
            what: "3MF model part bytes (inflated)",
            count: MAX_PART_BYTES + 1,
            limit: MAX_PART_BYTES,
        });
    }
    mesh
}

fn parse_model<B: BufRead>(input: B, part: &str) -> Result<ReadMesh, StlError> {
    let mut reader = quick_xml::Reader::from_reader(input);
    let mut buf = Vec::new();
    let mut metres_per_unit = None;
    let mut objects: HashMap<u64, Object> = HashMap::new();
    let mut current: Option<(u64, Object)> = None;
    let mut items: Vec<(u64, Transform)> = Vec::new();
    let mut in_build = false;
    let mut elements: u64 = 0;
    let count = |elements: &mut u64| -> Result<(), StlError> {
        *elements += 1;
        if *elements > MAX_ELEMENTS {
            return Err(StlError::TooLarge {
                what: "3MF vertices and triangles",
                count: *elements,
                limit: MAX_ELEMENTS,
            });
        }
        Ok(())
    };
    loop {
        let event = reader.read_event_into(&mut buf).map_err(|e| {
            model_err(
                part,
                format!("bad XML near byte {}: {e}", reader.buffer_position()),
            )
        })?;
        let (e, is_start) = match &event {
            Event::Start(e) => (e, true),
            Event::Empty(e) => (e, false),
            Event::End(e) => {
                match e.local_name().as_ref() {
                    b"object" => {
                        if let Some((id, o)) = current.take() {
                            let n = o.vertices.len();
                            if let Some((t, &i)) =
                                o.triangles.iter().enumerate().find_map(|(t, tri)| {
                                    tri.iter().find(|&&i| i as usize >= n).map(|i| (t, i))
                                })
                            {
                                return Err(model_err(
                                    part,
                                    format!(
                                        "object {id}: triangle {t} refers to vertex {i}, but the \
                                         object has {n} vertices"
                                    ),
                                ));
                            }
                            objects.insert(id, o);
                        }
                    }
                    b"build" => in_build = false,
                    _ => {}
                }
                buf.clear();
                continue;
            }
            Event::Eof => break,
            _ => {
                buf.clear();
                continue;
            }
        };
        match e.local_name().as_ref() {
            b"model" => {
                let a = attributes(e, part)?;
                let unit = a.get("unit").map_or("millimeter", String::as_str);
                let m = UNITS
                    .iter()
                    .find(|(n, _)| *n == unit)
                    .ok_or_else(|| model_err(part, format!("unknown unit {unit:?}")))?;
                metres_per_unit = Some(m.1);
            }
            b"object" => {
                let a = attributes(e, part)?;
                let id: u64 = number(&a, "id", "object", part)?;
                if objects.contains_key(&id) || current.as_ref().is_some_and(|c| c.0 == id) {
                    return Err(model_err(part, format!("object id {id} is used twice")));
                }
                let o = Object {
                    kind: a.get("type").cloned().unwrap_or_else(|| "model".into()),
                    ..Object::default()
                };
                if is_start {
                    current = Some((id, o));
                } else {
                    objects.insert(id, o);
                }
            }
            b"vertex" => {
                let o = current
                    .as_mut()
                    .ok_or_else(|| model_err(part, "<vertex> outside an <object>"))?;
                let a = attributes(e, part)?;
                let p = Vec3::new(
                    number(&a, "x", "vertex", part)?,
                    number(&a, "y", "vertex", part)?,
                    number(&a, "z", "vertex", part)?,
                );
                if !p.is_finite() {
                    return Err(model_err(
                        part,
                        format!(
                            "object {}: vertex {} is not finite",
                            o.0,
                            o.1.vertices.len()
                        ),
                    ));
                }
                count(&mut elements)?;
                o.1.vertices.push(p);
            }
            b"triangle" => {
                let o = current
                    .as_mut()
                    .ok_or_else(|| model_err(part, "<triangle> outside an <object>"))?;
                let a = attributes(e, part)?;
                let t = [
                    number(&a, "v1", "triangle", part)?,
                    number(&a, "v2", "triangle", part)?,
                    number(&a, "v3", "triangle", part)?,
                ];
                count(&mut elements)?;
                o.1.triangles.push(t);
            }
            b"component" => {
                let o = current
                    .as_mut()
                    .ok_or_else(|| model_err(part, "<component> outside an <object>"))?;
                let a = attributes(e, part)?;
                o.1.components.push((
                    number(&a, "objectid", "component", part)?,
                    transform(&a, "component", part)?,
                ));
            }
            b"build" => in_build = is_start,
            b"item" if in_build => {
                let a = attributes(e, part)?;
                items.push((
                    number(&a, "objectid", "item", part)?,
                    transform(&a, "item", part)?,
                ));
            }
            _ => {}
        }
        buf.clear();
    }
    let metres_per_unit = metres_per_unit.ok_or_else(|| model_err(part, "no <model> element"))?;
    if items.is_empty() {
        return Err(model_err(part, "the build has no items"));
    }
    let mut out = ReadMesh {
        metres_per_unit: Some(metres_per_unit),
        ..ReadMesh::default()
    };
    for (id, m) in &items {
        append_object(&objects, *id, m, 0, &mut out, part)?;
    }
    Ok(out)
}

/// Appends object `id` transformed by `m` (its components recursively) to `out`.
fn append_object(
    objects: &HashMap<u64, Object>,
    id: u64,
    m: &Transform,
    depth: usize,
    out: &mut ReadMesh,
    part: &str,
) -> Result<(), StlError> {
    if depth > MAX_COMPONENT_DEPTH {
        return Err(model_err(
            part,
            format!("components nest deeper than {MAX_COMPONENT_DEPTH} (a cycle?) at object {id}"),
        ));
    }
    let o = objects.get(&id).ok_or_else(|| {
        model_err(
            part,
            format!("reference to object {id}, which does not exist"),
        )
    })?;
    if !matches!(o.kind.as_str(), "model" | "solidsupport") {
        return Ok(());
    }
    let total =
        (out.vertices.len() + out.triangles.len() + o.vertices.len() + o.triangles.len()) as u64;
    if total > MAX_ELEMENTS {
        return Err(StlError::TooLarge {
            what: "3MF vertices and triangles after expanding components",
            count: total,
            limit: MAX_ELEMENTS,
        });
    }
    let base = u32::try_from(out.vertices.len()).map_err(|_| StlError::TooLarge {
        what: "3MF vertices",
        count: out.vertices.len() as u64,
        limit: u64::from(u32::MAX),
    })?;
    out.vertices.extend(o.vertices.iter().map(|&p| apply(m, p)));
    let mirror = determinant(m) < 0.0;
    out.triangles.extend(o.triangles.iter().map(|&[a, b, c]| {
        if mirror {
            [a + base, c + base, b + base]
        } else {
            [a + base, b + base, c + base]
        }
    }));
    for (child, cm) in &o.components {
        // The child's points go through its component transform, then through `m`.
        let mut composed = [0.0; 12];
        for col in 0..3 {
            for row in 0..4 {
                // Row `row` of cm · m (row vectors), plus m's translation in the last row.
                let mut s = 0.0;
                for k in 0..3 {
                    s += cm[row * 3 + k] * m[k * 3 + col];
                }
                if row == 3 {
                    s += m[9 + col];
                }
                composed[row * 3 + col] = s;
            }
        }
        append_object(objects, *child, &composed, depth + 1, out, part)?;
    }
    Ok(())
}
