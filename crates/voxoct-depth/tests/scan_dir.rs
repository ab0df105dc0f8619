//! The recorded-scan directory: round trips and every bad-input case.

use std::fs;
use std::path::{Path, PathBuf};

use voxoct_depth::glam::Vec3;
use voxoct_depth::scan::{
    MANIFEST_FILE, RecordedScan, ScanError, ScanManifest, ScanWriter, SnapshotEntry,
};
use voxoct_depth::{ClipBox, DepthFrame, FrameError, Intrinsics, Rig, ScannerConfig, SensorConfig};

fn config(w: u32, h: u32) -> ScannerConfig {
    ScannerConfig {
        sensor: SensorConfig {
            intrinsics: Intrinsics {
                width: w,
                height: h,
                fx: 58.0,
                fy: 57.5,
                cx: (w as f32 - 1.0) / 2.0,
                cy: (h as f32 - 1.0) / 2.0,
            },
            depth_unit_m: 0.001,
        },
        rig: Rig {
            tilt_deg: 19.65,
            sensor_position_m: Vec3::new(0.0, 0.3, 0.7),
        },
        clip: ClipBox {
            min: Vec3::new(-0.15, 0.003, -0.15),
            max: Vec3::new(0.15, 0.4, 0.15),
        },
    }
}

fn frame(w: u32, h: u32, seed: u16) -> DepthFrame {
    let mut f = DepthFrame::empty(w, h, 0.001);
    for (i, d) in f.data.iter_mut().enumerate() {
        // Every value class: holes, small, large, the maximum.
        *d = match (i as u16).wrapping_mul(31).wrapping_add(seed) % 7 {
            0 => 0,
            1 => u16::MAX,
            k => 500 + k * 37 + seed,
        };
    }
    f
}

/// A valid 3-snapshot scan of 8x6 frames, 2 frames per snapshot, written with `write`.
fn write_scan(dir: &Path) -> (ScanManifest, Vec<Vec<DepthFrame>>) {
    let mut m = ScanManifest::new(config(8, 6));
    let mut frames = Vec::new();
    for (k, angle) in [0.0f32, 120.0, -240.5].into_iter().enumerate() {
        m.snapshots.push(SnapshotEntry {
            angle_deg: angle,
            frames: (0..2)
                .map(|j| PathBuf::from(format!("frames/s{k:03}_f{j:02}.png")))
                .collect(),
        });
        frames.push((0..2).map(|j| frame(8, 6, (k * 2 + j) as u16)).collect());
    }
    RecordedScan::write(dir, &m, &frames).unwrap();
    (m, frames)
}

#[test]
fn write_then_open_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let (m, frames) = write_scan(dir.path());
    let scan = RecordedScan::open(dir.path()).unwrap();
    assert_eq!(scan.manifest, m);
    assert_eq!(scan.frames, frames);
    assert_eq!(scan.len(), 3);
    // The manifest is plain, readable TOML in the documented layout.
    let text = fs::read_to_string(dir.path().join(MANIFEST_FILE)).unwrap();
    for needle in [
        "format = \"voxoct-scan\"",
        "version = 1",
        "[sensor]",
        "depth_unit_m = 0.001",
        "tilt_deg = 19.65",
        "[[snapshot]]",
        "angle_deg = -240.5",
        "frames/s002_f01.png",
    ] {
        assert!(text.contains(needle), "{needle} not in\n{text}");
    }
}

