//! A scan session: where the frames come from, capturing them, and recording them.
//!
//! A [`Session`] names a [`Source`] — a simulated Kinect v1 looking at a built-in model or a
//! mesh file, a recorded-scan directory, a fakenect recording or (with the `freenect`
//! feature) a live Kinect and a networked turntable — with the capture's size.
//! [`Session::acquire`] checks it, estimates the memory the run will need
//! ([`crate::budget`]) and returns the scanner settings and the snapshots, ready for
//! [`crate::pipeline::reconstruct`]. [`capture`] is the capture loop over any
//! [`DepthSource`] and [`Turntable`]; [`record`] writes what was acquired as a recorded-scan
//! directory.
//!
//! Errors name the setting as the `scan` example's flag does (`--input`, `--snapshots`, …).
//!
//! A whole scan, as the `scan` example runs it: simulated, recorded, reloaded, meshed and
//! written.
//!
//! ```
//! use voxoct::mesh_file::{MeshFile, Units, Up};
//! use voxoct::output::Outputs;
//! use voxoct::pipeline::{Params, reconstruct};
//! use voxoct::session::{Session, SimModel, Source, record};
//!
//! let dir = tempfile::tempdir()?;
//! let params = Params { leaf_m: 0.004, ..Params::default() };
//! // Capture: a simulated Kinect v1 and turntable, four snapshots of one exact frame.
//! let session = Session {
//!     source: Source::Simulated { model: SimModel::Builtin("sphere".into()), seed: 1, exact: true },
//!     snapshots: 4,
//!     frames: 1,
//!     ..Session::default()
//! };
//! let captured = session.acquire(&params, |_| {})?;
//! record(&captured, &dir.path().join("rec"))?;
//!
//! // Reload the recorded scan (SCAN_FORMAT.md) and mesh it.
//! let recorded = Session { source: Source::Recorded(dir.path().join("rec")), ..Session::default() };
//! let scan = recorded.acquire(&params, |_| {})?;
//! assert_eq!(scan.snapshots, captured.snapshots);
//! let result = reconstruct(&scan.config, scan.snapshots, &params, |_| {})?;
//! assert!(result.mesh.check_closed_manifold().is_ok());
//!
//! // Write it for a slicer: millimetres, Z up, replaced atomically.
//! let path = dir.path().join("sphere.3mf");
//! let file = MeshFile::for_path(&path, None, false, Units::Mm, Up::Z)?;
//! let mut outputs = Outputs::new();
//! let out = outputs.add("--out", &path)?;
//! outputs.write(out, |w| file.write(&result.mesh, &result.tree, w))?;
//! outputs.commit()?;
//! assert!(path.is_file());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Duration;

use voxoct_depth::{
    DepthError, MANIFEST_FILE, RecordedScan, ScanManifest, ScanWriter, ScannerConfig, SensorConfig,
};
use voxoct_kinect::{
    DepthSource, FakenectSource, KinectDepth, Model, ModelConvention, ModelUp, SimConfig,
    SimulatedKinect,
};
use voxoct_turntable::{SimulatedTurntable, Turntable};

use crate::budget;
use crate::pipeline::{InvalidSetting, Params, SnapshotFrames, recorded_snapshots};

/// Microsteps per turntable revolution of the simulated table: a 1.8° motor at quarter
/// stepping (0.45° per step), the thesis's setting.
pub const SIM_MICROSTEPS_PER_REV: u64 = 800;
/// How long one frame may take to arrive.
pub const GRAB_TIMEOUT: Duration = Duration::from_secs(5);
/// How long one turn of the table may take.
pub const TURN_TIMEOUT: Duration = Duration::from_secs(60);
/// Most snapshots of a capture.
pub const MAX_SNAPSHOTS: u32 = 3600;
/// Most frames per snapshot.
pub const MAX_FRAMES: u32 = 1000;
/// A model file is refused as "too small" when its largest side is under this many leaves:
/// most likely its numbers are metres or inches read as millimetres.
pub const MIN_MODEL_LEAVES: f32 = 10.0;

/// Units of a model file's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
    #[must_use]
    pub fn metres(self) -> f64 {
        match self {
            Self::Mm => 0.001,
            Self::M => 1.0,
            Self::In => 0.0254,
        }
    }

    /// The unit's short name (`mm`, `m`, `in`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Mm => "mm",
            Self::M => "m",
            Self::In => "in",
        }
    }
}

