//! The exact self-intersection test against an independent brute-force reference: exact
//! rational arithmetic that computes the intersection of every pair of triangles and compares
//! it with the hull of their shared vertices, on small random meshes with integer
//! coordinates (so touching, shared-vertex, shared-edge, collinear and coplanar cases are
//! common); and the grid search against the all-pairs predicate on larger meshes.

use proptest::prelude::*;
use voxoct_mesh::glam::{UVec3, Vec3};
use voxoct_mesh::{
    Cell, GridSpec, Mesh, MeshOptions, Placement, Taubin, TopologyError, mesh_cells,
    mesh_cells_certified, self_intersecting_triangles, triangles_intersect,
};

/// An exact rational, `n / d` with `d > 0`, reduced; arithmetic panics on overflow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Q {
    n: i128,
    d: i128,
}

fn gcd(mut a: i128, mut b: i128) -> i128 {
    a = a.abs();
    b = b.abs();
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

impl Q {
    fn int(n: i64) -> Self {
        Self {
            n: i128::from(n),
            d: 1,
        }
    }
    fn new(n: i128, d: i128) -> Self {
        assert!(d != 0);
        let g = gcd(n, d).max(1);
        let s = if d < 0 { -1 } else { 1 };
        Self {
            n: s * n / g,
            d: s * d / g,
        }
    }
    fn add(self, o: Self) -> Self {
        Self::new(
            (self.n.checked_mul(o.d).unwrap())
                .checked_add(o.n.checked_mul(self.d).unwrap())
                .unwrap(),
            self.d.checked_mul(o.d).unwrap(),
        )
    }
    fn neg(self) -> Self {
        Self {
            n: -self.n,
            d: self.d,
        }
    }
    fn sub(self, o: Self) -> Self {
        self.add(o.neg())
    }
    fn mul(self, o: Self) -> Self {
        let g1 = gcd(self.n, o.d).max(1);
        let g2 = gcd(o.n, self.d).max(1);
        Self::new(
            (self.n / g1).checked_mul(o.n / g2).unwrap(),
            (self.d / g2).checked_mul(o.d / g1).unwrap(),
        )
    }
    fn div(self, o: Self) -> Self {
        assert!(o.n != 0);
        self.mul(Self { n: o.d, d: o.n }.norm())
    }
    fn norm(self) -> Self {
        Self::new(self.n, self.d)
    }
    fn sign(self) -> i32 {
        self.n.signum() as i32
    }
}

type V = [Q; 3];

fn sub(a: &V, b: &V) -> V {
    [a[0].sub(b[0]), a[1].sub(b[1]), a[2].sub(b[2])]
}
fn add(a: &V, b: &V) -> V {
    [a[0].add(b[0]), a[1].add(b[1]), a[2].add(b[2])]
}
fn scale(a: &V, s: Q) -> V {
    [a[0].mul(s), a[1].mul(s), a[2].mul(s)]
}
fn dot(a: &V, b: &V) -> Q {
    a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
}
fn cross(a: &V, b: &V) -> V {
    [
        a[1].mul(b[2]).sub(a[2].mul(b[1])),
        a[2].mul(b[0]).sub(a[0].mul(b[2])),
        a[0].mul(b[1]).sub(a[1].mul(b[0])),
    ]
}
fn is_zero(a: &V) -> bool {
    a.iter().all(|q| q.n == 0)
}

/// Clips the convex point list `poly` (cyclic order; collinear lists allowed) by
/// `g(x) >= 0`, `g` affine.
fn clip(poly: &[V], g: impl Fn(&V) -> Q) -> Vec<V> {
    let mut out = Vec::new();
    let n = poly.len();
    for i in 0..n {
        let (p, q) = (&poly[i], &poly[(i + 1) % n]);
        let (gp, gq) = (g(p), g(q));
        if gp.sign() >= 0 {
            out.push(*p);
        }
        if gp.sign() * gq.sign() < 0 {
            let t = gp.div(gp.sub(gq));
            out.push(add(p, &scale(&sub(q, p), t)));
        }
    }
    out
}

/// The corners of `T1 ∩ T2` (closed triangles, not degenerate), exactly.
fn intersection(t1: &[V; 3], t2: &[V; 3]) -> Vec<V> {
    let n2 = cross(&sub(&t2[1], &t2[0]), &sub(&t2[2], &t2[0]));
    let f: Vec<Q> = t1.iter().map(|p| dot(&n2, &sub(p, &t2[0]))).collect();
    let mut poly: Vec<V> = Vec::new();
    if f.iter().all(|q| q.n == 0) {
        poly.extend_from_slice(t1);
    } else {
        for i in 0..3 {
            let j = (i + 1) % 3;
            if f[i].n == 0 {
                poly.push(t1[i]);
            }
            if f[i].sign() * f[j].sign() < 0 {
                let t = f[i].div(f[i].sub(f[j]));
                poly.push(add(&t1[i], &scale(&sub(&t1[j], &t1[i]), t)));
            }
        }
    }
    for e in 0..3 {
        let (s, end) = (t2[e], t2[(e + 1) % 3]);
        let m = cross(&n2, &sub(&end, &s));
        poly = clip(&poly, |x| dot(&m, &sub(x, &s)));
        if poly.is_empty() {
            break;
        }
    }
    poly
}

/// The reference: whether triangles `i`, `j` of the integer mesh intersect improperly.
fn reference(verts: &[[i64; 3]], tris: &[[u32; 3]], i: usize, j: usize) -> bool {
    let q = |k: u32| verts[k as usize].map(Q::int);
    let tq = |t: [u32; 3]| t.map(q);
    let degenerate = |t: [u32; 3]| {
        t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || {
            let p = tq(t);
            is_zero(&cross(&sub(&p[1], &p[0]), &sub(&p[2], &p[0])))
        }
    };
    if i == j {
        return degenerate(tris[i]);
    }
    if degenerate(tris[i]) || degenerate(tris[j]) {
        return false;
    }
    let shared: Vec<u32> = tris[i]
        .iter()
        .filter(|k| tris[j].contains(k))
        .copied()
        .collect();
    let corners = intersection(&tq(tris[i]), &tq(tris[j]));
    match shared.len() {
        0 => !corners.is_empty(),
        1 => {
            let v = q(shared[0]);
            corners.iter().any(|c| *c != v)
        }
        2 => {
            let (u, v) = (q(shared[0]), q(shared[1]));
            let uv = sub(&v, &u);
            corners.iter().any(|c| {
                let uc = sub(c, &u);
                let t = dot(&uc, &uv);
                !(is_zero(&cross(&uc, &uv)) && t.sign() >= 0 && t.sub(dot(&uv, &uv)).sign() <= 0)
            })
        }
        _ => true,
    }
}

fn to_mesh(verts: &[[i64; 3]], tris: &[[u32; 3]], s: f32, o: Vec3) -> Mesh {
    Mesh {
        vertices: verts
            .iter()
            .map(|v| o + Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) * s)
            .collect(),
        triangles: tris.to_vec(),
    }
}