#[test]
fn scan_writer_writes_snapshot_by_snapshot() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("scan");
    let mut w = ScanWriter::create(&root, config(5, 4)).unwrap();
    let a = vec![frame(5, 4, 1), frame(5, 4, 2), frame(5, 4, 3)];
    w.add_snapshot(0.0, &a).unwrap();
    // Readable after the first snapshot already.
    assert_eq!(RecordedScan::open(&root).unwrap().frames, vec![a.clone()]);
    let b = vec![frame(5, 4, 9)];
    w.add_snapshot(45.0, &b).unwrap();
    // Bad snapshots are refused and leave the scan as it was.
    assert!(matches!(
        w.add_snapshot(f32::NAN, &b),
        Err(ScanError::Frame(FrameError::InvalidArgument {
            name: "angle_deg",
            ..
        }))
    ));
    assert!(matches!(
        w.add_snapshot(90.0, &[]),
        Err(ScanError::Frame(FrameError::NoFrames))
    ));
    assert!(matches!(
        w.add_snapshot(90.0, &[frame(4, 4, 0)]),
        Err(ScanError::ScanMismatch { .. })
    ));
    let m = w.finish().unwrap();
    assert_eq!(m.snapshots.len(), 2);
    assert_eq!(
        m.snapshots[1].frames,
        vec![PathBuf::from("frames/s001_f00.png")]
    );
    let scan = RecordedScan::open(&root).unwrap();
    assert_eq!(scan.manifest, m);
    assert_eq!(scan.frames, vec![a, b]);

    let empty = ScanWriter::create(dir.path().join("empty"), config(5, 4)).unwrap();
    assert!(matches!(empty.finish(), Err(ScanError::NoSnapshots { .. })));
}

#[test]
fn write_refuses_mismatched_input() {
    let dir = tempfile::tempdir().unwrap();
    let (m, frames) = write_scan(dir.path());
    let out = dir.path().join("out");
    assert!(matches!(
        RecordedScan::write(&out, &m, &frames[..2]),
        Err(ScanError::ScanMismatch { .. })
    ));
    let mut short = frames.clone();
    short[1].pop();
    assert!(matches!(
        RecordedScan::write(&out, &m, &short),
        Err(ScanError::ScanMismatch { .. })
    ));
    let mut units = frames.clone();
    units[0][0].unit_m = 0.0001;
    let e = RecordedScan::write(&out, &m, &units).unwrap_err();
    assert!(e.to_string().contains("units"), "{e}");
    assert!(!out.join(MANIFEST_FILE).exists());
}

#[test]
fn scanner_config_file_round_trips_and_overrides() {
    let dir = tempfile::tempdir().unwrap();
    let mut c = config(8, 6);
    c.rig.tilt_deg = 17.81889;
    c.sensor.depth_unit_m = 0.0005;
    let p = dir.path().join("scanner.toml");
    fs::write(&p, c.to_toml_string().unwrap()).unwrap();
    assert_eq!(ScannerConfig::from_file(&p).unwrap(), c);

    // A scan manifest is also a valid configuration (its snapshots are ignored).
    let (m, _) = write_scan(dir.path());
    let from_manifest = ScannerConfig::from_file(dir.path().join(MANIFEST_FILE)).unwrap();
    assert_eq!(from_manifest, m.config());

    let mut scan = RecordedScan::open(dir.path()).unwrap();
    scan.apply_config(&c).unwrap();
    assert_eq!(scan.manifest.config(), c);
    assert!(scan.frames.iter().flatten().all(|f| f.unit_m == 0.0005));
    assert!(matches!(
        scan.apply_config(&config(9, 6)),
        Err(ScanError::Frame(FrameError::FrameSizeMismatch { .. }))
    ));

    // Missing table, named.
    fs::write(&p, "[sensor]\nwidth = 1\n").unwrap();
    let e = ScannerConfig::from_file(&p).unwrap_err();
    assert!(e.to_string().contains("scanner.toml"), "{e}");
    assert!(matches!(e, ScanError::MissingKey { ref key, .. } if key == "sensor.height"));
    assert!(matches!(
        ScannerConfig::from_file(dir.path().join("nope.toml")),
        Err(ScanError::Io { .. })
    ));
}

