//! Meshing throughput in leaves per second: the 1 mm shell of a 15 cm object; the exact
//! self-intersection test (what the smoothing's certificate costs) and simplification on
//! its smooth mesh.

use std::hint::black_box;

use criterion::{BatchSize, BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use voxoct_mesh::glam::{UVec3, Vec3};
use voxoct_mesh::{
    Cell, GridSpec, Mesh, MeshOptions, Mesher, Placement, Simplify, mesh_cells,
    self_intersecting_triangles, simplify,
};

/// Every 1 mm cell whose box meets a sphere of radius `r` metres (a 15 cm object for
/// r = 0.075), with the signed distance of its centre.
fn sphere_shell(r: f32) -> (Vec<Cell>, GridSpec) {
    let grid = GridSpec {
        origin: Vec3::splat(-0.128),
        cell: 0.001,
        resolution: 256,
    };
    let c = Vec3::splat(0.0003);
    let mut cells = Vec::new();
    let lo = ((c.x - r - grid.origin.x) / grid.cell) as u32 - 1;
    let hi = ((c.x + r - grid.origin.x) / grid.cell) as u32 + 1;
    for z in lo..=hi {
        for y in lo..=hi {
            for x in lo..=hi {
                let coord = UVec3::new(x, y, z);
                let b = grid.cell_aabb(coord);
                let near = (c.clamp(b.min, b.max) - c).length();
                let far = (c - b.min).abs().max((c - b.max).abs()).length();
                if near <= r && r <= far {
                    let sdf = (grid.cell_center(coord) - c).length() - r;
                    cells.push(Cell {
                        coord,
                        hits: 2,
                        sdf_sum: 2.0 * sdf,
                    });
                }
            }
        }
    }
    (cells, grid)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("mesh_shell");
    for r in [0.04f32, 0.075] {
        let (cells, grid) = sphere_shell(r);
        g.throughput(Throughput::Elements(cells.len() as u64));
        let presets = [
            ("thesis", MeshOptions::thesis()),
            (
                "solid_sdf",
                MeshOptions {
                    solid: true,
                    placement: Placement::SignedDistance,
                    ..MeshOptions::thesis()
                },
            ),
            ("smooth", MeshOptions::smooth()),
        ];
        // Steady state: a reused `Mesher` and output mesh (no allocation once warm).
        let mut mesher = Mesher::new();
        let mut out = Mesh::default();
        for (name, opts) in presets {
            g.bench_with_input(BenchmarkId::new(name, cells.len()), &cells, |b, cells| {
                b.iter(|| {
                    mesher
                        .mesh_cells_into(cells, &grid, &opts, &mut out)
                        .unwrap();
                    black_box(out.triangles.len())
                })
            });
        }
        // One-shot: fresh buffers every time (page faults included).
        g.bench_with_input(
            BenchmarkId::new("thesis_fresh", cells.len()),
            &cells,
            |b, cells| {
                b.iter(|| {
                    black_box(
                        mesh_cells(cells, &grid, &MeshOptions::thesis())
                            .unwrap()
                            .triangles
                            .len(),
                    )
                })
            },
        );
    }
    g.finish();
}

/// The exact self-intersection test on the smooth mesh of the 15 cm sphere shell.
fn bench_self_intersections(c: &mut Criterion) {
    let (cells, grid) = sphere_shell(0.075);
    let mesh = mesh_cells(&cells, &grid, &MeshOptions::smooth()).unwrap();
    let mut g = c.benchmark_group("self_intersections");
    g.throughput(Throughput::Elements(mesh.triangles.len() as u64));
    g.bench_with_input(
        BenchmarkId::new("smooth_sphere", mesh.triangles.len()),
        &mesh,
        |b, mesh| b.iter(|| black_box(self_intersecting_triangles(mesh).len())),
    );
    g.finish();
}

/// Simplification with the default bound of 1 mm leaves, on the smooth mesh of the 15 cm
/// sphere shell (about the bunny scan's size).
fn bench_simplify(c: &mut Criterion) {
    let (cells, grid) = sphere_shell(0.075);
    let mesh = mesh_cells(&cells, &grid, &MeshOptions::smooth()).unwrap();
    let opts = Simplify::for_leaf(grid.cell);
    let mut g = c.benchmark_group("simplify");
    g.throughput(Throughput::Elements(mesh.triangles.len() as u64));
    g.bench_with_input(
        BenchmarkId::new("smooth_sphere", mesh.triangles.len()),
        &mesh,
        |b, mesh| {
            b.iter_batched(
                || mesh.clone(),
                |mut m| black_box(simplify(&mut m, &opts).triangles_after),
                BatchSize::LargeInput,
            )
        },
    );
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench, bench_self_intersections, bench_simplify
}
criterion_main!(benches);
