//! Where the frames come from: a simulated or live capture, a recorded scan, a fakenect recording.

use std::path::Path;
use std::time::Duration;

use voxoct::depth::ScannerConfig;
use voxoct::depth::scan::{RecordedScan, ScanWriter};
use voxoct::kinect::{DepthSource, FakenectSource, Model, SimConfig, SimulatedKinect};
use voxoct::pipeline::{SnapshotFrames, recorded_snapshots};
use voxoct::turntable::{SimulatedTurntable, Turntable};

use crate::{Args, Progress, budget};

/// Units of a `--model` file's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelUnits {
    /// Millimetres: how slicers and CAD tools write STL, OBJ and PLY files for printing.
    Mm,
    /// Metres: the library's own unit.
    M,
    /// Inches.
    In,
}

impl ModelUnits {
    /// Metres per unit.
    fn metres(self) -> f64 {
        match self {
            Self::Mm => 0.001,
            Self::M => 1.0,
            Self::In => 0.0254,
        }
    }
}

/// Microsteps per turntable revolution of the simulated table: a 1.8° motor at quarter
/// stepping (0.45° per step), the thesis's setting.
const SIM_MICROSTEPS_PER_REV: u64 = 800;
/// How long one frame may take to arrive.
const GRAB_TIMEOUT: Duration = Duration::from_secs(5);
/// How long one turn of the table may take.
const TURN_TIMEOUT: Duration = Duration::from_secs(60);

/// Scanner settings and a description of the source.
pub struct Settings {
    /// `[sensor]`, `[rig]`, `[clip]`.
    pub config: ScannerConfig,
    /// What the frames came from, for the stats.
    pub source: String,
}

/// Everything acquired: settings and frames.
pub struct Acquired {
    /// Sensor, rig and clip box.
    pub settings: Settings,
    /// The snapshots in capture order.
    pub snapshots: Vec<SnapshotFrames>,
}

/// Writes what was acquired as a recorded-scan directory (frames as 16-bit PNG, then
/// `scan.toml`, rewritten atomically after each snapshot).
pub fn record(acquired: &Acquired, dir: &Path) -> Result<(), String> {
    let err = |e: voxoct::depth::scan::ScanError| format!("--record-to {}: {e}", dir.display());
    let mut writer = ScanWriter::create(dir, acquired.settings.config).map_err(err)?;
    for s in &acquired.snapshots {
        writer.add_snapshot(s.angle_deg, &s.frames).map_err(err)?;
    }
    writer.finish().map(drop).map_err(err)
}

/// Reads the `--config` file, if any.
fn config_override(args: &Args) -> Result<Option<ScannerConfig>, String> {
    args.config
        .as_ref()
        .map(|p| ScannerConfig::from_file(p).map_err(|e| format!("--config: {e}")))
        .transpose()
}

/// Captures or loads the frames that `args` asks for.
pub fn acquire(args: &Args, progress: &Progress) -> Result<Acquired, String> {
    let config = config_override(args)?;
    if let Some(dir) = &args.input {
        return load_recorded(dir, args, config, progress);
    }
    if let Some(dir) = &args.fakenect {
        return load_fakenect(dir, args, config);
    }
    if args.kinect {
        return live::capture(args, config, progress);
    }
    simulate(args, config, progress)
}

fn load_recorded(
    dir: &Path,
    args: &Args,
    config: Option<ScannerConfig>,
    progress: &Progress,
) -> Result<Acquired, String> {
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(format!(
                "--input {} is a file; --input takes a recorded-scan directory (with scan.toml){}",
                dir.display(),
                if dir
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("stl"))
                {
                    "; to scan a mesh use --model"
                } else {
                    ""
                }
            ));
        }
        Err(_) => return Err(format!("--input {}: no such directory", dir.display())),
    }
    // The manifest first: the frames it lists must fit in memory.
    let manifest =
        voxoct::depth::scan::ScanManifest::load(dir.join(voxoct::depth::scan::MANIFEST_FILE))
            .map_err(|e| format!("--input: {e}"))?;
    let frames: usize = manifest.snapshots.iter().map(|s| s.frames.len()).sum();
    budget::check_memory(
        args,
        config.as_ref().unwrap_or(&manifest.config()),
        manifest.snapshots.len() as u64,
        frames as u64,
    )?;
    let pb = progress.stage("load", None);
    pb.set_message(dir.display().to_string());
    let mut scan = RecordedScan::open_limited(dir, budget::limit_bytes(args))
        .map_err(|e| format!("--input: {e}"))?;
    if let Some(c) = &config {
        scan.apply_config(c)
            .map_err(|e| format!("--config does not fit {}: {e}", dir.display()))?;
    }
    pb.finish_and_clear();
    let (config, snapshots) = recorded_snapshots(scan);
    let settings = Settings {
        config,
        source: format!("recorded scan {}", dir.display()),
    };
    Ok(Acquired {
        settings,
        snapshots,
    })
}

