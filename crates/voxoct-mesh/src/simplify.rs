//! Quadric-error edge collapse (Garland–Heckbert) that keeps the mesh a closed, oriented,
//! embedded 2-manifold.
//!
//! # Error measure
//! Every original triangle contributes its plane, weighted by a third of its area, to each of
//! its three vertices' quadrics; a collapse adds the two quadrics. The *error* of a vertex at
//! `p` is `sqrt(Q(p) / W)`: the area-weighted root-mean-square distance, in metres, from `p`
//! to the planes of the original triangles that were merged into it (`W` is their weight).
//! A collapse is made only while that error is at most [`Simplify::max_error`]. The new
//! vertex goes to the quadric's minimum, regularised towards the edge's midpoint along the
//! directions the quadric leaves free (flat or cylindrical patches), so vertices never
//! slide along the surface.
//!
//! Because the bound is a mean over the merged patch, a vertex may sit further than
//! `max_error` from the original surface where the patch is curved or cornered; the tests
//! check every vertex within three times the bound (and on a 30 mm sphere at 1 mm leaves,
//! `for_leaf` keeps the mean vertex 0.22 leaf, the worst 0.37 leaf from the sphere).
//!
//! # Guarantees (for a closed, oriented 2-manifold input, as [`crate::mesh_cells`] gives)
//! - **Link condition**: an edge `u w` collapses only if `u` and `w` have exactly two common
//!   neighbours (the apexes of its two triangles) and are not both of valence 3 (a
//!   tetrahedron), so the result stays a closed 2-manifold with the same pieces and genus.
//!   [`Mesh::check_closed_manifold`] is run on the result as a safety net: a failure (never
//!   seen) leaves the input unchanged.
//! - **No flips, no needles**: every triangle changed by a collapse keeps its normal within
//!   [`MAX_NORMAL_TURN_DEG`] of its direction before; within 60° of the mean normal of the
//!   fan it replaces; within 60° of the summed original normals of the clusters at its
//!   corners (so turns cannot add up over many collapses); and its shape quality
//!   (`4√3·area / Σ edge²`, 1 for an equilateral) does not fall below [`MIN_QUALITY`] unless
//!   it was already that low, and never below [`MIN_QUALITY_ABSOLUTE`].
//! - **No self-intersections introduced**: each collapse tests the new fan exactly against
//!   the other triangles around its outer vertices (the local folds). Then one exact test
//!   over all pairs of nearby triangles (a uniform grid; `f64` orientation tests) looks for
//!   intersecting pairs with a changed triangle, which only distant sheets (thin walls) or
//!   a crumpled input can give. If there are any, the original vertices merged into those
//!   triangles and their neighbours are frozen and the simplification is run again from the
//!   input; after [`MAX_RETRIES`] rounds the input is left unchanged. Intersections the
//!   input already had are left as they are (their triangles do not count as changed).
//!
//! # Speed
//! Collapses are made in passes (as meshoptimizer does): each pass evaluates the collapse
//! cost of every edge whose neighbourhood changed (in parallel with the `parallel`
//! feature), orders the edges by cost with a counting sort on the float's exponent bits
//! (coarse classes keep memory access local), and collapses greedily in that order, at most
//! one collapse per vertex per pass; vertex→triangle adjacency is a flat CSR rebuilt per
//! pass. No hash map, no heap. A marched, smoothed input that already intersects itself
//! in a few places takes two rounds. Figures: see BENCHMARKS.md (`cargo bench -p
//! voxoct-mesh`).

use voxoct_core::glam::{DVec3, Vec3};

use crate::fans::VertexFans;
use crate::mesh::{Mesh, TopologyError};
use crate::par;

/// Largest turn of a surviving triangle's normal in one collapse, degrees.
pub const MAX_NORMAL_TURN_DEG: f32 = 75.0;
/// Triangle quality (`4√3·area / Σ edge²`) below which a collapse may not push a triangle,
/// unless the triangle was already worse.
pub const MIN_QUALITY: f32 = 0.1;
/// Quality below which no collapse may ever push a triangle (far above the degeneracy
/// threshold of [`Mesh::check_closed_manifold`]).
pub const MIN_QUALITY_ABSOLUTE: f32 = 1.0e-3;
/// Rounds of freezing and re-running when the global self-intersection test fails.
pub const MAX_RETRIES: u32 = 4;

