//! voxoct-depth (under construction).

pub use glam;

mod types;

pub use types::{ClipBox, DepthFrame, Intrinsics, Rig};
