//! Octree invariants: fast insertion == the reference descent, parallel == serial,
//! merge, insert-then-query, level of detail, errors.

use proptest::prelude::*;
use voxoct_core::glam::{UVec3, Vec3};
use voxoct_core::{Aabb, Cell, MAX_DEPTH, Octree, OctreeError, Triangle};

#[allow(dead_code)]
mod support;
#[cfg(feature = "parallel")]
use support::snapshot;

/// A small tree so that the reference descent stays cheap; depth 0..=6 covers the
/// storage's special cases (regions smaller than a brick, single-brick regions).
fn tree(depth: u32) -> Octree {
    let edge = 0.8;
    let t = Octree::new(
        Vec3::new(-0.3, 0.1, -0.7),
        edge,
        edge / (1u32 << depth) as f32,
    )
    .unwrap();
    assert_eq!(t.depth(), depth);
    t
}

/// Triangles of every kind the octree must handle identically in both paths.
fn triangle_for(t: &Octree) -> impl Strategy<Value = Triangle> + use<> {
    let root = t.root();
    let grid = t.leaf_grid();
    let res = grid.resolution;
    let ext = root.max - root.min;
    let leaf = grid.cell;
    let anywhere = move |r: (f32, f32)| {
        (r.0..r.1, r.0..r.1, r.0..r.1)
            .prop_map(move |(x, y, z)| root.min + Vec3::new(x, y, z) * ext)
    };
    let corner = move || {
        (0..=res, 0..=res, 0..=res).prop_map(move |(x, y, z)| grid.corner(UVec3::new(x, y, z)))
    };
    prop_oneof![
        // Tiny: inside or across a leaf.
        (
            anywhere((0.0, 1.0)),
            -1.0f32..1.0,
            -1.0f32..1.0,
            -1.0f32..1.0,
            -1.0f32..1.0
        )
            .prop_map(move |(p, a, b, c, d)| Triangle::new(
                p,
                p + Vec3::new(a, b, 0.3) * leaf * 0.7,
                p + Vec3::new(c, 0.2, d) * leaf * 0.7
            )),
        // Anything, partly or fully outside included.
        (
            anywhere((-0.5, 1.5)),
            anywhere((-0.5, 1.5)),
            anywhere((-0.5, 1.5))
        )
            .prop_map(|(a, b, c)| Triangle::new(a, b, c)),
        // Huge: spanning the root.
        (
            anywhere((-3.0, 4.0)),
            anywhere((-3.0, 4.0)),
            anywhere((-3.0, 4.0))
        )
            .prop_map(|(a, b, c)| Triangle::new(a, b, c)),
        // Vertices on grid corners.
        (corner(), corner(), corner()).prop_map(|(a, b, c)| Triangle::new(a, b, c)),
        // Lying in a grid plane (axis-aligned), third vertex on a grid corner or not.
        (
            corner(),
            corner(),
            corner(),
            0usize..3,
            anywhere((0.0, 1.0)),
            any::<bool>()
        )
            .prop_map(|(a, b, c, axis, free, on_grid)| {
                let (mut b, mut c) = (b, c);
                b[axis] = a[axis];
                c[axis] = a[axis];
                let mut d = free;
                d[axis] = a[axis];
                Triangle::new(a, b, if on_grid { c } else { d })
            }),
        // Degenerate: repeated vertex, collinear, point.
        (corner(), anywhere((0.0, 1.0)), 0u8..3).prop_map(|(a, b, kind)| match kind {
            0 => Triangle::new(a, b, b),
            1 => Triangle::new(a, b, a + (b - a) * 0.5),
            _ => Triangle::new(a, a, a),
        }),
    ]
}

fn leaves(t: &Octree) -> Vec<Cell> {
    t.leaves().collect()
}