/// What the simulated sensor looks at.
#[derive(Debug, Clone, PartialEq)]
pub enum SimModel {
    /// A built-in model ([`Model::BUILTIN_NAMES`]).
    Builtin(String),
    /// A mesh file (STL, OBJ, PLY, 3MF) standing on the platform at its own size.
    File {
        /// The file.
        path: PathBuf,
        /// Its units; `None`: millimetres, or the unit a 3MF file states.
        units: Option<ModelUnits>,
        /// Its up axis.
        up: ModelUp,
    },
}

/// Where the frames come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A simulated Kinect v1 and turntable.
    Simulated {
        /// What it looks at.
        model: SimModel,
        /// Seed of the sensor's noise.
        seed: u64,
        /// Exact, noise-free frames.
        exact: bool,
    },
    /// A recorded-scan directory (SCAN_FORMAT.md).
    Recorded(PathBuf),
    /// A libfreenect (fakenect) recording: [`Session::frames`] frames per snapshot.
    Fakenect {
        /// The recording's directory.
        dir: PathBuf,
        /// Turntable angle between consecutive snapshots.
        degrees_per_snapshot: f32,
    },
    /// A live Kinect v1 (the `freenect` feature) and a turntable server.
    Kinect {
        /// `HOST:PORT` of the turntable server.
        turntable: Option<String>,
        /// Its shared secret.
        token: Option<String>,
        /// The depth stream.
        depth: KinectDepth,
        /// Let libfreenect print its own messages.
        verbose: bool,
    },
}

impl Source {
    /// The directory the frames are read from, for a recorded scan or a fakenect recording.
    #[must_use]
    pub fn input_dir(&self) -> Option<&Path> {
        match self {
            Self::Recorded(dir) | Self::Fakenect { dir, .. } => Some(dir),
            _ => None,
        }
    }
}

/// A scan to acquire: its source and the capture's size.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// Where the frames come from.
    pub source: Source,
    /// Scanner settings (`[sensor]`, `[rig]`, `[clip]`) overriding the source's own.
    pub config_file: Option<PathBuf>,
    /// Snapshots of a capture: turntable steps of 360°/N.
    pub snapshots: u32,
    /// Frames per snapshot (of a capture or a fakenect recording).
    pub frames: u32,
    /// Refuse runs estimated to need more than this many bytes; `None`:
    /// [`voxoct_depth::default_memory_limit`].
    pub memory_limit: Option<u64>,
}

impl Default for Session {
    /// A simulated scan of the built-in figurine: 8 snapshots of 4 frames, seed 1.
    fn default() -> Self {
        Self {
            source: Source::Simulated {
                model: SimModel::Builtin("figurine".into()),
                seed: 1,
                exact: false,
            },
            config_file: None,
            snapshots: 8,
            frames: 4,
            memory_limit: None,
        }
    }
}

/// What a session acquired: the scanner settings, a description and the frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Acquired {
    /// Sensor, rig and clip box.
    pub config: ScannerConfig,
    /// What the frames came from, for people (e.g. `recorded scan DIR`).
    pub source: String,
    /// The snapshots in capture order.
    pub snapshots: Vec<SnapshotFrames>,
}

/// What a session is doing, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Event<'a> {
    /// Loading the recorded scan in this directory.
    Loading(&'a Path),
    /// The recorded scan is loaded.
    Loaded,
    /// The live sensor is open, streaming this depth mode.
    SensorOpen(KinectDepth),
    /// A capture of this many snapshots begins.
    CaptureStarted(u32),
    /// Snapshot `index` (from 0) is taken.
    Snapshot {
        /// Its index.
        index: u32,
        /// Snapshots in the capture.
        of: u32,
        /// The table's angle.
        angle_deg: f32,
        /// Frames grabbed.
        frames: usize,
    },
    /// The table turned.
    Turned {
        /// By how much, degrees.
        by_deg: f64,
        /// By how much it was asked to, degrees.
        asked_deg: f64,
    },
    /// The capture is over.
    CaptureDone,
}

