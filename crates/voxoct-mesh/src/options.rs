//! Meshing options and the error type.

use voxoct_core::GridSpec;
use voxoct_core::glam::UVec3;

/// The floor: nothing below it is meshed, and the flood fill that finds the outside (solid
/// mode and signed-distance placement) cannot enter from below it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Floor {
    /// No floor: the outside is flooded from every side of the grid, bottom included. A scan
    /// whose underside was never seen stays open there, so its inside is not filled.
    None,
    /// The lowest layer (smallest `y`) that holds a marked cell is the floor: nothing below
    /// it, and the outside cannot enter from below. Right for an object standing on a
    /// turntable; harmless for a closed object (its lowest layer is a closed cap).
    #[default]
    LowestMarked,
    /// The plane `y` (metres, platform frame: the clip box's floor): cells whose centre lies
    /// below it are dropped and closed to the flood fill.
    Y(f32),
}

impl Floor {
    /// The grid layer of the plane `y` (metres): the first layer whose cell centres lie at or
    /// above it (0 when `y` is below the grid). This is where [`Floor::Y`] cuts.
    #[must_use]
    pub fn y_layer(y: f32, grid: &GridSpec) -> u32 {
        let l = ((y - grid.origin.y) * (1.0 / grid.cell) - 0.5).ceil();
        if l <= 0.0 {
            0
        } else {
            l.min(u32::MAX as f32) as u32
        }
    }
}

/// How vertices are placed along their grid edges. The default is [`Self::SignedDistance`],
/// as in [`MeshOptions::default`]; the thesis's mode is [`Self::Midpoint`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Placement {
    /// The thesis: every vertex at the midpoint of its edge (binary field, iso 0.5).
    Midpoint,
    /// Sub-cell placement from [`voxoct_core::Cell::mean_sdf`]: between two marked cells the
    /// zero of the linearly interpolated signed distance; between a marked and an unmarked
    /// cell, the marked cell's distance measured along the edge, except across the back of
    /// a wall that no view saw (the marked cell's other neighbour on the edge's line at
    /// least half a cell nearer the surface), which is put half a cell behind the surface
    /// (with [`MeshOptions::solid`]); next to a cell without an
    /// observed surface (enclosed by the fill, or added by the closure with
    /// [`crate::closure::CLOSED_SDF`]), the middle of the edge. Positions are clamped to
    /// `[0.02, 0.98]` of the edge, so topology is that of the binary field and no triangle
    /// degenerates. With [`MeshOptions::solid`], cells whose centre lies outside the surface
    /// (positive distance) count as outside, so the wall sits on the surface itself; so do
    /// enclosed cells that lie, along a grid axis, between the outside and a marked cell (the
    /// gap closing puts them into the dents of a ragged surface, beyond the marked cell's
    /// surface), with the pieces of fewer than [`MeshOptions::min_component_cells`] this cuts
    /// off.
    #[default]
    SignedDistance,
}

/// Taubin λ/μ smoothing: alternating shrink (λ > 0) and inflate (μ < −λ) Laplacian steps that
/// remove the staircase without shrinking the volume. Only positions change; connectivity is
/// untouched, and where the smoothed triangles would cut through each other or degenerate,
/// their vertices are moved back toward their unsmoothed positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Taubin {
    /// Number of λ/μ pairs.
    pub iterations: u32,
    /// Shrink factor, in (0, 1).
    pub lambda: f32,
    /// Inflate factor, negative with `|mu| > lambda`.
    pub mu: f32,
}

impl Default for Taubin {
    fn default() -> Self {
        Self {
            iterations: 10,
            lambda: 0.5,
            mu: -0.53,
        }
    }
}

