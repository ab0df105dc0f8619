//! Exact self-intersection test of a triangle mesh.
//!
//! # What counts
//! Triangles are closed point sets. Two triangles `T1`, `T2` of a mesh *intersect
//! improperly* when `T1 ∩ T2` is more than what their shared vertex indices allow:
//! - no shared vertex: `T1 ∩ T2` must be empty (touching counts as intersecting);
//! - one shared vertex `v`: `T1 ∩ T2` must be `{v}`. With `T1 = (v, a, b)` and
//!   `T2 = (v, c, d)` this fails exactly when the segment `ab` meets `T2` or `cd` meets `T1`
//!   (the line where the two planes meet runs through `v`; the shorter of the two chords from
//!   `v` ends on its triangle's opposite edge, inside the other triangle);
//! - a shared edge `uv` with opposite vertices `p`, `q`: `T1 ∩ T2` must be the segment `uv`.
//!   This fails exactly when `u, v, p, q` are coplanar and `p`, `q` lie on the same side of
//!   the line `uv` (a fold): otherwise the planes meet in the line `uv` only, or the two
//!   triangles lie in opposite half-planes;
//! - three shared vertices (a repeated triangle, in either orientation): always improper.
//!
//! A triangle that is not a proper triangle — an index out of range, a repeated index, a
//! non-finite vertex, or three exactly collinear positions — is reported as self-intersecting
//! itself and takes part in no pair test.
//!
//! # Exactness
//! Every decision is the sign of an orientation determinant (`orient3d`, or `orient2d` of a
//! projection onto a coordinate plane), evaluated by Shewchuk's adaptive-precision
//! predicates (the `robust` crate): a floating-point filter, then exact expansion arithmetic
//! when the filter cannot decide. The `f32` coordinates convert to `f64` exactly, and their
//! range keeps every intermediate product far from `f64` overflow and underflow, so every
//! sign is exact. Coplanar configurations are decided in the projection that drops the axis
//! of a non-zero normal component, which maps the common plane bijectively (preserving or
//! reversing every orientation alike), so they are exact too.
//!
//! # Speed
//! - Candidate pairs come from a uniform grid (cell edge 1.5 mean triangle extents): each
//!   triangle is entered in every cell its bounding box meets, flagged with the axes along
//!   which that cell is its first; the cells are hashed by their Morton code into buckets
//!   (nearby cells, nearby buckets) and counting-sorted. Two overlapping boxes have exactly
//!   one cell that is, along each axis, the first cell of one of them, and only the entries
//!   whose flags cover all three axes are paired, so each pair is found once.
//! - Pairs around a vertex need no test when the vertex's whole fan is *certified*: closed,
//!   and one-to-one in the projection along a coordinate axis (every triangle with the same
//!   orientation, the projections winding once around the vertex). Then any two of its
//!   triangles meet in exactly their shared vertex or edge. On a smooth scan nearly every
//!   vertex is certified, leaving the exact tests to the pairs that share no vertex.
//! - With the `parallel` feature the classification, the certificates and the buckets are
//!   processed on every core; the result is the same set.
//!
//! [`untangle`] reuses the search state to re-check only the pairs around moved vertices.

use robust::{Coord, Coord3D};
use voxoct_core::glam::{Vec3, Vec3A};

use crate::fans::VertexFans;
use crate::mesh::Mesh;

/// A vertex in `f64` (exact from `f32`).
type P = [f64; 3];

/// Marks a triangle that takes part in no pair test (invalid or degenerate).
const NO_AXIS: u8 = 3;

#[inline]
fn pt(v: Vec3) -> P {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

#[inline]
fn sign(x: f64) -> i8 {
    i8::from(x > 0.0) - i8::from(x < 0.0)
}

#[inline]
fn c3(a: &P) -> Coord3D<f64> {
    Coord3D {
        x: a[0],
        y: a[1],
        z: a[2],
    }
}

/// Exact sign of the orientation of `d` against the plane `a, b, c`; 0 when coplanar.
#[inline]
fn orient3d(a: &P, b: &P, c: &P, d: &P) -> i8 {
    sign(robust::orient3d(c3(a), c3(b), c3(c), c3(d)))
}

/// Exact sign of the orientation of the projections of `a, b, c` that drop axis `k`: the
/// sign of the `k` component of `(b - a) × (c - a)`.
#[inline]
fn orient2d(a: &P, b: &P, c: &P, k: usize) -> i8 {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    sign(robust::orient2d(
        Coord { x: a[i], y: a[j] },
        Coord { x: b[i], y: b[j] },
        Coord { x: c[i], y: c[j] },
    ))
}

/// Whether collinear points `x`, `y` lie in lexicographic order (`x <= y`).
#[inline]
fn lex_le(x: &P, y: &P) -> bool {
    x.partial_cmp(y).is_some_and(|o| o.is_le())
}

/// Closed segments `pq` and `rs` meet, in the projection dropping axis `k`.
fn seg_seg_2d(p: &P, q: &P, r: &P, s: &P, k: usize) -> bool {
    let d1 = orient2d(p, q, r, k);
    let d2 = orient2d(p, q, s, k);
    if d1 * d2 > 0 {
        return false;
    }
    let d3 = orient2d(r, s, p, k);
    let d4 = orient2d(r, s, q, k);
    if d3 * d4 > 0 {
        return false;
    }
    if d1 == 0 && d2 == 0 && d3 == 0 && d4 == 0 {
        // All four on one line: lexicographic order (of the projections, which keep the
        // order along the line) is the order along it; the intervals must overlap.
        let proj = |x: &P| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            [x[i], x[j], 0.0]
        };
        let (p, q, r, s) = (proj(p), proj(q), proj(r), proj(s));
        let (lo1, hi1) = if lex_le(&p, &q) { (p, q) } else { (q, p) };
        let (lo2, hi2) = if lex_le(&r, &s) { (r, s) } else { (s, r) };
        return lex_le(&lo1, &hi2) && lex_le(&lo2, &hi1);
    }
    true
}

