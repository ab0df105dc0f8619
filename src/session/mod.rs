//! A scan session: where the frames come from, capturing them, and recording them.
//!
//! A [`Session`] names a [`Source`] — a simulated Kinect v1 looking at a built-in model or a
//! mesh file, a recorded-scan directory, a fakenect recording or (with the `freenect`
//! feature) a live Kinect and a networked turntable — with the capture's size.
//! [`Session::acquire`] checks it, estimates the memory the run will need
//! ([`crate::budget`]) and returns the scanner settings and the snapshots, ready for
//! [`crate::pipeline::reconstruct`]. [`capture()`] is the capture loop over any
//! [`DepthSource`] and [`Turntable`](voxoct_turntable::Turntable); [`record()`] writes what was acquired as a recorded-scan
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

use voxoct_depth::scan::{MANIFEST_FILE, RecordedScan, ScanManifest};
use voxoct_depth::{ScannerConfig, SensorConfig};
use voxoct_kinect::{
    DepthSource, FakenectSource, KinectDepth, Model, ModelUp, SimConfig, SimulatedKinect,
};
use voxoct_turntable::SimulatedTurntable;

use crate::budget;

pub use capture::capture;
pub use model::{MIN_MODEL_LEAVES, ModelUnits, load_model};
pub use record::{check_record_dir, clear_recorded_scan, record};

mod capture;
mod live;
mod model;
mod record;
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
    /// [`voxoct_depth::scan::default_memory_limit`].
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
            .unwrap_or_else(voxoct_depth::scan::default_memory_limit)
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
            Source::Kinect {
                turntable,
                token,
                depth,
                verbose,
            } => {
                let live = live::Live {
                    turntable: turntable.as_deref(),
                    token: token.as_deref(),
                    depth: *depth,
                    verbose: *verbose,
                };
                live::capture(self, &live, config, params, &mut on_event)
            }
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
        let mut scan = RecordedScan::from_manifest(dir, manifest, self.limit_bytes())
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
