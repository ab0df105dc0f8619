//! The closure of unseen space on simulated scans of shapes with openings: what the views
//! saw as empty stays empty, the rest is closed by the smallest surface, and the mesh is
//! closed either way.

use voxoct::depth::ScannerConfig;
use voxoct::kinect::{Model, SimConfig, SimulatedKinect};
use voxoct::mesh::MeshOptions;
use voxoct::pipeline::{Params, SnapshotFrames, reconstruct, simulate_scan};

fn simulate(model: &str, n: u32) -> (ScannerConfig, Vec<SnapshotFrames>) {
    let sim = SimConfig {
        seed: 11,
        ..SimConfig::default()
    };
    let mut kinect = SimulatedKinect::builtin(model, sim).expect("built-in model");
    simulate_scan(&mut kinect, n, 2).expect("simulated scan")
}

fn volume_ratio(model: &str, leaf: f32) -> (f64, voxoct::mesh::Mesh) {
    let (config, snapshots) = simulate(model, 8);
    let params = Params {
        leaf_m: leaf,
        mesh: MeshOptions::smooth(),
        ..Params::default()
    };
    let r = reconstruct(&config, snapshots, &params, |_| {}).expect("reconstruction");
    r.mesh
        .check_closed_manifold()
        .unwrap_or_else(|e| panic!("{model}: not closed: {e}"));
    let want = f64::from(Model::builtin(model).unwrap().signed_volume());
    (r.mesh.stats().volume / want, r.mesh)
}

/// An upright ring: its hole is seen through from most views and stays open (filling it
/// would add about 29 % to the volume), and the wedge under the ring on the platform, which
/// no view sees, is closed by a small cap: one piece, volume within 5 % of the ring's.
#[test]
fn a_ring_on_its_rim_keeps_its_hole_open() {
    let (ratio, mesh) = volume_ratio("torus", 0.0015);
    assert!((ratio - 1.0).abs() < 0.05, "volume ratio {ratio}");
    assert_eq!(mesh.stats().components, 1);
}

/// A box keeps its height: its base is closed by the cut within the clip box's 3 mm margin
/// above the platform (where no triangle marks it), not above it, and its top is within two
/// leaves of the truth.
#[test]
fn a_box_stands_on_the_platform() {
    let (config, snapshots) = simulate("box", 8);
    let r = reconstruct(&config, snapshots, &Params::default(), |_| {}).expect("reconstruction");
    let leaf = r.tree.leaf_edge();
    let b = r.mesh.stats().bounds.expect("bounds");
    let model = Model::builtin("box").unwrap().bounds().unwrap();
    assert!(
        b.min.y >= -leaf && b.min.y <= config.clip.min.y,
        "base at {} m",
        b.min.y
    );
    assert!(
        (b.max.y - model.max.y).abs() <= 2.0 * leaf,
        "top at {} vs {}",
        b.max.y,
        model.max.y
    );
}
