//! Hostile recorded scans (issue 16): frame paths leaving the directory, huge PNG headers,
//! frame counts beyond memory, numbers out of `f32` range, and the format-preserving rig edit.

use std::fs;
use std::path::{Path, PathBuf};

use voxoct_depth::glam::Vec3;
use voxoct_depth::image::{RgbImage, write_png};
use voxoct_depth::scan::{
    MANIFEST_FILE, RecordedScan, ScanError, ScanManifest, SnapshotEntry, read_png_frame_sized,
    set_rig_in_manifest_text,
};
use voxoct_depth::{DepthFrame, Rig, ScannerConfig};

/// A one-snapshot scan of 8x6 frames in `dir`.
fn write_scan(dir: &Path) -> ScanManifest {
    let mut config = ScannerConfig::default();
    config.sensor.intrinsics.width = 8;
    config.sensor.intrinsics.height = 6;
    config.sensor.intrinsics.cx = 3.5;
    config.sensor.intrinsics.cy = 2.5;
    let mut m = ScanManifest::new(config);
    m.snapshots.push(SnapshotEntry {
        angle_deg: 0.0,
        frames: vec![PathBuf::from("frames/a.png")],
    });
    let mut f = DepthFrame::empty(8, 6, config.sensor.depth_unit_m);
    f.data.fill(700);
    RecordedScan::write(dir, &m, &[vec![f]]).unwrap();
    m
}

fn manifest_text(dir: &Path) -> String {
    fs::read_to_string(dir.join(MANIFEST_FILE)).unwrap()
}

#[test]
fn d11_frame_paths_must_stay_inside_the_scan_directory() {
    let dir = tempfile::tempdir().unwrap();
    write_scan(dir.path());
    let text = manifest_text(dir.path());
    for bad in ["../x.png", "/etc/passwd", "frames/../../x.png", ".."] {
        let t = text.replace("frames/a.png", bad);
        let e = ScanManifest::from_toml_str(&t, Path::new("scan.toml")).unwrap_err();
        assert!(
            e.to_string().contains("inside the scan directory"),
            "{bad}: {e}"
        );
    }
    // Inside after `..`: fine.
    let t = text.replace("frames/a.png", "frames/../frames/a.png");
    ScanManifest::from_toml_str(&t, Path::new("scan.toml")).unwrap();
}

#[test]
fn d11_a_symlink_leading_out_and_a_fifo_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan");
    write_scan(&scan);
    fs::rename(scan.join("frames/a.png"), dir.path().join("a.png")).unwrap();
    std::os::unix::fs::symlink("../../a.png", scan.join("frames/a.png")).unwrap();
    let e = RecordedScan::open(&scan).unwrap_err();
    assert!(e.to_string().contains("leaves the scan directory"), "{e}");
    fs::remove_file(scan.join("frames/a.png")).unwrap();
    assert!(
        std::process::Command::new("mkfifo")
            .arg(scan.join("frames/a.png"))
            .status()
            .unwrap()
            .success()
    );
    let e = RecordedScan::open(&scan).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
}

#[test]
fn d08_the_png_header_is_checked_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.png");
    let mut buf = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut buf, 100_000, 100_000);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut writer = enc.write_header().unwrap();
        writer
            .write_chunk(png::chunk::IDAT, &[0x78, 0x9c, 0x03, 0, 0, 0, 0, 1])
            .unwrap();
        std::mem::forget(writer);
    }
    fs::write(&p, &buf).unwrap();
    let e = read_png_frame_sized(&p, 0.001, Some((640, 480))).unwrap_err();
    assert!(matches!(e, ScanError::BadFrameFile { .. }), "{e}");
    assert!(e.to_string().contains("100000x100000"), "{e}");
    let e = read_png_frame_sized(&p, 0.001, None).unwrap_err();
    assert!(e.to_string().contains("larger than"), "{e}");
}

