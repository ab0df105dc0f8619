//! Round trips of every mesh format, the 3MF package checked against the rules slicers rely
//! on, and readers against malformed and hostile input.

use std::collections::HashMap;
use std::io::{Cursor, Read, Write};

use proptest::prelude::*;
use quick_xml::events::Event;
use voxoct_stl::glam::Vec3;
use voxoct_stl::{
    MeshFormat, MeshRef, StlError, StlFormat, WriteOptions, read_mesh, read_mesh_file, write_mesh,
    write_mesh_file,
};

/// A closed, outward-wound octahedron, metres.
fn octahedron() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let v = vec![
        Vec3::new(0.01, 0.0, 0.0),
        Vec3::new(-0.01, 0.0, 0.0),
        Vec3::new(0.0, 0.01, 0.0),
        Vec3::new(0.0, -0.01, 0.0),
        Vec3::new(0.0, 0.0, 0.01),
        Vec3::new(0.0, 0.0, -0.01),
    ];
    let t = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    (v, t)
}

fn write(format: MeshFormat, mesh: MeshRef<'_>, scale: f32) -> Vec<u8> {
    let mut bytes = Vec::new();
    let opts = WriteOptions {
        scale,
        stl: StlFormat::Binary,
    };
    write_mesh(&mut bytes, format, mesh, &opts).unwrap();
    bytes
}

/// The triangles as corner positions (what survives any re-indexing).
fn soup(v: &[Vec3], t: &[[u32; 3]]) -> Vec<[[u32; 3]; 3]> {
    t.iter()
        .map(|tri| tri.map(|i| v[i as usize].to_array().map(f32::to_bits)))
        .collect()
}

#[test]
fn every_format_round_trips_the_octahedron() {
    let (v, t) = octahedron();
    for format in MeshFormat::ALL {
        let bytes = write(format, MeshRef::new(&v, &t), 1000.0);
        let back = read_mesh(&bytes, format).unwrap();
        let scaled: Vec<Vec3> = v.iter().map(|&p| p * 1000.0).collect();
        if format == MeshFormat::Stl {
            assert_eq!(soup(&back.vertices, &back.triangles), soup(&scaled, &t));
        } else {
            assert_eq!(back.vertices, scaled, "{format}");
            assert_eq!(back.triangles, t, "{format}");
        }
        let unit = (format == MeshFormat::ThreeMf).then_some(1e-3);
        assert_eq!(back.metres_per_unit, unit, "{format}");
    }
}

#[test]
fn formats_come_from_extensions_and_unknown_ones_are_errors() {
    use std::path::Path;
    let cases = [
        ("a.stl", MeshFormat::Stl),
        ("b.STL", MeshFormat::Stl),
        ("c.3mf", MeshFormat::ThreeMf),
        ("d.ply", MeshFormat::Ply),
        ("e.Obj", MeshFormat::Obj),
    ];
    for (p, f) in cases {
        assert_eq!(MeshFormat::from_path(Path::new(p)).unwrap(), f);
        assert_eq!(f.extension().parse::<MeshFormat>().unwrap(), f);
    }
    for p in ["x.jpg", "noext", "y.stl.gz"] {
        let e = MeshFormat::from_path(Path::new(p)).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, StlError::UnknownFormat { .. }), "{p}");
        for ext in [".stl", ".3mf", ".ply", ".obj"] {
            assert!(msg.contains(ext), "{msg}");
        }
    }
}

fn zip_part(bytes: &[u8], name: &str) -> String {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).unwrap();
    let mut s = String::new();
    zip.by_name(name)
        .unwrap_or_else(|e| panic!("part {name}: {e}"))
        .read_to_string(&mut s)
        .unwrap();
    s
}

/// Every element of an XML document: (local name, namespace declaration, attributes).
fn elements(xml: &str) -> Vec<(String, HashMap<String, String>)> {
    let mut r = quick_xml::Reader::from_str(xml);
    let mut out = Vec::new();
    loop {
        match r.read_event().unwrap() {
            Event::Start(e) | Event::Empty(e) => {
                let name = String::from_utf8(e.name().as_ref().to_vec()).unwrap();
                let attrs = e
                    .attributes()
                    .map(|a| {
                        let a = a.unwrap();
                        (
                            String::from_utf8(a.key.as_ref().to_vec()).unwrap(),
                            a.unescape_value().unwrap().into_owned(),
                        )
                    })
                    .collect();
                out.push((name, attrs));
            }
            Event::Eof => return out,
            _ => {}
        }
    }
}

