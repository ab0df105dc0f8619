//! The storage of one region: a sparse tree of interior nodes over bricks of 4×4×4
//! leaves, whose payloads are packed per brick (see ARCHITECTURE.md, "Storage").

use glam::UVec3;

use super::layout::Layout;
use super::morton::*;
use crate::geometry::{Aabb, Real};
use crate::intersection_test_aabb_triangle::TriangleSat;

/// Empty child / free-list terminator / invalid brick.
pub(super) const NONE: u32 = u32::MAX;
/// Payload block capacities (entries) of a brick, smallest first.
pub(super) const CLASSES: [u32; 10] = [2, 4, 6, 8, 12, 16, 24, 32, 48, 64];
/// Dense slots (512 bytes each) a region may hold before an insertion batch packs them.
pub(super) const DENSE_LIMIT: usize = 4096;
/// Brick class of a brick without a payload block.
pub(super) const NO_BLOCK: u8 = u8::MAX;

/// What one leaf holds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Payload {
    pub(super) hits: u32,
    pub(super) sdf: f32,
}

/// A brick expanded for an insertion batch: its 64 leaves' payloads in place.
#[derive(Debug, Clone)]
pub(super) struct DenseBrick {
    pub(super) cells: [Payload; 64],
    pub(super) mask: u64,
    /// The brick's index.
    pub(super) brick: u32,
}

/// 4×4×4 leaves: occupancy bits in Morton order and a packed payload block.
#[derive(Debug, Clone, Copy)]
pub(super) struct Brick {
    pub(super) mask: u64,
    /// First payload entry of the block (meaningless while `class == NO_BLOCK`).
    pub(super) offset: u32,
    /// Index into [`CLASSES`], or [`NO_BLOCK`].
    pub(super) class: u8,
}

/// One of the `8^SPLIT_DEPTH` subtrees below the dense top level.
#[derive(Debug, Clone)]
pub(super) struct Region {
    /// Interior nodes; `nodes[0]` is the region's root when the region has more than
    /// one brick. Entries are child node indices or, on the lowest interior level,
    /// brick indices; [`NONE`] for an empty child.
    pub(super) nodes: Vec<[u32; 8]>,
    pub(super) bricks: Vec<Brick>,
    /// Packed payload blocks, one per brick, plus freed blocks awaiting reuse.
    pub(super) payload: Vec<Payload>,
    /// Heads of the free lists of each block class (the link lives in `hits`).
    pub(super) free: [u32; CLASSES.len()],
    /// Direct-mapped cache of the dense slots of recently used bricks, keyed by the
    /// brick coordinates' parity so that neighbouring bricks never evict each other.
    pub(super) cache_key: [u64; 8],
    pub(super) cache_val: [u32; 8],
    /// The same for the bricks' indices, for insertion straight into the packed storage
    /// (always valid: bricks are never removed).
    pub(super) brick_key: [u64; 8],
    pub(super) brick_val: [u32; 8],
    /// Bricks being written by an insertion batch, expanded to 64 payloads each so that
    /// an update is a plain add; packed back by [`Region::flush`] at the end of every
    /// public method (outside a batch these are empty).
    pub(super) dense: Vec<DenseBrick>,
    /// Dense slot of each brick ([`NONE`] when not expanded); empty outside a batch.
    pub(super) slot_of: Vec<u32>,
}

impl Region {
    pub(super) fn new() -> Self {
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

    pub(super) fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.nodes.capacity() * std::mem::size_of::<[u32; 8]>()
            + self.bricks.capacity() * std::mem::size_of::<Brick>()
            + self.payload.capacity() * std::mem::size_of::<Payload>()
    }

