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
//!   surface itself rather than half a cell outside the outermost marked cells, and the back
//!   of a wall that no view saw is put half a cell behind the surface that was seen, once the
//!   mesh is smoothed and simplified (ARCHITECTURE.md, "voxoct-mesh").
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

use std::borrow::Cow;
use std::time::{Duration, Instant};

mod backs;
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
    let (certified, _) =
        Mesher::new().run(Cow::Borrowed(cells), grid, opts, &mut mesh, false, true)?;
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
        self.run(Cow::Borrowed(cells), grid, opts, out, true, true)
            .map(|_| ())
    }

    /// Meshes into `out`; without `keep`, the working buffers are freed before smoothing
    /// (lower peak memory for a one-shot mesher). With `finish`, the mesh is smoothed and
    /// the backs of unseen walls are thinned ([`backs`]), and the result says whether that
    /// proved the mesh free of self-intersections ([`mesh_cells_certified`]); without, the
    /// marched mesh is left as it is (the options are checked all the same) and the backs
    /// are returned for the caller to thin once it is done with the mesh.
    fn run(
        &mut self,
        cells: Cow<'_, [Cell]>,
        grid: &GridSpec,
        opts: &MeshOptions,
        out: &mut Mesh,
        keep: bool,
        finish: bool,
    ) -> Result<(bool, Vec<backs::Back>), MeshError> {
        out.vertices.clear();
        out.triangles.clear();
        let (inside, floor) = field::prepare(cells, grid, opts, &mut self.scratch.entries)?;
        let inside = (inside, Some(opts.min_component_cells));
        let backs = march::march(
            &mut self.scratch,
            grid,
            inside,
            opts.placement,
            floor,
            out,
            keep,
        );
        if !finish {
            return Ok((false, backs));
        }
        let smoothed = opts
            .smoothing
            .as_ref()
            .is_some_and(|t| smooth::taubin(out, t));
        Ok((thinned(out, &backs, grid, smoothed), Vec::new()))
    }
}

/// [`backs::thin`] on `mesh` (the cells' `grid`), given whether `mesh` was proven free of
/// self-intersections before; returns whether it is after.
fn thinned(mesh: &mut Mesh, backs: &[backs::Back], grid: &GridSpec, certified: bool) -> bool {
    backs::thin(mesh, backs, grid.cell).map_or(certified, |proven| proven || certified)
}

/// Marched triangles past which [`mesh_cells_simplified`] smooths and simplifies the mesh
/// piece by piece instead of whole.
pub const PIECES_PAST_TRIANGLES: usize = 1 << 22;

/// Triangles of marched mesh that [`mesh_cells_simplified`] smooths and simplifies at once
/// past [`PIECES_PAST_TRIANGLES`]: whole pieces are grouped up to this many (a larger piece
/// is a group of its own).
pub const PIECE_GROUP_TRIANGLES: usize = 1 << 18;

/// What [`mesh_cells_simplified`] produced: the mesh, whether it is proven free of
/// self-intersections, and how long each step took.
#[derive(Debug, Clone, Default)]
pub struct Simplified {
    /// The closed, oriented mesh.
    pub mesh: Mesh,
    /// Proven free of self-intersections, as [`mesh_cells_certified`]'s flag.
    pub certified: bool,
    /// Wall-clock time of each step.
    pub times: StepTimes,
    /// Triangles that marching produced, small pieces dropped: what smoothing and
    /// simplification started from.
    pub marched_triangles: usize,
    /// What simplification did (`None` without it); on the pieces path, summed over the
    /// groups of the last round (`passes`: the most any group took; `skipped`: the first).
    pub simplify: Option<SimplifyStats>,
}

/// `into` summed with `other` for [`Simplified::simplify`] on the pieces path.
fn add_stats(into: &mut SimplifyStats, other: &SimplifyStats) {
    into.triangles_before += other.triangles_before;
    into.triangles_after += other.triangles_after;
    into.collapses += other.collapses;
    into.passes = into.passes.max(other.passes);
    into.retries += other.retries;
    into.frozen_vertices += other.frozen_vertices;
    into.new_intersections += other.new_intersections;
    if into.skipped.is_none() {
        into.skipped.clone_from(&other.skipped);
    }
}