fn load_fakenect(
    dir: &Path,
    args: &Args,
    config: Option<ScannerConfig>,
) -> Result<Acquired, String> {
    let config = config.unwrap_or_default();
    let degrees = args
        .degrees_per_snapshot
        .ok_or("--fakenect needs --degrees-per-snapshot D")?;
    let mut source = FakenectSource::open(dir)
        .and_then(|s| s.with_intrinsics(config.sensor.intrinsics))
        .map_err(|e| format!("--fakenect: {e}"))?;
    let count = source.depth_frame_count();
    let per = args.frames as usize;
    budget::check_memory(args, &config, (count / per.max(1)) as u64, count as u64)?;
    if count < per {
        return Err(format!(
            "--fakenect {}: {count} depth frames, fewer than --frames {per} for one snapshot",
            dir.display()
        ));
    }
    let mut snapshots = Vec::new();
    for k in 0..count / per {
        let frames = (0..per)
            .map(|_| source.grab(GRAB_TIMEOUT))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("--fakenect: {e}"))?;
        snapshots.push(SnapshotFrames {
            angle_deg: k as f32 * degrees,
            frames,
        });
    }
    let settings = Settings {
        config,
        source: format!("fakenect recording {}", dir.display()),
    };
    Ok(Acquired {
        settings,
        snapshots,
    })
}

/// Turns the table through `n` equal steps, grabbing `frames` frames at each stop.
///
/// The order, which a fakenect recording for a rehearsed live scan follows
/// (examples/record_fakenect.rs): home the table; then for each snapshot `k` of `0..n` read the
/// table's angle, grab `frames` frames, and — except after the last — turn by `360°/n` and wait
/// until the table has stopped. A live source has already consumed one frame when it opened.
/// With `log`, one line per snapshot and per turn goes to stderr (the progress bar only
/// shows on a terminal).
fn capture<S: DepthSource + ?Sized>(
    source: &mut S,
    table: &mut dyn Turntable,
    mut on_angle: impl FnMut(&mut S, f32),
    args: &Args,
    progress: &Progress,
    log: bool,
) -> Result<Vec<SnapshotFrames>, String> {
    let n = args.snapshots;
    let pb = progress.stage("capture", Some(u64::from(n)));
    table.home().map_err(|e| format!("turntable: {e}"))?;
    let mut snapshots = Vec::with_capacity(n as usize);
    for k in 0..n {
        let angle = table.angle_deg().map_err(|e| format!("turntable: {e}"))? as f32;
        on_angle(source, angle);
        let frames = (0..args.frames)
            .map(|_| source.grab(GRAB_TIMEOUT))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("depth source: {e}"))?;
        if log {
            pb.suspend(|| {
                eprintln!(
                    "capture: snapshot {}/{n} at {angle}°: {} frames",
                    k + 1,
                    frames.len()
                );
            });
        }
        snapshots.push(SnapshotFrames {
            angle_deg: angle,
            frames,
        });
        pb.inc(1);
        if k + 1 < n {
            let step = 360.0 / f64::from(n);
            let turned = table
                .rotate_by(step, TURN_TIMEOUT)
                .map_err(|e| format!("turntable: {e}"))?;
            if log {
                pb.suspend(|| eprintln!("turntable: turned by {turned}° (asked {step}°)"));
            }
        }
    }
    pb.finish_and_clear();
    source
        .shutdown()
        .map_err(|e| format!("depth source: {e}"))?;
    Ok(snapshots)
}

