//! Exact-in-practice triangle/box overlap: Akenine-Möller's separating-axis test.

use glam::{DVec3, Vec3};

use crate::geometry::{Aabb, Triangle};

/// Whether the closed triangle `tri` and the closed box `aabb` share at least one point.
///
/// This is the separating-axis test of T. Akenine-Möller, *Fast 3D Triangle-Box Overlap
/// Testing* (2001): the two convex sets are disjoint exactly when their projections are
/// disjoint on one of 13 axes — the 3 box normals, the triangle normal and the 9 cross
/// products of a triangle edge with a box axis. Both sets are **closed**: a triangle that
/// only touches a face, an edge or a corner of the box overlaps it.
///
/// # Precision
///
/// Coordinates are `f32`; the test runs in `f64`. Edge differences of `f32` values and
/// their products with `f32` coordinates are exact in `f64`, so the nine edge axes and
/// the three box axes are decided with a single rounding: the test never reports a
/// separation that exact arithmetic would not find (touching is never missed on those
/// axes), and it may report an overlap only across a gap of about one `f64` rounding
/// (~1e-16 relative). The normal axis carries one or two more roundings, still far below
/// `f32` resolution. No epsilon is added anywhere. (On an edge axis the triangle's
/// interval is spanned by the edge's first vertex and the opposite one: the edge's two
/// ends project to the same point exactly, so the second end adds nothing but a
/// rounding.)
///
/// The test is also *monotone*: if it accepts a box, it accepts every box containing it
/// (same arithmetic, same rounding direction). The octree relies on this: pruning a
/// node whose box is rejected can never drop a leaf whose own box would be accepted.
///
/// # Degenerate and invalid input
///
/// - A triangle with a non-finite coordinate overlaps nothing (`false`).
/// - A box with a non-finite coordinate, or with `min > max` on some axis, is empty and
///   overlaps nothing.
/// - A degenerate triangle (zero area: repeated vertices or collinear vertices) is
///   tested as the segment or point it is: its normal is exactly zero and its edges are
///   parallel, and the remaining axes are exactly the separating axes of a segment (or a
///   point) against a box. (The octree, which needs a normal, skips such triangles.)
///
/// # Example
///
/// ```
/// use voxoct_core::glam::Vec3;
/// use voxoct_core::{intersection_test_aabb_triangle, Aabb, Triangle};
///
/// let unit = Aabb::new(Vec3::ZERO, Vec3::ONE);
/// let touching = Triangle::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 0.0));
/// let apart = Triangle::new(Vec3::new(1.5, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 0.0));
/// assert!(intersection_test_aabb_triangle(&unit, &touching));
/// assert!(!intersection_test_aabb_triangle(&unit, &apart));
/// ```
#[inline]
#[must_use]
pub fn intersection_test_aabb_triangle(aabb: &Aabb, tri: &Triangle) -> bool {
    if !(aabb.min.is_finite() && aabb.max.is_finite() && aabb.min.cmple(aabb.max).all()) {
        return false;
    }
    if !tri.is_finite() {
        return false;
    }
    // The same formulas as `TriangleSat` (so the same bits), evaluated lazily: most
    // separated pairs are decided by the cheap axes first.
    let bmin = tri.v[0].min(tri.v[1]).min(tri.v[2]);
    let bmax = tri.v[0].max(tri.v[1]).max(tri.v[2]);
    if !(bmax.cmpge(aabb.min).all() && bmin.cmple(aabb.max).all()) {
        return false;
    }
    let (mn, mx) = (aabb.min.as_dvec3(), aabb.max.as_dvec3());
    let v = tri.v.map(Vec3::as_dvec3);
    let e = edges(&v);
    let n = e[0].cross(v[2] - v[0]);
    let (n_lo, n_hi) = min_max3(dot(n, v[0]), dot(n, v[1]), dot(n, v[2]));
    if !normal_passes(n, n_lo, n_hi, mn, mx) {
        return false;
    }
    let pairs = [
        (mn.y, mx.y, mn.z, mx.z),
        (mn.x, mx.x, mn.z, mx.z),
        (mn.x, mx.x, mn.y, mx.y),
    ];
    for (u, &(p0, p1, q0, q1)) in pairs.iter().enumerate() {
        for (i, &ed) in e.iter().enumerate() {
            let (a, b, lo, hi) = edge_axis(u, i, ed, &v);
            if !edge_passes(a, b, lo, hi, p0, p1, q0, q1) {
                return false;
            }
        }
    }
    true
}