/// Wall-clock time of the steps of [`mesh_cells_simplified`]. On the pieces path the
/// smoothing and simplification of each group are added up, and the exact check of the
/// joined pieces counts as smoothing (it proves what the untangling proves on a whole mesh).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepTimes {
    /// The fill and marching tetrahedra, with dropping small pieces.
    pub march: Duration,
    /// Taubin smoothing and the untangling that proves the smoothed mesh free of
    /// self-intersections, and, after simplification, putting the backs of unseen walls
    /// half a cell behind the seen surface (with its own untangling).
    pub smooth: Duration,
    /// Quadric simplification.
    pub simplify: Duration,
}

/// [`mesh_cells_certified`], then [`Mesh::remove_pieces_below_fraction`] and, with
/// `simplify`, [`simplify()`] (the cells are freed once marched), with a peak memory that follows the largest piece rather than
/// the whole mesh: the result is proven free of self-intersections when
/// [`Simplified::certified`] is `true`, as [`mesh_cells_certified`]'s.
///
/// Up to [`PIECES_PAST_TRIANGLES`] marched triangles (or with a triangle target), exactly
/// those three steps. Past it, the separate pieces of the marched mesh (a room's objects,
/// walls and the bubbles in them) are smoothed, untangled and simplified in groups of whole
/// pieces of about [`PIECE_GROUP_TRIANGLES`] triangles, and the joined result is checked
/// exactly for self-intersections: pieces that came to cut through each other are
/// processed again as one group (each such round merges groups, so this ends, at worst with
/// one group: the whole mesh). Each piece comes out as it would from the whole mesh unless
/// it met another one (smoothing and simplification are local to a piece); the pieces are
/// in group order.
///
/// # Errors
/// As [`mesh_cells`].
pub fn mesh_cells_simplified(
    cells: Vec<Cell>,
    grid: &GridSpec,
    opts: &MeshOptions,
    min_piece_fraction: f32,
    simplify: Option<&Simplify>,
) -> Result<Simplified, MeshError> {
    let mut times = StepTimes::default();
    let t = Instant::now();
    let mut mesh = Mesh::default();
    let (_, backs) = Mesher::new().run(Cow::Owned(cells), grid, opts, &mut mesh, false, false)?;
    let whole = mesh.triangles.len() <= PIECES_PAST_TRIANGLES
        || simplify.is_some_and(|s| s.target_triangles.is_some());
    if whole {
        times.march = t.elapsed();
        let t = Instant::now();
        let certified = opts
            .smoothing
            .as_ref()
            .is_some_and(|t| smooth::taubin(&mut mesh, t));
        times.smooth = t.elapsed();
        let t = Instant::now();
        mesh.remove_pieces_below_fraction(min_piece_fraction);
        times.march += t.elapsed();
        let marched_triangles = mesh.triangles.len();
        let t = Instant::now();
        let stats = simplify.map(|s| simplify::simplify(&mut mesh, s));
        times.simplify = t.elapsed();
        let t = Instant::now();
        let certified = thinned(&mut mesh, &backs, grid, certified);
        times.smooth += t.elapsed();
        return Ok(Simplified {
            mesh,
            certified,
            times,
            marched_triangles,
            simplify: stats,
        });
    }
    mesh.remove_pieces_below_fraction(min_piece_fraction);
    times.march = t.elapsed();
    let marched_triangles = mesh.triangles.len();
    let (mut mesh, certified, stats) = by_pieces(
        mesh,
        opts.smoothing.as_ref(),
        simplify,
        PIECE_GROUP_TRIANGLES,
        &mut times,
    );
    let t = Instant::now();
    let certified = thinned(&mut mesh, &backs, grid, certified);
    times.smooth += t.elapsed();
    Ok(Simplified {
        mesh,
        certified,
        times,
        marched_triangles,
        simplify: stats,
    })
}