fn simulate(
    args: &Args,
    config: Option<ScannerConfig>,
    progress: &Progress,
) -> Result<Acquired, String> {
    let config = config.unwrap_or_else(|| {
        let sim = SimConfig::default();
        ScannerConfig {
            sensor: voxoct::depth::SensorConfig {
                intrinsics: sim.intrinsics,
                depth_unit_m: sim.unit_m,
            },
            rig: sim.rig,
            ..ScannerConfig::default()
        }
    });
    let (model, name) = match &args.model {
        Some(path) => load_model(path, args, &config)?,
        None => {
            let m = Model::builtin(&args.builtin).ok_or_else(|| {
                format!(
                    "--builtin {}: unknown model; choose one of {}",
                    args.builtin,
                    Model::BUILTIN_NAMES.join(", ")
                )
            })?;
            let size = m
                .bounds()
                .map_or(Default::default(), |b| (b.max - b.min) * 1000.0);
            let name = format!(
                "simulated Kinect v1, built-in {}, {:.1} × {:.1} × {:.1} mm (width × depth × \
                 height)",
                args.builtin, size.x, size.z, size.y
            );
            (m, name)
        }
    };
    let sim_config = SimConfig {
        intrinsics: config.sensor.intrinsics,
        rig: config.rig,
        unit_m: config.sensor.depth_unit_m,
        seed: args.seed,
        exact: args.exact,
        ..SimConfig::default()
    };
    budget::check_memory(
        args,
        &config,
        u64::from(args.snapshots),
        u64::from(args.snapshots) * u64::from(args.frames),
    )?;
    let mut kinect =
        SimulatedKinect::new(&model, sim_config).map_err(|e| format!("simulator: {e}"))?;
    let mut table =
        SimulatedTurntable::new(SIM_MICROSTEPS_PER_REV).map_err(|e| format!("turntable: {e}"))?;
    // The simulated sensor is told where the simulated table stands before each snapshot.
    let snapshots = capture(
        &mut kinect,
        &mut table,
        SimulatedKinect::set_turntable_angle_deg,
        args,
        progress,
        false,
    )?;
    Ok(Acquired {
        settings: Settings {
            config,
            source: name,
        },
        snapshots,
    })
}

/// Loads `--model` as its file's convention says (`--model-units`, `--model-up`), standing on
/// the platform at its own size, and checks that it fits the clip box while it turns.
fn load_model(path: &Path, args: &Args, config: &ScannerConfig) -> Result<(Model, String), String> {
    let convention = voxoct::kinect::ModelConvention {
        metres_per_unit: args.model_units.map(ModelUnits::metres),
        up: match args.model_up {
            crate::output::Up::Z => voxoct::kinect::ModelUp::Z,
            crate::output::Up::Y => voxoct::kinect::ModelUp::Y,
        },
    };
    let m =
        voxoct::kinect::load_model_as(path, &convention).map_err(|e| format!("--model: {e}"))?;
    let b = m
        .bounds()
        .ok_or_else(|| format!("--model {}: no vertices", path.display()))?;
    let size_mm = (b.max - b.min) * 1000.0;
    let up = match args.model_up {
        crate::output::Up::Z => "z",
        crate::output::Up::Y => "y",
    };
    let units = args
        .model_units
        .map_or("mm, or the file's own unit", |u| match u {
            ModelUnits::Mm => "mm",
            ModelUnits::M => "m",
            ModelUnits::In => "in",
        });
    let described = format!(
        "{:.1} × {:.1} × {:.1} mm (width × depth × height; read as --model-units {units}, \
         --model-up {up})",
        size_mm.x, size_mm.z, size_mm.y
    );
    // The model turns about the Y axis: its farthest point from the axis sweeps a circle.
    let radius = m
        .vertices
        .iter()
        .map(|v| v.x.hypot(v.z))
        .fold(0.0f32, f32::max);
    let clip = config.clip;
    let room = [-clip.min.x, clip.max.x, -clip.min.z, clip.max.z]
        .into_iter()
        .fold(f32::INFINITY, f32::min);
    if radius > room || b.max.y > clip.max.y {
        return Err(format!(
            "--model {} is {described}: it does not fit the clip box while it turns (radius \
             {:.1} mm of {:.1} mm, height up to {:.1} mm); give the file's units and up axis \
             with --model-units and --model-up, or a larger [clip] with --config",
            path.display(),
            radius * 1000.0,
            room * 1000.0,
            clip.max.y * 1000.0
        ));
    }
    let largest = size_mm.max_element();
    if largest < 10.0 * args.leaf * 1000.0 {
        return Err(format!(
            "--model {} is {described}: too small to scan at --leaf {} m; is the file in \
             metres or inches (--model-units m / in)?",
            path.display(),
            args.leaf
        ));
    }
    Ok((
        m,
        format!("simulated Kinect v1, model {}, {described}", path.display()),
    ))
}

