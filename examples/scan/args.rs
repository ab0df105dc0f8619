//! The `scan` example's flags, and what they ask the library for.

use std::path::PathBuf;

use clap::parser::ValueSource;
use clap::{ArgMatches, Parser, ValueEnum};

use voxoct::depth::filter::FilterChain;
use voxoct::mesh::{MeshOptions, Placement, Taubin};
use voxoct::mesh_file::{self, MeshFile};
use voxoct::pipeline::{Params, Simplification};
use voxoct::session::{self, Session, SimModel, Source};

/// Which axis of a file points up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Up {
    /// Z up, base on z = 0, centred in x and y: what slicers and viewers expect.
    Z,
    /// Y up: the library's platform frame (SCAN_FORMAT.md), unchanged.
    Y,
}

impl Up {
    /// The library's up axis for this flag value.
    fn axis(self) -> voxoct::mesh_file::Up {
        match self {
            Self::Z => voxoct::mesh_file::Up::Z,
            Self::Y => voxoct::mesh_file::Up::Y,
        }
    }
}

/// Units of a `--model` file's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelUnits {
    /// Millimetres: how slicers and CAD tools write STL, OBJ and PLY files for printing.
    Mm,
    /// Metres: the library's own unit.
    M,
    /// Inches.
    In,
}

/// Output units of the mesh file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Units {
    /// Millimetres: what every slicer assumes.
    Mm,
    /// Metres: the library's own unit.
    M,
}