/// The three edges `b - a`, `c - b`, `a - c`.
#[inline(always)]
fn edges(v: &[DVec3; 3]) -> [DVec3; 3] {
    [v[1] - v[0], v[2] - v[1], v[0] - v[2]]
}

/// The axis `e_i × u` (edge `i`, box axis `u`) as coefficients on the two other
/// coordinates ((y, z), (x, z) or (x, y)), and the triangle's projection interval on
/// it: spanned by the edge's start `v[i]` and the opposite vertex `v[i + 2]` (the
/// edge's end projects to the same point as its start, exactly).
#[inline(always)]
fn edge_axis(u: usize, i: usize, ed: DVec3, v: &[DVec3; 3]) -> (f64, f64, f64, f64) {
    let (s, o) = (v[i], v[(i + 2) % 3]);
    let (a, b, ps, po);
    match u {
        0 => {
            // edge × x = (0, e.z, -e.y)
            (a, b) = (ed.z, -ed.y);
            (ps, po) = (a * s.y + b * s.z, a * o.y + b * o.z);
        }
        1 => {
            // edge × y = (-e.z, 0, e.x)
            (a, b) = (-ed.z, ed.x);
            (ps, po) = (a * s.x + b * s.z, a * o.x + b * o.z);
        }
        _ => {
            // edge × z = (e.y, -e.x, 0)
            (a, b) = (ed.y, -ed.x);
            (ps, po) = (a * s.x + b * s.y, a * o.x + b * o.y);
        }
    }
    let (lo, hi) = ends(ps, po);
    (a, b, lo, hi)
}

/// The normal axis does not separate the box `mn..=mx`.
#[inline(always)]
fn normal_passes(n: DVec3, n_lo: f64, n_hi: f64, mn: DVec3, mx: DVec3) -> bool {
    let (lx, hx) = span(n.x, mn.x, mx.x);
    let (ly, hy) = span(n.y, mn.y, mx.y);
    let (lz, hz) = span(n.z, mn.z, mx.z);
    !(n_hi < (lx + ly) + lz || n_lo > (hx + hy) + hz)
}

/// The edge axis `(a, b)` does not separate the box `[p0, p1] × [q0, q1]`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn edge_passes(a: f64, b: f64, lo: f64, hi: f64, p0: f64, p1: f64, q0: f64, q1: f64) -> bool {
    let (la, ha) = span(a, p0, p1);
    let (lb, hb) = span(b, q0, q1);
    !(hi < la + lb || lo > ha + hb)
}

/// The lower and upper ends of `a * [mn, mx]`: the smaller and the larger of the two
/// products (the one definition every test of the crate uses, cell by cell or for a
/// block of cells at once).
#[inline(always)]
fn span(a: f64, mn: f64, mx: f64) -> (f64, f64) {
    ends(a * mn, a * mx)
}

/// `(min, max)` of two numbers (neither NaN here; either when equal).
#[inline(always)]
fn ends(x: f64, y: f64) -> (f64, f64) {
    if x < y { (x, y) } else { (y, x) }
}

