//! The whole reconstruction in one call: depth frames in, a closed oriented mesh out.
//!
//! Stages, each a call into one crate: filter the frames of every snapshot
//! ([`voxoct_depth::filter::FilterChain`]), back-project, transform and clip ([`voxoct_depth::snapshot::Snapshot`]),
//! triangulate by pixel adjacency ([`voxoct_depth::triangulate::triangulate`]), mark the octree leaves every
//! triangle overlaps ([`voxoct_core::Octree`]), and mesh the marked leaves
//! ([`voxoct_mesh::mesh_cells`]) — in solid mode after closing what no frame saw with the
//! smallest surface ([`voxoct_depth::carve::visibility`], [`voxoct_mesh::closure`]).
//! Snapshots are processed in parallel with the `parallel` feature. [`Params::validate`]
//! checks every knob once, naming it as the `scan` example's flag does.

use std::time::{Duration, Instant};

use voxoct_core::glam::{UVec3, Vec3};
use voxoct_core::{Cell, GridSpec, HALF_CELL_DIAGONAL, Octree, OctreeError, Triangle};
use voxoct_depth::calib::{AxisOptions, CalibSnapshot, alignment_residual};
use voxoct_depth::filter::FilterChain;
use voxoct_depth::noise::kinect_v1_sigma;
use voxoct_depth::scan::RecordedScan;
use voxoct_depth::snapshot::Snapshot;
use voxoct_depth::triangulate::{DEFAULT_MAX_EDGE_SQ, triangulate};
use voxoct_depth::{DepthFrame, FrameError, ScannerConfig};
use voxoct_kinect::{DepthSource, SimulatedKinect, SourceError};
use voxoct_mesh::{Floor, Mesh, MeshError, MeshOptions, Simplified, Simplify, SimplifyStats};

use crate::par;

use voxoct_depth::carve::{CarveView, settle_disagreements, visibility};
use voxoct_mesh::closure::{
    CLOSED_HITS, CLOSED_SDF, ClosedSurface, Platform, close_cells, closure_box,
};

/// The frames of one snapshot and the turntable angle they were taken at.
#[derive(Debug, Clone, PartialEq)]
pub struct SnapshotFrames {
    /// Turntable angle, degrees.
    pub angle_deg: f32,
    /// The raw frames (one or more; several feed the multi-frame filters).
    pub frames: Vec<DepthFrame>,
}

/// The knobs of a reconstruction.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Depth filter chain applied to each snapshot's frames.
    pub filter: FilterChain,
    /// Leaf size, metres (`--leaf`): the real leaf edge is `root / 2^depth`, the largest not
    /// above this.
    pub leaf_m: f32,
    /// Edge of the octree's cubic root, metres (`--root`); the root is centred on the clip box.
    pub root_m: f32,
    /// Largest squared triangle edge kept by the triangulation, m² (`--threshold`).
    pub max_edge_sq: f32,
    /// Mesh this many levels coarser than the leaves (level of detail, `--lod`).
    pub lod: u32,
    /// Meshing options. With `solid` and [`Floor::LowestMarked`], the floor is taken to be
    /// the clip box's floor instead.
    pub mesh: MeshOptions,
    /// Drop connected pieces of the mesh with fewer triangles than this fraction of the
    /// largest piece (stray blobs of errant readings, bubbles inside the solid); 0 keeps all
    /// (`--min-piece`).
    pub min_piece_fraction: f32,
    /// With a solid mesh: close what no frame saw by a minimum cut between the space seen
    /// empty and the solid ([`voxoct_depth::carve::visibility`], [`voxoct_mesh::closure`]),
    /// so the solid closes over the unseen underside instead of leaking into a hollow shell.
    pub carve: bool,
    /// Measure how much the snapshots disagree under the rig
    /// ([`Reconstruction::disagreement_m`]): a wrong tilt or axis shows as doubled contours.
    pub check_agreement: bool,
    /// Simplify the mesh after dropping small pieces ([`voxoct_mesh::simplify`]: quadric edge
    /// collapse that keeps it closed, manifold and free of new self-intersections); `None`
    /// keeps every triangle.
    pub simplify: Option<Simplification>,
}

/// How [`reconstruct`] simplifies the mesh ([`Params::simplify`]). The default bounds the
/// error by [`Simplify::LEAF_FRACTION`] of the cell actually meshed (the leaf edge the
/// octree chose, times `2^lod`), so it follows `leaf_m` and `lod`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Simplification {
    /// Largest error of a collapse, metres (`--max-error`); `None`: a quarter of the meshed
    /// cell ([`Simplify::for_leaf`]).
    pub max_error_m: Option<f32>,
    /// Stop at this many triangles (`--triangles`); the error bound holds either way.
    pub target_triangles: Option<usize>,
}

