//! Signed-distance placement on a surface whose marked cells form a ragged outer layer (as
//! depth noise and rounding make them): the fill's gap closing must not fill the dents of
//! that layer and move the surface out by a cell.

use voxoct_core::glam::Vec3;
use voxoct_core::{Aabb, Octree, Triangle};
use voxoct_mesh::{MeshOptions, mesh_octree};

/// An axis-aligned box from `lo` to `hi` as 12 outward-facing triangles.
fn cuboid(lo: Vec3, hi: Vec3) -> Vec<Triangle> {
    Aabb::new(lo, hi).surface_triangles().to_vec()
}

/// A box (with a slit in one side) whose top face (y = 40.7 mm, in the layer of cells
/// 40..41 mm) carries, on every other cell of the layer above in x and z, a small patch of
/// surface 0.5 mm higher: the layer above is marked in patches, its cells' centres outside
/// the patches. The solid's top stays on the face: the cells between the patches, which the
/// gap closing encloses, lie above the observed face and count as outside. It used to rise
/// to 42 mm, between the layer above and the next.
#[test]
fn dents_of_a_ragged_layer_stay_outside() {
    let leaf = 0.001;
    let top = 0.0407;
    let (lo, hi) = (
        Vec3::new(0.0203, 0.0203, 0.0203),
        Vec3::new(0.0603, top, 0.0503),
    );
    // A slit through the -x face, one cell wide, as scans leave them: the fill closes it by its
    // gap closing, which also closes one-cell dents.
    let mut tris: Vec<Triangle> = cuboid(lo, hi)
        .into_iter()
        .filter(|t| t.v.iter().any(|p| p.x != lo.x))
        .collect();
    for (z0, z1) in [(lo.z, 0.0341), (0.0369, hi.z)] {
        let q = [
            Vec3::new(lo.x, lo.y, z0),
            Vec3::new(lo.x, lo.y, z1),
            Vec3::new(lo.x, hi.y, z1),
            Vec3::new(lo.x, hi.y, z0),
        ];
        tris.push(Triangle::new(q[0], q[1], q[2]));
        tris.push(Triangle::new(q[0], q[2], q[3]));
    }
    let y = top + 0.0005;
    for i in (21..60).step_by(2) {
        for k in (21..50).step_by(2) {
            let (x0, z0) = (i as f32 * leaf + 0.0001, k as f32 * leaf + 0.0001);
            let (x1, z1) = (x0 + 0.0008, z0 + 0.0008);
            // Normal +y: counter-clockwise seen from above.
            let a = Vec3::new(x0, y, z0);
            let b = Vec3::new(x0, y, z1);
            let c = Vec3::new(x1, y, z1);
            let d = Vec3::new(x1, y, z0);
            tris.push(Triangle::new(a, b, c));
            tris.push(Triangle::new(a, c, d));
        }
    }
    let mut tree = Octree::new(Vec3::ZERO, 0.128, leaf).unwrap();
    tree.insert_all(&tris);
    let opts = MeshOptions {
        smoothing: None,
        close_gaps: 1,
        ..MeshOptions::smooth()
    };
    let mesh = mesh_octree(&tree, &opts).unwrap();
    mesh.check_closed_manifold().unwrap();
    let s = mesh.stats();
    assert_eq!(s.components, 1, "{s:?}");
    let b = s.bounds.unwrap();
    assert!((b.max.y - top).abs() < 0.4 * leaf, "top at {} m", b.max.y);
}