/// Why a session failed. Every message names the setting as the `scan` example's flag does.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SessionError {
    /// A setting out of range or contradicting another.
    #[error(transparent)]
    Setting(#[from] InvalidSetting),
    /// An input (file, directory, device) cannot be used.
    #[error("{message}")]
    Input {
        /// The flag that names it (`--input`, `--model`, `--record-to`, …).
        flag: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The run would need more memory than allowed ([`crate::budget`]).
    #[error("{0}")]
    Memory(String),
    /// A device (sensor, turntable, simulator) failed.
    #[error("{what}: {message}")]
    Device {
        /// Which (`turntable`, `depth source`, `Kinect`, `simulator`).
        what: String,
        /// What went wrong.
        message: String,
    },
}

fn input(flag: &'static str, message: impl Into<String>) -> SessionError {
    SessionError::Input {
        flag,
        message: message.into(),
    }
}

fn device(what: impl Into<String>) -> impl FnOnce(&dyn std::fmt::Display) -> SessionError {
    let what = what.into();
    move |e| SessionError::Device {
        what,
        message: e.to_string(),
    }
}

/// The scanner settings that match a simulator: its intrinsics, depth unit and rig, and the
/// default clip box.
#[must_use]
pub fn scanner_config_of(sim: &SimConfig) -> ScannerConfig {
    ScannerConfig {
        sensor: SensorConfig {
            intrinsics: sim.intrinsics,
            depth_unit_m: sim.unit_m,
        },
        rig: sim.rig,
        ..ScannerConfig::default()
    }
}

/// A simulator that matches scanner settings (intrinsics, depth unit, rig), with a noise
/// `seed` or `exact` frames.
#[must_use]
pub fn sim_config_of(config: &ScannerConfig, seed: u64, exact: bool) -> SimConfig {
    SimConfig {
        intrinsics: config.sensor.intrinsics,
        rig: config.rig,
        unit_m: config.sensor.depth_unit_m,
        seed,
        exact,
        ..SimConfig::default()
    }
}

impl Session {
    /// Checks the capture's size: 1 to [`MAX_SNAPSHOTS`] snapshots, 1 to [`MAX_FRAMES`]
    /// frames, a fakenect step that is a finite angle within ±360°.
    ///
    /// # Errors
    /// [`SessionError::Setting`] naming the setting.
    pub fn validate(&self) -> Result<(), SessionError> {
        if self.snapshots == 0 || self.snapshots > MAX_SNAPSHOTS {
            return Err(InvalidSetting::new(
                "--snapshots",
                format!(
                    "--snapshots must be between 1 and {MAX_SNAPSHOTS}, got {}",
                    self.snapshots
                ),
            )
            .into());
        }
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return Err(InvalidSetting::new(
                "--frames",
                format!(
                    "--frames must be between 1 and {MAX_FRAMES}, got {}",
                    self.frames
                ),
            )
            .into());
        }
        if let Source::Fakenect {
            degrees_per_snapshot: d,
            ..
        } = self.source
            && (!d.is_finite() || d.abs() > 360.0)
        {
            return Err(InvalidSetting::new(
                "--degrees-per-snapshot",
                format!("--degrees-per-snapshot must be a finite angle within ±360, got {d}"),
            )
            .into());
        }
        Ok(())
    }

    /// The memory limit: [`Session::memory_limit`] or the machine's default.
    #[must_use]
    pub fn limit_bytes(&self) -> u64 {
        self.memory_limit
            .unwrap_or_else(voxoct_depth::default_memory_limit)
    }

    /// Captures or loads the frames, after checking the session ([`Session::validate`]) and
    /// the memory the run will need with `params` ([`budget::check_memory`]). `on_event`
    /// hears of the progress.
    ///
    /// # Errors
    /// [`SessionError`] naming the setting, input or device that failed.
    pub fn acquire(
        &self,
        params: &Params,
        mut on_event: impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        self.validate()?;
        let config = self
            .config_file
            .as_ref()
            .map(|p| {
                ScannerConfig::from_file(p).map_err(|e| input("--config", format!("--config: {e}")))
            })
            .transpose()?;
        match &self.source {
            Source::Recorded(dir) => self.load_recorded(dir, config, params, &mut on_event),
            Source::Fakenect {
                dir,
                degrees_per_snapshot,
            } => self.load_fakenect(dir, *degrees_per_snapshot, config, params),
            Source::Kinect { .. } => live::capture(self, config, params, &mut on_event),
            Source::Simulated { model, seed, exact } => {
                self.simulate(model, *seed, *exact, config, params, &mut on_event)
            }
        }
    }

    fn check_memory(
        &self,
        config: &ScannerConfig,
        params: &Params,
        snapshots: u64,
        frames: u64,
    ) -> Result<(), SessionError> {
        budget::check_memory(config, params, snapshots, frames, self.limit_bytes())
            .map_err(SessionError::Memory)
    }

    fn load_recorded(
        &self,
        dir: &Path,
        config: Option<ScannerConfig>,
        params: &Params,
        on_event: &mut impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => {
                let hint = if dir
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("stl"))
                {
                    "; to scan a mesh use --model"
                } else {
                    ""
                };
                return Err(input(
                    "--input",
                    format!(
                        "--input {} is a file; --input takes a recorded-scan directory (with \
                         scan.toml){hint}",
                        dir.display()
                    ),
                ));
            }
            Err(_) => {
                return Err(input(
                    "--input",
                    format!("--input {}: no such directory", dir.display()),
                ));
            }
        }
        // The manifest first: the frames it lists must fit in memory.
        let manifest = ScanManifest::load(dir.join(MANIFEST_FILE))
            .map_err(|e| input("--input", format!("--input: {e}")))?;
        let frames: usize = manifest.snapshots.iter().map(|s| s.frames.len()).sum();
        self.check_memory(
            config.as_ref().unwrap_or(&manifest.config()),
            params,
            manifest.snapshots.len() as u64,
            frames as u64,
        )?;
        on_event(Event::Loading(dir));
        let mut scan = RecordedScan::open_limited(dir, self.limit_bytes())
            .map_err(|e| input("--input", format!("--input: {e}")))?;
        if let Some(c) = &config {
            scan.apply_config(c).map_err(|e| {
                input(
                    "--config",
                    format!("--config does not fit {}: {e}", dir.display()),
                )
            })?;
        }
        on_event(Event::Loaded);
        let (config, snapshots) = recorded_snapshots(scan);
        Ok(Acquired {
            config,
            source: format!("recorded scan {}", dir.display()),
            snapshots,
        })
    }

    fn load_fakenect(
        &self,
        dir: &Path,
        degrees: f32,
        config: Option<ScannerConfig>,
        params: &Params,
    ) -> Result<Acquired, SessionError> {
        let config = config.unwrap_or_default();
        let fk = |e: &dyn std::fmt::Display| input("--fakenect", format!("--fakenect: {e}"));
        let mut source = FakenectSource::open(dir)
            .and_then(|s| s.with_intrinsics(config.sensor.intrinsics))
            .map_err(|e| fk(&e))?;
        let count = source.depth_frame_count();
        let per = self.frames as usize;
        self.check_memory(&config, params, (count / per.max(1)) as u64, count as u64)?;
        if count < per {
            return Err(input(
                "--fakenect",
                format!(
                    "--fakenect {}: {count} depth frames, fewer than --frames {per} for one \
                     snapshot",
                    dir.display()
                ),
            ));
        }
        let mut snapshots = Vec::new();
        for k in 0..count / per {
            let frames = (0..per)
                .map(|_| source.grab(GRAB_TIMEOUT))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| fk(&e))?;
            snapshots.push(SnapshotFrames {
                angle_deg: k as f32 * degrees,
                frames,
            });
        }
        Ok(Acquired {
            config,
            source: format!("fakenect recording {}", dir.display()),
            snapshots,
        })
    }

    fn simulate(
        &self,
        model: &SimModel,
        seed: u64,
        exact: bool,
        config: Option<ScannerConfig>,
        params: &Params,
        on_event: &mut impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        let config = config.unwrap_or_else(|| scanner_config_of(&SimConfig::default()));
        let (model, name) = match model {
            SimModel::File { path, units, up } => {
                load_model(path, *units, *up, &config, params.leaf_m)?
            }
            SimModel::Builtin(name) => {
                let m = Model::builtin(name).ok_or_else(|| {
                    input(
                        "--builtin",
                        format!(
                            "--builtin {name}: unknown model; choose one of {}",
                            Model::BUILTIN_NAMES.join(", ")
                        ),
                    )
                })?;
                let size = m
                    .bounds()
                    .map_or(Default::default(), |b| (b.max - b.min) * 1000.0);
                let described = format!(
                    "simulated Kinect v1, built-in {name}, {:.1} × {:.1} × {:.1} mm (width × \
                     depth × height)",
                    size.x, size.z, size.y
                );
                (m, described)
            }
        };
        let (n, f) = (u64::from(self.snapshots), u64::from(self.frames));
        self.check_memory(&config, params, n, n * f)?;
        let mut kinect = SimulatedKinect::new(&model, sim_config_of(&config, seed, exact))
            .map_err(|e| device("simulator")(&e))?;
        let mut table =
            SimulatedTurntable::new(SIM_MICROSTEPS_PER_REV).map_err(|e| device("turntable")(&e))?;
        // The simulated sensor is told where the simulated table stands before each snapshot.
        let snapshots = capture(
            &mut kinect,
            &mut table,
            SimulatedKinect::set_turntable_angle_deg,
            self.snapshots,
            self.frames,
            on_event,
        )?;
        Ok(Acquired {
            config,
            source: name,
            snapshots,
        })
    }
}

