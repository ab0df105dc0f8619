//! Fakenect replay: fixtures written by the tests, and the real NYU frame when present.

use std::path::Path;
use std::time::Duration;

use proptest::prelude::*;
use voxoct_kinect::{DepthSource, FakenectSource, SourceError, raw_disparity_to_m};

const T: Duration = Duration::from_secs(1);
const N: usize = 640 * 480;

/// A depth file as libfreenect's recorder writes it: header, then little-endian u16s.
fn depth_file(raw: impl Fn(usize) -> u16) -> Vec<u8> {
    let mut b = b"P5 640 480 65535\n".to_vec();
    for i in 0..N {
        b.extend_from_slice(&raw(i).to_le_bytes());
    }
    b
}

/// Writes `INDEX.txt` with `lines` and the given files.
fn recording(dir: &Path, lines: &[&str], files: &[(&str, Vec<u8>)]) {
    let mut index = lines.join("\n");
    index.push('\n');
    std::fs::write(dir.join("INDEX.txt"), index).unwrap();
    for (name, bytes) in files {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
}

#[test]
fn frames_are_served_in_order_converted_to_millimetres() {
    let dir = tempfile::tempdir().unwrap();
    let d0 = "d-1294356874.100000-1000.pgm";
    let d1 = "d-1294356874.133000-2000.pgm";
    let tilt = vec![0u8, 0, 0, 0, 0, 0, 20, 0, 0, 0, 0, 0]; // 20 half degrees up
    recording(
        dir.path(),
        &[
            "a-1294356874.090000-900.dump",
            d0,
            "r-1294356874.110000-1100.ppm",
            d1,
        ],
        &[
            ("a-1294356874.090000-900.dump", tilt),
            (d0, depth_file(|i| if i % 2 == 0 { 800 } else { 2047 })),
            (d1, depth_file(|_| 600)),
        ],
    );
    let mut src = FakenectSource::open(dir.path()).unwrap();
    assert_eq!(src.depth_frame_count(), 2);
    assert_eq!(src.tilt_deg(), None);
    let f0 = src.grab(T).unwrap();
    assert_eq!((f0.width, f0.height, f0.unit_m), (640, 480, 0.001));
    // 1 / (−0.0030711016·800 + 3.3309495161) = 1.14407 m.
    assert_eq!(f0.get(0, 0), 1144);
    assert_eq!(f0.get(1, 0), 0);
    assert_eq!(src.tilt_deg(), Some(-10.0));
    let f1 = src.grab(T).unwrap();
    let z = raw_disparity_to_m(600).unwrap();
    assert_eq!(f1.get(639, 479), (z * 1000.0).round() as u16);
    match src.grab(T) {
        Err(SourceError::EndOfRecording { frames: 2, .. }) => {}
        other => panic!("{other:?}"),
    }
    // Looping starts again.
    let mut src = FakenectSource::open(dir.path()).unwrap().looping(true);
    for _ in 0..3 {
        src.grab(T).unwrap();
    }
    assert_eq!(src.grab(T).unwrap().get(0, 0), f1.get(0, 0));
}

fn header_error(bytes: Vec<u8>) -> (SourceError, String) {
    let dir = tempfile::tempdir().unwrap();
    let name = "d-0.5-7.pgm";
    recording(dir.path(), &[name], &[(name, bytes)]);
    let err = FakenectSource::open(dir.path())
        .unwrap()
        .grab(T)
        .unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains(name), "{msg}");
    (err, msg)
}

