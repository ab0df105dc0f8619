//! The exact self-intersection test of a later round, made only where its result differs
//! from the round before.
//!
//! A later round's result equals the earlier one's except around the newly frozen
//! vertices (every phase is deterministic and local). A triangle that the earlier result
//! also had — the same corners, at the same positions — can intersect another such
//! triangle only if the earlier test found both; so every intersecting pair of the new
//! result has a *suspect*: a triangle the earlier result did not have, or one the earlier
//! test found. The other triangle of the pair meets the suspect's bounding box. The test
//! therefore runs on the triangles whose boxes meet a cell of a grid that a suspect's box
//! meets (with the vertex numbering kept, so shared vertices stay shared and every pair is
//! decided exactly as in the whole mesh), and finds every intersecting triangle.

use voxoct_core::glam::Vec3;

use crate::mesh::Mesh;

/// Cells per axis of the grid of suspects, at most.
const MAX_DIM: f32 = 256.0;

/// What [`intersecting_since`] needs of a round's result: its triangles, the positions of
/// the vertices they use (not of the others: a fraction of the input's), and every
/// self-intersecting triangle.
pub(super) struct Previous {
    nv: usize,
    triangles: Vec<[u32; 3]>,
    /// The vertices the triangles use, increasing, and their positions.
    used: Vec<u32>,
    at: Vec<Vec3>,
    bad: Vec<u32>,
}

impl Previous {
    /// The round's result `mesh` and every self-intersecting triangle of it.
    pub(super) fn new(mesh: Mesh, bad: Vec<u32>) -> Self {
        let nv = mesh.vertices.len();
        let mut is_used = vec![false; nv];
        for t in &mesh.triangles {
            for &k in t {
                is_used[k as usize] = true;
            }
        }
        let used: Vec<u32> = (0..nv as u32).filter(|&k| is_used[k as usize]).collect();
        let at = used.iter().map(|&k| mesh.vertices[k as usize]).collect();
        Self {
            nv,
            triangles: mesh.triangles,
            used,
            at,
            bad,
        }
    }

    /// The position of vertex `k` if a triangle uses it.
    fn position(&self, k: u32) -> Option<Vec3> {
        self.used.binary_search(&k).ok().map(|i| self.at[i])
    }
}

/// Every self-intersecting triangle of `mesh` (increasing), given the result of the round
/// before (the same vertex numbering).
pub(super) fn intersecting_since(mesh: &Mesh, prev: &Previous) -> Vec<u32> {
    let nv = mesh.vertices.len();
    if prev.nv != nv {
        return crate::selfx::self_intersecting_triangles(mesh);
    }
    let suspect = suspects(mesh, prev);
    let boxes: Vec<[Vec3; 2]> = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| mesh.vertices[k as usize]);
            [a.min(b).min(c), a.max(b).max(c)]
        })
        .collect();
    // A grid over the suspects' boxes, cells about twice their mean extent.
    let (mut lo, mut hi, mut extent, mut n) = (Vec3::INFINITY, Vec3::NEG_INFINITY, 0.0f64, 0);
    for (b, _) in boxes.iter().zip(&suspect).filter(|(_, s)| **s) {
        lo = lo.min(b[0]);
        hi = hi.max(b[1]);
        extent += f64::from((b[1] - b[0]).max_element());
        n += 1;
    }
    if n == 0 {
        return Vec::new();
    }
    let size = (hi - lo).max_element();
    let cell = (2.0 * extent / f64::from(n)) as f32;
    let cell = cell.max(size / MAX_DIM);
    if !(cell.is_finite() && cell > 0.0 && lo.is_finite() && hi.is_finite()) {
        return crate::selfx::self_intersecting_triangles(mesh);
    }
    let dims = ((hi - lo) / cell)
        .as_uvec3()
        .min(voxoct_core::glam::UVec3::splat(255))
        + 1;
    // The inclusive cell range of a box (monotone in the box, so boxes that meet share a
    // cell), or `None` when the box misses the grid.
    let range = |b: &[Vec3; 2]| {
        if b[1].cmplt(lo).any() || b[0].cmpgt(hi).any() {
            return None;
        }
        let c = |p: Vec3| ((p - lo) / cell).max(Vec3::ZERO).as_uvec3().min(dims - 1);
        Some((c(b[0]), c(b[1])))
    };
    let index = |x: u32, y: u32, z: u32| (x + dims.x * (y + dims.y * z)) as usize;
    let mut marked = vec![false; (dims.x * dims.y * dims.z) as usize];
    for (b, _) in boxes.iter().zip(&suspect).filter(|(_, s)| **s) {
        if let Some((a, z)) = range(b) {
            for k in a.z..=z.z {
                for j in a.y..=z.y {
                    for i in a.x..=z.x {
                        marked[index(i, j, k)] = true;
                    }
                }
            }
        }
    }
    let meets = |b: &[Vec3; 2]| {
        range(b).is_some_and(|(a, z)| {
            (a.z..=z.z).any(|k| (a.y..=z.y).any(|j| (a.x..=z.x).any(|i| marked[index(i, j, k)])))
        })
    };
    // The triangles near a suspect, their vertices numbered in order of first use.
    let mut map = vec![u32::MAX; nv];
    let mut sub = Mesh::default();
    let mut ids = Vec::new();
    for (t, (tri, b)) in mesh.triangles.iter().zip(&boxes).enumerate() {
        if !meets(b) {
            continue;
        }
        ids.push(t as u32);
        sub.triangles.push(tri.map(|k| {
            let m = &mut map[k as usize];
            if *m == u32::MAX {
                *m = sub.vertices.len() as u32;
                sub.vertices.push(mesh.vertices[k as usize]);
            }
            *m
        }));
    }
    drop((boxes, marked, map));
    crate::selfx::self_intersecting_triangles(&sub)
        .into_iter()
        .map(|t| ids[t as usize])
        .collect()
}