/// Options of [`simplify`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Simplify {
    /// Largest error of a collapse, metres: the area-weighted root-mean-square distance from
    /// the new vertex to the planes of the original triangles merged into it. 0 collapses
    /// only edges of flat patches.
    pub max_error: f32,
    /// Stop once the mesh has at most this many triangles (`None`: as few as `max_error`
    /// allows). The error bound holds either way.
    pub target_triangles: Option<usize>,
}

impl Simplify {
    /// Default error bound as a fraction of the leaf edge.
    ///
    /// A quarter of a leaf: the marked-cell surface cannot place detail more finely than
    /// about half a leaf, and a Kinect v1's depth noise (≈ 1.5 mm at 0.7 m) is larger
    /// than a 1 mm leaf, so a deviation of a quarter leaf (RMS over the merged patch) removes
    /// no detail the data holds.
    pub const LEAF_FRACTION: f32 = 0.25;

    /// The default options for meshes of leaves of edge `leaf` metres:
    /// `max_error = LEAF_FRACTION · leaf`, no triangle target.
    #[must_use]
    pub fn for_leaf(leaf: f32) -> Self {
        Self {
            max_error: Self::LEAF_FRACTION * leaf,
            target_triangles: None,
        }
    }
}

/// What [`simplify`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimplifyStats {
    /// Triangles before.
    pub triangles_before: usize,
    /// Triangles after.
    pub triangles_after: usize,
    /// Edge collapses made (in the final round).
    pub collapses: usize,
    /// Collapse passes (in the final round).
    pub passes: usize,
    /// Rounds re-run because the global self-intersection test found new intersections.
    pub retries: u32,
    /// Original vertices frozen by those rounds.
    pub frozen_vertices: usize,
    /// Intersecting triangle pairs that involve a changed triangle, found by the last
    /// global test (0 unless the input was left unchanged after [`MAX_RETRIES`] rounds).
    pub new_intersections: usize,
    /// Why the mesh was left unchanged: an index out of range, or the result is not a closed
    /// manifold (the input was not one; for a closed input this never happens, it is a
    /// safety net). `None` when simplified, and also when left unchanged because of invalid
    /// options or [`MAX_RETRIES`].
    pub skipped: Option<TopologyError>,
}