/// The rules of the 3MF core specification and the OPC package that slicers rely on.
fn check_3mf_package(bytes: &[u8], vertex_count: usize, triangle_count: usize) {
    // The package is a ZIP whose parts include the three required ones.
    let zip = zip::ZipArchive::new(Cursor::new(bytes)).unwrap();
    let names: Vec<String> = zip.file_names().map(|n| n.unwrap().into_owned()).collect();
    for part in ["[Content_Types].xml", "_rels/.rels", "3D/3dmodel.model"] {
        assert!(names.iter().any(|n| n == part), "missing {part}: {names:?}");
    }

    // Content types: rels and model by Default extension.
    let ct = elements(&zip_part(bytes, "[Content_Types].xml"));
    assert_eq!(ct[0].0, "Types");
    assert_eq!(
        ct[0].1["xmlns"],
        "http://schemas.openxmlformats.org/package/2006/content-types"
    );
    let defaults: HashMap<&str, &str> = ct
        .iter()
        .filter(|(n, _)| n == "Default")
        .map(|(_, a)| (a["Extension"].as_str(), a["ContentType"].as_str()))
        .collect();
    assert_eq!(
        defaults["rels"],
        "application/vnd.openxmlformats-package.relationships+xml"
    );
    assert_eq!(
        defaults["model"],
        "application/vnd.ms-package.3dmanufacturing-3dmodel+xml"
    );

    // The root relationship: the 3D model type, targeting /3D/3dmodel.model.
    let rels = elements(&zip_part(bytes, "_rels/.rels"));
    assert_eq!(rels[0].0, "Relationships");
    assert_eq!(
        rels[0].1["xmlns"],
        "http://schemas.openxmlformats.org/package/2006/relationships"
    );
    let model_rels: Vec<_> = rels
        .iter()
        .filter(|(n, a)| {
            n == "Relationship"
                && a["Type"] == "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
        })
        .collect();
    assert_eq!(model_rels.len(), 1);
    assert_eq!(model_rels[0].1["Target"], "/3D/3dmodel.model");
    assert!(!model_rels[0].1["Id"].is_empty());

    // The model: core namespace, a unit, objects with id and type, a build whose items
    // reference existing objects, triangle indices in range.
    let model = elements(&zip_part(bytes, "3D/3dmodel.model"));
    assert_eq!(model[0].0, "model");
    assert_eq!(
        model[0].1["xmlns"],
        "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
    );
    assert_eq!(model[0].1["unit"], "millimeter");
    let mut objects = HashMap::new();
    let mut current = None;
    let (mut vertices, mut triangles) = (0usize, Vec::new());
    let mut items = Vec::new();
    let mut order = Vec::new();
    for (name, a) in &model {
        order.push(name.as_str());
        match name.as_str() {
            "object" => {
                let id: u32 = a["id"].parse().unwrap();
                assert!(id >= 1, "object ids are positive");
                assert_eq!(a["type"], "model");
                assert!(objects.insert(id, ()).is_none(), "object id {id} twice");
                current = Some(id);
            }
            "vertex" => {
                assert!(current.is_some());
                for k in ["x", "y", "z"] {
                    let x: f32 = a[k].parse().unwrap();
                    assert!(x.is_finite());
                    // ST_Number: no exponent-less oddities such as "inf" or "NaN".
                    assert!(
                        a[k].chars()
                            .all(|c| c.is_ascii_digit() || "-+.eE".contains(c))
                    );
                }
                vertices += 1;
            }
            "triangle" => {
                triangles.push(["v1", "v2", "v3"].map(|k| a[k].parse::<usize>().unwrap()));
            }
            "item" => items.push(a["objectid"].parse::<u32>().unwrap()),
            _ => {}
        }
    }
    let pos = |n: &str| order.iter().position(|&o| o == n).unwrap();
    assert!(pos("resources") < pos("object") && pos("object") < pos("build"));
    assert!(pos("mesh") < pos("vertices") && pos("vertices") < pos("triangles"));
    assert_eq!(vertices, vertex_count);
    assert_eq!(triangles.len(), triangle_count);
    for t in &triangles {
        assert!(t.iter().all(|&i| i < vertices), "{t:?}");
        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    }
    assert!(!items.is_empty());
    for id in items {
        assert!(
            objects.contains_key(&id),
            "build item references object {id}"
        );
    }
}

