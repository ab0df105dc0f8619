//! Regions with frozen seams: one round of collapses split into spatial regions that run
//! independently (in parallel with the `parallel` feature, each on its own cache-sized
//! copy), then regions of the shifted cubes over the seams, then what is left.
//!
//! # Why the regions cannot disturb each other
//! Every triangle belongs to one region (the cube of a coarse grid that holds its
//! centroid). A vertex is *movable* in region `A` when every triangle around it and around
//! each of its neighbours belongs to `A` (two rings inside); only movable vertices may be an
//! end of a collapse there. A collapse in `A` rewrites only triangles around a movable
//! vertex of `A` — all of them `A`'s, and so they stay — and its checks read the triangles
//! around the vertices of those triangles and their positions and normals. A triangle that
//! `B` rewrites holds a movable vertex of `B`, whose neighbours have only `B`'s triangles,
//! so it shares no vertex with a triangle of `A`: `B` never rewrites, nor moves a vertex
//! of, anything `A`'s checks read, and the other way round. Each region therefore runs
//! on its own copy (its triangles and the *halo* of other regions' triangles around their
//! vertices, everything not movable frozen) and sees exactly what a run over the whole
//! mesh would see; the result does not depend on the number of threads.
//!
//! What the regions leave — the two or three rings of vertices along their borders — is
//! then collapsed by the regions of the same cubes shifted by half an edge, which start
//! from the vertices that were not movable (their edges were never tried), and what those
//! leave (where the borders of both cross) by one run over the whole mesh.

use std::borrow::Cow;
use std::sync::{Arc, Mutex, PoisonError};

use voxoct_core::glam::{DVec3, UVec3, Vec3};

use super::collapse::Collapser;
use super::quadric::Quadric;
use super::{RoundLog, Simplify};
use crate::fans::VertexFans;
use crate::mesh::Mesh;
use crate::par;

/// Triangles per region, about (a region's copy then fits a core's 2 MB L2 cache).
pub(super) const REGION_TRIANGLES: usize = 8192;

/// A vertex with triangles of more than one region.
const MIXED: u32 = u32::MAX;
/// A vertex that no triangle uses.
const UNUSED: u32 = u32::MAX - 1;

/// One region's copy of the mesh.
pub(super) struct Region {
    /// Its vertices (global indices): local vertex `i` is `verts[i]`. Those whose every
    /// triangle is its own come first (`inner` of them), in increasing order, then the
    /// others, also so.
    verts: Vec<u32>,
    inner: usize,
    /// Its triangles in local indices: its own first (in mesh order), then the halo. Empty
    /// when the plan keeps none: they are numbered again from the triangles the plan was
    /// made of when needed ([`Plan::local_triangles`]).
    tris: Vec<[u32; 3]>,
    /// The global index of each of `tris`.
    ids: Vec<u32>,
    /// How many of `tris` are its own.
    own: usize,
    /// The number of its cube in the grid (0 without a grid): the same region in another
    /// round.
    key: u32,
}

/// How the mesh is split: which vertices each region may move, and the regions' copies.
pub(super) struct Plan {
    /// Whether the vertex is movable in the region of its triangles.
    pub(super) movable: Vec<bool>,
    pub(super) regions: Vec<Region>,
    /// When the regions keep no triangles: the local number of each vertex whose every
    /// triangle belongs to one region, in that region (4 bytes a vertex instead of 12 a
    /// triangle). Empty when they keep them.
    local_of: Vec<u32>,
}

impl Plan {
    /// The triangles of `region` in local numbers: those it kept, or those of `source`
    /// (the triangles the plan was made of) that it names, numbered again: a vertex of
    /// its own by `local_of`, the few others (its border) by a binary search.
    fn local_triangles(&self, region: &Region, source: &[[u32; 3]]) -> Vec<[u32; 3]> {
        if self.local_of.is_empty() {
            return region.tris.clone();
        }
        let (inner, others) = region.verts.split_at(region.inner);
        let local = |g: u32| {
            let l = self.local_of[g as usize];
            // A vertex of another region's own has a number there, not here.
            if inner.get(l as usize) == Some(&g) {
                l
            } else {
                (inner.len() + others.binary_search(&g).unwrap_or(0)) as u32
            }
        };
        region
            .ids
            .iter()
            .map(|&t| source[t as usize].map(local))
            .collect()
    }
}

