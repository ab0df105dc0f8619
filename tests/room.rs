//! A real room-sized scene: the NYU Depth v2 Kinect frame of `../shared/data` with a clip box
//! of 6 × 6 × 4.6 m meshes closed at 5 mm leaves within a bounded memory (the closure of
//! unseen space on a coarser grid past its budget, the solid fill in tiles).

use std::time::Duration;

use voxoct::depth::ScannerConfig;
use voxoct::kinect::{DepthSource, FakenectSource};
use voxoct::pipeline::{Params, SnapshotFrames, reconstruct};

/// The room's scanner settings: the sensor at the origin looking down −z, no tilt.
const ROOM: &str = r"
[sensor]
width = 640
height = 480
fx = 580.0
fy = 580.0
cx = 319.5
cy = 239.5
depth_unit_m = 0.001

[rig]
tilt_deg = 0.0
sensor_position_m = [0.0, 0.0, 0.0]

[clip]
min_m = [-3.0, -3.0, -5.0]
max_m = [3.0, 3.0, -0.4]
";

/// This process's peak resident memory, bytes (Linux), if known.
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[test]
#[ignore = "needs ../shared/data"]
fn nyu_room_meshes_closed_at_5_mm_in_bounded_memory() {
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/nyu-kinect-fakenect"
    );
    let config = ScannerConfig::from_toml_str(ROOM, "room.toml".as_ref()).unwrap();
    let mut source = FakenectSource::open(dir)
        .and_then(|s| s.with_intrinsics(config.sensor.intrinsics))
        .unwrap();
    let frame = source.grab(Duration::from_secs(1)).unwrap();
    let snapshots = vec![SnapshotFrames {
        angle_deg: 0.0,
        frames: vec![frame],
    }];
    // 10.24 m / 2^11 = 5 mm leaves; the box the closure and the fill would hold densely is
    // about 10^9 cells (the fill refused it, the closure took 6.5 GB before this change).
    let params = Params {
        leaf_m: 0.005,
        root_m: 10.24,
        ..Params::default()
    };
    let r = reconstruct(&config, snapshots, &params, |_| {}).expect("the room meshes");
    assert!((r.tree.leaf_grid().cell - 0.005).abs() < 1e-6);
    assert!(
        r.mesh.triangles.len() > 100_000,
        "{}",
        r.mesh.triangles.len()
    );
    r.mesh.check_closed_manifold().expect("closed");
    if let Some(peak) = peak_rss_bytes() {
        assert!(
            peak < 1 << 30,
            "peak resident memory {peak} bytes, over 1 GiB"
        );
    }
}