/// Closed triangle `t` (not degenerate in projection `k`) contains `x`, all coplanar.
fn point_in_tri_2d(x: &P, t: &[P; 3], k: usize) -> bool {
    let o1 = orient2d(&t[0], &t[1], x, k);
    let o2 = orient2d(&t[1], &t[2], x, k);
    let o3 = orient2d(&t[2], &t[0], x, k);
    !((o1 > 0 || o2 > 0 || o3 > 0) && (o1 < 0 || o2 < 0 || o3 < 0))
}

/// Closed segment `pq` meets closed triangle `t`, all in one plane that projection `k`
/// maps bijectively.
fn seg_tri_coplanar(p: &P, q: &P, t: &[P; 3], k: usize) -> bool {
    point_in_tri_2d(p, t, k)
        || point_in_tri_2d(q, t, k)
        || seg_seg_2d(p, q, &t[0], &t[1], k)
        || seg_seg_2d(p, q, &t[1], &t[2], k)
        || seg_seg_2d(p, q, &t[2], &t[0], k)
}

/// Closed segment `pq` meets closed triangle `t` (not degenerate; `k` its projection axis),
/// given `sp`, `sq`: the orientations of `p`, `q` against the plane of `t`.
fn seg_tri(p: &P, q: &P, sp: i8, sq: i8, t: &[P; 3], k: usize) -> bool {
    if sp * sq > 0 {
        return false;
    }
    if sp == 0 && sq == 0 {
        return seg_tri_coplanar(p, q, t, k);
    }
    // The line pq crosses the plane in one point, within the closed segment; it lies in the
    // closed triangle when the line passes every directed edge on the same side (or on it).
    let s1 = orient3d(p, q, &t[0], &t[1]);
    let s2 = orient3d(p, q, &t[1], &t[2]);
    let s3 = orient3d(p, q, &t[2], &t[0]);
    !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0))
}

/// Orientations of the points `x` against the plane of `t`.
#[inline]
fn sides(t: &[P; 3], x: &[P; 3]) -> [i8; 3] {
    x.each_ref().map(|x| orient3d(&t[0], &t[1], &t[2], x))
}

/// Whether all three orientations are strictly on one side.
#[inline]
fn one_side(s: [i8; 3]) -> bool {
    (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0)
}

/// Two closed triangles with no shared vertex meet (`k1`, `k2`: their projection axes).
fn tri_tri(t1: &[P; 3], t2: &[P; 3], k1: usize, k2: usize) -> bool {
    let s2 = sides(t1, t2);
    if one_side(s2) {
        return false;
    }
    let s1 = sides(t2, t1);
    if one_side(s1) {
        return false;
    }
    // They meet exactly when an edge of one meets the other: the intersection is convex,
    // and an extreme point of it lies on the boundary of one of them.
    (0..3).any(|e| {
        let (i, j) = (e, (e + 1) % 3);
        seg_tri(&t1[i], &t1[j], s1[i], s1[j], t2, k2)
            || seg_tri(&t2[i], &t2[j], s2[i], s2[j], t1, k1)
    })
}

/// A triangle's vertices and projection axis.
#[derive(Clone, Copy)]
struct Tri<'a> {
    idx: [u32; 3],
    k: usize,
    v: &'a [Vec3],
}

impl Tri<'_> {
    #[inline]
    fn p(&self, i: usize) -> P {
        pt(self.v[self.idx[i] as usize])
    }
    #[inline]
    fn pts(&self) -> [P; 3] {
        [self.p(0), self.p(1), self.p(2)]
    }
}