/// Per triangle of `mesh`: whether `prev` lacks it (same corners in the same cyclic order,
/// at the same positions) or has it among its self-intersecting ones.
fn suspects(mesh: &Mesh, prev: &Previous) -> Vec<bool> {
    let nv = mesh.vertices.len();
    // `prev`'s triangles by their smallest corner, each rotated to start there.
    let rotated = |t: [u32; 3]| {
        if t[0] <= t[1] && t[0] <= t[2] {
            t
        } else if t[1] <= t[2] {
            [t[1], t[2], t[0]]
        } else {
            [t[2], t[0], t[1]]
        }
    };
    let mut start = vec![0u32; nv + 1];
    for t in &prev.triangles {
        start[rotated(*t)[0] as usize + 1] += 1;
    }
    for i in 0..nv {
        start[i + 1] += start[i];
    }
    let mut cursor = start.clone();
    let mut row = vec![0u32; prev.triangles.len()];
    for (i, t) in prev.triangles.iter().enumerate() {
        let c = &mut cursor[rotated(*t)[0] as usize];
        row[*c as usize] = i as u32;
        *c += 1;
    }
    drop(cursor);
    let mut was_bad = vec![false; prev.triangles.len()];
    for &t in &prev.bad {
        was_bad[t as usize] = true;
    }
    let bits = |p: Vec3| p.to_array().map(f32::to_bits);
    let same_place = |k: u32| {
        prev.position(k)
            .is_some_and(|p| bits(mesh.vertices[k as usize]) == bits(p))
    };
    mesh.triangles
        .iter()
        .map(|t| {
            let r = rotated(*t);
            let v = r[0] as usize;
            let found = row[start[v] as usize..start[v + 1] as usize]
                .iter()
                .find(|&&p| rotated(prev.triangles[p as usize]) == r);
            match found {
                Some(&p) => was_bad[p as usize] || !t.iter().all(|&k| same_place(k)),
                None => true,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed UV sphere of radius 1 with `n` rings of `2n` vertices between the poles.
    fn sphere(n: u32, centre: Vec3) -> Mesh {
        let mut m = Mesh::default();
        m.vertices.push(centre + Vec3::Z);
        for i in 1..n {
            let th = std::f32::consts::PI * i as f32 / n as f32;
            for j in 0..2 * n {
                let ph = std::f32::consts::PI * j as f32 / n as f32;
                m.vertices
                    .push(centre + Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
            }
        }
        m.vertices.push(centre - Vec3::Z);
        let ring = |i: u32, j: u32| 1 + (i - 1) * 2 * n + j % (2 * n);
        let last = m.vertices.len() as u32 - 1;
        for j in 0..2 * n {
            m.triangles.push([0, ring(1, j), ring(1, j + 1)]);
            m.triangles.push([last, ring(n - 1, j + 1), ring(n - 1, j)]);
            for i in 1..n - 1 {
                let (a, b) = (ring(i, j), ring(i, j + 1));
                let (c, d) = (ring(i + 1, j), ring(i + 1, j + 1));
                m.triangles.push([a, c, d]);
                m.triangles.push([a, d, b]);
            }
        }
        m
    }

    #[test]
    fn the_local_test_finds_what_the_whole_test_finds() {
        // Two spheres, apart; then one vertex of the second pushed into the first, and the
        // first shifted through the second; each against the state before.
        let mut a = sphere(12, Vec3::ZERO);
        let b = sphere(12, Vec3::new(2.5, 0.0, 0.0));
        let base = a.vertices.len() as u32;
        a.vertices.extend_from_slice(&b.vertices);
        a.triangles
            .extend(b.triangles.iter().map(|t| t.map(|k| k + base)));
        let whole = |m: &Mesh| crate::selfx::self_intersecting_triangles(m);
        assert!(whole(&a).is_empty());
        let mut poked = a.clone();
        let tip = base as usize + 1 + 5 * 24 + 12; // on the second sphere's -x side
        poked.vertices[tip] = Vec3::new(0.5, 0.0, 0.0);
        let want = whole(&poked);
        assert!(!want.is_empty());
        let since = |m: &Mesh, prev: &Mesh, bad: &[u32]| {
            intersecting_since(m, &Previous::new(prev.clone(), bad.to_vec()))
        };
        assert_eq!(since(&poked, &a, &[]), want);
        // Back: the local test sees that the pair is gone.
        assert_eq!(since(&a, &poked, &want), whole(&a));
        // The same triangles with their corners rotated are the same triangles.
        let mut moved = poked.clone();
        for t in moved.triangles.iter_mut().take(30) {
            *t = [t[1], t[2], t[0]];
        }
        assert_eq!(since(&moved, &poked, &want), whole(&moved));
        let mut shifted = a.clone();
        for p in shifted.vertices.iter_mut().take(base as usize) {
            *p += Vec3::new(1.0, 0.0, 0.0);
        }
        let want = whole(&shifted);
        assert!(!want.is_empty());
        assert_eq!(since(&shifted, &a, &[]), want);
    }
}
