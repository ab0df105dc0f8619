//! voxoct-mesh: closed, oriented meshes from the marked cells of a voxoct octree.
//!
//! # Method (J. Bennett's thesis, §3.4)
//! A *pseudo-voxel* is the cube whose eight corners are the centres of eight neighbouring
//! cells; a corner's value is 1 where the cell is marked and 0 elsewhere (unmarked or outside
//! the grid). Every pseudo-voxel that has a marked corner is generated exactly once, keyed by
//! the integer coordinates of its minimum corner (never by a float centre), and split into the
//! same six tetrahedra around its main diagonal, so that neighbouring cubes agree on their
//! shared faces. Marching tetrahedra places one vertex on every tetrahedron edge whose ends
//! differ, welded by the edge's integer key, and emits one or two triangles per tetrahedron,
//! oriented by a table that is proved correct once (see the `tables` module source): normals
//! point out of the marked region.
//!
//! # The guarantee
//! The six-tetrahedron split of every cube is one simplicial complex (the Kuhn/Freudenthal
//! triangulation) and inside-ness is a strict binary predicate on its vertices, so the surface
//! is the boundary of a union of closed simplex pieces: for **any** set of cells the result is
//! a closed, oriented 2-manifold — no hole, every edge in exactly two triangles with opposite
//! directions, every vertex's fan a single disc (cells that touch only diagonally are joined
//! along Kuhn diagonals or cleanly separated, never pinched), no degenerate triangle, and a
//! positive enclosed volume. [`Mesh::check_closed_manifold`] checks all of this and names what
//! is wrong; the test suite runs it over random cell sets with every option.
//!
//! The surface also does not cut through itself, so it is the boundary of a solid (what CAD
//! kernels, boolean libraries and slicers call watertight): with every vertex strictly inside
//! its edge, each tetrahedron's piece lies in that tetrahedron and meets a neighbour's only in
//! their common vertices and edges on the shared face. Taubin smoothing can break this where
//! two sheets are a cell or two apart, so after smoothing the vertices of any offending
//! triangle are moved back toward their unsmoothed positions (halfway, then further) until the
//! exact test [`self_intersecting_triangles`] finds none. [`Mesh::check_valid_solid`] checks
//! both properties; the test suite runs it over random cell sets, noisy thin shapes and every
//! option.
//!
//! # Beyond the thesis ([`MeshOptions`])
//! - `min_hits`: cells hit by fewer triangles count as unmarked.
//! - `min_component_cells`: isolated blobs of fewer cells are dropped.
//! - `solid` with a [`Floor`]: flood-fill the outside and fill what it cannot reach, so the
//!   double-walled shell becomes one solid with a flat base where the sensor never looked.
//! - [`closure`]: decide the cells no view saw with a minimum cut between the cells seen
//!   empty and the solid ones, each invented face priced by its distance from the nearest
//!   observation, so the unseen space is closed next to what was seen rather than across open
//!   space (a depth-scanning front end classifies the cells, e.g.
//!   `voxoct_depth::carve::visibility`).
//! - [`Placement::SignedDistance`]: vertices slide along their edges to where the mean signed
//!   distance stored in each [`Cell`] says the surface is; with `solid` the wall sits on the
//!   surface itself rather than half a cell outside the outermost marked cells.
//! - [`Taubin`] smoothing: volume-preserving, positions only.
//! - [`simplify()`]: quadric-error edge collapse bounded by a geometric error, keeping the mesh
//!   closed, manifold and free of new self-intersections (see [`Simplify`]).
//!
//! [`MeshOptions::default`] is [`MeshOptions::smooth`], the most accurate combination and
//! what the `scan` example uses; [`MeshOptions::thesis`] is the thesis's method. Why, with
//! the accuracy of each combination (`tests/accuracy.rs`), how marching stays fast (8×8×8
//! bricks, bit-parallel edges, prefix-sum vertex numbering, a bit-box flood fill) and the
//! design of the self-intersection test and simplification: ARCHITECTURE.md, section
//! "voxoct-mesh". Speed: BENCHMARKS.md (`cargo bench -p voxoct-mesh`). With the default
//! `parallel` feature, smoothing, [`Mesh::check_closed_manifold`] and the piece counts use
//! every core (rayon), with results identical to one thread.
//!
//! ```
//! use voxoct_mesh::{Cell, GridSpec, MeshOptions, glam::{UVec3, Vec3}, mesh_cells};
//!
//! let grid = GridSpec { origin: Vec3::ZERO, cell: 0.001, resolution: 16 };
//! let cell = Cell { coord: UVec3::new(3, 4, 5), hits: 1, sdf_sum: 0.0 };
//! let mesh = mesh_cells(&[cell], &grid, &MeshOptions::thesis()).unwrap();
//! // One cell: a vertex on each of its 14 Kuhn edges, one triangle per tetrahedron around it.
//! assert_eq!((mesh.vertices.len(), mesh.triangles.len()), (14, 24));
//! mesh.check_closed_manifold().unwrap();
//! let stats = mesh.stats();
//! assert!(stats.volume > 0.0 && stats.components == 1);
//! ```

