//! voxoct: watertight 3D scans from a depth sensor and a turntable.
//!
//! A facade over the member crates — each usable alone — and [`pipeline`], the whole
//! reconstruction in one call:
//!
//! | module | crate | what |
//! |---|---|---|
//! | [`core`] | `voxoct-core` | triangle/box overlap, the sparse octree |
//! | [`mesh`] | `voxoct-mesh` | pseudo-voxels, marching tetrahedra, closure, smoothing, valid-solid check |
//! | [`depth`] | `voxoct-depth` | frames, filters, rig transform, triangulation, recorded scans |
//! | [`kinect`] | `voxoct-kinect` | depth sources: simulated Kinect v1, fakenect, live (`freenect`) |
//! | [`turntable`] | `voxoct-turntable` | turntables: simulated, stepper on GPIO (`gpio`), TCP |
//! | [`stl`] | `voxoct-stl` | mesh files: STL, 3MF, PLY, OBJ; the atomic file writer |
//!
//! Above them, what a scanning tool needs: [`session`] (where the frames come from: a
//! simulated or live capture over a turntable, a recorded scan, a fakenect recording),
//! [`budget`] (the memory a run will need), [`mesh_file`] (the mesh file's format, units
//! and frame), [`preview`] (a shaded picture of the result) and [`output`] (output files
//! checked up front, written all or nothing). The `scan` example is these calls and its
//! flags; [`session`] shows a whole scan scripted with the library alone.
//!
//! ```
//! use voxoct::depth::ScannerConfig;
//! use voxoct::kinect::{DepthSource, SimConfig, SimulatedKinect};
//! use voxoct::pipeline::{Params, SnapshotFrames, reconstruct};
//!
//! // Four noise-free simulated snapshots of a sphere, 90° apart, meshed at 4 mm.
//! let sim = SimConfig { exact: true, ..SimConfig::default() };
//! let mut kinect = SimulatedKinect::builtin("sphere", sim)?;
//! let mut snapshots = Vec::new();
//! for k in 0..4 {
//!     let angle = 90.0 * k as f32;
//!     kinect.set_turntable_angle_deg(angle);
//!     snapshots.push(SnapshotFrames { angle_deg: angle, frames: vec![kinect.grab(std::time::Duration::from_secs(1))?] });
//! }
//! let config = ScannerConfig { rig: sim.rig, ..ScannerConfig::default() };
//! let params = Params { leaf_m: 0.004, ..Params::default() };
//! let result = reconstruct(&config, snapshots, &params, |_| {})?;
//! assert!(result.mesh.check_closed_manifold().is_ok());
//! // The built-in sphere has a radius of 6 cm: the mesh's volume is close to 4/3·π·r³.
//! let volume = result.mesh.stats().volume;
//! let expected = 4.0 / 3.0 * std::f64::consts::PI * 0.06f64.powi(3);
//! assert!((volume / expected - 1.0).abs() < 0.15, "{volume} vs {expected}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use voxoct_core as core;
pub use voxoct_depth as depth;
pub use voxoct_kinect as kinect;
pub use voxoct_mesh as mesh;
pub use voxoct_stl as stl;
pub use voxoct_turntable as turntable;

pub mod budget;
pub mod mesh_file;
pub mod output;
mod par;
pub mod pipeline;
pub mod preview;
pub mod session;

pub use par::threads;

/// The README's code blocks, compiled and run as doctests (`cargo test --doc`), so that
/// what it shows works as pasted.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
