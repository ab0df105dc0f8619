//! `scan`: a full 3D scan, from depth frames to a watertight, printable mesh (STL, 3MF, PLY, OBJ).
//!
//! ```sh
//! cargo run --release --example scan                       # simulated scan of a built-in model → scan.stl
//! cargo run --release --example scan -- --input DIR        # a recorded scan (SCAN_FORMAT.md)
//! cargo run --release --example scan -- --help             # everything else
//! ```
//!
//! The stages: capture (or load) → filter → back-project, transform, clip → triangulate →
//! octree insertion → marching tetrahedra → mesh file (Z up for printing, `output.rs`). Each
//! stage is a call into one voxoct crate; this file only parses the command line, times the
//! stages and reports.

mod budget;
mod output;
mod outputs;
mod preview;
mod source;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{ArgMatches, CommandFactory, FromArgMatches, Parser, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

use voxoct::depth::filter::FilterChain;
use voxoct::mesh::{MeshOptions, Placement, Taubin};
use voxoct::pipeline::{Params, Reconstruction, reconstruct};

/// Output units of the STL file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Units {
    /// Millimetres: what every slicer assumes.
    Mm,
    /// Metres: the library's own unit.
    M,
}

/// Scan an object on a turntable into a watertight, printable STL.
///
/// With no arguments: a simulated Kinect v1 scan of a built-in model, written to scan.stl.
#[derive(Debug, Parser)]
#[command(name = "scan", version, about, long_about = None)]
struct Args {
    // ---- where the depth frames come from -------------------------------------------------
    /// Process a recorded-scan directory (scan.toml + 16-bit PNG frames).
    #[arg(long, value_name = "DIR", help_heading = "Source")]
    input: Option<PathBuf>,
    /// Process a libfreenect (fakenect) recording; needs --degrees-per-snapshot.
    #[arg(
        long,
        value_name = "DIR",
        help_heading = "Source",
        requires = "degrees_per_snapshot"
    )]
    fakenect: Option<PathBuf>,
    /// Turntable angle between consecutive snapshots of a fakenect recording.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "D",
        help_heading = "Source"
    )]
    degrees_per_snapshot: Option<f32>,
    /// Simulated scan of your own mesh (STL, OBJ, PLY or 3MF), read as slicers write it:
    /// Z up, millimetres (3MF: its own unit); it keeps its size and orientation.
    #[arg(long, value_name = "FILE", help_heading = "Source")]
    model: Option<PathBuf>,
    /// Units of the --model file's numbers (default: mm, or the unit a 3MF file states).
    #[arg(long, value_enum, value_name = "UNIT", help_heading = "Source")]
    model_units: Option<source::ModelUnits>,
    /// Up axis of the --model file.
    #[arg(long, value_enum, default_value = "z", help_heading = "Source")]
    model_up: output::Up,
    /// Simulated scan of a built-in model (see --list-models).
    #[arg(
        long,
        value_name = "NAME",
        default_value = "figurine",
        help_heading = "Source"
    )]
    builtin: String,
    /// Print the built-in model names and exit.
    #[arg(long, help_heading = "Source")]
    list_models: bool,
    /// Live scan with a Kinect v1 (build with `--features freenect`).
    #[arg(long, help_heading = "Source")]
    kinect: bool,
    /// Depth stream of a live scan: `mm` (the device's own calibration), `raw` (11-bit
    /// disparities converted as the fakenect replay converts them; what libfreenect 0.5's
    /// fakenect library serves) or `registered` (aligned to the RGB camera). Default: mm.
    #[arg(long, value_name = "MODE", help_heading = "Source")]
    kinect_depth: Option<voxoct::kinect::KinectDepth>,
    /// Let libfreenect print its own messages during a live scan (quiet by default).
    #[arg(short, long, help_heading = "Source")]
    verbose: bool,
    /// The turntable server (examples/turntable_server.rs on the Pi) for a live scan.
    #[arg(long, value_name = "HOST:PORT", help_heading = "Source")]
    turntable: Option<String>,
    /// Shared secret of the turntable server (or VOXOCT_TURNTABLE_TOKEN).
    #[arg(
        long,
        value_name = "T",
        env = "VOXOCT_TURNTABLE_TOKEN",
        hide_env_values = true,
        help_heading = "Source"
    )]
    token: Option<String>,
    /// Seed of the simulated sensor's noise.
    #[arg(long, default_value_t = 1, help_heading = "Source")]
    seed: u64,
    /// Simulate exact, noise-free frames.
    #[arg(long, help_heading = "Source")]
    exact: bool,
    /// Also write what was captured as a recorded-scan directory (new or empty).
    #[arg(long, value_name = "DIR", help_heading = "Source")]
    record_to: Option<PathBuf>,
    /// Let --record-to replace the recorded scan already in its directory.
    #[arg(long, requires = "record_to", help_heading = "Source")]
    force: bool,
    /// Scanner settings ([sensor], [rig], [clip] tables) overriding the source's own.
    #[arg(long, value_name = "FILE", help_heading = "Source")]
    config: Option<PathBuf>,
    /// Snapshots of a capture (turntable steps of 360°/N).
    #[arg(long, value_name = "N", default_value_t = 8, help_heading = "Source")]
    snapshots: u32,
    /// Frames per snapshot of a capture (fakenect: frames per snapshot).
    #[arg(long, value_name = "F", default_value_t = 4, help_heading = "Source")]
    frames: u32,

    // ---- reconstruction ---------------------------------------------------------------------
    /// Depth filter chain, e.g. `median+outlier`, `average`, `average-discard`, `basic`.
    #[arg(long, value_name = "NAME", help_heading = "Reconstruction")]
    filter: Option<String>,
    /// Leaf size, metres (the real leaf edge is root / 2^depth, at most this).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M",
        default_value_t = 0.001,
        help_heading = "Reconstruction"
    )]
    leaf: f32,
    /// Edge of the octree's cubic root, metres (centred on the clip box).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M",
        default_value_t = 1.0,
        help_heading = "Reconstruction"
    )]
    root: f32,
    /// Largest squared triangle edge kept by the triangulation, m².
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M2",
        default_value_t = 0.0001,
        help_heading = "Reconstruction"
    )]
    threshold: f32,
    /// Mesh N levels coarser than the leaves (level of detail).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        help_heading = "Reconstruction"
    )]
    lod: u32,

    // ---- meshing ---------------------------------------------------------------------------
    /// The thesis's mesh: binary leaf values, hollow double-walled shell, no smoothing.
    #[arg(long, help_heading = "Meshing")]
    thesis: bool,
    /// Keep the hollow double-walled shell instead of one solid with a flat base.
    #[arg(long, help_heading = "Meshing")]
    hollow: bool,
    /// Place vertices at the leaf centres' midpoints (binary field) instead of the surface.
    #[arg(long, help_heading = "Meshing")]
    binary: bool,
    /// Drop pieces of the mesh smaller than this fraction of the largest (0 keeps all).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "FRACTION",
        default_value_t = 0.01,
        help_heading = "Meshing"
    )]
    min_piece: f32,
    /// Do not fill the space no frame could see (the unseen underside stays open to the
    /// solid fill, which may then leave the shell hollow there).
    #[arg(long, help_heading = "Meshing")]
    no_carve: bool,
    /// Taubin smoothing iterations (0 = none).
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    smooth: Option<u32>,
    /// Simplify the mesh (quadric edge collapse, closed and valid kept) with this largest
    /// error, metres; a quarter of --leaf is a good value. Off unless this or --triangles.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M",
        help_heading = "Meshing"
    )]
    max_error: Option<f32>,
    /// Simplify down to at most N triangles (within --max-error, default a quarter leaf).
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    triangles: Option<usize>,
    /// Leaves hit by fewer triangles count as empty (rejects single errant readings).
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    min_hits: Option<u32>,
    /// Remove disconnected pieces of fewer leaves than this.
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    min_component: Option<usize>,

    // ---- output ----------------------------------------------------------------------------
    /// The mesh file to write; its extension picks the format: .stl, .3mf, .ply, .obj
    /// (`-`: standard output, with --format).
    #[arg(
        long,
        value_name = "FILE",
        default_value = "scan.stl",
        help_heading = "Output"
    )]
    out: PathBuf,
    /// Format of --out regardless of its extension: stl, 3mf, ply or obj.
    #[arg(long, value_name = "FORMAT", help_heading = "Output")]
    format: Option<String>,
    /// Write ASCII STL instead of binary.
    #[arg(long, help_heading = "Output")]
    ascii: bool,
    /// Units of the file's numbers (3MF records them).
    #[arg(long, value_enum, default_value = "mm", help_heading = "Output")]
    units: Units,
    /// Up axis of the file: z (for printing: base on z = 0, centred in x and y) or y (the
    /// library's platform frame).
    #[arg(long, value_enum, default_value = "z", help_heading = "Output")]
    up: output::Up,
    /// Write figures of the run as one JSON object.
    #[arg(long, value_name = "FILE.json", help_heading = "Output")]
    stats: Option<PathBuf>,
    /// Write a shaded picture of the result from three sides.
    #[arg(long, value_name = "FILE.png", help_heading = "Output")]
    preview: Option<PathBuf>,
    /// Refuse runs estimated to need more memory than this (e.g. 8G, 512M; default: half
    /// the machine's memory).
    #[arg(long, value_name = "BYTES", value_parser = budget::parse_bytes, help_heading = "Output")]
    max_memory: Option<u64>,
    /// No progress bars and no summary.
    #[arg(short, long, help_heading = "Output")]
    quiet: bool,
}

