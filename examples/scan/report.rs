//! What a scan reports: the `--stats` JSON object, the summary, and why a mesh came out empty.

use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use voxoct::mesh_file::MeshFile;
use voxoct::pipeline::{Params, Reconstruction, Timings};

use crate::args::Args;

/// Stage progress: a spinner per stage on a terminal, nothing otherwise or with `-q`.
pub struct Progress {
    /// Whether to draw.
    pub enabled: bool,
}

impl Progress {
    /// A bar (with `len`) or a spinner for the stage `name`.
    pub fn stage(&self, name: &str, len: Option<u64>) -> ProgressBar {
        if !self.enabled {
            return ProgressBar::hidden();
        }
        let pb = match len {
            Some(n) => ProgressBar::with_draw_target(Some(n), ProgressDrawTarget::stderr())
                .with_style(
                    ProgressStyle::with_template("{prefix:>12} [{bar:30}] {pos}/{len} {msg}")
                        .unwrap_or_else(|_| ProgressStyle::default_bar())
                        .progress_chars("=> "),
                ),
            None => ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr()).with_style(
                ProgressStyle::with_template("{prefix:>12} {spinner} {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            ),
        };
        pb.set_prefix(name.to_string());
        pb.enable_steady_tick(Duration::from_millis(100));
        pb
    }
}

/// Warns when the snapshots disagree by more than the sensor's noise explains.
pub fn warn_if_disagreeing(disagreement_m: Option<f32>, limit_m: f32) {
    if let Some(d) = disagreement_m.filter(|&d| d > limit_m) {
        eprintln!(
            "warning: the snapshots disagree by {:.1} mm, more than the sensor's noise explains ({:.1} mm): \
             the rig (tilt, sensor position) is off and the mesh may show doubled contours; \
             fix it with `calibrate --input DIR --write` (record with --record-to first)",
            d * 1e3,
            limit_m * 1e3
        );
    }
}

/// Seconds spent in each stage.
#[derive(Debug, Default, Serialize)]
pub struct Seconds {
    pub load: f64,
    pub filter: f64,
    pub agreement: f64,
    pub triangulate: f64,
    pub insert: f64,
    pub mesh: f64,
    /// Parts of `mesh`.
    pub mesh_steps: MeshSteps,
    pub write: f64,
    pub total: f64,
}

/// Seconds spent in the mesh stage's steps (the rest of it reads the octree's cells).
#[derive(Debug, Default, Serialize)]
pub struct MeshSteps {
    /// Closing what no view saw.
    pub closure: f64,
    /// Fill, marching tetrahedra, dropping small pieces.
    pub march: f64,
    /// Smoothing and the untangling that proves the mesh free of self-intersections.
    pub smooth: f64,
    /// Quadric simplification.
    pub simplify: f64,
}

/// What simplification did (`--stats`), summed over the pieces of a large mesh; it took
/// `mesh_marched_triangles` to `mesh_triangles`.
#[derive(Debug, Serialize)]
pub struct Simplification {
    /// Edge collapses made.
    pub collapses: usize,
    /// Collapse passes (the most any piece needed).
    pub passes: usize,
    /// Rounds replayed because the exact test found a new intersection.
    pub retries: u32,
    /// Vertices those rounds froze.
    pub frozen_vertices: usize,
}

/// The `--stats` JSON object.
#[derive(Debug, Serialize)]
pub struct Stats {
    pub source: String,
    pub snapshots: usize,
    pub frames: usize,
    pub filter: String,
    pub triangles_in: usize,
    pub leaves: usize,
    pub leaf_size_m: f32,
    pub octree_depth: u32,
    pub octree_bytes: usize,
    pub mesh_triangles: usize,
    /// Triangles marching produced (small pieces dropped), before simplification.
    pub mesh_marched_triangles: usize,
    /// Null with `--no-simplify` (and `--thesis`).
    pub simplification: Option<Simplification>,
    pub mesh_vertices: usize,
    pub mesh_components: usize,
    /// Handles (tunnels) summed over the components when closed (null otherwise): 0 for
    /// each solid without a hole through it.
    pub mesh_genus: Option<usize>,
    /// Share of the closed solid's surface that no view saw, which the closure invented
    /// (leaf faces of the closure's cells, before marching; null when nothing was closed).
    pub unseen_surface_share: Option<f64>,
    /// Marked cells that the views' readings put on the other side of the surface than
    /// their own triangles did, settled by both before the closure (0: none, or nothing
    /// closed).
    pub settled_cells: usize,
    pub mesh_volume_m3: f64,
    pub mesh_area_m2: f64,
    pub closed_manifold: bool,
    /// How much the snapshots disagree under the rig, metres (null: not measurable).
    pub snapshot_disagreement_m: Option<f32>,
    /// What the sensor's noise explains; above it a warning is printed.
    pub snapshot_disagreement_limit_m: f32,
    pub self_intersecting_triangles: usize,
    pub valid_solid: bool,
    pub peak_rss_bytes: u64,
    pub threads: usize,
    pub seconds: Seconds,
}

impl Seconds {
    /// The load time and the pipeline's stages; `write` and `total` are filled later.
    pub fn of(load: Duration, t: &Timings) -> Self {
        Self {
            load: load.as_secs_f64(),
            filter: t.filter.as_secs_f64(),
            agreement: t.agreement.as_secs_f64(),
            triangulate: t.triangulate.as_secs_f64(),
            insert: t.insert.as_secs_f64(),
            mesh: t.mesh.as_secs_f64(),
            mesh_steps: MeshSteps {
                closure: t.closure.as_secs_f64(),
                march: t.march.as_secs_f64(),
                smooth: t.smooth.as_secs_f64(),
                simplify: t.simplify.as_secs_f64(),
            },
            ..Self::default()
        }
    }
}

impl Stats {
    /// The figures of a run: its source, `(snapshots, frames)`, parameters and result,
    /// with the disagreement limit and whether the mesh is closed; the times and peak
    /// memory are filled later.
    pub fn new(
        source: String,
        (snapshots, frames): (usize, usize),
        params: &Params,
        r: &Reconstruction,
        (limit_m, closed): (f32, bool),
    ) -> Self {
        let (mesh, tree) = (&r.mesh, &r.tree);
        let mstats = mesh.stats();
        // The mesh stage's untangling already ran the exact test when it certifies the mesh.
        let self_intersecting = if r.self_intersection_free {
            0
        } else {
            mesh.self_intersecting_triangles().len()
        };
        Self {
            source,
            snapshots,
            frames,
            filter: params.filter.to_string(),
            triangles_in: r.triangles_in,
            leaves: tree.leaf_count(),
            leaf_size_m: tree.leaf_edge(),
            octree_depth: tree.depth(),
            octree_bytes: tree.memory_bytes(),
            mesh_triangles: mesh.triangles.len(),
            mesh_marched_triangles: r.marched_triangles,
            simplification: r.simplify.as_ref().map(|s| Simplification {
                collapses: s.collapses,
                passes: s.passes,
                retries: s.retries,
                frozen_vertices: s.frozen_vertices,
            }),
            mesh_vertices: mesh.vertices.len(),
            mesh_components: mstats.components,
            mesh_genus: mstats.genus().filter(|_| closed),
            unseen_surface_share: r.closed_surface.and_then(|c| c.invented_share()),
            settled_cells: r.settled_cells,
            mesh_volume_m3: mstats.volume,
            mesh_area_m2: mstats.area,
            closed_manifold: closed,
            snapshot_disagreement_m: r.disagreement_m,
            snapshot_disagreement_limit_m: limit_m,
            self_intersecting_triangles: self_intersecting,
            valid_solid: closed && self_intersecting == 0,
            peak_rss_bytes: 0,
            threads: voxoct::threads(),
            seconds: Seconds::default(),
        }
    }
}

/// The short report at the end of a run.
pub fn summary(s: &Stats, out: &std::path::Path, file: &MeshFile) {
    let t = &s.seconds;
    eprintln!(
        "{} snapshots × {} frames ({}), {} triangles → {} leaves of {:.3} mm → {} triangles",
        s.snapshots,
        s.frames / s.snapshots.max(1),
        s.filter,
        s.triangles_in,
        s.leaves,
        s.leaf_size_m * 1000.0,
        s.mesh_triangles
    );
    eprintln!(
        "time: load {:.2}s, filter {:.2}s, triangulate {:.2}s, insert {:.2}s, mesh {:.2}s, write {:.2}s; total {:.2}s; peak memory {:.0} MB",
        t.load,
        t.filter,
        t.triangulate,
        t.insert,
        t.mesh,
        t.write,
        t.total,
        s.peak_rss_bytes as f64 / 1e6
    );
    eprintln!("source: {}", s.source);
    eprintln!(
        "watertight: {}; self-intersecting triangles: {}; valid solid: {}; wrote {} ({})",
        if s.closed_manifold { "yes" } else { "NO" },
        s.self_intersecting_triangles,
        if s.valid_solid { "yes" } else { "NO" },
        out.display(),
        file.describe()
    );
    if let Some(share) = s.unseen_surface_share {
        eprintln!(
            "surface no view saw: {:.0} % (closed with the smallest surface next to what was seen)",
            share * 100.0
        );
    }
}

/// Why the mesh came out empty, from what the run saw (`clip_floor_m`: the height of the
/// clip box's floor over the platform, metres).
pub fn explain_empty(args: &Args, triangles_in: usize, leaves: usize, clip_floor_m: f32) -> String {
    if triangles_in == 0 {
        return format!(
            "the scan produced an empty mesh: no frame had a valid depth pixel inside the clip \
             box (all-zero or out-of-range frames, the object outside [clip], or an object no \
             taller than the clip box's floor, {:.1} mm over the platform, whose readings are \
             dropped with the platform's; check [clip], [rig] and the frames)",
            clip_floor_m * 1000.0
        );
    }
    if leaves == 0 {
        return format!(
            "the scan produced an empty mesh: {triangles_in} triangles were triangulated but none \
             fell inside the octree (--root {} m centred on the clip box)",
            args.root
        );
    }
    let h = args.min_hits;
    if h > 1 {
        return format!(
            "the scan produced an empty mesh: every one of the {leaves} leaves was hit by fewer \
             than --min-hits {h} triangles"
        );
    }
    if let Some(c) = args.min_component {
        return format!(
            "the scan produced an empty mesh: every piece has fewer than --min-component {c} leaves"
        );
    }
    if args.lod > 0 {
        return format!(
            "the scan produced an empty mesh: at --lod {} the {leaves} leaves merge into cells \
             too coarse to enclose anything; use a smaller --lod",
            args.lod
        );
    }
    format!(
        "the scan produced an empty mesh: {leaves} leaves of {} m enclose no volume (too few \
         views of the object, or a leaf too coarse for it)",
        args.leaf
    )
}