pub use voxoct_core::glam;
pub use voxoct_core::{Cell, GridSpec, Octree};

mod bitbox;
pub mod closure;
mod collide;
mod export;
mod fans;
mod field;
mod march;
mod mesh;
mod options;
mod par;
mod selfx;
mod simplify;
mod smooth;
mod tables;

pub use export::{platform_to_print, print_frame_vertices, to_print_frame, vertex_hits};
pub use field::FILL_LIMIT;
pub use mesh::{Mesh, MeshStats, TopologyError};
pub use options::{Floor, MeshError, MeshOptions, Placement, Taubin};
pub use selfx::{self_intersecting_triangles, triangles_intersect};
pub use simplify::{
    MAX_NORMAL_TURN_DEG, MAX_RETRIES, MIN_QUALITY, MIN_QUALITY_ABSOLUTE, Simplify, SimplifyStats,
    simplify,
};

/// Meshes marked cells of one grid (e.g. an octree's leaves and its leaf grid).
///
/// `cells` may come in any order; a coordinate given twice keeps the later cell. Cells with
/// `hits == 0` are unmarked.
///
/// # Errors
/// [`MeshError::CellOutsideGrid`], [`MeshError::InvalidArgument`],
/// [`MeshError::FillTooLarge`].
pub fn mesh_cells(cells: &[Cell], grid: &GridSpec, opts: &MeshOptions) -> Result<Mesh, MeshError> {
    Ok(mesh_cells_certified(cells, grid, opts)?.0)
}

/// As [`mesh_cells`], and whether the mesh is *proven* free of self-intersections: with
/// smoothing on, the untangling step runs the exact test of [`Mesh::self_intersecting_triangles`]
/// over every triangle and leaves none, so a caller that reports validity need not run it
/// again. `false` means "not checked here" (no smoothing, or smoothing undone), not that
/// the mesh has intersections: run the check then.
///
/// # Errors
/// As [`mesh_cells`].
pub fn mesh_cells_certified(
    cells: &[Cell],
    grid: &GridSpec,
    opts: &MeshOptions,
) -> Result<(Mesh, bool), MeshError> {
    let mut mesh = Mesh::default();
    let certified = Mesher::new().run(cells, grid, opts, &mut mesh, false)?;
    Ok((mesh, certified))
}

/// A reusable mesher: keeps its working buffers (and the caller keeps the output [`Mesh`])
/// from one call to the next, so meshing repeatedly allocates nothing once warm.
#[derive(Debug, Default)]
pub struct Mesher {
    scratch: march::Scratch,
}

impl Mesher {
    /// A mesher with empty buffers.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// As [`mesh_cells`], into `out` (cleared first, capacity kept).
    ///
    /// # Errors
    /// As [`mesh_cells`]; `out` is then empty.
    pub fn mesh_cells_into(
        &mut self,
        cells: &[Cell],
        grid: &GridSpec,
        opts: &MeshOptions,
        out: &mut Mesh,
    ) -> Result<(), MeshError> {
        self.run(cells, grid, opts, out, true).map(|_| ())
    }

    /// Meshes into `out`; without `keep`, the working buffers are freed before smoothing
    /// (lower peak memory for a one-shot mesher). Returns whether the smoothing proved the
    /// mesh free of self-intersections ([`mesh_cells_certified`]).
    fn run(
        &mut self,
        cells: &[Cell],
        grid: &GridSpec,
        opts: &MeshOptions,
        out: &mut Mesh,
        keep: bool,
    ) -> Result<bool, MeshError> {
        out.vertices.clear();
        out.triangles.clear();
        let inside = field::prepare(cells, grid, opts, &mut self.scratch.entries)?;
        let inside = (inside, Some(opts.min_component_cells));
        march::march(&mut self.scratch, grid, inside, opts.placement, out, keep);
        Ok(opts
            .smoothing
            .as_ref()
            .is_some_and(|t| smooth::taubin(out, t)))
    }
}

/// Meshes the marked leaves of `octree` (see [`mesh_cells`]).
///
/// # Errors
/// As [`mesh_cells`].
pub fn mesh_octree(octree: &Octree, opts: &MeshOptions) -> Result<Mesh, MeshError> {
    let cells: Vec<Cell> = octree.leaves().collect();
    mesh_cells(&cells, &octree.leaf_grid(), opts)
}

/// Meshes the marked nodes of one `depth` of `octree`: level of detail, each level up halving
/// the resolution (see [`Octree::cells_at_depth`]; the signed distances are then approximate).
///
/// # Errors
/// As [`mesh_cells`].
pub fn mesh_octree_at_depth(
    octree: &Octree,
    depth: u32,
    opts: &MeshOptions,
) -> Result<Mesh, MeshError> {
    let depth = depth.min(octree.depth());
    mesh_cells(&octree.cells_at_depth(depth), &octree.grid(depth), opts)
}