#[test]
fn d07_frames_beyond_the_memory_limit_are_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    write_scan(dir.path());
    let e = RecordedScan::open_limited(dir.path(), 10).unwrap_err();
    assert!(e.to_string().contains("bytes of memory"), "{e}");
    RecordedScan::open_limited(dir.path(), 1 << 20).unwrap();
}

#[test]
fn d17_numbers_out_of_f32_range_are_out_of_range_not_non_finite() {
    let dir = tempfile::tempdir().unwrap();
    write_scan(dir.path());
    let text = manifest_text(dir.path());
    for (key, to) in [("depth_unit_m", "1e-45"), ("angle_deg", "1e300")] {
        let t = set_first(&text, key, to);
        let e = ScanManifest::from_toml_str(&t, Path::new("scan.toml")).unwrap_err();
        assert!(e.to_string().contains("out of range"), "{key} = {to}: {e}");
    }
}

/// `text` with the first `key = …` line's value replaced by `value`.
fn set_first(text: &str, key: &str, value: &str) -> String {
    let mut done = false;
    text.lines()
        .map(|l| {
            if !done && l.trim_start().starts_with(&format!("{key} =")) {
                done = true;
                format!("{key} = {value}")
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn d06_the_rig_edit_keeps_comments_unknown_keys_and_formatting() {
    let dir = tempfile::tempdir().unwrap();
    write_scan(dir.path());
    let text = format!(
        "# my scan of the bunny\n{}\n[extra]\nnote = \"kept\" # trailing comment\n",
        manifest_text(dir.path()).replace("[rig]", "# the rig, measured by hand\n[rig]")
    );
    let rig = Rig {
        tilt_deg: 21.5,
        sensor_position_m: Vec3::new(0.001, 0.31, 0.69),
    };
    let out = set_rig_in_manifest_text(&text, &rig, Path::new("scan.toml")).unwrap();
    for kept in [
        "# my scan of the bunny",
        "# the rig, measured by hand",
        "note = \"kept\" # trailing comment",
    ] {
        assert!(out.contains(kept), "{kept:?} lost:\n{out}");
    }
    let m = ScanManifest::from_toml_str(&out, Path::new("scan.toml")).unwrap();
    assert_eq!(m.rig.tilt_deg, 21.5);
    assert_eq!(m.rig.sensor_position_m, rig.sensor_position_m);
    // Only the rig lines differ.
    let changed: Vec<_> = text
        .lines()
        .zip(out.lines())
        .filter(|(a, b)| a != b)
        .collect();
    assert_eq!(changed.len(), 2, "{changed:?}");
}

#[test]
fn d01_library_writes_follow_symlinks_keep_permissions_and_write_to_devices() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let img = RgbImage {
        width: 2,
        height: 2,
        data: vec![7; 12],
    };
    fs::write(d.join("real.png"), b"old").unwrap();
    fs::set_permissions(d.join("real.png"), fs::Permissions::from_mode(0o640)).unwrap();
    std::os::unix::fs::symlink("real.png", d.join("link.png")).unwrap();
    write_png(d.join("link.png"), &img).unwrap();
    assert!(
        fs::symlink_metadata(d.join("link.png"))
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        fs::read(d.join("real.png"))
            .unwrap()
            .starts_with(b"\x89PNG")
    );
    let mode = fs::metadata(d.join("real.png"))
        .unwrap()
        .permissions()
        .mode()
        & 0o777;
    assert_eq!(mode, 0o640);
    std::os::unix::fs::symlink("/dev/null", d.join("null.png")).unwrap();
    write_png(d.join("null.png"), &img).unwrap();
    assert!(
        fs::symlink_metadata(d.join("null.png"))
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(!fs::metadata("/dev/null").unwrap().is_file());
}

#[test]
fn d10_a_manifest_or_settings_file_that_is_a_device_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.path().join(MANIFEST_FILE)).unwrap();
    let e = RecordedScan::open(dir.path()).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    // A settings file may be a pipe, but not an endless one.
    let e = ScannerConfig::from_file("/dev/zero").unwrap_err();
    assert!(e.to_string().contains("larger than"), "{e}");
}
