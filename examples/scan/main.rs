//! `scan`: a full 3D scan, from depth frames to a watertight, printable mesh (STL, 3MF, PLY, OBJ).
//!
//! ```sh
//! cargo run --release --example scan                       # simulated scan of a built-in model → scan.stl
//! cargo run --release --example scan -- --input DIR        # a recorded scan (SCAN_FORMAT.md)
//! cargo run --release --example scan -- --help             # everything else
//! ```
//!
//! The stages: capture or load ([`voxoct::session`]) → filter, back-project, triangulate,
//! insert, mesh ([`voxoct::pipeline`]) → mesh file ([`voxoct::mesh_file`]), preview
//! ([`voxoct::preview`]) and stats, all replaced together ([`voxoct::output`]). This file
//! parses the command line (`args.rs`), calls the library, times the stages and reports
//! (`report.rs`).

mod args;
mod report;

use std::io::IsTerminal;
use std::process::ExitCode;
use std::time::Instant;

use clap::{ArgMatches, CommandFactory, FromArgMatches};
use indicatif::ProgressBar;

use voxoct::mesh_file::MeshFile;
use voxoct::output::{OutputId, Outputs};
use voxoct::pipeline::{Params, Reconstruction, disagreement_explained_m, reconstruct};
use voxoct::session::{self, Acquired, Event, Session};

use args::Args;
use report::{Progress, Seconds, Stats};

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
            eprintln!("error: {}", voxoct::output::terminal_safe(&e));
            ExitCode::FAILURE
        }
    }
}

/// The outputs of a run, planned before any frame is read.
struct Planned {
    outputs: Outputs,
    out: OutputId,
    stats: Option<OutputId>,
    preview: Option<OutputId>,
}

fn plan(args: &Args, session: &Session) -> Result<Planned, String> {
    let mut outputs = Outputs::new();
    let e = |e: voxoct::output::OutputError| e.to_string();
    let out = outputs.add("--out", &args.out).map_err(e)?;
    let mut add = |flag, p: &Option<std::path::PathBuf>| {
        p.as_deref()
            .map(|p| outputs.add(flag, p))
            .transpose()
            .map_err(e)
    };
    let stats = add("--stats", &args.stats)?;
    let preview = add("--preview", &args.preview)?;
    if let Some(dir) = &args.record_to {
        session::check_record_dir(dir, session.source.input_dir(), args.force)
            .map_err(|e| e.to_string())?;
    }
    Ok(Planned {
        outputs,
        out,
        stats,
        preview,
    })
}

fn run(args: &Args, matches: &ArgMatches) -> Result<(), String> {
    if args.list_models {
        for name in voxoct::kinect::Model::BUILTIN_NAMES {
            println!("{name}");
        }
        return Ok(());
    }
    // Every flag is checked before any work: by the library, where each value is used.
    args.check_sources(matches)?;
    let params = args.params()?;
    params.validate().map_err(|e| e.to_string())?;
    let session = args.session();
    session.validate().map_err(|e| e.to_string())?;
    let file = args.mesh_file()?;
    let planned = plan(args, &session)?;
    let progress = Progress {
        enabled: !args.quiet && std::io::stderr().is_terminal(),
    };
    let t_start = Instant::now();

    let acquired = acquire(args, &session, &params, &progress)?;
    let load = t_start.elapsed();
    let source = acquired.source.clone();
    let (n_snapshots, n_frames) = (
        acquired.snapshots.len(),
        acquired.snapshots.iter().map(|s| s.frames.len()).sum(),
    );
    let limit_m = disagreement_explained_m(acquired.config.rig.sensor_position_m.length());
    let clip_floor_m = acquired.config.clip.min.y;
    let result = reconstruct_with_progress(acquired, &params, &progress)?;
    report::warn_if_disagreeing(result.disagreement_m, limit_m);
    if result.mesh.triangles.is_empty() {
        let leaves = result.tree.leaf_count();
        return Err(report::explain_empty(
            args,
            result.triangles_in,
            leaves,
            clip_floor_m,
        ));
    }
    let closed = result.mesh.check_closed_manifold();
    let facts = (limit_m, closed.is_ok());
    let mut stats = Stats::new(source, (n_snapshots, n_frames), &params, &result, facts);
    stats.seconds = Seconds::of(load, &result.timings);
    write_outputs(planned, &file, &result, &mut stats, t_start)?;
    if !args.quiet {
        report::summary(&stats, &args.out, &file);
    }
    closed.map_err(|e| {
        format!("internal error: the mesh is not closed ({e}); please report this with the scan")
    })
}

