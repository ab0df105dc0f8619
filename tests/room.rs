//! A real room-sized scene: the NYU Depth v2 Kinect frame of `../shared/data` with a clip box
//! of 6 × 6 × 4.6 m meshes closed at 5 mm leaves within a bounded memory (the closure of
//! unseen space on a coarser grid past its budget, the solid fill in tiles).

use std::time::Duration;

use voxoct::depth::ScannerConfig;
use voxoct::kinect::{DepthSource, FakenectSource};
use voxoct::pipeline::{Params, SnapshotFrames, reconstruct};

/// The room's scanner settings: the NYU toolbox's intrinsics (as `.ci/live_scan.sh` uses),
/// the sensor at the origin looking down −z, no tilt.
const ROOM: &str = r"
[sensor]
width = 640
height = 480
fx = 582.62
fy = 582.69
cx = 313.04
cy = 238.44
depth_unit_m = 0.001

[rig]
tilt_deg = 0.0
sensor_position_m = [0.0, 0.0, 0.0]

[clip]
min_m = [-3.0, -3.0, -5.0]
max_m = [3.0, 3.0, -0.4]
";

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
    // 0 where the platform does not say.
    let peak = voxoct::budget::peak_rss_bytes();
    if peak > 0 {
        assert!(
            peak < 1 << 30,
            "peak resident memory {peak} bytes, over 1 GiB"
        );
    }
}