/// Simplifies a closed, oriented 2-manifold mesh in place by quadric-error edge collapse
/// (see the module docs for the error measure and the guarantees).
///
/// A mesh whose result fails [`Mesh::check_closed_manifold`] (as one that is not a closed
/// manifold to begin with may) is left unchanged, the error in [`SimplifyStats::skipped`];
/// so is any mesh when `max_error` is negative or not finite.
/// Otherwise the vertices are renumbered in the order the triangles first use them (also
/// when no collapse could be made); triangles keep their relative order.
pub fn simplify(mesh: &mut Mesh, opts: &Simplify) -> SimplifyStats {
    let mut stats = SimplifyStats {
        triangles_before: mesh.triangles.len(),
        triangles_after: mesh.triangles.len(),
        ..SimplifyStats::default()
    };
    if !(opts.max_error.is_finite() && opts.max_error >= 0.0) {
        return stats;
    }
    // Indices in range are all the collapses need to run; whether the input is a closed
    // manifold is decided by the check of the result, which leaves the input unchanged when
    // it fails (the full check of a large input would cost a sixth of the time).
    let nv = mesh.vertices.len();
    if let Some((i, &k)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find_map(|(i, t)| t.iter().find(|&&k| k as usize >= nv).map(|k| (i, k)))
    {
        stats.skipped = Some(TopologyError::IndexOutOfRange {
            triangle: i,
            index: k,
        });
        return stats;
    }
    if opts
        .target_triangles
        .is_some_and(|t| t >= mesh.triangles.len())
    {
        return stats;
    }
    let mut frozen = vec![false; nv];
    let original = renumbered_by_first_use(mesh);
    let quadrics = initial_quadrics(&original);
    loop {
        let mut work = Collapser::new(&original, &quadrics, &frozen, opts);
        work.run();
        let (passes, collapses) = (work.passes, work.collapses);
        let Collapser {
            pos,
            tris,
            parent,
            moved,
            ..
        } = work;
        let candidate = Mesh {
            vertices: pos,
            triangles: tris,
        };
        let bad = if collapses == 0 {
            Vec::new()
        } else {
            new_intersections(&candidate, &moved)
        };
        stats.new_intersections = bad.len();
        if bad.is_empty() {
            let mut candidate = candidate;
            candidate.remove_unused_vertices();
            // The collapses keep the mesh closed by construction; this check (a few per cent
            // of the time) makes sure that no rounding breaks the promise.
            if let Err(e) = candidate.check_closed_manifold() {
                stats.skipped = Some(e);
                return stats;
            }
            *mesh = candidate;
            stats.triangles_after = mesh.triangles.len();
            stats.passes = passes;
            stats.collapses = collapses;
            return stats;
        }
        if stats.retries == MAX_RETRIES {
            *mesh = original;
            stats.triangles_after = mesh.triangles.len();
            return stats;
        }
        stats.retries += 1;
        // Freeze every original vertex merged into a vertex of an intersecting triangle or
        // into one of their neighbours.
        let mut hit = vec![false; nv];
        for &t in &bad {
            for k in candidate.triangles[t as usize] {
                hit[k as usize] = true;
            }
        }
        let mut near = hit.clone();
        for t in &candidate.triangles {
            if t.iter().any(|&k| hit[k as usize]) {
                for &k in t {
                    near[k as usize] = true;
                }
            }
        }
        let hit = near;
        for (v, f) in frozen.iter_mut().enumerate() {
            let mut r = v;
            while parent[r] as usize != r {
                r = parent[r] as usize;
            }
            if hit[r] && !*f {
                *f = true;
                stats.frozen_vertices += 1;
            }
        }
    }
}

/// `mesh` with its vertices numbered in the order the triangles first use them, so that
/// walking the triangles in order touches vertex data in order (the marcher numbers
/// vertices by grid edge, far from its triangle order: this halves the time).
fn renumbered_by_first_use(mesh: &Mesh) -> Mesh {
    let mut map = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::with_capacity(mesh.vertices.len());
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let mut out = [0u32; 3];
        for (o, &k) in out.iter_mut().zip(t) {
            let m = &mut map[k as usize];
            if *m == u32::MAX {
                *m = vertices.len() as u32;
                vertices.push(mesh.vertices[k as usize]);
            }
            *o = *m;
        }
        triangles.push(out);
    }
    Mesh {
        vertices,
        triangles,
    }
}

/// A symmetric 4×4 quadric (upper triangle, row by row) and its weight.
#[derive(Debug, Clone, Copy, Default)]
struct Quadric {
    q: [f64; 10],
    w: f64,
}