/// Writes the mesh, the preview and the stats; they replace the old files together.
fn write_outputs(
    mut planned: Planned,
    file: &MeshFile,
    result: &Reconstruction,
    stats: &mut Stats,
    t_start: Instant,
) -> Result<(), String> {
    let e = |e: voxoct::output::OutputError| e.to_string();
    let (mesh, o) = (&result.mesh, &mut planned.outputs);
    let t = Instant::now();
    o.write(planned.out, |w| file.write(mesh, &result.tree, w))
        .map_err(e)?;
    stats.seconds.write = t.elapsed().as_secs_f64();
    if let Some(id) = planned.preview {
        o.write(id, |w| {
            voxoct::preview::write_preview(w, &mesh.vertices, &mesh.triangles)
        })
        .map_err(e)?;
    }
    stats.seconds.total = t_start.elapsed().as_secs_f64();
    stats.peak_rss_bytes = voxoct::budget::peak_rss_bytes();
    if let Some(id) = planned.stats {
        let json = serde_json::to_string_pretty(&stats).map_err(|e| format!("stats: {e}"))?;
        o.write(id, |w| w.write_all(json.as_bytes())).map_err(e)?;
    }
    planned.outputs.commit().map_err(e)
}

/// Captures or loads the frames, with a progress bar, and records them with `--record-to`.
fn acquire(
    args: &Args,
    session: &session::Session,
    params: &Params,
    progress: &Progress,
) -> Result<Acquired, String> {
    // Live captures log each snapshot and turn (the bar only shows on a terminal).
    let log = args.kinect && !args.quiet;
    let mut pb = ProgressBar::hidden();
    let acquired = session
        .acquire(params, |event| match event {
            Event::Loading(dir) => {
                pb = progress.stage("load", None);
                pb.set_message(dir.display().to_string());
            }
            Event::SensorOpen(depth) if log => {
                eprintln!("capture: Kinect v1 open, depth mode {depth}");
            }
            Event::CaptureStarted(n) => pb = progress.stage("capture", Some(u64::from(n))),
            Event::Snapshot {
                index,
                of,
                angle_deg,
                frames,
            } => {
                if log {
                    pb.suspend(|| {
                        eprintln!(
                            "capture: snapshot {}/{of} at {angle_deg}°: {frames} frames",
                            index + 1
                        );
                    });
                }
                pb.inc(1);
            }
            Event::Turned { by_deg, asked_deg } if log => {
                pb.suspend(|| eprintln!("turntable: turned by {by_deg}° (asked {asked_deg}°)"));
            }
            Event::Loaded | Event::CaptureDone => pb.finish_and_clear(),
            _ => {}
        })
        .map_err(|e| e.to_string())?;
    if let Some(dir) = &args.record_to {
        if args.force {
            session::clear_recorded_scan(dir).map_err(|e| e.to_string())?;
        }
        session::record(&acquired, dir).map_err(|e| e.to_string())?;
    }
    Ok(acquired)
}

/// [`reconstruct`] with a spinner per stage.
fn reconstruct_with_progress(
    acquired: Acquired,
    params: &Params,
    progress: &Progress,
) -> Result<Reconstruction, String> {
    let mut bar: Option<ProgressBar> = None;
    let result = reconstruct(&acquired.config, acquired.snapshots, params, |stage| {
        if let Some(b) = bar.take() {
            b.finish_and_clear();
        }
        bar = Some(progress.stage(&format!("{stage:?}").to_lowercase(), None));
    });
    if let Some(b) = bar.take() {
        b.finish_and_clear();
    }
    result.map_err(|e| e.to_string())
}