#[test]
fn a_3mf_package_follows_the_rules_slicers_rely_on() {
    let (v, t) = octahedron();
    let bytes = write(MeshFormat::ThreeMf, MeshRef::new(&v, &t), 1000.0);
    check_3mf_package(&bytes, v.len(), t.len());
}

#[test]
fn a_3mf_records_the_unit_its_scale_implies() {
    let (v, t) = octahedron();
    for (scale, unit, m) in [(1.0, "meter", 1.0), (100.0, "centimeter", 0.01)] {
        let bytes = write(MeshFormat::ThreeMf, MeshRef::new(&v, &t), scale);
        assert!(zip_part(&bytes, "3D/3dmodel.model").contains(&format!("unit=\"{unit}\"")));
        assert_eq!(
            read_mesh(&bytes, MeshFormat::ThreeMf)
                .unwrap()
                .metres_per_unit,
            Some(m)
        );
    }
    let mut sink = Vec::new();
    let opts = WriteOptions {
        scale: 7.0,
        ..WriteOptions::default()
    };
    let e = write_mesh(&mut sink, MeshFormat::ThreeMf, MeshRef::new(&v, &t), &opts);
    assert!(matches!(e, Err(StlError::No3mfUnit { .. })), "{e:?}");
}

#[test]
fn xml_escape_replaces_the_special_characters() {
    assert_eq!(
        voxoct_stl::threemf::xml_escape(r#"a<b>&"c'"#),
        "a&lt;b&gt;&amp;&quot;c&apos;"
    );
}

/// The PLY header and the per-vertex records parsed independently of the crate's reader.
fn ply_vertices(bytes: &[u8]) -> (String, Vec<[u8; 28]>) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8(bytes[..end].to_vec()).unwrap();
    let n: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .unwrap()
        .parse()
        .unwrap();
    let recs = bytes[end..end + 28 * n]
        .chunks_exact(28)
        .map(|c| c.try_into().unwrap())
        .collect();
    (header, recs)
}

#[test]
fn ply_carries_normals_and_hits() {
    let (v, t) = octahedron();
    let hits: Vec<u32> = (0..v.len() as u32).map(|i| 10 * i + 1).collect();
    let mesh = MeshRef {
        vertices: &v,
        triangles: &t,
        hits: Some(&hits),
    };
    let bytes = write(MeshFormat::Ply, mesh, 1000.0);
    let (header, recs) = ply_vertices(&bytes);
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    let props: Vec<&str> = header
        .lines()
        .filter_map(|l| l.strip_prefix("property "))
        .collect();
    assert_eq!(
        props,
        [
            "float x",
            "float y",
            "float z",
            "float nx",
            "float ny",
            "float nz",
            "uint hits",
            "list uchar uint vertex_indices"
        ]
    );
    for (i, r) in recs.iter().enumerate() {
        let f = |k: usize| f32::from_le_bytes(r[4 * k..4 * k + 4].try_into().unwrap());
        let p = Vec3::new(f(0), f(1), f(2));
        let n = Vec3::new(f(3), f(4), f(5));
        // The octahedron's vertex normals point straight out from the centre.
        assert!((n - p.normalize()).length() < 1e-5, "{i}: {p} {n}");
        assert_eq!(u32::from_le_bytes(r[24..28].try_into().unwrap()), hits[i]);
    }
    // Wrong number of hits: an error, not a corrupt file.
    let short = MeshRef {
        hits: Some(&hits[1..]),
        ..mesh
    };
    let mut sink = Vec::new();
    let e = write_mesh(&mut sink, MeshFormat::Ply, short, &WriteOptions::default());
    assert!(matches!(e, Err(StlError::VertexDataLength { .. })), "{e:?}");
}

