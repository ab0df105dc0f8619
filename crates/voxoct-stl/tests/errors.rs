//! Every reader error is precise and tested.

use voxoct_stl::glam::Vec3;
use voxoct_stl::{StlError, StlFormat, parse, read_file, write_ascii, write_binary, write_file};

fn tet() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    (
        vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
}

fn binary() -> Vec<u8> {
    let (v, t) = tet();
    let mut b = Vec::new();
    write_binary(&mut b, &v, &t, 1.0).unwrap();
    b
}

#[test]
fn truncated_binary_names_counts_and_first_missing_triangle() {
    let mut b = binary();
    b.truncate(84 + 2 * 50 + 7);
    match parse(&b) {
        Err(StlError::Truncated {
            count: 4,
            expected_len: 284,
            actual_len: 191,
            first_missing: 2,
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn trailing_bytes_are_a_count_mismatch() {
    let mut b = binary();
    b.extend_from_slice(&[0; 10]);
    assert!(matches!(
        parse(&b),
        Err(StlError::CountMismatch {
            count: 4,
            expected_len: 284,
            actual_len: 294
        })
    ));
}

#[test]
fn short_input_is_too_short() {
    assert!(matches!(
        parse(&[1, 2, 3]),
        Err(StlError::TooShort { len: 3 })
    ));
    assert!(matches!(parse(&[]), Err(StlError::TooShort { len: 0 })));
}

#[test]
fn binary_nan_names_triangle_and_offset() {
    let mut b = binary();
    let off = 84 + 2 * 50 + 12 + 4; // triangle 2, first vertex, y
    b[off..off + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(matches!(
        parse(&b),
        Err(StlError::NonFinite {
            triangle: 2,
            offset: 184
        })
    ));
}

#[test]
fn binary_header_starting_with_solid_is_still_binary() {
    let mut b = binary();
    b[..5].copy_from_slice(b"solid");
    assert_eq!(parse(&b).unwrap().len(), 4);
}

fn ascii() -> String {
    let (v, t) = tet();
    let mut b = Vec::new();
    write_ascii(&mut b, &v, &t, 1.0).unwrap();
    String::from_utf8(b).unwrap()
}

#[test]
fn ascii_syntax_error_has_line_number() {
    let text = ascii();
    let mut lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[10], "      vertex 0e0 0e0 0e0");
    lines[10] = "      vertex 0 zero 0";
    let bad = lines.join("\n");
    match parse(bad.as_bytes()) {
        Err(StlError::Syntax {
            line: 11,
            expected: "a number",
            found,
        }) => assert_eq!(found, "zero"),
        other => panic!("{other:?}"),
    }
    let mut lines: Vec<&str> = text.lines().collect();
    lines[4] = "      vertx 1 2 3";
    let bad = lines.join("\n");
    let err = parse(bad.as_bytes()).unwrap_err();
    assert!(
        matches!(
            err,
            StlError::Syntax {
                line: 5,
                expected: "vertex",
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("line 5"));
}

#[test]
fn ascii_missing_endsolid_is_reported_at_the_end() {
    let text = ascii();
    let cut: String = text.lines().take(15).collect::<Vec<_>>().join("\n");
    assert!(matches!(
        parse(cut.as_bytes()),
        Err(StlError::Syntax {
            expected: "facet or endsolid",
            line: 15,
            ..
        })
    ));
}

#[test]
fn ascii_non_finite_names_the_line() {
    let text = ascii().replacen("vertex 1e0 0e0 0e0", "vertex inf 0 0", 1);
    match parse(text.as_bytes()) {
        Err(StlError::NonFiniteAscii { line, triangle: 0 }) => assert_eq!(line, 6),
        other => panic!("{other:?}"),
    }
}

#[test]
fn writer_rejects_bad_index_and_scale() {
    let (v, _) = tet();
    let mut b = Vec::new();
    assert!(matches!(
        write_binary(&mut b, &v, &[[0, 1, 9]], 1.0),
        Err(StlError::IndexOutOfRange {
            triangle: 0,
            index: 9,
            vertex_count: 4
        })
    ));
    for s in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(matches!(
            write_ascii(&mut b, &v, &[[0, 1, 2]], s),
            Err(StlError::InvalidArgument { name: "scale", .. })
        ));
    }
}

#[test]
fn file_errors_name_the_path_and_failed_writes_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.stl");
    let err = read_file(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.stl"), "{err}");
    assert!(matches!(err.root(), StlError::Io(_)));

    let (v, t) = tet();
    let out = dir.path().join("out.stl");
    assert!(write_file(&out, &v, &[[0, 1, 7]], StlFormat::Binary, 1.0).is_err());
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "temp file left"
    );

    write_file(&out, &v, &t, StlFormat::Ascii, 1000.0).unwrap();
    let back = read_file(&out).unwrap();
    assert_eq!(back.len(), 4);
    assert_eq!(back[1].v[1], Vec3::new(1000.0, 0.0, 0.0));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

    std::fs::write(&out, b"solid x\nfacet normal 0 0 1\n").unwrap();
    let err = read_file(&out).unwrap_err();
    assert!(
        err.to_string().contains("out.stl") && err.to_string().contains("line 3"),
        "{err}"
    );
}

#[test]
fn mesh_writers_refuse_what_is_not_a_regular_file_and_name_it() {
    use voxoct_stl::{MeshFormat, MeshRef, WriteOptions, write_mesh_file};
    let dir = tempfile::tempdir().unwrap();
    let (v, t) = tet();
    let sub = dir.path().join("sub.stl");
    std::fs::create_dir(&sub).unwrap();
    let err = write_file(&sub, &v, &t, StlFormat::Binary, 1.0).unwrap_err();
    assert!(err.to_string().contains("sub.stl"), "{err}");
    assert!(err.to_string().contains("a directory"), "{err}");
    assert!(matches!(err.root(), StlError::Io(e) if e.kind() == std::io::ErrorKind::InvalidInput));
    #[cfg(unix)]
    {
        let target = dir.path().join("target.ply");
        std::fs::write(&target, b"keep").unwrap();
        let link = dir.path().join("link.ply");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let opts = WriteOptions::default();
        let err = write_mesh_file(&link, MeshFormat::Ply, MeshRef::new(&v, &t), &opts).unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert_eq!(std::fs::read(&target).unwrap(), b"keep");
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
    }
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(
        names.iter().all(|n| !n.to_string_lossy().ends_with(".tmp")),
        "{names:?}"
    );
}
