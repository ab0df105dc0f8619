//! Taubin λ/μ smoothing: positions only, connectivity untouched.

use voxoct_core::glam::{Vec3, Vec3A};

use crate::mesh::{Mesh, triangle_area};
use crate::options::Taubin;
use crate::par;

/// Vertex neighbours (each undirected mesh edge once per end), CSR.
fn neighbours(mesh: &Mesh) -> (Vec<u32>, Vec<u32>) {
    let n = mesh.vertices.len();
    // In a closed oriented mesh every undirected edge appears once as a -> b with a < b
    // and once with a > b; take each directed edge as a neighbour of its start: that lists
    // every neighbour exactly once.
    let mut start = vec![0u32; n + 1];
    for t in &mesh.triangles {
        for k in 0..3 {
            start[t[k] as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut adj = vec![0u32; start[n] as usize];
    for t in &mesh.triangles {
        for k in 0..3 {
            let a = t[k] as usize;
            adj[fill[a] as usize] = t[(k + 1) % 3];
            fill[a] += 1;
        }
    }
    (start, adj)
}

fn step(src: &[Vec3A], dst: &mut [Vec3A], start: &[u32], adj: &[u32], f: f32) {
    par::fill(dst, |v| {
        let nb = &adj[start[v] as usize..start[v + 1] as usize];
        let p = src[v];
        if nb.is_empty() {
            return p;
        }
        let mean = nb.iter().map(|&j| src[j as usize]).sum::<Vec3A>() / nb.len() as f32;
        p + f * (mean - p)
    });
}

fn any_degenerate(mesh: &Mesh, v: &[Vec3]) -> bool {
    par::any(&mesh.triangles, |&t| triangle_area(v, t).1)
}

fn has_duplicates(v: &[Vec3]) -> bool {
    let key = |p: &Vec3| p.to_array().map(|x| if x == 0.0 { 0 } else { x.to_bits() });
    let mut k: Vec<[u32; 3]> = v.iter().map(key).collect();
    par::sort(&mut k);
    k.windows(2).any(|w| w[0] == w[1])
}

fn run(mesh: &Mesh, start: &[u32], adj: &[u32], opts: &Taubin, iterations: u32) -> Vec<Vec3> {
    // SIMD lanes; the arithmetic is per lane, so the result is that of `Vec3` bit for bit.
    let mut cur: Vec<Vec3A> = mesh.vertices.iter().map(|&p| p.into()).collect();
    let mut tmp = cur.clone();
    for _ in 0..iterations {
        step(&cur, &mut tmp, start, adj, opts.lambda);
        step(&tmp, &mut cur, start, adj, opts.mu);
    }
    drop(tmp);
    cur.into_iter().map(Vec3::from).collect()
}

/// Smooths `mesh` in place. If the result had a degenerate triangle or two coinciding
/// vertices, it is discarded and smoothing is retried with half the iterations (down to
/// none), so the result keeps every property that [`Mesh::check_closed_manifold`] checks.
pub(crate) fn taubin(mesh: &mut Mesh, opts: &Taubin) {
    if mesh.vertices.is_empty() || opts.iterations == 0 {
        return;
    }
    let (start, adj) = neighbours(mesh);
    let mut iterations = opts.iterations;
    while iterations > 0 {
        let v = run(mesh, &start, &adj, opts, iterations);
        if !any_degenerate(mesh, &v) && !has_duplicates(&v) {
            mesh.vertices = v;
            return;
        }
        iterations /= 2;
    }
}