impl Simplification {
    /// The simplifier's options for cells of edge `cell` metres.
    #[must_use]
    pub fn for_cell(&self, cell: f32) -> Simplify {
        Simplify {
            max_error: self
                .max_error_m
                .unwrap_or(Simplify::for_leaf(cell).max_error),
            target_triangles: self.target_triangles,
        }
    }
}

impl Default for Params {
    /// 1 mm leaves in a 1 m root, the default filter, 1 cm triangle edges, the best-quality
    /// meshing ([`MeshOptions::smooth`]), simplified within a quarter leaf
    /// ([`Simplify::for_leaf`]).
    fn default() -> Self {
        Self {
            filter: FilterChain::default(),
            leaf_m: 0.001,
            root_m: 1.0,
            max_edge_sq: DEFAULT_MAX_EDGE_SQ,
            lod: 0,
            mesh: MeshOptions::smooth(),
            carve: true,
            check_agreement: true,
            min_piece_fraction: 0.01,
            simplify: Some(Simplification::default()),
        }
    }
}

/// Most Taubin smoothing iterations [`Params::validate`] accepts (each is a pass over the mesh).
pub const MAX_SMOOTH: u32 = 1000;
/// Most triangle hits per leaf [`Params::validate`] accepts ([`MeshOptions::min_hits`]).
pub const MAX_MIN_HITS: u32 = 1 << 16;
/// Largest leaf [`Params::validate`] accepts, metres: larger than the objects a turntable
/// scanner takes, so most likely a size given in millimetres.
pub const MAX_LEAF_M: f32 = 0.05;

/// A setting out of range or contradicting another. Its message names the setting as the
/// `scan` example's flag does (`--leaf` for [`Params::leaf_m`], `--threshold` for
/// [`Params::max_edge_sq`], …), which [`InvalidSetting::flag`] returns.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct InvalidSetting {
    flag: &'static str,
    message: String,
}

impl InvalidSetting {
    /// A refusal of the setting that `flag` sets, with the whole message.
    #[must_use]
    pub fn new(flag: &'static str, message: impl Into<String>) -> Self {
        Self {
            flag,
            message: message.into(),
        }
    }

    /// The setting, named as the `scan` example's flag (e.g. `--leaf`).
    #[must_use]
    pub fn flag(&self) -> &'static str {
        self.flag
    }
}

impl Params {
    /// Checks every knob, the one place they are checked: sizes positive and finite, the
    /// leaf within the root and at most [`MAX_LEAF_M`], fractions in `0..=1`, counts
    /// bounded ([`MAX_SMOOTH`], [`MAX_MIN_HITS`]), `lod` within the octree's depth and
    /// `min_component_cells` within its largest surface. [`reconstruct`] calls it first; a
    /// tool calls it too, to refuse bad flags before any frame is read.
    ///
    /// # Errors
    /// [`PipelineError::Setting`] naming the setting as the `scan` example's flag does;
    /// [`PipelineError::Octree`] when no octree of that root and leaf can be built.
    pub fn validate(&self) -> Result<(), PipelineError> {
        let bad = |flag, message: String| Err(InvalidSetting::new(flag, message).into());
        for (flag, v) in [("--leaf", self.leaf_m), ("--root", self.root_m)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(
                    flag,
                    format!("{flag} must be a positive number of metres, got {v}"),
                );
            }
        }
        if self.leaf_m > self.root_m {
            return bad(
                "--leaf",
                format!(
                    "--leaf {} is larger than the octree root --root {}",
                    self.leaf_m, self.root_m
                ),
            );
        }
        if !(self.max_edge_sq.is_finite() && self.max_edge_sq > 0.0) {
            return bad(
                "--threshold",
                format!(
                    "--threshold must be a positive squared edge length in m², got {}",
                    self.max_edge_sq
                ),
            );
        }
        if let Some(e) = self.simplify.and_then(|s| s.max_error_m)
            && !(e.is_finite() && e >= 0.0)
        {
            return bad(
                "--max-error",
                format!("--max-error must be a non-negative number of metres, got {e}"),
            );
        }
        if !(0.0..=1.0).contains(&self.min_piece_fraction) {
            return bad(
                "--min-piece",
                format!(
                    "--min-piece must be a fraction between 0 and 1, got {}",
                    self.min_piece_fraction
                ),
            );
        }
        if let Some(n) = self.mesh.smoothing.as_ref().map(|t| t.iterations)
            && n > MAX_SMOOTH
        {
            return bad(
                "--smooth",
                format!("--smooth must be between 0 and {MAX_SMOOTH} iterations, got {n}"),
            );
        }
        let hits = self.mesh.min_hits;
        if hits > MAX_MIN_HITS {
            return bad(
                "--min-hits",
                format!(
                    "--min-hits must be between 0 and {MAX_MIN_HITS}, got {hits} (no leaf is hit \
                     that often: the mesh would be empty)"
                ),
            );
        }
        let depth = Octree::new(Vec3::ZERO, self.root_m, self.leaf_m)
            .map_err(|source| PipelineError::Octree {
                root_m: self.root_m,
                leaf_m: self.leaf_m,
                source,
            })?
            .depth();
        if self.lod > depth {
            return bad(
                "--lod",
                format!(
                    "--lod {}: the level of detail cannot exceed the octree's {depth} levels \
                     (--root {} m with --leaf {} m)",
                    self.lod, self.root_m, self.leaf_m
                ),
            );
        }
        let c = self.mesh.min_component_cells;
        let leaves_per_side = 1u64 << depth.min(21);
        if c as u64
            > leaves_per_side
                .saturating_mul(leaves_per_side)
                .saturating_mul(6)
        {
            return bad(
                "--min-component",
                format!(
                    "--min-component {c} is more leaves than any surface in this octree has; \
                     every piece would be removed"
                ),
            );
        }
        if self.leaf_m > MAX_LEAF_M {
            return bad(
                "--leaf",
                format!(
                    "--leaf {} m is larger than the objects a turntable scanner takes; --leaf is \
                     in metres (0.001 = 1 mm)",
                    self.leaf_m
                ),
            );
        }
        Ok(())
    }
}

