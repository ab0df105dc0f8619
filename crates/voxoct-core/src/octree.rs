//! The sparse octree of marked leaves.

use glam::{UVec3, Vec3};

use crate::error::OctreeError;
use crate::geometry::{Aabb, Cell, GridSpec, Real, Triangle};
use crate::intersection_test_aabb_triangle::{TriangleSat, intersection_test_aabb_triangle};

/// The deepest octree supported: `2^21` leaves per axis (Morton keys fit in 63 bits and
/// grid coordinates stay exact in `f32`).
pub const MAX_DEPTH: u32 = 21;

/// Depth of the dense top level: the root is split into `8^SPLIT_DEPTH` regions, each
/// an independent sparse subtree (this is the unit of parallel insertion).
const SPLIT_DEPTH: u32 = 3;
/// Empty child / free-list terminator / invalid brick.
const NONE: u32 = u32::MAX;
/// Payload block capacities (entries) of a brick, smallest first.
const CLASSES: [u32; 10] = [2, 4, 6, 8, 12, 16, 24, 32, 48, 64];
/// Dense slots (512 bytes each) a region may hold before an insertion batch packs them.
const DENSE_LIMIT: usize = 4096;
/// Brick class of a brick without a payload block.
const NO_BLOCK: u8 = u8::MAX;

/// What one leaf holds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Payload {
    hits: u32,
    sdf: f32,
}

/// A brick expanded for an insertion batch: its 64 leaves' payloads in place.
#[derive(Debug, Clone)]
struct DenseBrick {
    cells: [Payload; 64],
    mask: u64,
    /// The brick's index.
    brick: u32,
}

/// 4×4×4 leaves: occupancy bits in Morton order and a packed payload block.
#[derive(Debug, Clone, Copy)]
struct Brick {
    mask: u64,
    /// First payload entry of the block (meaningless while `class == NO_BLOCK`).
    offset: u32,
    /// Index into [`CLASSES`], or [`NO_BLOCK`].
    class: u8,
}

/// One of the `8^SPLIT_DEPTH` subtrees below the dense top level.
#[derive(Debug, Clone)]
struct Region {
    /// Interior nodes; `nodes[0]` is the region's root when the region has more than
    /// one brick. Entries are child node indices or, on the lowest interior level,
    /// brick indices; [`NONE`] for an empty child.
    nodes: Vec<[u32; 8]>,
    bricks: Vec<Brick>,
    /// Packed payload blocks, one per brick, plus freed blocks awaiting reuse.
    payload: Vec<Payload>,
    /// Heads of the free lists of each block class (the link lives in `hits`).
    free: [u32; CLASSES.len()],
    /// Direct-mapped cache of the dense slots of recently used bricks, keyed by the
    /// brick coordinates' parity so that neighbouring bricks never evict each other.
    cache_key: [u64; 8],
    cache_val: [u32; 8],
    /// The same for the bricks' indices, for insertion straight into the packed storage
    /// (always valid: bricks are never removed).
    brick_key: [u64; 8],
    brick_val: [u32; 8],
    /// Bricks being written by an insertion batch, expanded to 64 payloads each so that
    /// an update is a plain add; packed back by [`Region::flush`] at the end of every
    /// public method (outside a batch these are empty).
    dense: Vec<DenseBrick>,
    /// Dense slot of each brick ([`NONE`] when not expanded); empty outside a batch.
    slot_of: Vec<u32>,
}

/// Geometry shared by all regions of one octree.
#[derive(Debug, Clone, Copy)]
struct Layout {
    /// The leaf grid.
    grid: GridSpec,
    /// `depth - split`: leaf coordinate `>> region_shift` is the region coordinate.
    region_shift: u32,
    /// Interior levels of a region's brick tree.
    levels: u32,
    /// About `1 / grid.cell` (first guesses of cell indices only).
    inv_cell: Real,
}

/// A sparse octree over a cubic root whose leaves are marked by inserted triangles.
///
/// See the [crate documentation](crate) for the semantics and the storage layout.
#[derive(Debug, Clone)]
pub struct Octree {
    min: Vec3,
    edge: Real,
    leaf_size: Real,
    depth: u32,
    leaf_edge: Real,
    layout: Layout,
    /// Indexed by the Morton code of the region coordinates.
    regions: Vec<Option<Box<Region>>>,
    /// Regions written by the insertion batch in progress (empty between calls).
    dirty: Vec<u32>,
}

