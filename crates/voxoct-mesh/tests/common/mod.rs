//! Analytic test shapes, finely triangulated and oriented outward.

#![allow(dead_code)]

use voxoct_core::Triangle;
use voxoct_core::glam::Vec3;

/// An icosphere of radius `r` about `c`, subdivided `level` times, outward wound.
pub fn icosphere(c: Vec3, r: f32, level: u32) -> Vec<Triangle> {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from_array(*p).normalize())
    .collect();
    let f: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut tris: Vec<[Vec3; 3]> = f.iter().map(|t| t.map(|i| v[i])).collect();
    for _ in 0..level {
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let (ab, bc, ca) = (
                (a + b).normalize(),
                (b + c).normalize(),
                (c + a).normalize(),
            );
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    tris.into_iter()
        .map(|t| {
            let [a, b, cc] = t.map(|p| c + p * r);
            let tri = Triangle::new(a, b, cc);
            // Outward: the normal agrees with the direction from the centre.
            if tri.scaled_normal().dot(a - c) > 0.0 {
                tri
            } else {
                Triangle::new(a, cc, b)
            }
        })
        .collect()
}

/// Distance from `p` to the sphere.
pub fn sphere_distance(p: Vec3, c: Vec3, r: f32) -> f32 {
    ((p - c).length() - r).abs()
}

/// A torus about `c`, axis +Y, radii `big` and `small`, `nu × nv` quads, outward wound.
pub fn torus(c: Vec3, big: f32, small: f32, nu: u32, nv: u32) -> Vec<Triangle> {
    let p = |i: u32, j: u32| {
        let u = std::f32::consts::TAU * (i % nu) as f32 / nu as f32;
        let v = std::f32::consts::TAU * (j % nv) as f32 / nv as f32;
        let ring = big + small * v.cos();
        c + Vec3::new(ring * u.cos(), small * v.sin(), ring * u.sin())
    };
    let mut out = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, cc, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            for tri in [Triangle::new(a, b, cc), Triangle::new(a, cc, d)] {
                let centroid = (tri.v[0] + tri.v[1] + tri.v[2]) / 3.0 - c;
                let radial = Vec3::new(centroid.x, 0.0, centroid.z).normalize() * big;
                let outward = centroid - radial;
                out.push(if tri.scaled_normal().dot(outward) > 0.0 {
                    tri
                } else {
                    Triangle::new(tri.v[0], tri.v[2], tri.v[1])
                });
            }
        }
    }
    out
}

/// Distance from `p` to the torus.
pub fn torus_distance(p: Vec3, c: Vec3, big: f32, small: f32) -> f32 {
    let q = p - c;
    let ring = Vec3::new(q.x, 0.0, q.z).length() - big;
    (Vec3::new(ring, q.y, 0.0).length() - small).abs()
}