/// Cells with `sdf_sum` compared bit for bit.
fn bits(cells: &[Cell]) -> Vec<(UVec3, u32, u32)> {
    cells
        .iter()
        .map(|c| (c.coord, c.hits, c.sdf_sum.to_bits()))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    #[test]
    fn fast_insert_equals_reference(
        (depth, tris) in (0u32..=6).prop_flat_map(|d| (Just(d), prop::collection::vec(triangle_for(&tree(d)), 1..6)))
    ) {
        let mut fast = tree(depth);
        let mut reference = tree(depth);
        for t in &tris {
            let n_fast = fast.insert(t);
            let n_ref = reference.insert_reference(t);
            prop_assert_eq!(n_fast, n_ref, "triangle {:?} bits {:x?}", t, t.v.map(|v| v.to_array().map(f32::to_bits)));
        }
        prop_assert_eq!(bits(&leaves(&fast)), bits(&leaves(&reference)));
        prop_assert_eq!(fast.leaf_count(), leaves(&fast).len());
        // Degenerate triangles mark nothing (repeated vertices: exactly zero area; the
        // generated "collinear" ones are only collinear up to f32 rounding).
        for t in &tris {
            if t.v[0] == t.v[1] || t.v[1] == t.v[2] || t.v[2] == t.v[0] {
                let mut empty = tree(depth);
                prop_assert_eq!(empty.insert(t), 0);
                prop_assert!(empty.is_empty());
            }
        }
    }

}

/// Triangles a few leaves across (the insertion's 4×4×4 fast path and its
/// neighbours), anywhere, with vertices snapped to grid planes now and then so that
/// touching cases are common.
fn small_triangle_for(t: &Octree) -> impl Strategy<Value = Triangle> + use<> {
    let root = t.root();
    let grid = t.leaf_grid();
    let ext = root.max - root.min;
    let leaf = grid.cell;
    let snap = move |p: Vec3, on: [bool; 3]| {
        let mut q = p;
        for a in 0..3 {
            if on[a] {
                let i = ((p[a] - grid.origin[a]) / leaf).round().max(0.0) as u32;
                q[a] = grid.corner(UVec3::splat(i.min(grid.resolution)))[a];
            }
        }
        q
    };
    let offset =
        move |s: f32| (-s..s, -s..s, -s..s).prop_map(move |(x, y, z)| Vec3::new(x, y, z) * leaf);
    (
        (-0.05f32..1.05, -0.05f32..1.05, -0.05f32..1.05),
        prop_oneof![Just(0.5f32), Just(1.5f32), Just(2.5f32), Just(4.0f32)],
    )
        .prop_flat_map(move |((x, y, z), s)| {
            let p = root.min + Vec3::new(x, y, z) * ext;
            (
                Just(p),
                offset(s),
                offset(s),
                any::<[bool; 3]>(),
                any::<[bool; 3]>(),
                any::<[bool; 3]>(),
            )
        })
        .prop_map(move |(p, d1, d2, s0, s1, s2)| {
            Triangle::new(snap(p, s0), snap(p + d1, s1), snap(p + d2, s2))
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1500))]

    /// The fast path for triangles a few leaves across marks exactly the reference's
    /// leaves with bit-identical payloads, in deep trees too.
    #[test]
    fn small_triangles_equal_reference(
        (depth, tris) in prop_oneof![Just(3u32), Just(5u32), Just(8u32), Just(10u32)]
            .prop_flat_map(|d| (Just(d), prop::collection::vec(small_triangle_for(&tree(d)), 1..8)))
    ) {
        let mut fast = tree(depth);
        let mut reference = tree(depth);
        for t in &tris {
            prop_assert_eq!(fast.insert(t), reference.insert_reference(t), "triangle {:?}", t);
        }
        prop_assert_eq!(bits(&leaves(&fast)), bits(&leaves(&reference)));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    /// Batched insertion (bricks expanded for the batch, packed at its end) gives the
    /// tree of inserting one triangle at a time, also when a batch continues leaves
    /// of an earlier one.
    #[test]
    fn batches_equal_single_insertions(
        tris in prop::collection::vec(triangle_for(&tree(5)), 1..60),
        split in 0usize..60,
    ) {
        let mut single = tree(5);
        for t in &tris {
            single.insert(t);
        }
        let mut batched = tree(5);
        let (a, b) = tris.split_at(split.min(tris.len()));
        batched.insert_all(a);
        batched.insert_all(b);
        prop_assert_eq!(bits(&leaves(&batched)), bits(&leaves(&single)));
    }

    #[cfg(feature = "parallel")]
    #[test]
    fn par_insert_equals_serial(
        tris in prop::collection::vec(triangle_for(&tree(5)), 1..60)
    ) {
        let mut serial = tree(5);
        serial.insert_all(&tris);
        let mut par = tree(5);
        // Two batches: the second continues the first's sums.
        let (a, b) = tris.split_at(tris.len() / 2);
        par.par_insert(a);
        par.par_insert(b);
        prop_assert_eq!(bits(&leaves(&par)), bits(&leaves(&serial)));
        let mut ext = tree(5);
        ext.extend(tris.iter().copied());
        prop_assert_eq!(bits(&leaves(&ext)), bits(&leaves(&serial)));
    }

    #[test]
    fn merge_equals_inserting_both(
        a in prop::collection::vec(triangle_for(&tree(5)), 0..20),
        b in prop::collection::vec(triangle_for(&tree(5)), 0..20),
    ) {
        let mut ta = tree(5);
        ta.insert_all(&a);
        let mut tb = tree(5);
        tb.insert_all(&b);
        let mut both = tree(5);
        both.insert_all(&a);
        both.insert_all(&b);
        ta.merge(&tb).unwrap();
        let (m, o) = (leaves(&ta), leaves(&both));
        prop_assert_eq!(m.len(), o.len());
        for (x, y) in m.iter().zip(&o) {
            prop_assert_eq!((x.coord, x.hits), (y.coord, y.hits));
            prop_assert!((x.sdf_sum - y.sdf_sum).abs() <= 1e-5 * (1.0 + y.sdf_sum.abs()));
        }
    }

    /// A point on an inserted triangle has value 1 (points within rounding of a grid
    /// plane are skipped: there the f32 sample may leave the triangle's closed cells).
    #[test]
    fn insert_then_query(
        t in triangle_for(&tree(6)),
        u in 0.0f32..1.0, v in 0.0f32..1.0,
    ) {
        prop_assume!(t.scaled_normal().length() > 1e-9);
        let mut tr = tree(6);
        tr.insert(&t);
        let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
        let p = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * v;
        let g = tr.leaf_grid();
        let rel = (p - g.origin) / g.cell;
        let near_plane = (rel - rel.round()).abs().min_element() < 1e-3;
        prop_assume!(!near_plane);
        let inside = tr.root().contains(p);
        prop_assert_eq!(tr.value_at(p), if inside { 1.0 } else { 0.0 });
        if inside {
            let c = (rel.floor()).as_uvec3();
            prop_assert!(tr.get(c).is_some_and(|c| c.hits == 1));
        }
    }

    #[test]
    fn lod_counts(tris in prop::collection::vec(triangle_for(&tree(5)), 1..20)) {
        let mut t = tree(5);
        t.insert_all(&tris);
        let lv = leaves(&t);
        let total_hits: u32 = lv.iter().map(|c| c.hits).sum();
        let mut nodes = 0;
        let mut prev = 0;
        for d in 0..=5 {
            let cells = t.cells_at_depth(d);
            nodes += cells.len();
            // Monotone in depth, 8x at most per level.
            prop_assert!(cells.len() >= prev && cells.len() <= prev.max(1) * 8);
            prev = cells.len();
            prop_assert_eq!(cells.iter().map(|c| c.hits).sum::<u32>(), total_hits);
            // Exactly the parents of the leaves, each once, sorted.
            let mut parents: Vec<UVec3> = lv.iter().map(|c| c.coord >> (5 - d)).collect();
            parents.dedup();
            let got: Vec<UVec3> = cells.iter().map(|c| c.coord).collect();
            prop_assert_eq!(got, parents);
        }
        prop_assert_eq!(t.node_count(), nodes);
        prop_assert_eq!(t.cells_at_depth(0).len(), usize::from(!lv.is_empty()));
        prop_assert_eq!(bits(&t.cells_at_depth(9)), bits(&lv));
        // Every leaf is found by `get`.
        for c in &lv {
            prop_assert_eq!(t.get(c.coord), Some(*c));
        }
    }
}

