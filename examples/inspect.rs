//! `inspect`: pictures of a recorded scan's depth data.
//!
//! ```sh
//! # snapshot 0 filtered, grey (nearer lighter), pixels missed by some frame in red
//! cargo run --release --example inspect -- --input DIR --snapshot 0 --out s0.png
//! # one raw frame
//! cargo run --release --example inspect -- --input DIR --snapshot 0 --frame 3 --out f3.png
//! # the difference of two filters on snapshot 0 (red: the first farther, blue: nearer)
//! cargo run --release --example inspect -- --input DIR --snapshot 0 --filter basic --versus average --out d.png
//! # top and side view of all snapshots in the common frame
//! cargo run --release --example inspect -- --input DIR --views views.png
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

use voxoct::depth::filter::FilterChain;
use voxoct::depth::image::{
    depth_image, difference_image, snapshot_image, views_image, write_png_to,
};
use voxoct::depth::scan::RecordedScan;
use voxoct::depth::snapshot::Snapshot;
use voxoct::output::Outputs;

/// Pictures of a recorded scan: frames, filtered snapshots, filter differences, point views.
#[derive(Debug, Parser)]
#[command(name = "inspect", version, long_about = None)]
struct Args {
    /// The recorded scan (scan.toml + frames).
    #[arg(long, value_name = "DIR")]
    input: PathBuf,
    /// The snapshot to show (0-based).
    #[arg(long, value_name = "K", requires = "out")]
    snapshot: Option<usize>,
    /// Show this raw frame of the snapshot instead of the filtered snapshot.
    #[arg(
        long,
        value_name = "J",
        requires = "snapshot",
        conflicts_with = "versus"
    )]
    frame: Option<usize>,
    /// Filter chain of the snapshot image (the first of a difference).
    #[arg(long, default_value = "average+outlier")]
    filter: String,
    /// Show the difference between --filter and this filter chain.
    #[arg(long, value_name = "CHAIN", requires = "snapshot")]
    versus: Option<String>,
    /// Full colour of a difference at this many millimetres (default: 99th percentile).
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    scale_mm: Option<f32>,
    /// Output PNG of --snapshot.
    #[arg(long, value_name = "FILE.png")]
    out: Option<PathBuf>,
    /// Write the top and side views of all snapshots (clipped, common frame) to this PNG.
    #[arg(long, value_name = "FILE.png")]
    views: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    if let Err(e) = voxoct::output::remove_temporary_files_on_signal() {
        eprintln!("error: cannot install the signal handlers: {e}");
        return ExitCode::FAILURE;
    }
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", voxoct::output::terminal_safe(&e.to_string()));
            ExitCode::FAILURE
        }
    }
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    if args.snapshot.is_none() && args.views.is_none() {
        return Err(
            "nothing to do: give --snapshot K --out FILE.png and/or --views FILE.png".into(),
        );
    }
    if let Some(s) = args.scale_mm
        && !(s.is_finite() && s > 0.0)
    {
        return Err(format!("--scale-mm must be a positive number of millimetres, got {s}").into());
    }
    if args.out.is_some() && args.snapshot.is_none() {
        return Err("--out is the picture of --snapshot K: add --snapshot".into());
    }
    // Every output is checked before the scan is read; all are written together at the end.
    let mut outputs = Outputs::new();
    let out_id = args
        .out
        .as_deref()
        .map(|p| outputs.add("--out", p))
        .transpose()?;
    let views_id = args
        .views
        .as_deref()
        .map(|p| outputs.add("--views", p))
        .transpose()?;
    let stdout_taken = [out_id, views_id]
        .into_iter()
        .flatten()
        .any(|id| outputs.is_stdout(id));
    let chain = FilterChain::parse(&args.filter)?;
    let scan = RecordedScan::open(&args.input)?;
    let mut said = Vec::new();
    if let (Some(k), Some(out), Some(out_id)) = (args.snapshot, &args.out, out_id) {
        let frames = scan.frames.get(k).ok_or_else(|| {
            format!(
                "--snapshot {k}: the scan has {} snapshots (0 to {})",
                scan.len(),
                scan.len().saturating_sub(1)
            )
        })?;
        let img = if let Some(j) = args.frame {
            let f = frames.get(j).ok_or_else(|| {
                format!(
                    "--frame {j}: snapshot {k} has {} frames (0 to {})",
                    frames.len(),
                    frames.len().saturating_sub(1)
                )
            })?;
            depth_image(f)?
        } else if let Some(versus) = &args.versus {
            let a = chain.apply(frames)?;
            let b = FilterChain::parse(versus)?.apply(frames)?;
            let (img, st) = difference_image(&a, &b, args.scale_mm.map(|s| s * 1e-3))?;
            let line = format!(
                "{} − {versus}: {} pixels in both, {} only in the first, {} only in the second; \
                 mean |difference| {:.3} mm, max {:.2} mm, full colour at {:.2} mm",
                args.filter,
                st.both,
                st.only_a,
                st.only_b,
                st.mean_abs_m * 1e3,
                st.max_abs_m * 1e3,
                st.scale_m * 1e3
            );
            said.push(line);
            img
        } else {
            snapshot_image(frames, &chain.apply(frames)?)?
        };
        outputs.write(out_id, |w| write_png_to(w, &img))?;
        said.push(format!("wrote {}", out.display()));
    }
    if let (Some(path), Some(views_id)) = (&args.views, views_id) {
        let m = &scan.manifest;
        let snaps = m
            .snapshots
            .iter()
            .zip(&scan.frames)
            .map(|(s, frames)| {
                Snapshot::from_frame(
                    &chain.apply(frames)?,
                    &m.sensor.intrinsics,
                    &m.rig,
                    s.angle_deg,
                    &m.clip,
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        outputs.write(views_id, |w| write_png_to(w, &views_image(&snaps, 600)))?;
        said.push(format!(
            "wrote {} (left: top view, +z down; right: side view; one colour per snapshot)",
            path.display()
        ));
    }
    outputs.commit()?;
    for line in said {
        if stdout_taken {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    }
    Ok(())
}