impl Octree {
    /// An empty octree whose root is the cube `min ..= min + edge`, subdivided down to
    /// the first depth whose node edge is `<= leaf_size`.
    ///
    /// # Errors
    ///
    /// [`OctreeError::NonFinite`] / [`OctreeError::NonPositive`] for bad values,
    /// [`OctreeError::LeafLargerThanRoot`], [`OctreeError::TooDeep`] beyond
    /// [`MAX_DEPTH`], and [`OctreeError::LeafBelowPrecision`] when the leaves are too
    /// small for `f32` coordinates at the root's position.
    pub fn new(min: Vec3, edge: Real, leaf_size: Real) -> Result<Self, OctreeError> {
        for (name, value) in [
            ("min.x", min.x),
            ("min.y", min.y),
            ("min.z", min.z),
            ("edge", edge),
            ("leaf_size", leaf_size),
        ] {
            if !value.is_finite() {
                return Err(OctreeError::NonFinite { name, value });
            }
        }
        for (name, value) in [("edge", edge), ("leaf_size", leaf_size)] {
            if value <= 0.0 {
                return Err(OctreeError::NonPositive { name, value });
            }
        }
        if leaf_size > edge {
            return Err(OctreeError::LeafLargerThanRoot { leaf_size, edge });
        }
        let max = min + Vec3::splat(edge);
        if let Some(value) = max.to_array().into_iter().find(|v| !v.is_finite()) {
            return Err(OctreeError::NonFinite {
                name: "min + edge",
                value,
            });
        }
        let mut depth = 0;
        while depth <= MAX_DEPTH && edge_at(edge, depth) > leaf_size {
            depth += 1;
        }
        if depth > MAX_DEPTH {
            let needed = (f64::from(edge) / f64::from(leaf_size)).log2().ceil() as u32;
            return Err(OctreeError::TooDeep {
                depth: needed.max(MAX_DEPTH + 1),
                max: MAX_DEPTH,
            });
        }
        let leaf_edge = edge_at(edge, depth);
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
            edge,
            leaf_size,
            depth,
            leaf_edge,
            layout,
            regions,
            dirty: Vec::new(),
        })
    }

    /// An empty octree whose cubic root encloses `bounds`: centred on them, with an edge
    /// of `leaf_size · 2^k` for the smallest `k` that fits, so that the real leaf edge
    /// is exactly `leaf_size`.
    ///
    /// # Errors
    ///
    /// [`OctreeError::InvalidBounds`] when `bounds.min > bounds.max` on an axis, and
    /// the errors of [`Octree::new`].
    pub fn enclosing(bounds: Aabb, leaf_size: Real) -> Result<Self, OctreeError> {
        let names = [
            ("bounds.min.x", bounds.min.x),
            ("bounds.min.y", bounds.min.y),
            ("bounds.min.z", bounds.min.z),
            ("bounds.max.x", bounds.max.x),
            ("bounds.max.y", bounds.max.y),
            ("bounds.max.z", bounds.max.z),
            ("leaf_size", leaf_size),
        ];
        for (name, value) in names {
            if !value.is_finite() {
                return Err(OctreeError::NonFinite { name, value });
            }
        }
        if leaf_size <= 0.0 {
            return Err(OctreeError::NonPositive {
                name: "leaf_size",
                value: leaf_size,
            });
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
        let mut edge = leaf_size;
        let mut depth = 0;
        loop {
            if edge >= extent {
                let min = bounds.center() - Vec3::splat(edge * 0.5);
                if min.cmple(bounds.min).all() && (min + Vec3::splat(edge)).cmpge(bounds.max).all()
                {
                    return Self::new(min, edge, leaf_size);
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

    /// The real leaf edge, `edge / 2^depth` (`<= leaf_size`).
    #[inline]
    #[must_use]
    pub fn leaf_edge(&self) -> Real {
        self.leaf_edge
    }

    /// The leaf size the octree was built with (an upper bound of [`leaf_edge`](Self::leaf_edge)).
    #[inline]
    #[must_use]
    pub fn leaf_size(&self) -> Real {
        self.leaf_size
    }

    /// Edge of the root cube, metres.
    #[inline]
    #[must_use]
    pub fn edge(&self) -> Real {
        self.edge
    }

    /// The root cube (closed).
    #[inline]
    #[must_use]
    pub fn root(&self) -> Aabb {
        Aabb::cube(self.min, self.edge)
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
            cell: edge_at(self.edge, depth),
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
        if self.min != other.min || self.edge != other.edge {
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

impl GridSpec {
    /// Plane `i` on axis `a`: the same value as `corner(..)[a]`.
    #[inline]
    fn plane(&self, a: usize, i: u32) -> Real {
        self.origin[a] + i as Real * self.cell
    }
}

/// On one axis of a grid (planes `o + i * cell`, `i = 0..=res`), the cells `a..=b` whose
/// closed extent meets `[lo, hi]`; `None` when the interval misses the grid. `inv` is
/// about `1 / cell`: it only makes the first guesses, which the loops make exact.
#[inline(always)]
fn cell_range_1d(
    o: Real,
    cell: Real,
    inv: Real,
    res: u32,
    lo: Real,
    hi: Real,
) -> Option<(u32, u32)> {
    // The same expression as `GridSpec::corner`, component-wise.
    let plane = |i: u32| o + i as Real * cell;
    // (NaN fails both comparisons.)
    if !(hi >= o && lo <= plane(res)) {
        return None;
    }
    let last = res - 1;
    // Truncating guesses (`as` saturates: negative and NaN give 0).
    let guess = |v: Real| (((v - o) * inv) as u32).min(last);
    // Each loop sits behind its first test so that the compiler does not turn it into
    // a vectorised search (which costs far more than the usual zero or one step).
    let mut a = guess(lo);
    if a < last && plane(a + 1) < lo {
        while a < last && plane(a + 1) < lo {
            a += 1;
        }
    } else if a > 0 && plane(a) >= lo {
        while a > 0 && plane(a) >= lo {
            a -= 1;
        }
    }
    let mut b = guess(hi);
    if b > 0 && plane(b) > hi {
        while b > 0 && plane(b) > hi {
            b -= 1;
        }
    } else if b < last && plane(b + 1) <= hi {
        while b < last && plane(b + 1) <= hi {
            b += 1;
        }
    }
    Some((a, b))
}

impl Layout {
    /// The leaf cells whose closed boxes meet the closed box `bmin..=bmax`, clamped to
    /// the grid; `None` when the box misses the root. Exactly the cells whose boxes
    /// pass the three box-normal axes of the overlap test.
    #[inline]
    fn candidates_of_box(&self, bmin: Vec3, bmax: Vec3) -> Option<(UVec3, UVec3)> {
        let (g, inv) = (&self.grid, self.inv_cell);
        let (x0, x1) = cell_range_1d(g.origin.x, g.cell, inv, g.resolution, bmin.x, bmax.x)?;
        let (y0, y1) = cell_range_1d(g.origin.y, g.cell, inv, g.resolution, bmin.y, bmax.y)?;
        let (z0, z1) = cell_range_1d(g.origin.z, g.cell, inv, g.resolution, bmin.z, bmax.z)?;
        Some((UVec3::new(x0, y0, z0), UVec3::new(x1, y1, z1)))
    }

    #[inline]
    fn candidates(&self, sat: &TriangleSat) -> Option<(UVec3, UVec3)> {
        self.candidates_of_box(sat.bmin, sat.bmax)
    }

    /// The regions (first and last region coordinates) that the candidate cells of
    /// the box `bmin..=bmax` (finite) may reach: a superset, from truncated guesses
    /// widened by two cells each way (they are within one cell of the exact ranges);
    /// `None` only when the box is surely outside the root.
    #[cfg(feature = "parallel")]
    #[inline]
    fn regions_near(&self, bmin: Vec3, bmax: Vec3) -> Option<(UVec3, UVec3)> {
        let g = &self.grid;
        let last = i64::from(g.resolution - 1);
        let mut r = [(0u32, 0u32); 3];
        for (a, r) in r.iter_mut().enumerate() {
            // `as` saturates; the inputs are finite.
            let guess = |v: Real| ((v - g.origin[a]) * self.inv_cell) as i64;
            let (lo, hi) = (guess(bmin[a]) - 2, guess(bmax[a]) + 2);
            if hi < 0 || lo > last {
                return None;
            }
            *r = (
                (lo.max(0) as u32) >> self.region_shift,
                (hi.min(last) as u32) >> self.region_shift,
            );
        }
        Some((
            UVec3::new(r[0].0, r[1].0, r[2].0),
            UVec3::new(r[0].1, r[1].1, r[2].1),
        ))
    }

    /// First and last leaf coordinates of region `rc`.
    #[inline]
    fn region_span(&self, rc: UVec3) -> (UVec3, UVec3) {
        let base = rc << self.region_shift;
        (base, base + UVec3::splat((1 << self.region_shift) - 1))
    }
}

impl Region {
    fn new() -> Self {
        Self {
            nodes: Vec::new(),
            bricks: Vec::new(),
            payload: Vec::new(),
            free: [NONE; CLASSES.len()],
            cache_key: [u64::MAX; 8],
            cache_val: [NONE; 8],
            brick_key: [u64::MAX; 8],
            brick_val: [NONE; 8],
            dense: Vec::new(),
            slot_of: Vec::new(),
        }
    }

    fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.nodes.capacity() * std::mem::size_of::<[u32; 8]>()
            + self.bricks.capacity() * std::mem::size_of::<Brick>()
            + self.payload.capacity() * std::mem::size_of::<Payload>()
    }

    /// [`insert`](Self::insert) of one triangle; in a batch (`DENSE`) first packs the
    /// expanded bricks when they take more than [`DENSE_LIMIT`] slots.
    #[inline]
    fn insert_batched<const DENSE: bool>(
        &mut self,
        lay: &Layout,
        base: UVec3,
        sat: &TriangleSat,
        lo: UVec3,
        hi: UVec3,
    ) -> usize {
        if DENSE && self.dense.len() >= DENSE_LIMIT {
            self.flush();
        }
        self.insert::<DENSE>(lay, base, sat, lo, hi)
    }

    /// Marks the cells of `lo..=hi` (inside this region, whose first leaf is `base`)
    /// that the triangle overlaps; returns how many.
    fn insert<const DENSE: bool>(
        &mut self,
        lay: &Layout,
        base: UVec3,
        sat: &TriangleSat,
        lo: UVec3,
        hi: UVec3,
    ) -> usize {
        let n = hi - lo + UVec3::ONE;
        if n.max_element() <= 4 {
            return self.insert_small::<DENSE>(lay, base, sat, lo, n);
        }
        if n.max_element() <= 8 {
            // Up to 2×2×2 blocks of the 4×4×4 path, not tested as wholes.
            let mut count = 0;
            for tz in 0..2u32 {
                for ty in 0..2u32 {
                    for tx in 0..2u32 {
                        let a = lo + UVec3::new(tx, ty, tz) * 4;
                        if a.cmple(hi).all() {
                            let b = hi.min(a + UVec3::splat(3));
                            count +=
                                self.insert_small::<DENSE>(lay, base, sat, a, b - a + UVec3::ONE);
                        }
                    }
                }
            }
            return count;
        }
        // Large: prune with the test on the block's box (exact, thanks to the test's
        // monotonicity and to grid corners that nest bit for bit), then halve.
        let grid = &lay.grid;
        let block = Aabb::new(grid.corner(lo), grid.corner(hi + UVec3::ONE));
        if !sat.overlaps(&block) {
            return 0;
        }
        let axis = if n.x >= n.y && n.x >= n.z {
            0
        } else if n.y >= n.z {
            1
        } else {
            2
        };
        let mid = lo[axis] + n[axis] / 2;
        let mut hi_a = hi;
        hi_a[axis] = mid - 1;
        let mut lo_b = lo;
        lo_b[axis] = mid;
        self.insert::<DENSE>(lay, base, sat, lo, hi_a)
            + self.insert::<DENSE>(lay, base, sat, lo_b, hi)
    }

    /// [`insert`](Self::insert) for a block of at most 4×4×4 cells from `lo`: the
    /// common case, triangles about the size of a leaf.
    #[inline]
    fn insert_small<const DENSE: bool>(
        &mut self,
        lay: &Layout,
        base: UVec3,
        sat: &TriangleSat,
        lo: UVec3,
        n: UVec3,
    ) -> usize {
        let g = &lay.grid;
        let dims = [n.x as usize, n.y as usize, n.z as usize];
        // The bounding-box axes hold for every cell of the candidate range; the planes
        // are the very `f32` corners of `GridSpec::cell_aabb`, widened to f64, and
        // further (finite) planes up to 4 cells: `block_mask` evaluates blocks of fixed
        // sizes and drops the padding cells.
        let planes: [[f64; 5]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|t| f64::from(g.plane(a, lo[a] + t as u32)))
        });
        let mut mask = sat.block_mask(&planes, dims);
        if mask == 0 {
            return 0;
        }
        let count = mask.count_ones() as usize;
        // Per axis and cell of the block: the sdf term (cell `(i, j, k)` has sdf
        // `((terms[0][i] + terms[1][j]) + terms[2][k]) as f32`, bit for bit
        // `TriangleSat::signed_distance` of `GridSpec::cell_center`), the part of the
        // brick-cache key and way, and the Morton bits within the brick.
        let l0 = lo - base;
        let mut terms = [[0.0f64; 4]; 3];
        let mut keys = [[0u64; 4]; 3];
        let mut ways = [[0u32; 4]; 3];
        let mut bits = [[0u32; 4]; 3];
        for a in 0..3 {
            let (o, cell) = (g.origin[a], g.cell);
            // The same expression as `GridSpec::cell_center`, component-wise
            // (coordinates below 2^22 convert exactly from i32).
            let c: [Real; 4] =
                std::array::from_fn(|t| o + ((lo[a] + t as u32) as i32 as Real + 0.5) * cell);
            terms[a] = std::array::from_fn(|t| sat.sdf_term(a, c[t]));
            // Cell `t` is in brick `(l0 >> 2) + carry` at position `(l0 & 3) + t` mod 4.
            let (b0, r0) = (l0[a] >> 2, (l0[a] & 3) as usize);
            let (kb, wb) = (u64::from(b0) << (21 * a), b0 & 1);
            for t in 0..4 {
                let (carry, r) = (CARRY[r0 + t], (r0 + t) & 3);
                keys[a][t] = kb + (u64::from(carry) << (21 * a));
                ways[a][t] = ((wb ^ carry) & 1) << a;
                bits[a][t] = morton2_axis(r as u32) << a;
            }
        }
        while mask != 0 {
            let bit = mask.trailing_zeros();
            mask &= mask - 1;
            let (i, j, k) = (
                (bit & 3) as usize,
                ((bit >> 2) & 3) as usize,
                (bit >> 4) as usize,
            );
            let sdf = ((terms[0][i] + terms[1][j]) + terms[2][k]) as f32;
            let key = keys[0][i] | keys[1][j] | keys[2][k];
            let way = ((ways[0][i] | ways[1][j] | ways[2][k]) & 7) as usize;
            let bit = bits[0][i] | bits[1][j] | bits[2][k];
            if DENSE {
                let slot = if self.cache_key[way] == key {
                    self.cache_val[way]
                } else {
                    self.slot_miss(key, lay.levels, way)
                };
                self.add_dense(slot, bit, sdf);
            } else {
                let b = if self.brick_key[way] == key {
                    self.brick_val[way]
                } else {
                    self.brick_miss(key, lay.levels, way)
                };
                self.add_known(b, bit, sdf);
            }
        }
        count
    }

    /// Adds to the leaf at region-local coordinates `local` (packed storage, outside
    /// a batch).
    fn mark(&mut self, lay: &Layout, local: UVec3, hits: u32, sdf: f32) {
        debug_assert!(self.dense.is_empty());
        let b = self.find_or_create_brick(local >> 2, lay.levels);
        self.add(b, morton2(local & UVec3::splat(3)), hits, sdf);
    }

    /// One hit and `sdf` added to bit `bit` of brick `b` in the packed storage, the
    /// common case inline: the leaf is already marked.
    #[inline(always)]
    fn add_known(&mut self, b: u32, bit: u32, sdf: f32) {
        let brick = self.bricks[b as usize];
        let m = 1u64 << (bit & 63);
        if brick.mask & m != 0 {
            let rank = (brick.mask & (m - 1)).count_ones() as usize;
            let p = &mut self.payload[brick.offset as usize + rank];
            p.hits = p.hits.saturating_add(1);
            p.sdf += sdf;
            return;
        }
        self.add_new(b, bit, sdf);
    }

    /// [`add_known`](Self::add_known) out of line, for a leaf not yet marked.
    #[inline(never)]
    fn add_new(&mut self, b: u32, bit: u32, sdf: f32) {
        self.add(b, bit, 1, sdf);
    }

    /// The brick whose coordinates `x | y << 21 | z << 42` are `key` (cache way
    /// `way`) when the packed path's cache misses, created when missing.
    #[inline(never)]
    fn brick_miss(&mut self, key: u64, levels: u32, way: usize) -> u32 {
        let b = self.find_or_create_brick(brick_coords(key), levels);
        self.brick_key[way] = key;
        self.brick_val[way] = b;
        b
    }

    /// Adds one hit and `sdf` to bit `bit` of dense slot `slot`.
    #[inline(always)]
    fn add_dense(&mut self, slot: u32, bit: u32, sdf: f32) {
        let d = &mut self.dense[slot as usize];
        let p = &mut d.cells[(bit & 63) as usize];
        p.hits = p.hits.saturating_add(1);
        p.sdf += sdf;
        d.mask |= 1u64 << (bit & 63);
    }

    /// The dense slot of the brick whose coordinates `x | y << 21 | z << 42` are `key`
    /// (cache way `way`) when the cache misses: the brick created and expanded when
    /// needed.
    #[inline(never)]
    fn slot_miss(&mut self, key: u64, levels: u32, way: usize) -> u32 {
        let b = self.find_or_create_brick(brick_coords(key), levels);
        if self.slot_of.len() < self.bricks.len() {
            self.slot_of.resize(self.bricks.len(), NONE);
        }
        let mut slot = self.slot_of[b as usize];
        if slot == NONE {
            slot = self.dense.len() as u32;
            let brick = self.bricks[b as usize];
            self.dense.push(DenseBrick {
                cells: [Payload::default(); 64],
                mask: brick.mask,
                brick: b,
            });
            let block = &mut self.dense[slot as usize].cells;
            for (rank, bit) in BitIter(brick.mask).enumerate() {
                block[bit as usize] = self.payload[brick.offset as usize + rank];
            }
            self.slot_of[b as usize] = slot;
        }
        self.cache_key[way] = key;
        self.cache_val[way] = slot;
        slot
    }

    /// Packs every dense slot back into its brick's payload block (a block of the
    /// smallest class that fits when the old one is too small, the old one freed) and
    /// ends the batch. The leaves and payloads are those of updating the packed storage
    /// directly, in the same order.
    fn flush(&mut self) {
        if self.dense.is_empty() {
            return;
        }
        for slot in 0..self.dense.len() {
            let (b, mask) = (self.dense[slot].brick as usize, self.dense[slot].mask);
            let brick = self.bricks[b];
            let n = mask.count_ones();
            let off = if brick.class != NO_BLOCK && CLASSES[brick.class as usize] >= n {
                brick.offset as usize
            } else {
                let class = CLASSES
                    .iter()
                    .position(|&c| c >= n)
                    .unwrap_or(CLASSES.len() - 1);
                let off = self.alloc_block(class);
                if brick.class != NO_BLOCK {
                    self.free_block(brick.class as usize, brick.offset as usize);
                }
                let bk = &mut self.bricks[b];
                bk.offset = off as u32;
                bk.class = class as u8;
                off
            };
            let block = &self.dense[slot].cells;
            for (rank, bit) in BitIter(mask).enumerate() {
                self.payload[off + rank] = block[bit as usize];
            }
            self.bricks[b].mask = mask;
        }
        self.dense = Vec::new();
        self.slot_of = Vec::new();
        self.cache_key = [u64::MAX; 8];
        self.cache_val = [NONE; 8];
    }

    fn new_brick(&mut self) -> u32 {
        reserve_gently(&mut self.bricks, 1);
        self.bricks.push(Brick {
            mask: 0,
            offset: 0,
            class: NO_BLOCK,
        });
        (self.bricks.len() - 1) as u32
    }

    fn find_or_create_brick(&mut self, bc: UVec3, levels: u32) -> u32 {
        if levels == 0 {
            if self.bricks.is_empty() {
                self.new_brick();
            }
            return 0;
        }
        if self.nodes.is_empty() {
            self.nodes.push([NONE; 8]);
        }
        let mut node = 0usize;
        for level in (0..levels).rev() {
            let oct = octant(bc, level);
            let child = self.nodes[node][oct];
            if level == 0 {
                if child != NONE {
                    return child;
                }
                let b = self.new_brick();
                self.nodes[node][oct] = b;
                return b;
            }
            if child == NONE {
                reserve_gently(&mut self.nodes, 1);
                self.nodes.push([NONE; 8]);
                let c = (self.nodes.len() - 1) as u32;
                self.nodes[node][oct] = c;
                node = c as usize;
            } else {
                node = child as usize;
            }
        }
        NONE // unreachable: the loop returns on level 0
    }

    fn find_brick(&self, bc: UVec3, levels: u32) -> Option<u32> {
        if levels == 0 {
            return (!self.bricks.is_empty()).then_some(0);
        }
        let mut node = *self.nodes.first()?;
        for level in (0..levels).rev() {
            let child = node[octant(bc, level)];
            if child == NONE {
                return None;
            }
            if level == 0 {
                return Some(child);
            }
            node = self.nodes[child as usize];
        }
        None
    }

    /// Adds `hits` and `sdf` to bit `bit` of brick `b`.
    #[inline]
    fn add(&mut self, b: u32, bit: u32, hits: u32, sdf: f32) {
        let brick = self.bricks[b as usize];
        let m = 1u64 << bit;
        let rank = (brick.mask & (m - 1)).count_ones() as usize;
        if brick.mask & m != 0 {
            let p = &mut self.payload[brick.offset as usize + rank];
            p.hits = p.hits.saturating_add(hits);
            p.sdf += sdf;
            return;
        }
        let n = brick.mask.count_ones() as usize;
        let new = Payload { hits, sdf };
        let off = if brick.class != NO_BLOCK && n < CLASSES[brick.class as usize] as usize {
            let off = brick.offset as usize;
            self.payload
                .copy_within(off + rank..off + n, off + rank + 1);
            off
        } else {
            let class = if brick.class == NO_BLOCK {
                0
            } else {
                brick.class as usize + 1
            };
            let off = self.alloc_block(class);
            if brick.class != NO_BLOCK {
                let old = brick.offset as usize;
                self.payload.copy_within(old..old + rank, off);
                self.payload
                    .copy_within(old + rank..old + n, off + rank + 1);
                self.free_block(brick.class as usize, old);
            }
            let bk = &mut self.bricks[b as usize];
            bk.offset = off as u32;
            bk.class = class as u8;
            off
        };
        self.payload[off + rank] = new;
        self.bricks[b as usize].mask |= m;
    }

    fn alloc_block(&mut self, class: usize) -> usize {
        let head = self.free[class];
        if head != NONE {
            self.free[class] = self.payload[head as usize].hits;
            return head as usize;
        }
        let cap = CLASSES[class] as usize;
        let off = self.payload.len();
        reserve_gently(&mut self.payload, cap);
        self.payload.resize(off + cap, Payload::default());
        off
    }

    fn free_block(&mut self, class: usize, off: usize) {
        self.payload[off].hits = self.free[class];
        self.free[class] = off as u32;
    }

    /// `(brick coordinates, brick index)` of every brick, in Morton order.
    fn bricks_in_order(&self, levels: u32) -> Vec<(UVec3, u32)> {
        let mut out = Vec::with_capacity(self.bricks.len());
        if levels == 0 {
            if !self.bricks.is_empty() {
                out.push((UVec3::ZERO, 0));
            }
        } else if !self.nodes.is_empty() {
            self.collect_bricks(0, levels, UVec3::ZERO, &mut out);
        }
        out
    }

    fn collect_bricks(&self, node: u32, level: u32, coord: UVec3, out: &mut Vec<(UVec3, u32)>) {
        for (oct, &child) in self.nodes[node as usize].iter().enumerate() {
            if child == NONE {
                continue;
            }
            let oct = oct as u32;
            let c = coord * 2 + UVec3::new(oct & 1, (oct >> 1) & 1, oct >> 2);
            if level == 1 {
                out.push((c, child));
            } else {
                self.collect_bricks(child, level - 1, c, out);
            }
        }
    }
}

/// Grows `v`'s capacity by about a quarter (not the doubling of `Vec`), so that spare
/// capacity stays small.
#[inline]
fn reserve_gently<T>(v: &mut Vec<T>, extra: usize) {
    if v.capacity() - v.len() < extra {
        v.reserve_exact((v.len() / 4).max(extra).max(16));
    }
}

#[inline]
fn octant(bc: UVec3, level: u32) -> usize {
    (((bc.x >> level) & 1) | ((bc.y >> level) & 1) << 1 | ((bc.z >> level) & 1) << 2) as usize
}

/// Whether position `r` (below 7) of a row starting inside a brick is in the next brick.
const CARRY: [u32; 8] = [0, 0, 0, 0, 1, 1, 1, 1];

/// The brick coordinates of a brick-cache key `x | y << 21 | z << 42`.
#[inline]
fn brick_coords(key: u64) -> UVec3 {
    let m = (1 << 21) - 1;
    UVec3::new((key & m) as u32, (key >> 21 & m) as u32, (key >> 42) as u32)
}

/// Index of the region at region coordinates `rc` (each below `2^SPLIT_DEPTH`): their
/// Morton code, by table.
#[inline(always)]
fn region_index(rc: UVec3) -> usize {
    const SPREAD: [u16; 8] = [0, 1, 8, 9, 64, 65, 72, 73];
    let s = |v: u32| usize::from(SPREAD[(v & 7) as usize]);
    s(rc.x) | s(rc.y) << 1 | s(rc.z) << 2
}

/// Morton index of a 4×4×4 local coordinate (bits `z1 y1 x1 z0 y0 x0`).
#[inline]
fn morton2(l: UVec3) -> u32 {
    morton2_axis(l.x) | morton2_axis(l.y) << 1 | morton2_axis(l.z) << 2
}

/// The Morton bits of one coordinate below 4 (x's place; shift by the axis).
#[inline(always)]
fn morton2_axis(v: u32) -> u32 {
    (v & 1) | (v & 2) << 2
}

#[inline]
fn demorton2(bit: u32) -> UVec3 {
    UVec3::new(
        (bit & 1) | (bit >> 2) & 2,
        (bit >> 1) & 1 | (bit >> 3) & 2,
        (bit >> 2) & 1 | (bit >> 4) & 2,
    )
}

/// Spreads the low 21 bits of `v` to every third bit.
#[inline]
fn part1by2(v: u32) -> u64 {
    let mut x = u64::from(v) & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

#[inline]
fn compact1by2(x: u64) -> u32 {
    let mut x = x & 0x1249_2492_4924_9249;
    x = (x | x >> 2) & 0x10c3_0c30_c30c_30c3;
    x = (x | x >> 4) & 0x100f_00f0_0f00_f00f;
    x = (x | x >> 8) & 0x001f_0000_ff00_00ff;
    x = (x | x >> 16) & 0x001f_0000_0000_ffff;
    x = (x | x >> 32) & 0x1f_ffff;
    x as u32
}

/// Morton code (x in the lowest bit) of coordinates below `2^21`.
#[inline]
fn morton3(c: UVec3) -> u64 {
    part1by2(c.x) | part1by2(c.y) << 1 | part1by2(c.z) << 2
}

#[inline]
fn demorton3(m: u64) -> UVec3 {
    UVec3::new(compact1by2(m), compact1by2(m >> 1), compact1by2(m >> 2))
}

/// Set bits of a mask, lowest first.
struct BitIter(u64);

impl Iterator for BitIter {
    type Item = u32;
    #[inline]
    fn next(&mut self) -> Option<u32> {
        if self.0 == 0 {
            return None;
        }
        let b = self.0.trailing_zeros();
        self.0 &= self.0 - 1;
        Some(b)
    }
}

// Brick records are 16 bytes, payload entries 8, nodes 32: the figures of the crate docs.
const _: () = assert!(std::mem::size_of::<Brick>() == 16);
const _: () = assert!(std::mem::size_of::<Payload>() == 8);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_round_trips() {
        for c in [
            UVec3::ZERO,
            UVec3::new(1, 2, 3),
            UVec3::new(0x1f_ffff, 0, 7),
            UVec3::splat(0x1f_ffff),
        ] {
            assert_eq!(demorton3(morton3(c)), c);
        }
        assert_eq!(morton3(UVec3::new(1, 0, 0)), 1);
        assert_eq!(morton3(UVec3::new(0, 1, 0)), 2);
        assert_eq!(morton3(UVec3::new(0, 0, 1)), 4);
        for bit in 0..64 {
            assert_eq!(morton2(demorton2(bit)), bit);
            assert_eq!(u64::from(morton2(demorton2(bit))), morton3(demorton2(bit)));
        }
    }

    #[test]
    fn payload_blocks_grow_and_stay_sorted() {
        let mut r = Region::new();
        let b = r.new_brick();
        // Insert all 64 bits in a scrambled order; each gets hits = bit + 1.
        for i in 0..64u32 {
            let bit = (i * 37) % 64;
            r.add(b, bit, bit + 1, bit as f32);
        }
        let brick = r.bricks[b as usize];
        assert_eq!(brick.mask, u64::MAX);
        for (rank, bit) in BitIter(brick.mask).enumerate() {
            let p = r.payload[brick.offset as usize + rank];
            assert_eq!(p.hits, bit + 1);
            assert_eq!(p.sdf, bit as f32);
        }
        // Freed blocks are reused by a second brick.
        let before = r.payload.len();
        let b2 = r.new_brick();
        for bit in 0..8 {
            r.add(b2, bit, 1, 0.0);
        }
        assert_eq!(r.payload.len(), before);
    }

    #[test]
    fn candidate_range_is_closed() {
        let t = Octree::new(Vec3::ZERO, 1.0, 0.25).unwrap();
        let lay = t.layout;
        // A box touching the plane x = 0.5 from below reaches cell 2 too.
        let (lo, hi) = lay
            .candidates_of_box(Vec3::new(0.3, 0.1, 0.1), Vec3::new(0.5, 0.1, 0.1))
            .unwrap();
        assert_eq!((lo.x, hi.x), (1, 2));
        assert_eq!((lo.y, hi.y), (0, 0));
        assert!(
            lay.candidates_of_box(Vec3::splat(1.01), Vec3::splat(2.0))
                .is_none()
        );
        let (lo, hi) = lay
            .candidates_of_box(Vec3::splat(-5.0), Vec3::splat(5.0))
            .unwrap();
        assert_eq!((lo, hi), (UVec3::ZERO, UVec3::splat(3)));
    }
}
