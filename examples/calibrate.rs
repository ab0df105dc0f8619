//! `calibrate`: the rig of a recorded scan, measured from the scan itself.
//!
//! ```sh
//! cargo run --release --example calibrate -- --input DIR                 # print the rig
//! cargo run --release --example calibrate -- --input DIR --write         # update DIR/scan.toml
//! cargo run --release --example calibrate -- --input DIR --platform EMPTY --preview top.png
//! ```
//!
//! The platform plane (from `--platform`, a scan of the empty platform, or else from the
//! turntable disk around the object) gives the sensor's tilt and height; the agreement of
//! the snapshots over a full turn gives the sensor's horizontal position (the turntable
//! axis). The rig in the scan's `scan.toml` is the starting point: it may be off by a
//! centimetre and a few degrees.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use serde::Serialize;

use voxoct::depth::Rig;
use voxoct::depth::calib::{
    AxisOptions, CalibOptions, CalibSnapshot, Calibration, calibrate, calibrate_with_platform,
};
use voxoct::depth::filter::FilterChain;
use voxoct::depth::image::{views_image, write_png_to};
use voxoct::depth::scan::{MANIFEST_FILE, RecordedScan, set_rig_in_manifest_text};
use voxoct::depth::snapshot::Snapshot;
use voxoct::output::Outputs;

/// Measure a recorded scan's rig (tilt and sensor position) from the scan itself.
#[derive(Debug, Parser)]
#[command(name = "calibrate", version, long_about = None)]
struct Args {
    /// The recorded scan of an object over a full turn (scan.toml + frames).
    #[arg(long, value_name = "DIR")]
    input: PathBuf,
    /// A recorded scan of the empty platform, for the tilt and height.
    #[arg(long, value_name = "DIR")]
    platform: Option<PathBuf>,
    /// Write the calibrated rig into DIR/scan.toml (atomically; only the [rig] values change,
    /// comments and other keys are kept; a symlink's target is updated).
    #[arg(long)]
    write: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Write the top and side views of the aligned snapshots to this PNG.
    #[arg(long, value_name = "FILE.png")]
    preview: Option<PathBuf>,
    /// Filter chain for each snapshot's frames.
    #[arg(long, default_value = "average+outlier")]
    filter: String,
    /// Also minimise the tilt over the snapshots' agreement (default: from the plane only).
    #[arg(long)]
    free_tilt: bool,
}

#[derive(Serialize)]
struct Report {
    tilt_deg: f32,
    sensor_position_m: [f32; 3],
    residual_before_m: f32,
    residual_after_m: f32,
    start_tilt_deg: f32,
    start_sensor_position_m: [f32; 3],
    platform_roll_deg: Option<f32>,
    iterations: u32,
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
    let chain = FilterChain::parse(&args.filter)?;
    // Every output is checked before the scan is read; all are written together at the end.
    let manifest_path = args.input.join(MANIFEST_FILE);
    let mut outputs = Outputs::new();
    let preview_id = args
        .preview
        .as_deref()
        .map(|p| outputs.add("--preview", p))
        .transpose()?;
    let write_id = args
        .write
        .then(|| outputs.add("--write", &manifest_path))
        .transpose()?;
    let scan = RecordedScan::open(&args.input)?;
    let snaps = CalibSnapshot::from_scan(&scan, &chain)?;
    let platform = match &args.platform {
        Some(dir) => Some(CalibSnapshot::from_scan(&RecordedScan::open(dir)?, &chain)?),
        None => None,
    };
    let m = &scan.manifest;
    let start = m.rig;
    let axis = AxisOptions {
        free_tilt: args.free_tilt,
        ..AxisOptions::default()
    };
    let opts = CalibOptions {
        axis,
        ..CalibOptions::default()
    };
    let cal = match &platform {
        Some(p) => calibrate_with_platform(&m.config(), &snaps, p, &opts)?,
        None => calibrate(&m.config(), &snaps, &opts)?,
    };
    if let Some(id) = preview_id {
        let views = snaps
            .iter()
            .map(|s| {
                Snapshot::from_frame(
                    &s.frame,
                    &m.sensor.intrinsics,
                    &cal.rig,
                    s.angle_deg,
                    &m.clip,
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        outputs.write(id, |w| write_png_to(w, &views_image(&views, 600)))?;
    }
    if args.json {
        let report = Report {
            tilt_deg: cal.rig.tilt_deg,
            sensor_position_m: cal.rig.sensor_position_m.to_array(),
            residual_before_m: cal.residual_before_m,
            residual_after_m: cal.residual_after_m,
            start_tilt_deg: start.tilt_deg,
            start_sensor_position_m: start.sensor_position_m.to_array(),
            platform_roll_deg: cal.platform.map(|p| p.roll_deg),
            iterations: cal.iterations,
        };
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_text(&start, &cal);
        if let Some(path) = &args.preview {
            println!(
                "# preview (top | side view, one colour per snapshot): {}",
                path.display()
            );
        }
    }
    if let Some(id) = write_id {
        let text = std::fs::read_to_string(&manifest_path)
            .map_err(|e| format!("{}: {e}", manifest_path.display()))?;
        let edited = set_rig_in_manifest_text(&text, &cal.rig, &manifest_path)?;
        outputs.write(id, |w| w.write_all(edited.as_bytes()))?;
    }
    outputs.commit()?;
    if args.write && !args.json {
        println!("# written to {}", manifest_path.display());
    }
    Ok(())
}

fn print_text(start: &Rig, cal: &Calibration) {
    let p = cal.rig.sensor_position_m;
    let s = start.sensor_position_m;
    println!(
        "# disagreement between snapshots: {:.2} mm before, {:.2} mm after ({} iterations)",
        cal.residual_before_m * 1e3,
        cal.residual_after_m * 1e3,
        cal.iterations
    );
    match &cal.platform {
        Some(f) => println!(
            "# platform plane: {} inliers, rms {:.2} mm, roll {:.2}° (the rig assumes 0)",
            f.plane.inliers,
            f.plane.rms_m * 1e3,
            f.roll_deg
        ),
        None => {
            println!("# no platform plane found: tilt from the snapshots' agreement, height kept")
        }
    }
    println!(
        "# change: tilt {:+.3}°, position ({:+.2}, {:+.2}, {:+.2}) mm",
        cal.rig.tilt_deg - start.tilt_deg,
        (p.x - s.x) * 1e3,
        (p.y - s.y) * 1e3,
        (p.z - s.z) * 1e3
    );
    println!("[rig]");
    println!("tilt_deg = {:.4}", cal.rig.tilt_deg);
    println!(
        "sensor_position_m = [{}, {}, {}]",
        decimals(p.x, 5),
        decimals(p.y, 5),
        decimals(p.z, 5)
    );
}

/// `x` with `n` decimals, without the sign of a negative zero ("-0.00000").
fn decimals(x: f32, n: usize) -> String {
    let s = format!("{x:.n$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_owned()
    } else {
        s
    }
}