/// Splits `mesh` (indices in range) into the regions of `grid`'s cubes, each triangle in
/// the cube of its centroid (one region without a grid). With `keep_tris`, each region
/// keeps its copy of its triangles; without, they are numbered again from `mesh`'s when
/// needed (12 bytes a triangle less for as long as the plan is kept).
pub(super) fn plan(mesh: &Mesh, grid: Option<&Grid>, keep_tris: bool) -> Plan {
    let nv = mesh.vertices.len();
    let (region_of, keys) = assign(mesh, grid);
    let count = keys.len();
    let pure = pure_regions(nv, &mesh.triangles, &region_of);
    // Movable: every triangle around it has three vertices of its own region only. Each
    // region's own triangles, in mesh order, and its pure vertices, in index order
    // (counting sorts by region). Two independent halves, side by side.
    let ((movable, order), (pure_order, local_of)) = par::join(
        || {
            let mut movable: Vec<bool> = pure.iter().map(|&p| p < UNUSED).collect();
            for t in &mesh.triangles {
                let p = t.map(|k| pure[k as usize]);
                if !(p[0] == p[1] && p[1] == p[2] && p[0] < UNUSED) {
                    for &k in t {
                        movable[k as usize] = false;
                    }
                }
            }
            (movable, by_region(&region_of, count))
        },
        || {
            let pure_order = by_region(&pure, count);
            let mut local_of = vec![0u32; nv];
            for r in 0..count {
                for (i, &v) in pure_order.1[pure_order.0[r]..pure_order.0[r + 1]]
                    .iter()
                    .enumerate()
                {
                    local_of[v as usize] = i as u32;
                }
            }
            (pure_order, local_of)
        },
    );
    // The fans of the vertices shared by regions (complete: every triangle around such a
    // vertex is kept), to find the halos; the other triangles are left out.
    let mixed = |t: [u32; 3]| t.iter().any(|&k| pure[k as usize] == MIXED);
    let fans = (count > 1).then(|| VertexFans::new(nv, &mesh.triangles, mixed, false));
    let mut regions = Vec::new();
    par::map_into(&mut regions, count, |r| {
        let own = &order.1[order.0[r]..order.0[r + 1]];
        let inner = &pure_order.1[pure_order.0[r]..pure_order.0[r + 1]];
        let mut halo: Vec<u32> = Vec::new();
        if let Some(fans) = &fans {
            for &t in own {
                for &k in &mesh.triangles[t as usize] {
                    if pure[k as usize] == MIXED {
                        halo.extend(
                            fans.fan(k)
                                .iter()
                                .filter(|&&u| region_of[u as usize] != r as u32),
                        );
                    }
                }
            }
            halo.sort_unstable();
            halo.dedup();
        }
        let ids: Vec<u32> = own.iter().chain(&halo).copied().collect();
        // The region's own vertices first (numbered by `local_of`), then the others.
        let mut others: Vec<u32> = ids
            .iter()
            .flat_map(|&t| mesh.triangles[t as usize])
            .filter(|&k| pure[k as usize] != r as u32)
            .collect();
        others.sort_unstable();
        others.dedup();
        let local = |k: u32| {
            if pure[k as usize] == r as u32 {
                local_of[k as usize]
            } else {
                (inner.len() + others.binary_search(&k).unwrap_or(0)) as u32
            }
        };
        let tris = if keep_tris {
            ids.iter()
                .map(|&t| mesh.triangles[t as usize].map(local))
                .collect()
        } else {
            Vec::new()
        };
        let mut verts = inner.to_vec();
        verts.extend_from_slice(&others);
        Region {
            tris,
            inner: inner.len(),
            ids,
            own: own.len(),
            verts,
            key: keys[r],
        }
    });
    let local_of = if keep_tris { Vec::new() } else { local_of };
    Plan {
        movable,
        regions,
        local_of,
    }
}

/// The region of each vertex's triangles (`region_of`), `MIXED` where they are of more
/// than one, `UNUSED` where it has none: the two halves of the triangles at once, their
/// verdicts merged (the same whatever the order).
fn pure_regions(nv: usize, triangles: &[[u32; 3]], region_of: &[u32]) -> Vec<u32> {
    let merge = |p: u32, r: u32| {
        if p == UNUSED || p == r {
            r
        } else if r == UNUSED {
            p
        } else {
            MIXED
        }
    };
    let scan = |range: std::ops::Range<usize>| {
        let mut pure = vec![UNUSED; nv];
        for (t, &r) in triangles[range.clone()].iter().zip(&region_of[range]) {
            for &k in t {
                let p = &mut pure[k as usize];
                *p = merge(*p, r);
            }
        }
        pure
    };
    let half = triangles.len() / 2;
    let (mut pure, second) = par::join(|| scan(0..half), || scan(half..triangles.len()));
    for (p, &q) in pure.iter_mut().zip(&second) {
        *p = merge(*p, q);
    }
    pure
}

/// The items of each group `0..count` (`group[i]`; larger values belong to none), in index
/// order: the start of each group's run (`count + 1` of them) and the runs.
fn by_region(group: &[u32], count: usize) -> (Vec<usize>, Vec<u32>) {
    let mut start = vec![0usize; count + 1];
    for &r in group {
        if (r as usize) < count {
            start[r as usize + 1] += 1;
        }
    }
    for r in 0..count {
        start[r + 1] += start[r];
    }
    let mut items = vec![0u32; start[count]];
    let mut cursor = start.clone();
    for (i, &r) in group.iter().enumerate() {
        if (r as usize) < count {
            items[cursor[r as usize]] = i as u32;
            cursor[r as usize] += 1;
        }
    }
    (start, items)
}

