//! voxoct-depth: everything between raw depth frames and the triangles the octree takes.
//!
//! Three concerns, each a group of public modules with its own error type:
//!
//! - **Frames → triangles** (always built): the shared types at the root ([`DepthFrame`],
//!   [`Intrinsics`], [`Rig`], [`ClipBox`], [`ScannerConfig`]); [`filter`] turns the frames
//!   of one snapshot into one ([`filter::FilterChain`]); [`snapshot`] back-projects,
//!   transforms and clips it into a point grid ([`snapshot::Snapshot`]); [`triangulate`]
//!   joins neighbouring pixels into triangles; [`carve`] says which cells of a grid the
//!   frames see empty; [`noise`] is the Kinect v1 noise model they share. Their errors are
//!   [`FrameError`] (and [`filter::FilterError`] for a chain that does not parse).
//! - **The recorded-scan directory** ([`scan`], feature `scan-dir`, on by default): a
//!   `scan.toml` and 16-bit PNG frames (SCAN_FORMAT.md), read, written and edited;
//!   errors are [`scan::ScanError`], naming the file and the key.
//! - **Calibration and inspection**: [`calib`] measures the rig from a scan
//!   ([`calib::CalibError`]); [`image`] draws frames, filter differences and aligned views
//!   as RGB images and writes PNGs (feature `png`, implied by `scan-dir`).
//!
//! Without default features the crate needs only `voxoct-core`, `glam` and `thiserror`: a
//! depth source can name a [`DepthFrame`] without TOML, PNG or serde.
//!
//! ARCHITECTURE.md (section voxoct-depth) explains the design.
//!
//! ```
//! use voxoct_depth::filter::FilterChain;
//! use voxoct_depth::glam::Vec3;
//! use voxoct_depth::snapshot::Snapshot;
//! use voxoct_depth::triangulate::{DEFAULT_MAX_EDGE_SQ, triangulate_vec};
//! use voxoct_depth::{ClipBox, DepthFrame, Intrinsics, Rig};
//!
//! // A small sensor looking straight at a wall 0.5 m away (two noisy frames).
//! // 5 mm between neighbouring pixels at 0.5 m.
//! let intr = Intrinsics { width: 8, height: 6, fx: 100.0, fy: 100.0, cx: 3.5, cy: 2.5 };
//! let mut a = DepthFrame::empty(8, 6, 0.001);
//! a.data.fill(500);
//! let mut b = a.clone();
//! b.data[0] = 0; // one missing reading
//! let frame = FilterChain::parse("average")?.apply(&[a, b])?;
//! assert_eq!(frame.depth_m(0, 0), Some(0.5));
//!
//! let rig = Rig { tilt_deg: 0.0, sensor_position_m: Vec3::new(0.0, 0.0, 0.7) };
//! let clip = ClipBox { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
//! let snap = Snapshot::from_frame(&frame, &intr, &rig, 0.0, &clip)?;
//! assert_eq!(snap.points.len(), 48);
//! // The wall sits at z = 0.7 − 0.5 = 0.2 m in the platform frame.
//! assert!(snap.valid_points().all(|p| (p.z - 0.2).abs() < 1e-6));
//!
//! // 7 × 5 pixels with a right and lower neighbour, two triangles each,
//! // all facing the sensor (+z).
//! let tris = triangulate_vec(&snap, DEFAULT_MAX_EDGE_SQ);
//! assert_eq!(tris.len(), 2 * 7 * 5);
//! assert!(tris.iter().all(|t| t.scaled_normal().z > 0.0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use glam;

#[cfg(feature = "png")]
mod atomic;
pub mod calib;
pub mod carve;
mod error;
pub mod filter;
pub mod image;
pub mod noise;
#[cfg(feature = "scan-dir")]
pub mod scan;
pub mod snapshot;
pub mod triangulate;
mod types;

pub use error::FrameError;
pub use types::{ClipBox, DepthFrame, Intrinsics, Rig, ScannerConfig, SensorConfig};
