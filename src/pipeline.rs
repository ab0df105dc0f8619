//! The whole reconstruction in one call: depth frames in, a closed oriented mesh out.
//!
//! Stages, each a call into one crate: filter the frames of every snapshot
//! ([`voxoct_depth::filter::FilterChain`]), back-project, transform and clip ([`voxoct_depth::snapshot::Snapshot`]),
//! triangulate by pixel adjacency ([`voxoct_depth::triangulate::triangulate`]), mark the octree leaves every
//! triangle overlaps ([`voxoct_core::Octree`]), and mesh the marked leaves
//! ([`voxoct_mesh::mesh_cells`]) — in solid mode after closing what no frame saw with the
//! smallest surface ([`voxoct_depth::carve::visibility`], [`voxoct_mesh::closure`]).
//! Snapshots are processed in parallel with the `parallel` feature.

use std::time::{Duration, Instant};

use voxoct_core::glam::{UVec3, Vec3};
use voxoct_core::{Octree, OctreeError, Triangle};
use voxoct_depth::calib::{AxisOptions, CalibSnapshot, alignment_residual};
use voxoct_depth::filter::FilterChain;
use voxoct_depth::noise::kinect_v1_sigma;
use voxoct_depth::scan::RecordedScan;
use voxoct_depth::snapshot::Snapshot;
use voxoct_depth::triangulate::{DEFAULT_MAX_EDGE_SQ, triangulate};
use voxoct_depth::{DepthFrame, FrameError, ScannerConfig, SensorConfig};
use voxoct_kinect::{DepthSource, SimulatedKinect, SourceError};
use voxoct_mesh::{Floor, Mesh, MeshError, MeshOptions, Simplify};

use voxoct_depth::carve::{CarveView, Seen, visibility};
use voxoct_mesh::closure::{close_cells, closure_box};

#[cfg(feature = "parallel")]
use rayon::prelude::*;

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
    /// Leaf size, metres: the real leaf edge is `root / 2^depth`, the largest not above this.
    pub leaf_m: f32,
    /// Edge of the octree's cubic root, metres; the root is centred on the clip box.
    pub root_m: f32,
    /// Largest squared triangle edge kept by the triangulation, m².
    pub max_edge_sq: f32,
    /// Mesh this many levels coarser than the leaves (level of detail).
    pub lod: u32,
    /// Meshing options. With `solid` and [`Floor::LowestMarked`], the floor is taken to be
    /// the clip box's floor instead.
    pub mesh: MeshOptions,
    /// Drop connected pieces of the mesh with fewer triangles than this fraction of the
    /// largest piece (stray blobs of errant readings, bubbles inside the solid); 0 keeps all.
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
    /// keeps every triangle. Off by default: it keeps the accuracy
    /// but costs about 1 µs per triangle (three times the rest of the pipeline); use
    /// [`Simplify::for_leaf`] of `leaf_m`.
    pub simplify: Option<Simplify>,
}

impl Default for Params {
    /// 1 mm leaves in a 1 m root, the default filter, 1 cm triangle edges, the best-quality
    /// meshing ([`MeshOptions::smooth`]).
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
            simplify: None,
        }
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
    /// Measuring the snapshots' disagreement ([`Params::check_agreement`]), after the
    /// filter stage and not included in it.
    pub agreement: Duration,
    /// [`Stage::Triangulate`].
    pub triangulate: Duration,
    /// [`Stage::Insert`].
    pub insert: Duration,
    /// [`Stage::Mesh`].
    pub mesh: Duration,
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
    /// `lod` is more levels than the octree has.
    #[error("level of detail {lod} is more levels than the octree has ({depth})")]
    Lod {
        /// Levels asked for.
        lod: u32,
        /// The octree's depth.
        depth: u32,
    },
    /// Meshing failed (an option out of range, a solid fill too large).
    #[error("meshing: {0}")]
    Mesh(#[from] MeshError),
    /// No snapshots were given.
    #[error("no snapshots to reconstruct")]
    NoSnapshots,
    /// A parameter is out of range.
    #[error("{name} = {value}: {reason}")]
    Param {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f32,
        /// Why it is refused.
        reason: &'static str,
    },
}

