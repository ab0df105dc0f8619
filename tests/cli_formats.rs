//! The `scan` example's output formats and frames, and `--model` files as slicers write
//! them: what a user gets from `--out x.3mf`, `--up`, `--format`, `--model-units`.

use std::path::Path;
use std::process::Output;

use voxoct::mesh::Mesh;
use voxoct::stl::glam::Vec3;

mod common;

fn scan(args: &[&str], cwd: &Path) -> Output {
    common::run_example("scan", args, cwd)
}

use common::SMALL_SCAN as SMALL;

fn read(path: &Path) -> Mesh {
    let m = voxoct::stl::read_mesh_file(path).unwrap();
    Mesh {
        vertices: m.vertices,
        triangles: m.triangles,
    }
}

#[test]
fn every_output_format_is_written_z_up_on_the_bed() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["s.stl", "s.3mf", "s.ply", "s.obj"] {
        let args = [&SMALL[..], &["--builtin", "sphere", "--out", name, "-q"]].concat();
        let out = scan(&args, dir.path());
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let mesh = read(&dir.path().join(name));
        mesh.check_closed_manifold()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let b = mesh.stats().bounds.unwrap();
        assert_eq!(b.min.z, 0.0, "{name}: base on the bed");
        assert!((b.min.x + b.max.x).abs() < 1e-3 && (b.min.y + b.max.y).abs() < 1e-3);
        // The 12 cm sphere, in millimetres, its height along z (its bottom, which no view
        // sees under the line of sight, is capped up to about a centimetre above the bed).
        let size = b.max - b.min;
        assert!(size.z > 105.0 && size.z < 126.0, "{name}: {size}");
    }
    let ply = std::fs::read(dir.path().join("s.ply")).unwrap();
    let head = String::from_utf8_lossy(&ply[..400]);
    assert!(head.contains("property float nx") && head.contains("property uint hits"));

    // --up y keeps the platform frame: the height along y, the base where the scan put it.
    let args = [
        &SMALL[..],
        &["--builtin", "sphere", "--up", "y", "--out", "y.stl", "-q"],
    ]
    .concat();
    let out = scan(&args, dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let b = read(&dir.path().join("y.stl")).stats().bounds.unwrap();
    assert!(
        (b.max.y - 120.0).abs() < 6.0 && b.min.y >= 0.0 && b.min.y < 15.0,
        "{b:?}"
    );

    // --format wins over the extension.
    let args = [
        &SMALL[..],
        &[
            "--builtin",
            "sphere",
            "--format",
            "ply",
            "--out",
            "f.dat",
            "-q",
        ],
    ]
    .concat();
    let out = scan(&args, dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        std::fs::read(dir.path().join("f.dat"))
            .unwrap()
            .starts_with(b"ply\n")
    );
}

#[test]
fn unknown_output_names_fail_cleanly() {
    common::assert_scan_fails_cleanly(&["--out", "x.jpg"], ".stl, .3mf, .ply, .obj");
    common::assert_scan_fails_cleanly(&["--out", "noext"], ".3mf");
    common::assert_scan_fails_cleanly(&["--format", "xyz"], "xyz");
    common::assert_scan_fails_cleanly(&["--preview", "p.jpg"], ".png");
    common::assert_scan_fails_cleanly(&["--out", "x.3mf", "--ascii"], "--ascii");
}

/// Writes a box from the origin to `size` (Z up, millimetres, outward triangles) as binary
/// STL `name` in `dir`; returns its path.
fn box_stl(dir: &std::path::Path, name: &str, size: Vec3) -> std::path::PathBuf {
    let v: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { 0.0 } else { size.x },
                if i & 2 == 0 { 0.0 } else { size.y },
                if i & 4 == 0 { 0.0 } else { size.z },
            )
        })
        .collect();
    let t = [
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
    let model = dir.join(name);
    voxoct::stl::write_file(&model, &v, &t, voxoct::stl::StlFormat::Binary, 1.0).unwrap();
    model
}

/// A box lower than the clip box's floor (3 mm over the platform) leaves no reading: the
/// error says so, with the floor's height, and nothing is written.
#[test]
fn a_model_lower_than_the_clip_floor_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    // 40 x 30 mm, 2 mm tall, Z up in millimetres.
    let model = box_stl(dir.path(), "plate.stl", Vec3::new(40.0, 30.0, 2.0));
    let m = model.to_str().unwrap();
    let args = [&SMALL[..], &["--model", m, "--out", "plate-scan.stl"]].concat();
    common::assert_scan_fails_cleanly(&args, "3.0 mm over the platform");
}

#[test]
fn a_z_up_millimetre_model_keeps_its_size_and_orientation() {
    let dir = tempfile::tempdir().unwrap();
    // A tower 40 mm wide (x), 30 mm deep (y), 70 mm tall (z), as a slicer would write it.
    let model = box_stl(dir.path(), "tower.stl", Vec3::new(40.0, 30.0, 70.0));
    let m = model.to_str().unwrap();
    let args = [&SMALL[..], &["--model", m, "--out", "t.stl"]].concat();
    let out = scan(&args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("40.0 × 30.0 × 70.0 mm"), "{stderr}");
    let size = {
        let b = read(&dir.path().join("t.stl")).stats().bounds.unwrap();
        b.max - b.min
    };
    // Scanned at 3 mm leaves from 4 sides (a box's corners bulge between the views):
    // standing up, 70 mm tall, its footprint still 40 × 30 mm give or take the bulges.
    assert!((size.z - 70.0).abs() < 4.0, "{size}");
    assert!(
        (size.x - 40.0).abs() < 10.0 && (size.y - 30.0).abs() < 10.0,
        "{size}"
    );
    assert!(size.x > size.y, "{size}");

    // Read as metres it would not fit: a clear error that names the flags.
    common::assert_scan_fails_cleanly(&["--model", m, "--model-units", "m"], "--model-units");
}
