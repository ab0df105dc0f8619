//! One round of collapses: candidates per pass, their order, and the checks that keep the
//! mesh a closed, embedded manifold.

use voxoct_core::glam::{DVec3, Vec3};

use super::*;
use crate::fans::VertexFans;
use crate::par;

/// Smallest cosine between a new triangle's normal and the old fan's mean normal.
pub(super) const FAN_COS_MIN: f32 = 0.5;

/// One candidate collapse of a pass.
#[derive(Debug, Clone, Copy)]
pub(super) struct Candidate {
    /// Sort key: the error²'s float bits.
    pub(super) key: u32,
    pub(super) u: u32,
    pub(super) w: u32,
    pub(super) p: Vec3,
}

/// Below one active vertex per this many triangles, [`Collapser::candidates`] finds the
/// triangles to look at from the active vertices' fans (about six each) instead of looking
/// at every triangle.
const FEW_ACTIVE: usize = 24;

/// Bits dropped from the sort key by the counting sort: classes of a factor 256 in error²
/// (16 in error). Coarse classes are visited in memory order, which is faster by a third
/// than finer ones (cache misses) and changes the result by well under 1 %.
pub(super) const KEY_SHIFT: u32 = 26;

/// The state of one simplification round.
pub(super) struct Collapser {
    pub(super) pos: Vec<Vec3>,
    pub(super) tris: Vec<[u32; 3]>,
    /// A caller's number for each of `tris`, kept in step with them (empty: none).
    pub(super) ids: Vec<u32>,
    pub(super) quad: Vec<Quadric>,
    /// Area-weighted normal of the original triangles merged into each vertex.
    pub(super) nrm: Vec<Vec3>,
    /// `parent[v] == v` for a live vertex, else the vertex it collapsed into.
    pub(super) parent: Vec<u32>,
    /// Whether the vertex survived a collapse (its position and fan changed).
    pub(super) moved: Vec<bool>,
    /// Vertices that must not move (no collapse has them as an end).
    pub(super) frozen: Vec<bool>,
    pub(super) locked: Vec<bool>,
    /// Vertices whose edges are evaluated this pass: all in the first, then those whose
    /// neighbourhood changed in the last pass or whose edge was skipped for a lock.
    pub(super) active: Vec<bool>,
    pub(super) next_active: Vec<bool>,
    pub(super) csr: VertexFans,
    pub(super) origin: DVec3,
    pub(super) max_sq: f64,
    pub(super) target: usize,
    pub(super) passes: usize,
    pub(super) collapses: usize,
    /// Every collapse made, `(u, w)` in order, and where each pass's collapses end: a
    /// later round replays them ([`Collapser::replay`]).
    pub(super) log: Vec<(u32, u32)>,
    pub(super) pass_ends: Vec<usize>,
    pub(super) ring_u: Vec<u32>,
    pub(super) ring_w: Vec<u32>,
    pub(super) fan: Vec<FanTriangle>,
    /// Whether to evaluate the candidates in one task (a region among others).
    pub(super) one_task: bool,
    /// Stamps of [`Collapser::link_condition`] (one per vertex) and the latest.
    mark: Vec<u32>,
    stamp: u32,
}

impl Collapser {
    /// The state before any collapse of `mesh` (numbered by first use), whose quadrics (in
    /// coordinates relative to `origin`) and normals are given.
    pub(super) fn new(
        mesh: Mesh,
        (quad, nrm): (Vec<Quadric>, Vec<Vec3>),
        frozen: Vec<bool>,
        opts: &Simplify,
        origin: DVec3,
    ) -> Self {
        let nv = mesh.vertices.len();
        Self {
            pos: mesh.vertices,
            tris: mesh.triangles,
            ids: Vec::new(),
            quad,
            nrm,
            parent: (0..nv as u32).collect(),
            moved: vec![false; nv],
            frozen,
            locked: vec![false; nv],
            active: vec![true; nv],
            next_active: vec![false; nv],
            csr: VertexFans::default(),
            origin,
            max_sq: f64::from(opts.max_error) * f64::from(opts.max_error),
            target: opts.target_triangles.unwrap_or(0),
            passes: 0,
            collapses: 0,
            log: Vec::new(),
            pass_ends: Vec::new(),
            ring_u: Vec::new(),
            ring_w: Vec::new(),
            fan: Vec::new(),
            one_task: false,
            mark: vec![0; nv],
            stamp: 0,
        }
    }