/// Seconds spent in each stage.
#[derive(Debug, Default, Serialize)]
struct Seconds {
    load: f64,
    filter: f64,
    agreement: f64,
    triangulate: f64,
    insert: f64,
    mesh: f64,
    write: f64,
    total: f64,
}

/// The `--stats` JSON object.
#[derive(Debug, Serialize)]
struct Stats {
    source: String,
    snapshots: usize,
    frames: usize,
    filter: String,
    triangles_in: usize,
    leaves: usize,
    leaf_size_m: f32,
    octree_depth: u32,
    octree_bytes: usize,
    mesh_triangles: usize,
    mesh_vertices: usize,
    mesh_components: usize,
    mesh_volume_m3: f64,
    mesh_area_m2: f64,
    closed_manifold: bool,
    /// How much the snapshots disagree under the rig, metres (null: not measurable).
    snapshot_disagreement_m: Option<f32>,
    /// What the sensor's noise explains; above it a warning is printed.
    snapshot_disagreement_limit_m: f32,
    self_intersecting_triangles: usize,
    valid_solid: bool,
    peak_rss_bytes: u64,
    threads: usize,
    seconds: Seconds,
}

fn main() -> ExitCode {
    let matches = Args::command().get_matches();
    let args = Args::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Err(e) = voxoct::output::remove_temporary_files_on_signal() {
        eprintln!("error: cannot install the signal handlers: {e}");
        return ExitCode::FAILURE;
    }
    match run(&args, &matches) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", voxoct::output::terminal_safe(&e.to_string()));
            ExitCode::FAILURE
        }
    }
}

