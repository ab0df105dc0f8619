//! voxoct-depth: everything between raw depth frames and the triangles the octree takes.
//!
//! 1. **Filter** the N frames of one snapshot into one [`DepthFrame`] with a
//!    [`FilterChain`]: the thesis's *Basic*, *Average* and *Average-Discard*, a temporal
//!    *median* that drops flickering pixels, and a spatial *outlier* rejection scaled by
//!    the Kinect v1 noise σ(z) ∝ z² (default chain: `average+outlier`).
//! 2. **Back-project, transform and clip** it into a [`Snapshot`]
//!    ([`Snapshot::from_frame`]): pixel `(u, v)` at depth `z` is
//!    `((u − cx) z / fx, (v − cy) z / fy, z)` in the camera frame, then
//!    [`Rig::camera_to_object`] takes it to the common object frame exactly as
//!    SCAN_FORMAT.md defines, and the [`ClipBox`] turns points outside into holes. The
//!    grid keeps one point per pixel (holes are NaN), so it can be stored
//!    ([`Snapshot::save`]) and re-run later with other parameters.
//! 3. **Triangulate** by pixel adjacency ([`triangulate`]): two triangles per pixel,
//!    none over a hole or with a squared edge above [`DEFAULT_MAX_EDGE_SQ`], each wound so
//!    that its normal faces the sensor (the outside of the object).
//!
//! 4. **Carve** ([`carve`]): what the frames say of every cell of a grid — seen empty, on a
//!    seen surface, or unseen — for closing what no view saw (`voxoct_mesh::closure`).
//!
//! Recorded scans (a `scan.toml` and 16-bit PNG frames) are read by
//! [`RecordedScan::open`] and written by [`ScanWriter`] / [`RecordedScan::write`]; the
//! scanner settings alone live in a [`ScannerConfig`] file.
//!
//! Speed (one core, `benches/depth.rs` on the bunny scan, a busy 2-core machine): one
//! snapshot's depth work — Average over 10 frames of 640×480 (1.7 ms), back-projection,
//! transform and clip (0.44 ms), triangulation (0.32 ms) — takes 2.4 ms; the default
//! chain's outlier rejection adds about 2 ms, the median instead of the mean about 1.3 ms.
//! A Kinect delivers a frame every 33 ms.
//!
//! ```
//! use voxoct_depth::{
//!     triangulate_vec, ClipBox, DepthFrame, FilterChain, Intrinsics, Rig, Snapshot,
//!     DEFAULT_MAX_EDGE_SQ,
//! };
//! use voxoct_depth::glam::Vec3;
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
//! # Ok::<(), voxoct_depth::DepthError>(())
//! ```

pub use glam;

mod calibrate;
pub mod carve;
mod error;
mod filter;
mod inspect;
mod scan;
mod snapshot;
mod triangulate;
mod types;

pub use calibrate::{
    AxisOptions, CalibError, CalibSnapshot, Calibration, Minimum, NelderMeadOptions, PlaneFit,
    PlatformFit, PlatformOptions, RESIDUAL_CAP_M, RansacOptions, alignment_residual, calibrate,
    calibrate_axis, calibrate_platform, fit_plane_ransac, nelder_mead,
};
pub use error::DepthError;
pub use filter::{FILTER_NAMES, Filter, FilterChain, KINECT_V1_SIGMA_COEFF, kinect_v1_sigma};
pub use inspect::{
    DiffStats, RgbImage, depth_image, difference_image, invalid_counts, snapshot_colour,
    snapshot_image, views_image, write_png, write_png_to,
};
pub use scan::{
    MANIFEST_FILE, MAX_ABS_ANGLE_DEG, MAX_FRAME_SIDE, RecordedScan, SCAN_FORMAT, SCAN_VERSION,
    ScanManifest, ScanWriter, ScannerConfig, SensorConfig, SnapshotEntry, default_memory_limit,
    read_png_frame, read_png_frame_sized, set_rig_in_manifest_text, write_png_frame,
};
pub use snapshot::{HOLE, Snapshot};
pub use triangulate::{DEFAULT_MAX_EDGE_SQ, triangulate, triangulate_vec};
pub use types::{ClipBox, DepthFrame, Intrinsics, Rig};
