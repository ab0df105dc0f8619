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
//! - **Root and depth.** [`Octree::new`]`(min, edge, leaf_size)` covers the closed cube
//!   `min ..= min + edge`. Subdivision stops at the first depth whose node edge is
//!   `<= leaf_size`; the real leaf edge is `edge / 2^depth` ([`Octree::leaf_edge`]), so
//!   4 mm and 5 mm leaves in a 1 m root give the same depth-8 tree (3.9 mm leaves).
//!   Leaf `(i, j, k)` spans `min + leaf_edge · (i, j, k)` to `… (i + 1, j + 1, k + 1)`
//!   ([`GridSpec`], [`Octree::leaf_grid`]); coordinates are integers, never float centres.
//! - **Marking.** A leaf is marked when the closed triangle and the closed leaf box share
//!   a point ([`intersection_test_aabb_triangle`], Akenine-Möller's separating-axis test
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
//! # Why the fast path marks exactly the reference's leaves
//!
//! Every box corner is computed as `min + i · cell` in `f32` with the cell edge an exact
//! power-of-two fraction of the root edge, so a node's box has bit for bit the corners of
//! the union of its children. The overlap test compares projections computed with one
//! fixed formula whose rounding is monotone in the box corners, so a box that contains an
//! accepted box is accepted too. Hence pruning a rejected node can never lose a leaf, and
//! the recursive descent marks exactly the leaves whose own box passes the test. The fast
//! path takes the leaf cells of the triangle's bounding box (clamped to the root; the
//! candidate range *is* the test's three box axes) as one block of at most 4×4×4 cells
//! (2×2×2 such blocks up to 8 cells per axis; larger ranges are halved after testing
//! the whole range's box, exact by the same monotonicity) and decides the ten other
//! axes for all its cells at once with the very same `f64` products, sums and
//! comparisons. The block is padded to 2 or 4 cells per axis so that every loop has a
//! fixed length (the padding cells are dropped). An edge axis acts on two coordinates
//! only, so it is decided once per column of cells, and since its sums are monotone in
//! the cell index (so is `f64` rounding) an edge axis that does not separate the
//! block's most exposed cell separates none and is not evaluated cell by cell. A marked
//! leaf's sdf is `(x + y) + z` of per-axis terms: the operations of the reference's dot
//! product, in the same order.
//!
//! # Storage
//!
//! A sparse octree, compact:
//!
//! - the top 3 levels are a dense table of `8^3` region slots (8 bytes each when empty);
//! - each region is a sparse subtree of interior nodes, each a record of eight `u32`
//!   child indices into a per-region pool (32 bytes; no pointers);
//! - its lowest level are **bricks** of 4×4×4 leaves: a `u64` occupancy mask in Morton
//!   order, a `u32` offset and a size class (16 bytes);
//! - the leaves' payloads (`hits: u32`, `sdf_sum: f32`, 8 bytes) are packed per brick in
//!   the order of the mask's set bits, in blocks of 2, 4, 6, 8, 12, … 64 entries that are
//!   recycled through free lists when a brick grows; pools grow by ~25 %, not 100 %.
//!
//! A batch (`insert_all`, `extend`, `par_insert`) works on a scratch copy of the bricks
//! it touches, each expanded to 64 payloads so that adding a triangle to a leaf is a
//! plain add, and packs them back when it returns (or midway, past 4096 expanded bricks
//! in a region, 2 MiB); the scratch is gone between calls, so the figures below are the
//! resting size. A single `insert` writes straight into the packed storage.
//!
//! Measured on the bench snapshot (a 640×480 depth image, f = 580 px, of a 7.5 cm-radius
//! sphere at 0.7 m: 23 976 triangles with 1–2 mm edges; 1 m root, 1 mm leaf size →
//! depth 10, 0.977 mm leaves): **43 762 leaves, 58 749 nodes, 537 168 bytes = 12.3 bytes
//! per marked leaf**, everything included (a pointer octree would need 64+ bytes per
//! node).
//!
//! Speed (`cargo bench -p voxoct-core`, on a shared 2-core VM whose speed drifts by
//! up to 50 % from minute to minute: the figures are CPU time of the working threads,
//! and instruction counts by callgrind, which do not drift): the one-shot overlap test
//! 48–72 ns per call; serial `insert_all` **~2 590 instructions per triangle, 0.20–0.26
//! µs of CPU in calm minutes** (0.33 µs in busy ones), tree construction included (down
//! from ~3 760 instructions and 0.41 µs with one packed update per leaf). Per triangle
//! there are ~13 candidate cells and ~7 marked leaves; ~1 030 instructions go to the
//! setup of the edge axes, the candidate range and the dispatch, ~750 to the exact
//! block test and ~800 to the payload updates and the bricks' expansion. One `insert`
//! call per triangle (straight into the packed storage) costs ~0.28 µs; the reference
//! descent ~3 µs. `par_insert` partitions the triangles in parallel (~7 % more
//! instructions in all); on the snapshot (4 equal regions) the busiest of 2 threads
//! does about half the work of one (0.17–0.22 µs of CPU per triangle).
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
pub use geometry::{Aabb, Cell, GridSpec, Real, Triangle};
pub use intersection_test_aabb_triangle::intersection_test_aabb_triangle;
pub use octree::{MAX_DEPTH, Octree};
