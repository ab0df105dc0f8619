//! Every source behind the one trait, and models loaded from files.

use std::path::Path;
use std::time::Duration;

use proptest::prelude::*;
use voxoct_kinect::glam::Vec3;
use voxoct_kinect::{
    DepthSource, FakenectSource, Model, SimConfig, SimulatedKinect, SourceError, load_model,
    parse_obj,
};

const T: Duration = Duration::from_secs(1);

/// A closed tetrahedron, outward-wound, as OBJ text.
const TETRA_OBJ: &str = "o tetra\nv 0 0 0\nv 2 0 0\nv 0 0 -2\nv 0 4 0\n\
                         f 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n";

fn tetra_triangles() -> Vec<[Vec3; 3]> {
    let m = parse_obj(TETRA_OBJ, Path::new("tetra.obj")).unwrap();
    m.triangles().iter().map(|t| t.v).collect()
}

fn binary_stl(tris: &[[Vec3; 3]]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
        for v in [n, t[0], t[1], t[2]] {
            for c in v.to_array() {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

fn ascii_stl(tris: &[[Vec3; 3]]) -> String {
    let mut s = String::from("solid tetra\n");
    for t in tris {
        s.push_str("  facet normal 0 0 0\n    outer loop\n");
        for v in t {
            s.push_str(&format!("      vertex {} {} {}\n", v.x, v.y, v.z));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str("endsolid tetra\n");
    s
}

#[test]
fn obj_and_stl_files_load_to_the_same_model() {
    let dir = tempfile::tempdir().unwrap();
    let tris = tetra_triangles();
    let files = [
        ("tetra.obj", TETRA_OBJ.as_bytes().to_vec()),
        ("tetra.stl", binary_stl(&tris)),
        ("tetra_ascii.STL", ascii_stl(&tris).into_bytes()),
    ];
    for (name, bytes) in files {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let mut m = load_model(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let got: Vec<[Vec3; 3]> = m.triangles().iter().map(|t| t.v).collect();
        assert_eq!(got, tris, "{name}");
        assert!((m.signed_volume() - 8.0 / 6.0 * 2.0).abs() < 1e-4, "{name}");
        m.place_on_platform(0.12).unwrap();
        let b = m.bounds().unwrap();
        assert!(
            (b.max.y - 0.12).abs() < 1e-6 && b.min.y == 0.0,
            "{name}: {b:?}"
        );
    }
}

#[test]
fn model_file_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("broken.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap();
    let e = load_model(&obj).unwrap_err();
    assert!(matches!(e, SourceError::Obj { line: 3, .. }), "{e:?}");
    assert!(e.to_string().contains("broken.obj:3"), "{e}");

    let stl = dir.path().join("short.stl");
    std::fs::write(&stl, &binary_stl(&tetra_triangles())[..120]).unwrap();
    let e = load_model(&stl).unwrap_err();
    assert!(matches!(e, SourceError::Stl { .. }), "{e:?}");
    assert!(e.to_string().contains("short.stl"), "{e}");

    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, "# nothing\n").unwrap();
    assert!(matches!(
        load_model(&empty),
        Err(SourceError::BadModel { .. })
    ));

    let ply = dir.path().join("model.ply");
    std::fs::write(&ply, "ply\n").unwrap();
    let e = load_model(&ply).unwrap_err();
    assert!(matches!(e, SourceError::Stl { .. }), "{e:?}");
    assert!(e.to_string().contains("model.ply"), "{e}");
    let xyz = dir.path().join("model.xyz");
    std::fs::write(&xyz, "0 0 0\n").unwrap();
    let e = load_model(&xyz).unwrap_err();
    assert!(matches!(e, SourceError::UnknownModelFormat { .. }), "{e:?}");
    assert!(e.to_string().contains(".3mf"), "{e}");
    assert!(matches!(
        load_model(&dir.path().join("missing.obj")),
        Err(SourceError::Io { .. })
    ));
}

#[test]
fn every_source_works_behind_the_trait() {
    let dir = tempfile::tempdir().unwrap();
    let mut raw = b"P5 640 480 65535\n".to_vec();
    raw.extend((0..640 * 480).flat_map(|_| 700u16.to_le_bytes()));
    std::fs::write(dir.path().join("INDEX.txt"), "d-0.0-0.pgm\n").unwrap();
    std::fs::write(dir.path().join("d-0.0-0.pgm"), raw).unwrap();

    // A loaded file on the simulated platform.
    let obj = dir.path().join("tetra.obj");
    std::fs::write(&obj, TETRA_OBJ).unwrap();
    let mut tetra = load_model(&obj).unwrap();
    tetra.place_on_platform(0.1).unwrap();

    let mut sources: Vec<Box<dyn DepthSource>> = vec![
        Box::new(SimulatedKinect::builtin("figurine", SimConfig::default()).unwrap()),
        Box::new(SimulatedKinect::new(&tetra, SimConfig::default()).unwrap()),
        Box::new(FakenectSource::open(dir.path()).unwrap()),
    ];
    for s in &mut sources {
        let k = s.intrinsics();
        let f = s.grab(T).unwrap();
        assert_eq!((f.width, f.height), (k.width, k.height));
        assert_eq!(f.len(), (k.width * k.height) as usize);
        assert!(f.data.iter().any(|&d| d != 0));
        s.shutdown().unwrap();
    }
    assert_eq!(sources[0].tilt_deg(), Some(17.82));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

    /// Fan triangulation: an n-gon gives n − 2 triangles, all sharing its first vertex and
    /// all indices in range, whatever mix of absolute and relative indices is used.
    #[test]
    fn obj_polygons_fan_into_triangles(sizes in prop::collection::vec(3usize..8, 1..6), relative in any::<bool>()) {
        let mut text = String::new();
        let mut expected = 0;
        let mut count = 0usize;
        for &n in &sizes {
            for k in 0..n {
                let a = k as f32 / n as f32 * std::f32::consts::TAU;
                text.push_str(&format!("v {} {} 0\n", a.cos(), a.sin()));
            }
            count += n;
            let idx: Vec<String> = (0..n)
                .map(|k| if relative { format!("-{}", n - k) } else { format!("{}/1/1", count - n + k + 1) })
                .collect();
            text.push_str(&format!("f {}\n", idx.join(" ")));
            expected += n - 2;
        }
        let m = parse_obj(&text, Path::new("p.obj")).unwrap();
        prop_assert_eq!(m.indices.len(), expected);
        prop_assert!(m.indices.iter().flatten().all(|&i| (i as usize) < count));
        m.validate("p.obj").unwrap();
    }
}

#[test]
fn builtin_names_all_resolve() {
    for name in Model::BUILTIN_NAMES {
        assert!(Model::builtin(name).is_some(), "{name}");
    }
}

/// A Z-up tower in millimetres (40 × 30 mm base, 70 mm tall), outward wound: a box.
fn tower_mm() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (w, d, h) = (40.0, 30.0, 70.0);
    let v: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { 0.0 } else { w },
                if i & 2 == 0 { 0.0 } else { d },
                if i & 4 == 0 { 0.0 } else { h },
            ) + Vec3::new(100.0, 100.0, 5.0)
        })
        .collect();
    let t = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (v, t)
}

#[test]
fn model_files_keep_their_size_and_orientation() {
    use voxoct_kinect::{ModelConvention, ModelUp, load_model_as};
    use voxoct_stl::{MeshFormat, MeshRef, WriteOptions, write_mesh_file};
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = tower_mm();
    for format in MeshFormat::ALL {
        let path = dir.path().join(format!("tower.{}", format.extension()));
        // Numbers as in the file: millimetres (scale 1; 3MF then says "millimeter" when
        // written with scale 1000 from metres, so write metres for it).
        let (verts, scale): (Vec<Vec3>, f32) = if format == MeshFormat::ThreeMf {
            (v.iter().map(|&p| p * 0.001).collect(), 1000.0)
        } else {
            (v.clone(), 1.0)
        };
        let opts = WriteOptions {
            scale,
            ..WriteOptions::default()
        };
        write_mesh_file(&path, format, MeshRef::new(&verts, &t), &opts).unwrap();
        let m = load_model_as(&path, &ModelConvention::default()).unwrap();
        let b = m.bounds().unwrap();
        let size = b.max - b.min;
        assert!(
            (size - Vec3::new(0.04, 0.07, 0.03)).abs().max_element() < 1e-6,
            "{format}: {size}"
        );
        assert_eq!(b.min.y, 0.0, "{format}");
        assert!((b.min.x + b.max.x).abs() < 1e-6 && (b.min.z + b.max.z).abs() < 1e-6);
        assert!(m.signed_volume() > 0.0, "{format}: still outward");

        // Y up and inches: the file's y becomes the height, each unit 25.4 mm.
        let conv = ModelConvention {
            metres_per_unit: Some(0.0254),
            up: ModelUp::Y,
        };
        let m = load_model_as(&path, &conv).unwrap();
        let size = {
            let b = m.bounds().unwrap();
            b.max - b.min
        };
        // (An explicit unit overrides the one a 3MF states; its numbers are millimetres.)
        let want = Vec3::new(40.0, 30.0, 70.0) * 0.0254;
        assert!((size - want).abs().max_element() < 1e-5, "{format}: {size}");
    }
    // A 3MF in metres keeps its size by its own unit.
    let path = dir.path().join("tower_m.3mf");
    let verts: Vec<Vec3> = v.iter().map(|&p| p * 0.001).collect();
    let opts = WriteOptions {
        scale: 1.0,
        ..WriteOptions::default()
    };
    write_mesh_file(&path, MeshFormat::ThreeMf, MeshRef::new(&verts, &t), &opts).unwrap();
    let m = load_model_as(&path, &ModelConvention::default()).unwrap();
    let b = m.bounds().unwrap();
    assert!(((b.max.y - b.min.y) - 0.07).abs() < 1e-6);
}