/// A triangle prepared for many box tests: axes and projections computed once.
///
/// Every box test of the crate (the public function, the reference descent and the
/// pruning of large blocks) goes through [`TriangleSat::overlaps_skip_box_axes`] with
/// the same `f64` box corners; the fast insertion's [`TriangleSat::block_mask`]
/// evaluates the very same products, sums and comparisons for many cells at once, so
/// they all agree bit for bit.
#[derive(Debug, Clone)]
pub(crate) struct TriangleSat {
    /// The triangle's bounding box (exact, `f32`).
    pub(crate) bmin: Vec3,
    pub(crate) bmax: Vec3,
    /// First vertex, `f64`.
    v0: DVec3,
    /// Unnormalised normal `(b - a) × (c - a)` in `f64`.
    n: DVec3,
    /// Unit normal (zero for a degenerate triangle).
    n_unit: DVec3,
    /// Projection interval of the triangle on `n`.
    n_lo: f64,
    n_hi: f64,
    /// For box axis `u` (x, y, z) and edge `i`, the axis `edge_i × u` acts on the two
    /// other coordinates (y, z), (x, z), (x, y) with coefficients `ea[u][i]`,
    /// `eb[u][i]`; the triangle projects to `elo[u][i] ..= ehi[u][i]` on it.
    ea: [[f64; 3]; 3],
    eb: [[f64; 3]; 3],
    elo: [[f64; 3]; 3],
    ehi: [[f64; 3]; 3],
}

impl TriangleSat {
    /// Prepares `tri`; `None` when a coordinate is not finite.
    #[inline(always)]
    pub(crate) fn new(tri: &Triangle) -> Option<Self> {
        tri.is_finite().then(|| Self::of_finite(tri))
    }

    /// Prepares `tri`, whose coordinates the caller has checked to be finite (built
    /// in place: no `Option` to move out of).
    #[inline(always)]
    pub(crate) fn of_finite(tri: &Triangle) -> Self {
        let v = [
            tri.v[0].as_dvec3(),
            tri.v[1].as_dvec3(),
            tri.v[2].as_dvec3(),
        ];
        let e = edges(&v);
        let n = e[0].cross(v[2] - v[0]);
        let (n_lo, n_hi) = min_max3(dot(n, v[0]), dot(n, v[1]), dot(n, v[2]));
        let len = n.length();
        let n_unit = if len > 0.0 { n / len } else { DVec3::ZERO };
        let mut ea = [[0.0; 3]; 3];
        let mut eb = [[0.0; 3]; 3];
        let mut elo = [[0.0; 3]; 3];
        let mut ehi = [[0.0; 3]; 3];
        for u in 0..3 {
            for (i, &ed) in e.iter().enumerate() {
                (ea[u][i], eb[u][i], elo[u][i], ehi[u][i]) = edge_axis(u, i, ed, &v);
            }
        }
        let bmin = tri.v[0].min(tri.v[1]).min(tri.v[2]);
        let bmax = tri.v[0].max(tri.v[1]).max(tri.v[2]);
        Self {
            bmin,
            bmax,
            v0: v[0],
            n,
            n_unit,
            n_lo,
            n_hi,
            ea,
            eb,
            elo,
            ehi,
        }
    }

    /// Whether the triangle has zero area (its computed normal is exactly zero: repeated
    /// or exactly collinear vertices).
    #[inline]
    pub(crate) fn is_degenerate(&self) -> bool {
        self.n == DVec3::ZERO
    }

    /// Signed distance from `p` to the triangle's plane, positive on the normal side
    /// (0 for a degenerate triangle).
    #[inline]
    pub(crate) fn signed_distance(&self, p: Vec3) -> f32 {
        dot(self.n_unit, p.as_dvec3() - self.v0) as f32
    }

    /// The separating-axis test against a closed box given by its `f32` corners
    /// (`min <= max` is the caller's job).
    #[inline]
    pub(crate) fn overlaps(&self, aabb: &Aabb) -> bool {
        // The three box normals: the bounding boxes must overlap (closed).
        if !(self.bmax.cmpge(aabb.min).all() && self.bmin.cmple(aabb.max).all()) {
            return false;
        }
        self.overlaps_skip_box_axes(aabb.min.as_dvec3(), aabb.max.as_dvec3())
    }

    /// The ten non-box axes of the test, for a box (corners converted from `f32`) whose
    /// bounding-box test already passed.
    #[inline]
    pub(crate) fn overlaps_skip_box_axes(&self, mn: DVec3, mx: DVec3) -> bool {
        if !normal_passes(self.n, self.n_lo, self.n_hi, mn, mx) {
            return false;
        }
        // Nine edge axes.
        self.edges_pass(0, mn.y, mx.y, mn.z, mx.z)
            && self.edges_pass(1, mn.x, mx.x, mn.z, mx.z)
            && self.edges_pass(2, mn.x, mx.x, mn.y, mx.y)
    }