/// Stage progress: a spinner per stage on a terminal, nothing otherwise or with `-q`.
struct Progress {
    enabled: bool,
}

impl Progress {
    fn stage(&self, name: &str, len: Option<u64>) -> ProgressBar {
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

fn run(args: &Args, matches: &ArgMatches) -> Result<(), String> {
    if args.list_models {
        for name in voxoct::kinect::Model::BUILTIN_NAMES {
            println!("{name}");
        }
        return Ok(());
    }
    check_args(args)?;
    budget::check_flags(args, matches)?;
    let outputs::Planned {
        mut outputs,
        out,
        stats: stats_out,
        preview: preview_out,
    } = outputs::plan(args)?;
    let progress = Progress {
        enabled: !args.quiet && std::io::stderr().is_terminal(),
    };
    let t_start = Instant::now();
    let mut seconds = Seconds::default();

    // 1. Capture or load.
    let t = Instant::now();
    let acquired = source::acquire(args, &progress)?;
    seconds.load = t.elapsed().as_secs_f64();
    if let Some(dir) = &args.record_to {
        if args.force {
            outputs::clear_record_to(dir)?;
        }
        source::record(&acquired, dir)?;
    }
    let source::Acquired {
        settings,
        snapshots,
    } = acquired;
    let n_snapshots = snapshots.len();
    let n_frames: usize = snapshots.iter().map(|s| s.frames.len()).sum();

    // 2–5. Filter, back-project, triangulate, insert, mesh.
    let params = Params {
        filter: match &args.filter {
            Some(name) => name.parse().map_err(|e| format!("--filter: {e}"))?,
            None => FilterChain::default(),
        },
        leaf_m: args.leaf,
        root_m: args.root,
        max_edge_sq: args.threshold,
        lod: args.lod,
        mesh: mesh_options(args),
        carve: !args.no_carve,
        check_agreement: true,
        min_piece_fraction: args.min_piece,
        simplify: (args.max_error.is_some() || args.triangles.is_some()).then(|| {
            voxoct::mesh::Simplify {
                max_error: args
                    .max_error
                    .unwrap_or(voxoct::mesh::Simplify::LEAF_FRACTION * args.leaf),
                target_triangles: args.triangles,
            }
        }),
    };
    let mut bar: Option<ProgressBar> = None;
    let result = reconstruct(&settings.config, snapshots, &params, |stage| {
        if let Some(b) = bar.take() {
            b.finish_and_clear();
        }
        bar = Some(progress.stage(&format!("{stage:?}").to_lowercase(), None));
    });
    if let Some(b) = bar.take() {
        b.finish_and_clear();
    }
    let Reconstruction {
        mesh,
        tree,
        triangles_in,
        timings,
        disagreement_m,
    } = result.map_err(|e| e.to_string())?;
    let agreement_limit_m =
        voxoct::pipeline::disagreement_explained_m(settings.config.rig.sensor_position_m.length());
    if let Some(d) = disagreement_m.filter(|&d| d > agreement_limit_m) {
        eprintln!(
            "warning: the snapshots disagree by {:.1} mm, more than the sensor's noise explains ({:.1} mm): \
             the rig (tilt, sensor position) is off and the mesh may show doubled contours; \
             fix it with `calibrate --input DIR --write` (record with --record-to first)",
            d * 1e3,
            agreement_limit_m * 1e3
        );
    }
    seconds.filter = timings.filter.as_secs_f64();
    seconds.agreement = timings.agreement.as_secs_f64();
    seconds.triangulate = timings.triangulate.as_secs_f64();
    seconds.insert = timings.insert.as_secs_f64();
    seconds.mesh = timings.mesh.as_secs_f64();
    let closed = mesh.check_closed_manifold();
    if mesh.triangles.is_empty() {
        return Err(budget::explain_empty(args, triangles_in, tree.leaf_count()));
    }

    // 6. Write the mesh, the preview and the stats; they replace the old files together.
    let t = Instant::now();
    outputs
        .write(out, |w| output::write(args, &mesh, &tree, w))
        .map_err(|e| e.to_string())?;
    seconds.write = t.elapsed().as_secs_f64();
    if let Some(id) = preview_out {
        outputs
            .write(id, |w| {
                preview::write_preview(w, &mesh.vertices, &mesh.triangles)
            })
            .map_err(|e| e.to_string())?;
    }
    seconds.total = t_start.elapsed().as_secs_f64();

    let mstats = mesh.stats();
    let self_intersecting = mesh.self_intersecting_triangles().len();
    let stats = Stats {
        source: settings.source.clone(),
        snapshots: n_snapshots,
        frames: n_frames,
        filter: params.filter.to_string(),
        triangles_in,
        leaves: tree.leaf_count(),
        leaf_size_m: tree.leaf_edge(),
        octree_depth: tree.depth(),
        octree_bytes: tree.memory_bytes(),
        mesh_triangles: mesh.triangles.len(),
        mesh_vertices: mesh.vertices.len(),
        mesh_components: mstats.components,
        mesh_volume_m3: mstats.volume,
        mesh_area_m2: mstats.area,
        closed_manifold: closed.is_ok(),
        snapshot_disagreement_m: disagreement_m,
        snapshot_disagreement_limit_m: agreement_limit_m,
        self_intersecting_triangles: self_intersecting,
        valid_solid: closed.is_ok() && self_intersecting == 0,
        peak_rss_bytes: peak_rss_bytes(),
        threads: rayon::current_num_threads(),
        seconds,
    };
    if let Some(id) = stats_out {
        let json = serde_json::to_string_pretty(&stats).map_err(|e| format!("stats: {e}"))?;
        outputs
            .write(id, |w| w.write_all(json.as_bytes()))
            .map_err(|e| e.to_string())?;
    }
    outputs.commit().map_err(|e| e.to_string())?;
    if !args.quiet {
        summary(args, &stats);
    }
    closed.map_err(|e| {
        format!("internal error: the mesh is not closed ({e}); please report this with the scan")
    })?;
    Ok(())
}

/// The meshing options the flags ask for: the best quality unless told otherwise.
fn mesh_options(args: &Args) -> MeshOptions {
    let mut o = if args.thesis {
        MeshOptions::thesis()
    } else {
        MeshOptions::smooth()
    };
    if args.hollow {
        o.solid = false;
    }
    if args.binary {
        o.placement = Placement::Midpoint;
    }
    if let Some(n) = args.smooth {
        o.smoothing = (n > 0).then(|| Taubin {
            iterations: n,
            ..Taubin::default()
        });
    }
    if let Some(h) = args.min_hits {
        o.min_hits = h;
    }
    if let Some(c) = args.min_component {
        o.min_component_cells = c;
    }
    o
}

/// Rejects contradictory or out-of-range flags before any work is done.
fn check_args(args: &Args) -> Result<(), String> {
    let sources = [
        args.input.is_some(),
        args.fakenect.is_some(),
        args.model.is_some(),
        args.kinect,
    ]
    .iter()
    .filter(|&&b| b)
    .count();
    if sources > 1 {
        return Err("choose one source: --input, --fakenect, --model or --kinect".into());
    }
    let positive = |name: &str, v: f32| -> Result<(), String> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(format!(
                "{name} must be a positive number of metres, got {v}"
            ))
        }
    };
    positive("--leaf", args.leaf)?;
    positive("--root", args.root)?;
    if args.leaf > args.root {
        return Err(format!(
            "--leaf {} is larger than the octree root --root {}",
            args.leaf, args.root
        ));
    }
    if !(args.threshold.is_finite() && args.threshold > 0.0) {
        return Err(format!(
            "--threshold must be a positive squared edge length in m², got {}",
            args.threshold
        ));
    }
    if let Some(e) = args.max_error
        && !(e.is_finite() && e >= 0.0)
    {
        return Err(format!(
            "--max-error must be a non-negative number of metres, got {e}"
        ));
    }
    if !(0.0..=1.0).contains(&args.min_piece) {
        return Err(format!(
            "--min-piece must be a fraction between 0 and 1, got {}",
            args.min_piece
        ));
    }
    if args.snapshots == 0 || args.snapshots > 3600 {
        return Err(format!(
            "--snapshots must be between 1 and 3600, got {}",
            args.snapshots
        ));
    }
    if args.frames == 0 || args.frames > 1000 {
        return Err(format!(
            "--frames must be between 1 and 1000, got {}",
            args.frames
        ));
    }
    if let Some(d) = args.degrees_per_snapshot
        && (!d.is_finite() || d.abs() > 360.0)
    {
        return Err(format!(
            "--degrees-per-snapshot must be a finite angle within ±360, got {d}"
        ));
    }
    if args.turntable.is_some() && !args.kinect {
        return Err("--turntable is for live scans: add --kinect".into());
    }
    if args.kinect_depth.is_some() && !args.kinect {
        return Err("--kinect-depth is for live scans: add --kinect".into());
    }
    output::check(args)?;
    Ok(())
}

/// Peak resident set size of this process (Linux `VmHWM`), 0 where unknown.
fn peak_rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// The short report at the end of a run.
fn summary(args: &Args, s: &Stats) {
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
        args.out.display(),
        output::describe(args)
    );
}