#[cfg(feature = "parallel")]
#[test]
fn snapshot_parallel_equals_serial_and_is_compact() {
    let tris = snapshot::triangles();
    assert!(
        (20_000..40_000).contains(&tris.len()),
        "{} triangles",
        tris.len()
    );
    let mut serial = Octree::new(snapshot::root_min(), 1.0, 0.001).unwrap();
    serial.insert_all(&tris);
    let mut par = Octree::new(snapshot::root_min(), 1.0, 0.001).unwrap();
    par.par_insert(&tris);
    let s = leaves(&serial);
    assert_eq!(bits(&leaves(&par)), bits(&s));
    let bytes_per_leaf = serial.memory_bytes() as f64 / s.len() as f64;
    println!(
        "snapshot: {} triangles, {} leaves, {} nodes, {} bytes, {bytes_per_leaf:.2} bytes/leaf",
        tris.len(),
        s.len(),
        serial.node_count(),
        serial.memory_bytes()
    );
    assert!(bytes_per_leaf <= 16.0, "{bytes_per_leaf} bytes per leaf");
    // Every leaf lies within one leaf diagonal of the sphere.
    let g = serial.leaf_grid();
    for c in &s {
        let d = g.cell_center(c.coord).distance(snapshot::CENTRE) - snapshot::RADIUS;
        assert!(
            d.abs() <= g.cell * voxoct_core::HALF_CELL_DIAGONAL + 3e-4,
            "leaf {:?} at {d}",
            c.coord
        );
        // Normals face the sensor (outward from the sphere): mean sdf grows outward.
        assert!(
            (c.mean_sdf() - d).abs() <= g.cell * 0.9,
            "sdf {} vs {d}",
            c.mean_sdf()
        );
    }
}

