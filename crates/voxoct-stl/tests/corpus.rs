//! STL files as other tools write them (issue 16, item 18): names in UTF-8 and Latin-1,
//! colour headers, `solid` at the start of binary headers, CRLF line ends, several solids,
//! upper-case keywords. Each is made here, byte for byte, and must read as its triangles.

use voxoct_stl::glam::Vec3;
use voxoct_stl::{StlError, parse, read_file, write_binary};

/// The closed tetrahedron every file of the corpus holds.
fn tet() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    (
        vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
}

/// ASCII facets of the tetrahedron with `eol` line ends and keywords in `case`.
fn facets(eol: &str, upper: bool) -> String {
    let (v, t) = tet();
    let k = |w: &str| {
        if upper {
            w.to_uppercase()
        } else {
            w.to_owned()
        }
    };
    let mut s = String::new();
    for tri in &t {
        s += &format!(
            "  {} {} 0 0 1{eol}    {} {}{eol}",
            k("facet"),
            k("normal"),
            k("outer"),
            k("loop")
        );
        for &i in tri {
            let p = v[i as usize];
            s += &format!("      {} {:e} {:e} {:e}{eol}", k("vertex"), p.x, p.y, p.z);
        }
        s += &format!("    {}{eol}  {}{eol}", k("endloop"), k("endfacet"));
    }
    s
}

fn binary_with_header(header: &[u8]) -> Vec<u8> {
    let (v, t) = tet();
    let mut b = Vec::new();
    write_binary(&mut b, &v, &t, 1.0).unwrap();
    let n = header.len().min(80);
    b[..80].fill(b' ');
    b[..n].copy_from_slice(&header[..n]);
    b
}

fn assert_tet(bytes: &[u8], what: &str) {
    match parse(bytes) {
        Ok(tris) => assert_eq!(tris.len(), 4, "{what}"),
        Err(e) => panic!("{what}: {e}"),
    }
}

#[test]
fn ascii_with_a_utf8_name_is_ascii() {
    // numpy-stl's tests/stl_ascii/Moon_Chinese.stl starts like this.
    let text = format!("solid 月球\n{}endsolid 月球\n", facets("\n", false));
    assert_tet(text.as_bytes(), "UTF-8 name");
}

#[test]
fn ascii_with_a_latin1_name_is_ascii() {
    let mut b = b"solid Pi\xe8ce d\xe9tach\xe9e\n".to_vec();
    b.extend_from_slice(facets("\n", false).as_bytes());
    b.extend_from_slice(b"endsolid Pi\xe8ce\n");
    assert_tet(&b, "Latin-1 name");
}

#[test]
fn ascii_variants_other_exporters_write() {
    let cases = [
        (
            "CRLF",
            format!("solid part\r\n{}endsolid part\r\n", facets("\r\n", false)),
        ),
        (
            "no name",
            format!("solid\n{}endsolid\n", facets("\n", false)),
        ),
        (
            "upper case",
            format!("SOLID PART\n{}ENDSOLID PART\n", facets("\n", true)),
        ),
        (
            "leading blank line",
            format!("\n  solid x\n{}endsolid x", facets("\n", false)),
        ),
        (
            "tabs",
            format!(
                "solid\tx\n{}endsolid\tx\n",
                facets("\n", false).replace("  ", "\t")
            ),
        ),
    ];
    for (what, text) in cases {
        assert_tet(text.as_bytes(), what);
    }
}

#[test]
fn ascii_with_two_solids_reads_both() {
    let text = format!(
        "solid a\n{}endsolid a\nsolid b\n{}endsolid b\n",
        facets("\n", false),
        facets("\n", false)
    );
    assert_eq!(parse(text.as_bytes()).unwrap().len(), 8);
}

#[test]
fn binary_headers_other_exporters_write() {
    let cases: [(&str, &[u8]); 5] = [
        ("SolidWorks", b"solid Part1 exported by SolidWorks"),
        ("solid then a facet-like word", b"solid x\nfacet normal"),
        (
            "Materialise colour",
            b"COLOR=\xff\x80\x40\xff MATERIAL=\x10\x20\x30\xff",
        ),
        ("zero header", &[0u8; 80]),
        ("UTF-8 header", "solid 月球 binary".as_bytes()),
    ];
    for (what, header) in cases {
        assert_tet(&binary_with_header(header), what);
    }
}

#[test]
fn a_binary_file_with_solid_header_and_wrong_length_is_reported_as_binary() {
    let mut b = binary_with_header(b"solid cut");
    b.truncate(200);
    assert!(
        matches!(parse(&b), Err(StlError::Truncated { .. })),
        "{:?}",
        parse(&b)
    );
}

#[test]
fn read_file_refuses_devices_and_directories() {
    let e = read_file("/dev/zero").unwrap_err();
    assert!(matches!(e.root(), StlError::NotAFile { .. }), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let e = read_file(dir.path()).unwrap_err();
    assert!(matches!(e.root(), StlError::NotAFile { .. }), "{e}");
    let link = dir.path().join("zero.stl");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let e = read_file(&link).unwrap_err();
    assert!(e.to_string().contains("zero.stl"), "{e}");
}
