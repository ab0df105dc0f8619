//! The sparse octree of marked leaves, one concept per file:
//!
//! - `tree`: [`Octree`], the public API — construction, insertion (serial, batched,
//!   parallel, and the thesis's reference descent), queries, merging, memory figures;
//! - `layout`: the leaf grid's geometry — the candidate cells of a box, the regions;
//! - `region`: the storage of one region — interior nodes, bricks, packed payloads,
//!   the dense scratch of an insertion batch;
//! - `morton`: Morton codes and bit helpers.
//!
//! The design (why the fast path marks exactly the reference's leaves, the storage
//! layout) is in ARCHITECTURE.md, section "voxoct-core".

mod layout;
mod morton;
mod region;
mod tree;

pub use tree::{MAX_DEPTH, Octree};
