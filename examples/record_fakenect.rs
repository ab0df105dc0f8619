//! `record_fakenect`: the simulator's frames as a libfreenect **fakenect** recording, laid out
//! in the order a live scan (`scan --kinect`) consumes them — to rehearse a live scan without a
//! Kinect or a turntable.
//!
//! ```sh
//! cargo run --release --example record_fakenect -- --out rec --expected expected \
//!     --snapshots 4 --frames 3
//! cargo run --release --example turntable_server -- --listen 127.0.0.1:7899 &
//! FAKENECT_PATH=rec LD_LIBRARY_PATH=/usr/lib/x86_64-linux-gnu/fakenect \
//!   cargo run --release --features freenect --example scan -- --kinect --kinect-depth raw \
//!     --turntable 127.0.0.1:7899 --snapshots 4 --frames 3 --config expected/scan.toml
//! ```
//!
//! # The frame order of a live scan
//! `scan --kinect --snapshots N --frames F` opens the Kinect, which grabs (and discards) one
//! frame; it homes the turntable, then for each snapshot `k` of `0..N` it reads the table's
//! angle, grabs `F` frames, and — except after the last snapshot — turns the table by
//! `360°/N` and waits until it has stopped. So it consumes `1 + N·F` depth frames:
//!
//! | frames | what |
//! |---|---|
//! | 1 (`--lead-in`) | opening the device |
//! | `F` per snapshot, `N` times | snapshot `k` at the angle the table reports after `k` turns |
//! | `--tail` more | never grabbed: they keep fakenect's runloop alive until the scan stops it |
//!
//! The simulated object is turned exactly as the table turns it: a simulated table with the
//! same microsteps per revolution (`--microsteps-per-rev`, 800 like `turntable_server`'s
//! default quarter stepping of a 200-step motor) is turned by `360°/N` between snapshots and
//! the frames are rendered at the angle it reports, so angles that are not whole microsteps
//! are rounded as the real table rounds them.
//!
//! # Timing
//! The fakenect library replays one frame every `--interval-ms` (the recorded gaps), whether
//! or not the scan grabs; libfreenect_sync keeps only the newest frame. A scan that spends
//! longer than the interval between two grabs (turning the table, say) loses frames and then
//! takes later ones, so the interval must exceed the table's turning time (`turntable_server`
//! turns instantly unless `--sim-speed` is given). `--expected DIR` writes what the scan
//! should capture as a recorded scan (SCAN_FORMAT.md) — read back from the recording with
//! voxoct's own fakenect reader — so a rehearsal can check it frame for frame
//! (`.ci/live_scan.sh` does). Its `scan.toml` also holds the rig to pass as `--config`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::Parser;
use voxoct::depth::ScannerConfig;
use voxoct::depth::scan::ScanWriter;
use voxoct::kinect::{
    DepthFrame, DepthSource, FAKENECT_HEIGHT, FAKENECT_WIDTH, FakenectSource, FakenectWriter,
    Model, SimConfig, SimulatedKinect,
};
use voxoct::session::Event;
use voxoct::turntable::SimulatedTurntable;

/// Write simulated Kinect v1 frames as a fakenect recording for a rehearsed live scan.
#[derive(Debug, Parser)]
#[command(name = "record_fakenect", version)]
struct Args {
    /// The fakenect recording to write (INDEX.txt + d-*.pgm); must be new or empty.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Also write the frames the live scan should capture as a recorded scan (its scan.toml
    /// is the --config for the live scan).
    #[arg(long, value_name = "DIR")]
    expected: Option<PathBuf>,
    /// Snapshots the live scan will take (turns of 360°/N).
    #[arg(long, value_name = "N", default_value_t = 4)]
    snapshots: u32,
    /// Frames per snapshot the live scan will take.
    #[arg(long, value_name = "F", default_value_t = 3)]
    frames: u32,
    /// Frames before the first snapshot (opening the Kinect consumes one).
    #[arg(long, value_name = "K", default_value_t = 1)]
    lead_in: u32,
    /// Frames after the last snapshot, never grabbed: they keep libfreenect 0.5's fakenect
    /// runloop going until the scan stops it (it ends at the end of INDEX.txt).
    #[arg(long, value_name = "K", default_value_t = 5)]
    tail: u32,
    /// Recorded time between frames (the replay's frame period), milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 400)]
    interval_ms: u64,
    /// Microsteps per revolution of the turntable the live scan will use.
    #[arg(long, value_name = "STEPS", default_value_t = 800)]
    microsteps_per_rev: u64,
    /// A built-in model (see `scan --list-models`).
    #[arg(long, value_name = "NAME", default_value = "figurine")]
    builtin: String,
    /// Your own mesh (STL or OBJ) instead of a built-in model.
    #[arg(long, value_name = "FILE")]
    model: Option<PathBuf>,
    /// Scanner settings ([sensor], [rig], [clip]) instead of the simulator's defaults.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Seed of the simulated sensor's noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Noise-free frames.
    #[arg(long)]
    exact: bool,
}