#[test]
fn ply_reader_takes_ascii_big_endian_and_polygons() {
    let ascii = b"ply\nformat ascii 1.0\ncomment hi\nelement vertex 4\nproperty double x\n\
                  property double y\nproperty double z\nproperty uchar red\nelement face 1\n\
                  property list uchar int vertex_index\nend_header\n0 0 0 1\n1 0 0 2\n1 1 0 3\n\
                  0 1 0 4\n4 0 1 2 3\n";
    let m = read_mesh(ascii, MeshFormat::Ply).unwrap();
    assert_eq!(m.vertices[2], Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);

    let mut big =
        b"ply\r\nformat binary_big_endian 1.0\r\nelement vertex 3\r\nproperty float x\r\n\
                    property float y\r\nproperty float z\r\nelement face 1\r\n\
                    property list uchar ushort vertex_indices\r\nend_header\r\n"
            .to_vec();
    for x in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        big.extend_from_slice(&x.to_be_bytes());
    }
    big.push(3);
    for i in [0u16, 1, 2] {
        big.extend_from_slice(&i.to_be_bytes());
    }
    let m = read_mesh(&big, MeshFormat::Ply).unwrap();
    assert_eq!(m.vertices[1], Vec3::X);
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
}

#[test]
fn ply_reader_rejects_hostile_and_broken_files() {
    let head = |n: &str| {
        format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
             property float y\nproperty float z\nelement face 0\n\
             property list uchar uint vertex_indices\nend_header\n"
        )
        .into_bytes()
    };
    // A count far beyond the bytes that follow: refused before allocating.
    let e = read_mesh(&head("4000000000"), MeshFormat::Ply).unwrap_err();
    assert!(e.to_string().contains("more than the"), "{e}");
    let e = read_mesh(&head("18446744073709551615"), MeshFormat::Ply).unwrap_err();
    assert!(matches!(e, StlError::TooLarge { .. }), "{e}");
    // Cut off inside a vertex.
    let mut cut = head("1");
    cut.extend_from_slice(&[0; 12]);
    cut.truncate(cut.len() - 1);
    assert!(read_mesh(&cut, MeshFormat::Ply).is_err());
    // An index past the vertices.
    let (v, t) = octahedron();
    let mut bytes = write(MeshFormat::Ply, MeshRef::new(&v, &t), 1.0);
    let n = bytes.len();
    bytes[n - 4..].copy_from_slice(&99u32.to_le_bytes());
    let e = read_mesh(&bytes, MeshFormat::Ply).unwrap_err();
    assert!(
        matches!(e, StlError::IndexOutOfRange { index: 99, .. }),
        "{e}"
    );
    for bad in [&b"plx\n"[..], b"ply\nformat ascii 1.0\n", b""] {
        assert!(read_mesh(bad, MeshFormat::Ply).is_err());
    }
}

/// A 3MF package with the given model XML (and the usual content types and relationships).
fn package(model: &str) -> Vec<u8> {
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let o = zip::write::SimpleFileOptions::default();
    zip.start_file("_rels/.rels", o).unwrap();
    zip.write_all(
        br#"<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships"><Relationship Target="/3D/other.model" Id="r" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/></Relationships>"#,
    )
    .unwrap();
    zip.start_file("3D/other.model", o).unwrap();
    zip.write_all(model.as_bytes()).unwrap();
    zip.finish().unwrap().into_inner()
}

#[test]
fn threemf_reader_follows_relationships_components_and_transforms() {
    let model = r#"<?xml version="1.0"?>
<model unit="inch" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">
 <resources>
  <object id="3" type="model"><mesh><vertices>
   <vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"/><vertex x="0" y="1" z="0"/>
  </vertices><triangles><triangle v1="0" v2="1" v3="2"/></triangles></mesh></object>
  <object id="4" type="model"><components>
   <component objectid="3" transform="1 0 0 0 1 0 0 0 1 10 0 0"/>
  </components></object>
  <object id="5" type="support"><mesh><vertices><vertex x="0" y="0" z="0"/></vertices>
  <triangles/></mesh></object>
 </resources>
 <build><item objectid="4" transform="-1 0 0 0 1 0 0 0 1 0 0 5"/><item objectid="5"/></build>
</model>"#;
    let m = read_mesh(&package(model), MeshFormat::ThreeMf).unwrap();
    assert_eq!(m.metres_per_unit, Some(0.0254));
    // Component moves x by +10, the item mirrors x and lifts z by 5.
    assert_eq!(
        m.vertices,
        vec![
            Vec3::new(-10.0, 0.0, 5.0),
            Vec3::new(-11.0, 0.0, 5.0),
            Vec3::new(-10.0, 1.0, 5.0)
        ]
    );
    // The mirror is re-wound so the normal still points the way it did (+z).
    let [a, b, c] = m.triangles[0].map(|i| m.vertices[i as usize]);
    assert!((b - a).cross(c - a).z > 0.0);
}