/// Writes a valid scan, applies `edit` to its manifest text, and opens it.
fn open_edited(edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, ScanError) {
    let dir = tempfile::tempdir().unwrap();
    write_scan(dir.path());
    let p = dir.path().join(MANIFEST_FILE);
    let text = fs::read_to_string(&p).unwrap();
    let edited = edit(text.clone());
    assert_ne!(edited, text, "the edit changed nothing");
    fs::write(&p, edited).unwrap();
    let e = RecordedScan::open(dir.path()).unwrap_err();
    (dir, e)
}

fn replace(from: &'static str, to: &'static str) -> impl FnOnce(String) -> String {
    move |t| {
        assert!(t.contains(from), "`{from}` not in\n{t}");
        t.replacen(from, to, 1)
    }
}

fn key_of(e: &ScanError) -> &str {
    match e {
        ScanError::MissingKey { key, .. }
        | ScanError::WrongType { key, .. }
        | ScanError::InvalidValue { key, .. } => key,
        e => panic!("not a key error: {e:?}"),
    }
}

#[test]
fn missing_keys_are_named() {
    for (from, key) in [
        ("fx = 58.0\n", "sensor.fx"),
        ("depth_unit_m = 0.001\n", "sensor.depth_unit_m"),
        ("tilt_deg = 19.65\n", "rig.tilt_deg"),
        ("format = \"voxoct-scan\"\n", "format"),
        ("version = 1\n", "version"),
        ("angle_deg = 120.0\n", "snapshot[1].angle_deg"),
    ] {
        let (_d, e) = open_edited(replace(from, ""));
        assert!(matches!(e, ScanError::MissingKey { .. }), "{e:?}");
        assert_eq!(key_of(&e), key);
        let msg = e.to_string();
        assert!(msg.contains(key) && msg.contains(MANIFEST_FILE), "{msg}");
    }
    let (_d, e) = open_edited(|t| t.replace("[clip]", "[clipx]"));
    assert_eq!(key_of(&e), "clip");
    let (_d, e) = open_edited(|t| t.replace("frames = [", "framez = ["));
    assert_eq!(key_of(&e), "snapshot[0].frames");
}

#[test]
fn mistyped_keys_are_named() {
    for (from, to, key) in [
        ("width = 8", "width = \"8\"", "sensor.width"),
        ("width = 8", "width = 8.5", "sensor.width"),
        ("fy = 57.5", "fy = true", "sensor.fy"),
        ("version = 1", "version = \"1\"", "version"),
        (
            "sensor_position_m = [0.0, 0.3, 0.7]",
            "sensor_position_m = [0.0, \"0.3\", 0.7]",
            "rig.sensor_position_m[1]",
        ),
        (
            "sensor_position_m = [0.0, 0.3, 0.7]",
            "sensor_position_m = [0.0, 0.3]",
            "rig.sensor_position_m",
        ),
        ("min_m = [", "min_m = 3\nx = [", "clip.min_m"),
        (
            "angle_deg = 0.0",
            "angle_deg = \"zero\"",
            "snapshot[0].angle_deg",
        ),
        ("\"frames/s000_f01.png\"", "7", "snapshot[0].frames[1]"),
    ] {
        let (_d, e) = open_edited(replace(from, to));
        assert!(
            matches!(e, ScanError::WrongType { .. }),
            "{from} -> {to}: {e:?}"
        );
        assert_eq!(key_of(&e), key, "{e}");
        assert!(e.to_string().contains(key), "{e}");
    }
    let (_d, e) = open_edited(|t| t.replacen("[sensor]", "sensor = 3\n[sensorx]", 1));
    assert!(
        matches!(e, ScanError::WrongType { ref key, .. } if key == "sensor"),
        "{e:?}"
    );
}