/// Whether two proper triangles intersect improperly (see the module documentation).
fn improper(a: Tri<'_>, b: Tri<'_>) -> bool {
    // ma, mb: which corners are shared.
    let (mut ma, mut mb, mut n) = (0u8, 0u8, 0u8);
    for i in 0..3 {
        for j in 0..3 {
            if a.idx[i] == b.idx[j] {
                ma |= 1 << i;
                mb |= 1 << j;
                n += 1;
            }
        }
    }
    match n {
        0 => tri_tri(&a.pts(), &b.pts(), a.k, b.k),
        1 => {
            // Rotate each so that corner 0 is the shared vertex.
            let ra = rotated(a, ma.trailing_zeros() as usize);
            let rb = rotated(b, mb.trailing_zeros() as usize);
            let sa = [
                0,
                orient3d(&rb[0], &rb[1], &rb[2], &ra[1]),
                orient3d(&rb[0], &rb[1], &rb[2], &ra[2]),
            ];
            if seg_tri(&ra[1], &ra[2], sa[1], sa[2], &rb, b.k) {
                return true;
            }
            let sb = [
                0,
                orient3d(&ra[0], &ra[1], &ra[2], &rb[1]),
                orient3d(&ra[0], &ra[1], &ra[2], &rb[2]),
            ];
            seg_tri(&rb[1], &rb[2], sb[1], sb[2], &ra, a.k)
        }
        2 => {
            // Corner 0 of each rotated one is the opposite vertex.
            let ra = rotated(a, (!ma & 7).trailing_zeros() as usize);
            let q = b.p((!mb & 7).trailing_zeros() as usize);
            let (u, v, p) = (&ra[1], &ra[2], &ra[0]);
            orient3d(u, v, p, &q) == 0 && orient2d(u, v, p, a.k) == orient2d(u, v, &q, a.k)
        }
        _ => true,
    }
}

/// The triangle's points rotated so that corner `first` comes first (orientation kept).
#[inline]
fn rotated(t: Tri<'_>, first: usize) -> [P; 3] {
    [t.p(first), t.p((first + 1) % 3), t.p((first + 2) % 3)]
}

/// A triangle's projection axis ([`NO_AXIS`] when it is not a proper triangle) and the exact
/// signs of its normal's components (bit `k`: positive, bit `3 + k`: negative).
fn classify(vertices: &[Vec3], t: [u32; 3]) -> (u8, u8) {
    let n = vertices.len();
    if t.iter().any(|&i| i as usize >= n) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return (NO_AXIS, 0);
    }
    let [a, b, c] = t.map(|i| vertices[i as usize]);
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return (NO_AXIS, 0);
    }
    let (a, b, c) = (pt(a), pt(b), pt(c));
    let mut signs = 0u8;
    for k in 0..3 {
        match orient2d(&a, &b, &c, k) {
            1 => signs |= 1 << k,
            -1 => signs |= 8 << k,
            _ => {}
        }
    }
    if signs == 0 {
        return (NO_AXIS, 0);
    }
    // Among the exactly non-zero components, the largest (best-conditioned projection).
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let nrm = [
        (u[1] * w[2] - u[2] * w[1]).abs(),
        (u[2] * w[0] - u[0] * w[2]).abs(),
        (u[0] * w[1] - u[1] * w[0]).abs(),
    ];
    let k = (0..3)
        .filter(|&k| signs & (9 << k) != 0)
        .max_by(|&x, &y| nrm[x].total_cmp(&nrm[y]))
        .unwrap_or(0);
    (k as u8, signs)
}

/// Whether triangles `i` and `j` of `mesh` intersect improperly (see
/// [`self_intersecting_triangles`]); for `i == j`, whether the triangle is not a proper
/// triangle (bad or repeated index, non-finite or collinear vertices: such a triangle takes
/// part in no pair). One pair, exactly, without the grid or any shortcut: the reference for
/// the search.
///
/// # Panics
/// If `i` or `j` is not a triangle index.
#[must_use]
pub fn triangles_intersect(mesh: &Mesh, i: usize, j: usize) -> bool {
    let (ti, tj) = (mesh.triangles[i], mesh.triangles[j]);
    let (ki, kj) = (
        classify(&mesh.vertices, ti).0,
        classify(&mesh.vertices, tj).0,
    );
    if i == j {
        return ki == NO_AXIS;
    }
    if ki == NO_AXIS || kj == NO_AXIS {
        return false;
    }
    let tri = |idx, k: u8| Tri {
        idx,
        k: k as usize,
        v: &mesh.vertices,
    };
    improper(tri(ti, ki), tri(tj, kj))
}

