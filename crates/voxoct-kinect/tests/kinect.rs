//! The live Kinect source without a device: opening fails fast and clearly.
#![cfg(feature = "freenect")]

use std::time::{Duration, Instant};

use voxoct_kinect::{KinectSource, SourceError};

#[test]
fn opening_without_a_device_is_a_clear_error() {
    let start = Instant::now();
    match KinectSource::open(0) {
        Err(e @ SourceError::NoKinect { index: 0, .. }) => {
            assert!(KinectSource::library_available());
            let msg = e.to_string();
            assert!(
                msg.contains("no Kinect v1 found") && msg.contains("USB"),
                "{msg}"
            );
        }
        Err(SourceError::FreenectUnavailable) => assert!(!KinectSource::library_available()),
        Err(other) => panic!("unexpected error: {other}"),
        Ok(_) => {
            println!("a Kinect is attached: nothing to check here");
            return;
        }
    }
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );
    assert!(matches!(
        KinectSource::open(-1),
        Err(SourceError::Config { field: "index", .. })
    ));
}

/// Set in the child process that runs under the fakenect library.
const CHILD: &str = "VOXOCT_FAKENECT_CHILD";

/// The directory of libfreenect's fakenect library (Debian: libfreenect0.5), if installed.
fn fakenect_lib_dir() -> Option<std::path::PathBuf> {
    let mut dirs: Vec<_> = std::fs::read_dir("/usr/lib")
        .ok()?
        .filter_map(|e| Some(e.ok()?.path().join("fakenect")))
        .filter(|d| d.join("libfreenect.so.0.5").exists())
        .collect();
    dirs.sort();
    dirs.into_iter().next()
}

/// The real libfreenect_sync calls of `KinectSource`, answered by libfreenect's fakenect
/// library replaying a recording our `FakenectWriter` wrote: in raw mode every frame equals
/// what our own `FakenectSource` reads from it (one disparity model), after the one frame that
/// opening consumes. The library must be loaded at process start (`LD_LIBRARY_PATH`), so the
/// test runs itself again as a child process.
#[test]
fn raw_frames_under_the_fakenect_library_equal_our_replay() {
    use voxoct_kinect::{DepthSource, FakenectSource, FakenectWriter, KinectDepth, KinectOptions};
    const GRABBED: usize = 3;
    if let Some(dir) = std::env::var_os(CHILD) {
        // The child: FAKENECT_PATH and LD_LIBRARY_PATH are set.
        let refused = KinectSource::open(0).unwrap_err();
        assert!(
            matches!(refused, SourceError::Config { field: "depth", .. }),
            "{refused}"
        );
        let options = KinectOptions {
            depth: KinectDepth::Raw,
            verbose: false,
        };
        let mut kinect = KinectSource::open_with(0, options).unwrap();
        let mut ours = FakenectSource::open(&dir).unwrap();
        ours.grab(Duration::from_secs(1)).unwrap(); // the frame opening consumed
        for i in 0..GRABBED {
            let live = kinect.grab(Duration::from_secs(10)).unwrap();
            let want = ours.grab(Duration::from_secs(1)).unwrap();
            assert_eq!((live.width, live.height, live.unit_m), (640, 480, 0.001));
            assert!(live.data == want.data, "frame {i} differs");
        }
        kinect.shutdown().unwrap();
        println!("child: {GRABBED} frames equal");
        return;
    }
    let Some(lib) = fakenect_lib_dir() else {
        println!("skipped: no fakenect library under /usr/lib/*/fakenect (libfreenect0.5)");
        return;
    };
    if !KinectSource::library_available() {
        println!("skipped: built without libfreenect");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    let mut w = FakenectWriter::create(&rec, Duration::from_millis(300)).unwrap();
    // 1 consumed on opening, GRABBED grabbed, 3 to spare: each frame its own pattern.
    for k in 0..(1 + GRABBED + 3) as u16 {
        let raw: Vec<u16> = (0..640 * 480u32)
            .map(|i| ((i % 640) as u16 + 97 * k) % 1100)
            .collect();
        w.add_raw(&raw).unwrap();
    }
    w.finish().unwrap();
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "raw_frames_under_the_fakenect_library_equal_our_replay",
            "--exact",
            "--nocapture",
        ])
        .env(CHILD, &rec)
        .env("FAKENECT_PATH", &rec)
        .env("LD_LIBRARY_PATH", &lib)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("the child under fakenect hung");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(stdout.contains("child: 3 frames equal"), "{stdout}");
}