/// Smooths and simplifies one group of pieces of the pieces path in place, adding the
/// steps' times; returns what simplifying did. Only what is kept stays resident.
fn process_group(
    part: &mut Mesh,
    smoothing: Option<&Taubin>,
    simplify: Option<&Simplify>,
    times: &mut StepTimes,
) -> Option<SimplifyStats> {
    let t0 = Instant::now();
    if let Some(t) = smoothing {
        smooth::taubin(part, t);
    }
    let t1 = Instant::now();
    times.smooth += t1 - t0;
    let stats = simplify.map(|s| simplify::simplify(part, s));
    times.simplify += t1.elapsed();
    // The buffers were sized for the input.
    part.vertices.shrink_to_fit();
    part.triangles.shrink_to_fit();
    stats
}

/// The pieces path of [`mesh_cells_simplified`] on the marched mesh `raw`, in groups of
/// whole pieces of about `group_triangles`.
///
/// The groups are copied out of `raw`, which is kept for a group that must be processed
/// again. When all the pieces make one group (a single large piece, the usual object),
/// nothing can be processed again: `raw` itself becomes the group, as the copy would be
/// (its vertices renumbered by first use, the unused ones dropped), and is processed in
/// place, so the marched mesh is never held twice.
fn by_pieces(
    mut raw: Mesh,
    smoothing: Option<&Taubin>,
    simplify: Option<&Simplify>,
    group_triangles: usize,
    times: &mut StepTimes,
) -> (Mesh, bool, Option<SimplifyStats>) {
    let (roots, size) = raw.triangle_components();
    // Groups of whole pieces (by root vertex), in root order.
    let mut group = vec![u32::MAX; raw.vertices.len()];
    let mut groups = 0u32;
    let mut filled = 0usize;
    for (r, &n) in size.iter().enumerate() {
        if n == 0 {
            continue;
        }
        if groups == 0 || filled + n > group_triangles {
            groups += 1;
            filled = 0;
        }
        group[r] = groups - 1;
        filled += n;
    }
    drop(size);
    if groups == 1 {
        drop((roots, group));
        raw.renumber_by_first_use();
        raw.remove_unused_vertices();
        let stats = process_group(&mut raw, smoothing, simplify, times);
        let t0 = Instant::now();
        let bad = raw.self_intersecting_triangles();
        times.smooth += t0.elapsed();
        // As the joined result of one group: unproven when it still cuts through itself
        // (cannot happen for a marched mesh: see below).
        return (raw, bad.is_empty(), stats);
    }
    let mut tri_group: Vec<u32> = roots.iter().map(|&r| group[r as usize]).collect();
    drop((roots, group));
    let mut done: Vec<Option<Mesh>> = (0..groups).map(|_| None).collect();
    // What simplifying each group did (kept with the group, so that a group processed again
    // replaces its figures).
    let mut group_stats: Vec<Option<SimplifyStats>> = (0..groups).map(|_| None).collect();
    let mut map = vec![u32::MAX; raw.vertices.len()];
    let mut used: Vec<u32> = Vec::new();
    loop {
        let mut count = vec![0usize; done.len()];
        for &g in &tri_group {
            count[g as usize] += 1;
        }
        for (g, slot) in done.iter_mut().enumerate() {
            if slot.is_some() || count[g] == 0 {
                continue;
            }
            let mut part = Mesh::default();
            part.triangles.reserve_exact(count[g]);
            used.clear();
            for (t, _) in tri_group
                .iter()
                .enumerate()
                .filter(|&(_, &x)| x == g as u32)
            {
                let tri = raw.triangles[t].map(|k| {
                    let m = &mut map[k as usize];
                    if *m == u32::MAX {
                        *m = used.len() as u32;
                        used.push(k);
                    }
                    *m
                });
                part.triangles.push(tri);
            }
            part.vertices = used.iter().map(|&k| raw.vertices[k as usize]).collect();
            for &k in &used {
                map[k as usize] = u32::MAX;
            }
            group_stats[g] = process_group(&mut part, smoothing, simplify, times);
            *slot = Some(part);
        }
        // Joined in group order, with each triangle's group.
        let mut out = Mesh::default();
        let mut out_group = Vec::new();
        for (g, part) in done.iter().enumerate() {
            if let Some(part) = part {
                let base = out.vertices.len() as u32;
                out.vertices.extend_from_slice(&part.vertices);
                out.triangles
                    .extend(part.triangles.iter().map(|t| t.map(|k| k + base)));
                out_group.extend(std::iter::repeat_n(g as u32, part.triangles.len()));
            }
        }
        let t0 = Instant::now();
        let bad = out.self_intersecting_triangles();
        times.smooth += t0.elapsed();
        let summed = || {
            simplify.map(|_| {
                let mut sum = SimplifyStats::default();
                for (d, st) in done.iter().zip(&group_stats) {
                    if let (Some(_), Some(st)) = (d, st) {
                        add_stats(&mut sum, st);
                    }
                }
                sum
            })
        };
        if bad.is_empty() {
            return (out, true, summed());
        }
        let mut flagged: Vec<u32> = bad.iter().map(|&t| out_group[t as usize]).collect();
        flagged.sort_unstable();
        flagged.dedup();
        if flagged.len() < 2 {
            if done.iter().filter(|d| d.is_some()).count() < 2 {
                // One group (the whole mesh) that still cuts through itself: cannot happen
                // for a marched mesh (smoothing is undone rather than left tangled, and
                // simplification introduces none); returned unproven.
                let stats = summed();
                return (out, false, stats);
            }
            // A group that cuts through itself (never seen): all pieces as one group.
            flagged = (0..groups)
                .filter(|&g| done[g as usize].is_some())
                .collect();
        }
        drop(out);
        // The flagged groups become one, processed again.
        let into = flagged[0];
        for &g in &flagged {
            done[g as usize] = None;
        }
        for x in &mut tri_group {
            if flagged.binary_search(x).is_ok() {
                *x = into;
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{UVec3, Vec3};
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Piece by piece in small groups (so that pieces of different groups meet after
        /// smoothing and are merged): a valid solid with the pieces of the whole path,
        /// proven free of self-intersections.
        #[test]
        fn pieces_in_groups_give_a_valid_solid(
            blobs in prop::collection::vec((0u32..20, 0u32..20, 0u32..20, 1u32..4), 2..12),
            specks in prop::collection::vec((0u32..24, 0u32..24, 0u32..24, -0.9f32..0.9), 0..60),
            group in 1usize..400,
            simplified in any::<bool>(),
        ) {
            let grid = GridSpec { origin: Vec3::new(-0.3, 0.1, 2.0), cell: 0.001, resolution: 32 };
            let mut cells = Vec::new();
            for (cx, cy, cz, r) in blobs {
                let r = r as i32;
                for z in -r..=r {
                    for y in -r..=r {
                        for x in -r..=r {
                            let d2 = x * x + y * y + z * z;
                            let p = [cx as i32 + x, cy as i32 + y, cz as i32 + z];
                            if d2 <= r * r && d2 > (r - 1) * (r - 1) && p.iter().all(|&v| v >= 0) {
                                let coord = UVec3::new(p[0] as u32, p[1] as u32, p[2] as u32);
                                cells.push(Cell { coord, hits: 1, sdf_sum: 0.0 });
                            }
                        }
                    }
                }
            }
            for (x, y, z, s) in specks {
                cells.push(Cell { coord: UVec3::new(x, y, z), hits: 1, sdf_sum: s * 0.001 });
            }
            let opts = MeshOptions { solid: false, ..MeshOptions::smooth() };
            let mut raw = Mesh::default();
            Mesher::new()
                .run(Cow::Borrowed(&cells), &grid, &opts, &mut raw, false, false)
                .unwrap();
            prop_assume!(!raw.triangles.is_empty());
            let s = Simplify::for_leaf(grid.cell);
            let simplify = simplified.then_some(&s);
            let (mesh, certified, stats) = by_pieces(raw.clone(), opts.smoothing.as_ref(), simplify, group, &mut StepTimes::default());
            prop_assert!(certified);
            // The groups' figures add up to the whole: every marched triangle went in, every
            // output triangle came out.
            prop_assert_eq!(stats.is_some(), simplified);
            if let Some(st) = stats {
                prop_assert_eq!(st.triangles_before, raw.triangles.len());
                prop_assert_eq!(st.triangles_after, mesh.triangles.len());
            }
            mesh.check_valid_solid().map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(mesh.stats().components, raw.stats().components);
        }
    }
}