/// The stages, in order, as reported to the progress callback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Filtering each snapshot's frames into one frame.
    Filter,
    /// Back-projection, transform, clipping and triangulation.
    Triangulate,
    /// Octree insertion.
    Insert,
    /// Pseudo-voxels and marching tetrahedra.
    Mesh,
}

/// Wall-clock time of each stage.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timings {
    /// [`Stage::Filter`].
    pub filter: Duration,
    /// Measuring the snapshots' disagreement ([`Params::check_agreement`]): not included
    /// in the filter stage. It runs alongside the closure, so its time is part of
    /// `closure`'s as well.
    pub agreement: Duration,
    /// [`Stage::Triangulate`].
    pub triangulate: Duration,
    /// [`Stage::Insert`].
    pub insert: Duration,
    /// [`Stage::Mesh`]: the closure, march, smoothing and simplification below, and the
    /// rest (reading the octree's cells).
    pub mesh: Duration,
    /// Part of `mesh`: closing what no view saw ([`Params::carve`]), with the views'
    /// verdicts on every cell of its box.
    pub closure: Duration,
    /// Part of `mesh`: [`voxoct_mesh::StepTimes::march`].
    pub march: Duration,
    /// Part of `mesh`: [`voxoct_mesh::StepTimes::smooth`] (smoothing and the untangling
    /// that proves the mesh free of self-intersections).
    pub smooth: Duration,
    /// Part of `mesh`: [`voxoct_mesh::StepTimes::simplify`].
    pub simplify: Duration,
}

/// What a reconstruction produced.
#[derive(Debug)]
pub struct Reconstruction {
    /// The closed, oriented mesh (metres, platform frame).
    pub mesh: Mesh,
    /// The octree with every marked leaf.
    pub tree: Octree,
    /// Number of triangles inserted into the octree.
    pub triangles_in: usize,
    /// Time per stage.
    pub timings: Timings,
    /// How much the snapshots disagree under the rig, metres: the mean point-to-plane
    /// distance between overlapping snapshots ([`voxoct_depth::calib::alignment_residual`]); `None`
    /// when not measured or not measurable (too few points, one snapshot). Compare it with
    /// [`disagreement_explained_m`].
    pub disagreement_m: Option<f32>,
    /// The closed solid's surface, in faces of cells, and how much of it no view saw (the
    /// closure invented it: the back of walls seen from one side, the base on the platform,
    /// caps over unseen openings); counted on the closure's cells before marching, in leaf
    /// faces. `None` when nothing was closed ([`Params::carve`] off, or not solid).
    pub closed_surface: Option<ClosedSurface>,
    /// Marked cells whose own triangles and the views' readings disagreed on the side of the
    /// surface they lie on, settled by both before the closure
    /// ([`voxoct_depth::carve::settle_disagreements`]); 0 when nothing was closed.
    pub settled_cells: usize,
    /// Whether the mesh stage proved the mesh free of self-intersections
    /// ([`voxoct_mesh::mesh_cells_simplified`]: the smoothing's untangling ran the exact test
    /// over every triangle and dropping small pieces and simplifying keep it, or, for a mesh
    /// done piece by piece, the exact test ran over the joined result). `false`: not
    /// checked — run [`Mesh::self_intersecting_triangles`].
    pub self_intersection_free: bool,
    /// Triangles the marching produced (small pieces dropped), before simplification.
    pub marched_triangles: usize,
    /// What simplification did; `None` when it is off.
    pub simplify: Option<SimplifyStats>,
}