#[test]
fn out_of_range_values_are_refused() {
    for (from, to, key) in [
        ("fx = 58.0", "fx = 0.0", "sensor.fx"),
        ("fy = 57.5", "fy = -57.5", "sensor.fy"),
        ("fx = 58.0", "fx = nan", "sensor.fx"),
        ("cx = 3.5", "cx = inf", "sensor.cx"),
        (
            "depth_unit_m = 0.001",
            "depth_unit_m = 0",
            "sensor.depth_unit_m",
        ),
        (
            "depth_unit_m = 0.001",
            "depth_unit_m = -0.001",
            "sensor.depth_unit_m",
        ),
        ("width = 8", "width = 0", "sensor.width"),
        ("height = 6", "height = -6", "sensor.height"),
        ("tilt_deg = 19.65", "tilt_deg = 95.0", "rig.tilt_deg"),
        (
            "sensor_position_m = [0.0, 0.3, 0.7]",
            "sensor_position_m = [0.0, nan, 0.7]",
            "rig.sensor_position_m[1]",
        ),
        ("min_m = [-0.15, 0.003", "min_m = [-0.15, 0.5", "clip"),
        (
            "angle_deg = 120.0",
            "angle_deg = 4000.0",
            "snapshot[1].angle_deg",
        ),
        (
            "angle_deg = -240.5",
            "angle_deg = -inf",
            "snapshot[2].angle_deg",
        ),
    ] {
        let (_d, e) = open_edited(replace(from, to));
        assert!(
            matches!(e, ScanError::InvalidValue { .. }),
            "{from} -> {to}: {e:?}"
        );
        assert_eq!(key_of(&e), key, "{e}");
    }
    let (_d, e) = open_edited(|t| {
        let i = t.find("frames = [").unwrap();
        let j = i + t[i..].find(']').unwrap();
        format!("{}frames = []{}", &t[..i], &t[j + 1..])
    });
    assert_eq!(key_of(&e), "snapshot[0].frames");
}

#[test]
fn format_version_and_snapshot_list_are_checked() {
    let (_d, e) = open_edited(replace("\"voxoct-scan\"", "\"tum-rgbd\""));
    assert!(matches!(e, ScanError::WrongFormat { ref found, .. } if found == "tum-rgbd"));
    let (_d, e) = open_edited(replace("version = 1", "version = 2"));
    assert!(matches!(
        e,
        ScanError::UnsupportedVersion {
            found: 2,
            supported: 1,
            ..
        }
    ));
    let (_d, e) = open_edited(|t| {
        let i = t.find("[[snapshot]]").unwrap();
        format!("{}snapshot = []\n", &t[..i])
    });
    assert!(matches!(e, ScanError::NoSnapshots { .. }), "{e:?}");
    let (_d, e) = open_edited(|t| t[..t.find("[[snapshot]]").unwrap()].to_owned());
    assert!(matches!(e, ScanError::NoSnapshots { .. }), "{e:?}");
    let (_d, e) = open_edited(replace("[sensor]", "[sensor"));
    assert!(matches!(e, ScanError::Toml { .. }), "{e:?}");
    assert!(e.to_string().contains(MANIFEST_FILE));
}

#[test]
fn unknown_keys_are_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let (m, _) = write_scan(dir.path());
    let p = dir.path().join(MANIFEST_FILE);
    let text = fs::read_to_string(&p).unwrap();
    let text = text
        .replacen(
            "version = 1\n",
            "version = 1\ncreated_by = \"a simulator\"\n",
            1,
        )
        .replacen("[sensor]\n", "[sensor]\nmodel = \"Kinect v1\"\n", 1)
        .replacen("[[snapshot]]\n", "[[snapshot]]\nexposure = 3\n", 1)
        + "\n[notes]\ntext = \"hello\"\n";
    fs::write(&p, text).unwrap();
    assert_eq!(RecordedScan::open(dir.path()).unwrap().manifest, m);
}