/// Scan an object on a turntable into a watertight, printable STL (or 3MF, PLY, OBJ).
///
/// With no arguments: a simulated Kinect v1 scan of a built-in model, written to scan.stl.
#[derive(Debug, Parser)]
#[command(name = "scan", version)]
pub struct Args {
    // ---- where the depth frames come from -------------------------------------------------
    /// Process a recorded-scan directory (scan.toml + 16-bit PNG frames).
    #[arg(long, value_name = "DIR", help_heading = "Source")]
    pub input: Option<PathBuf>,
    /// Process a libfreenect (fakenect) recording; needs --degrees-per-snapshot.
    #[arg(
        long,
        value_name = "DIR",
        help_heading = "Source",
        requires = "degrees_per_snapshot"
    )]
    pub fakenect: Option<PathBuf>,
    /// Turntable angle between consecutive snapshots of a fakenect recording.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "D",
        help_heading = "Source"
    )]
    pub degrees_per_snapshot: Option<f32>,
    /// Simulated scan of your own mesh (STL, OBJ, PLY or 3MF), read as slicers write it:
    /// Z up, millimetres (3MF: its own unit); it keeps its size and orientation.
    #[arg(long, value_name = "FILE", help_heading = "Source")]
    pub model: Option<PathBuf>,
    /// Units of the --model file's numbers (default: mm, or the unit a 3MF file states).
    #[arg(long, value_enum, value_name = "UNIT", help_heading = "Source")]
    pub model_units: Option<ModelUnits>,
    /// Up axis of the --model file.
    #[arg(long, value_enum, default_value = "z", help_heading = "Source")]
    pub model_up: Up,
    /// Simulated scan of a built-in model (see --list-models).
    #[arg(
        long,
        value_name = "NAME",
        default_value = "figurine",
        help_heading = "Source"
    )]
    pub builtin: String,
    /// Print the built-in model names and exit.
    #[arg(long, help_heading = "Source")]
    pub list_models: bool,
    /// Live scan with a Kinect v1 (build with `--features freenect`).
    #[arg(long, help_heading = "Source")]
    pub kinect: bool,
    /// Depth stream of a live scan: `mm` (the device's own calibration), `raw` (11-bit
    /// disparities converted as the fakenect replay converts them; what libfreenect 0.5's
    /// fakenect library serves) or `registered` (aligned to the RGB camera). Default: mm.
    #[arg(long, value_name = "MODE", help_heading = "Source")]
    pub kinect_depth: Option<voxoct::kinect::KinectDepth>,
    /// Let libfreenect print its own messages during a live scan (quiet by default).
    #[arg(short, long, help_heading = "Source")]
    pub verbose: bool,
    /// The turntable server (examples/turntable_server.rs on the Pi) for a live scan.
    #[arg(long, value_name = "HOST:PORT", help_heading = "Source")]
    pub turntable: Option<String>,
    /// Shared secret of the turntable server (or VOXOCT_TURNTABLE_TOKEN).
    #[arg(
        long,
        value_name = "T",
        env = voxoct::turntable::TOKEN_ENV,
        hide_env_values = true,
        help_heading = "Source"
    )]
    pub token: Option<String>,
    /// Seed of the simulated sensor's noise.
    #[arg(long, default_value_t = 1, help_heading = "Source")]
    pub seed: u64,
    /// Simulate exact, noise-free frames.
    #[arg(long, help_heading = "Source")]
    pub exact: bool,
    /// Also write what was captured as a recorded-scan directory (new or empty).
    #[arg(long, value_name = "DIR", help_heading = "Source")]
    pub record_to: Option<PathBuf>,
    /// Let --record-to replace the recorded scan already in its directory.
    #[arg(long, requires = "record_to", help_heading = "Source")]
    pub force: bool,
    /// Scanner settings ([sensor], [rig], [clip] tables) overriding the source's own.
    #[arg(long, value_name = "FILE", help_heading = "Source")]
    pub config: Option<PathBuf>,
    /// Snapshots of a capture (turntable steps of 360°/N).
    #[arg(long, value_name = "N", default_value_t = 8, help_heading = "Source")]
    pub snapshots: u32,
    /// Frames per snapshot of a capture (fakenect: frames per snapshot).
    #[arg(long, value_name = "F", default_value_t = 4, help_heading = "Source")]
    pub frames: u32,

    // ---- reconstruction ---------------------------------------------------------------------
    /// Depth filter chain, e.g. `median+outlier`, `average`, `average-discard`, `basic`.
    #[arg(long, value_name = "NAME", default_value_t = FilterChain::default().to_string(), help_heading = "Reconstruction")]
    pub filter: String,
    /// Leaf size, metres (the real leaf edge is root / 2^depth, at most this).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M",
        default_value_t = 0.001,
        help_heading = "Reconstruction"
    )]
    pub leaf: f32,
    /// Edge of the octree's cubic root, metres (centred on the clip box).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M",
        default_value_t = 1.0,
        help_heading = "Reconstruction"
    )]
    pub root: f32,
    /// Largest squared triangle edge kept by the triangulation, m².
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M2",
        default_value_t = 0.0001,
        help_heading = "Reconstruction"
    )]
    pub threshold: f32,
    /// Mesh N levels coarser than the leaves (level of detail).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        help_heading = "Reconstruction"
    )]
    pub lod: u32,

    // ---- meshing ---------------------------------------------------------------------------
    /// The thesis's mesh: binary leaf values, hollow double-walled shell, no smoothing.
    #[arg(long, help_heading = "Meshing")]
    pub thesis: bool,
    /// Keep the hollow double-walled shell instead of one solid with a flat base.
    #[arg(long, help_heading = "Meshing")]
    pub hollow: bool,
    /// Place vertices at the leaf centres' midpoints (binary field) instead of the surface.
    #[arg(long, help_heading = "Meshing")]
    pub binary: bool,
    /// Drop pieces of the mesh smaller than this fraction of the largest (0 keeps all).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "FRACTION",
        default_value_t = 0.01,
        help_heading = "Meshing"
    )]
    pub min_piece: f32,
    /// Do not fill the space no frame could see (the unseen underside stays open to the
    /// solid fill, which may then leave the shell hollow there).
    #[arg(long, help_heading = "Meshing")]
    pub no_carve: bool,
    /// Taubin smoothing iterations (0 = none) [default: 10; with --thesis: 0].
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    pub smooth: Option<u32>,
    /// Largest error of the simplification (quadric edge collapse, closed and valid kept),
    /// metres [default: a quarter of the meshed cell, --leaf · 2^--lod; with --thesis: no
    /// simplification unless this or --triangles is given].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "M",
        help_heading = "Meshing"
    )]
    pub max_error: Option<f32>,
    /// Simplify down to at most N triangles (within --max-error).
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    pub triangles: Option<usize>,
    /// Keep every triangle of the marched, smoothed mesh (no simplification).
    #[arg(long, conflicts_with_all = ["max_error", "triangles"], help_heading = "Meshing")]
    pub no_simplify: bool,
    /// Leaves hit by fewer triangles count as empty (rejects single errant readings).
    #[arg(long, value_name = "N", default_value_t = MeshOptions::smooth().min_hits, help_heading = "Meshing")]
    pub min_hits: u32,
    /// Remove disconnected pieces of fewer leaves than this.
    #[arg(long, value_name = "N", help_heading = "Meshing")]
    pub min_component: Option<usize>,

    // ---- output ----------------------------------------------------------------------------
    /// The mesh file to write; its extension picks the format: .stl, .3mf, .ply, .obj
    /// (`-`: standard output, with --format).
    #[arg(
        long,
        value_name = "FILE",
        default_value = "scan.stl",
        help_heading = "Output"
    )]
    pub out: PathBuf,
    /// Format of --out regardless of its extension: stl, 3mf, ply or obj.
    #[arg(long, value_name = "FORMAT", help_heading = "Output")]
    pub format: Option<String>,
    /// Write ASCII STL instead of binary.
    #[arg(long, help_heading = "Output")]
    pub ascii: bool,
    /// Units of the file's numbers (3MF records them).
    #[arg(long, value_enum, default_value = "mm", help_heading = "Output")]
    pub units: Units,
    /// Up axis of the file: z (for printing: base on z = 0, centred in x and y) or y (the
    /// library's platform frame).
    #[arg(long, value_enum, default_value = "z", help_heading = "Output")]
    pub up: Up,
    /// Write figures of the run as one JSON object.
    #[arg(long, value_name = "FILE.json", help_heading = "Output")]
    pub stats: Option<PathBuf>,
    /// Write a shaded picture of the result from three sides.
    #[arg(long, value_name = "FILE.png", help_heading = "Output")]
    pub preview: Option<PathBuf>,
    /// Refuse runs estimated to need more memory than this (e.g. 8G, 512M; default: half
    /// the machine's memory).
    #[arg(long, value_name = "BYTES", value_parser = voxoct::budget::parse_bytes, help_heading = "Output")]
    pub max_memory: Option<u64>,
    /// No progress bars and no summary.
    #[arg(short, long, help_heading = "Output")]
    pub quiet: bool,
}