    /// The cells of a block of at most 4×4×4 cells whose box is
    /// `planes[0][i]..=planes[0][i + 1]` × … (`i < dims[0]`, …) and whose bounding-box
    /// axes are already known to pass, as bits `i + 4 j + 16 k` of the result. Planes
    /// beyond `dims` must be finite (further grid planes): the cells they bound are
    /// evaluated with the others and dropped.
    ///
    /// Bit-identical to [`overlaps_skip_box_axes`](Self::overlaps_skip_box_axes) cell
    /// by cell: the very same products, sums and comparisons. An edge axis acts on a
    /// pair of coordinates only, so it is decided once per column of cells; and since
    /// the sums are monotone in the cell index (so is `f64` rounding), an edge axis that
    /// does not separate the block's most exposed cells (the largest low end and the
    /// smallest high end of a cell's projection) separates none and is not evaluated
    /// cell by cell.
    #[inline]
    pub(crate) fn block_mask(&self, planes: &[[f64; 5]; 3], dims: [usize; 3]) -> u64 {
        const ROW: [u64; 5] = [0, 0x1, 0x11, 0x111, 0x1111];
        const LAYER: [u64; 5] = [0, 0x1, 0x1_0001, 0x1_0001_0001, 0x1_0001_0001_0001];
        let [nx, ny, nz] = dims;
        let valid = ((1u64 << nx) - 1) * ROW[ny] * LAYER[nz];
        // Fixed sizes (2, 3 or 4 per axis), so that every loop unrolls.
        let size = |n: usize| n.clamp(2, 4);
        let m = match (size(nx), size(ny), size(nz)) {
            (2, 2, 2) => self.block_mask_n::<2, 2, 2>(planes),
            (2, 2, 3) => self.block_mask_n::<2, 2, 3>(planes),
            (2, 2, 4) => self.block_mask_n::<2, 2, 4>(planes),
            (2, 3, 2) => self.block_mask_n::<2, 3, 2>(planes),
            (2, 3, 3) => self.block_mask_n::<2, 3, 3>(planes),
            (2, 3, 4) => self.block_mask_n::<2, 3, 4>(planes),
            (2, 4, 2) => self.block_mask_n::<2, 4, 2>(planes),
            (2, 4, 3) => self.block_mask_n::<2, 4, 3>(planes),
            (2, 4, 4) => self.block_mask_n::<2, 4, 4>(planes),
            (3, 2, 2) => self.block_mask_n::<3, 2, 2>(planes),
            (3, 2, 3) => self.block_mask_n::<3, 2, 3>(planes),
            (3, 2, 4) => self.block_mask_n::<3, 2, 4>(planes),
            (3, 3, 2) => self.block_mask_n::<3, 3, 2>(planes),
            (3, 3, 3) => self.block_mask_n::<3, 3, 3>(planes),
            (3, 3, 4) => self.block_mask_n::<3, 3, 4>(planes),
            (3, 4, 2) => self.block_mask_n::<3, 4, 2>(planes),
            (3, 4, 3) => self.block_mask_n::<3, 4, 3>(planes),
            (3, 4, 4) => self.block_mask_n::<3, 4, 4>(planes),
            (4, 2, 2) => self.block_mask_n::<4, 2, 2>(planes),
            (4, 2, 3) => self.block_mask_n::<4, 2, 3>(planes),
            (4, 2, 4) => self.block_mask_n::<4, 2, 4>(planes),
            (4, 3, 2) => self.block_mask_n::<4, 3, 2>(planes),
            (4, 3, 3) => self.block_mask_n::<4, 3, 3>(planes),
            (4, 3, 4) => self.block_mask_n::<4, 3, 4>(planes),
            (4, 4, 2) => self.block_mask_n::<4, 4, 2>(planes),
            (4, 4, 3) => self.block_mask_n::<4, 4, 3>(planes),
            (4, 4, 4) => self.block_mask_n::<4, 4, 4>(planes),
            _ => 0, // unreachable: the sizes are 2, 3 or 4
        };
        m & valid
    }

