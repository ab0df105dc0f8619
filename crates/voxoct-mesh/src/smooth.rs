//! Taubin λ/μ smoothing: positions only, connectivity untouched.

use voxoct_core::glam::{Vec3, Vec3A};

use crate::fans::VertexFans;
use crate::mesh::Mesh;
use crate::options::Taubin;
use crate::par;
use crate::selfx;

/// One Laplacian step. A vertex's neighbours are the first vertices after it of its
/// corners (`fans`): in a closed oriented mesh every undirected edge appears once as
/// a -> b and once as b -> a, so that lists every neighbour exactly once.
fn step(src: &[Vec3A], dst: &mut [Vec3A], fans: &VertexFans, f: f32) {
    par::fill(dst, |v| {
        let nb = fans.corners(v as u32);
        let p = src[v];
        if nb.is_empty() {
            return p;
        }
        let mean = nb.iter().map(|j| src[j[0] as usize]).sum::<Vec3A>() / nb.len() as f32;
        p + f * (mean - p)
    });
}

fn run(mesh: &Mesh, fans: &VertexFans, opts: &Taubin, iterations: u32) -> Vec<Vec3> {
    // SIMD lanes; the arithmetic is per lane, so the result is that of `Vec3` bit for bit.
    let mut cur: Vec<Vec3A> = mesh.vertices.iter().map(|&p| p.into()).collect();
    let mut tmp = cur.clone();
    for _ in 0..iterations {
        step(&cur, &mut tmp, fans, opts.lambda);
        step(&tmp, &mut cur, fans, opts.mu);
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
    // One fan table for smoothing (the corners' vertices) and the untangling's search.
    let mut fans = selfx::fans_of(mesh.vertices.len(), &mesh.triangles, true);
    let smoothed = run(mesh, &fans, opts, opts.iterations);
    fans.pairs = Vec::new();
    let safe = std::mem::replace(&mut mesh.vertices, smoothed);
    if !selfx::untangle(mesh, &safe, fans) {
        mesh.vertices = safe;
        return false;
    }
    true
}