impl Quadric {
    /// `w · (n·x + d)²` for the plane with unit normal `n`.
    fn plane(n: DVec3, d: f64, w: f64) -> Self {
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

    fn add(&mut self, o: &Self) {
        for (a, b) in self.q.iter_mut().zip(&o.q) {
            *a += b;
        }
        self.w += o.w;
    }

    fn sum(a: &Self, b: &Self) -> Self {
        let mut s = *a;
        s.add(b);
        s
    }

    /// `Q(p)`: the weighted sum of squared plane distances.
    fn eval(&self, p: DVec3) -> f64 {
        let q = &self.q;
        let (x, y, z) = (p.x, p.y, p.z);
        x * (q[0] * x + 2.0 * (q[1] * y + q[2] * z + q[3]))
            + y * (q[4] * y + 2.0 * (q[5] * z + q[6]))
            + z * (q[7] * z + 2.0 * q[8])
            + q[9]
    }

    /// Mean squared distance at `p` (the error² of the module docs).
    fn mean_sq(&self, p: DVec3) -> f64 {
        if self.w > 0.0 {
            (self.eval(p) / self.w).max(0.0)
        } else {
            0.0
        }
    }

    /// The minimum of `Q`, regularised towards `m`: solves `(A + λI) x = λm − b` with
    /// `λ = RIDGE · trace(A)`; `None` if singular.
    fn minimum(&self, m: DVec3) -> Option<DVec3> {
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

/// Smallest cosine between a new triangle's normal and the old fan's mean normal.
const FAN_COS_MIN: f32 = 0.5;

/// Ridge of [`Quadric::minimum`] relative to the quadric's trace.
const RIDGE: f64 = 1e-3;

/// Per-vertex quadrics of `mesh` (in coordinates relative to its first vertex) and
/// area-weighted normals.
fn initial_quadrics(mesh: &Mesh) -> Vec<(Quadric, Vec3)> {
    let o = origin(mesh);
    let planes: Vec<Quadric> = {
        let mut v = Vec::new();
        par::map_into(&mut v, mesh.triangles.len(), |i| {
            let [a, b, c] = mesh.triangles[i].map(|k| mesh.vertices[k as usize].as_dvec3() - o);
            let n = (b - a).cross(c - a);
            let len = n.length();
            if len > 0.0 {
                let n = n / len;
                Quadric::plane(n, -n.dot(a), len / 6.0)
            } else {
                Quadric::default()
            }
        });
        v
    };
    let csr = VertexFans::new(mesh.vertices.len(), &mesh.triangles, |_| true, false);
    let mut out = Vec::new();
    par::map_into(&mut out, mesh.vertices.len(), |v| {
        let mut q = Quadric::default();
        let mut n = Vec3::ZERO;
        for &t in csr.fan(v as u32) {
            q.add(&planes[t as usize]);
            let [a, b, c] = mesh.triangles[t as usize].map(|k| mesh.vertices[k as usize]);
            n += (b - a).cross(c - a);
        }
        (q, n)
    });
    out
}

/// The origin of the quadrics' coordinates.
fn origin(mesh: &Mesh) -> DVec3 {
    mesh.vertices.first().map_or(DVec3::ZERO, |p| p.as_dvec3())
}

/// One candidate collapse of a pass.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// Sort key: the error²'s float bits.
    key: u32,
    u: u32,
    w: u32,
    p: Vec3,
}

/// Bits dropped from the sort key by the counting sort: classes of a factor 256 in error²
/// (16 in error). Coarse classes are visited in memory order, which is faster by a third
/// than finer ones (cache misses) and changes the result by well under 1 %.
const KEY_SHIFT: u32 = 26;

/// The state of one simplification round.
struct Collapser<'a> {
    pos: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
    quad: Vec<Quadric>,
    /// Area-weighted normal of the original triangles merged into each vertex.
    nrm: Vec<Vec3>,
    /// `parent[v] == v` for a live vertex, else the vertex it collapsed into.
    parent: Vec<u32>,
    /// Whether the vertex survived a collapse (its position and fan changed).
    moved: Vec<bool>,
    frozen: &'a [bool],
    locked: Vec<bool>,
    /// Vertices whose edges are evaluated this pass: all in the first, then those whose
    /// neighbourhood changed in the last pass or whose edge was skipped for a lock.
    active: Vec<bool>,
    next_active: Vec<bool>,
    csr: VertexFans,
    origin: DVec3,
    max_sq: f64,
    target: usize,
    passes: usize,
    collapses: usize,
    ring_u: Vec<u32>,
    ring_w: Vec<u32>,
    normals: Vec<(Vec3, u32, u32)>,
}

impl<'a> Collapser<'a> {
    fn new(mesh: &Mesh, quadrics: &[(Quadric, Vec3)], frozen: &'a [bool], opts: &Simplify) -> Self {
        let nv = mesh.vertices.len();
        Self {
            pos: mesh.vertices.clone(),
            tris: mesh.triangles.clone(),
            quad: quadrics.iter().map(|q| q.0).collect(),
            nrm: quadrics.iter().map(|q| q.1).collect(),
            parent: (0..nv as u32).collect(),
            moved: vec![false; nv],
            frozen,
            locked: vec![false; nv],
            active: vec![true; nv],
            next_active: vec![false; nv],
            csr: VertexFans::default(),
            origin: origin(mesh),
            max_sq: f64::from(opts.max_error) * f64::from(opts.max_error),
            target: opts.target_triangles.unwrap_or(0),
            passes: 0,
            collapses: 0,
            ring_u: Vec::new(),
            ring_w: Vec::new(),
            normals: Vec::new(),
        }
    }

