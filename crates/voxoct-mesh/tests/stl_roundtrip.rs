//! A mesh written as STL (millimetres), read back and re-welded is still a closed, oriented
//! manifold: shared vertices are identical `f32` bits in the file, so slicers see it watertight.

mod common;

use proptest::prelude::*;
use voxoct_core::Octree;
use voxoct_mesh::glam::{UVec3, Vec3};
use voxoct_mesh::{Cell, GridSpec, Mesh, MeshOptions, mesh_cells, mesh_octree};
use voxoct_stl::{StlFormat, parse, weld, write};

fn round_trip(mesh: &Mesh, format: StlFormat) -> Mesh {
    let mut bytes = Vec::new();
    write(&mut bytes, &mesh.vertices, &mesh.triangles, format, 1000.0).unwrap();
    let (vertices, triangles) = weld(&parse(&bytes).unwrap());
    Mesh {
        vertices,
        triangles,
    }
}

fn assert_same_topology(a: &Mesh, b: &Mesh) {
    b.check_closed_manifold().unwrap();
    assert_eq!(a.triangles.len(), b.triangles.len());
    assert_eq!(a.vertices.len(), b.vertices.len());
    let (va, vb) = (a.volume() * 1e9, b.volume());
    assert!((va - vb).abs() <= 1e-4 * va.abs(), "{va} mm³ vs {vb} mm³");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn random_cells_survive_binary_and_ascii(
        cells in prop::collection::vec((0u32..12, 0u32..12, 0u32..12, -0.5f32..0.5), 1..200),
        smooth in any::<bool>(),
    ) {
        let grid = GridSpec { origin: Vec3::new(0.013, -0.2, 0.07), cell: 0.001, resolution: 12 };
        let cells: Vec<Cell> = cells
            .into_iter()
            .map(|(x, y, z, s)| Cell { coord: UVec3::new(x, y, z), hits: 1, sdf_sum: s * 0.001 })
            .collect();
        let opts = if smooth { MeshOptions::smooth() } else { MeshOptions::thesis() };
        let mesh = mesh_cells(&cells, &grid, &opts).unwrap();
        prop_assume!(!mesh.triangles.is_empty());
        for format in [StlFormat::Binary, StlFormat::Ascii] {
            assert_same_topology(&mesh, &round_trip(&mesh, format));
        }
    }
}

#[test]
fn octree_sphere_through_an_stl_file() {
    let c = Vec3::new(0.0011, -0.0023, 0.0005);
    let mut tree = Octree::new(Vec3::splat(-0.032), 0.064, 0.001).unwrap();
    tree.insert_all(&common::icosphere(c, 0.02, 4));
    let dir = tempfile_dir();
    for opts in [MeshOptions::thesis(), MeshOptions::smooth()] {
        let mesh = mesh_octree(&tree, &opts).unwrap();
        let path = dir.join("sphere.stl");
        voxoct_stl::write_file(
            &path,
            &mesh.vertices,
            &mesh.triangles,
            StlFormat::Binary,
            1000.0,
        )
        .unwrap();
        let (vertices, triangles) = weld(&voxoct_stl::read_file(&path).unwrap());
        let back = Mesh {
            vertices,
            triangles,
        };
        assert_same_topology(&mesh, &back);
        assert_eq!(back.stats().components, mesh.stats().components);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn tempfile_dir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("voxoct-mesh-stl-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}