/// Turns the table through `n` equal steps, grabbing `frames` frames at each stop;
/// `on_angle` is told the table's angle before each snapshot's frames are grabbed.
///
/// The order, which a fakenect recording for a rehearsed live scan follows
/// (examples/record_fakenect.rs): home the table; then for each snapshot `k` of `0..n` read the
/// table's angle, grab `frames` frames, and — except after the last — turn by `360°/n` and wait
/// until the table has stopped ([`TURN_TIMEOUT`]); finally shut the source down. A live
/// source has already consumed one frame when it opened.
///
/// # Errors
/// [`SessionError::Device`] from the table or the source.
pub fn capture<S: DepthSource + ?Sized>(
    source: &mut S,
    table: &mut dyn Turntable,
    mut on_angle: impl FnMut(&mut S, f32),
    n: u32,
    frames: u32,
    mut on_event: impl FnMut(Event<'_>),
) -> Result<Vec<SnapshotFrames>, SessionError> {
    on_event(Event::CaptureStarted(n));
    table.home().map_err(|e| device("turntable")(&e))?;
    let mut snapshots = Vec::with_capacity(n as usize);
    for k in 0..n {
        let angle = table.angle_deg().map_err(|e| device("turntable")(&e))? as f32;
        on_angle(source, angle);
        let grabbed = (0..frames)
            .map(|_| source.grab(GRAB_TIMEOUT))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| device("depth source")(&e))?;
        on_event(Event::Snapshot {
            index: k,
            of: n,
            angle_deg: angle,
            frames: grabbed.len(),
        });
        snapshots.push(SnapshotFrames {
            angle_deg: angle,
            frames: grabbed,
        });
        if k + 1 < n {
            let step = 360.0 / f64::from(n);
            let turned = table
                .rotate_by(step, TURN_TIMEOUT)
                .map_err(|e| device("turntable")(&e))?;
            on_event(Event::Turned {
                by_deg: turned,
                asked_deg: step,
            });
        }
    }
    on_event(Event::CaptureDone);
    source.shutdown().map_err(|e| device("depth source")(&e))?;
    Ok(snapshots)
}