/// The triangles of `mesh` that intersect another triangle *improperly*, or are not proper
/// triangles, in increasing order. A closed, oriented 2-manifold with none is the boundary
/// of a solid.
///
/// Triangles are closed point sets, and two of them intersect improperly when they meet in
/// more than their shared vertex indices allow:
/// - no shared vertex: they must not meet at all (touching counts);
/// - one shared vertex `v`: they must meet in `v` only;
/// - a shared edge: they must meet in that edge only, that is, they must not be folded onto
///   each other (coplanar with the opposite vertices on the same side of the edge);
/// - a repeated triangle (three shared vertices, either orientation) always does.
///
/// A triangle with an index out of range, a repeated index, a non-finite vertex or three
/// exactly collinear vertices is not a proper triangle: it is reported itself and takes part
/// in no pair.
///
/// Every decision is exact: signs of orientation determinants evaluated with Shewchuk's
/// adaptive-precision predicates, which are exact for `f32` coordinates. Candidate pairs come
/// from a uniform grid over the triangles' bounding boxes; pairs of triangles around a vertex
/// whose whole fan is proved embedded (it projects one-to-one along an axis) need no test.
/// With the `parallel` feature the work is spread over every core, with the same result.
#[must_use]
pub fn self_intersecting_triangles(mesh: &Mesh) -> Vec<u32> {
    let checker = Checker::new(&mesh.vertices, &mesh.triangles, None, false);
    checker.check_all(&mesh.vertices)
}

/// A triangle's bounding box `[min, max]` (zero-sized at the origin for a bad index).
#[inline]
fn tri_box(vertices: &[Vec3], t: [u32; 3]) -> [Vec3A; 2] {
    let g = |i: u32| Vec3A::from(vertices.get(i as usize).copied().unwrap_or(Vec3::ZERO));
    let (a, b, c) = (g(t[0]), g(t[1]), g(t[2]));
    [a.min(b).min(c), a.max(b).max(c)]
}

/// Largest fan that [`certified`] examines.
const MAX_FAN: usize = 32;

/// Whether the triangles around vertex `v` (its `fan`) cannot intersect each other
/// improperly, proved exactly: all are proper, each link vertex starts exactly one and ends
/// exactly one of them (closed), and along some coordinate axis every one projects with the
/// same orientation and the projections wind once around `v`. Then the projection maps each
/// triangle one-to-one onto a sector at `v`, the sectors meet only in `v` or (consecutive
/// ones) along the ray of their shared edge, so any two of the triangles meet in exactly
/// their shared vertex or edge.
fn certified(
    v: u32,
    fan: &[u32],
    triangles: &[[u32; 3]],
    vertices: &[Vec3],
    facts: &[(u8, u8)],
) -> bool {
    let m = fan.len();
    if !(3..=MAX_FAN).contains(&m) {
        return false;
    }
    let mut link = [(0u32, 0u32); MAX_FAN];
    let mut all = 0x3fu8;
    for (l, &t) in link.iter_mut().zip(fan) {
        let (k, signs) = facts[t as usize];
        if k == NO_AXIS {
            return false;
        }
        all &= signs;
        let tri = triangles[t as usize];
        let r = if tri[0] == v {
            0
        } else if tri[1] == v {
            1
        } else {
            2
        };
        *l = (tri[(r + 1) % 3], tri[(r + 2) % 3]);
    }
    if all == 0 {
        return false;
    }
    let link = &link[..m];
    // Closed: starts distinct, ends distinct, and each end is some triangle's start (so the
    // ends are the starts, permuted); `succ[i]` is the triangle that starts where triangle i
    // ends.
    let mut succ = [0u8; MAX_FAN];
    for (i, l) in link.iter().enumerate() {
        if link[i + 1..].iter().any(|x| x.0 == l.0 || x.1 == l.1) {
            return false;
        }
        match link.iter().position(|x| x.0 == l.1) {
            Some(j) => succ[i] = j as u8,
            None => return false,
        }
    }
    let k = all.trailing_zeros() as usize;
    let (k, flip) = if k < 3 { (k, 1) } else { (k - 3, -1) };
    // Winding: the sectors (start, end] that hold the direction of the first link vertex.
    let pv = pt(vertices[v as usize]);
    let r = pt(vertices[link[0].0 as usize]);
    let mut side = [0i8; MAX_FAN];
    for (s, l) in side.iter_mut().zip(link).skip(1) {
        *s = flip * orient2d(&pv, &pt(vertices[l.0 as usize]), &r, k);
    }
    let mut count = 0;
    for i in 0..m {
        if side[i] > 0 && side[succ[i] as usize] <= 0 {
            count += 1;
        }
    }
    count == 1
}

/// Whether the indices are in range and distinct.
#[inline]
fn valid_indices(nv: usize, t: [u32; 3]) -> bool {
    t.iter().all(|&i| (i as usize) < nv) && t[0] != t[1] && t[1] != t[2] && t[0] != t[2]
}

