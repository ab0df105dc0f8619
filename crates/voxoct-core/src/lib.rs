//! voxoct-core: the sparse octree and the exact triangle/box overlap test of
//! voxel octree intersection.
//!
//! (Front page under construction.)

pub use glam;

mod geometry;

pub use geometry::{Aabb, Cell, GridSpec, Real, Triangle};