/// Loads a model file as its convention says, standing on the platform at its own size,
/// and checks that it fits the clip box while it turns and is at least
/// [`MIN_MODEL_LEAVES`] leaves of `leaf_m` across. Returns it with a description.
///
/// # Errors
/// [`SessionError::Input`] for `--model`: unreadable, empty, too large or too small.
pub fn load_model(
    path: &Path,
    units: Option<ModelUnits>,
    up: ModelUp,
    config: &ScannerConfig,
    leaf_m: f32,
) -> Result<(Model, String), SessionError> {
    let convention = ModelConvention {
        metres_per_unit: units.map(ModelUnits::metres),
        up,
    };
    let m = voxoct_kinect::load_model_as(path, &convention)
        .map_err(|e| input("--model", format!("--model: {e}")))?;
    let b = m.bounds().ok_or_else(|| {
        input(
            "--model",
            format!("--model {}: no vertices", path.display()),
        )
    })?;
    let size_mm = (b.max - b.min) * 1000.0;
    let up = match up {
        ModelUp::Z => "z",
        ModelUp::Y => "y",
    };
    let units = units.map_or("mm, or the file's own unit", ModelUnits::name);
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
        return Err(input(
            "--model",
            format!(
                "--model {} is {described}: it does not fit the clip box while it turns (radius \
                 {:.1} mm of {:.1} mm, height up to {:.1} mm); give the file's units and up axis \
                 with --model-units and --model-up, or a larger [clip] with --config",
                path.display(),
                radius * 1000.0,
                room * 1000.0,
                clip.max.y * 1000.0
            ),
        ));
    }
    if size_mm.max_element() < MIN_MODEL_LEAVES * leaf_m * 1000.0 {
        return Err(input(
            "--model",
            format!(
                "--model {} is {described}: too small to scan at --leaf {} m; is the file in \
                 metres or inches (--model-units m / in)?",
                path.display(),
                leaf_m
            ),
        ));
    }
    Ok((
        m,
        format!("simulated Kinect v1, model {}, {described}", path.display()),
    ))
}

