//! The guarantee: for any set of cells and any options the mesh is a closed, oriented
//! 2-manifold with positive volume whose triangles do not cut through each other (a valid
//! solid).

use proptest::prelude::*;
use voxoct_mesh::glam::{UVec3, Vec3};
use voxoct_mesh::{
    Cell, Floor, GridSpec, Mesh, MeshError, MeshOptions, Placement, Taubin, TopologyError,
    mesh_cells,
};

const RES: u32 = 16;

fn grid() -> GridSpec {
    GridSpec {
        origin: Vec3::new(-0.3, 0.1, 2.0),
        cell: 0.001,
        resolution: RES,
    }
}

fn cell(x: u32, y: u32, z: u32, hits: u32, sdf: f32) -> Cell {
    Cell {
        coord: UVec3::new(x, y, z),
        hits,
        sdf_sum: sdf * 0.001 * hits as f32,
    }
}

fn all_options() -> Vec<MeshOptions> {
    let mut out = Vec::new();
    for solid in [false, true] {
        for placement in [Placement::Midpoint, Placement::SignedDistance] {
            for (floor, close_gaps) in [
                (Floor::None, 0),
                (Floor::LowestMarked, 1),
                (Floor::Y(0.1 + 0.0042), 2),
            ] {
                for smoothing in [None, Some(Taubin::default())] {
                    for (min_hits, min_component_cells) in [(1, 0), (2, 3)] {
                        out.push(MeshOptions {
                            min_hits,
                            min_component_cells,
                            solid,
                            floor,
                            close_gaps,
                            placement,
                            smoothing,
                        });
                    }
                }
            }
        }
    }
    out
}

/// Checks that the mesh is a valid solid (closed, oriented, no self-intersection); an empty
/// mesh is fine only when no cell can produce a surface.
fn check(cells: &[Cell], opts: &MeshOptions) -> Result<Mesh, TestCaseError> {
    let mesh = mesh_cells(cells, &grid(), opts).map_err(|e| TestCaseError::fail(e.to_string()))?;
    match mesh.check_valid_solid() {
        Ok(()) => {}
        Err(TopologyError::Empty) => {}
        Err(e) => return Err(TestCaseError::fail(format!("{opts:?}: {e}"))),
    }
    Ok(mesh)
}