impl Args {
    /// The session the source flags describe.
    pub fn session(&self) -> Session {
        let source = if let Some(dir) = &self.input {
            Source::Recorded(dir.clone())
        } else if let Some(dir) = &self.fakenect {
            Source::Fakenect {
                dir: dir.clone(),
                // clap requires --degrees-per-snapshot with --fakenect.
                degrees_per_snapshot: self.degrees_per_snapshot.unwrap_or(f32::NAN),
            }
        } else if self.kinect {
            Source::Kinect {
                turntable: self.turntable.clone(),
                token: self.token.clone(),
                depth: self.kinect_depth.unwrap_or_default(),
                verbose: self.verbose,
            }
        } else {
            let model = match &self.model {
                Some(path) => SimModel::File {
                    path: path.clone(),
                    units: self.model_units.map(|u| match u {
                        ModelUnits::Mm => session::ModelUnits::Mm,
                        ModelUnits::M => session::ModelUnits::M,
                        ModelUnits::In => session::ModelUnits::In,
                    }),
                    up: self.model_up.axis(),
                },
                None => SimModel::Builtin(self.builtin.clone()),
            };
            Source::Simulated {
                model,
                seed: self.seed,
                exact: self.exact,
            }
        };
        Session {
            source,
            config_file: self.config.clone(),
            snapshots: self.snapshots,
            frames: self.frames,
            memory_limit: self.max_memory,
        }
    }