/// Options of [`crate::mesh_cells`].
///
/// `Default` is what the project recommends and the `scan` example uses:
/// [`MeshOptions::smooth`], a solid with signed-distance placement and Taubin smoothing.
/// [`MeshOptions::thesis`] is the thesis's method (hollow shell, midpoints).
///
/// ```
/// use voxoct_mesh::{MeshOptions, Placement};
///
/// assert_eq!(MeshOptions::default(), MeshOptions::smooth());
/// let thesis = MeshOptions::thesis();
/// assert!(!thesis.solid && thesis.placement == Placement::Midpoint && thesis.smoothing.is_none());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    /// Cells hit by fewer triangles count as unmarked (single errant depth values). 0 and 1
    /// keep every cell.
    pub min_hits: u32,
    /// Connected groups of marked cells (connected as the mesh connects them) with fewer
    /// cells than this are dropped before meshing: isolated blobs, the thesis's
    /// "protrusions". 0 keeps everything.
    pub min_component_cells: usize,
    /// Solid mode: the unmarked cells that the outside cannot reach (flood fill from the grid
    /// boundary, see [`Floor`]) are filled, so a hollow double-walled shell becomes one solid
    /// with one wall (about half the triangles) and a flat base at the floor.
    pub solid: bool,
    /// The floor used by the flood fill.
    pub floor: Floor,
    /// Holes in the shell up to `2 · close_gaps` cells wide need not let the flood fill in:
    /// the fill may keep up to `close_gaps` cells (L∞) away from marked cells and is grown
    /// back afterwards. Scans miss patches at grazing angles, most of all near the floor.
    /// Closing also fills concavities narrower than twice its width (such as the wedge
    /// between the floor and a rounded bottom), so it is used only as far as needed: the
    /// smallest width (from 0) whose enclosed space is at least half that of the widest.
    pub close_gaps: u32,
    /// Vertex placement.
    pub placement: Placement,
    /// Optional smoothing after marching.
    pub smoothing: Option<Taubin>,
}

impl Default for MeshOptions {
    /// [`MeshOptions::smooth`], the recommended options.
    fn default() -> Self {
        Self::smooth()
    }
}

impl MeshOptions {
    /// The thesis: every marked cell, hollow, midpoints, no smoothing.
    #[must_use]
    pub const fn thesis() -> Self {
        Self {
            min_hits: 1,
            min_component_cells: 0,
            solid: false,
            floor: Floor::LowestMarked,
            close_gaps: 0,
            placement: Placement::Midpoint,
            smoothing: None,
        }
    }

    /// The most accurate combination, and the [`Default`]: solid with the floor at the lowest marked layer and
    /// gaps up to 2 cells closed, signed-distance placement, Taubin smoothing (10
    /// iterations), blobs under 8 cells dropped.
    #[must_use]
    pub fn smooth() -> Self {
        Self {
            min_hits: 1,
            min_component_cells: 8,
            solid: true,
            floor: Floor::LowestMarked,
            close_gaps: 1,
            placement: Placement::SignedDistance,
            smoothing: Some(Taubin::default()),
        }
    }
}

/// Why meshing failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A cell lies outside the grid.
    ///
    /// How to fix: pass the [`voxoct_core::GridSpec`] of the depth the cells come from.
    #[error("cell {index} at {coord} is outside the grid of resolution {resolution}")]
    CellOutsideGrid {
        /// Index in the input slice.
        index: usize,
        /// Its coordinates.
        coord: UVec3,
        /// The grid's resolution.
        resolution: u32,
    },
    /// A grid parameter or an option is out of its domain: `name` is the field as
    /// written in Rust (`"grid.origin.x"`, `"grid.cell"`, `"grid.resolution"`,
    /// `"smoothing.lambda"`, `"smoothing.mu"`, `"floor"`); the same pattern as
    /// `voxoct_core::OctreeError::InvalidArgument` and
    /// `voxoct_stl::StlError::InvalidArgument`.
    ///
    /// How to fix: pass the [`voxoct_core::GridSpec`] the octree gives
    /// (`Octree::leaf_grid`), and options within the ranges the message states.
    #[error("invalid `{name}` = {value}: {reason}")]
    InvalidArgument {
        /// The field.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What the value must be.
        reason: &'static str,
    },
    /// The box to flood-fill for solid mode needs more tiles than the tiled fill allocates
    /// (2^26 tiles of 16 384 cells: a box far beyond any scene at its leaf size).
    ///
    /// How to fix: mesh a coarser depth, or crop the cells.
    #[error("solid fill needs {cells} cells, more than the limit {limit}")]
    FillTooLarge {
        /// Cells in the padded bounding box.
        cells: u64,
        /// The limit.
        limit: u64,
    },
}
