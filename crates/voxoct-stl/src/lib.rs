//! voxoct-stl: mesh files for voxoct meshes — STL (binary and ASCII), 3MF, PLY and OBJ,
//! written and read.
//!
//! - [`MeshFormat`] names a format and is chosen from a file extension
//!   ([`MeshFormat::from_path`]) or a name; [`write_mesh`] / [`write_mesh_file`] write any
//!   of them, [`read_mesh`] / [`read_mesh_file`] read any of them back (bounded against
//!   hostile sizes, see [`MAX_ELEMENTS`]).
//! - 3MF ([`threemf`]): a ZIP package with `[Content_Types].xml`, `_rels/.rels` and
//!   `3D/3dmodel.model`, one object of type `model`, one build item, and the unit
//!   (`millimeter` for the default scale 1000).
//! - PLY ([`ply`]): binary little-endian, vertex normals `nx ny nz`, and a per-vertex `hits`
//!   property when [`MeshRef::hits`] is given.
//! - OBJ ([`obj`]): `v`, `vn`, `f a//a b//b c//c` (1-based).
//!
//! The rest of this page is about STL.
//!
//! The library works in metres; printers and slicers assume millimetres. The writers take a
//! `scale` applied at the file boundary (`1000.0` for metres → millimetres); the readers
//! return file units, and [`scale_triangles`] converts back.
//!
//! - [`write_binary`] / [`write_ascii`] stream an indexed mesh to any [`std::io::Write`];
//!   facet normals come from the winding (counter-clockwise seen from outside).
//! - [`write_file`] (and [`write_mesh_file`] for every format) writes through
//!   [`write_atomic`]: a temporary file in the same directory, synced and renamed, so a
//!   failed write never leaves a partial file at the destination. [`write_atomic`] is public
//!   so that every file the workspace writes goes through the same code.
//! - [`read()`] / [`read_file`] detect binary or ASCII robustly (a binary header may begin with
//!   `solid`), and report truncation, a count that disagrees with the length, non-finite
//!   coordinates and ASCII syntax errors with line numbers.
//! - [`weld`] turns the triangle soup back into an indexed mesh: identical `f32` bits are one
//!   vertex, which is what makes a welded STL watertight for slicers.
//!
//! ```
//! use voxoct_stl::{glam::Vec3, read, weld, write_binary};
//!
//! // A tetrahedron, outward wound, in metres.
//! let v = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z].map(|p| p * 0.01);
//! let t = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
//! let mut bytes = Vec::new();
//! write_binary(&mut bytes, &v, &t, 1000.0).unwrap(); // millimetres in the file
//! assert_eq!(bytes.len(), 84 + 4 * 50);
//!
//! let soup = read(bytes.as_slice()).unwrap();
//! let (vertices, triangles) = weld(&soup);
//! assert_eq!((vertices.len(), triangles.len()), (4, 4));
//! assert_eq!(soup[3].v[2], Vec3::new(0.0, 0.0, 10.0));
//! ```
//!
//! Throughput of the writers (`benches/stl.rs`): see BENCHMARKS.md.

pub use voxoct_core::glam;

mod atomic;
mod error;
mod format;
pub mod obj;
pub mod ply;
mod read;
pub mod threemf;
mod write;

pub use atomic::write_atomic;
pub use error::StlError;
pub use format::UpAxis;
pub use format::{
    MAX_ELEMENTS, MeshFormat, MeshRef, ReadMesh, WriteOptions, read_mesh, read_mesh_file,
    write_mesh, write_mesh_file,
};
pub use read::{MAX_FILE_BYTES, check_mesh_file, parse, read, read_file, scale_triangles, weld};
/// Area-weighted unit vertex normals (in `voxoct_core`, where the mesher uses them too).
pub use voxoct_core::vertex_normals;
pub use write::{
    BINARY_HEADER_BYTES, BINARY_TRIANGLE_BYTES, StlFormat, write, write_ascii, write_binary,
    write_file,
};