    pub(super) fn run(&mut self) {
        let mut cands = Vec::new();
        let mut sorted = Vec::new();
        let mut scratch = Vec::new();
        while self.tris.len() > self.target {
            self.passes += 1;
            self.csr.rebuild(self.pos.len(), &self.tris, |_| true, true);
            self.candidates(&mut cands, &mut scratch);
            counting_sort(&cands, &mut sorted);
            let made = self.collapse_pass(&cands, &sorted);
            if made == 0 {
                break;
            }
            std::mem::swap(&mut self.active, &mut self.next_active);
            self.next_active.iter_mut().for_each(|a| *a = false);
            self.collapses += made;
            self.pass_ends.push(self.log.len());
            self.drop_degenerate();
        }
    }

    /// Replays the collapses of an earlier round (`log`, its passes ending at `pass_ends`)
    /// in their order, pass by pass, skipping those with a frozen end and those the checks
    /// now refuse; each made one is re-placed at its quadric's minimum. No candidate is
    /// evaluated and nothing is sorted: a fraction of the cost of [`Collapser::run`]. The
    /// result is that round's result with the collapses around frozen vertices left out.
    pub(super) fn replay(&mut self, log: &[(u32, u32)], pass_ends: &[usize]) {
        let mut begin = 0;
        for &end in pass_ends {
            self.passes += 1;
            self.csr.rebuild(self.pos.len(), &self.tris, |_| true, true);
            let mut made = 0;
            for &(u, w) in &log[begin..end] {
                if self.frozen[u as usize] || self.frozen[w as usize] {
                    continue;
                }
                if let Some(c) = self.cost(u, w)
                    && self.allowed(u, w, c.p)
                {
                    self.apply(&c);
                    made += 1;
                }
            }
            begin = end;
            if made == 0 {
                continue;
            }
            self.collapses += made;
            self.pass_ends.push(self.log.len());
            self.drop_degenerate();
        }
    }