/// The state of one self-intersection search, kept for re-checking after local moves.
pub(crate) struct Checker<'a> {
    triangles: &'a [[u32; 3]],
    /// Also treat triangles that [`Mesh::check_closed_manifold`] calls degenerate as
    /// improper.
    f32_degenerate: bool,
    facts: Vec<(u8, u8)>,
    boxes: Vec<[Vec3A; 2]>,
    fans: VertexFans,
    cert: Vec<bool>,
    /// The boxes the index was built from, when not the current ones.
    index_boxes: Option<Vec<[Vec3A; 2]>>,
    index: Index,
}

impl<'a> Checker<'a> {
    /// Prepares the search; `index_boxes` (per triangle, each containing every box the
    /// triangle will have) default to the current boxes.
    pub(crate) fn new(
        vertices: &[Vec3],
        triangles: &'a [[u32; 3]],
        index_boxes: Option<Vec<[Vec3A; 2]>>,
        f32_degenerate: bool,
    ) -> Self {
        let nv = vertices.len();
        let facts = crate::par::map(triangles, |t| fact(vertices, *t, f32_degenerate));
        let boxes = crate::par::map(triangles, |t| tri_box(vertices, *t));
        let fans = VertexFans::new(nv, triangles, |t| valid_indices(nv, t), false);
        let mut cert = Vec::new();
        crate::par::map_into(&mut cert, nv, |v| {
            certified(v as u32, fans.fan(v as u32), triangles, vertices, &facts)
        });
        let index = match &index_boxes {
            Some(b) => Index::build(b, |t| valid_indices(nv, triangles[t])),
            None => Index::build(&boxes, |t| facts[t].0 != NO_AXIS),
        };
        Self {
            triangles,
            f32_degenerate,
            facts,
            boxes,
            fans,
            cert,
            index_boxes,
            index,
        }
    }

    /// Every flagged triangle, in increasing order.
    pub(crate) fn check_all(&self, vertices: &[Vec3]) -> Vec<u32> {
        let mut out = self.index.pairs(self, vertices, None);
        self.add_improper(&mut out, 0..self.triangles.len());
        out.sort_unstable();
        out.dedup();
        out
    }

    fn add_improper(&self, out: &mut Vec<u32>, ts: impl Iterator<Item = usize>) {
        out.extend(ts.filter(|&t| self.facts[t].0 == NO_AXIS).map(|t| t as u32));
    }