/// The cubes that make the regions: minimum corner, edge and count per axis.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    lo: Vec3,
    edge: f32,
    dims: UVec3,
}

impl Grid {
    /// Cubes that hold about `per_region` triangles each of a surface of `mesh`'s mean
    /// triangle area; `None` when that makes fewer than two regions' worth (or `per_region`
    /// is 0, or the mesh is degenerate).
    pub(super) fn new(mesh: &Mesh, per_region: usize) -> Option<Self> {
        let nt = mesh.triangles.len();
        if per_region == 0 || nt < 2 * per_region {
            return None;
        }
        let at = |k: u32| mesh.vertices[k as usize];
        let area = par::sum(&mesh.triangles, |t| {
            let [a, b, c] = t.map(at);
            f64::from((b - a).cross(c - a).length()) * 0.5
        });
        let edge = (area / nt as f64 * per_region as f64).sqrt() as f32;
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for p in &mesh.vertices {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if !(edge.is_finite() && edge > 0.0 && lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let dims = ((hi - lo) / edge).as_uvec3().min(UVec3::splat(1022)) + 1;
        Some(Self { lo, edge, dims })
    }

    /// The same cubes shifted by half an edge along every axis (one more per axis), so
    /// that the borders of one lie inside the cubes of the other.
    pub(super) fn shifted(&self) -> Self {
        Self {
            lo: self.lo - self.edge * 0.5,
            edge: self.edge,
            dims: self.dims + 1,
        }
    }
}

/// The region of every triangle: the cube of its centroid (all 0 without a grid), the
/// cubes that hold none skipped; and each region's cube.
fn assign(mesh: &Mesh, grid: Option<&Grid>) -> (Vec<u32>, Vec<u32>) {
    let Some(&Grid { lo, edge, dims }) = grid else {
        let keys = if mesh.triangles.is_empty() {
            Vec::new()
        } else {
            vec![0]
        };
        return (vec![0; mesh.triangles.len()], keys);
    };
    let at = |k: u32| mesh.vertices[k as usize];
    let cell = |t: &[u32; 3]| {
        let [a, b, c] = t.map(at);
        let g = (((a + b + c) / 3.0 - lo) / edge)
            .max(Vec3::ZERO)
            .as_uvec3()
            .min(dims - 1);
        g.x + dims.x * (g.y + dims.y * g.z)
    };
    let keys = par::map(&mesh.triangles, cell);
    // Dense region numbers in the order of the cubes.
    let mut used = vec![u32::MAX; (dims.x * dims.y * dims.z) as usize];
    for &k in &keys {
        used[k as usize] = 0;
    }
    let mut cubes = Vec::new();
    for (c, u) in used.iter_mut().enumerate() {
        if *u == 0 {
            *u = cubes.len() as u32;
            cubes.push(c as u32);
        }
    }
    (par::map(&keys, |&k| used[k as usize]), cubes)
}

/// The result of one round over the whole mesh (global indices, `tris` in mesh order).
pub(super) struct Round {
    pub(super) pos: Vec<Vec3>,
    pub(super) tris: Vec<[u32; 3]>,
    pub(super) parent: Vec<u32>,
    pub(super) moved: Vec<bool>,
    pub(super) passes: usize,
    pub(super) collapses: usize,
}

/// The whole mesh during a round (global indices). A phase's regions read and write it
/// under a lock, each when it starts and when it is done: a region reads only its own
/// movable vertices (which no other region writes) and vertices no region may move, and
/// writes only its own movable vertices, so the result does not depend on the order.
struct State {
    pos: Vec<Vec3>,
    /// The quadrics and normals of the vertices that have a slot (`slot`, by global index;
    /// `u32::MAX`: none). In the first phase there are none: each region's copy computes
    /// its own vertices' from its triangles (exactly, for every vertex it may read), and
    /// only the vertices the phase leaves get one (the largest arrays follow what is left).
    quad: Vec<Quadric>,
    nrm: Vec<Vec3>,
    slot: Vec<u32>,
    parent: Vec<u32>,
    moved: Vec<bool>,
    /// The triangles the latest phase left, in order (empty during a phase: the regions'
    /// copies are the triangles it works on).
    slots: Vec<[u32; 3]>,
    /// The most passes a region of the phase made, and the collapses.
    passes: usize,
    collapses: usize,
}

impl State {
    /// A region's result written back.
    fn stitch(&mut self, region: &Region, out: &RegionResult) {
        self.passes = self.passes.max(out.passes);
        self.collapses += out.collapses;
        for &(g, p) in &out.parents {
            self.parent[g as usize] = p;
        }
        for &(l, pos) in &out.moved {
            let g = region.verts[l as usize] as usize;
            self.moved[g] = true;
            self.pos[g] = pos;
        }
        for (&(l, _), &(quad, nrm)) in out.moved.iter().zip(&out.sums) {
            let g = region.verts[l as usize] as usize;
            if let Some(&s) = self.slot.get(g) {
                self.quad[s as usize] = quad;
                self.nrm[s as usize] = nrm;
            }
        }
    }

    /// The triangles the regions of `plan` left (`results`, by region), in the order of
    /// the phase's triangles (`count` of them, every one a region's own): each is placed
    /// at the rank of its number among the survivors' (a bitmap of them, counted by word).
    /// Built from the results rather than kept for the whole phase (a copy of its input's
    /// triangles, while a phase leaves a fraction of them).
    fn survivors(
        plan: &Plan,
        results: &[(Arc<RegionResult>, RoundLog, u64)],
        count: usize,
    ) -> Vec<[u32; 3]> {
        let global = |region: &Region, k: u32| region.ids[k as usize] as usize;
        let mut bits = vec![0u64; count.div_ceil(64)];
        for (region, (result, _, _)) in plan.regions.iter().zip(results) {
            for &(k, _) in &result.tris {
                let id = global(region, k);
                bits[id / 64] |= 1 << (id % 64);
            }
        }
        let mut before = Vec::with_capacity(bits.len());
        let mut n = 0u32;
        for w in &bits {
            before.push(n);
            n += w.count_ones();
        }
        let mut left = vec![[0u32; 3]; n as usize];
        for (region, (result, _, _)) in plan.regions.iter().zip(results) {
            for &(k, t) in &result.tris {
                let id = global(region, k);
                let below = bits[id / 64] & ((1u64 << (id % 64)) - 1);
                left[(before[id / 64] + below.count_ones()) as usize] = t;
            }
        }
        left
    }

    /// Runs every region of `plan` on this state (the vertices `active` first tried,
    /// `None`: all), or, where `done` holds a region's result, takes it as it is, or replays
    /// `logs` on the regions `redo` names, or, where `cache` holds the result of a region
    /// of the same cube whose copy had the same fingerprint, takes that; returns the
    /// regions' results, logs and fingerprints (0 without `cache`).
    #[allow(clippy::too_many_arguments)]
    fn phase(
        self,
        plan: &Plan,
        source: &[[u32; 3]],
        frozen: &[bool],
        active: Option<&[bool]>,
        opts: &Simplify,
        origin: DVec3,
        done: Option<Done<'_>>,
        cache: Option<&[Cached]>,
    ) -> (Self, Vec<(Arc<RegionResult>, RoundLog, u64)>) {
        let shared = Mutex::new(self);
        let mut out = Vec::new();
        par::map_into(&mut out, plan.regions.len(), |r| {
            let region = &plan.regions[r];
            let result = match done {
                Some((results, _, redo)) if !redo[r] => {
                    (Arc::clone(&results[r]), (Vec::new(), Vec::new()), 0)
                }
                _ => {
                    let copy = region_copy(
                        &shared,
                        (region, source),
                        plan,
                        frozen,
                        active,
                        opts,
                        origin,
                    );
                    let replay = done.map(|(_, logs, _)| &logs[r]);
                    let print = cache.map_or(0, |_| fingerprint(&copy, region));
                    let hit = cache.and_then(|c| {
                        let i = c.binary_search_by_key(&region.key, |e| e.0).ok()?;
                        (c[i].1 == print).then(|| Arc::clone(&c[i].2))
                    });
                    match hit {
                        Some(result) => (result, (Vec::new(), Vec::new()), print),
                        None => {
                            let (result, log) = run_region(copy, region, plan, frozen, replay);
                            (Arc::new(result), log, print)
                        }
                    }
                }
            };
            let mut st = shared.lock().unwrap_or_else(PoisonError::into_inner);
            st.stitch(region, &result.0);
            result
        });
        let mut st = shared.into_inner().unwrap_or_else(PoisonError::into_inner);
        let count = plan.regions.iter().map(|region| region.own).sum();
        st.slots = Self::survivors(plan, &out, count);
        (st, out)
    }
}

/// The rounds of one simplification. Each has three phases: the regions (cubes of
/// [`REGION_TRIANGLES`]), then the regions of the same cubes shifted by half an edge
/// (which hold most of the first phase's seams; they start from the vertices the first
/// could not move), then one run over the whole mesh for what is left (from the vertices
/// the second phase could not move). A later round replays the first phase's collapses
/// without the frozen vertices in the regions that hold a vertex frozen since (the other
/// regions' results are kept: their movable vertices that moved and the collapsed ones,
/// and their triangles, a fraction of the mesh) and runs the other two phases again, the
/// second one's regions whose copies have the fingerprint of the round before's in the same
/// cube taking that round's result (a run depends on nothing but its copy).
pub(super) struct Rounds<'m> {
    mesh: &'m Mesh,
    grid: Option<Grid>,
    plan: Plan,
    opts: &'m Simplify,
    /// Per first-phase region: its latest result, and the first round's collapses.
    done: Vec<Arc<RegionResult>>,
    logs: Vec<RoundLog>,
    /// The frozen vertices of the latest round.
    frozen_then: Vec<bool>,
    /// The second phase's results of the latest round, by cube (increasing).
    shifted_done: Vec<Cached>,
}

/// A region's cube, the fingerprint of its copy and its result.
type Cached = (u32, u64, Arc<RegionResult>);

/// The first phase's results and collapses of the round before, by region, and which
/// regions to replay.
type Done<'a> = (&'a [Arc<RegionResult>], &'a [RoundLog], &'a [bool]);

