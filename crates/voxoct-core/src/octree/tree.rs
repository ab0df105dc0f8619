//! [`Octree`]: construction, insertion, queries and merging.

use glam::{UVec3, Vec3};

use super::layout::{Layout, SPLIT_DEPTH, cell_range_1d};
use super::morton::*;
use super::region::*;
use crate::error::OctreeError;
use crate::geometry::{Aabb, Cell, GridSpec, Real, Triangle};
use crate::intersection_test_aabb_triangle::{TriangleSat, intersection_test_aabb_triangle};

/// The deepest octree supported: `2^21` leaves per axis (Morton keys fit in 63 bits and
/// grid coordinates stay exact in `f32`).
pub const MAX_DEPTH: u32 = 21;

/// A sparse octree over a cubic root whose leaves are marked by inserted triangles.
///
/// See the [crate documentation](crate) for the semantics, and ARCHITECTURE.md for the
/// storage layout.
#[derive(Debug, Clone)]
pub struct Octree {
    min: Vec3,
    root_m: Real,
    leaf_m: Real,
    depth: u32,
    leaf_edge: Real,
    pub(super) layout: Layout,
    /// Indexed by the Morton code of the region coordinates.
    regions: Vec<Option<Box<Region>>>,
    /// Regions written by the insertion batch in progress (empty between calls).
    dirty: Vec<u32>,
}

impl Octree {
    /// An empty octree whose root is the cube `min ..= min + root_m` (metres), subdivided
    /// down to the first depth whose node edge is `<= leaf_m`: the names and units of the
    /// facade's `Params { root_m, leaf_m }`.
    ///
    /// # Errors
    ///
    /// [`OctreeError::InvalidArgument`] for a non-finite or non-positive value (named
    /// `"min.x"`, `"root_m"`, `"leaf_m"`, …),
    /// [`OctreeError::LeafLargerThanRoot`], [`OctreeError::TooDeep`] beyond
    /// [`MAX_DEPTH`], and [`OctreeError::LeafBelowPrecision`] when the leaves are too
    /// small for `f32` coordinates at the root's position.
    pub fn new(min: Vec3, root_m: Real, leaf_m: Real) -> Result<Self, OctreeError> {
        for (name, value) in [
            ("min.x", min.x),
            ("min.y", min.y),
            ("min.z", min.z),
            ("root_m", root_m),
            ("leaf_m", leaf_m),
        ] {
            if !value.is_finite() {
                return Err(OctreeError::not_finite(name, value));
            }
        }
        for (name, value) in [("root_m", root_m), ("leaf_m", leaf_m)] {
            if value <= 0.0 {
                return Err(OctreeError::not_positive(name, value));
            }
        }
        if leaf_m > root_m {
            return Err(OctreeError::LeafLargerThanRoot { leaf_m, root_m });
        }
        let max = min + Vec3::splat(root_m);
        if let Some(value) = max.to_array().into_iter().find(|v| !v.is_finite()) {
            return Err(OctreeError::not_finite("min + root_m", value));
        }
        let mut depth = 0;
        while depth <= MAX_DEPTH && edge_at(root_m, depth) > leaf_m {
            depth += 1;
        }
        if depth > MAX_DEPTH {
            let needed = (f64::from(root_m) / f64::from(leaf_m)).log2().ceil() as u32;
            return Err(OctreeError::TooDeep {
                depth: needed.max(MAX_DEPTH + 1),
                max: MAX_DEPTH,
            });
        }
        let leaf_edge = edge_at(root_m, depth);
        let magnitude = min.abs().max(max.abs()).max_element();
        if !leaf_edge.is_normal() || leaf_edge < magnitude * (1.0 / (1u32 << 20) as Real) {
            return Err(OctreeError::LeafBelowPrecision {
                leaf_edge,
                magnitude,
            });
        }
        let split = depth.min(SPLIT_DEPTH);
        let region_shift = depth - split;
        let layout = Layout {
            grid: GridSpec {
                origin: min,
                cell: leaf_edge,
                resolution: 1 << depth,
            },
            region_shift,
            levels: region_shift.saturating_sub(2),
            inv_cell: 1.0 / leaf_edge,
        };
        let mut regions = Vec::new();
        regions.resize_with(1 << (3 * split), || None);
        Ok(Self {
            min,
            root_m,
            leaf_m,
            depth,
            leaf_edge,
            layout,
            regions,
            dirty: Vec::new(),
        })
    }