fn main() -> ExitCode {
    match run(&Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("record_fakenect: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: &Args) -> Result<(), String> {
    if args.snapshots == 0 || args.snapshots > 3600 || args.frames == 0 || args.frames > 1000 {
        return Err(format!(
            "--snapshots must be 1..=3600 and --frames 1..=1000, got {} and {}",
            args.snapshots, args.frames
        ));
    }
    if args.interval_ms == 0 {
        return Err("--interval-ms must be positive".into());
    }
    let model = match &args.model {
        Some(path) => {
            let mut m = voxoct::kinect::load_model(path).map_err(|e| format!("--model: {e}"))?;
            m.place_on_platform(0.12)
                .map_err(|e| format!("--model {}: {e}", path.display()))?;
            m
        }
        None => Model::builtin(&args.builtin).ok_or_else(|| {
            format!(
                "--builtin {}: unknown model; choose one of {}",
                args.builtin,
                Model::BUILTIN_NAMES.join(", ")
            )
        })?,
    };
    let config = match &args.config {
        Some(p) => ScannerConfig::from_file(p).map_err(|e| format!("--config: {e}"))?,
        None => voxoct::session::scanner_config_of(&SimConfig::default()),
    };
    let intrinsics = config.sensor.intrinsics;
    if (intrinsics.width, intrinsics.height) != (FAKENECT_WIDTH, FAKENECT_HEIGHT) {
        return Err(format!(
            "--config: the sensor is {}x{}; a fakenect recording is 640x480",
            intrinsics.width, intrinsics.height
        ));
    }
    let sim_config = voxoct::session::sim_config_of(&config, args.seed, args.exact);
    let mut kinect =
        SimulatedKinect::new(&model, sim_config).map_err(|e| format!("simulator: {e}"))?;
    let mut table =
        SimulatedTurntable::new(args.microsteps_per_rev).map_err(|e| format!("turntable: {e}"))?;
    let mut writer = FakenectWriter::create(&args.out, Duration::from_millis(args.interval_ms))
        .map_err(|e| format!("--out: {e}"))?;
    let t = Duration::from_secs(60);
    let grab = |kinect: &mut SimulatedKinect, n: u32| -> Result<Vec<DepthFrame>, String> {
        (0..n)
            .map(|_| kinect.grab(t).map_err(|e| format!("simulator: {e}")))
            .collect()
    };

    // Lead-in at the home position, then the live scan's own capture loop
    // (voxoct::session::capture, which homes the table first: already there).
    kinect.set_turntable_angle_deg(0.0);
    let lead_in = grab(&mut kinect, args.lead_in)?;
    let snapshots = voxoct::session::capture(
        &mut kinect,
        &mut table,
        SimulatedKinect::set_turntable_angle_deg,
        args.snapshots,
        args.frames,
        |event| {
            if let Event::Snapshot {
                index,
                of,
                angle_deg,
                frames,
            } = event
            {
                eprintln!(
                    "record_fakenect: snapshot {}/{of} at {angle_deg}°: {frames} frames",
                    index + 1
                );
            }
        },
    )
    .map_err(|e| e.to_string())?;
    let tail = grab(&mut kinect, args.tail)?;
    let captured = snapshots.iter().flat_map(|s| &s.frames);
    for frame in lead_in.iter().chain(captured).chain(&tail) {
        writer.add_frame(frame).map_err(|e| format!("--out: {e}"))?;
    }
    let angles: Vec<f32> = snapshots.iter().map(|s| s.angle_deg).collect();
    let total = writer.frames();
    let dir = writer.finish().map_err(|e| format!("--out: {e}"))?;
    eprintln!(
        "record_fakenect: wrote {} ({total} depth frames: {} lead-in, {} × {}, {} tail; {} ms apart)",
        dir.display(),
        args.lead_in,
        args.snapshots,
        args.frames,
        args.tail,
        args.interval_ms
    );

    if let Some(expected) = &args.expected {
        // What the live scan should capture, read back through voxoct's own fakenect reader.
        let mut replay = FakenectSource::open(&dir)
            .and_then(|s| s.with_intrinsics(intrinsics))
            .map_err(|e| format!("reading back {}: {e}", dir.display()))?;
        let err = |e: voxoct::depth::scan::ScanError| format!("--expected: {e}");
        let mut scan = ScanWriter::create(expected, config).map_err(err)?;
        let mut read = || replay.grab(t).map_err(|e| format!("reading back: {e}"));
        for _ in 0..args.lead_in {
            read()?;
        }
        for angle in angles {
            let frames = (0..args.frames)
                .map(|_| read())
                .collect::<Result<Vec<_>, _>>()?;
            scan.add_snapshot(angle, &frames).map_err(err)?;
        }
        scan.finish().map_err(err)?;
        eprintln!(
            "record_fakenect: wrote {} (the frames a live scan should capture; its scan.toml is the --config)",
            expected.display()
        );
    }
    Ok(())
}
