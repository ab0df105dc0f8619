//! Simplifies a closed STL mesh: `simplify_stl IN.stl OUT.stl MAX_ERROR_M [TARGET]`
//! (coordinates in millimetres, as the scan example writes them).

use std::time::Instant;

use voxoct_mesh::{Mesh, Simplify, simplify};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err("usage: simplify_stl IN.stl OUT.stl MAX_ERROR_M [TARGET]".into());
    }
    let mut soup = voxoct_stl::read_file(&args[1])?;
    voxoct_stl::scale_triangles(&mut soup, 0.001);
    let (vertices, triangles) = voxoct_stl::weld(&soup);
    let mut mesh = Mesh {
        vertices,
        triangles,
    };
    let opts = Simplify {
        max_error: args[3].parse()?,
        target_triangles: args.get(4).map(|s| s.parse()).transpose()?,
    };
    let t = Instant::now();
    let stats = simplify(&mut mesh, &opts);
    let dt = t.elapsed();
    println!("{stats:?} in {dt:?}");
    mesh.check_closed_manifold()?;
    voxoct_stl::write_file(
        &args[2],
        &mesh.vertices,
        &mesh.triangles,
        voxoct_stl::StlFormat::Binary,
        1000.0,
    )?;
    Ok(())
}