/// The largest snapshot disagreement ([`Reconstruction::disagreement_m`]) that the sensor's
/// noise explains for a sensor at `distance_m` from the object: the residual is a mean of
/// point-to-plane distances between two noisy readings (each of σ(z), so √2·σ apart, whose
/// mean absolute value is √(2/π)·√2·σ ≈ 1.13·σ), plus half a millimetre for the
/// triangulated planes' own error; twice that is the limit.
#[must_use]
pub fn disagreement_explained_m(distance_m: f32) -> f32 {
    2.0 * (1.13 * kinect_v1_sigma(distance_m) + 0.0005)
}

/// Why a reconstruction failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// A snapshot's frames could not be filtered or back-projected.
    #[error("snapshot {index} (turntable at {angle_deg}°): {source}")]
    Snapshot {
        /// Index of the snapshot.
        index: usize,
        /// Its turntable angle.
        angle_deg: f32,
        /// What went wrong.
        #[source]
        source: FrameError,
    },
    /// The octree could not be built (leaf larger than the root, non-finite sizes, too deep).
    #[error("octree (root {root_m} m, leaf {leaf_m} m): {source}")]
    Octree {
        /// The root edge asked for.
        root_m: f32,
        /// The leaf size asked for.
        leaf_m: f32,
        /// What went wrong.
        #[source]
        source: OctreeError,
    },
    /// Meshing failed (an option out of range, a solid fill too large).
    #[error("meshing: {0}")]
    Mesh(#[from] MeshError),
    /// No snapshots were given.
    #[error("no snapshots to reconstruct")]
    NoSnapshots,
    /// A parameter is out of range ([`Params::validate`]).
    #[error(transparent)]
    Setting(#[from] InvalidSetting),
}

/// Runs the whole reconstruction. `on_stage` is called as each stage starts.
///
/// Takes the snapshots by value so that their frames are freed as soon as they are filtered.
///
/// # Errors
/// [`PipelineError`] naming the snapshot, parameter or stage that failed; the parameters
/// are checked first ([`Params::validate`]).
pub fn reconstruct(
    config: &ScannerConfig,
    snapshots: Vec<SnapshotFrames>,
    params: &Params,
    mut on_stage: impl FnMut(Stage),
) -> Result<Reconstruction, PipelineError> {
    if snapshots.is_empty() {
        return Err(PipelineError::NoSnapshots);
    }
    params.validate()?;
    let mut timings = Timings::default();

    on_stage(Stage::Filter);
    let t = Instant::now();
    let angles: Vec<f32> = snapshots.iter().map(|s| s.angle_deg).collect();
    let readings: Vec<u32> = snapshots
        .iter()
        .map(|s| params.filter.readings(s.frames.len()))
        .collect();
    let filtered = filter_snapshots(snapshots, &params.filter)?;
    timings.filter = t.elapsed();

    on_stage(Stage::Triangulate);
    let t = Instant::now();
    let triangles = triangulate_snapshots(config, &filtered, &angles, params.max_edge_sq)?;
    timings.triangulate = t.elapsed();

    on_stage(Stage::Insert);
    let t = Instant::now();
    let tree = build_octree(config, params, &triangles)?;
    let triangles_in = triangles.len();
    drop(triangles);
    timings.insert = t.elapsed();

    on_stage(Stage::Mesh);
    let t = Instant::now();
    let (meshed, disagreement_m, (closed_surface, settled_cells)) = mesh_tree(
        config,
        params,
        &tree,
        (filtered, &angles, &readings),
        &mut timings,
    )?;
    timings.mesh = t.elapsed();

    Ok(Reconstruction {
        mesh: meshed.mesh,
        tree,
        triangles_in,
        timings,
        disagreement_m,
        closed_surface,
        settled_cells,
        self_intersection_free: meshed.certified,
        marched_triangles: meshed.marched_triangles,
        simplify: meshed.simplify,
    })
}

/// Stage 1: each snapshot's frames filtered into one frame.
fn filter_snapshots(
    snapshots: Vec<SnapshotFrames>,
    filter: &FilterChain,
) -> Result<Vec<DepthFrame>, PipelineError> {
    par::map_indexed(snapshots, |index, s| {
        filter
            .apply(&s.frames)
            .map_err(|source| PipelineError::Snapshot {
                index,
                angle_deg: s.angle_deg,
                source,
            })
    })
}

/// How much the filtered snapshots disagree under the rig ([`Reconstruction::disagreement_m`]),
/// measured at half resolution: a quarter of the memory and time, and still thousands of
/// points per snapshot.
fn measure_disagreement(
    config: &ScannerConfig,
    filtered: &[DepthFrame],
    angles: &[f32],
) -> Option<f32> {
    let calib: Vec<CalibSnapshot> = filtered
        .iter()
        .zip(angles)
        .map(|(frame, &angle_deg)| CalibSnapshot {
            angle_deg,
            frame: half_resolution(frame),
        })
        .collect();
    let i = config.sensor.intrinsics;
    let half = voxoct_depth::Intrinsics {
        width: i.width.div_ceil(2),
        height: i.height.div_ceil(2),
        fx: i.fx * 0.5,
        fy: i.fy * 0.5,
        cx: i.cx * 0.5,
        cy: i.cy * 0.5,
    };
    alignment_residual(
        &calib,
        &half,
        &config.rig,
        &config.clip,
        &AxisOptions::default(),
    )
    .ok()
    .map(|(r, _)| r)
}

/// Stage 2: every filtered snapshot back-projected, transformed, clipped and triangulated,
/// the triangles in snapshot order.
fn triangulate_snapshots(
    config: &ScannerConfig,
    filtered: &[DepthFrame],
    angles: &[f32],
    max_edge_sq: f32,
) -> Result<Vec<Triangle>, PipelineError> {
    let intrinsics = config.sensor.intrinsics;
    let jobs: Vec<(&DepthFrame, f32)> = filtered.iter().zip(angles.iter().copied()).collect();
    let per_snapshot = par::map_indexed(jobs, |index, (frame, angle_deg)| {
        let snap = Snapshot::from_frame(frame, &intrinsics, &config.rig, angle_deg, &config.clip)
            .map_err(|source| PipelineError::Snapshot {
            index,
            angle_deg,
            source,
        })?;
        let mut tris = Vec::new();
        triangulate(&snap, max_edge_sq, &mut tris);
        Ok::<_, PipelineError>(tris)
    })?;
    Ok(per_snapshot.concat())
}

/// Stage 3: the octree (root centred on the clip box) with every triangle inserted.
fn build_octree(
    config: &ScannerConfig,
    params: &Params,
    triangles: &[Triangle],
) -> Result<Octree, PipelineError> {
    let centre = (config.clip.min + config.clip.max) * 0.5;
    let mut tree = Octree::new(
        centre - Vec3::splat(params.root_m * 0.5),
        params.root_m,
        params.leaf_m,
    )
    .map_err(|source| PipelineError::Octree {
        root_m: params.root_m,
        leaf_m: params.leaf_m,
        source,
    })?;
    par::insert(&mut tree, triangles);
    Ok(tree)
}

/// What the closure did: the closed surface (`None`: nothing closed) and how many marked
/// cells the views settled ([`Reconstruction::closed_surface`],
/// [`Reconstruction::settled_cells`]).
type Closed = (Option<ClosedSurface>, usize);

/// Stage 4: the marked leaves (at `lod` levels coarser) meshed; in solid mode what no
/// frame saw is closed first ([`Params::carve`]); small pieces dropped, then simplified. The
/// steps' times go into `timings`. The snapshots' disagreement
/// ([`Reconstruction::disagreement_m`]) is measured alongside the closure.
fn mesh_tree(
    config: &ScannerConfig,
    params: &Params,
    tree: &Octree,
    (filtered, angles, readings): (Vec<DepthFrame>, &[f32], &[u32]),
    timings: &mut Timings,
) -> Result<(Simplified, Option<f32>, Closed), PipelineError> {
    // `Params::validate` refused a `lod` beyond the depth of this root and leaf.
    let depth = tree.depth() - params.lod;
    let options = mesh_options(config, params);
    let grid = tree.grid(depth);
    let cells = tree.cells_at_depth(depth);
    let t = Instant::now();
    // The closure's minimum cut is serial: the agreement check (serial too) takes the other
    // core meanwhile.
    let ((cells, closed_surface, settled), (disagreement_m, agreement)) = par::join(
        || {
            if params.carve && options.solid {
                let views = (filtered.as_slice(), angles, readings);
                close_unseen_in_budget(
                    config,
                    &options,
                    (tree, depth),
                    cells,
                    views,
                    CLOSURE_BUDGET_CELLS,
                )
            } else {
                (cells, None, 0)
            }
        },
        || {
            let t = Instant::now();
            let d = (params.check_agreement && filtered.len() > 1)
                .then(|| measure_disagreement(config, &filtered, angles))
                .flatten();
            (d, t.elapsed())
        },
    );
    timings.agreement = agreement;
    drop(filtered);
    timings.closure = t.elapsed();
    // Removing whole pieces cannot make two triangles intersect; simplification refuses
    // every collapse that would (its own exact check). A large mesh is smoothed and
    // simplified piece by piece, its peak memory that of the largest pieces.
    let simplify = params.simplify.map(|s| s.for_cell(grid.cell));
    let out = voxoct_mesh::mesh_cells_simplified(
        cells,
        &grid,
        &options,
        params.min_piece_fraction,
        simplify.as_ref(),
    )?;
    timings.march = out.times.march;
    timings.smooth = out.times.smooth;
    timings.simplify = out.times.simplify;
    Ok((out, disagreement_m, (closed_surface, settled)))
}

/// The meshing options of `params` for a scan with `config`: in solid mode with
/// [`Floor::LowestMarked`], the floor is put on the platform (y = 0) — the object stands
/// there, not at the clip box's floor a few millimetres above, which only keeps the
/// platform's readings out.
fn mesh_options(config: &ScannerConfig, params: &Params) -> MeshOptions {
    let mut options = params.mesh;
    if options.solid && options.floor == Floor::LowestMarked {
        options.floor = Floor::Y(config.clip.min.y.min(0.0));
    }
    options
}

/// Cells of the closure box past which [`close_unseen`] runs on a coarser grid: its views'
/// verdicts and the minimum cut take several bytes per cell of the box, not of the surface
/// (the bunny at 0.5 mm, 24 million cells, peaks at 300 MB in the closure).
const CLOSURE_BUDGET_CELLS: u64 = 1 << 25;

/// [`close_unseen`] on the cells of `depth` of `tree`, or, when their closure box exceeds
/// `budget` cells ([`CLOSURE_BUDGET_CELLS`]), on the grid `k` levels coarser whose box fits
/// (the closure's other inputs unchanged); every cell of a coarse cell it adds is then added
/// at `depth`. The marked cells stay at full resolution, settled by the views first
/// ([`settle_disagreements`], `readings` frames averaged per view); returns the cells, the
/// closed surface and how many cells the views settled.
///
/// Why a coarser grid is right there: the closure decides space that no view saw, where any
/// surface is invented, so its resolution bounds no measured detail; it only has to be
/// about as fine as the sensor can place the surface it meets, and the Kinect's depth noise
/// (σ ≈ 2.85 × 10⁻³ z² m) grows with the square of the distance. A box past the budget is
/// either a scene metres across seen from metres away (a room at 3 m: σ ≈ 2.6 cm, closed on
/// 2–3 cm cells) or an object at a leaf far below the noise (at 0.7 m, σ ≈ 1.4 mm: 0.25 mm
/// leaves are closed on 0.5 mm cells). The development scans (boxes of at most 24 million
/// cells at 0.5 mm) stay below the budget and are closed at full resolution as before.
fn close_unseen_in_budget(
    config: &ScannerConfig,
    options: &MeshOptions,
    (tree, depth): (&Octree, u32),
    mut cells: Vec<Cell>,
    (filtered, angles, readings): (&[DepthFrame], &[f32], &[u32]),
    budget: u64,
) -> (Vec<Cell>, Option<ClosedSurface>, usize) {
    let grid = tree.grid(depth);
    let views = carve_views(config, filtered, angles);
    // The marked cells at full resolution, whichever grid the closure then runs on.
    let settled = settle_disagreements(&mut cells, &views, readings, &grid);
    let platform = closure_platform(config, options, &grid);
    let floor = platform.floor;
    let Some((lo, hi)) = closure_box(&cells, &grid, floor) else {
        return (cells, None, settled);
    };
    let volume = |lo: UVec3, hi: UVec3| {
        let d = (hi - lo + UVec3::ONE).as_u64vec3();
        d.x * d.y * d.z
    };
    if volume(lo, hi) <= budget {
        let (cells, surface) = close_unseen(
            config,
            &grid,
            cells,
            (lo, hi),
            platform,
            &views,
            options.min_hits,
        );
        return (cells, Some(surface), settled);
    }
    // The finest coarser grid whose box fits (its box holds the fine one's cells).
    let mut k = 1;
    while k < depth && volume(lo >> k, hi >> k) > budget {
        k += 1;
    }
    let coarse_grid = tree.grid(depth - k);
    let coarse = tree.cells_at_depth(depth - k);
    let known = coarse.len();
    let coarse_platform = closure_platform(config, options, &coarse_grid);
    let Some(coarse_box) = closure_box(&coarse, &coarse_grid, coarse_platform.floor) else {
        return (cells, None, settled);
    };
    let (closed, coarse_surface) = close_unseen(
        config,
        &coarse_grid,
        coarse,
        coarse_box,
        coarse_platform,
        &views,
        options.min_hits,
    );
    // `close_cells` appends the cells it adds after the ones it was given; a coarse cell it
    // adds holds no marked leaf (else it would be known), so all its cells are added.
    let added = &closed[known..];
    let side = 1u32 << k;
    let mut cells = cells;
    cells.reserve_exact(added.len() * (side as usize).pow(3));
    for c in added {
        let base = c.coord << k;
        // The fine layers of the coarse cell at or above the floor.
        for z in 0..side {
            for y in floor.saturating_sub(base.y).min(side)..side {
                for x in 0..side {
                    cells.push(Cell {
                        coord: base + UVec3::new(x, y, z),
                        hits: CLOSED_HITS,
                        sdf_sum: CLOSED_SDF,
                    });
                }
            }
        }
    }
    // A coarse cell's face is 4^k faces of the leaves.
    let leaf_faces = 1u64 << (2 * k);
    let surface = ClosedSurface {
        faces: coarse_surface.faces * leaf_faces,
        invented: coarse_surface.invented * leaf_faces,
    };
    (cells, Some(surface), settled)
}

/// The platform for [`close_unseen`]: the layer below which it excludes cells (the floor's,
/// else none), and the layers above it whose readings the clip box removed (from the floor
/// up to the clip box's bottom, when that is above the floor).
fn closure_platform(config: &ScannerConfig, options: &MeshOptions, grid: &GridSpec) -> Platform {
    match options.floor {
        Floor::Y(y) => {
            let floor = Floor::y_layer(y, grid);
            let clipped = if config.clip.min.y > y {
                Floor::y_layer(config.clip.min.y, grid).saturating_sub(floor)
            } else {
                0
            };
            Platform { floor, clipped }
        }
        _ => Platform::default(),
    }
}

/// Closes what no frame saw in the box `lo..=hi` of `grid` (the cells' [`closure_box`] above
/// `floor`) by the cheapest surface between the space seen empty and the solid ([`voxoct_depth::carve::visibility`], [`voxoct_mesh::closure`]): invented surface
/// costs its area, and one more unit of area for every carving margin (the uncertainty of
/// an observed surface's position) it lies away from the nearest observation.
fn close_unseen(
    config: &ScannerConfig,
    grid: &GridSpec,
    cells: Vec<Cell>,
    (lo, hi): (UVec3, UVec3),
    platform: Platform,
    views: &[CarveView<'_>],
    min_hits: u32,
) -> (Vec<Cell>, ClosedSurface) {
    // Two standard deviations of the sensor's depth noise at the distance of the box's
    // centre (the object on the turntable, or the middle of a scene), plus half a cell
    // diagonal.
    let camera = config
        .rig
        .camera_to_object(0.0)
        .transform_point3(Vec3::ZERO);
    let centre = (grid.cell_center(lo) + grid.cell_center(hi)) * 0.5;
    let distance = centre.distance(camera);
    let margin = 2.0 * kinect_v1_sigma(distance) + HALF_CELL_DIAGONAL * grid.cell;
    // The distance at which invented surface costs twice as much as surface next to an
    // observation: one margin.
    close_cells(
        cells,
        (lo, hi),
        platform,
        min_hits,
        margin / grid.cell,
        grid.cell,
        || visibility(views, grid, lo, hi, margin),
    )
}

/// The filtered snapshots as views for carving, each where its camera was.
fn carve_views<'a>(
    config: &ScannerConfig,
    filtered: &'a [DepthFrame],
    angles: &[f32],
) -> Vec<CarveView<'a>> {
    filtered
        .iter()
        .zip(angles)
        .map(|(frame, &angle)| CarveView {
            frame,
            intrinsics: config.sensor.intrinsics,
            object_to_camera: config.rig.camera_to_object(angle).inverse(),
        })
        .collect()
}