    /// [`block_mask`](Self::block_mask) of the `NX × NY × NZ` block (bits of cells
    /// beyond the real block included).
    #[inline(always)]
    fn block_mask_n<const NX: usize, const NY: usize, const NZ: usize>(
        &self,
        planes: &[[f64; 5]; 3],
    ) -> u64 {
        let [xs, ys, zs] = planes;
        // Edge axes, as bits `4 q + p` of the columns they pass, spread to the cells.
        let yz = self.pair_pass::<NY, NZ>(0, ys, zs);
        let xz = self.pair_pass::<NX, NZ>(1, xs, zs);
        let xy = self.pair_pass::<NX, NY>(2, xs, ys);
        if yz == 0 || xz == 0 || xy == 0 {
            return 0;
        }
        let edges = (spread_nibbles(yz) * 0xf)
            & (spread_rows(xz) * 0x1111)
            & (u64::from(xy) * 0x0001_0001_0001_0001);
        // Normal axis: `span` of each cell on each axis, summed as in `normal_passes`.
        let cell = |a: usize, i: usize| span(self.n[a], planes[a][i], planes[a][i + 1]);
        let ex: [(f64, f64); NX] = std::array::from_fn(|i| cell(0, i));
        let ey: [(f64, f64); NY] = std::array::from_fn(|j| cell(1, j));
        let ez: [(f64, f64); NZ] = std::array::from_fn(|k| cell(2, k));
        let mut sxy = [[(0.0f64, 0.0f64); NX]; NY];
        for (j, &(ly, hy)) in ey.iter().enumerate() {
            for (i, &(lx, hx)) in ex.iter().enumerate() {
                sxy[j][i] = (lx + ly, hx + hy);
            }
        }
        let mut normal = 0u64;
        for (k, &(lz, hz)) in ez.iter().enumerate() {
            for (j, row) in sxy.iter().enumerate() {
                for (i, &(l, h)) in row.iter().enumerate() {
                    let pass = self.n_hi >= l + lz && self.n_lo <= h + hz;
                    normal |= u64::from(pass) << (i + 4 * j + 16 * k);
                }
            }
        }
        normal & edges
    }

    /// For box axis `u`, the pairs `(p, q)` of cells (planes `ps`, `qs`; `p < NP`,
    /// `q < NQ`) on which none of the three edge axes separates, as bits `4 q + p`
    /// (`edge_passes` cell by cell).
    #[inline(always)]
    fn pair_pass<const NP: usize, const NQ: usize>(
        &self,
        u: usize,
        ps: &[f64; 5],
        qs: &[f64; 5],
    ) -> u32 {
        let mut sep = 0u32;
        for e in 0..3 {
            let (a, b, lo, hi) = (self.ea[u][e], self.eb[u][e], self.elo[u][e], self.ehi[u][e]);
            // `span` from products shared by neighbouring cells: cell `p` spans
            // `min(pa[p], pa[p + 1])..=max(..)`.
            let pa: [f64; 5] = std::array::from_fn(|t| if t <= NP { a * ps[t] } else { 0.0 });
            let pb: [f64; 5] = std::array::from_fn(|t| if t <= NQ { b * qs[t] } else { 0.0 });
            // The cells most likely separated: the largest low end and the smallest
            // high end of the block's cells (planes 1 and N - 1, whatever the signs).
            let low = hi < max(pa[1], pa[NP - 1]) + max(pb[1], pb[NQ - 1]);
            let high = lo > min(pa[1], pa[NP - 1]) + min(pb[1], pb[NQ - 1]);
            if low {
                for q in 0..NQ {
                    let lb = min(pb[q], pb[q + 1]);
                    for p in 0..NP {
                        sep |= u32::from(hi < min(pa[p], pa[p + 1]) + lb) << (4 * q + p);
                    }
                }
            }
            if high {
                for q in 0..NQ {
                    let hb = max(pb[q], pb[q + 1]);
                    for p in 0..NP {
                        sep |= u32::from(lo > max(pa[p], pa[p + 1]) + hb) << (4 * q + p);
                    }
                }
            }
        }
        !sep & 0xffff
    }