#[test]
fn depth_rule_and_grids() {
    let a = Octree::new(Vec3::ZERO, 1.0, 0.004).unwrap();
    let b = Octree::new(Vec3::ZERO, 1.0, 0.005).unwrap();
    assert_eq!((a.depth(), b.depth()), (8, 8));
    assert_eq!(a.leaf_edge(), 1.0 / 256.0);
    let c = Octree::new(Vec3::ZERO, 1.0, 1.0 / 256.0).unwrap();
    assert_eq!(c.depth(), 8);
    let root = Octree::new(Vec3::ONE, 2.0, 2.0).unwrap();
    assert_eq!(root.depth(), 0);
    assert_eq!(root.leaf_grid().resolution, 1);
    assert_eq!(a.grid(3).resolution, 8);
    assert_eq!(a.grid(3).cell, 0.125);
    assert_eq!(a.leaf_grid(), a.grid(8));
    assert_eq!(a.root(), Aabb::new(Vec3::ZERO, Vec3::ONE));
}

#[test]
fn enclosing_fits_and_keeps_the_leaf_size() {
    let bounds = Aabb::new(Vec3::new(-0.07, 0.0, 0.62), Vec3::new(0.08, 0.15, 0.7));
    let t = Octree::enclosing(bounds, 0.001).unwrap();
    assert_eq!(t.leaf_edge(), 0.001);
    assert_eq!(t.depth(), 8);
    assert!(t.root().contains(bounds.min) && t.root().contains(bounds.max));
    let point = Octree::enclosing(Aabb::new(Vec3::ONE, Vec3::ONE), 0.01).unwrap();
    assert_eq!(point.depth(), 0);
    assert!(matches!(
        Octree::enclosing(Aabb::new(Vec3::ONE, Vec3::ZERO), 0.01),
        Err(OctreeError::InvalidBounds { axis: 'x', .. })
    ));
}

