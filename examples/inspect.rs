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

use voxoct::depth::{
    FilterChain, RecordedScan, Snapshot, depth_image, difference_image, snapshot_image,
    views_image, write_png,
};

/// Pictures of a recorded scan: frames, filtered snapshots, filter differences, point views.
#[derive(Debug, Parser)]
#[command(name = "inspect", version, about, long_about = None)]
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
    #[arg(long, value_name = "MM")]
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
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
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
    let scan = RecordedScan::open(&args.input)?;
    let chain = FilterChain::parse(&args.filter)?;
    if let (Some(k), Some(out)) = (args.snapshot, &args.out) {
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
            println!(
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
            img
        } else {
            snapshot_image(frames, &chain.apply(frames)?)?
        };
        write_png(out, &img)?;
        println!("wrote {}", out.display());
    }
    if let Some(path) = &args.views {
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
        write_png(path, &views_image(&snaps, 600))?;
        println!(
            "wrote {} (left: top view, +z down; right: side view; one colour per snapshot)",
            path.display()
        );
    }
    Ok(())
}