/// A 64-bit fingerprint (SipHash) of everything a region's run depends on and its result
/// names: its copy (positions, triangles and their order, quadrics, normals, the vertices
/// that may not move and those tried first), its vertices' global numbers and how many of
/// its triangles are its own. The options and the quadrics' origin are the same in every
/// round.
fn fingerprint(c: &Collapser, region: &Region) -> u64 {
    use std::hash::Hasher;
    let mut h = std::hash::DefaultHasher::new();
    h.write_usize(region.own);
    h.write_usize(c.tris.len());
    for t in &c.tris {
        h.write_u64(u64::from(t[0]) | u64::from(t[1]) << 32);
        h.write_u32(t[2]);
    }
    h.write_usize(region.verts.len());
    for (l, &g) in region.verts.iter().enumerate() {
        let p = c.pos[l];
        let n = c.nrm[l];
        h.write_u32(g);
        h.write_u64(u64::from(p.x.to_bits()) | u64::from(p.y.to_bits()) << 32);
        h.write_u64(u64::from(p.z.to_bits()) | u64::from(n.x.to_bits()) << 32);
        h.write_u64(u64::from(n.y.to_bits()) | u64::from(n.z.to_bits()) << 32);
        for q in &c.quad[l].q {
            h.write_u64(q.to_bits());
        }
        h.write_u64(c.quad[l].w.to_bits());
        h.write_u8(u8::from(c.frozen[l]) | u8::from(c.active[l]) << 1);
    }
    h.finish()
}