#[test]
fn threemf_reader_rejects_broken_models() {
    let wrap = |body: &str| {
        format!(
            r#"<model unit="millimeter" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02"><resources>{body}</resources><build><item objectid="1"/></build></model>"#
        )
    };
    let tri = |v3: &str| {
        wrap(&format!(
            r#"<object id="1"><mesh><vertices><vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"/><vertex x="0" y="1" z="0"/></vertices><triangles><triangle v1="0" v2="1" v3="{v3}"/></triangles></mesh></object>"#
        ))
    };
    let cases = [
        (tri("7"), "refers to vertex 7"),
        (tri("x"), "not a valid number"),
        (wrap(""), "does not exist"),
        (
            wrap(r#"<object id="1"><components><component objectid="1"/></components></object>"#),
            "nest deeper",
        ),
        (tri("2").replace("millimeter", "furlong"), "unknown unit"),
        (
            tri("2").replace("<triangles>", "<triangles><vertex x=\"1\" x=\"2\"/>"),
            "bad",
        ),
    ];
    for (model, needle) in cases {
        let e = read_mesh(&package(&model), MeshFormat::ThreeMf).unwrap_err();
        assert!(e.to_string().contains(needle), "{needle}: {e}");
    }
    assert!(matches!(
        read_mesh(b"PK not a zip", MeshFormat::ThreeMf),
        Err(StlError::Zip(_))
    ));
}

#[test]
fn obj_writes_normals_and_one_based_faces() {
    let (v, t) = octahedron();
    let text = String::from_utf8(write(MeshFormat::Obj, MeshRef::new(&v, &t), 1000.0)).unwrap();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 6);
    assert_eq!(text.lines().filter(|l| l.starts_with("vn ")).count(), 6);
    assert!(text.contains("\nf 1//1 3//3 5//5\n"), "{text}");
}

#[test]
fn files_are_written_atomically_and_read_back_by_extension() {
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = octahedron();
    for format in MeshFormat::ALL {
        let path = dir.path().join(format!("m.{}", format.extension()));
        write_mesh_file(
            &path,
            format,
            MeshRef::new(&v, &t),
            &WriteOptions::default(),
        )
        .unwrap();
        let back = read_mesh_file(&path).unwrap();
        assert_eq!(back.triangles.len(), t.len(), "{format}");
    }
    // Only the four files: no temporaries left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 4);
    let e = read_mesh_file(dir.path().join("m.xyz")).unwrap_err();
    assert!(e.to_string().contains("m.xyz"), "{e}");
}

fn arb_mesh() -> impl Strategy<Value = (Vec<Vec3>, Vec<[u32; 3]>)> {
    prop::collection::vec(prop::array::uniform3(-1.0e3f32..1.0e3), 3..40).prop_flat_map(|vs| {
        let n = vs.len() as u32;
        let verts: Vec<Vec3> = vs.into_iter().map(Vec3::from_array).collect();
        (
            Just(verts),
            prop::collection::vec(prop::array::uniform3(0..n), 0..60),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Whatever the mesh, every format gives back the same vertices and triangles
    /// (STL: the same corner positions, as it has no shared vertices).
    #[test]
    fn round_trips_keep_vertices_and_triangles((v, t) in arb_mesh(), scale_mm in any::<bool>()) {
        let scale = if scale_mm { 1000.0 } else { 1.0 };
        let expect: Vec<Vec3> = v.iter().map(|&p| p * scale).collect();
        for format in MeshFormat::ALL {
            let bytes = write(format, MeshRef::new(&v, &t), scale);
            let back = read_mesh(&bytes, format).unwrap();
            if format == MeshFormat::Stl {
                prop_assert_eq!(soup(&back.vertices, &back.triangles), soup(&expect, &t));
            } else {
                prop_assert_eq!(&back.vertices, &expect);
                prop_assert_eq!(&back.triangles, &t);
            }
        }
    }

    /// Arbitrary bytes never make a reader panic.
    #[test]
    fn readers_survive_garbage(bytes in prop::collection::vec(any::<u8>(), 0..300), k in 0usize..4) {
        let _ = read_mesh(&bytes, MeshFormat::ALL[k]);
        let mut with_head = b"ply\nformat binary_little_endian 1.0\n".to_vec();
        with_head.extend_from_slice(&bytes);
        let _ = read_mesh(&with_head, MeshFormat::Ply);
    }
}