/// Writes what was acquired as a recorded-scan directory (frames as 16-bit PNG, then
/// `scan.toml`, rewritten atomically after each snapshot).
///
/// # Errors
/// [`SessionError::Input`] for `--record-to`.
pub fn record(acquired: &Acquired, dir: &Path) -> Result<(), SessionError> {
    let err = |e: DepthError| input("--record-to", format!("--record-to {}: {e}", dir.display()));
    let mut writer = ScanWriter::create(dir, acquired.config).map_err(err)?;
    for s in &acquired.snapshots {
        writer.add_snapshot(s.angle_deg, &s.frames).map_err(err)?;
    }
    writer.finish().map(drop).map_err(err)
}

/// Checks a directory to record into before any work: it must be new (in an existing
/// directory) or empty, and not the directory `input` reads from; one that holds a readable
/// recorded scan is accepted with `force` (then [`clear_recorded_scan`] removes it).
///
/// # Errors
/// [`SessionError::Input`] for `--record-to`, saying what to do instead.
pub fn check_record_dir(
    dir: &Path,
    input_dir: Option<&Path>,
    force: bool,
) -> Result<(), SessionError> {
    let shown = dir.display();
    let refuse = |message: String| Err(input("--record-to", message));
    if let Some(from) = input_dir
        && let (Ok(a), Ok(b)) = (dir.canonicalize(), from.canonicalize())
        && a == b
    {
        return refuse(format!(
            "--record-to {shown} is the directory the frames are read from; choose another"
        ));
    }
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let parent = match dir.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            if !parent.is_dir() {
                return refuse(format!(
                    "--record-to {shown}: the directory {} does not exist",
                    parent.display()
                ));
            }
            Ok(())
        }
        Err(e) => refuse(format!("--record-to {shown}: {e}")),
        Ok(m) if !m.is_dir() => {
            refuse(format!("--record-to {shown} exists and is not a directory"))
        }
        Ok(_) => {
            let entries = std::fs::read_dir(dir)
                .map_err(|e| input("--record-to", format!("--record-to {shown}: {e}")))?
                .count();
            if entries == 0 {
                return Ok(());
            }
            let manifest = dir.join(MANIFEST_FILE);
            if !manifest.is_file() {
                return refuse(format!(
                    "--record-to {shown} is not empty and holds no recorded scan; choose a new or \
                     empty directory"
                ));
            }
            if !force {
                return refuse(format!(
                    "--record-to {shown} already holds a recorded scan; choose a new directory, or \
                     add --force to replace it (its frames are removed)"
                ));
            }
            ScanManifest::load(&manifest).map(drop).map_err(|e| {
                input(
                    "--record-to",
                    format!("--record-to {shown}: not replacing a scan that cannot be read ({e})"),
                )
            })
        }
    }
}