impl<'m> Rounds<'m> {
    /// No round made yet; regions of about `per_region` triangles (0: one region, and no
    /// other phase).
    pub(super) fn new(mesh: &'m Mesh, opts: &'m Simplify, per_region: usize) -> Self {
        let grid = Grid::new(mesh, per_region);
        // The first phase's plan is kept for the later rounds: without its triangles,
        // which `mesh`'s give again.
        let plan = plan(mesh, grid.as_ref(), false);
        Self {
            mesh,
            plan,
            grid,
            opts,
            done: Vec::new(),
            logs: Vec::new(),
            frozen_then: vec![false; mesh.vertices.len()],
            shifted_done: Vec::new(),
        }
    }

    /// The next round, with the `frozen` vertices (a superset of the last round's) kept
    /// where they are.
    pub(super) fn next(&mut self, frozen: &[bool]) -> Round {
        let (mesh, opts, plan) = (self.mesh, self.opts, &self.plan);
        let origin = super::quadric::origin(mesh);
        let nv = mesh.vertices.len();
        let state = State {
            pos: mesh.vertices.clone(),
            quad: Vec::new(),
            nrm: Vec::new(),
            slot: Vec::new(),
            parent: (0..nv as u32).collect(),
            moved: vec![false; nv],
            slots: Vec::new(),
            passes: 0,
            collapses: 0,
        };
        // The first phase: every region the first time; then those that hold a vertex
        // frozen since, replayed (the others' results stand: they depend on nothing
        // outside the region).
        let redo: Vec<bool> = plan
            .regions
            .iter()
            .map(|region| {
                region
                    .verts
                    .iter()
                    .any(|&g| frozen[g as usize] != self.frozen_then[g as usize])
            })
            .collect();
        let done = (!self.done.is_empty()).then_some((&self.done[..], &self.logs[..], &redo[..]));
        let (mut state, outs) = state.phase(
            plan,
            &mesh.triangles,
            frozen,
            None,
            opts,
            origin,
            done,
            None,
        );
        let first = self.done.is_empty();
        for (r, (result, log, _)) in outs.into_iter().enumerate() {
            if first {
                self.done.push(result);
                self.logs.push(log);
            } else {
                self.done[r] = result;
            }
        }
        self.frozen_then.copy_from_slice(frozen);
        let mut active: Vec<bool> = plan.movable.iter().map(|m| !m).collect();
        if self.grid.is_some() {
            self.give_slots(&mut state, origin);
        }
        // Kept for the later rounds without their sums (nothing else reads them; the
        // results are not shared any more: the phase's were moved here).
        for result in &mut self.done {
            if let Some(result) = Arc::get_mut(result) {
                result.sums = Vec::new();
            }
        }
        // The second phase: the shifted cubes, from the vertices the first could not move.
        if let Some(grid) = &self.grid {
            // Planned on the vertices that are left only, numbered in the same order (the
            // regions come out the same), so that the plan's work and arrays follow the
            // mesh that is left rather than the input's vertex count; then numbered back.
            let mut tris = std::mem::take(&mut state.slots);
            let (local_of, live) = numbered_used(nv, &tris);
            for t in &mut tris {
                *t = t.map(|k| local_of[k as usize]);
            }
            drop(local_of);
            let lookup = Mesh {
                vertices: live.iter().map(|&g| state.pos[g as usize]).collect(),
                triangles: tris,
            };
            let mut shifted = super::regions::plan(&lookup, Some(&grid.shifted()), true);
            // The plan holds the phase's triangles: its regions' copies.
            drop(lookup);
            let mut movable = vec![false; nv];
            for (&g, &m) in live.iter().zip(&shifted.movable) {
                movable[g as usize] = m;
            }
            shifted.movable = movable;
            for region in &mut shifted.regions {
                for v in &mut region.verts {
                    *v = live[*v as usize];
                }
            }
            drop(live);
            let cache = Some(&self.shifted_done[..]);
            let (next, outs) = state.phase(
                &shifted,
                &[],
                frozen,
                Some(&active),
                opts,
                origin,
                None,
                cache,
            );
            state = next;
            // Kept for the next round, whose regions of the same cubes and copies take them.
            self.shifted_done = shifted
                .regions
                .iter()
                .zip(outs)
                .map(|(region, (result, _, print))| (region.key, print, result))
                .collect();
            for (a, &m) in active.iter_mut().zip(&shifted.movable) {
                *a = !m;
            }
        }
        // The seams: a run over the whole mesh, from the vertices no region could move.
        let State {
            mut pos,
            quad,
            nrm,
            slot,
            mut parent,
            mut moved,
            mut slots,
            passes,
            collapses,
        } = state;
        if self.grid.is_none() {
            return Round {
                passes,
                collapses,
                pos,
                tris: slots,
                parent,
                moved,
            };
        }
        // On the vertices that are left only, numbered in the same order (so the run makes
        // the same collapses as on the global numbering), so that each pass's work follows
        // the mesh that is left rather than the input's vertex count.
        let (local_of, live) = numbered_used(nv, &slots);
        let at = |g: &u32| *g as usize;
        for t in &mut slots {
            *t = t.map(|k| local_of[k as usize]);
        }
        drop(local_of);
        // The quadrics of the vertices that are left, in place: they all have a slot, and
        // both are numbered in increasing global order, so each one's slot is at or after
        // its new place (no second copy of the largest arrays, even for a moment).
        let (mut quad, mut nrm) = (quad, nrm);
        for (i, g) in live.iter().enumerate() {
            let s = slot[at(g)] as usize;
            debug_assert!(
                s >= i,
                "a vertex that is left has a slot at or after its place"
            );
            quad[i] = quad[s];
            nrm[i] = nrm[s];
        }
        drop(slot);
        quad.truncate(live.len());
        nrm.truncate(live.len());
        quad.shrink_to_fit();
        nrm.shrink_to_fit();
        let quadrics = (quad, nrm);
        let mut seam = Collapser::new(
            Mesh {
                vertices: live.iter().map(|g| pos[at(g)]).collect(),
                triangles: slots,
            },
            quadrics,
            live.iter().map(|g| frozen[at(g)]).collect(),
            opts,
            origin,
        );
        seam.active = live.iter().map(|g| active[at(g)]).collect();
        seam.run();
        for (l, &g) in live.iter().enumerate() {
            let g = g as usize;
            if seam.parent[l] as usize != l {
                parent[g] = live[seam.parent[l] as usize];
            }
            moved[g] |= seam.moved[l];
            pos[g] = seam.pos[l];
        }
        Round {
            passes: passes + seam.passes,
            collapses: collapses + seam.collapses,
            pos,
            tris: seam
                .tris
                .iter()
                .map(|t| t.map(|k| live[k as usize]))
                .collect(),
            parent,
            moved,
        }
    }

