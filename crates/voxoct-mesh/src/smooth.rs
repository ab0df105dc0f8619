//! Taubin λ/μ smoothing: positions only, connectivity untouched.

use voxoct_core::glam::{Vec3, Vec3A};

use crate::mesh::Mesh;
use crate::options::Taubin;
use crate::par;
use crate::selfx;

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

/// Vertices per parallel task of [`step`].
const STEP_BLOCK: usize = 1 << 13;

/// One relaxation of every vertex, `src` to `dst`: `p + f (mean of the neighbours - p)`.
/// A block of vertices per task, walked as a plain loop with each vertex's neighbour range
/// taken from consecutive pairs of `start`: a quarter less time than a fill by vertex
/// index on the bunny's smoothing (the same arithmetic).
fn step(src: &[Vec3A], dst: &mut [Vec3A], start: &[u32], adj: &[u32], f: f32) {
    par::for_each_chunk_mut(dst, STEP_BLOCK, |k, out| {
        let lo = k * STEP_BLOCK;
        let ends = start[lo..=lo + out.len()].windows(2);
        for ((d, &p), e) in out.iter_mut().zip(&src[lo..]).zip(ends) {
            let nb = &adj[e[0] as usize..e[1] as usize];
            *d = if nb.is_empty() {
                p
            } else {
                let mean = nb.iter().map(|&j| src[j as usize]).sum::<Vec3A>() / nb.len() as f32;
                p + f * (mean - p)
            };
        }
    });
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

/// Smooths `mesh` in place. Where the smoothed triangles would cut through each other (or
/// degenerate), their vertices are moved back toward their unsmoothed positions until none
/// does ([`crate::selfx`]'s `untangle`); should the unsmoothed mesh itself not be clean,
/// smoothing is undone. Returns whether the result is proven free of self-intersections:
/// the untangling ran the exact test over every triangle and left none (`false`: not
/// checked — nothing to smooth, or smoothing undone).
pub(crate) fn taubin(mesh: &mut Mesh, opts: &Taubin) -> bool {
    if mesh.vertices.is_empty() || opts.iterations == 0 {
        return false;
    }
    // The untangling's fans (one serial pass) are built alongside the neighbours (another).
    let ((start, adj), fans) = par::join(
        || neighbours(mesh),
        || selfx::vertex_fans(mesh.vertices.len(), &mesh.triangles),
    );
    let smoothed = run(mesh, &start, &adj, opts, opts.iterations);
    drop((start, adj));
    let safe = std::mem::replace(&mut mesh.vertices, smoothed);
    if !selfx::untangle(mesh, &safe, Some(fans)) {
        mesh.vertices = safe;
        return false;
    }
    true
}
