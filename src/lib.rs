//! voxoct: watertight 3D scans from a depth sensor and a turntable.
//!
//! A facade over the member crates; see the README.

pub use voxoct_core as core;
pub use voxoct_depth as depth;
pub use voxoct_kinect as kinect;
pub use voxoct_mesh as mesh;
pub use voxoct_stl as stl;
pub use voxoct_turntable as turntable;