    /// [`insert`](Self::insert) of one triangle; in a batch (`DENSE`) first packs the
    /// expanded bricks when they take more than [`DENSE_LIMIT`] slots.
    #[inline]
    pub(super) fn insert_batched<const DENSE: bool>(
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
    pub(super) fn insert<const DENSE: bool>(
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
    pub(super) fn insert_small<const DENSE: bool>(
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
    pub(super) fn mark(&mut self, lay: &Layout, local: UVec3, hits: u32, sdf: f32) {
        debug_assert!(self.dense.is_empty());
        let b = self.find_or_create_brick(local >> 2, lay.levels);
        self.add(b, morton2(local & UVec3::splat(3)), hits, sdf);
    }

    /// One hit and `sdf` added to bit `bit` of brick `b` in the packed storage, the
    /// common case inline: the leaf is already marked.
    #[inline(always)]
    pub(super) fn add_known(&mut self, b: u32, bit: u32, sdf: f32) {
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
    pub(super) fn add_new(&mut self, b: u32, bit: u32, sdf: f32) {
        self.add(b, bit, 1, sdf);
    }

    /// The brick whose coordinates `x | y << 21 | z << 42` are `key` (cache way
    /// `way`) when the packed path's cache misses, created when missing.
    #[inline(never)]
    pub(super) fn brick_miss(&mut self, key: u64, levels: u32, way: usize) -> u32 {
        let b = self.find_or_create_brick(brick_coords(key), levels);
        self.brick_key[way] = key;
        self.brick_val[way] = b;
        b
    }

    /// Adds one hit and `sdf` to bit `bit` of dense slot `slot`.
    #[inline(always)]
    pub(super) fn add_dense(&mut self, slot: u32, bit: u32, sdf: f32) {
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
    pub(super) fn slot_miss(&mut self, key: u64, levels: u32, way: usize) -> u32 {
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
    pub(super) fn flush(&mut self) {
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

    pub(super) fn new_brick(&mut self) -> u32 {
        reserve_gently(&mut self.bricks, 1);
        self.bricks.push(Brick {
            mask: 0,
            offset: 0,
            class: NO_BLOCK,
        });
        (self.bricks.len() - 1) as u32
    }

    pub(super) fn find_or_create_brick(&mut self, bc: UVec3, levels: u32) -> u32 {
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

    pub(super) fn find_brick(&self, bc: UVec3, levels: u32) -> Option<u32> {
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
    pub(super) fn add(&mut self, b: u32, bit: u32, hits: u32, sdf: f32) {
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

    pub(super) fn alloc_block(&mut self, class: usize) -> usize {
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

    pub(super) fn free_block(&mut self, class: usize, off: usize) {
        self.payload[off].hits = self.free[class];
        self.free[class] = off as u32;
    }

    /// `(brick coordinates, brick index)` of every brick, in Morton order.
    pub(super) fn bricks_in_order(&self, levels: u32) -> Vec<(UVec3, u32)> {
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

    pub(super) fn collect_bricks(
        &self,
        node: u32,
        level: u32,
        coord: UVec3,
        out: &mut Vec<(UVec3, u32)>,
    ) {
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
pub(super) fn reserve_gently<T>(v: &mut Vec<T>, extra: usize) {
    if v.capacity() - v.len() < extra {
        v.reserve_exact((v.len() / 4).max(extra).max(16));
    }
}

#[inline]
pub(super) fn octant(bc: UVec3, level: u32) -> usize {
    (((bc.x >> level) & 1) | ((bc.y >> level) & 1) << 1 | ((bc.z >> level) & 1) << 2) as usize
}

/// Whether position `r` (below 7) of a row starting inside a brick is in the next brick.
pub(super) const CARRY: [u32; 8] = [0, 0, 0, 0, 1, 1, 1, 1];

// Brick records are 16 bytes, payload entries 8, nodes 32: the figures of the crate docs.
const _: () = assert!(std::mem::size_of::<Brick>() == 16);
const _: () = assert!(std::mem::size_of::<Payload>() == 8);

#[cfg(test)]
mod tests {
    use super::*;

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
}