    /// An empty octree whose cubic root encloses `bounds`: centred on them, with an edge
    /// of `leaf_m · 2^k` for the smallest `k` that fits, so that the real leaf edge
    /// is exactly `leaf_m` (metres).
    ///
    /// # Errors
    ///
    /// [`OctreeError::InvalidBounds`] when `bounds.min > bounds.max` on an axis, and
    /// the errors of [`Octree::new`].
    pub fn enclosing(bounds: Aabb, leaf_m: Real) -> Result<Self, OctreeError> {
        let names = [
            ("bounds.min.x", bounds.min.x),
            ("bounds.min.y", bounds.min.y),
            ("bounds.min.z", bounds.min.z),
            ("bounds.max.x", bounds.max.x),
            ("bounds.max.y", bounds.max.y),
            ("bounds.max.z", bounds.max.z),
            ("leaf_m", leaf_m),
        ];
        for (name, value) in names {
            if !value.is_finite() {
                return Err(OctreeError::not_finite(name, value));
            }
        }
        if leaf_m <= 0.0 {
            return Err(OctreeError::not_positive("leaf_m", leaf_m));
        }
        for (i, axis) in ['x', 'y', 'z'].into_iter().enumerate() {
            if bounds.min[i] > bounds.max[i] {
                return Err(OctreeError::InvalidBounds {
                    axis,
                    min: bounds.min[i],
                    max: bounds.max[i],
                });
            }
        }
        let extent = (bounds.max - bounds.min).max_element();
        let mut edge = leaf_m;
        let mut depth = 0;
        loop {
            if edge >= extent {
                let min = bounds.center() - Vec3::splat(edge * 0.5);
                if min.cmple(bounds.min).all() && (min + Vec3::splat(edge)).cmpge(bounds.max).all()
                {
                    return Self::new(min, edge, leaf_m);
                }
            }
            edge *= 2.0;
            depth += 1;
            if depth > MAX_DEPTH || !edge.is_finite() {
                return Err(OctreeError::TooDeep {
                    depth,
                    max: MAX_DEPTH,
                });
            }
        }
    }

    /// Depth of the leaves (the root is depth 0).
    #[inline]
    #[must_use]
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// The real leaf edge, metres: `root_m / 2^depth` (`<= leaf_m`).
    #[inline]
    #[must_use]
    pub fn leaf_edge(&self) -> Real {
        self.leaf_edge
    }

    /// The leaf size the octree was built with, metres (an upper bound of
    /// [`leaf_edge`](Self::leaf_edge)).
    #[inline]
    #[must_use]
    pub fn leaf_m(&self) -> Real {
        self.leaf_m
    }

    /// Edge of the root cube, metres.
    #[inline]
    #[must_use]
    pub fn root_m(&self) -> Real {
        self.root_m
    }

    /// The root cube (closed).
    #[inline]
    #[must_use]
    pub fn root(&self) -> Aabb {
        Aabb::cube(self.min, self.root_m)
    }

    /// Leaves per axis, `2^depth`.
    #[inline]
    #[must_use]
    pub fn resolution(&self) -> u32 {
        1 << self.depth
    }

    /// The grid of the nodes at `depth` (any depth, also deeper than the leaves).
    #[inline]
    #[must_use]
    pub fn grid(&self, depth: u32) -> GridSpec {
        let depth = depth.min(31);
        GridSpec {
            origin: self.min,
            cell: edge_at(self.root_m, depth),
            resolution: 1 << depth,
        }
    }

    /// The grid of the leaves, `grid(depth())`.
    #[inline]
    #[must_use]
    pub fn leaf_grid(&self) -> GridSpec {
        self.layout.grid
    }