    /// Gives the vertices the first phase left (those its triangles use) a slot, with their
    /// quadric and normal: a moved one's from its region's result, or added up again along
    /// its collapses when the result was reused without them, the others' initial ones (one
    /// pass over the input's triangles, in order).
    fn give_slots(&self, state: &mut State, origin: DVec3) {
        let (slot, used) = numbered_used(state.pos.len(), &state.slots);
        let n = used.len() as u32;
        drop(used);
        let mut quad = vec![Quadric::default(); n as usize];
        let mut nrm = vec![Vec3::ZERO; n as usize];
        // A region's copy read the input's positions (its own vertices, which no other
        // region moves, and vertices no region moves) and summed its initial quadrics from
        // its triangles; its collapses then added `u`'s sums to `w`'s, in order.
        let sums = Mutex::new((&mut quad, &mut nrm));
        par::for_each(self.plan.regions.len(), |r| {
            let (region, result) = (&self.plan.regions[r], &self.done[r]);
            let added_up = || {
                let copy = local_mesh(&self.plan, region, self.mesh);
                let (mut q, mut m) = super::quadric::initial_quadrics_at(&copy, origin);
                let log = result.applied.as_ref().unwrap_or(&self.logs[r].0);
                for &(u, w) in log {
                    super::quadric::merge(&mut q, &mut m, u as usize, w as usize);
                }
                result
                    .moved
                    .iter()
                    .map(|&(l, _)| (q[l as usize], m[l as usize]))
                    .collect::<Vec<_>>()
            };
            let of_moved: Cow<'_, [(Quadric, Vec3)]> = if result.sums.len() == result.moved.len() {
                // What a reused result relies on: adding up again gives the same bits.
                #[cfg(debug_assertions)]
                for (a, b) in added_up().iter().zip(&result.sums) {
                    let bits = |(q, m): &(Quadric, Vec3)| {
                        (
                            q.q.map(f64::to_bits),
                            q.w.to_bits(),
                            m.to_array().map(f32::to_bits),
                        )
                    };
                    debug_assert!(bits(a) == bits(b), "region {r}: sums added up differ");
                }
                Cow::Borrowed(&result.sums)
            } else {
                Cow::Owned(added_up())
            };
            let mut guard = sums.lock().unwrap_or_else(PoisonError::into_inner);
            let (quad, nrm) = &mut *guard;
            for (&(l, _), &(q, m)) in result.moved.iter().zip(of_moved.iter()) {
                let s = slot[region.verts[l as usize] as usize];
                if s != u32::MAX {
                    quad[s as usize] = q;
                    nrm[s as usize] = m;
                }
            }
        });
        // The unmoved ones: two halves of the slots at once, each summing its vertices'
        // triangles in order (so the sums do not depend on the threads).
        let (moved, half) = (&state.moved, n / 2);
        let pick = |lo: u32, hi: u32| {
            let slot = &slot;
            move |k: u32| {
                let s = slot[k as usize];
                (s >= lo && s < hi && !moved[k as usize]).then(|| (s - lo) as usize)
            }
        };
        let (qa, qb) = quad.split_at_mut(half as usize);
        let (na, nb) = nrm.split_at_mut(half as usize);
        let mesh = self.mesh;
        par::join(
            || super::quadric::add_initial(mesh, origin, pick(0, half), qa, na),
            || super::quadric::add_initial(mesh, origin, pick(half, n), qb, nb),
        );
        (state.quad, state.nrm, state.slot) = (quad, nrm, slot);
    }
}