#[test]
fn errors_name_the_bad_value() {
    use OctreeError as E;
    let nan = f32::NAN;
    assert!(matches!(
        Octree::new(Vec3::new(0.0, nan, 0.0), 1.0, 0.1),
        Err(E::InvalidArgument { name: "min.y", .. })
    ));
    assert!(matches!(
        Octree::new(Vec3::ZERO, f32::INFINITY, 0.1),
        Err(E::InvalidArgument { name: "root_m", .. })
    ));
    assert!(matches!(
        Octree::new(Vec3::ZERO, 1.0, -0.1),
        Err(E::InvalidArgument { name: "leaf_m", .. })
    ));
    assert!(matches!(
        Octree::new(Vec3::ZERO, 0.0, 0.1),
        Err(E::InvalidArgument { name: "root_m", .. })
    ));
    assert!(matches!(
        Octree::new(Vec3::ZERO, 1.0, 2.0),
        Err(E::LeafLargerThanRoot { .. })
    ));
    let e = Octree::new(Vec3::ZERO, 1.0, 1e-9).unwrap_err();
    assert!(
        matches!(
            e,
            E::TooDeep {
                depth: 30,
                max: MAX_DEPTH
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("depth 30"));
    assert!(matches!(
        Octree::new(Vec3::splat(1e5), 1.0, 1e-3),
        Err(E::LeafBelowPrecision { .. })
    ));
    assert!(matches!(
        Octree::new(Vec3::splat(f32::MAX), 1e38, 1e38),
        Err(E::InvalidArgument {
            name: "min + root_m",
            ..
        })
    ));
    let mut a = Octree::new(Vec3::ZERO, 1.0, 0.1).unwrap();
    let b = Octree::new(Vec3::ZERO, 1.0, 0.01).unwrap();
    assert!(matches!(
        a.merge(&b),
        Err(E::DepthMismatch { this: 4, other: 7 })
    ));
    let c = Octree::new(Vec3::ONE, 1.0, 0.1).unwrap();
    assert!(matches!(a.merge(&c), Err(E::RootMismatch { .. })));
}

#[test]
fn exactly_degenerate_marks_nothing() {
    let mut t = tree(4);
    let c = t.root().center();
    let d = Vec3::splat(t.leaf_edge());
    for tri in [
        Triangle::new(c, c + d, c + d * 2.0),
        Triangle::new(c, c, c + d),
        Triangle::new(c, c, c),
        Triangle::new(c, c + d, Vec3::new(f32::NAN, 0.0, 0.0)),
    ] {
        assert_eq!(t.insert(&tri), 0);
        assert_eq!(t.insert_reference(&tri), 0);
    }
    assert!(t.is_empty());
}

#[test]
fn queries_outside_and_clear() {
    let mut t = tree(4);
    let root = t.root();
    let tri = Triangle::new(
        root.min - Vec3::splat(1.0),
        root.max + Vec3::splat(1.0),
        Vec3::new(root.max.x + 1.0, root.min.y - 1.0, root.center().z),
    );
    assert!(t.insert(&tri) > 0);
    assert_eq!(t.value_at(root.max + Vec3::splat(0.01)), 0.0);
    assert_eq!(t.value_at(Vec3::splat(f32::NAN)), 0.0);
    assert_eq!(t.get(UVec3::splat(16)), None);
    let full = t.memory_bytes();
    t.clear();
    assert!(t.is_empty());
    assert_eq!(t.leaf_count(), 0);
    assert_eq!(t.node_count(), 0);
    assert!(t.memory_bytes() < full);
    assert_eq!(t.leaves().count(), 0);
}

#[test]
fn value_at_on_shared_faces() {
    // A triangle lying exactly in the grid plane x = plane 2 marks the leaves on both
    // sides; a point on that face sees a marked leaf.
    let mut t = tree(3);
    let g = t.leaf_grid();
    let a = g.corner(UVec3::new(2, 1, 1));
    let b = g.corner(UVec3::new(2, 3, 1));
    let c = g.corner(UVec3::new(2, 1, 3));
    assert!(t.insert(&Triangle::new(a, b, c)) > 0);
    assert!(t.get(UVec3::new(1, 1, 1)).is_some());
    assert!(t.get(UVec3::new(2, 1, 1)).is_some());
    assert!(t.get(UVec3::new(3, 1, 1)).is_none());
    assert_eq!(t.value_at(a + (b - a) * 0.25 + (c - a) * 0.25), 1.0);
    assert_eq!(t.value_at(g.cell_center(UVec3::new(5, 5, 5))), 0.0);
}

/// A batch that expands more bricks of one region than the batch keeps expanded at once
/// (it packs them midway) gives the same tree as single insertions.
#[test]
fn large_batch_packs_midway() {
    let new = || Octree::new(Vec3::ZERO, 1.0, 1.0 / 1024.0).unwrap();
    let cell = 1.0 / 1024.0;
    // Six planes z = const inside the first region (128 leaves wide), each tiled with
    // triangles 4 leaves across: 6 × 1024 bricks.
    let mut tris = Vec::new();
    for plane in 0..6 {
        let z = (plane as f32 * 20.0 + 2.5) * cell;
        for j in 0..32 {
            for i in 0..32 {
                let (x, y) = (
                    i as f32 * 4.0 * cell + 0.3 * cell,
                    j as f32 * 4.0 * cell + 0.3 * cell,
                );
                let d = 3.4 * cell;
                let p = |dx: f32, dy: f32| Vec3::new(x + dx, y + dy, z + 0.1 * dx);
                tris.push(Triangle::new(p(0.0, 0.0), p(d, 0.0), p(0.0, d)));
                tris.push(Triangle::new(p(d, 0.0), p(d, d), p(0.0, d)));
            }
        }
    }
    let mut batched = new();
    batched.insert_all(&tris);
    // Twice: the second batch adds to every leaf of the first.
    batched.insert_all(&tris);
    let mut single = new();
    for t in tris.iter().chain(&tris) {
        single.insert(t);
    }
    let b = leaves(&batched);
    assert!(b.len() >= 6 * 1024 * 16, "{} leaves", b.len());
    assert!(b.iter().all(|c| c.hits >= 2));
    assert_eq!(bits(&b), bits(&leaves(&single)));
}