#[test]
fn malformed_depth_files_are_clear_errors() {
    let good = depth_file(|_| 700);
    let with_header = |h: &str| {
        let mut b = h.as_bytes().to_vec();
        b.extend_from_slice(&good[17..]);
        b
    };
    for (bytes, offset, needle) in [
        (with_header("P6 640 480 65535\n"), 0, "magic"),
        (with_header("P5 320 480 65535\n"), 3, "width 320"),
        (with_header("P5 640 480 255\n"), 11, "maximum value 255"),
        (with_header("P5 640 4x0 65535\n"), 7, "not a number"),
        (b"P5 640 480".to_vec(), 10, "missing maximum value"),
        (b"P5 640 480 65535".to_vec(), 16, "no whitespace"),
    ] {
        match header_error(bytes) {
            (SourceError::FakenectHeader { offset: o, .. }, msg) => {
                assert_eq!(o, offset, "{msg}");
                assert!(msg.contains(needle), "{msg}");
            }
            (other, _) => panic!("{other:?}"),
        }
    }
    match header_error(good[..1000].to_vec()) {
        (
            SourceError::FakenectShort {
                expected, found, ..
            },
            _,
        ) => assert_eq!((expected, found), (2 * N, 1000 - 17)),
        (other, _) => panic!("{other:?}"),
    }
}

#[test]
fn bad_index_lines_name_the_line() {
    for (lines, line, needle) in [
        (
            vec!["d-1.0-5.pgm", "", "frames/d-1.0-6.pgm"],
            3,
            "bare file name",
        ),
        (vec!["d-1.0-5.pgm", "depth.pgm"], 2, "not <kind>"),
        (vec!["d-1.0-x.pgm"], 1, "not <kind>"),
        (vec!["x-1.0-5.pgm"], 1, "unknown kind"),
        (vec!["d-1.0-5.ppm"], 1, "unexpected extension"),
        (vec!["r-1.0-5.ppm", "a-1.0-6.dump"], 2, "no depth frame"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        recording(dir.path(), &lines, &[]);
        match FakenectSource::open(dir.path()) {
            Err(e @ SourceError::FakenectIndex { line: l, .. }) => {
                let msg = e.to_string();
                assert_eq!(l, line, "{msg}");
                assert!(msg.contains(needle) && msg.contains("INDEX.txt"), "{msg}");
            }
            other => panic!("{lines:?}: {other:?}"),
        }
    }
    // No index at all, and a listed file that is missing: I/O errors naming the file.
    let dir = tempfile::tempdir().unwrap();
    let e = FakenectSource::open(dir.path()).unwrap_err();
    assert!(matches!(e, SourceError::Io { .. }) && e.to_string().contains("INDEX.txt"));
    recording(dir.path(), &["d-1.0-5.pgm"], &[]);
    let e = FakenectSource::open(dir.path())
        .unwrap()
        .grab(T)
        .unwrap_err();
    assert!(matches!(e, SourceError::Io { .. }) && e.to_string().contains("d-1.0-5.pgm"));
}

#[test]
fn real_nyu_frame_is_a_room() {
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/nyu-kinect-fakenect"
    );
    if !Path::new(dir).join("INDEX.txt").exists() {
        println!("skipped: {dir} is absent");
        return;
    }
    let mut src = FakenectSource::open(dir).unwrap();
    let frame = src.grab(T).unwrap();
    let mut z: Vec<u16> = frame.data.iter().copied().filter(|&d| d != 0).collect();
    z.sort_unstable();
    let valid = z.len() as f32 / frame.len() as f32;
    let median = f32::from(z[z.len() / 2]) / 1000.0;
    let (near, far) = (f32::from(z[0]) / 1000.0, f32::from(z[z.len() - 1]) / 1000.0);
    println!("valid {valid:.3}, median {median} m, range {near}..{far} m");
    assert!(valid > 0.85, "{valid}");
    assert!((3.1..3.5).contains(&median), "{median}");
    assert!(near > 1.0 && far < 8.0, "{near}..{far}");
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn raw_disparity_grows_into_depth(a in 0u16..1100, b in 0u16..1100) {
        let (lo, hi) = (a.min(b), a.max(b));
        match (raw_disparity_to_m(lo), raw_disparity_to_m(hi)) {
            (Some(zl), Some(zh)) => prop_assert!(zl <= zh && zl >= 0.3 && zh <= 10.0),
            // Once out of range, stays out of range.
            (_, z) => prop_assert!(z.is_none()),
        }
    }
}