/// Live capture: a Kinect v1 through libfreenect and a networked turntable.
#[cfg(feature = "freenect")]
mod live {
    use super::*;
    use voxoct::kinect::{KinectOptions, KinectSource};
    use voxoct::turntable::{ClientTimeouts, RemoteTurntable};

    pub fn capture(
        args: &Args,
        config: Option<ScannerConfig>,
        progress: &Progress,
    ) -> Result<Acquired, String> {
        let addr = args
            .turntable
            .as_deref()
            .ok_or("--kinect needs a turntable: --turntable HOST:PORT (examples/turntable_server.rs on the Pi)")?;
        let config = config.ok_or("--kinect needs --config FILE with the rig's [sensor], [rig] and [clip] (see examples/thesis-rig.toml)")?;
        budget::check_memory(
            args,
            &config,
            u64::from(args.snapshots),
            u64::from(args.snapshots) * u64::from(args.frames),
        )?;
        // The sensor first: it is local, and without it there is nothing to turn the table for.
        let depth = args.kinect_depth.unwrap_or_default();
        if let Some(dir) = std::env::var_os("FAKENECT_PATH") {
            check_fakenect_length(Path::new(&dir), args)?;
        }
        let options = KinectOptions {
            depth,
            verbose: args.verbose,
        };
        let mut kinect = KinectSource::open_with(0, options)
            .and_then(|k| k.with_intrinsics(config.sensor.intrinsics))
            .map_err(|e| format!("Kinect: {e}"))?;
        let log = !args.quiet;
        if log {
            eprintln!("capture: Kinect v1 open, depth mode {depth}");
        }
        let mut table =
            RemoteTurntable::connect(addr, args.token.as_deref(), ClientTimeouts::default())
                .map_err(|e| format!("turntable at {addr}: {e}"))?;
        let snapshots = super::capture(&mut kinect, &mut table, |_, _| {}, args, progress, log)?;
        Ok(Acquired {
            settings: Settings {
                config,
                source: format!("Kinect v1 ({depth} depth)"),
            },
            snapshots,
        })
    }
}

/// A rehearsed live scan (FAKENECT_PATH set, libfreenect's fakenect library loaded) needs a
/// recording long enough: opening the Kinect consumes one frame, the scan `snapshots × frames`,
/// and libfreenect 0.5's fakenect ends its runloop at the end of `INDEX.txt` — a grab after that
/// crashes or waits for ever — so one frame more must follow the last one grabbed.
#[cfg(feature = "freenect")]
fn check_fakenect_length(dir: &Path, args: &Args) -> Result<(), String> {
    let count = FakenectSource::open(dir)
        .map_err(|e| format!("FAKENECT_PATH: {e}"))?
        .depth_frame_count();
    let need = 2 + args.snapshots as usize * args.frames as usize;
    if count < need {
        return Err(format!(
            "FAKENECT_PATH {}: {count} depth frames, but a live scan of {} snapshots × {} frames \
             needs at least {need} (1 consumed on opening, then the scan's, then 1 more before \
             the end of the recording); record one with the record_fakenect example",
            dir.display(),
            args.snapshots,
            args.frames
        ));
    }
    Ok(())
}

/// Without the `freenect` feature a live scan is not possible: say how to get one.
#[cfg(not(feature = "freenect"))]
mod live {
    use super::*;

    pub fn capture(_: &Args, _: Option<ScannerConfig>, _: &Progress) -> Result<Acquired, String> {
        Err(
            "--kinect needs the live sensor support: install libfreenect-dev and run with \
             `cargo run --release --features freenect --example scan -- --kinect ...`"
                .into(),
        )
    }
}