/// The snapshots of a recorded scan, ready for [`reconstruct`], with its scanner settings.
#[must_use]
pub fn recorded_snapshots(scan: RecordedScan) -> (ScannerConfig, Vec<SnapshotFrames>) {
    let config = scan.manifest.config();
    let snapshots = scan
        .frames
        .into_iter()
        .zip(&scan.manifest.snapshots)
        .map(|(frames, entry)| SnapshotFrames {
            angle_deg: entry.angle_deg,
            frames,
        })
        .collect();
    (config, snapshots)
}

/// Captures a simulated scan: `snapshots` equal turntable steps over a full turn, starting at
/// 0°, with `frames` frames at each, from `kinect` (whose turntable angle it sets). Returns the
/// scanner settings that match the simulator ([`crate::session::scanner_config_of`]) and the
/// snapshots, ready for [`reconstruct`]. (A [`crate::session::Session`] captures through a
/// simulated turntable instead, whose angles are whole microsteps.)
///
/// # Errors
/// The simulator's own errors (none for a valid configuration).
pub fn simulate_scan(
    kinect: &mut SimulatedKinect,
    snapshots: u32,
    frames: u32,
) -> Result<(ScannerConfig, Vec<SnapshotFrames>), SourceError> {
    let config = crate::session::scanner_config_of(kinect.config());
    let mut out = Vec::with_capacity(snapshots as usize);
    for k in 0..snapshots {
        let angle_deg = 360.0 / snapshots as f32 * k as f32;
        kinect.set_turntable_angle_deg(angle_deg);
        let frames = (0..frames)
            .map(|_| kinect.grab(crate::session::GRAB_TIMEOUT))
            .collect::<Result<_, _>>()?;
        out.push(SnapshotFrames { angle_deg, frames });
    }
    Ok((config, out))
}

