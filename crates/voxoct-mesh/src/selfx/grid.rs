//! The candidate-pair grid of the search: triangles' cells hashed by Morton code into
//! buckets, each pair found once.

use std::sync::atomic::{AtomicU8, AtomicU32, Ordering};

use voxoct_core::glam::{Vec3, Vec3A, Vec4};

use super::*;

/// Spreads the low 21 bits of `x` to every third bit.
#[inline]
pub(super) fn spread(x: u32) -> u64 {
    let mut x = u64::from(x) & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// The bits of one axis in a Morton code.
pub(super) const DILATED: u64 = 0x1249_2492_4924_9249;

#[inline]
pub(super) fn morton(c: [u32; 3]) -> u64 {
    spread(c[0]) | (spread(c[1]) << 1) | (spread(c[2]) << 2)
}

/// Grid cells per axis at most (Morton codes hold 21 bits per axis).
pub(super) const MAX_CELLS: f32 = (1 << 20) as f32;
/// Cell edge in mean triangle extents: the least time on the bunny scan's mesh and the
/// bench's sphere (more candidate pairs than with 1.5, fewer entries to sort and gather).
pub(super) const CELL_FACTOR: f64 = 2.5;
/// Boxes per parallel task of the grid's bounds and size.
pub(super) const CHUNK: usize = 1 << 14;
/// Buckets per parallel task of the pair search (the result does not depend on it).
pub(super) const BUCKETS_PER_TASK: usize = 4096;

/// The candidate-pair grid. Every indexed triangle has an entry in each cell its box meets,
/// with flags saying along which axes that cell is the triangle's first. Cells are hashed
/// into buckets by their Morton code (nearby cells, nearby buckets). Two boxes that overlap
/// have exactly one cell whose every coordinate is the first cell of one of them (the cell
/// of the overlap's minimum corner): the pair is tested only there, from the entries whose
/// flags together cover all three axes.
pub(super) struct Index {
    pub(super) origin: Vec3A,
    pub(super) inv: f32,
    pub(super) dims: [u32; 3],
    pub(super) mask: u64,
    pub(super) start: Vec<u32>,
    pub(super) items: Vec<u32>,
    pub(super) flags: Vec<u8>,
}

impl Index {
    /// Indexes the boxes `box_of(i)`, `i < len`, that `include` accepts, box `i` as
    /// triangle `ids[i]` (without `ids`, as triangle `i`). A box is computed where it is
    /// used (a stored one is 32 bytes a triangle at the peak of a large mesh's check), and
    /// only when `include` accepts it.
    #[inline(never)]
    pub(super) fn build(
        len: usize,
        box_of: impl Fn(usize) -> [Vec3A; 2] + Sync,
        ids: Option<&[u32]>,
        include: impl Fn(usize) -> bool + Sync,
    ) -> Self {
        // The bounds, summed extents and count of the included boxes, by fixed chunks (the
        // same sums whatever the threads).
        let chunks = len.div_ceil(CHUNK);
        let chunk = |c: usize| c * CHUNK..((c + 1) * CHUNK).min(len);
        let mut parts = Vec::new();
        crate::par::map_into(&mut parts, chunks, |c| {
            let mut lo = Vec3A::splat(f32::INFINITY);
            let mut hi = Vec3A::splat(f32::NEG_INFINITY);
            let mut sum = 0.0f64;
            let mut n = 0usize;
            for t in chunk(c) {
                if !include(t) {
                    continue;
                }
                let b = box_of(t);
                if b[0].is_finite() && b[1].is_finite() {
                    lo = lo.min(b[0]);
                    hi = hi.max(b[1]);
                    sum += f64::from((b[1] - b[0]).max_element());
                    n += 1;
                }
            }
            (lo, hi, sum, n)
        });
        let mut lo = Vec3A::splat(f32::INFINITY);
        let mut hi = Vec3A::splat(f32::NEG_INFINITY);
        let mut sum = 0.0f64;
        let mut n = 0usize;
        for p in &parts {
            lo = lo.min(p.0);
            hi = hi.max(p.1);
            sum += p.2;
            n += p.3;
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
        // Each box's range of cells, computed where it is used (not stored: 24 bytes a
        // triangle at the peak of a large mesh's check).
        let grid = &index;
        let range = |t: usize| {
            let b = box_of(t);
            [grid.cell(b[0]), grid.cell(b[1])]
        };
        // Four to eight entries a bucket: a smooth surface fills a few per cent of its
        // cells' Morton codes, so with about one bucket per entry most were empty and the
        // counts of the sort below (one array per run) did not fit a core's cache (the
        // bunny's check: 1M buckets, 5 % used; a fifth less time with an eighth of them).
        // Cells that share a bucket only add candidates whose boxes are far apart, which
        // the box test drops. The entries are estimated at two a box (2.2 on the bunny's
        // mesh, cells being 2.5 mean extents wide), not counted: that would take another
        // pass over the boxes, and the count only sets the speed.
        let buckets = ((2 * n).next_power_of_two() / 8).max(1);
        let mask = buckets as u64 - 1;
        // A counting sort by bucket, in `parts` consecutive runs of triangles counted and
        // placed in parallel: run `c`'s entries of a bucket go after those of runs before
        // it, so the layout is that of one run, whatever `parts` is.
        let parts = crate::par::threads().clamp(1, len.div_ceil(1 << 14).max(1));
        let run = len.div_ceil(parts);
        let runs: Vec<std::ops::Range<usize>> = (0..parts)
            .map(|c| c * run..((c + 1) * run).min(len))
            .collect();
        let mut cursors: Vec<Vec<u32>> = Vec::new();
        crate::par::map_into(&mut cursors, parts, |c| {
            let mut count = vec![0u32; buckets];
            for_each_cell(range, runs[c].clone(), &include, |_, m, _| {
                count[(m & mask) as usize] += 1;
            });
            count
        });
        let mut start = vec![0u32; buckets + 1];
        let mut next = 0u32;
        for b in 0..buckets {
            start[b] = next;
            for cursor in &mut cursors {
                let n = cursor[b];
                cursor[b] = next;
                next += n;
            }
        }
        start[buckets] = next;
        let total = next as usize;
        let items: Vec<AtomicU32> = (0..total).map(|_| AtomicU32::new(0)).collect();
        let flags: Vec<AtomicU8> = (0..total).map(|_| AtomicU8::new(0)).collect();
        crate::par::for_each_zip(cursors, runs, |_, mut cursor, r| {
            for_each_cell(range, r, &include, |t, m, f| {
                let k = &mut cursor[(m & mask) as usize];
                let id = ids.map_or(t, |ids| ids[t as usize]);
                items[*k as usize].store(id, Ordering::Relaxed);
                flags[*k as usize].store(f, Ordering::Relaxed);
                *k += 1;
            });
        });
        let items: Vec<u32> = items.into_iter().map(AtomicU32::into_inner).collect();
        let flags: Vec<u8> = flags.into_iter().map(AtomicU8::into_inner).collect();
        index.mask = mask;
        index.start = start;
        index.items = items;
        index.flags = flags;
        index
    }

    /// The grid cell of point `p` (clamped to the grid).
    #[inline]
    pub(super) fn cell(&self, p: Vec3A) -> [u32; 3] {
        let g = (p - self.origin) * self.inv;
        [
            (g.x.max(0.0) as u32).min(self.dims[0] - 1),
            (g.y.max(0.0) as u32).min(self.dims[1] - 1),
            (g.z.max(0.0) as u32).min(self.dims[2] - 1),
        ]
    }

    /// Both triangles of every improper pair among the indexed proper triangles whose
    /// current boxes overlap (the indexed boxes must be the current ones); with `dirty`,
    /// only the pairs with a dirty member.
    pub(super) fn pairs(
        &self,
        ck: &Checker<'_>,
        vertices: &[Vec3],
        dirty: Option<&[bool]>,
    ) -> Vec<u32> {
        let count = self.start.len() - 1;
        let one = |task: usize, out: &mut Vec<u32>| {
            let mut scratch = Scratch::default();
            let range = task * BUCKETS_PER_TASK..((task + 1) * BUCKETS_PER_TASK).min(count);
            for b in range {
                self.bucket_pairs(ck, vertices, dirty, b, &mut scratch, out);
            }
        };
        let mut out = Vec::new();
        crate::par::extend_in_order(&mut out, count.div_ceil(BUCKETS_PER_TASK), 1, one);
        out
    }

    /// Appends both triangles of every improper pair of one of `tris` and an indexed
    /// proper triangle that is not `touched` (whose indexed box is its current one), their
    /// current boxes overlapping. Each pair is tested once: in the cell of the minimum
    /// corner of the boxes' overlap, which lies in both triangles' ranges of cells.
    pub(super) fn pairs_with_untouched(
        &self,
        ck: &Checker<'_>,
        vertices: &[Vec3],
        tris: &[u32],
        touched: &[bool],
        out: &mut Vec<u32>,
    ) {
        if self.items.is_empty() {
            return;
        }
        for &t in tris {
            let kt = ck.facts[t as usize].0;
            if kt == NO_AXIS {
                continue;
            }
            let bt = ck.tri_box(vertices, t);
            let cvt = ck.certified_vertices(t);
            let (lo, hi) = (self.cell(bt[0]), self.cell(bt[1]));
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let b = (morton([x, y, z]) & self.mask) as usize;
                        let (s, e) = (self.start[b] as usize, self.start[b + 1] as usize);
                        for &u in &self.items[s..e] {
                            let ku = ck.facts[u as usize].0;
                            if touched[u as usize] || ku == NO_AXIS {
                                continue;
                            }
                            let bu = ck.tri_box(vertices, u);
                            if !(bt[0].cmple(bu[1]) & bu[0].cmple(bt[1])).all()
                                || self.cell(bt[0].max(bu[0])) != [x, y, z]
                                || shares_certified(cvt, ck.certified_vertices(u))
                            {
                                continue;
                            }
                            let tri = |i: u32, k: u8| Tri {
                                idx: ck.triangles[i as usize],
                                k: k as usize,
                                v: vertices,
                            };
                            if improper(tri(t, kt), tri(u, ku)) {
                                out.push(t);
                                out.push(u);
                            }
                        }
                    }
                }
            }
        }
    }

    /// The improper pairs owned by the cells of bucket `b` (see [`Self::pairs`]).
    #[inline(never)]
    pub(super) fn bucket_pairs(
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
        // The bucket's proper entries, their flags and boxes (one array per bound, padded
        // to whole lanes with boxes that overlap nothing), 64 at a time; `has[r]`: the
        // entries of a block whose flags include the axes `r`.
        // `cv`: the triangle's certified vertices (others `u32::MAX`): a pair that shares one
        // needs no test.
        let Scratch { id, fl, bounds, cv } = scratch;
        let mut n = 0;
        for (&t, &f) in items.iter().zip(flags) {
            if ck.facts[t as usize].0 != NO_AXIS {
                if n == id.len() {
                    id.resize(n + BLOCK, 0);
                    fl.resize(n + BLOCK, 0);
                    for a in bounds.iter_mut() {
                        a.resize(n + BLOCK, 0.0);
                    }
                    cv.resize(n + BLOCK, [0; 3]);
                }
                id[n] = t;
                fl[n] = f;
                let [lo, hi] = ck.tri_box(vertices, t);
                for k in 0..3 {
                    bounds[k][n] = lo[k];
                    bounds[3 + k][n] = hi[k];
                }
                cv[n] = ck.certified_vertices(t);
                n += 1;
            }
        }
        let pad = n..n.next_multiple_of(LANES);
        for (k, a) in bounds.iter_mut().enumerate() {
            a[pad.clone()].fill(if k < 3 {
                f32::INFINITY
            } else {
                f32::NEG_INFINITY
            });
        }
        let (id, fl, cv) = (&id[..n], &fl[..n], &cv[..n]);
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
            for (x, &fx) in fl[..end].iter().enumerate() {
                // Partners in this block that come after x.
                let mut m = has[usize::from(7 & !fx)];
                if x >= base {
                    m &= (!0u64 << (x - base)) << 1;
                }
                if m == 0 {
                    continue;
                }
                // Which of the lanes from the first to the last partner hold a box that
                // overlaps x's, four at a time and without a branch per candidate.
                let lo = Vec4::new(bounds[0][x], bounds[1][x], bounds[2][x], 0.0);
                let hi = Vec4::new(bounds[3][x], bounds[4][x], bounds[5][x], 0.0);
                let mut hit = 0u64;
                let first = m.trailing_zeros() as usize & !(LANES - 1);
                let last = BLOCK - m.leading_zeros() as usize;
                for c in (first..last).step_by(LANES) {
                    let i = base + c;
                    let lane = |a: &Vec<f32>| Vec4::from_slice(&a[i..i + LANES]);
                    let o = lane(&bounds[0]).cmple(Vec4::splat(hi.x))
                        & lane(&bounds[1]).cmple(Vec4::splat(hi.y))
                        & lane(&bounds[2]).cmple(Vec4::splat(hi.z))
                        & Vec4::splat(lo.x).cmple(lane(&bounds[3]))
                        & Vec4::splat(lo.y).cmple(lane(&bounds[4]))
                        & Vec4::splat(lo.z).cmple(lane(&bounds[5]));
                    hit |= u64::from(o.bitmask()) << c;
                }
                hit &= m;
                // Of those, the ones that share no certified vertex with x, again without a
                // branch per pair (most share one, which one varies).
                let mut keep = 0u64;
                while hit != 0 {
                    let y = hit.trailing_zeros() as usize;
                    hit &= hit - 1;
                    keep |= u64::from(!shares_certified(cv[x], cv[base + y])) << y;
                }
                while keep != 0 {
                    let y = keep.trailing_zeros() as usize;
                    keep &= keep - 1;
                    test(id[x], id[base + y], out);
                }
            }
        }
    }
}

/// Entries per block of the pair loop (one bit each in a `u64`).
pub(super) const BLOCK: usize = 64;
/// Boxes compared at once in the pair loop (a multiple of which divides [`BLOCK`]).
pub(super) const LANES: usize = 4;

/// Reused buffers of [`Index::bucket_pairs`].
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) id: Vec<u32>,
    pub(super) fl: Vec<u8>,
    /// Per bound (minimum x, y, z, maximum x, y, z), its value for each entry.
    pub(super) bounds: [Vec<f32>; 6],
    pub(super) cv: Vec<[u32; 3]>,
}

/// Morton codes of the cells of every included triangle's range (of the triangles `run`), with the triangle and the
/// cell's flags (bit `k`: the cell is the range's first along axis `k`).
#[inline(never)]
pub(super) fn for_each_cell(
    range: impl Fn(usize) -> [[u32; 3]; 2],
    run: std::ops::Range<usize>,
    include: impl Fn(usize) -> bool,
    mut f: impl FnMut(u32, u64, u8),
) {
    for t in run {
        if !include(t) {
            continue;
        }
        let r = range(t);
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