/// All-pairs flags from a pair predicate.
fn all_pairs(n: usize, f: impl Fn(usize, usize) -> bool) -> Vec<u32> {
    (0..n)
        .filter(|&i| (0..n).any(|j| f(i, j)))
        .map(|i| i as u32)
        .collect()
}

fn small_mesh(max_coord: i64) -> impl Strategy<Value = (Vec<[i64; 3]>, Vec<[u32; 3]>)> {
    (3usize..10).prop_flat_map(move |nv| {
        (
            prop::collection::vec(prop::array::uniform3(0..=max_coord), nv),
            prop::collection::vec(prop::array::uniform3(0..nv as u32), 1..14),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    /// Every pair against the rational reference, on a coarse integer lattice (many
    /// coplanar, collinear, touching and shared cases), at several scales and offsets (the
    /// positions stay exact in `f32`).
    #[test]
    fn pairs_match_the_rational_reference((verts, tris) in small_mesh(3), scale_pow in -3i32..4) {
        let s = 2f32.powi(scale_pow);
        let mesh = to_mesh(&verts, &tris, s, Vec3::new(-1.0, 2.0, 0.5));
        for i in 0..tris.len() {
            for j in 0..tris.len() {
                let want = reference(&verts, &tris, i, j);
                prop_assert_eq!(triangles_intersect(&mesh, i, j), want, "pair {} {} of {:?} {:?}", i, j, verts, tris);
            }
        }
        let want = all_pairs(tris.len(), |i, j| reference(&verts, &tris, i, j));
        prop_assert_eq!(self_intersecting_triangles(&mesh), want);
    }

    /// Fans around one vertex and strips along one edge: the shared-vertex and shared-edge
    /// rules in every configuration the lattice allows.
    #[test]
    fn fans_and_folds_match_the_rational_reference(
        verts in prop::collection::vec(prop::array::uniform3(-2i64..=2), 7),
        order in Just(()).prop_perturb(|_, mut rng| {
            let mut v: Vec<u32> = (1..7).collect();
            for i in (1..v.len()).rev() {
                v.swap(i, (rng.next_u32() as usize) % (i + 1));
            }
            v
        }),
    ) {
        let mut tris: Vec<[u32; 3]> = (0..6).map(|k| [0, order[k], order[(k + 1) % 6]]).collect();
        tris.push([order[0], order[1], order[3]]);
        let mesh = to_mesh(&verts, &tris, 0.25, Vec3::ZERO);
        let want = all_pairs(tris.len(), |i, j| reference(&verts, &tris, i, j));
        prop_assert_eq!(self_intersecting_triangles(&mesh), want);
    }

    /// The grid search finds exactly what all pairs find, on triangle soups with shared
    /// vertices at arbitrary float positions and sizes.
    #[test]
    fn grid_search_matches_all_pairs(
        verts in prop::collection::vec(prop::array::uniform3(-1.0f32..1.0), 4..60),
        picks in prop::collection::vec((0usize..1000, 0usize..1000, 0usize..1000, 0.0f32..1.0), 1..120),
    ) {
        let n = verts.len();
        let mesh = Mesh {
            vertices: verts.iter().map(|v| Vec3::from_array(*v)).collect(),
            triangles: picks
                .iter()
                .map(|&(a, b, c, local)| {
                    // Mostly local triangles: near neighbours in index order.
                    if local < 0.8 {
                        let a = a % n;
                        [a, (a + 1 + b % 3) % n, (a + 2 + c % 4) % n].map(|x| x as u32)
                    } else {
                        [a % n, b % n, c % n].map(|x| x as u32)
                    }
                })
                .collect(),
        };
        let want = all_pairs(mesh.triangles.len(), |i, j| triangles_intersect(&mesh, i, j));
        prop_assert_eq!(self_intersecting_triangles(&mesh), want);
    }

    /// The grid search finds exactly what all pairs find when one grid cell holds more
    /// than one block of 64 entries (a dense cluster of small triangles, made to share one
    /// cell by a few large ones that set the cell size), whatever the boxes' positions in
    /// the pair loop's lanes.
    #[test]
    fn grid_search_matches_all_pairs_in_crowded_cells(
        verts in prop::collection::vec(prop::array::uniform3(-1.0f32..1.0), 12..80),
        picks in prop::collection::vec((0usize..1000, 0usize..1000, 0usize..1000), 70..200),
        big in 1usize..4,
    ) {
        let n = verts.len();
        // Small vertices in a 2 cm cube, three far corners for the large triangles.
        let mut vertices: Vec<Vec3> = verts.iter().map(|v| Vec3::from_array(*v) * 0.01).collect();
        vertices.extend([Vec3::new(-5.0, -5.0, 5.0), Vec3::new(5.0, -5.0, 5.0), Vec3::new(0.0, 5.0, 5.0)]);
        let mut triangles: Vec<[u32; 3]> = picks
            .iter()
            .map(|&(a, b, c)| {
                let a = a % n;
                [a, (a + 1 + b % 5) % n, (a + 2 + c % 7) % n].map(|x| x as u32)
            })
            .collect();
        for _ in 0..big {
            triangles.push([n as u32, n as u32 + 1, n as u32 + 2]);
        }
        let mesh = Mesh { vertices, triangles };
        let want = all_pairs(mesh.triangles.len(), |i, j| triangles_intersect(&mesh, i, j));
        prop_assert_eq!(self_intersecting_triangles(&mesh), want);
    }
}

#[test]
fn hand_made_cases() {
    let v = |x: i64, y: i64, z: i64| [x, y, z];
    // (vertices, triangles, flagged triangles)
    type Case = (Vec<[i64; 3]>, Vec<[u32; 3]>, Vec<u32>);
    let cases: Vec<Case> = vec![
        // Two triangles touching at a corner that is not a shared index: intersecting.
        (
            vec![
                v(0, 0, 0),
                v(2, 0, 0),
                v(0, 2, 0),
                v(0, 0, 0),
                v(-2, 0, 1),
                v(0, -2, 1),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
            vec![0, 1],
        ),
        // The same sharing the vertex index: proper.
        (
            vec![v(0, 0, 0), v(2, 0, 0), v(0, 2, 0), v(-2, 0, 1), v(0, -2, 1)],
            vec![[0, 1, 2], [0, 3, 4]],
            vec![],
        ),
        // Shared vertex, coplanar, overlapping wedges: improper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(0, 4, 0), v(4, 1, 0), v(1, 4, 0)],
            vec![[0, 1, 2], [0, 3, 4]],
            vec![0, 1],
        ),
        // Shared vertex, coplanar, wedges touching along a ray: improper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(4, 4, 0), v(2, 2, 0), v(0, 4, 0)],
            vec![[0, 1, 2], [0, 3, 4]],
            vec![0, 1],
        ),
        // Shared vertex, the opposite edge pierces the other triangle: improper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(0, 4, 0), v(1, 1, -1), v(1, 1, 1)],
            vec![[0, 1, 2], [0, 3, 4]],
            vec![0, 1],
        ),
        // Shared edge, folded flat onto each other: improper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(1, 3, 0), v(3, 2, 0)],
            vec![[0, 1, 2], [1, 0, 3]],
            vec![0, 1],
        ),
        // Shared edge, coplanar, opposite sides: proper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(1, 3, 0), v(3, -2, 0)],
            vec![[0, 1, 2], [1, 0, 3]],
            vec![],
        ),
        // Shared edge, bent: proper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(1, 3, 0), v(3, 1, 1)],
            vec![[0, 1, 2], [1, 0, 3]],
            vec![],
        ),
        // A repeated triangle (opposite orientation): improper.
        (
            vec![v(0, 0, 0), v(4, 0, 0), v(1, 3, 0)],
            vec![[0, 1, 2], [1, 0, 2]],
            vec![0, 1],
        ),
        // Collinear and repeated-index triangles: flagged themselves only.
        (
            vec![
                v(0, 0, 0),
                v(1, 1, 1),
                v(2, 2, 2),
                v(5, 5, 0),
                v(6, 5, 0),
                v(5, 6, 0),
            ],
            vec![[0, 1, 2], [3, 4, 5], [3, 3, 4]],
            vec![0, 2],
        ),
        // Disjoint parallel triangles, and an edge grazing a face from outside: none.
        (
            vec![
                v(0, 0, 0),
                v(4, 0, 0),
                v(0, 4, 0),
                v(0, 0, 1),
                v(4, 0, 1),
                v(0, 4, 1),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
            vec![],
        ),
        // An edge lying in the other's plane, crossing it: improper.
        (
            vec![
                v(0, 0, 0),
                v(4, 0, 0),
                v(0, 4, 0),
                v(-1, 1, 0),
                v(3, 1, 0),
                v(1, 1, 3),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
            vec![0, 1],
        ),
    ];
    for (k, (verts, tris, want)) in cases.iter().enumerate() {
        let mesh = to_mesh(verts, tris, 1.0, Vec3::ZERO);
        let ref_flags = all_pairs(tris.len(), |i, j| reference(verts, tris, i, j));
        assert_eq!(&ref_flags, want, "reference, case {k}");
        assert_eq!(&self_intersecting_triangles(&mesh), want, "case {k}");
    }
    // Out-of-range index and a non-finite vertex are flagged.
    let mut m = to_mesh(&cases[1].0, &cases[1].1, 1.0, Vec3::ZERO);
    m.triangles.push([0, 1, 99]);
    assert_eq!(self_intersecting_triangles(&m), vec![2]);
    m.triangles.pop();
    m.vertices[4] = Vec3::NAN;
    assert_eq!(self_intersecting_triangles(&m), vec![1]);
    assert!(self_intersecting_triangles(&Mesh::default()).is_empty());
}