    /// Drops the triangles collapsed to an edge (and their `ids`).
    fn drop_degenerate(&mut self) {
        let live = |t: &[u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
        if self.ids.is_empty() {
            self.tris.retain(live);
            return;
        }
        let mut n = 0;
        for i in 0..self.tris.len() {
            if live(&self.tris[i]) {
                self.tris[n] = self.tris[i];
                self.ids[n] = self.ids[i];
                n += 1;
            }
        }
        self.tris.truncate(n);
        self.ids.truncate(n);
    }

    /// Every edge's best collapse within the error bound, in the order of the triangles (the
    /// fans, [`Collapser::csr`], must be those of the current triangles).
    pub(super) fn candidates(&self, out: &mut Vec<Candidate>, scratch: &mut Vec<u32>) {
        self.candidates_with(out, scratch, FEW_ACTIVE);
    }

    /// [`Collapser::candidates`], from the fans below one active vertex per `few_active`
    /// triangles.
    pub(super) fn candidates_with(
        &self,
        out: &mut Vec<Candidate>,
        scratch: &mut Vec<u32>,
        few_active: usize,
    ) {
        out.clear();
        let tris = &self.tris;
        let edges = |i: usize, out: &mut Vec<Candidate>| {
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
        };
        // Only a triangle with an active corner has an edge to evaluate. When few vertices
        // are active (the last passes), those triangles are taken from their fans, in
        // triangle order: the same candidates, without a look at every triangle.
        let active = self.active.iter().filter(|&&a| a).count();
        if active.saturating_mul(few_active) < tris.len() {
            scratch.clear();
            for (v, _) in self.active.iter().enumerate().filter(|&(_, &a)| a) {
                scratch.extend_from_slice(self.csr.fan(v as u32));
            }
            scratch.sort_unstable();
            scratch.dedup();
            for &i in scratch.iter() {
                edges(i as usize, out);
            }
            return;
        }
        // One of several regions runs on one thread (the regions run in parallel).
        let per_task = if self.one_task { usize::MAX } else { 4096 };
        par::extend_in_order(out, tris.len(), per_task, edges);
    }

    /// The collapse of edge `u w`: position and error², if within the bound.
    pub(super) fn cost(&self, u: u32, w: u32) -> Option<Candidate> {
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
    pub(super) fn collapse_pass(&mut self, cands: &[Candidate], order: &[u32]) -> usize {
        self.locked.iter_mut().for_each(|l| *l = false);
        let mut made = 0;
        let mut live = self.tris.len();
        for c in order.iter().map(|&i| &cands[i as usize]) {
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
            self.apply(c);
            made += 1;
            live -= 2;
        }
        made
    }

    /// Collapses `c.u` into `c.w` at `c.p` (checked by [`Collapser::allowed`] just before:
    /// its rings are in `ring_u` and `ring_w`).
    fn apply(&mut self, c: &Candidate) {
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
        super::quadric::merge(&mut self.quad, &mut self.nrm, u, w);
        self.locked[u] = true;
        self.locked[w] = true;
        self.next_active[w] = true;
        for &x in self.ring_u.iter().chain(&self.ring_w) {
            self.next_active[x as usize] = true;
        }
        self.moved[w] = true;
        self.log.push((c.u, c.w));
    }

    /// The live corners of `v`: (next, previous) of each triangle of `v` that no collapse
    /// of this pass removed.
    #[inline]
    pub(super) fn live_corners(&self, v: u32) -> impl Iterator<Item = [u32; 2]> + '_ {
        self.csr
            .corners(v)
            .iter()
            .copied()
            .filter(move |&[n, p]| n != p && n != v && p != v)
    }

    /// Whether collapsing `u w` to `p` keeps the guarantees (link condition, normals,
    /// quality).
    pub(super) fn allowed(&mut self, u: u32, w: u32, p: Vec3) -> bool {
        let mut ring_u = std::mem::take(&mut self.ring_u);
        let mut ring_w = std::mem::take(&mut self.ring_w);
        let mut fan = std::mem::take(&mut self.fan);
        let ok = self.ring(u, &mut ring_u)
            && self.ring(w, &mut ring_w)
            && self.link_condition(w, &ring_u, &ring_w)
            && self.new_fan_ok(u, w, p, &mut fan)
            && self.near_old_fans(u, w, p);
        self.ring_u = ring_u;
        self.ring_w = ring_w;
        self.fan = fan;
        ok
    }

    /// Whether `p` lies within the error bound of the triangles around `u` and `w` as they
    /// are. The quadric bounds a mean over the merged planes weighted by area, so a sliver's
    /// plane (at a crease, say) barely counts, and the minimum may slide along a large
    /// plane past the crease, off the surface; this bounds the step of every collapse by
    /// the surface itself (`p` is rounded to `f32`, hence the slack of a few ulps).
    fn near_old_fans(&self, u: u32, w: u32, p: Vec3) -> bool {
        let pd = p.as_dvec3();
        let slack = 4.0 * f64::from(f32::EPSILON) * f64::from(p.abs().max_element());
        let bound = self.max_sq.sqrt() + slack;
        let bound_sq = bound * bound;
        [u, w].into_iter().any(|v| {
            let a = self.pos[v as usize].as_dvec3();
            self.live_corners(v).any(|[b, c]| {
                let t = [
                    a,
                    self.pos[b as usize].as_dvec3(),
                    self.pos[c as usize].as_dvec3(),
                ];
                crate::collide::point_triangle_sq(pd, t) <= bound_sq
            })
        })
    }

    /// The neighbours of `v` (each once on a closed manifold); false if fewer than three.
    pub(super) fn ring(&self, v: u32, out: &mut Vec<u32>) -> bool {
        out.clear();
        out.extend(self.live_corners(v).map(|[n, _]| n));
        out.len() >= 3
    }

    /// The link condition for a closed manifold: `w` is a neighbour of `u`, they share
    /// exactly two neighbours, and are not both of valence 3 (a tetrahedron would fold onto
    /// itself). Common neighbours are found with stamps (one write and one read each).
    fn link_condition(&mut self, w: u32, ring_u: &[u32], ring_w: &[u32]) -> bool {
        if ring_u.len() == 3 && ring_w.len() == 3 {
            return false;
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.mark.iter_mut().for_each(|m| *m = 0);
            self.stamp = 1;
        }
        for &x in ring_w {
            self.mark[x as usize] = self.stamp;
        }
        let (mut common, mut has_w) = (0, false);
        for &x in ring_u {
            if x == w {
                has_w = true;
            } else if self.mark[x as usize] == self.stamp {
                common += 1;
            }
        }
        has_w && common == 2
    }

    /// Whether moving `u` and `w` to `p` keeps the normal and quality of every triangle of
    /// either that does not hold both (`fan` receives them, `u`'s first), the new fan faces
    /// the way the old one did, and (unless it is nearly flat) it does not fold onto the
    /// triangles around it. Every check is a conjunction: the first failure ends the test.
    fn new_fan_ok(&self, u: u32, w: u32, p: Vec3, fan: &mut Vec<FanTriangle>) -> bool {
        fan.clear();
        let mut old_sum = Vec3::ZERO;
        for (v, other) in [(u, w), (w, u)] {
            let a = self.pos[v as usize];
            for [b, c] in self.live_corners(v) {
                if b == other || c == other {
                    continue;
                }
                let n_old = (self.pos[b as usize] - a).cross(self.pos[c as usize] - a);
                old_sum += n_old;
                fan.push(FanTriangle {
                    v,
                    b,
                    c,
                    n_old,
                    n_new: Vec3::ZERO,
                    len_new: 0.0,
                });
            }
        }
        let len = old_sum.length();
        let ends = self.nrm[u as usize] + self.nrm[w as usize];
        let cos_turn_min = MAX_NORMAL_TURN_DEG.to_radians().cos();
        let mut flat = true;
        for t in fan.iter_mut() {
            let a = self.pos[t.v as usize];
            let b = self.pos[t.b as usize];
            let c = self.pos[t.c as usize];
            let n_new = (b - p).cross(c - p);
            let d = t.n_old.dot(n_new);
            // A flip (cheap to see) fails the turn test below whatever the lengths.
            if !greater(d, 0.0) {
                return false;
            }
            let (lo, ln) = (t.n_old.length(), n_new.length());
            if !greater(d, cos_turn_min * lo * ln) {
                return false;
            }
            // The new fan stays on the side the old one faced (no fold within the fan).
            let (d, l) = (n_new.dot(old_sum), len * ln);
            if !greater(d, FAN_COS_MIN * l) {
                return false;
            }
            flat &= d > FLAT_COS * l;
            // Never against the original surface: the new triangle faces the way the
            // original triangles merged into its corners face on the whole.
            let corners = [ends, self.nrm[t.b as usize], self.nrm[t.c as usize]];
            let reference = corners[0] + corners[1] + corners[2];
            if !greater(
                n_new.dot(reference),
                REFERENCE_COS_MIN * ln * reference.length(),
            ) {
                return false;
            }
            // Nor against any one corner's cluster: where a thin part folds back within a
            // leaf, the sum above can agree while the triangle spans the fold and lies on
            // the sheet that faces the other way (a random case did).
            if corners.iter().any(|m| !greater(n_new.dot(*m), 0.0)) {
                return false;
            }
            let q_new = quality(ln, p, b, c);
            if q_new < MIN_QUALITY_ABSOLUTE || (q_new < MIN_QUALITY && q_new < quality(lo, a, b, c))
            {
                return false;
            }
            t.n_new = n_new;
            t.len_new = ln;
        }
        // A nearly flat new fan cannot fold onto its neighbours unless they were already
        // folded; the global test catches what this skips.
        flat || self.no_local_folds(u, w, p, fan)
    }
}

/// A triangle of the fan of a collapse: corner `v` (an end of the edge) with outer
/// vertices `b` and `c`, its normal (twice its area) before and after.
#[derive(Debug, Clone, Copy)]
pub(super) struct FanTriangle {
    v: u32,
    b: u32,
    c: u32,
    n_old: Vec3,
    n_new: Vec3,
    len_new: f32,
}

impl Collapser {
    /// Whether the new fan (`p` with the given outer edges and normals) stays clear of the
    /// other triangles around its outer vertices: every such pair facing away from each
    /// other is tested exactly (pairs sharing an outer edge must not fold flat).
    pub(super) fn no_local_folds(&self, u: u32, w: u32, p: Vec3, fan: &[FanTriangle]) -> bool {
        let pd = p.as_dvec3();
        let at = |k: u32| self.pos[k as usize].as_dvec3();
        // Each outer vertex x once (as the first outer vertex of its new triangle), its old
        // triangles (those of the collapsed edge's fans excepted) against the two new
        // triangles that hold x.
        for fi in fan {
            let x = fi.b;
            let Some(fj) = fan.iter().find(|f| f.c == x) else {
                continue;
            };
            let a0 = self.pos[x as usize];
            for [n, q] in self.live_corners(x) {
                // `x` is an outer vertex, neither `u` nor `w`.
                if n == u || n == w || q == u || q == w {
                    continue;
                }
                let (a1, a2) = (self.pos[n as usize], self.pos[q as usize]);
                let nt = (a1 - a0).cross(a2 - a0);
                let (di, dj) = (fi.n_new.dot(nt), fj.n_new.dot(nt));
                // Most pairs face the same way: nothing more to test (and no square root).
                if di >= 0.0 && dj >= 0.0 {
                    continue;
                }
                let tt = [x, n, q];
                for (f, d) in [(fi, di), (fj, dj)] {
                    if d >= 0.0 {
                        continue;
                    }
                    let (b, c) = (f.b, f.c);
                    if tt.contains(&b) && tt.contains(&c) {
                        // Sharing an outer edge: they must not fold flat onto each other.
                        if d < -FOLD_COS * f.len_new * nt.length() {
                            return false;
                        }
                        continue;
                    }
                    let tri_new = [pd, at(b), at(c)];
                    let tri_old = [at(x), at(n), at(q)];
                    // The old triangle's edge opposite x, and the new triangle's edge from
                    // p to its other outer vertex.
                    let other = if b == x { c } else { b };
                    if crate::collide::segment_triangle(tri_old[1], tri_old[2], tri_new)
                        || crate::collide::segment_triangle(pd, at(other), tri_old)
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
pub(super) const FLAT_COS: f32 = 0.94;

/// Smallest cosine between a new triangle's normal and the summed original normals of
/// the clusters at its corners.
pub(super) const REFERENCE_COS_MIN: f32 = 0.5;

/// Cosine beyond which two triangles sharing an edge count as folded flat onto each other.
pub(super) const FOLD_COS: f32 = 0.95;

/// `a > b`, false when either is NaN (so a NaN never passes a check).
#[inline]
pub(super) fn greater<T: PartialOrd>(a: T, b: T) -> bool {
    a > b
}

/// `4√3·area / Σ edge²` with `cross_len = 2·area`.
#[inline]
pub(super) fn quality(cross_len: f32, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let s = (b - a).length_squared() + (c - b).length_squared() + (a - c).length_squared();
    if s > 0.0 {
        2.0 * 3f32.sqrt() * cross_len / s
    } else {
        0.0
    }
}

/// The candidates' indices ordered by the leading bits of their keys (a counting sort:
/// stable, linear; indices rather than copies keep the memory small).
pub(super) fn counting_sort(cands: &[Candidate], out: &mut Vec<u32>) {
    const BUCKETS: usize = 1 << (32 - KEY_SHIFT - 1);
    let mut count = [0u32; BUCKETS + 1];
    for c in cands {
        count[(c.key >> KEY_SHIFT) as usize + 1] += 1;
    }
    for i in 0..BUCKETS {
        count[i + 1] += count[i];
    }
    out.clear();
    out.resize(cands.len(), 0);
    for (i, c) in cands.iter().enumerate() {
        let slot = &mut count[(c.key >> KEY_SHIFT) as usize];
        out[*slot as usize] = i as u32;
        *slot += 1;
    }
}
