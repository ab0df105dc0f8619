//! voxoct-core: the sparse octree and the exact triangle/box overlap test of *voxel
//! octree intersection* (J. Bennett, MSc thesis, 2014), usable on its own.
//!
//! Give it triangles (metres, `f32`) and it marks every leaf of a cubic octree that a
//! triangle touches. The marked leaves are the surface's voxels: the meshing crate turns
//! them into a closed mesh, another tool may voxelise with them, query them, or merge
//! trees built from several views or threads. No I/O, no unsafe code, dependencies:
//! `glam` (re-exported) and, behind the default feature `parallel`, `rayon`.
//!
//! # Semantics
//!
//! - **Root and depth.** [`Octree::new`]`(min, root_m, leaf_m)` covers the closed cube
//!   `min ..= min + root_m` (metres). Subdivision stops at the first depth whose node edge
//!   is `<= leaf_m`; the real leaf edge is `root_m / 2^depth` ([`Octree::leaf_edge`]), so
//!   4 mm and 5 mm leaves in a 1 m root give the same depth-8 tree (3.9 mm leaves).
//!   Leaf `(i, j, k)` spans `min + leaf_edge · (i, j, k)` to `… (i + 1, j + 1, k + 1)`
//!   ([`GridSpec`], [`Octree::leaf_grid`]); coordinates are integers, never float centres.
//! - **Marking.** A leaf is marked when the closed triangle and the closed leaf box share
//!   a point ([`intersection_test_aabb_triangle()`], Akenine-Möller's separating-axis test
//!   in `f64`, no epsilon: touching counts). [`Octree::insert`] marks *exactly* the
//!   leaves the thesis's recursive descent marks ([`Octree::insert_reference`], kept in
//!   the crate; property tests compare both). Parts outside the root are ignored.
//!   Degenerate triangles (zero area) and non-finite ones mark nothing.
//! - **Payload.** Each marked leaf counts the triangles that overlap it (`hits`) and sums
//!   the signed distance from the leaf centre to each triangle's *plane*, `n̂·(c − v0)`,
//!   positive on the side the normal points to (`sdf_sum`, see [`Cell::mean_sdf`]).
//!   Triangles from depth images are wound so that normals face the sensor (outward).
//! - **Queries.** [`Octree::leaves`] (Morton order), [`Octree::cells_at_depth`] (level of
//!   detail: a node is marked when a leaf below it is; payloads summed, so the sdf is
//!   only approximate there), [`Octree::get`], [`Octree::value_at`] (1.0 in a marked leaf,
//!   else 0.0), [`Octree::merge`], [`Octree::node_count`], [`Octree::memory_bytes`].
//! - **Parallel.** [`Octree::par_insert`] (feature `parallel`) gives a result identical
//!   to serial insertion, down to the bits of every `sdf_sum`: the root is split into
//!   `8^3` regions, a worker owns whole regions and inserts their triangles in input
//!   order (a triangle spanning regions is handled by each of them; the triangles are
//!   sorted into the regions' lists in parallel too).
//!
//! # Design
//!
//! Why the fast insertion marks exactly the leaves of the reference descent (a proof
//! sketch), and the storage layout (bricks of 4×4×4 leaves, packed payloads, 8^3
//! regions), are in ARCHITECTURE.md, section "voxoct-core"; insertion speed and bytes per
//! leaf are in BENCHMARKS.md (`cargo bench -p voxoct-core`).
//!
//! # Example
//!
//! ```
//! use voxoct_core::glam::{UVec3, Vec3};
//! use voxoct_core::{Octree, Triangle};
//!
//! // A 1 m root with 25 cm leaves: depth 2, 4×4×4 leaves.
//! let mut tree = Octree::new(Vec3::ZERO, 1.0, 0.25)?;
//! assert_eq!((tree.depth(), tree.leaf_edge()), (2, 0.25));
//!
//! // A small triangle at z = 0.1, normal +z, inside leaf (0, 0, 0).
//! let tri = Triangle::new(
//!     Vec3::new(0.05, 0.05, 0.1),
//!     Vec3::new(0.20, 0.05, 0.1),
//!     Vec3::new(0.05, 0.20, 0.1),
//! );
//! assert_eq!(tree.insert(&tri), 1);
//! let leaves: Vec<_> = tree.leaves().collect();
//! assert_eq!(leaves.len(), 1);
//! assert_eq!((leaves[0].coord, leaves[0].hits), (UVec3::ZERO, 1));
//! // The leaf centre (0.125, 0.125, 0.125) is 2.5 cm above the triangle's plane.
//! assert!((leaves[0].mean_sdf() - 0.025).abs() < 1e-6);
//! assert_eq!(tree.value_at(Vec3::new(0.1, 0.1, 0.1)), 1.0);
//! assert_eq!(tree.value_at(Vec3::new(0.9, 0.9, 0.9)), 0.0);
//!
//! // A triangle exactly on the plane x = 0.5 marks the leaves on both sides.
//! let wall = Triangle::new(
//!     Vec3::new(0.5, 0.3, 0.3),
//!     Vec3::new(0.5, 0.45, 0.3),
//!     Vec3::new(0.5, 0.3, 0.45),
//! );
//! assert_eq!(tree.insert(&wall), 2);
//! assert!(tree.get(UVec3::new(1, 1, 1)).is_some() && tree.get(UVec3::new(2, 1, 1)).is_some());
//! assert_eq!(tree.cells_at_depth(0).len(), 1);
//! assert_eq!(tree.cells_at_depth(1).len(), 2);
//! # Ok::<(), voxoct_core::OctreeError>(())
//! ```
//!
//! # Using voxoct-core alone
//!
//! ```toml
//! [dependencies]
//! voxoct-core = "0.1"   # default feature `parallel` pulls in rayon; opt out with
//!                       # default-features = false
//! ```
//!
//! ```
//! use voxoct_core::glam::Vec3;
//! use voxoct_core::{Aabb, Octree, Triangle};
//!
//! # fn main() -> Result<(), voxoct_core::OctreeError> {
//! // Any triangle soup in metres, e.g. from your own depth-image triangulation.
//! let tris = vec![
//!     Triangle::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.1, 0.0)),
//!     Triangle::new(Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.1, 0.1, 0.0), Vec3::new(0.0, 0.1, 0.0)),
//! ];
//! // A root that encloses the data, with exactly 5 mm leaves.
//! let bounds = tris.iter().map(Triangle::aabb).reduce(|a, b| Aabb::new(a.min.min(b.min), a.max.max(b.max)));
//! let mut tree = Octree::enclosing(bounds.unwrap(), 0.005)?;
//! tree.insert_all(&tris); // or `tree.par_insert(&tris)` with the `parallel` feature
//! println!("{} leaves, {} bytes", tree.leaf_count(), tree.memory_bytes());
//! for cell in tree.leaves() {
//!     let centre = tree.leaf_grid().cell_center(cell.coord);
//!     let _ = (centre, cell.hits, cell.mean_sdf());
//! }
//! // The 10 cm square at z = 0 covers 20 × 20 leaves, and touches the layer below too.
//! assert!(tree.leaf_count() >= 400);
//! # Ok(())
//! # }
//! ```

pub use glam;

mod error;
mod geometry;
mod intersection_test_aabb_triangle;
mod octree;

pub use error::OctreeError;
pub use geometry::{
    Aabb, Cell, GridSpec, HALF_CELL_DIAGONAL, Real, Seen, Triangle, vertex_normals,
};
pub use intersection_test_aabb_triangle::intersection_test_aabb_triangle;
pub use octree::{MAX_DEPTH, Octree};
