//! The output mesh file: its format (from `--out`'s extension or `--format`), its frame
//! (Z up for printing unless `--up y`) and its bytes (written through `outputs.rs`).

use clap::ValueEnum;
use voxoct::mesh::{Mesh, Octree, print_frame_vertices, vertex_hits};
use voxoct::stl::{MeshFormat, MeshRef, StlFormat, WriteOptions};

use crate::{Args, Units};

/// Which axis of the written file points up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Up {
    /// Z up, base on z = 0, centred in x and y: what slicers and viewers expect.
    Z,
    /// Y up: the library's platform frame (SCAN_FORMAT.md), unchanged.
    Y,
}

/// The format `--format` names, else the one `--out`'s extension names; STL for standard
/// output (`-`) and for what is not a file name with an extension of its own (a device, a
/// FIFO, a directory: the output check then says what is wrong with it).
pub fn format(args: &Args) -> Result<MeshFormat, String> {
    let out = &args.out;
    let not_a_file_name = out.as_os_str() == "-"
        || out.as_os_str().to_string_lossy().ends_with('/')
        || std::fs::metadata(out).is_ok_and(|m| !m.is_file());
    match &args.format {
        Some(name) => name.parse().map_err(|e| format!("--format: {e}")),
        None if out.extension().is_none() && not_a_file_name => Ok(MeshFormat::Stl),
        None => MeshFormat::from_path(&args.out).map_err(|e| {
            format!(
                "--out {}: {e} (or choose one with --format)",
                args.out.display()
            )
        }),
    }
}

/// Rejects output flags that cannot work, before any work is done.
pub fn check(args: &Args) -> Result<(), String> {
    let format = format(args)?;
    if args.ascii && format != MeshFormat::Stl {
        return Err(format!(
            "--ascii is for STL, but the output format is {format}"
        ));
    }
    if let Some(p) = &args.preview
        && !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        return Err(format!(
            "--preview {}: the preview is a PNG picture; name a .png file",
            p.display()
        ));
    }
    Ok(())
}

/// File units per metre.
pub fn scale(args: &Args) -> f32 {
    match args.units {
        Units::Mm => 1000.0,
        Units::M => 1.0,
    }
}

/// Writes `mesh` (platform frame, metres) into `w` in the format and frame `--out` asks for;
/// a PLY gets per-vertex hit counts from `tree`.
pub fn write(
    args: &Args,
    mesh: &Mesh,
    tree: &Octree,
    w: &mut dyn std::io::Write,
) -> std::io::Result<()> {
    let format = format(args).map_err(std::io::Error::other)?;
    let hits = (format == MeshFormat::Ply).then(|| vertex_hits(tree, &mesh.vertices));
    // The triangles do not change: only the vertices are copied into the print frame.
    let print;
    let vertices = match args.up {
        Up::Z => {
            print = print_frame_vertices(&mesh.vertices);
            &print
        }
        Up::Y => &mesh.vertices,
    };
    let opts = WriteOptions {
        scale: scale(args),
        stl: if args.ascii {
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
    voxoct::stl::write_mesh(w, format, m, &opts).map_err(std::io::Error::other)
}

/// How the summary names what was written, e.g. `3mf, mm, Z up`.
pub fn describe(args: &Args) -> String {
    let format = format(args).map_or_else(|_| "?".into(), |f| f.to_string());
    let units = match args.units {
        Units::Mm => "mm",
        Units::M => "m",
    };
    let up = match args.up {
        Up::Z => "Z up, base on z = 0",
        Up::Y => "Y up (platform frame)",
    };
    format!("{format}, {units}, {up}")
}
