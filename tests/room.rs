//! A real room-sized scene: the NYU Depth v2 Kinect frame of `../shared/data` with a clip box
//! of 6 × 6 × 4.6 m meshes closed at 5 mm and at 2 mm leaves within a bounded memory (the
//! closure of unseen space on a coarser grid past its budget, the solid fill in tiles, a
//! march whose buffers follow the surface, smoothing and simplification piece by piece); so
//! does a tabletop-sized box of the same frame (1.0 × 0.9 × 0.7 m) at 1 mm, the scene a dense
//! fill of the clip box refused (630 million cells).

use std::sync::Mutex;
use std::time::Duration;

use voxoct::core::glam::Vec3;
use voxoct::depth::{ClipBox, ScannerConfig};
use voxoct::kinect::{DepthSource, FakenectSource};
use voxoct::pipeline::{Params, SnapshotFrames, reconstruct};

/// The room's scanner settings (the NYU toolbox's intrinsics, the sensor at the origin
/// looking down −z, no tilt): the one file `.ci/live_scan.sh` and the figures also read.
const ROOM: &str = include_str!("../examples/nyu-room.toml");

/// The tests run one at a time: the peak they check is the process's.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Meshes the room (or, with `clip`, that box of it) at `leaf_m` leaves under a root of
/// `root_m`; checks the mesh is closed, has more than `min_triangles`, and the process's
/// peak resident memory is under 1 GiB.
fn room_in_bounded_memory(leaf_m: f32, root_m: f32, min_triangles: usize, clip: Option<ClipBox>) {
    let _one = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/nyu-kinect-fakenect"
    );
    let mut config = ScannerConfig::from_toml_str(ROOM, "examples/nyu-room.toml".as_ref()).unwrap();
    if let Some(clip) = clip {
        config.clip = clip;
    }
    let mut source = FakenectSource::open(dir)
        .and_then(|s| s.with_intrinsics(config.sensor.intrinsics))
        .unwrap();
    let frame = source.grab(Duration::from_secs(1)).unwrap();
    let snapshots = vec![SnapshotFrames {
        angle_deg: 0.0,
        frames: vec![frame],
    }];
    let params = Params {
        leaf_m,
        root_m,
        ..Params::default()
    };
    let r = reconstruct(&config, snapshots, &params, |_| {}).expect("the room meshes");
    assert!((r.tree.leaf_grid().cell - leaf_m).abs() < 1e-6);
    assert!(
        r.mesh.triangles.len() > min_triangles,
        "{}",
        r.mesh.triangles.len()
    );
    r.mesh.check_closed_manifold().expect("closed");
    assert!(
        r.self_intersection_free,
        "proven free of self-intersections"
    );
    // 0 where the platform does not say.
    let peak = voxoct::budget::peak_rss_bytes();
    if peak > 0 {
        assert!(
            peak < 1 << 30,
            "peak resident memory {peak} bytes, over 1 GiB"
        );
    }
}

#[test]
#[ignore = "needs ../shared/data"]
fn nyu_room_meshes_closed_at_5_mm_in_bounded_memory() {
    // 10.24 m / 2^11 = 5 mm leaves; the box the closure and the fill would hold densely is
    // about 10^9 cells (the fill refused it, the closure took 6.5 GB before it worked on a
    // coarser grid).
    room_in_bounded_memory(0.005, 10.24, 100_000, None);
}

#[test]
#[ignore = "needs ../shared/data"]
fn nyu_room_meshes_closed_at_2_mm_in_bounded_memory() {
    // 8.192 m / 2^12 = 2 mm leaves: 24 million marched triangles, smoothed and simplified
    // piece by piece (3.8 GB peak when done whole).
    room_in_bounded_memory(0.002, 8.192, 1_000_000, None);
}

#[test]
#[ignore = "needs ../shared/data"]
fn a_tabletop_sized_box_of_the_room_meshes_closed_at_1_mm_in_bounded_memory() {
    // The floor and what stands on it 2.6–3.3 m in front of the sensor, 1.0 × 0.9 × 0.7 m:
    // the size of issue 14's tabletop capture, 1.024 m / 2^10 = 1 mm leaves.
    let clip = ClipBox {
        min: Vec3::new(-0.5, -1.2, -3.3),
        max: Vec3::new(0.5, -0.3, -2.6),
    };
    room_in_bounded_memory(0.001, 1.024, 50_000, Some(clip));
}