    fn run(&mut self) {
        let mut cands = Vec::new();
        let mut sorted = Vec::new();
        while self.tris.len() > self.target {
            self.passes += 1;
            self.csr.rebuild(self.pos.len(), &self.tris, |_| true, true);
            self.candidates(&mut cands);
            counting_sort(&cands, &mut sorted);
            let made = self.collapse_pass(&sorted);
            if made == 0 {
                break;
            }
            std::mem::swap(&mut self.active, &mut self.next_active);
            self.next_active.iter_mut().for_each(|a| *a = false);
            self.collapses += made;
            self.tris
                .retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        }
    }

    /// Every edge's best collapse within the error bound.
    fn candidates(&self, out: &mut Vec<Candidate>) {
        out.clear();
        let tris = &self.tris;
        par::extend_in_order(out, tris.len(), 4096, |i, out| {
            let t = tris[i];
            for k in 0..3 {
                let (u, w) = (t[k], t[(k + 1) % 3]);
                if u < w
                    && (self.active[u as usize] || self.active[w as usize])
                    && !self.frozen[u as usize]
                    && !self.frozen[w as usize]
                    && let Some(c) = self.cost(u, w)
                {
                    out.push(c);
                }
            }
        });
    }

    /// The collapse of edge `u w`: position and error², if within the bound.
    fn cost(&self, u: u32, w: u32) -> Option<Candidate> {
        let q = Quadric::sum(&self.quad[u as usize], &self.quad[w as usize]);
        let pu = self.pos[u as usize].as_dvec3() - self.origin;
        let pw = self.pos[w as usize].as_dvec3() - self.origin;
        let m = 0.5 * (pu + pw);
        let reach_sq = (pu - pw).length_squared();
        let mut best = q
            .minimum(m)
            .filter(|x| (*x - m).length_squared() <= reach_sq);
        let mut err = best.map_or(f64::INFINITY, |x| q.mean_sq(x));
        if best.is_none() {
            for x in [m, pu, pw] {
                let e = q.mean_sq(x);
                if e < err {
                    (best, err) = (Some(x), e);
                }
            }
        }
        let x = best?;
        (err <= self.max_sq).then(|| Candidate {
            key: (err as f32).to_bits(),
            u,
            w,
            p: (x + self.origin).as_vec3(),
        })
    }

    /// Collapses greedily in the given order; returns the number made.
    fn collapse_pass(&mut self, sorted: &[Candidate]) -> usize {
        self.locked.iter_mut().for_each(|l| *l = false);
        let mut made = 0;
        let mut live = self.tris.len();
        for c in sorted {
            if live <= self.target {
                break;
            }
            if self.locked[c.u as usize] || self.locked[c.w as usize] {
                self.next_active[c.u as usize] = true;
                self.next_active[c.w as usize] = true;
                continue;
            }
            if !self.allowed(c.u, c.w, c.p) {
                continue;
            }
            let (u, w) = (c.u as usize, c.w as usize);
            self.parent[u] = c.w;
            for i in self.csr.start[u]..self.csr.start[u + 1] {
                let t = &mut self.tris[self.csr.tris[i as usize] as usize];
                for k in t.iter_mut() {
                    if *k == c.u {
                        *k = c.w;
                    }
                }
            }
            // The fans of u's neighbours (and w's own) now see w where they saw u; the
            // collapsed edge's two triangles become degenerate there and are skipped.
            for &x in &self.ring_u {
                for i in self.csr.range(x) {
                    for k in &mut self.csr.pairs[i] {
                        if *k == c.u {
                            *k = c.w;
                        }
                    }
                }
            }
            self.pos[w] = c.p;
            let qu = self.quad[u];
            self.quad[w].add(&qu);
            let nu = self.nrm[u];
            self.nrm[w] += nu;
            self.locked[u] = true;
            self.locked[w] = true;
            self.next_active[w] = true;
            for &x in self.ring_u.iter().chain(&self.ring_w) {
                self.next_active[x as usize] = true;
            }
            self.moved[w] = true;
            made += 1;
            live -= 2;
        }
        made
    }