    /// Whether no leaf is marked.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.regions.iter().flatten().all(|r| r.bricks.is_empty())
    }

    /// Marks every leaf that the closed triangle overlaps (see
    /// [`intersection_test_aabb_triangle`]) and adds the triangle to its payload.
    /// Returns how many leaves it overlapped (already marked ones included).
    ///
    /// Degenerate triangles (zero area) and triangles with a non-finite coordinate mark
    /// nothing and return 0; parts outside the root are ignored. This writes straight
    /// into the packed storage; for many triangles [`insert_all`](Self::insert_all) is
    /// faster (it expands the touched bricks once and packs them at the end).
    pub fn insert(&mut self, tri: &Triangle) -> usize {
        self.insert_with::<false>(tri)
    }

    /// [`insert`](Self::insert) without packing the touched bricks: a batch in progress.
    #[inline]
    fn insert_unflushed(&mut self, tri: &Triangle) -> usize {
        self.insert_with::<true>(tri)
    }

    /// [`insert`](Self::insert) into expanded bricks (`DENSE`, a batch in progress:
    /// [`flush`](Self::flush) ends it) or straight into the packed storage.
    #[inline]
    fn insert_with<const DENSE: bool>(&mut self, tri: &Triangle) -> usize {
        if !tri.is_finite() {
            return 0;
        }
        let sat = TriangleSat::of_finite(tri);
        if sat.is_degenerate() {
            return 0;
        }
        let Some((lo, hi)) = self.layout.candidates(&sat) else {
            return 0;
        };
        let lay = self.layout;
        let (rlo, rhi) = (lo >> lay.region_shift, hi >> lay.region_shift);
        if rlo == rhi {
            // The common case: one region.
            let ri = region_index(rlo);
            let region = self.regions[ri].get_or_insert_with(|| Box::new(Region::new()));
            if DENSE && region.dense.is_empty() {
                self.dirty.push(ri as u32);
            }
            return region.insert_batched::<DENSE>(&lay, rlo << lay.region_shift, &sat, lo, hi);
        }
        let mut count = 0;
        for rz in rlo.z..=rhi.z {
            for ry in rlo.y..=rhi.y {
                for rx in rlo.x..=rhi.x {
                    let rc = UVec3::new(rx, ry, rz);
                    let ri = region_index(rc);
                    let (base, last) = lay.region_span(rc);
                    let region = self.regions[ri].get_or_insert_with(|| Box::new(Region::new()));
                    if DENSE && region.dense.is_empty() {
                        self.dirty.push(ri as u32);
                    }
                    count += region.insert_batched::<DENSE>(
                        &lay,
                        base,
                        &sat,
                        lo.max(base),
                        hi.min(last),
                    );
                }
            }
        }
        count
    }

    /// Ends an insertion batch: packs the bricks that it expanded.
    fn flush(&mut self) {
        for ri in self.dirty.drain(..) {
            if let Some(r) = self.regions[ri as usize].as_deref_mut() {
                r.flush();
            }
        }
    }

    /// Inserts every triangle, in order: the same result as [`insert`](Self::insert)
    /// on each, faster.
    pub fn insert_all(&mut self, tris: &[Triangle]) {
        for t in tris {
            self.insert_unflushed(t);
        }
        self.flush();
    }

    /// Inserts the triangles on all threads of the current rayon pool. The result is
    /// identical to [`insert_all`](Self::insert_all): the same leaves, the same hits
    /// and bit-identical `sdf_sum`s.
    ///
    /// The root is split into `8^3` regions (`8^depth` when `depth < 3`); each worker
    /// owns whole regions and inserts, in input order, the triangles whose bounding
    /// box reaches its region (a triangle spanning regions is handled by each). Every
    /// leaf is therefore written by one worker, in input order. The per-region lists
    /// are built in parallel too (chunks of the input, concatenated in input order).
    /// Speed-up needs the data to span several regions (a root edge of at most ~8
    /// times the object's size).
    #[cfg(feature = "parallel")]
    pub fn par_insert(&mut self, tris: &[Triangle]) {
        use rayon::prelude::*;

        // Triangle indices are `u32`: absurdly long inputs go in consecutive batches
        // (the same result, input order is kept).
        if tris.len() > u32::MAX as usize {
            for part in tris.chunks(u32::MAX as usize) {
                self.par_insert(part);
            }
            return;
        }

        let lay = self.layout;
        let n_regions = self.regions.len();
        // Partition triangle indices by region, in input order: chunks of the input in
        // parallel, then each region's lists concatenated in chunk order.
        let chunk = tris
            .len()
            .div_ceil(4 * rayon::current_num_threads())
            .max(1024);
        let parts: Vec<Vec<Vec<u32>>> = tris
            .par_chunks(chunk)
            .enumerate()
            .map(|(c, part)| {
                let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n_regions];
                for (k, t) in part.iter().enumerate() {
                    let i = (c * chunk + k) as u32;
                    if !t.is_finite() {
                        continue;
                    }
                    let bb = t.aabb();
                    let Some((rlo, rhi)) = lay.regions_near(bb.min, bb.max) else {
                        continue;
                    };
                    for rz in rlo.z..=rhi.z {
                        for ry in rlo.y..=rhi.y {
                            for rx in rlo.x..=rhi.x {
                                lists[region_index(UVec3::new(rx, ry, rz))].push(i);
                            }
                        }
                    }
                }
                lists
            })
            .collect();
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); n_regions];
        for (ri, list) in lists.iter_mut().enumerate() {
            let len = parts.iter().map(|p| p[ri].len()).sum();
            if len > 0 {
                list.reserve_exact(len);
                for p in &parts {
                    list.extend_from_slice(&p[ri]);
                }
            }
        }
        drop(parts);
        let mut work: Vec<(usize, Box<Region>, Vec<u32>)> = lists
            .into_iter()
            .enumerate()
            .filter(|(_, l)| !l.is_empty())
            .map(|(ri, l)| {
                let region = self.regions[ri]
                    .take()
                    .unwrap_or_else(|| Box::new(Region::new()));
                (ri, region, l)
            })
            .collect();
        // Biggest first, for a better balance.
        work.sort_by_key(|w| std::cmp::Reverse(w.2.len()));
        work.par_iter_mut().for_each(|(ri, region, list)| {
            let rc = demorton3(*ri as u64);
            let (base, last) = lay.region_span(rc);
            for &i in list.iter() {
                // Listed triangles are finite.
                let sat = TriangleSat::of_finite(&tris[i as usize]);
                if sat.is_degenerate() {
                    continue;
                }
                // The lists are a superset: the part of the candidates in this region
                // may be empty.
                if let Some((lo, hi)) = lay.candidates(&sat) {
                    let (lo, hi) = (lo.max(base), hi.min(last));
                    if lo.cmple(hi).all() {
                        region.insert_batched::<true>(&lay, base, &sat, lo, hi);
                    }
                }
            }
            region.flush();
        });
        for (ri, region, _) in work {
            if !region.bricks.is_empty() {
                self.regions[ri] = Some(region);
            }
        }
    }

    /// The thesis's Algorithm 1, kept as the reference: test the node's box against the
    /// triangle, recurse into the 8 children of an overlapped node, mark the overlapped
    /// leaves. [`insert`](Self::insert) marks exactly the same leaves with the same
    /// payload (the tests check it); this one is much slower.
    pub fn insert_reference(&mut self, tri: &Triangle) -> usize {
        let Some(sat) = TriangleSat::new(tri) else {
            return 0;
        };
        if sat.is_degenerate() {
            return 0;
        }
        let mut leaves = Vec::new();
        self.descend(0, UVec3::ZERO, tri, &mut leaves);
        let grid = self.layout.grid;
        for &c in &leaves {
            self.add_cell(c, 1, sat.signed_distance(grid.cell_center(c)));
        }
        leaves.len()
    }

    fn descend(&self, depth: u32, coord: UVec3, tri: &Triangle, out: &mut Vec<UVec3>) {
        if !intersection_test_aabb_triangle(&self.grid(depth).cell_aabb(coord), tri) {
            return;
        }
        if depth == self.depth {
            out.push(coord);
            return;
        }
        for oct in 0..8u32 {
            let child = coord * 2 + UVec3::new(oct & 1, (oct >> 1) & 1, oct >> 2);
            self.descend(depth + 1, child, tri, out);
        }
    }

    /// Adds `hits` and `sdf` to the leaf `coord` (which must be inside the grid),
    /// marking it when new.
    fn add_cell(&mut self, coord: UVec3, hits: u32, sdf: f32) {
        let lay = self.layout;
        let rc = coord >> lay.region_shift;
        let (base, _) = lay.region_span(rc);
        let region =
            self.regions[morton3(rc) as usize].get_or_insert_with(|| Box::new(Region::new()));
        region.mark(&lay, coord - base, hits, sdf);
    }

    /// Every marked leaf, in increasing Morton (Z-order) code of its coordinates (bits
    /// interleaved as `…z1 y1 x1 z0 y0 x0`), which is also depth-first octree order with
    /// children in octant order `x + 2y + 4z`.
    pub fn leaves(&self) -> impl Iterator<Item = Cell> + '_ {
        let lay = self.layout;
        self.regions
            .iter()
            .enumerate()
            .filter_map(|(ri, r)| r.as_deref().map(|r| (ri, r)))
            .flat_map(move |(ri, region)| {
                let (base, _) = lay.region_span(demorton3(ri as u64));
                region
                    .bricks_in_order(lay.levels)
                    .into_iter()
                    .flat_map(move |(bc, bi)| {
                        let brick = region.bricks[bi as usize];
                        let origin = base + bc * 4;
                        BitIter(brick.mask).enumerate().map(move |(rank, bit)| {
                            let p = region.payload[brick.offset as usize + rank];
                            Cell {
                                coord: origin + demorton2(bit),
                                hits: p.hits,
                                sdf_sum: p.sdf,
                            }
                        })
                    })
            })
    }

    /// The marked nodes at `depth` (level of detail), in Morton order: a node is marked
    /// when any leaf below it is; its `hits` and `sdf_sum` are the sums over those
    /// leaves (in Morton order). The sdf is then only approximate: the leaves' distances
    /// are measured from their own centres, not from the node's. `depth >= depth()`
    /// gives the leaves.
    #[must_use]
    pub fn cells_at_depth(&self, depth: u32) -> Vec<Cell> {
        if depth >= self.depth {
            return self.leaves().collect();
        }
        let shift = self.depth - depth;
        let mut out: Vec<Cell> = Vec::new();
        for leaf in self.leaves() {
            let coord = leaf.coord >> shift;
            match out.last_mut() {
                Some(last) if last.coord == coord => {
                    last.hits = last.hits.saturating_add(leaf.hits);
                    last.sdf_sum += leaf.sdf_sum;
                }
                _ => out.push(Cell { coord, ..leaf }),
            }
        }
        out
    }

    /// The leaf at `coord`, when marked.
    #[must_use]
    pub fn get(&self, coord: UVec3) -> Option<Cell> {
        let lay = self.layout;
        if coord.cmpge(UVec3::splat(lay.grid.resolution)).any() {
            return None;
        }
        let rc = coord >> lay.region_shift;
        let (base, _) = lay.region_span(rc);
        let region = self.regions[morton3(rc) as usize].as_deref()?;
        let local = coord - base;
        let bi = region.find_brick(local >> 2, lay.levels)?;
        let brick = region.bricks[bi as usize];
        let m = 1u64 << morton2(local & UVec3::splat(3));
        if brick.mask & m == 0 {
            return None;
        }
        let rank = (brick.mask & (m - 1)).count_ones() as usize;
        let p = region.payload[brick.offset as usize + rank];
        Some(Cell {
            coord,
            hits: p.hits,
            sdf_sum: p.sdf,
        })
    }

    /// The thesis's value at point `p`: 1.0 when a marked leaf contains `p`, 0.0 when
    /// none does or `p` is outside the root (or not finite). Leaves are closed boxes: a
    /// point on a face shared by several leaves takes the value of the marked one.
    #[must_use]
    pub fn value_at(&self, p: Vec3) -> Real {
        let g = self.layout.grid;
        if !p.is_finite() {
            return 0.0;
        }
        let mut ranges = [(0u32, 0u32); 3];
        for (a, range) in ranges.iter_mut().enumerate() {
            let inv = self.layout.inv_cell;
            match cell_range_1d(g.origin[a], g.cell, inv, g.resolution, p[a], p[a]) {
                Some(r) => *range = r,
                None => return 0.0,
            }
        }
        for z in ranges[2].0..=ranges[2].1 {
            for y in ranges[1].0..=ranges[1].1 {
                for x in ranges[0].0..=ranges[0].1 {
                    if self.get(UVec3::new(x, y, z)).is_some() {
                        return 1.0;
                    }
                }
            }
        }
        0.0
    }

    /// Number of marked leaves.
    #[must_use]
    pub fn leaf_count(&self) -> usize {
        self.regions
            .iter()
            .flatten()
            .flat_map(|r| r.bricks.iter())
            .map(|b| b.mask.count_ones() as usize)
            .sum()
    }

    /// Number of nodes of the sparse octree at all depths, root and leaves included:
    /// every node with at least one marked leaf below it (`Σ_d cells_at_depth(d).len()`;
    /// 0 for an empty tree). This is the node count of the thesis's pointer octree, not
    /// the number of storage records (see [`memory_bytes`](Self::memory_bytes)).
    #[must_use]
    pub fn node_count(&self) -> usize {
        let mut count = 0usize;
        let mut prev: Option<u64> = None;
        for leaf in self.leaves() {
            let m = morton3(leaf.coord);
            count += match prev {
                None => self.depth as usize + 1,
                Some(q) => {
                    let level = (63 - (m ^ q).leading_zeros()) / 3;
                    level as usize + 1
                }
            };
            prev = Some(m);
        }
        count
    }

    /// Bytes of all storage the octree holds, spare capacity included: the struct, the
    /// region table, each region's node pool, brick pool and payload pool.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.regions.capacity() * std::mem::size_of::<Option<Box<Region>>>()
            + self
                .regions
                .iter()
                .flatten()
                .map(|r| r.memory_bytes())
                .sum::<usize>()
    }

    /// Releases spare capacity of the pools (freed payload blocks stay for reuse).
    pub fn shrink_to_fit(&mut self) {
        for r in self.regions.iter_mut().flatten() {
            r.nodes.shrink_to_fit();
            r.bricks.shrink_to_fit();
            r.payload.shrink_to_fit();
        }
    }

    /// Adds every leaf of `other` into `self`: the same leaves and hits as inserting
    /// both triangle sets into one tree; each `sdf_sum` is `self`'s plus `other`'s
    /// (equal to the one-tree sum up to the order of the float additions).
    ///
    /// # Errors
    ///
    /// [`OctreeError::RootMismatch`] when the roots differ, [`OctreeError::DepthMismatch`]
    /// when the depths do; `self` is then unchanged.
    pub fn merge(&mut self, other: &Octree) -> Result<(), OctreeError> {
        if self.min != other.min || self.root_m != other.root_m {
            return Err(OctreeError::RootMismatch {
                this: self.root(),
                other: other.root(),
            });
        }
        if self.depth != other.depth {
            return Err(OctreeError::DepthMismatch {
                this: self.depth,
                other: other.depth,
            });
        }
        for cell in other.leaves() {
            self.add_cell(cell.coord, cell.hits, cell.sdf_sum);
        }
        Ok(())
    }

    /// Removes every leaf and releases the storage (the octree's root and depth stay).
    pub fn clear(&mut self) {
        for r in &mut self.regions {
            *r = None;
        }
    }
}

impl Extend<Triangle> for Octree {
    fn extend<I: IntoIterator<Item = Triangle>>(&mut self, iter: I) {
        for t in iter {
            self.insert_unflushed(&t);
        }
        self.flush();
    }
}

impl<'a> Extend<&'a Triangle> for Octree {
    fn extend<I: IntoIterator<Item = &'a Triangle>>(&mut self, iter: I) {
        for t in iter {
            self.insert_unflushed(t);
        }
        self.flush();
    }
}

/// `edge / 2^depth`, exact.
#[inline]
fn edge_at(edge: Real, depth: u32) -> Real {
    edge / (1u64 << depth) as Real
}