    /// The unit normal's contribution `n̂[a] · (c - v0[a])` of coordinate `c` on axis
    /// `a` to [`signed_distance`](Self::signed_distance) (which is
    /// `(x + y) + z` of these, rounded to `f32`).
    #[inline(always)]
    pub(crate) fn sdf_term(&self, a: usize, c: f32) -> f64 {
        self.n_unit[a] * (f64::from(c) - self.v0[a])
    }

    #[inline(always)]
    fn edges_pass(&self, u: usize, p0: f64, p1: f64, q0: f64, q1: f64) -> bool {
        let (ea, eb, elo, ehi) = (&self.ea[u], &self.eb[u], &self.elo[u], &self.ehi[u]);
        edge_passes(ea[0], eb[0], elo[0], ehi[0], p0, p1, q0, q1)
            && edge_passes(ea[1], eb[1], elo[1], ehi[1], p0, p1, q0, q1)
            && edge_passes(ea[2], eb[2], elo[2], ehi[2], p0, p1, q0, q1)
    }
}

/// The smaller of two numbers (neither NaN here; either when equal).
#[inline(always)]
fn min(x: f64, y: f64) -> f64 {
    if x < y { x } else { y }
}

/// The larger of two numbers (neither NaN here; either when equal).
#[inline(always)]
fn max(x: f64, y: f64) -> f64 {
    if x > y { x } else { y }
}

/// Bit `b` of a 16-bit mask to bit `4 b`.
#[inline(always)]
fn spread_nibbles(x: u32) -> u64 {
    let mut x = u64::from(x) & 0xffff;
    x = (x | x << 24) & 0x0000_00ff_0000_00ff;
    x = (x | x << 12) & 0x000f_000f_000f_000f;
    x = (x | x << 6) & 0x0303_0303_0303_0303;
    x = (x | x << 3) & 0x1111_1111_1111_1111;
    x
}

/// Nibble `k` of a 16-bit mask to bits `16 k ..`.
#[inline(always)]
fn spread_rows(x: u32) -> u64 {
    let x = u64::from(x);
    (x & 0xf) | (x & 0xf0) << 12 | (x & 0xf00) << 24 | (x & 0xf000) << 36
}

/// `a · b`, summed in the fixed order `(x + y) + z` used for every projection.
#[inline(always)]
fn dot(a: DVec3, b: DVec3) -> f64 {
    (a.x * b.x + a.y * b.y) + a.z * b.z
}