fn cells_strategy(max: usize) -> impl Strategy<Value = Vec<Cell>> {
    prop::collection::vec((0..RES, 0..RES, 0..RES, 1u32..4, -0.9f32..0.9), 1..max).prop_map(|v| {
        v.into_iter()
            .map(|(x, y, z, h, s)| cell(x, y, z, h, s))
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn random_cells_every_option(cells in cells_strategy(300)) {
        for opts in all_options() {
            check(&cells, &opts)?;
        }
    }

    #[test]
    fn random_dense_clusters(seed_cells in cells_strategy(12), r in 1u32..4) {
        // Blobs: every cell within r (L∞) of a seed, giving thick and touching shapes.
        let mut cells = Vec::new();
        for s in &seed_cells {
            let c = s.coord.as_ivec3();
            for dz in -(r as i32)..=r as i32 {
                for dy in -(r as i32)..=r as i32 {
                    for dx in -(r as i32)..=r as i32 {
                        let p = c + voxoct_mesh::glam::IVec3::new(dx, dy, dz);
                        if p.min_element() >= 0 && p.max_element() < RES as i32 && (dx + dy + dz) % 3 != 0 {
                            cells.push(cell(p.x as u32, p.y as u32, p.z as u32, 1 + (dx & 1) as u32, (dx - dy) as f32 * 0.3));
                        }
                    }
                }
            }
        }
        for opts in [MeshOptions::thesis(), MeshOptions::smooth(), MeshOptions { solid: true, ..MeshOptions::thesis() }] {
            check(&cells, &opts)?;
        }
    }

    #[test]
    fn removing_small_pieces_keeps_the_mesh_closed(cells in cells_strategy(300), min in 2usize..200) {
        for opts in [MeshOptions::thesis(), MeshOptions::smooth()] {
            let mut mesh = check(&cells, &opts)?;
            let before = mesh.stats().components;
            let removed = mesh.remove_small_components(min);
            if mesh.triangles.is_empty() {
                continue;
            }
            mesh.check_valid_solid().map_err(|e| TestCaseError::fail(format!("{opts:?}: {e}")))?;
            prop_assert_eq!(mesh.stats().components, before - removed);
            // Every piece left has at least `min` triangles: removing again removes nothing.
            prop_assert_eq!(mesh.remove_small_components(min), 0);
            // Relative removal: what is left is closed, and removing again removes nothing.
            mesh.remove_pieces_below_fraction(0.5);
            mesh.check_valid_solid().map_err(|e| TestCaseError::fail(format!("{opts:?}: {e}")))?;
            prop_assert_eq!(mesh.remove_pieces_below_fraction(0.5), 0);
        }
    }

    #[test]
    fn thousands_of_random_cells(cells in cells_strategy(3000)) {
        for opts in [MeshOptions::thesis(), MeshOptions::smooth()] {
            check(&cells, &opts)?;
        }
    }
}

/// Cells near a noisy signed-distance field of thin shapes (walls one or two cells thick,
/// small shells, close parallel sheets): where smoothing and sub-cell placement could push
/// sheets through each other.
fn noisy_shape(kind: u8, size: f32, thick: f32, tilt: f32, noise: &[f32]) -> Vec<Cell> {
    let c = Vec3::splat(RES as f32 / 2.0);
    let n = Vec3::new(tilt, 1.0, 0.3 * tilt).normalize();
    let mut cells = Vec::new();
    let mut k = 0usize;
    for z in 0..RES {
        for y in 0..RES {
            for x in 0..RES {
                let p = Vec3::new(x as f32, y as f32, z as f32) + 0.5 - c;
                let d = match kind {
                    // A thin slab.
                    0 => p.dot(n).abs() - thick,
                    // A thin spherical shell.
                    1 => (p.length() - size).abs() - thick,
                    // Two close parallel slabs.
                    _ => (p.dot(n).abs() - size * 0.5).abs() - thick,
                };
                let e = noise[k % noise.len()];
                k += 1;
                if d + e < 0.9 {
                    cells.push(cell(x, y, z, 1 + (k % 3) as u32, (d + e).clamp(-0.9, 0.9)));
                }
            }
        }
    }
    cells
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn noisy_thin_shapes_every_option(
        kind in 0u8..3,
        size in 1.5f32..6.0,
        thick in 0.2f32..1.2,
        tilt in -1.0f32..1.0,
        noise in prop::collection::vec(-0.6f32..0.6, 1..97),
    ) {
        let cells = noisy_shape(kind, size, thick, tilt, &noise);
        for opts in all_options() {
            check(&cells, &opts)?;
        }
        // Harder smoothing than the default: more room to tangle.
        let hard = MeshOptions {
            smoothing: Some(Taubin { iterations: 40, lambda: 0.9, mu: -0.95 }),
            ..MeshOptions::smooth()
        };
        check(&cells, &hard)?;
    }
}

#[test]
fn single_cells_everywhere_including_grid_corners() {
    for &(x, y, z) in &[(0, 0, 0), (15, 15, 15), (0, 15, 7), (5, 6, 7)] {
        for opts in all_options() {
            let m = check(&[cell(x, y, z, 3, 0.1)], &opts).unwrap();
            let below_floor = matches!(opts.floor, Floor::Y(_)) && y < 4;
            let sdf_outside = opts.solid && opts.placement == Placement::SignedDistance;
            if opts.min_component_cells <= 1 && !sdf_outside && !below_floor {
                assert!(!m.triangles.is_empty(), "{opts:?}");
            }
        }
    }
}

#[test]
fn checkerboard_and_diagonal_contacts() {
    let mut board = Vec::new();
    for z in 2..10 {
        for y in 2..10 {
            for x in 2..10 {
                if (x + y + z) % 2 == 0 {
                    board.push(cell(x, y, z, 2, -0.2));
                }
            }
        }
    }
    // Every kind of diagonal contact: edge-touching in each plane and both diagonal senses,
    // corner-touching along all four body diagonals.
    let mut diag = Vec::new();
    let pairs: &[[i32; 3]] = &[
        [1, 1, 0],
        [1, -1, 0],
        [1, 0, 1],
        [1, 0, -1],
        [0, 1, 1],
        [0, 1, -1],
        [1, 1, 1],
        [1, 1, -1],
        [1, -1, 1],
        [-1, 1, 1],
    ];
    for (k, d) in pairs.iter().enumerate() {
        let base = [2 + 3 * (k as i32 % 4), 3 + 4 * (k as i32 / 4), 5];
        diag.push(cell(base[0] as u32, base[1] as u32, base[2] as u32, 1, 0.0));
        diag.push(cell(
            (base[0] + d[0]) as u32,
            (base[1] + d[1]) as u32,
            (base[2] + d[2]) as u32,
            1,
            0.0,
        ));
    }
    for opts in all_options() {
        check(&board, &opts).unwrap();
        let m = check(&diag, &opts).unwrap();
        if opts == MeshOptions::thesis() {
            // Pairs along Kuhn diagonals (+,+ senses) join, the others stay apart.
            assert_eq!(m.stats().components, 4 + 2 * 6, "{:?}", m.stats());
        }
    }
}

#[test]
fn thin_walls_full_blocks_and_hollow_boxes() {
    let mut wall = Vec::new();
    let mut block = Vec::new();
    let mut boxy = Vec::new();
    for z in 0..RES {
        for y in 0..RES {
            wall.push(cell(7, y, z, 1, 0.3));
            for x in 0..RES {
                block.push(cell(x, y, z, 1, 0.0));
                let border = [x, y, z].iter().any(|&c| c == 2 || c == 12);
                let within = [x, y, z].iter().all(|&c| (2..=12).contains(&c));
                if border && within {
                    boxy.push(cell(x, y, z, 1, if x == 2 { -0.4 } else { 0.4 }));
                }
            }
        }
    }
    for opts in all_options() {
        check(&wall, &opts).unwrap();
        check(&block, &opts).unwrap();
        check(&boxy, &opts).unwrap();
    }
    // A hollow box: two walls in thesis mode, one in solid mode, same outer bounds.
    let hollow = mesh_cells(&boxy, &grid(), &MeshOptions::thesis()).unwrap();
    let solid = mesh_cells(
        &boxy,
        &grid(),
        &MeshOptions {
            solid: true,
            ..MeshOptions::thesis()
        },
    )
    .unwrap();
    assert_eq!(hollow.stats().components, 2);
    assert_eq!(solid.stats().components, 1);
    assert_eq!(hollow.stats().bounds, solid.stats().bounds);
    assert!(
        solid.triangles.len() * 100 < hollow.triangles.len() * 65,
        "{} vs {}",
        solid.triangles.len(),
        hollow.triangles.len()
    );
    assert!(solid.volume() > 2.0 * hollow.volume());
}

#[test]
fn min_hits_and_small_components() {
    let mut cells = Vec::new();
    for x in 3..9 {
        for y in 3..9 {
            cells.push(cell(x, y, 5, 2, 0.0));
        }
    }
    cells.push(cell(13, 13, 13, 1, 0.0)); // weak, isolated
    cells.push(cell(0, 14, 0, 5, 0.0)); // strong, isolated
    let base = mesh_cells(&cells, &grid(), &MeshOptions::thesis()).unwrap();
    assert_eq!(base.stats().components, 3);
    let weak = MeshOptions {
        min_hits: 2,
        ..MeshOptions::thesis()
    };
    assert_eq!(
        mesh_cells(&cells, &grid(), &weak)
            .unwrap()
            .stats()
            .components,
        2
    );
    let small = MeshOptions {
        min_component_cells: 2,
        ..MeshOptions::thesis()
    };
    let m = mesh_cells(&cells, &grid(), &small).unwrap();
    assert_eq!(m.stats().components, 1);
    m.check_closed_manifold().unwrap();
}

#[test]
fn open_cup_is_closed_by_the_floor_in_solid_mode() {
    // An upside-down cup: walls and a top, no bottom (what a turntable scan sees). Solid with
    // the floor at the lowest layer fills it.
    let mut cup = Vec::new();
    for y in 3..12 {
        for z in 3..12 {
            for x in 3..12 {
                if x == 3 || x == 11 || z == 3 || z == 11 || y == 11 {
                    cup.push(cell(x, y, z, 1, 0.0));
                }
            }
        }
    }
    let closed = MeshOptions {
        solid: true,
        floor: Floor::LowestMarked,
        ..MeshOptions::thesis()
    };
    let open = MeshOptions {
        solid: true,
        floor: Floor::None,
        ..MeshOptions::thesis()
    };
    let a = mesh_cells(&cup, &grid(), &closed).unwrap();
    let b = mesh_cells(&cup, &grid(), &open).unwrap();
    a.check_closed_manifold().unwrap();
    b.check_closed_manifold().unwrap();
    assert_eq!(a.stats().components, 1);
    // Filled: the volume covers the whole 9×9×9 block (≈ 729 cells, minus half-cell rims).
    let cells_vol = a.volume() / 1e-9;
    assert!(cells_vol > 500.0, "{cells_vol}");
    assert!(b.volume() < a.volume() * 0.6);
    // Flat base: the lowest vertices all lie on one plane, half a cell under the floor
    // layer's centres (layer 3: centres at 3.5 cells).
    let min_y = a.vertices.iter().map(|v| v.y).fold(f32::MAX, f32::min);
    assert!((min_y - (0.1 + 3.0 * 0.001)).abs() < 1e-6, "{min_y}");
    let base = a
        .vertices
        .iter()
        .filter(|v| (v.y - min_y).abs() < 1e-6)
        .count();
    assert!(base > 49, "{base}");
}

#[test]
fn errors_name_the_cell_and_option() {
    let e = mesh_cells(&[cell(1, 2, 16, 1, 0.0)], &grid(), &MeshOptions::thesis()).unwrap_err();
    assert!(e.to_string().contains("cell 0"), "{e}");
    let bad = MeshOptions {
        smoothing: Some(Taubin {
            iterations: 1,
            lambda: 0.5,
            mu: 0.5,
        }),
        ..MeshOptions::thesis()
    };
    assert!(matches!(
        mesh_cells(&[], &grid(), &bad),
        Err(MeshError::InvalidArgument {
            name: "smoothing.mu",
            ..
        })
    ));
    let g = GridSpec {
        cell: 0.0,
        ..grid()
    };
    let e = mesh_cells(&[], &g, &MeshOptions::thesis()).unwrap_err();
    assert!(
        matches!(
            e,
            MeshError::InvalidArgument {
                name: "grid.cell",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("grid.cell"), "{e}");
    assert!(
        mesh_cells(&[], &grid(), &MeshOptions::thesis())
            .unwrap()
            .triangles
            .is_empty()
    );
}

#[test]
fn checker_names_what_is_wrong() {
    let mut m = mesh_cells(&[cell(4, 4, 4, 1, 0.0)], &grid(), &MeshOptions::thesis()).unwrap();
    m.check_closed_manifold().unwrap();
    let mut flipped = m.clone();
    flipped.triangles[3].swap(0, 1);
    assert!(matches!(
        flipped.check_closed_manifold(),
        Err(TopologyError::RepeatedEdge { .. })
    ));
    let mut holed = m.clone();
    holed.triangles.pop();
    assert!(matches!(
        holed.check_closed_manifold(),
        Err(TopologyError::OpenEdge { .. })
    ));
    let mut inverted = m.clone();
    for t in &mut inverted.triangles {
        t.swap(0, 1);
    }
    assert!(matches!(
        inverted.check_closed_manifold(),
        Err(TopologyError::NonPositiveVolume { .. })
    ));
    // Two copies glued at one vertex: a pinched, non-manifold vertex.
    let n = m.vertices.len() as u32;
    let mut pinched = m.clone();
    let shift = m.vertices[1] - m.vertices[0];
    pinched
        .vertices
        .extend(m.vertices.iter().map(|&p| p + shift * 2.0 + Vec3::X * 1e-9));
    let far = m.vertices[0] + shift * 2.0;
    let _ = far;
    pinched
        .triangles
        .extend(m.triangles.iter().map(|t| t.map(|i| i + n)));
    // Make copy's vertex 0 the original vertex 1 by relabelling.
    let v0 = n;
    for t in pinched.triangles.iter_mut().skip(m.triangles.len()) {
        for i in t.iter_mut() {
            if *i == v0 {
                *i = 1;
            }
        }
    }
    pinched.vertices[v0 as usize] = Vec3::splat(1e3); // unused now
    match pinched.check_closed_manifold() {
        Err(TopologyError::UnusedVertex { vertex }) => assert_eq!(vertex, v0),
        other => panic!("{other:?}"),
    }
    pinched.remove_unused_vertices();
    match pinched.check_closed_manifold() {
        Err(TopologyError::NonManifoldVertex {
            vertex: 1, fans: 2, ..
        }) => {}
        other => panic!("{other:?}"),
    }
    m.vertices[2] = m.vertices[1];
    assert!(matches!(
        m.check_closed_manifold(),
        Err(TopologyError::Degenerate { .. }) | Err(TopologyError::DuplicatePosition { .. })
    ));
}

#[test]
fn valid_solid_check_counts_self_intersections() {
    let m = mesh_cells(&[cell(4, 4, 4, 1, 0.0)], &grid(), &MeshOptions::thesis()).unwrap();
    m.check_valid_solid().unwrap();
    assert!(m.self_intersecting_triangles().is_empty());
    // Two overlapping copies: closed and oriented, but cutting through each other.
    let mut two = m.clone();
    let n = m.vertices.len() as u32;
    let shift = Vec3::new(0.0003, 0.0002, 0.0001);
    two.vertices.extend(m.vertices.iter().map(|&p| p + shift));
    two.triangles
        .extend(m.triangles.iter().map(|t| t.map(|i| i + n)));
    two.check_closed_manifold().unwrap();
    let bad = two.self_intersecting_triangles();
    match two.check_valid_solid() {
        Err(TopologyError::SelfIntersecting { triangles, first }) => {
            assert!(triangles > 0);
            assert_eq!((triangles, first), (bad.len(), bad[0] as usize));
        }
        other => panic!("{other:?}"),
    }
}