    /// After `moved` vertices changed position: updates what depends on them and returns
    /// the flagged triangles among the pairs that involve them (increasing order). With no
    /// flagged pair before the move except those around `moved`, that is every one.
    pub(crate) fn recheck(
        &mut self,
        vertices: &[Vec3],
        moved: &[u32],
        dirty: &mut [bool],
    ) -> Vec<u32> {
        let mut tris: Vec<u32> = Vec::new();
        for &v in moved {
            tris.extend_from_slice(self.fans.fan(v));
        }
        tris.sort_unstable();
        tris.dedup();
        let mut verts: Vec<u32> = Vec::new();
        for &t in &tris {
            let tri = self.triangles[t as usize];
            self.facts[t as usize] = fact(vertices, tri, self.f32_degenerate);
            self.boxes[t as usize] = tri_box(vertices, tri);
            dirty[t as usize] = true;
            verts.extend_from_slice(&tri);
        }
        verts.sort_unstable();
        verts.dedup();
        for &v in &verts {
            let ok = certified(v, self.fans.fan(v), self.triangles, vertices, &self.facts);
            self.cert[v as usize] = ok;
        }
        let mut out = self.index.pairs(self, vertices, Some((&tris, dirty)));
        self.add_improper(&mut out, tris.iter().map(|&t| t as usize));
        for &t in &tris {
            dirty[t as usize] = false;
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// [`classify`], and with `f32_degenerate` the degenerate test of
/// [`Mesh::check_closed_manifold`] on top.
fn fact(vertices: &[Vec3], t: [u32; 3], f32_degenerate: bool) -> (u8, u8) {
    let f = classify(vertices, t);
    if f32_degenerate && f.0 != NO_AXIS && crate::mesh::triangle_area(vertices, t).1 {
        return (NO_AXIS, 0);
    }
    f
}

/// Moves the vertices of improper triangles — self-intersecting, collinear, or degenerate
/// as [`Mesh::check_closed_manifold`] counts them — back toward `safe` (the same
/// connectivity with no improper triangle) until none is left: each round, every vertex of
/// a flagged triangle goes to the next of `moved + f · (safe - moved)` for f = 1/2, 3/4, 7/8,
/// then to `safe` itself, and the triangles around the moved vertices are checked again.
/// Every round moves a vertex, and a pair of triangles whose vertices are all at `safe` is
/// proper, so this ends. Returns the number of vertices not at their moved position, or
/// `None` when flagged triangles are left with every vertex at `safe` (`safe` was not
/// clean).
pub(crate) fn untangle(mesh: &mut Mesh, safe: &[Vec3]) -> Option<usize> {
    let Mesh {
        vertices,
        triangles,
    } = mesh;
    let target = vertices.clone();
    let swept = crate::par::map(triangles, |t| {
        let (a, b) = (tri_box(&target, *t), tri_box(safe, *t));
        [a[0].min(b[0]), a[1].max(b[1])]
    });
    let mut checker = Checker::new(vertices, triangles, Some(swept), true);
    let mut flagged = checker.check_all(vertices);
    if flagged.is_empty() {
        return Some(0);
    }
    let mut level = vec![0u8; vertices.len()];
    let mut dirty = vec![false; triangles.len()];
    let mut moved: Vec<u32> = Vec::new();
    while !flagged.is_empty() {
        moved.clear();
        for &t in &flagged {
            moved.extend_from_slice(&triangles[t as usize]);
        }
        moved.sort_unstable();
        moved.dedup();
        moved.retain(|&v| level[v as usize] < UNTANGLE_STEPS);
        if moved.is_empty() {
            return None;
        }
        for &v in &moved {
            let l = &mut level[v as usize];
            *l += 1;
            let (s, m) = (safe[v as usize], target[v as usize]);
            vertices[v as usize] = if *l == UNTANGLE_STEPS {
                s
            } else {
                // Clamped so that rounding cannot leave the indexed (swept) boxes.
                (s + (m - s) * 0.5f32.powi(i32::from(*l))).clamp(s.min(m), s.max(m))
            };
        }
        flagged = checker.recheck(vertices, &moved, &mut dirty);
    }
    Some(level.iter().filter(|&&l| l > 0).count())
}

/// Steps from the moved position to the safe one in [`untangle`].
const UNTANGLE_STEPS: u8 = 4;

/// Spreads the low 21 bits of `x` to every third bit.
#[inline]
fn spread(x: u32) -> u64 {
    let mut x = u64::from(x) & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// The bits of one axis in a Morton code.
const DILATED: u64 = 0x1249_2492_4924_9249;

#[inline]
fn morton(c: [u32; 3]) -> u64 {
    spread(c[0]) | (spread(c[1]) << 1) | (spread(c[2]) << 2)
}

/// Grid cells per axis at most (Morton codes hold 21 bits per axis).
const MAX_CELLS: f32 = (1 << 20) as f32;
/// Cell edge in mean triangle extents (fewest candidate pairs on scanned meshes).
const CELL_FACTOR: f64 = 1.5;
/// Buckets per parallel task of the pair search (the result does not depend on it).
const BUCKETS_PER_TASK: usize = 4096;

/// The candidate-pair grid. Every indexed triangle has an entry in each cell its box meets,
/// with flags saying along which axes that cell is the triangle's first. Cells are hashed
/// into buckets by their Morton code (nearby cells, nearby buckets). Two boxes that overlap
/// have exactly one cell whose every coordinate is the first cell of one of them (the cell
/// of the overlap's minimum corner): the pair is tested only there, from the entries whose
/// flags together cover all three axes.
struct Index {
    origin: Vec3A,
    inv: f32,
    dims: [u32; 3],
    mask: u64,
    start: Vec<u32>,
    items: Vec<u32>,
    flags: Vec<u8>,
}

impl Index {
    /// Indexes the `boxes` of the triangles that `include` accepts.
    #[inline(never)]
    fn build(boxes: &[[Vec3A; 2]], include: impl Fn(usize) -> bool + Sync) -> Self {
        let mut lo = Vec3A::splat(f32::INFINITY);
        let mut hi = Vec3A::splat(f32::NEG_INFINITY);
        let mut sum = 0.0f64;
        let mut n = 0usize;
        for (t, b) in boxes.iter().enumerate() {
            if include(t) && b[0].is_finite() && b[1].is_finite() {
                lo = lo.min(b[0]);
                hi = hi.max(b[1]);
                sum += f64::from((b[1] - b[0]).max_element());
                n += 1;
            }
        }
        let mut index = Self {
            origin: Vec3A::ZERO,
            inv: 1.0,
            dims: [1; 3],
            mask: 0,
            start: vec![0, 0],
            items: Vec::new(),
            flags: Vec::new(),
        };
        if n == 0 {
            return index;
        }
        let extent = (hi - lo).max_element();
        let mut h = (CELL_FACTOR * sum / n as f64) as f32;
        if !(h.is_finite() && h > 0.0) || extent / h > MAX_CELLS - 2.0 {
            h = (extent / (MAX_CELLS - 2.0)).max(f32::MIN_POSITIVE);
        }
        index.origin = lo;
        index.inv = 1.0 / h;
        index.dims = ((hi - lo) * index.inv)
            .to_array()
            .map(|d| (d as u32).saturating_add(1).min(MAX_CELLS as u32));
        let ranges: Vec<[[u32; 3]; 2]> =
            crate::par::map(boxes, |b| [index.cell(b[0]), index.cell(b[1])]);
        let total: usize = ranges
            .iter()
            .enumerate()
            .filter(|&(t, _)| include(t))
            .map(|(_, r)| {
                (0..3)
                    .map(|i| (r[1][i] - r[0][i] + 1) as usize)
                    .product::<usize>()
            })
            .sum();
        let buckets = (total.next_power_of_two() / 2).max(1);
        index.mask = buckets as u64 - 1;
        let mask = index.mask;
        let mut start = vec![0u32; buckets + 1];
        for_each_cell(&ranges, &include, |_, m, _| {
            start[(m & mask) as usize + 1] += 1;
        });
        for i in 0..buckets {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; total];
        let mut flags = vec![0u8; total];
        for_each_cell(&ranges, &include, |t, m, f| {
            let b = (m & mask) as usize;
            let k = fill[b] as usize;
            items[k] = t;
            flags[k] = f;
            fill[b] += 1;
        });
        index.start = start;
        index.items = items;
        index.flags = flags;
        index
    }

    /// The grid cell of point `p` (clamped to the grid).
    #[inline]
    fn cell(&self, p: Vec3A) -> [u32; 3] {
        let g = (p - self.origin) * self.inv;
        [
            (g.x.max(0.0) as u32).min(self.dims[0] - 1),
            (g.y.max(0.0) as u32).min(self.dims[1] - 1),
            (g.z.max(0.0) as u32).min(self.dims[2] - 1),
        ]
    }

    /// Both triangles of every improper pair among the proper triangles whose current boxes
    /// overlap; with `dirty = (triangles, flags)`, only the pairs with a dirty member (the
    /// indexed boxes must contain the current ones).
    fn pairs(
        &self,
        ck: &Checker<'_>,
        vertices: &[Vec3],
        dirty: Option<(&[u32], &[bool])>,
    ) -> Vec<u32> {
        let visit: Vec<u32> = match dirty {
            None => Vec::new(),
            Some((tris, _)) => {
                // The buckets of the dirty triangles' indexed ranges: the cell where a pair
                // is tested lies in both triangles' indexed ranges.
                let indexed = ck.index_boxes.as_ref().unwrap_or(&ck.boxes);
                let mut v = Vec::new();
                for &t in tris {
                    let b = indexed[t as usize];
                    let (lo, hi) = (self.cell(b[0]), self.cell(b[1]));
                    for z in lo[2]..=hi[2] {
                        for y in lo[1]..=hi[1] {
                            for x in lo[0]..=hi[0] {
                                v.push((morton([x, y, z]) & self.mask) as u32);
                            }
                        }
                    }
                }
                v.sort_unstable();
                v.dedup();
                v
            }
        };
        let count = if dirty.is_some() {
            visit.len()
        } else {
            self.start.len() - 1
        };
        let one = |task: usize, out: &mut Vec<u32>| {
            let mut scratch = Scratch::default();
            let range = task * BUCKETS_PER_TASK..((task + 1) * BUCKETS_PER_TASK).min(count);
            let d = dirty.map(|d| d.1);
            if dirty.is_some() {
                for &b in &visit[range] {
                    self.bucket_pairs(ck, vertices, d, b as usize, &mut scratch, out);
                }
            } else {
                for b in range {
                    self.bucket_pairs(ck, vertices, d, b, &mut scratch, out);
                }
            }
        };
        let mut out = Vec::new();
        crate::par::extend_in_order(&mut out, count.div_ceil(BUCKETS_PER_TASK), 1, one);
        out
    }

    /// The improper pairs owned by the cells of bucket `b` (see [`Self::pairs`]).
    #[inline(never)]
    fn bucket_pairs(
        &self,
        ck: &Checker<'_>,
        vertices: &[Vec3],
        dirty: Option<&[bool]>,
        b: usize,
        scratch: &mut Scratch,
        out: &mut Vec<u32>,
    ) {
        let (s, e) = (self.start[b] as usize, self.start[b + 1] as usize);
        if e - s < 2 {
            return;
        }
        let (items, flags) = (&self.items[s..e], &self.flags[s..e]);
        let is_dirty = |t: u32| dirty.is_none_or(|d| d[t as usize]);
        let test = |ti: u32, tj: u32, out: &mut Vec<u32>| {
            if ti == tj || !(is_dirty(ti) || is_dirty(tj)) {
                return;
            }
            let (a, c) = (ck.triangles[ti as usize], ck.triangles[tj as usize]);
            let a = Tri {
                idx: a,
                k: ck.facts[ti as usize].0 as usize,
                v: vertices,
            };
            let c = Tri {
                idx: c,
                k: ck.facts[tj as usize].0 as usize,
                v: vertices,
            };
            if improper(a, c) {
                out.push(ti);
                out.push(tj);
            }
        };
        let overlap = |p: &[Vec3A; 2], q: &[Vec3A; 2]| (p[0].cmple(q[1]) & q[0].cmple(p[1])).all();
        // The bucket's proper entries, their flags and boxes together, 64 at a time; `has[r]`:
        // the entries of a block whose flags include the axes `r`.
        // `cv`: the triangle's certified vertices (others `u32::MAX`): a pair that shares one
        // needs no test.
        let Scratch { id, fl, bx, cv } = scratch;
        let mut n = 0;
        for (&t, &f) in items.iter().zip(flags) {
            if ck.facts[t as usize].0 != NO_AXIS {
                if n == id.len() {
                    id.resize(n + BLOCK, 0);
                    fl.resize(n + BLOCK, 0);
                    bx.resize(n + BLOCK, [Vec3A::ZERO; 2]);
                    cv.resize(n + BLOCK, [0; 3]);
                }
                id[n] = t;
                fl[n] = f;
                bx[n] = ck.boxes[t as usize];
                cv[n] = ck.triangles[t as usize].map(|v| {
                    if ck.cert.get(v as usize).copied().unwrap_or(false) {
                        v
                    } else {
                        u32::MAX
                    }
                });
                n += 1;
            }
        }
        let (id, fl, bx, cv) = (&id[..n], &fl[..n], &bx[..n], &cv[..n]);
        for base in (0..n).step_by(BLOCK) {
            let end = (base + BLOCK).min(n);
            // By exact flags, then (summing over supersets) by included axes.
            let mut has = [0u64; 8];
            for (k, &f) in fl[base..end].iter().enumerate() {
                has[usize::from(f & 7)] |= 1 << k;
            }
            for bit in [1, 2, 4] {
                for r in 0..8 {
                    if r & bit == 0 {
                        has[r] |= has[r | bit];
                    }
                }
            }
            let block = &bx[base..end];
            for (x, (bxx, &fx)) in bx[..end].iter().zip(&fl[..end]).enumerate() {
                // Partners in this block that come after x.
                let mut m = has[usize::from(7 & !fx)];
                if x >= base {
                    m &= (!0u64 << (x - base)) << 1;
                }
                while m != 0 {
                    let y = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if let Some(by) = block.get(y)
                        && overlap(bxx, by)
                        && !shares_certified(cv[x], cv[base + y])
                    {
                        test(id[x], id[base + y], out);
                    }
                }
            }
        }
    }
}

/// Entries per block of the pair loop (one bit each in a `u64`).
const BLOCK: usize = 64;

/// Reused buffers of [`Index::bucket_pairs`].
#[derive(Default)]
struct Scratch {
    id: Vec<u32>,
    fl: Vec<u8>,
    bx: Vec<[Vec3A; 2]>,
    cv: Vec<[u32; 3]>,
}

/// Morton codes of the cells of every included triangle's range, with the triangle and the
/// cell's flags (bit `k`: the cell is the range's first along axis `k`).
#[inline(never)]
fn for_each_cell(
    ranges: &[[[u32; 3]; 2]],
    include: impl Fn(usize) -> bool,
    mut f: impl FnMut(u32, u64, u8),
) {
    for (t, r) in ranges.iter().enumerate() {
        if !include(t) {
            continue;
        }
        // Morton codes stepped in place: adding one to the bits of one axis.
        let step = |d: u64, axis: u32| {
            let m = DILATED << axis;
            ((d | !m).wrapping_add(1 << axis)) & m
        };
        let mut mz = spread(r[0][2]) << 2;
        let mut fz = 4u8;
        let mut z = r[0][2];
        loop {
            let mut my = spread(r[0][1]) << 1;
            let mut fy = fz | 2;
            let mut y = r[0][1];
            loop {
                let mut mx = spread(r[0][0]);
                let mut fx = fy | 1;
                let mut x = r[0][0];
                loop {
                    f(t as u32, mz | my | mx, fx);
                    if x >= r[1][0] {
                        break;
                    }
                    x += 1;
                    mx = step(mx, 0);
                    fx = fy;
                }
                if y >= r[1][1] {
                    break;
                }
                y += 1;
                my = step(my, 1);
                fy = fz;
            }
            if z >= r[1][2] {
                break;
            }
            z += 1;
            mz = step(mz, 2);
            fz = 0;
        }
    }
}

/// Whether two triangles given by their certified vertices (others `u32::MAX`) share one:
/// a vertex whose fan is [`certified`].
#[inline]
fn shares_certified(a: [u32; 3], b: [u32; 3]) -> bool {
    a.iter().any(|&v| v != u32::MAX && b.contains(&v))
}