    /// The reconstruction the flags ask for (not yet checked: [`Params::validate`]).
    pub fn params(&self) -> Result<Params, String> {
        let mut mesh = if self.thesis {
            MeshOptions::thesis()
        } else {
            MeshOptions::smooth()
        };
        if self.hollow {
            mesh.solid = false;
        }
        if self.binary {
            mesh.placement = Placement::Midpoint;
        }
        if let Some(n) = self.smooth {
            mesh.smoothing = (n > 0).then(|| Taubin {
                iterations: n,
                ..Taubin::default()
            });
        }
        mesh.min_hits = self.min_hits;
        if let Some(c) = self.min_component {
            mesh.min_component_cells = c;
        }
        Ok(Params {
            filter: self.filter.parse().map_err(|e| format!("--filter: {e}"))?,
            leaf_m: self.leaf,
            root_m: self.root,
            max_edge_sq: self.threshold,
            lod: self.lod,
            mesh,
            carve: !self.no_carve,
            check_agreement: true,
            min_piece_fraction: self.min_piece,
            simplify: self.simplify(),
        })
    }

    /// The simplification `--max-error`, `--triangles`, `--no-simplify` and `--thesis` ask
    /// for: on by default (a quarter of the meshed cell unless `--max-error`); off with
    /// `--no-simplify`, and with `--thesis` unless asked for by the other two.
    fn simplify(&self) -> Option<Simplification> {
        let asked = self.max_error.is_some() || self.triangles.is_some();
        if self.no_simplify || (self.thesis && !asked) {
            return None;
        }
        Some(Simplification {
            max_error_m: self.max_error,
            target_triangles: self.triangles,
        })
    }

    /// The mesh file `--out`, `--format`, `--ascii`, `--units` and `--up` ask for.
    pub fn mesh_file(&self) -> Result<MeshFile, String> {
        let units = match self.units {
            Units::Mm => mesh_file::Units::Mm,
            Units::M => mesh_file::Units::M,
        };
        let file = MeshFile::for_path(
            &self.out,
            self.format.as_deref(),
            self.ascii,
            units,
            self.up.axis(),
        )
        .map_err(|e| e.to_string())?;
        if let Some(p) = &self.preview {
            mesh_file::check_preview_path(p).map_err(|e| e.to_string())?;
        }
        Ok(file)
    }

    /// The source flags: one source, and no flag that only another source reads.
    pub fn check_sources(&self, m: &ArgMatches) -> Result<(), String> {
        let chosen = [
            self.input.is_some(),
            self.fakenect.is_some(),
            self.model.is_some(),
            self.kinect,
        ];
        if chosen.iter().filter(|&&b| b).count() > 1 {
            return Err("choose one source: --input, --fakenect, --model or --kinect".into());
        }
        if self.turntable.is_some() && !self.kinect {
            return Err("--turntable is for live scans: add --kinect".into());
        }
        if self.kinect_depth.is_some() && !self.kinect {
            return Err("--kinect-depth is for live scans: add --kinect".into());
        }
        let source = match (&self.input, &self.fakenect, self.kinect, &self.model) {
            (Some(_), ..) => "--input",
            (_, Some(_), ..) => "--fakenect",
            (_, _, true, _) => "--kinect",
            (.., Some(_)) => "--model",
            _ => "--builtin",
        };
        let simulated = matches!(source, "--model" | "--builtin");
        let captured = simulated || source == "--kinect";
        let rules: [(&str, &str, bool); 7] = [
            (
                "degrees_per_snapshot",
                "--degrees-per-snapshot",
                source == "--fakenect",
            ),
            ("snapshots", "--snapshots", captured),
            ("frames", "--frames", captured || source == "--fakenect"),
            ("seed", "--seed", simulated),
            ("exact", "--exact", simulated),
            ("builtin", "--builtin", source == "--builtin"),
            ("token", "--token", self.turntable.is_some()),
        ];
        for (id, flag, applies) in rules {
            if !applies && m.value_source(id) == Some(ValueSource::CommandLine) {
                return Err(format!("{flag} does not apply to {source}: remove it"));
            }
        }
        Ok(())
    }
}