/// The vertices (of `nv`) that `tris` use, numbered in increasing order: each one's number
/// (`u32::MAX` for an unused one) and the used ones in order.
fn numbered_used(nv: usize, tris: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut number = vec![u32::MAX; nv];
    for t in tris {
        for &k in t {
            number[k as usize] = 0;
        }
    }
    let mut used = Vec::new();
    for (g, n) in number.iter_mut().enumerate() {
        if *n == 0 {
            *n = used.len() as u32;
            used.push(g as u32);
        }
    }
    (number, used)
}

/// The region's vertices at `at`'s positions and its triangles (`at`'s when the plan was
/// made of them and keeps none), in local numbers.
fn local_mesh(plan: &Plan, region: &Region, at: &Mesh) -> Mesh {
    Mesh {
        vertices: region
            .verts
            .iter()
            .map(|&g| at.vertices[g as usize])
            .collect(),
        triangles: plan.local_triangles(region, &at.triangles),
    }
}

/// A region's copy of the mesh, ready to run: its vertices (positions, quadrics,
/// normals), its triangles, and which of its vertices may move and are tried first. The
/// state is locked only to read it; the quadrics are computed from the copy when the state
/// holds none (the first phase).
fn region_copy(
    shared: &Mutex<State>,
    (region, source): (&Region, &[[u32; 3]]),
    plan: &Plan,
    frozen: &[bool],
    active: Option<&[bool]>,
    opts: &Simplify,
    origin: DVec3,
) -> Collapser {
    let verts = &region.verts;
    // Numbered again (when the plan keeps no copy) without the lock.
    let triangles = plan.local_triangles(region, source);
    let (local, stored) = {
        let st = shared.lock().unwrap_or_else(PoisonError::into_inner);
        let local = Mesh {
            vertices: verts.iter().map(|&g| st.pos[g as usize]).collect(),
            triangles,
        };
        let of = |g: u32| st.slot[g as usize] as usize;
        let stored = (!st.slot.is_empty()).then(|| {
            (
                verts.iter().map(|&g| st.quad[of(g)]).collect(),
                verts.iter().map(|&g| st.nrm[of(g)]).collect(),
            )
        });
        (local, stored)
    };
    // Every vertex whose triangles are all the region's own has them in mesh order here,
    // so its sums are those of the whole mesh to the bit; those are the only vertices
    // whose quadric or normal a region's run reads (the ends of a collapse are movable,
    // and their neighbours have only triangles of the region).
    let quadrics = stored.unwrap_or_else(|| super::quadric::initial_quadrics_at(&local, origin));
    let fixed = verts
        .iter()
        .map(|&g| frozen[g as usize] || !plan.movable[g as usize])
        .collect();
    let mut c = Collapser::new(local, quadrics, fixed, opts, origin);
    c.ids.clone_from(&region.ids);
    c.one_task = plan.regions.len() > 1;
    if let Some(active) = active {
        for (a, &g) in c.active.iter_mut().zip(verts) {
            *a = active[g as usize];
        }
    }
    c
}