/// Removes the recorded scan in `dir` (its manifest and the frame files it lists inside
/// the directory, then their emptied subdirectories), so that a new scan's frames are all
/// that remain. Nothing to do when `dir` holds no manifest.
///
/// # Errors
/// [`SessionError::Input`] for `--record-to`.
pub fn clear_recorded_scan(dir: &Path) -> Result<(), SessionError> {
    let manifest_path = dir.join(MANIFEST_FILE);
    if !manifest_path.is_file() {
        return Ok(());
    }
    let err = |e: &dyn std::fmt::Display| {
        input(
            "--record-to",
            format!("--record-to {} --force: {e}", dir.display()),
        )
    };
    let manifest = ScanManifest::load(&manifest_path).map_err(|e| err(&e))?;
    let root = dir.canonicalize().map_err(|e| err(&e))?;
    let mut dirs: Vec<PathBuf> = Vec::new();
    for rel in manifest.snapshots.iter().flat_map(|s| &s.frames) {
        let path = dir.join(rel);
        // Only files inside the scan directory are removed.
        if let Ok(real) = path.canonicalize()
            && real.starts_with(&root)
            && real.is_file()
        {
            std::fs::remove_file(&real).map_err(|e| err(&e))?;
            if let Some(p) = real.parent() {
                dirs.push(p.to_owned());
            }
        }
    }
    std::fs::remove_file(&manifest_path).map_err(|e| err(&e))?;
    dirs.sort();
    dirs.dedup();
    for d in dirs.iter().rev().filter(|d| **d != root) {
        let _ = std::fs::remove_dir(d); // only when empty
    }
    Ok(())
}

/// Live capture: a Kinect v1 through libfreenect and a networked turntable.
#[cfg(feature = "freenect")]
mod live {
    use super::*;
    use voxoct_kinect::{KinectOptions, KinectSource};
    use voxoct_turntable::{ClientTimeouts, RemoteTurntable};

    pub(super) fn capture(
        session: &Session,
        config: Option<ScannerConfig>,
        params: &Params,
        on_event: &mut impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        let Source::Kinect {
            turntable,
            token,
            depth,
            verbose,
        } = &session.source
        else {
            unreachable!("live::capture is called for Source::Kinect");
        };
        let addr = turntable.as_deref().ok_or_else(|| {
            input(
                "--turntable",
                "--kinect needs a turntable: --turntable HOST:PORT (examples/turntable_server.rs on the Pi)",
            )
        })?;
        let config = config.ok_or_else(|| {
            input(
                "--config",
                "--kinect needs --config FILE with the rig's [sensor], [rig] and [clip] (see examples/thesis-rig.toml)",
            )
        })?;
        let (n, f) = (u64::from(session.snapshots), u64::from(session.frames));
        session.check_memory(&config, params, n, n * f)?;
        // The sensor first: it is local, and without it there is nothing to turn the table for.
        if let Some(dir) = std::env::var_os("FAKENECT_PATH") {
            check_fakenect_length(Path::new(&dir), session.snapshots, session.frames)?;
        }
        let options = KinectOptions {
            depth: *depth,
            verbose: *verbose,
        };
        let mut kinect = KinectSource::open_with(0, options)
            .and_then(|k| k.with_intrinsics(config.sensor.intrinsics))
            .map_err(|e| device("Kinect")(&e))?;
        on_event(Event::SensorOpen(*depth));
        let mut table = RemoteTurntable::connect(addr, token.as_deref(), ClientTimeouts::default())
            .map_err(|e| device(format!("turntable at {addr}"))(&e))?;
        let snapshots = super::capture(
            &mut kinect,
            &mut table,
            |_, _| {},
            session.snapshots,
            session.frames,
            on_event,
        )?;
        Ok(Acquired {
            config,
            source: format!("Kinect v1 ({depth} depth)"),
            snapshots,
        })
    }