/// Smallest and largest of three values (never NaN here: finite `f32` input cannot
/// overflow `f64` in these formulas).
#[inline(always)]
fn min_max3(a: f64, b: f64, c: f64) -> (f64, f64) {
    let (lo, hi) = ends(a, b);
    (min(c, lo), max(c, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        Triangle::new(Vec3::from(a), Vec3::from(b), Vec3::from(c))
    }

    const UNIT: Aabb = Aabb::new(Vec3::ZERO, Vec3::ONE);

    #[test]
    fn inside_crossing_touching_apart() {
        let inside = tri([0.2, 0.2, 0.5], [0.8, 0.2, 0.5], [0.5, 0.8, 0.5]);
        assert!(intersection_test_aabb_triangle(&UNIT, &inside));
        // A big triangle cutting through the box, no vertex inside.
        let through = tri([-5.0, -5.0, 0.5], [5.0, -5.0, 0.5], [0.0, 5.0, 0.5]);
        assert!(intersection_test_aabb_triangle(&UNIT, &through));
        // Touching a corner with a vertex.
        let corner = tri([1.0, 1.0, 1.0], [2.0, 1.0, 1.0], [1.0, 2.0, 1.0]);
        assert!(intersection_test_aabb_triangle(&UNIT, &corner));
        // Lying in the top face plane, overlapping the face.
        let in_face = tri([-1.0, -1.0, 1.0], [3.0, -1.0, 1.0], [-1.0, 3.0, 1.0]);
        assert!(intersection_test_aabb_triangle(&UNIT, &in_face));
        // Just above the top face.
        let above = tri(
            [-1.0, -1.0, 1.0001],
            [3.0, -1.0, 1.0001],
            [-1.0, 3.0, 1.0001],
        );
        assert!(!intersection_test_aabb_triangle(&UNIT, &above));
    }

    #[test]
    fn edge_axis_separates() {
        // The bounding boxes overlap and the plane crosses the box, but the triangle's
        // hypotenuse passes beside the corner (1, 1, z): only an edge axis separates.
        let t = tri([0.5, 3.0, 0.5], [3.0, 0.5, 0.5], [3.0, 3.0, 0.5]);
        assert!(!intersection_test_aabb_triangle(&UNIT, &t));
        // The hypotenuse through the corner edge exactly: touching.
        let t = tri([0.0, 2.0, 0.5], [2.0, 0.0, 0.5], [3.0, 3.0, 0.5]);
        assert!(intersection_test_aabb_triangle(&UNIT, &t));
    }

    #[test]
    fn plane_separates() {
        // A tilted plane passing just beyond the corner (1, 1, 1).
        let t = tri([3.1, 0.0, 0.0], [0.0, 3.1, 0.0], [0.0, 0.0, 3.1]);
        assert!(!intersection_test_aabb_triangle(&UNIT, &t));
        let t = tri([3.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 3.0]);
        assert!(intersection_test_aabb_triangle(&UNIT, &t));
    }

    #[test]
    fn degenerate_is_a_segment_or_point() {
        let point_in = tri([0.5; 3], [0.5; 3], [0.5; 3]);
        let point_out = tri([1.5; 3], [1.5; 3], [1.5; 3]);
        assert!(intersection_test_aabb_triangle(&UNIT, &point_in));
        assert!(!intersection_test_aabb_triangle(&UNIT, &point_out));
        // Segment crossing the box diagonally (collinear vertices).
        let seg = tri([-1.0, -1.0, 0.5], [0.5, 0.5, 0.5], [2.0, 2.0, 0.5]);
        assert!(intersection_test_aabb_triangle(&UNIT, &seg));
        // Segment passing beside a corner edge: a triangle with a third vertex would hit.
        let seg = tri([0.0, 2.1, 0.5], [2.1, 0.0, 0.5], [1.05, 1.05, 0.5]);
        assert!(!intersection_test_aabb_triangle(&UNIT, &seg));
        assert!(TriangleSat::new(&seg).is_some_and(|s| s.is_degenerate()));
    }

    #[test]
    fn non_finite_overlaps_nothing() {
        let big = Aabb::new(Vec3::splat(-1e30), Vec3::splat(1e30));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let t = tri([0.5, 0.5, 0.5], [bad, 0.5, 0.5], [0.5, 0.6, 0.5]);
            assert!(!intersection_test_aabb_triangle(&big, &t));
            let ok = tri([0.5, 0.5, 0.5], [0.6, 0.5, 0.5], [0.5, 0.6, 0.5]);
            let bad_box = Aabb::new(Vec3::new(0.0, bad, 0.0), Vec3::ONE);
            assert!(!intersection_test_aabb_triangle(&bad_box, &ok));
        }
        let inverted = Aabb::new(Vec3::ONE, Vec3::ZERO);
        let ok = tri([-1.0, -1.0, 0.5], [3.0, -1.0, 0.5], [-1.0, 3.0, 0.5]);
        assert!(!intersection_test_aabb_triangle(&inverted, &ok));
    }

    #[test]
    fn huge_finite_coordinates_do_not_overflow() {
        let m = f32::MAX;
        let t = tri([-m, -m, 0.5], [m, -m, 0.5], [0.0, m, 0.5]);
        assert!(intersection_test_aabb_triangle(&UNIT, &t));
        let t = tri([-m, -m, 2.0], [m, -m, 2.0], [0.0, m, 2.0]);
        assert!(!intersection_test_aabb_triangle(&UNIT, &t));
    }
}
