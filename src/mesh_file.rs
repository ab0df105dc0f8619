//! The mesh file a scan writes: its format (from the file name or named), its units and
//! its frame (Z up for printing, or the platform frame).
//!
//! ```
//! use voxoct::mesh_file::{MeshFile, Units, Up};
//! let file = MeshFile::for_path("part.3mf".as_ref(), None, false, Units::Mm, Up::Z)?;
//! assert_eq!(file.describe(), "3mf, mm, Z up, base on z = 0");
//! // ASCII is an STL option only.
//! assert!(MeshFile::for_path("part.3mf".as_ref(), None, true, Units::Mm, Up::Z).is_err());
//! # Ok::<(), voxoct::pipeline::InvalidSetting>(())
//! ```

use std::path::Path;

use voxoct_core::Octree;
use voxoct_mesh::{Mesh, print_frame_vertices, vertex_hits};
use voxoct_stl::{MeshFormat, MeshRef, StlFormat, WriteOptions};

use crate::pipeline::InvalidSetting;

/// Which axis of the written file points up (the one type for every mesh file's up axis,
/// also [`voxoct_kinect::ModelUp`]).
pub use voxoct_stl::UpAxis as Up;

/// Units of the file's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Units {
    /// Millimetres: what every slicer assumes.
    #[default]
    Mm,
    /// Metres: the library's own unit.
    M,
}

impl Units {
    /// File units per metre.
    #[must_use]
    pub fn per_metre(self) -> f32 {
        match self {
            Self::Mm => 1000.0,
            Self::M => 1.0,
        }
    }
}

/// How a mesh is written: format, units, frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshFile {
    /// The file format.
    pub format: MeshFormat,
    /// ASCII STL instead of binary (STL only).
    pub ascii: bool,
    /// Units of the numbers.
    pub units: Units,
    /// The up axis.
    pub up: Up,
}

impl MeshFile {
    /// The file for `out`: the format `format` names, else the one `out`'s extension
    /// names; STL for standard output (`-`) and for what is not a file name with an
    /// extension of its own (a device, a FIFO, a directory: the output check then says
    /// what is wrong with it).
    ///
    /// # Errors
    /// [`InvalidSetting`] for `--format` (unknown), `--out` (no known extension) or
    /// `--ascii` (not STL).
    pub fn for_path(
        out: &Path,
        format: Option<&str>,
        ascii: bool,
        units: Units,
        up: Up,
    ) -> Result<Self, InvalidSetting> {
        let not_a_file_name = out.as_os_str() == "-"
            || out.as_os_str().to_string_lossy().ends_with('/')
            || std::fs::metadata(out).is_ok_and(|m| !m.is_file());
        let format = match format {
            Some(name) => name
                .parse()
                .map_err(|e| InvalidSetting::new("--format", format!("--format: {e}")))?,
            None if out.extension().is_none() && not_a_file_name => MeshFormat::Stl,
            None => MeshFormat::from_path(out).map_err(|e| {
                InvalidSetting::new(
                    "--out",
                    format!("--out {}: {e} (or choose one with --format)", out.display()),
                )
            })?,
        };
        if ascii && format != MeshFormat::Stl {
            return Err(InvalidSetting::new(
                "--ascii",
                format!("--ascii is for STL, but the output format is {format}"),
            ));
        }
        Ok(Self {
            format,
            ascii,
            units,
            up,
        })
    }

    /// Writes `mesh` (platform frame, metres) into `w` in this format and frame; a PLY
    /// gets per-vertex hit counts from `tree`.
    ///
    /// # Errors
    /// The writer's I/O errors.
    pub fn write(
        &self,
        mesh: &Mesh,
        tree: &Octree,
        w: &mut dyn std::io::Write,
    ) -> std::io::Result<()> {
        let hits = (self.format == MeshFormat::Ply).then(|| vertex_hits(tree, &mesh.vertices));
        // The triangles do not change: only the vertices are copied into the print frame.
        let print;
        let vertices = match self.up {
            Up::Z => {
                print = print_frame_vertices(&mesh.vertices);
                &print
            }
            Up::Y => &mesh.vertices,
        };
        let opts = WriteOptions {
            scale: self.units.per_metre(),
            stl: if self.ascii {
                StlFormat::Ascii
            } else {
                StlFormat::Binary
            },
        };
        let m = MeshRef {
            vertices,
            triangles: &mesh.triangles,
            hits: hits.as_deref(),
        };
        voxoct_stl::write_mesh(w, self.format, m, &opts).map_err(std::io::Error::other)
    }

    /// How a summary names the file, e.g. `3mf, mm, Z up, base on z = 0`.
    #[must_use]
    pub fn describe(&self) -> String {
        let units = match self.units {
            Units::Mm => "mm",
            Units::M => "m",
        };
        let up = match self.up {
            Up::Z => "Z up, base on z = 0",
            Up::Y => "Y up (platform frame)",
        };
        format!("{}, {units}, {up}", self.format)
    }
}

/// Checks that a preview picture's path names a PNG file.
///
/// # Errors
/// [`InvalidSetting`] for `--preview`.
pub fn check_preview_path(path: &Path) -> Result<(), InvalidSetting> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        Ok(())
    } else {
        Err(InvalidSetting::new(
            "--preview",
            format!(
                "--preview {}: the preview is a PNG picture; name a .png file",
                path.display()
            ),
        ))
    }
}