    /// A rehearsed live scan (FAKENECT_PATH set, libfreenect's fakenect library loaded) needs a
    /// recording long enough: opening the Kinect consumes one frame, the scan `snapshots ×
    /// frames`, and libfreenect 0.5's fakenect ends its runloop at the end of `INDEX.txt` — a
    /// grab after that crashes or waits for ever — so one frame more must follow the last one
    /// grabbed.
    fn check_fakenect_length(dir: &Path, snapshots: u32, frames: u32) -> Result<(), SessionError> {
        let count = FakenectSource::open(dir)
            .map_err(|e| input("--kinect", format!("FAKENECT_PATH: {e}")))?
            .depth_frame_count();
        let need = 2 + snapshots as usize * frames as usize;
        if count < need {
            return Err(input(
                "--kinect",
                format!(
                    "FAKENECT_PATH {}: {count} depth frames, but a live scan of {snapshots} \
                     snapshots × {frames} frames needs at least {need} (1 consumed on opening, \
                     then the scan's, then 1 more before the end of the recording); record one \
                     with the record_fakenect example",
                    dir.display(),
                ),
            ));
        }
        Ok(())
    }
}

/// Without the `freenect` feature a live scan is not possible: say how to get one.
#[cfg(not(feature = "freenect"))]
mod live {
    use super::*;

    pub(super) fn capture(
        _: &Session,
        _: Option<ScannerConfig>,
        _: &Params,
        _: &mut impl FnMut(Event<'_>),
    ) -> Result<Acquired, SessionError> {
        Err(input(
            "--kinect",
            "--kinect needs the live sensor support: install libfreenect-dev and run with \
             `cargo run --release --features freenect --example scan -- --kinect ...`",
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulator_and_scanner_conversions_round_trip() {
        let sim = SimConfig::default();
        let config = scanner_config_of(&sim);
        let back = sim_config_of(&config, sim.seed, sim.exact);
        assert_eq!(back.intrinsics, sim.intrinsics);
        assert_eq!(back.rig, sim.rig);
        assert_eq!(back.unit_m, sim.unit_m);
    }

    #[test]
    fn out_of_range_capture_sizes_name_their_flag() {
        for (session, flag) in [
            (
                Session {
                    snapshots: 0,
                    ..Session::default()
                },
                "--snapshots",
            ),
            (
                Session {
                    frames: MAX_FRAMES + 1,
                    ..Session::default()
                },
                "--frames",
            ),
            (
                Session {
                    source: Source::Fakenect {
                        dir: "x".into(),
                        degrees_per_snapshot: f32::NAN,
                    },
                    ..Session::default()
                },
                "--degrees-per-snapshot",
            ),
        ] {
            match session.validate() {
                Err(SessionError::Setting(e)) => {
                    assert_eq!(e.flag(), flag);
                    assert!(e.to_string().starts_with(flag), "{e}");
                }
                other => panic!("{flag}: {other:?}"),
            }
        }
        assert!(Session::default().validate().is_ok());
    }

    #[test]
    fn the_capture_loop_visits_equal_steps_from_home() {
        let mut kinect = SimulatedKinect::builtin(
            "sphere",
            SimConfig {
                exact: true,
                ..SimConfig::default()
            },
        )
        .unwrap();
        let mut table = SimulatedTurntable::new(SIM_MICROSTEPS_PER_REV).unwrap();
        let mut turns = 0;
        let snaps = capture(
            &mut kinect,
            &mut table,
            SimulatedKinect::set_turntable_angle_deg,
            4,
            2,
            |e| turns += usize::from(matches!(e, Event::Turned { .. })),
        )
        .unwrap();
        let angles: Vec<f32> = snaps.iter().map(|s| s.angle_deg).collect();
        assert_eq!(angles, [0.0, 90.0, 180.0, 270.0]);
        assert!(snaps.iter().all(|s| s.frames.len() == 2));
        assert_eq!(turns, 3);
    }

    #[test]
    fn a_model_in_metres_read_as_millimetres_is_too_small_and_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiny.stl");
        let sphere = Model::builtin("sphere").unwrap();
        // The sphere's metres written as file units: read as mm, it is 0.12 mm wide.
        voxoct_stl::write_file(
            &path,
            &sphere.vertices,
            &sphere.indices,
            voxoct_stl::StlFormat::Binary,
            1.0,
        )
        .unwrap();
        let err = load_model(&path, None, ModelUp::Y, &ScannerConfig::default(), 0.001)
            .unwrap_err()
            .to_string();
        assert!(err.contains("too small"), "{err}");
        assert!(
            load_model(
                &path,
                Some(ModelUnits::M),
                ModelUp::Y,
                &ScannerConfig::default(),
                0.001
            )
            .is_ok()
        );
    }
}
