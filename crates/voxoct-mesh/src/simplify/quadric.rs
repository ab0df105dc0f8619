//! Garland–Heckbert quadrics: the error measure of a collapse and the new vertex's place.

use voxoct_core::glam::{DVec3, Vec3};

use super::collapse::greater;
use crate::mesh::Mesh;

/// A symmetric 4×4 quadric (upper triangle, row by row) and its weight.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Quadric {
    pub(super) q: [f64; 10],
    pub(super) w: f64,
}

impl Quadric {
    /// `w · (n·x + d)²` for the plane with unit normal `n`.
    pub(super) fn plane(n: DVec3, d: f64, w: f64) -> Self {
        let q = [
            n.x * n.x,
            n.x * n.y,
            n.x * n.z,
            n.x * d,
            n.y * n.y,
            n.y * n.z,
            n.y * d,
            n.z * n.z,
            n.z * d,
            d * d,
        ];
        Self {
            q: q.map(|x| x * w),
            w,
        }
    }

    pub(super) fn add(&mut self, o: &Self) {
        for (a, b) in self.q.iter_mut().zip(&o.q) {
            *a += b;
        }
        self.w += o.w;
    }

    pub(super) fn sum(a: &Self, b: &Self) -> Self {
        let mut s = *a;
        s.add(b);
        s
    }

    /// `Q(p)`: the weighted sum of squared plane distances.
    pub(super) fn eval(&self, p: DVec3) -> f64 {
        let q = &self.q;
        let (x, y, z) = (p.x, p.y, p.z);
        x * (q[0] * x + 2.0 * (q[1] * y + q[2] * z + q[3]))
            + y * (q[4] * y + 2.0 * (q[5] * z + q[6]))
            + z * (q[7] * z + 2.0 * q[8])
            + q[9]
    }

    /// Mean squared distance at `p` (the error² of the module docs).
    pub(super) fn mean_sq(&self, p: DVec3) -> f64 {
        if self.w > 0.0 {
            (self.eval(p) / self.w).max(0.0)
        } else {
            0.0
        }
    }

    /// The minimum of `Q`, regularised towards `m`: solves `(A + λI) x = λm − b` with
    /// `λ = RIDGE · trace(A)`; `None` if singular.
    pub(super) fn minimum(&self, m: DVec3) -> Option<DVec3> {
        let q = &self.q;
        let lambda = RIDGE * (q[0] + q[4] + q[7]);
        let (a00, a01, a02) = (q[0] + lambda, q[1], q[2]);
        let (a11, a12) = (q[4] + lambda, q[5]);
        let a22 = q[7] + lambda;
        let r = DVec3::new(
            lambda * m.x - q[3],
            lambda * m.y - q[6],
            lambda * m.z - q[8],
        );
        // Cramer's rule on the symmetric matrix.
        let c00 = a11 * a22 - a12 * a12;
        let c01 = a02 * a12 - a01 * a22;
        let c02 = a01 * a12 - a02 * a11;
        let det = a00 * c00 + a01 * c01 + a02 * c02;
        if !greater(det.abs(), 1e-300) {
            return None;
        }
        let c11 = a00 * a22 - a02 * a02;
        let c12 = a01 * a02 - a00 * a12;
        let c22 = a00 * a11 - a01 * a01;
        let x = DVec3::new(
            c00 * r.x + c01 * r.y + c02 * r.z,
            c01 * r.x + c11 * r.y + c12 * r.z,
            c02 * r.x + c12 * r.y + c22 * r.z,
        ) / det;
        x.is_finite().then_some(x)
    }
}

/// What a collapse of `u` into `w` does to their quadrics and normals: `u`'s added to
/// `w`'s. The one place it is done, for the collapses and for adding a region's sums up
/// again from its log (which must give the same bits).
pub(super) fn merge(quad: &mut [Quadric], nrm: &mut [Vec3], u: usize, w: usize) {
    let qu = quad[u];
    quad[w].add(&qu);
    let nu = nrm[u];
    nrm[w] += nu;
}

/// Ridge of [`Quadric::minimum`] relative to the quadric's trace.
pub(super) const RIDGE: f64 = 1e-3;

/// [`initial_quadrics_at`] relative to `mesh`'s first vertex ([`origin`]).
#[cfg(test)]
pub(super) fn initial_quadrics(mesh: &Mesh) -> (Vec<Quadric>, Vec<Vec3>) {
    initial_quadrics_at(mesh, origin(mesh))
}

/// Per-vertex quadrics of `mesh` (in coordinates relative to `o`) and area-weighted
/// normals: each triangle's plane and normal added to its three corners (one pass in
/// triangle order; the vertices are numbered by first use, so the writes are local).
pub(super) fn initial_quadrics_at(mesh: &Mesh, o: DVec3) -> (Vec<Quadric>, Vec<Vec3>) {
    let nv = mesh.vertices.len();
    let mut quad = vec![Quadric::default(); nv];
    let mut nrm = vec![Vec3::ZERO; nv];
    add_initial(mesh, o, |k| Some(k as usize), &mut quad, &mut nrm);
    (quad, nrm)
}

/// Adds each triangle's plane and normal, in triangle order, to the slot `slot` gives for
/// each of its corners (none: skipped). A vertex's sum is its initial quadric and normal
/// when every triangle around it is in `mesh` (in the same order as in the whole mesh,
/// so the same to the bit).
pub(super) fn add_initial(
    mesh: &Mesh,
    o: DVec3,
    slot: impl Fn(u32) -> Option<usize>,
    quad: &mut [Quadric],
    nrm: &mut [Vec3],
) {
    for t in &mesh.triangles {
        let slots = t.map(&slot);
        if slots.iter().all(Option::is_none) {
            continue;
        }
        let [a, b, c] = t.map(|k| mesh.vertices[k as usize]);
        let nf = (b - a).cross(c - a);
        let [ad, bd, cd] = [a, b, c].map(|p| p.as_dvec3() - o);
        let n = (bd - ad).cross(cd - ad);
        let len = n.length();
        let plane = if len > 0.0 {
            let n = n / len;
            Quadric::plane(n, -n.dot(ad), len / 6.0)
        } else {
            Quadric::default()
        };
        for s in slots.into_iter().flatten() {
            quad[s].add(&plane);
            nrm[s] += nf;
        }
    }
}

/// The origin of the quadrics' coordinates.
pub(super) fn origin(mesh: &Mesh) -> DVec3 {
    mesh.vertices.first().map_or(DVec3::ZERO, |p| p.as_dvec3())
}
