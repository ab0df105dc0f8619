//! Meshes for other tools: the print frame (Z up) and per-vertex confidence from the octree.

use voxoct_core::Octree;
use voxoct_core::glam::{DVec3, UVec3, Vec3};

use crate::Mesh;
use crate::par;

/// The rotation from the platform frame to the print frame, `(x, y, z) → (x, −z, y)`: the
/// right-handed rotation by +90° about +X (determinant +1, no mirroring), exact in `f32`.
///
/// The platform frame (see `SCAN_FORMAT.md`) has +Y up along the turntable axis and +Z
/// towards the sensor; slicers and most viewers take +Z as up with the bed in the XY plane.
/// Up (+Y) becomes +Z, and the side that faced the sensor at angle 0 (+Z) becomes −Y, the
/// front of the bed as PrusaSlicer and Cura show it.
#[inline]
#[must_use]
pub fn platform_to_print(v: Vec3) -> Vec3 {
    Vec3::new(v.x, -v.z, v.y)
}

/// The mesh in the print frame, as written for printing: rotated by [`platform_to_print`],
/// then moved so that its bounding box is centred on the origin in x and y and its lowest
/// point is at z = 0 (the base on the bed).
///
/// A proper rotation and a translation keep the winding, so triangles stay counter-clockwise
/// seen from outside, normals point out and the enclosed volume stays positive; the
/// triangles are unchanged. Each coordinate is computed in `f64` and rounded to `f32` once.
///
/// ```
/// use voxoct_mesh::{Mesh, glam::Vec3, to_print_frame};
/// // A tetrahedron standing on the platform, its apex up (+Y), outward wound.
/// let mesh = Mesh {
///     vertices: vec![
///         Vec3::new(0.0, 0.0, 0.0),
///         Vec3::new(0.02, 0.0, 0.0),
///         Vec3::new(0.0, 0.0, 0.02),
///         Vec3::new(0.0, 0.03, 0.0),
///     ],
///     triangles: vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
/// };
/// assert!(mesh.volume() > 0.0);
/// let print = to_print_frame(&mesh);
/// let b = print.stats().bounds.unwrap();
/// assert_eq!((b.min.z, b.max.z), (0.0, 0.03)); // the height is along z now
/// assert_eq!((b.min.x + b.max.x, b.min.y + b.max.y), (0.0, 0.0));
/// assert!((print.volume() - mesh.volume()).abs() < 1e-12);
/// ```
#[must_use]
pub fn to_print_frame(mesh: &Mesh) -> Mesh {
    Mesh {
        vertices: print_frame_vertices(&mesh.vertices),
        triangles: mesh.triangles.clone(),
    }
}

/// The vertices of [`to_print_frame`] alone, for writers that borrow the triangles of the
/// original mesh instead of copying them (the triangles do not change).
#[must_use]
pub fn print_frame_vertices(vertices: &[Vec3]) -> Vec<Vec3> {
    let Some(&first) = vertices.first() else {
        return Vec::new();
    };
    let p0 = platform_to_print(first);
    let (lo, hi) = vertices.iter().fold((p0, p0), |(lo, hi), &v| {
        let p = platform_to_print(v);
        (lo.min(p), hi.max(p))
    });
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    let offset = DVec3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), lo.z);
    let mut out = Vec::new();
    par::map_into(&mut out, vertices.len(), |i| {
        (platform_to_print(vertices[i]).as_dvec3() - offset).as_vec3()
    });
    out
}

/// A confidence for every vertex of a mesh made from `octree` (vertices in the octree's
/// frame, i.e. the platform frame, before [`to_print_frame`]): the largest hit count among
/// the 2 × 2 × 2 leaves whose centres surround the vertex (the cells of the pseudo-voxel it
/// lies in), 0 where none of them is marked (e.g. a base filled where no frame looked).
///
/// Eight octree look-ups per vertex.
#[must_use]
pub fn vertex_hits(octree: &Octree, vertices: &[Vec3]) -> Vec<u32> {
    let g = octree.leaf_grid();
    let res = g.resolution as i64;
    let mut out = Vec::new();
    par::map_into(&mut out, vertices.len(), |i| {
        let p = vertices[i];
        if !p.is_finite() {
            return 0;
        }
        // The leaf whose centre is the pseudo-voxel's minimum corner.
        let base = ((p - g.origin) / g.cell - Vec3::splat(0.5)).floor();
        let mut best = 0;
        for k in 0..8u32 {
            let c = [
                base.x as i64 + i64::from(k & 1),
                base.y as i64 + i64::from((k >> 1) & 1),
                base.z as i64 + i64::from(k >> 2),
            ];
            if c.iter().all(|&x| (0..res).contains(&x))
                && let Some(cell) = octree.get(UVec3::new(c[0] as u32, c[1] as u32, c[2] as u32))
            {
                best = best.max(cell.hits);
            }
        }
        best
    });
    out
}
