//! The `scan` example as a user runs it: a small scan end to end, and every kind of bad input
//! ending with one clear line on stderr, a non-zero exit, no panic and no file at `--out`.

use std::path::Path;
use std::process::Output;

mod common;

/// Runs the `scan` example (built first when it is missing or stale).
fn scan(args: &[&str], cwd: &Path) -> Output {
    common::run_example("scan", args, cwd)
}

/// Asserts a clean failure of the scan writing to `x.stl`
/// ([`common::assert_scan_fails_cleanly`]).
fn assert_fails(args: &[&str], needle: &str) {
    common::assert_scan_fails_cleanly(&[args, &["--out", "x.stl"]].concat(), needle);
}

#[test]
fn a_small_simulated_scan_writes_a_closed_stl_stats_and_a_preview() {
    let dir = tempfile::tempdir().unwrap();
    let flags = [
        "--builtin",
        "sphere",
        "--stats",
        "s.json",
        "--preview",
        "p.png",
        "--out",
        "s.stl",
        "--record-to",
        "rec",
        "-q",
    ];
    let out = scan(&[&common::SMALL_SCAN[..], &flags].concat(), dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    for key in [
        "snapshots",
        "frames",
        "triangles_in",
        "leaves",
        "leaf_size_m",
        "mesh_triangles",
        "mesh_marched_triangles",
        "simplification",
        "mesh_vertices",
        "mesh_genus",
        "unseen_surface_share",
        "settled_cells",
        "closed_manifold",
        "peak_rss_bytes",
    ] {
        assert!(stats.get(key).is_some(), "stats lack {key}: {stats}");
    }
    // Simplification (on by default) took the marched mesh to the output by collapses (that
    // its figures are the marched mesh's and the output's is the pieces proptest's
    // assertion, in voxoct-mesh).
    let simp = &stats["simplification"];
    assert!(simp["collapses"].as_u64().unwrap() > 0, "{stats}");
    assert!(
        stats["mesh_triangles"].as_u64().unwrap()
            < stats["mesh_marched_triangles"].as_u64().unwrap(),
        "{stats}"
    );
    for key in [
        "load",
        "filter",
        "triangulate",
        "insert",
        "mesh",
        "write",
        "total",
    ] {
        assert!(
            stats["seconds"][key].as_f64().is_some(),
            "stats lack seconds.{key}"
        );
    }
    // The mesh stage's steps are parts of it.
    let steps = ["closure", "march", "smooth", "simplify"].map(|key| {
        stats["seconds"]["mesh_steps"][key]
            .as_f64()
            .unwrap_or_else(|| panic!("stats lack seconds.mesh_steps.{key}"))
    });
    let mesh = stats["seconds"]["mesh"].as_f64().unwrap();
    assert!(
        steps.iter().all(|&t| t >= 0.0) && steps.iter().sum::<f64>() <= mesh,
        "mesh steps {steps:?} vs mesh {mesh}"
    );
    assert_eq!(stats["closed_manifold"], true);
    // A closed mesh has a genus (null only for an open one).
    assert!(stats["mesh_genus"].as_u64().is_some(), "{stats}");
    // The closure ran (solid by default): some of the surface no view saw (at least the
    // base on the platform), never all of it.
    let unseen = stats["unseen_surface_share"].as_f64().expect("a share");
    assert!(unseen > 0.0 && unseen < 1.0, "{stats}");
    // The views settled some of this noisy scan's marked cells (1840 of 19203 leaves when
    // written), never all of them.
    let settled = stats["settled_cells"].as_u64().expect("a count");
    let leaves = stats["leaves"].as_u64().expect("a count");
    assert!(settled > 0 && settled < leaves, "{stats}");
    assert_eq!(stats["snapshots"], 4);
    // mm by default: a 12 cm sphere is ~120 units wide.
    let soup = voxoct::stl::read_file(dir.path().join("s.stl")).unwrap();
    let max_x = soup
        .iter()
        .flat_map(|t| t.v)
        .map(|p| p.x)
        .fold(f32::MIN, f32::max);
    assert!(
        (50.0..80.0).contains(&max_x),
        "STL not in millimetres: max x {max_x}"
    );
    assert!(std::fs::metadata(dir.path().join("p.png")).unwrap().len() > 1000);

    // The recorded scan reprocesses to the same mesh.
    let again = scan(
        &[
            "--input",
            "rec",
            "--leaf",
            "0.003",
            "--out",
            "again.stl",
            "-q",
        ],
        dir.path(),
    );
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    assert_eq!(
        std::fs::read(dir.path().join("s.stl")).unwrap(),
        std::fs::read(dir.path().join("again.stl")).unwrap()
    );
}

/// The mesh triangles and validity a small simulated scan reports with `extra` flags.
fn sphere_stats(extra: &[&str]) -> (u64, bool, u64) {
    let dir = tempfile::tempdir().unwrap();
    let flags = [
        "--builtin",
        "sphere",
        "--stats",
        "s.json",
        "--out",
        "s.stl",
        "-q",
    ];
    let args = [&common::SMALL_SCAN[..], &flags, extra].concat();
    let out = scan(&args, dir.path());
    assert!(
        out.status.success(),
        "{extra:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("s.json")).unwrap()).unwrap();
    (
        stats["mesh_triangles"].as_u64().unwrap(),
        stats["valid_solid"].as_bool().unwrap(),
        stats["self_intersecting_triangles"].as_u64().unwrap(),
    )
}

#[test]
fn simplification_is_on_by_default_and_off_with_no_simplify_and_thesis() {
    let (simplified, valid, selfx) = sphere_stats(&[]);
    let (full, full_valid, _) = sphere_stats(&["--no-simplify"]);
    assert!(valid && full_valid && selfx == 0);
    assert!(
        simplified * 3 < full,
        "default {simplified} triangles, --no-simplify {full}"
    );
    // --thesis keeps every triangle unless simplification is asked for.
    let (thesis, _, _) = sphere_stats(&["--thesis"]);
    let (thesis_full, _, _) = sphere_stats(&["--thesis", "--no-simplify"]);
    let (thesis_simplified, thesis_valid, _) =
        sphere_stats(&["--thesis", "--max-error", "0.00075"]);
    assert_eq!(thesis, thesis_full);
    assert!(thesis_valid && thesis_simplified < thesis);
}

#[test]
fn bad_flags_fail_cleanly() {
    assert_fails(&["--leaf", "2", "--root", "1"], "--leaf");
    assert_fails(&["--no-simplify", "--max-error", "0.001"], "--no-simplify");
    assert_fails(&["--no-simplify", "--triangles", "1000"], "--no-simplify");
    assert_fails(&["--leaf", "-0.001"], "--leaf");
    assert_fails(&["--threshold", "-1"], "--threshold");
    assert_fails(&["--snapshots", "0"], "--snapshots");
    assert_fails(&["--builtin", "teapot"], "teapot");
    assert_fails(
        &[
            "--lod",
            "40",
            "--snapshots",
            "1",
            "--frames",
            "1",
            "--leaf",
            "0.01",
        ],
        "level of detail",
    );
    assert_fails(&["--filter", "bogus"], "bogus");
    assert_fails(&["--turntable", "127.0.0.1:1"], "--kinect");
}

#[test]
fn bad_files_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert_fails(&["--input", d.join("missing").to_str().unwrap()], "missing");
    assert_fails(
        &["--model", d.join("nope.stl").to_str().unwrap()],
        "nope.stl",
    );
    assert_fails(
        &[
            "--fakenect",
            d.join("nofk").to_str().unwrap(),
            "--degrees-per-snapshot",
            "45",
        ],
        "nofk",
    );

    // A malformed scan.toml, a malformed config, a frame of the wrong size.
    let bad = d.join("bad");
    std::fs::create_dir_all(bad.join("frames")).unwrap();
    std::fs::write(
        bad.join("scan.toml"),
        "format = \"voxoct-scan\"\nversion = 1\n[sensor]\nwidth = \"x\"\n",
    )
    .unwrap();
    assert_fails(&["--input", bad.to_str().unwrap()], "width");
    let cfg = d.join("cfg.toml");
    std::fs::write(&cfg, "[rig]\ntilt_deg = 10.0\n").unwrap();
    assert_fails(&["--config", cfg.to_str().unwrap()], "cfg.toml");

    let garbage = d.join("garbage.stl");
    std::fs::write(
        &garbage,
        b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 1 2\n",
    )
    .unwrap();
    assert_fails(&["--model", garbage.to_str().unwrap()], "garbage.stl");
}

#[test]
fn live_scan_without_hardware_is_a_clear_error() {
    // No Kinect here: either the feature is off (say how to build it) or no device is found.
    assert_fails(&["--kinect", "--turntable", "127.0.0.1:1"], "Kinect");
    // libfreenect's own messages are quietened: our one line is all there is.
    let dir = tempfile::tempdir().unwrap();
    let out = scan(
        &["--kinect", "--turntable", "127.0.0.1:1", "--out", "x.stl"],
        dir.path(),
    );
    let all = [out.stdout, out.stderr].concat();
    let text = String::from_utf8_lossy(&all);
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{text}");
    assert_fails(&["--kinect-depth", "raw"], "--kinect");
    assert_fails(
        &[
            "--kinect",
            "--kinect-depth",
            "metres",
            "--turntable",
            "127.0.0.1:1",
        ],
        "metres",
    );
}
