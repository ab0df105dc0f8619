//! Pairs of intersecting triangles of a mesh (used by the simplifier to prove that it
//! introduced none): a uniform grid finds the pairs whose boxes overlap, and an
//! orientation-based triangle–triangle test in `f64` decides each pair.
//!
//! Triangles that share an edge intersect only when they fold onto each other (coplanar,
//! on the same side of the edge); triangles that share one vertex intersect when they meet
//! anywhere else (one's opposite edge meets the other). Touching counts as intersecting.

use voxoct_core::glam::{DVec2, DVec3, Vec3};

use crate::mesh::Mesh;
use crate::par;

/// Largest number of grid cells along one axis (keys hold 21 bits per axis).
const MAX_CELLS_PER_AXIS: f32 = ((1u32 << 21) - 2) as f32;

/// Grid cell edge relative to the mean largest extent of a triangle's box.
const CELL_PER_EXTENT: f32 = 1.0;

/// Every pair `(a, b)`, `a < b`, of triangles of `mesh` that intersect, sorted.
pub(crate) fn intersecting_pairs(mesh: &Mesh) -> Vec<(u32, u32)> {
    let tris = &mesh.triangles;
    if tris.len() < 2 {
        return Vec::new();
    }
    let v = &mesh.vertices;
    let boxes: Vec<(Vec3, Vec3)> = {
        let mut b = Vec::new();
        par::map_into(&mut b, tris.len(), |i| {
            let [p, q, r] = tris[i].map(|k| v[k as usize]);
            (p.min(q).min(r), p.max(q).max(r))
        });
        b
    };
    let (lo, hi) = boxes.iter().fold((boxes[0].0, boxes[0].1), |(lo, hi), b| {
        (lo.min(b.0), hi.max(b.1))
    });
    let mean_extent = boxes
        .iter()
        .map(|b| f64::from((b.1 - b.0).max_element()))
        .sum::<f64>()
        / boxes.len() as f64;
    let span = (hi - lo).max_element();
    let cell = (CELL_PER_EXTENT * mean_extent as f32)
        .max(span / MAX_CELLS_PER_AXIS)
        .max(f32::MIN_POSITIVE);
    if !cell.is_finite() || !span.is_finite() {
        return Vec::new();
    }
    let coord = |p: Vec3| {
        ((p - lo) / cell)
            .floor()
            .as_uvec3()
            .min(voxoct_core::glam::UVec3::splat((1 << 21) - 1))
    };
    let key = |c: voxoct_core::glam::UVec3| {
        (u64::from(c.x) << 42) | (u64::from(c.y) << 21) | u64::from(c.z)
    };
    let mut entries: Vec<(u64, u32)> = Vec::with_capacity(2 * tris.len());
    for (i, b) in boxes.iter().enumerate() {
        let (c0, c1) = (coord(b.0), coord(b.1));
        for x in c0.x..=c1.x {
            for y in c0.y..=c1.y {
                for z in c0.z..=c1.z {
                    entries.push((key(voxoct_core::glam::UVec3::new(x, y, z)), i as u32));
                }
            }
        }
    }
    par::sort(&mut entries);
    let mut runs = Vec::new();
    let mut s = 0;
    for i in 1..=entries.len() {
        if i == entries.len() || entries[i].0 != entries[s].0 {
            if i - s > 1 {
                runs.push((s, i));
            }
            s = i;
        }
    }
    let mut pairs = Vec::new();
    par::extend_in_order(&mut pairs, runs.len(), 64, |r, out| {
        let (s, e) = runs[r];
        let here = entries[s].0;
        for i in s..e {
            let a = entries[i].1;
            let ba = boxes[a as usize];
            for &(_, b) in &entries[i + 1..e] {
                let bb = boxes[b as usize];
                if ba.0.cmpgt(bb.1).any() || bb.0.cmpgt(ba.1).any() {
                    continue;
                }
                // Test each pair once: in the cell of the overlap's minimum corner.
                if key(coord(ba.0.max(bb.0))) != here {
                    continue;
                }
                if triangles_intersect(mesh, a, b) {
                    out.push((a.min(b), a.max(b)));
                }
            }
        }
    });
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Whether triangles `a` and `b` of `mesh` intersect (see the module docs).
pub(crate) fn triangles_intersect(mesh: &Mesh, a: u32, b: u32) -> bool {
    let ta = mesh.triangles[a as usize];
    let tb = mesh.triangles[b as usize];
    let p = |k: u32| mesh.vertices[k as usize].as_dvec3();
    let mut shared = [(0usize, 0usize); 3];
    let mut n = 0;
    for (i, a) in ta.iter().enumerate() {
        for (j, b) in tb.iter().enumerate() {
            if a == b {
                shared[n.min(2)] = (i, j);
                n += 1;
            }
        }
    }
    match n {
        0 => tri_tri(ta.map(p), tb.map(p)),
        1 => {
            let (i, j) = shared[0];
            let pa = ta.map(p);
            let pb = tb.map(p);
            segment_triangle(pa[(i + 1) % 3], pa[(i + 2) % 3], pb)
                || segment_triangle(pb[(j + 1) % 3], pb[(j + 2) % 3], pa)
        }
        2 => {
            // Shared edge u w; opposite vertices x (of a) and y (of b).
            let x = (0..3).find(|&i| !tb.contains(&ta[i])).unwrap_or(0);
            let y = (0..3).find(|&j| !ta.contains(&tb[j])).unwrap_or(0);
            let (u, w) = (p(ta[(x + 1) % 3]), p(ta[(x + 2) % 3]));
            let (x, y) = (p(ta[x]), p(tb[y]));
            let e = w - u;
            let (nx, ny) = (e.cross(x - u), e.cross(y - u));
            let vol = e.dot((x - u).cross(y - u)).abs();
            let scale = e.length() * (x - u).length() * (y - u).length();
            vol <= 1e-12 * scale && nx.dot(ny) > 0.0
        }
        _ => true,
    }
}

/// `(b − a) · ((c − a) × (d − a))`: positive when `d` is on the side of `a b c`'s normal.
#[inline]
fn orient(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    (b - a).cross(c - a).dot(d - a)
}

/// Triangle–triangle intersection (no shared vertices), touching included.
pub(crate) fn tri_tri(p: [DVec3; 3], q: [DVec3; 3]) -> bool {
    let dq = q.map(|x| orient(p[0], p[1], p[2], x));
    if same_strict_sign(dq) {
        return false;
    }
    let dp = p.map(|x| orient(q[0], q[1], q[2], x));
    if same_strict_sign(dp) {
        return false;
    }
    let np = (p[1] - p[0]).cross(p[2] - p[0]);
    if dq.iter().all(|&d| d == 0.0) {
        return coplanar_tri_tri(p, q, np);
    }
    let nq = (q[1] - q[0]).cross(q[2] - q[0]);
    let dir = np.cross(nq);
    match (interval(p, dp, dir), interval(q, dq, dir)) {
        (Some(a), Some(b)) => a.1 >= b.0 && b.1 >= a.0,
        _ => false,
    }
}

fn same_strict_sign(d: [f64; 3]) -> bool {
    (d[0] > 0.0 && d[1] > 0.0 && d[2] > 0.0) || (d[0] < 0.0 && d[1] < 0.0 && d[2] < 0.0)
}

/// The projection onto `dir` of the part of triangle `t` on the other triangle's plane
/// (`d`: the vertices' signed plane values).
fn interval(t: [DVec3; 3], d: [f64; 3], dir: DVec3) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut add = |x: DVec3| {
        let s = x.dot(dir);
        lo = lo.min(s);
        hi = hi.max(s);
    };
    for i in 0..3 {
        let j = (i + 1) % 3;
        if d[i] == 0.0 {
            add(t[i]);
        }
        if (d[i] < 0.0 && d[j] > 0.0) || (d[i] > 0.0 && d[j] < 0.0) {
            add(t[i] + (t[j] - t[i]) * (d[i] / (d[i] - d[j])));
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Segment `a b` against triangle `t`, touching included.
pub(crate) fn segment_triangle(a: DVec3, b: DVec3, t: [DVec3; 3]) -> bool {
    let sa = orient(t[0], t[1], t[2], a);
    let sb = orient(t[0], t[1], t[2], b);
    if (sa > 0.0 && sb > 0.0) || (sa < 0.0 && sb < 0.0) {
        return false;
    }
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if sa == 0.0 && sb == 0.0 {
        let (to2, tt) = project(n, t);
        let (a2, b2) = (to2(a), to2(b));
        return point_in_triangle_2d(a2, tt)
            || point_in_triangle_2d(b2, tt)
            || (0..3).any(|i| segments_2d(a2, b2, tt[i], tt[(i + 1) % 3]));
    }
    let x = a + (b - a) * (sa / (sa - sb));
    (0..3).all(|i| (t[(i + 1) % 3] - t[i]).cross(x - t[i]).dot(n) >= 0.0)
}

/// Coplanar triangles (normal `n`), touching included.
fn coplanar_tri_tri(p: [DVec3; 3], q: [DVec3; 3], n: DVec3) -> bool {
    let (to2, pp) = project(n, p);
    let qq = q.map(to2);
    (0..3).any(|i| (0..3).any(|j| segments_2d(pp[i], pp[(i + 1) % 3], qq[j], qq[(j + 1) % 3])))
        || point_in_triangle_2d(pp[0], qq)
        || point_in_triangle_2d(qq[0], pp)
}

/// Drops the axis along which `n` is largest; returns the projection and `t` projected.
fn project(n: DVec3, t: [DVec3; 3]) -> (impl Fn(DVec3) -> DVec2, [DVec2; 3]) {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let f = move |x: DVec3| match axis {
        0 => DVec2::new(x.y, x.z),
        1 => DVec2::new(x.z, x.x),
        _ => DVec2::new(x.x, x.y),
    };
    let tt = t.map(f);
    (f, tt)
}

fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

fn point_in_triangle_2d(x: DVec2, t: [DVec2; 3]) -> bool {
    let s = [0, 1, 2].map(|i| cross2(t[(i + 1) % 3] - t[i], x - t[i]));
    s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
}

fn segments_2d(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let d1 = cross2(b - a, c - a);
    let d2 = cross2(b - a, d - a);
    let d3 = cross2(d - c, a - c);
    let d4 = cross2(d - c, b - c);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, d: f64| {
        d == 0.0
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(a, b, c, d1) || on(a, b, d, d2) || on(c, d, a, d3) || on(c, d, b, d4)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(v: &[[f32; 3]], t: &[[u32; 3]]) -> Mesh {
        Mesh {
            vertices: v.iter().map(|&p| Vec3::from(p)).collect(),
            triangles: t.to_vec(),
        }
    }

    #[test]
    fn crossing_and_separate_triangles() {
        let m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.2, 0.2, -0.5],
                [0.2, 0.2, 0.5],
                [0.9, 0.9, 0.5],
                [0.2, 0.2, 0.1],
                [0.9, 0.2, 0.1],
                [0.2, 0.9, 0.1],
            ],
            &[[0, 1, 2], [3, 4, 5], [6, 7, 8]],
        );
        assert!(triangles_intersect(&m, 0, 1));
        assert!(!triangles_intersect(&m, 0, 2));
        assert!(triangles_intersect(&m, 1, 2));
        assert_eq!(intersecting_pairs(&m), vec![(0, 1), (1, 2)]);
    }

    #[test]
    fn shared_vertex_and_edge() {
        // Two triangles sharing vertex 0: apart, then one folded through the other.
        let m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
                [1.0, 1.0, -0.5],
                [1.0, 1.0, 0.5],
            ],
            &[[0, 1, 2], [0, 3, 4], [0, 5, 6], [1, 2, 3]],
        );
        assert!(!triangles_intersect(&m, 0, 1));
        assert!(triangles_intersect(&m, 0, 2));
        // Shared edge 1-2, not coplanar-folded.
        let m2 = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.3],
            ],
            &[[0, 1, 2], [2, 1, 3]],
        );
        assert!(!triangles_intersect(&m2, 0, 1));
        // Folded flat onto each other.
        let m3 = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.2, 0.2, 0.0],
            ],
            &[[0, 1, 2], [2, 1, 3]],
        );
        assert!(triangles_intersect(&m3, 0, 1));
    }
}
