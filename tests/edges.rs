//! Edges do not grow (issue 12): a simulated box comes out with the box's size, its faces
//! where the box's are and its base on the platform.

use voxoct::kinect::{Model, SimConfig, SimulatedKinect};
use voxoct::pipeline::{Params, reconstruct, simulate_scan};

/// A simulated scan of the built-in box with the scan example's defaults (8 snapshots of 4
/// frames, default options): how far each face of the mesh's bounding box lies beyond the
/// model's (metres; negative: inside), `[-x, +x, base, top, -z, +z]`; the share of the
/// mesh's vertices more than one leaf outside the model's box; and the leaf edge.
fn face_offsets(sim: SimConfig) -> ([f32; 6], f32, f32) {
    let mut kinect = SimulatedKinect::builtin("box", sim).expect("built-in box");
    let (config, snapshots) = simulate_scan(&mut kinect, 8, 4).expect("simulated scan");
    let r = reconstruct(&config, snapshots, &Params::default(), |_| {}).expect("reconstruction");
    r.mesh.check_closed_manifold().expect("closed");
    let b = r.mesh.stats().bounds.expect("bounds");
    let m = Model::builtin("box").unwrap().bounds().unwrap();
    let out = [
        m.min.x - b.min.x,
        b.max.x - m.max.x,
        m.min.y - b.min.y,
        b.max.y - m.max.y,
        m.min.z - b.min.z,
        b.max.z - m.max.z,
    ];
    let leaf = r.tree.leaf_edge();
    let v = &r.mesh.vertices;
    let beyond = v
        .iter()
        .filter(|p| {
            let d = (m.min - **p).max(**p - m.max);
            d.max_element() > leaf
        })
        .count();
    (out, beyond as f32 / v.len() as f32, leaf)
}

/// With exact frames, every face of the box, base included, lies within one leaf of the
/// model's. The fill's gap closing and the closure used to fill the one-cell dents of the
/// observed faces' ragged outer layer (depth rounding makes the marked shell two layers
/// thick in patches), which moved whole faces out by 1.1–1.6 mm (82.2 × 120.5 × 63.2 mm
/// for the 80 × 120 × 60 mm box).
#[test]
fn an_exact_box_keeps_its_size() {
    let (out, share, leaf) = face_offsets(SimConfig {
        seed: 1,
        exact: true,
        ..SimConfig::default()
    });
    for (face, d) in ["-x", "+x", "base", "top", "-z", "+z"].iter().zip(out) {
        assert!(
            d.abs() <= leaf,
            "{face} face {:.2} mm off: {out:?}",
            d * 1e3
        );
    }
    assert!(share == 0.0, "{share}");
}

/// With the simulated sensor's noise, the faces stay where the box's are: under 0.5 % of
/// the mesh's vertices lie more than one leaf outside the box (0.7 % before the views
/// settled the cells they disagree on, 15–16 % when the fill and the closure filled the
/// dents of the ragged outer layer, which the noise makes two or three layers deep), and
/// the base is on the platform. The bounding box itself is set by a few bumps at the
/// fringe of the noise near the vertical edges: up to 1.03 leaves out on this seed (1.0 mm
/// at 0.98 mm leaves; 2 leaves before the views settled the cells marked by a single
/// view's outlying readings, 2.4 before that).
#[test]
fn a_noisy_box_keeps_its_faces_in_place() {
    let (out, share, leaf) = face_offsets(SimConfig {
        seed: 1,
        ..SimConfig::default()
    });
    assert!(
        share < 0.005,
        "{:.2} % of the vertices beyond one leaf",
        share * 100.0
    );
    assert!(out[2].abs() <= leaf, "base {:.2} mm off", out[2] * 1e3);
    for (face, d) in ["-x", "+x", "base", "top", "-z", "+z"].iter().zip(out) {
        assert!(
            d <= 1.1 * leaf,
            "{face} face {:.2} mm out: {out:?}",
            d * 1e3
        );
    }
}