/// What a region did: its movable vertices that collapsed (into which, global indices)
/// and that moved (their local numbers and where), its own triangles that are left (their
/// places among its own and their corners, global indices), and its passes and collapses.
///
/// `sums`: the moved vertices' quadrics and normals, in the order of `moved`. A first
/// phase's result, kept for the later rounds, holds them only until its phase's slot pass
/// has taken them (88 + 12 bytes a moved vertex): they are the sums of its copy's initial
/// ones along its collapses, which [`Rounds::give_slots`] adds up again when a later round
/// reuses the result. A replayed region keeps the collapses it made (`applied`); a run one
/// made those of its log.
#[derive(Default)]
struct RegionResult {
    parents: Vec<(u32, u32)>,
    moved: Vec<(u32, Vec3)>,
    sums: Vec<(Quadric, Vec3)>,
    applied: Option<Vec<(u32, u32)>>,
    tris: Vec<(u32, [u32; 3])>,
    passes: usize,
    collapses: usize,
}

/// Runs a region's copy, or replays `replay` on it; returns its result and its collapses
/// (none for a replay: its result keeps them, in `applied`).
fn run_region(
    mut c: Collapser,
    region: &Region,
    plan: &Plan,
    frozen: &[bool],
    replay: Option<&RoundLog>,
) -> (RegionResult, RoundLog) {
    match replay {
        None => c.run(),
        Some((log, ends)) => c.replay(log, ends),
    }
    let mut out = RegionResult {
        passes: c.passes,
        collapses: c.collapses,
        ..RegionResult::default()
    };
    for (l, &g) in region.verts.iter().enumerate() {
        if !plan.movable[g as usize] || frozen[g as usize] {
            continue;
        }
        if c.parent[l] as usize != l {
            out.parents.push((g, region.verts[c.parent[l] as usize]));
        } else if c.moved[l] {
            out.moved.push((l as u32, c.pos[l]));
            out.sums.push((c.quad[l], c.nrm[l]));
        }
    }
    for (t, &id) in c.tris.iter().zip(&c.ids) {
        if let Ok(k) = region.ids[..region.own].binary_search(&id) {
            out.tris
                .push((k as u32, t.map(|k| region.verts[k as usize])));
        }
    }
    // Kept to the end of the simplification, and pushed to: without the growth slack.
    out.parents.shrink_to_fit();
    out.moved.shrink_to_fit();
    out.sums.shrink_to_fit();
    out.tris.shrink_to_fit();
    c.log.shrink_to_fit();
    if replay.is_some() {
        out.applied = Some(c.log);
        return (out, (Vec::new(), Vec::new()));
    }
    (out, (c.log, c.pass_ends))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plan that keeps no triangles gives each region the very copy of a plan that keeps
    /// them: the same local triangles, in the same order, from the mesh's.
    #[test]
    fn triangles_numbered_again_are_the_kept_ones() {
        let mesh = super::super::tests::ball_of(32, 12.0);
        let cubes = Grid::new(&mesh, 512).unwrap();
        for grid in [cubes, cubes.shifted()] {
            let kept = plan(&mesh, Some(&grid), true);
            let again = plan(&mesh, Some(&grid), false);
            assert!(kept.regions.len() > 8);
            assert_eq!(kept.movable, again.movable);
            for (k, a) in kept.regions.iter().zip(&again.regions) {
                assert!(a.tris.is_empty());
                assert_eq!((&k.verts, &k.ids, k.own), (&a.verts, &a.ids, a.own));
                assert_eq!(k.tris, again.local_triangles(a, &mesh.triangles));
                assert_eq!(k.tris, kept.local_triangles(k, &[]));
            }
        }
    }
}