fn cell(x: u32, y: u32, z: u32, sdf: f32) -> Cell {
    Cell {
        coord: UVec3::new(x, y, z),
        hits: 1,
        sdf_sum: sdf * 0.001,
    }
}

fn grid() -> GridSpec {
    GridSpec {
        origin: Vec3::new(-0.3, 0.1, 2.0),
        cell: 0.001,
        resolution: 16,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// On meshes from the mesher, smoothed hard (to make intersections) or not, the grid
    /// search agrees with all pairs, and `check_valid_solid` reports the count.
    #[test]
    fn mesher_output_grid_matches_all_pairs(
        cells in prop::collection::vec((0u32..12, 0u32..12, 0u32..12, -0.9f32..0.9), 1..80),
        iterations in 0u32..40,
    ) {
        let cells: Vec<Cell> = cells.iter().map(|&(x, y, z, s)| cell(x, y, z, s)).collect();
        let opts = MeshOptions { placement: Placement::SignedDistance, ..MeshOptions::thesis() };
        let mut mesh = mesh_cells(&cells, &grid(), &opts).unwrap();
        // Raw Laplacian steps, without the mesher's safeguards.
        let t = Taubin { iterations, lambda: 0.9, mu: -0.95 };
        for _ in 0..t.iterations {
            let mut sum = vec![Vec3::ZERO; mesh.vertices.len()];
            let mut cnt = vec![0f32; mesh.vertices.len()];
            for tri in &mesh.triangles {
                for k in 0..3 {
                    sum[tri[k] as usize] += mesh.vertices[tri[(k + 1) % 3] as usize];
                    cnt[tri[k] as usize] += 1.0;
                }
            }
            for (i, p) in mesh.vertices.iter_mut().enumerate() {
                *p += t.lambda * (sum[i] / cnt[i] - *p);
            }
        }
        let want = all_pairs(mesh.triangles.len(), |i, j| triangles_intersect(&mesh, i, j));
        let got = self_intersecting_triangles(&mesh);
        prop_assert_eq!(&got, &want);
        match mesh.check_valid_solid() {
            Err(TopologyError::SelfIntersecting { triangles, .. }) => prop_assert_eq!(triangles, got.len()),
            Ok(()) => prop_assert!(got.is_empty()),
            Err(_) => {}
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Closed fans that wind once or twice around their vertex, on a lattice with noise:
    /// the fan certificate must never skip a pair that the reference finds.
    #[test]
    fn winding_fans_match_the_rational_reference(
        m in 3usize..10,
        turns in 1u32..3,
        radius in 2i64..6,
        noise in prop::collection::vec((-1i64..=1, -1i64..=1, -1i64..=1), 10),
    ) {
        let mut verts = vec![[0, 0, 0]];
        for (i, &(dx, dy, dz)) in noise.iter().enumerate().take(m) {
            let a = std::f64::consts::TAU * f64::from(turns) * i as f64 / m as f64;
            let r = radius as f64;
            verts.push([(r * a.cos()).round() as i64 + dx, (r * a.sin()).round() as i64 + dy, dz]);
        }
        let tris: Vec<[u32; 3]> =
            (0..m).map(|i| [0, 1 + i as u32, 1 + ((i + 1) % m) as u32]).collect();
        let mesh = to_mesh(&verts, &tris, 0.5, Vec3::new(0.25, -1.0, 3.0));
        let want = all_pairs(tris.len(), |i, j| reference(&verts, &tris, i, j));
        prop_assert_eq!(self_intersecting_triangles(&mesh), want);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// A mesh that `mesh_cells_certified` calls free of self-intersections is: the exact
    /// search over every pair agrees, on random cell sets with noisy signed distances, solid
    /// or not, with the default smoothing and with much stronger smoothing.
    #[test]
    fn a_certified_mesh_has_no_self_intersections(
        cells in prop::collection::vec((0u32..12, 0u32..12, 0u32..12, -0.9f32..0.9), 1..120),
        solid in any::<bool>(),
        iterations in prop::sample::select(vec![10u32, 40, 100]),
    ) {
        let cells: Vec<Cell> = cells.iter().map(|&(x, y, z, s)| cell(x, y, z, s)).collect();
        let mut opts = MeshOptions::smooth();
        opts.solid = solid;
        if let Some(t) = &mut opts.smoothing {
            t.iterations = iterations;
        }
        let (mesh, certified) = mesh_cells_certified(&cells, &grid(), &opts).unwrap();
        if certified {
            prop_assert!(mesh.self_intersecting_triangles().is_empty());
        }
        prop_assert_eq!(&mesh, &mesh_cells(&cells, &grid(), &opts).unwrap());
    }
}