/// Every second pixel of every second row (pixel `(2u, 2v)` becomes `(u, v)`, so the
/// principal point and focal lengths halve).
fn half_resolution(frame: &DepthFrame) -> DepthFrame {
    let (w, h) = (frame.width.div_ceil(2), frame.height.div_ceil(2));
    let mut out = DepthFrame::empty(w, h, frame.unit_m);
    let fw = frame.width as usize;
    for (v, row) in out.data.chunks_exact_mut(w as usize).enumerate() {
        for (u, d) in row.iter_mut().enumerate() {
            *d = frame.data.get(2 * v * fw + 2 * u).copied().unwrap_or(0);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use voxoct_kinect::SimConfig;

    /// The default simplification bound follows the cell meshed; an explicit one does not.
    #[test]
    fn the_default_simplification_follows_the_meshed_cell() {
        let d = Simplification::default();
        assert_eq!(
            d.for_cell(0.002).max_error,
            2.0 * d.for_cell(0.001).max_error
        );
        assert_eq!(d.for_cell(0.001).max_error, Simplify::LEAF_FRACTION * 0.001);
        let fixed = Simplification {
            max_error_m: Some(3e-4),
            target_triangles: Some(10),
        };
        assert_eq!(fixed.for_cell(0.002).max_error, 3e-4);
        assert_eq!(fixed.for_cell(0.002).target_triangles, Some(10));
    }

    /// The closure on a grid one level coarser (a budget the box exceeds) closes a simulated
    /// figurine, whose inside and the underside of whose ring no view sees, to nearly the
    /// same solid as at full resolution. (A cup is not such a case: on cells twice as large,
    /// its walls leave too few cells for the cut to keep its unseen inside open along them.)
    #[test]
    fn closure_on_a_coarser_grid_keeps_the_solid() {
        let sim = SimConfig {
            seed: 7,
            ..SimConfig::default()
        };
        let mut kinect = SimulatedKinect::builtin("figurine", sim).unwrap();
        let (config, snapshots) = simulate_scan(&mut kinect, 8, 1).unwrap();
        let params = Params {
            leaf_m: 0.002,
            ..Params::default()
        };
        let angles: Vec<f32> = snapshots.iter().map(|s| s.angle_deg).collect();
        let filtered = filter_snapshots(snapshots, &params.filter).unwrap();
        let triangles =
            triangulate_snapshots(&config, &filtered, &angles, params.max_edge_sq).unwrap();
        let tree = build_octree(&config, &params, &triangles).unwrap();
        let depth = tree.depth();
        let options = mesh_options(&config, &params);
        let grid = tree.grid(depth);
        let marked = tree.cells_at_depth(depth);
        let (lo, hi) = closure_box(
            &marked,
            &grid,
            closure_platform(&config, &options, &grid).floor,
        )
        .unwrap();
        let d = (hi - lo + UVec3::ONE).as_u64vec3();
        let solid = |budget: u64| {
            let views = (filtered.as_slice(), angles.as_slice(), &[1; 8][..]);
            let (cells, surface, _) = close_unseen_in_budget(
                &config,
                &options,
                (&tree, depth),
                marked.clone(),
                views,
                budget,
            );
            let (mesh, _) = voxoct_mesh::mesh_cells_certified(&cells, &grid, &options).unwrap();
            mesh.check_closed_manifold().unwrap();
            let unseen = surface.and_then(|s| s.invented_share()).unwrap();
            (cells.len(), mesh.volume(), unseen)
        };
        let (fine_cells, fine, fine_unseen) = solid(u64::MAX);
        // Between an eighth and the whole box: one level coarser.
        let (coarse_cells, coarse, coarse_unseen) = solid(d.x * d.y * d.z / 4);
        assert_ne!(fine_cells, coarse_cells, "the coarse closure ran");
        assert!(
            fine > 0.0 && (coarse - fine).abs() < 0.05 * fine,
            "{coarse} vs {fine}"
        );
        // The coarse count, in leaf faces, is near the fine one: some of the surface no view
        // saw, never all of it.
        assert!(
            fine_unseen > 0.0 && fine_unseen < 0.5 && (coarse_unseen - fine_unseen).abs() < 0.05,
            "unseen share {coarse_unseen} (coarse) vs {fine_unseen}"
        );
    }
}