    /// The live corners of `v`: (next, previous) of each triangle of `v` that no collapse
    /// of this pass removed.
    #[inline]
    fn live_corners(&self, v: u32) -> impl Iterator<Item = [u32; 2]> + '_ {
        self.csr
            .corners(v)
            .iter()
            .copied()
            .filter(move |&[n, p]| n != p && n != v && p != v)
    }

    /// Whether collapsing `u w` to `p` keeps the guarantees (link condition, normals,
    /// quality).
    fn allowed(&mut self, u: u32, w: u32, p: Vec3) -> bool {
        let mut ring_u = std::mem::take(&mut self.ring_u);
        let mut ring_w = std::mem::take(&mut self.ring_w);
        let mut normals = std::mem::take(&mut self.normals);
        normals.clear();
        let mut old_sum = Vec3::ZERO;
        let ok = self.ring(u, &mut ring_u)
            && self.ring(w, &mut ring_w)
            && link_condition(w, &ring_u, &ring_w)
            && self.shapes_ok(u, w, p, &mut normals, &mut old_sum)
            && self.shapes_ok(w, u, p, &mut normals, &mut old_sum)
            && {
                // The new fan stays on the side the old one faced (no fold within the fan).
                let len = old_sum.length();
                let mut flat = true;
                let ok = normals.iter().all(|n| {
                    let (d, l) = (n.0.dot(old_sum), len * n.0.length());
                    flat &= d > FLAT_COS * l;
                    d > FAN_COS_MIN * l
                });
                // A nearly flat new fan cannot fold onto its neighbours unless they were
                // already folded; the global test catches what this skips.
                ok && (flat || self.no_local_folds(u, w, p, &normals))
            };
        self.ring_u = ring_u;
        self.ring_w = ring_w;
        self.normals = normals;
        ok
    }

    /// The neighbours of `v` (each once on a closed manifold); false if unusually many.
    fn ring(&self, v: u32, out: &mut Vec<u32>) -> bool {
        out.clear();
        out.extend(self.live_corners(v).map(|[n, _]| n));
        out.len() >= 3
    }

    /// Whether moving `v` to `p` keeps the normal and quality of every triangle of `v` that
    /// does not also hold `other`.
    fn shapes_ok(
        &self,
        v: u32,
        other: u32,
        p: Vec3,
        normals: &mut Vec<(Vec3, u32, u32)>,
        old_sum: &mut Vec3,
    ) -> bool {
        let cos_min = MAX_NORMAL_TURN_DEG.to_radians().cos();
        for [bi, ci] in self.live_corners(v) {
            if bi == other || ci == other {
                continue;
            }
            let b = self.pos[bi as usize];
            let c = self.pos[ci as usize];
            let a = self.pos[v as usize];
            let n_old = (b - a).cross(c - a);
            let n_new = (b - p).cross(c - p);
            let (lo, ln) = (n_old.length(), n_new.length());
            // Never against the original surface: the new triangle faces the way the
            // original triangles merged into its corners face on the whole.
            let reference = self.nrm[v as usize]
                + self.nrm[other as usize]
                + self.nrm[bi as usize]
                + self.nrm[ci as usize];
            if !greater(
                n_new.dot(reference),
                REFERENCE_COS_MIN * ln * reference.length(),
            ) {
                return false;
            }
            *old_sum += n_old;
            normals.push((n_new, bi, ci));
            if !greater(n_old.dot(n_new), cos_min * lo * ln) {
                return false;
            }
            let q_new = quality(ln, p, b, c);
            if q_new < MIN_QUALITY_ABSOLUTE || (q_new < MIN_QUALITY && q_new < quality(lo, a, b, c))
            {
                return false;
            }
        }
        true
    }
}