/// Runs the whole reconstruction. `on_stage` is called as each stage starts.
///
/// Takes the snapshots by value so that their frames are freed as soon as they are filtered.
///
/// # Errors
/// [`PipelineError`] naming the snapshot, parameter or stage that failed.
pub fn reconstruct(
    config: &ScannerConfig,
    snapshots: Vec<SnapshotFrames>,
    params: &Params,
    mut on_stage: impl FnMut(Stage),
) -> Result<Reconstruction, PipelineError> {
    if snapshots.is_empty() {
        return Err(PipelineError::NoSnapshots);
    }
    if !(params.max_edge_sq.is_finite() && params.max_edge_sq > 0.0) {
        return Err(PipelineError::Param {
            name: "max_edge_sq",
            value: params.max_edge_sq,
            reason: "must be a positive squared length in m²",
        });
    }
    let mut timings = Timings::default();

    on_stage(Stage::Filter);
    let t = Instant::now();
    let angles: Vec<f32> = snapshots.iter().map(|s| s.angle_deg).collect();
    let filtered = map_snapshots(snapshots, |index, s| {
        params
            .filter
            .apply(&s.frames)
            .map_err(|source| PipelineError::Snapshot {
                index,
                angle_deg: s.angle_deg,
                source,
            })
    })?;
    timings.filter = t.elapsed();
    let t_agreement = Instant::now();
    let disagreement_m = if params.check_agreement && filtered.len() > 1 {
        // At half resolution: a quarter of the memory and time, and still thousands of
        // points per snapshot.
        let calib: Vec<CalibSnapshot> = filtered
            .iter()
            .zip(&angles)
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
    } else {
        None
    };
    timings.agreement = t_agreement.elapsed();

    on_stage(Stage::Triangulate);
    let t = Instant::now();
    let intrinsics = config.sensor.intrinsics;
    let jobs: Vec<(&DepthFrame, f32)> = filtered.iter().zip(angles.iter().copied()).collect();
    let per_snapshot = map_snapshots(jobs, |index, (frame, angle_deg)| {
        let snap = Snapshot::from_frame(frame, &intrinsics, &config.rig, angle_deg, &config.clip)
            .map_err(|source| PipelineError::Snapshot {
            index,
            angle_deg,
            source,
        })?;
        let mut tris = Vec::new();
        triangulate(&snap, params.max_edge_sq, &mut tris);
        Ok(tris)
    })?;
    let triangles: Vec<Triangle> = per_snapshot.concat();
    timings.triangulate = t.elapsed();

    on_stage(Stage::Insert);
    let t = Instant::now();
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
    #[cfg(feature = "parallel")]
    tree.par_insert(&triangles);
    #[cfg(not(feature = "parallel"))]
    tree.insert_all(&triangles);
    let triangles_in = triangles.len();
    drop(triangles);
    timings.insert = t.elapsed();

    on_stage(Stage::Mesh);
    let t = Instant::now();
    let depth = tree
        .depth()
        .checked_sub(params.lod)
        .ok_or(PipelineError::Lod {
            lod: params.lod,
            depth: tree.depth(),
        })?;
    let mut options = params.mesh;
    if options.solid && options.floor == Floor::LowestMarked {
        // The object stands on the platform (y = 0): its base is there, not at the clip
        // box's floor a few millimetres above, which only keeps the platform's readings out.
        options.floor = Floor::Y(config.clip.min.y.min(0.0));
    }
    let grid = tree.grid(depth);
    let mut cells = tree.cells_at_depth(depth);
    if params.carve && options.solid {
        let views: Vec<CarveView<'_>> = filtered
            .iter()
            .zip(&angles)
            .map(|(frame, &angle)| CarveView {
                frame,
                intrinsics,
                object_to_camera: config.rig.camera_to_object(angle).inverse(),
            })
            .collect();
        // Two standard deviations of the sensor's depth noise at the object's distance,
        // plus half a cell diagonal.
        let distance = config.rig.sensor_position_m.length();
        let margin = 2.0 * kinect_v1_sigma(distance) + 0.87 * grid.cell;
        let floor = match options.floor {
            Floor::Y(y) => Floor::y_layer(y, &grid),
            _ => 0,
        };
        if let Some((lo, hi)) = closure_box(&cells, &grid, floor) {
            let seen = visibility(&views, &grid, lo, hi, margin, |_| false);
            let dim = hi - lo + UVec3::ONE;
            cells = close_cells(cells, &grid, (lo, hi), floor, options.min_hits, |c| {
                let d = c - lo;
                seen[((d.z * dim.y + d.y) * dim.x + d.x) as usize] == Seen::Empty
            });
        }
    }
    drop(filtered);
    let mut mesh = voxoct_mesh::mesh_cells(&cells, &grid, &options)?;
    drop(cells);
    mesh.remove_pieces_below_fraction(params.min_piece_fraction);
    if let Some(opts) = &params.simplify {
        voxoct_mesh::simplify(&mut mesh, opts);
    }
    timings.mesh = t.elapsed();

    Ok(Reconstruction {
        mesh,
        tree,
        triangles_in,
        timings,
        disagreement_m,
    })
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
/// scanner settings that match the simulator (its intrinsics, depth unit and rig, and the
/// default clip box) and the snapshots, ready for [`reconstruct`].
///
/// # Errors
/// The simulator's own errors (none for a valid configuration).
pub fn simulate_scan(
    kinect: &mut SimulatedKinect,
    snapshots: u32,
    frames: u32,
) -> Result<(ScannerConfig, Vec<SnapshotFrames>), SourceError> {
    let sim = *kinect.config();
    let config = ScannerConfig {
        sensor: SensorConfig {
            intrinsics: sim.intrinsics,
            depth_unit_m: sim.unit_m,
        },
        rig: sim.rig,
        ..ScannerConfig::default()
    };
    let timeout = Duration::from_secs(5);
    let mut out = Vec::with_capacity(snapshots as usize);
    for k in 0..snapshots {
        let angle_deg = 360.0 / snapshots as f32 * k as f32;
        kinect.set_turntable_angle_deg(angle_deg);
        let frames = (0..frames)
            .map(|_| kinect.grab(timeout))
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

/// Applies `f` to every item with its index, in parallel with the `parallel` feature,
/// keeping the order; the first error wins.
fn map_snapshots<I: Send, O: Send>(
    items: Vec<I>,
    f: impl Fn(usize, I) -> Result<O, PipelineError> + Sync + Send,
) -> Result<Vec<O>, PipelineError> {
    #[cfg(feature = "parallel")]
    {
        items
            .into_par_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        items
            .into_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    }
}