#[test]
fn bad_frame_files_are_named() {
    fn with_frame(bytes: impl FnOnce(&Path)) -> ScanError {
        let dir = tempfile::tempdir().unwrap();
        write_scan(dir.path());
        bytes(&dir.path().join("frames/s001_f00.png"));
        let e = RecordedScan::open(dir.path()).unwrap_err();
        assert!(e.to_string().contains("s001_f00.png"), "{e}");
        e
    }
    fn png(path: &Path, w: u32, h: u32, color: png::ColorType, depth: png::BitDepth) {
        let f = fs::File::create(path).unwrap();
        let mut enc = png::Encoder::new(f, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        let samples = match color {
            png::ColorType::Rgb => 3,
            png::ColorType::GrayscaleAlpha => 2,
            _ => 1,
        };
        let bytes = (w * h) as usize
            * samples
            * if depth == png::BitDepth::Sixteen {
                2
            } else {
                1
            };
        let mut wr = enc.write_header().unwrap();
        wr.write_image_data(&vec![7u8; bytes]).unwrap();
        wr.finish().unwrap();
    }

    let e = with_frame(|p| fs::remove_file(p).unwrap());
    assert!(matches!(e, ScanError::Io { .. }), "{e:?}");
    let e = with_frame(|p| png(p, 8, 5, png::ColorType::Grayscale, png::BitDepth::Sixteen));
    assert!(
        matches!(e, ScanError::BadFrameFile { ref reason, .. } if reason.contains("8x5")),
        "{e:?}"
    );
    let e = with_frame(|p| png(p, 8, 6, png::ColorType::Grayscale, png::BitDepth::Eight));
    assert!(
        matches!(e, ScanError::BadFrameFile { ref reason, .. } if reason.contains("8-bit")),
        "{e:?}"
    );
    let e = with_frame(|p| png(p, 8, 6, png::ColorType::Rgb, png::BitDepth::Sixteen));
    assert!(
        matches!(e, ScanError::BadFrameFile { ref reason, .. } if reason.contains("Rgb")),
        "{e:?}"
    );
    let e = with_frame(|p| fs::write(p, b"P5 8 6 65535\n").unwrap());
    assert!(matches!(e, ScanError::Png { .. }), "{e:?}");
    let e = with_frame(|p| {
        let b = fs::read(p).unwrap();
        fs::write(p, &b[..b.len() / 2]).unwrap();
    });
    assert!(matches!(e, ScanError::Png { .. }), "{e:?}");

    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(
        RecordedScan::open(dir.path()),
        Err(ScanError::Io { ref path, .. }) if path.ends_with(MANIFEST_FILE)
    ));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

    /// Any valid manifest survives TOML exactly, every f32 bit for bit.
    #[test]
    fn manifest_round_trips_through_toml(
        f in proptest::array::uniform4(1e-3f32..1e4),
        unit in 1e-6f32..1.0,
        tilt in -89.9f32..89.9,
        pos in proptest::array::uniform3(-10.0f32..10.0),
        lo in proptest::array::uniform3(-5.0f32..0.0),
        hi in proptest::array::uniform3(0.0f32..5.0),
        angles in proptest::collection::vec(-3600.0f32..3600.0, 1..5),
    ) {
        let mut m = ScanManifest::new(ScannerConfig {
            sensor: SensorConfig {
                intrinsics: Intrinsics { width: 640, height: 480, fx: f[0], fy: f[1], cx: f[2], cy: f[3] },
                depth_unit_m: unit,
            },
            rig: Rig { tilt_deg: tilt, sensor_position_m: Vec3::from_array(pos) },
            clip: ClipBox { min: Vec3::from_array(lo), max: Vec3::from_array(hi) },
        });
        for (k, a) in angles.into_iter().enumerate() {
            m.snapshots.push(SnapshotEntry { angle_deg: a, frames: vec![PathBuf::from(format!("f/{k}.png"))] });
        }
        let text = m.to_toml_string().unwrap();
        let back = ScanManifest::from_toml_str(&text, Path::new("scan.toml")).unwrap();
        proptest::prop_assert_eq!(back, m);
    }
}