impl Collapser<'_> {
    /// Whether the new fan (`p` with the given outer edges and normals) stays clear of the
    /// other triangles around its outer vertices: every such pair facing away from each
    /// other is tested exactly (pairs sharing an outer edge must not fold flat).
    fn no_local_folds(&self, u: u32, w: u32, p: Vec3, fan: &[(Vec3, u32, u32)]) -> bool {
        let pd = p.as_dvec3();
        let at = |k: u32| self.pos[k as usize].as_dvec3();
        // Each outer vertex once (as the first vertex of its outgoing outer edge).
        for &(_, x, _) in fan {
            for [n, q] in self.live_corners(x) {
                let tt = [x, n, q];
                if tt.contains(&u) || tt.contains(&w) {
                    continue;
                }
                let [a0, a1, a2] = tt.map(|k| self.pos[k as usize]);
                let nt = (a1 - a0).cross(a2 - a0);
                for &(nn, b, c) in fan {
                    if b != x && c != x || nn.dot(nt) >= 0.0 {
                        continue;
                    }
                    let shared_edge = tt.contains(&b) && tt.contains(&c);
                    if shared_edge {
                        if nn.dot(nt) < -FOLD_COS * nn.length() * nt.length() {
                            return false;
                        }
                        continue;
                    }
                    let tri_new = [pd, at(b), at(c)];
                    let tri_old = tt.map(at);
                    let kx = tt.iter().position(|&k| k == x).unwrap_or(0);
                    let (o1, o2) = (tri_old[(kx + 1) % 3], tri_old[(kx + 2) % 3]);
                    let (n1, n2) = if b == x { (pd, at(c)) } else { (pd, at(b)) };
                    if crate::collide::segment_triangle(o1, o2, tri_new)
                        || crate::collide::segment_triangle(n1, n2, tri_old)
                    {
                        return false;
                    }
                }
            }
        }
        true
    }
}

/// Cosine (≈ 20°) above which every new triangle of a fan counts as flat with the old fan,
/// so the fold test against the neighbours is skipped.
const FLAT_COS: f32 = 0.94;

/// Smallest cosine between a new triangle's normal and the summed original normals of
/// the clusters at its corners.
const REFERENCE_COS_MIN: f32 = 0.5;

/// Cosine beyond which two triangles sharing an edge count as folded flat onto each other.
const FOLD_COS: f32 = 0.95;

/// `a > b`, false when either is NaN (so a NaN never passes a check).
#[inline]
fn greater<T: PartialOrd>(a: T, b: T) -> bool {
    a > b
}

/// `4√3·area / Σ edge²` with `cross_len = 2·area`.
#[inline]
fn quality(cross_len: f32, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let s = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if s > 0.0 {
        2.0 * 3f32.sqrt() * cross_len / s
    } else {
        0.0
    }
}

/// The link condition for a closed manifold: `u` and `w` share exactly two neighbours, and
/// are not both of valence 3 (a tetrahedron would fold onto itself).
fn link_condition(w: u32, ring_u: &[u32], ring_w: &[u32]) -> bool {
    if ring_u.len() == 3 && ring_w.len() == 3 {
        return false;
    }
    let mut common = 0;
    for &x in ring_u {
        if x != w && ring_w.contains(&x) {
            common += 1;
        }
    }
    common == 2
}

/// Orders candidates by the leading bits of their key (a counting sort: stable, linear).
fn counting_sort(cands: &[Candidate], out: &mut Vec<Candidate>) {
    const BUCKETS: usize = 1 << (32 - KEY_SHIFT - 1);
    let mut count = [0u32; BUCKETS + 1];
    for c in cands {
        count[(c.key >> KEY_SHIFT) as usize + 1] += 1;
    }
    for i in 0..BUCKETS {
        count[i + 1] += count[i];
    }
    out.clear();
    out.resize(
        cands.len(),
        Candidate {
            key: 0,
            u: 0,
            w: 0,
            p: Vec3::ZERO,
        },
    );
    for c in cands {
        let slot = &mut count[(c.key >> KEY_SHIFT) as usize];
        out[*slot as usize] = *c;
        *slot += 1;
    }
}

/// The changed triangles (with a moved vertex) that cut through another triangle, by the
/// exact check ([`crate::selfx`]), in increasing order. Every new intersection involves a
/// changed triangle; intersections between unchanged ones were in the input.
fn new_intersections(mesh: &Mesh, moved: &[bool]) -> Vec<u32> {
    let changed = |t: u32| {
        mesh.triangles[t as usize]
            .iter()
            .any(|&k| moved[k as usize])
    };
    let mut out = crate::selfx::self_intersecting_triangles(mesh);
    out.retain(|&t| changed(t));
    out
}
