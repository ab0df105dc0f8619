//! A sparse box of cells as bits in tiles, with the operations of the solid fill (L∞
//! dilation, flood fills along the mesh's Kuhn connectivity, removal of small groups), so
//! that the fill's memory follows the surface instead of the box.
//!
//! The box is cut into tiles of [`TX`] × [`TY`] × [`TZ`] cells. A tile whose cells are all
//! clear or all set is one word of the tile grid ([`ZERO`], [`ONE`]); only the others hold
//! their bits (one `u64` per row along x). Far from the marked cells every tile is uniform:
//! the flood crosses such a tile in one step and marks it whole, and a dilation leaves it as
//! it is unless a neighbour differs. Every operation gives exactly the set the dense
//! [`crate::bitbox::BitBox`] version gives on the same box.

use crate::bitbox::{BitBox, fill_runs};

/// Cells of a tile along x (one word per row).
pub(crate) const TX: usize = 64;
/// Cells of a tile along y.
pub(crate) const TY: usize = 16;
/// Cells of a tile along z.
pub(crate) const TZ: usize = 16;
/// Rows of a tile (`y + TY · z`).
const ROWS: usize = TY * TZ;
/// Cells of a tile.
pub(crate) const TILE_CELLS: u64 = (TX * ROWS) as u64;
/// Tile-grid entry of a tile with every cell clear.
const ZERO: u32 = u32::MAX;
/// Tile-grid entry of a tile with every cell set.
const ONE: u32 = u32::MAX - 1;
/// Row marker of a whole uniform tile in flood work items and callbacks.
pub(crate) const WHOLE: u32 = u32::MAX;
/// Widest dilation done in one pass (within the tile's neighbours).
const STEP: usize = if TY < TZ { TY } else { TZ };

/// A set of cells of a box of `t` tiles (cell `(x, y, z)` of the box is bit `x % TX` of row
/// `y % TY + TY · (z % TZ)` of tile `(x / TX, y / TY, z / TZ)`).
#[derive(Debug, Clone)]
pub(crate) struct Tiled {
    /// Tiles along x, y, z.
    pub t: [usize; 3],
    /// Per tile (x fastest): [`ZERO`], [`ONE`] or the index of its rows in `pool`.
    grid: Vec<u32>,
    /// The rows of the tiles that are neither clear nor full, [`ROWS`] words each.
    pool: Vec<u64>,
}

/// The 14 Kuhn directions (the mesh's connectivity between cells): the parent module's seven
/// positive ones and their opposites.
fn kuhn_dirs() -> [[i32; 3]; 14] {
    let mut out = [[0; 3]; 14];
    for (k, d) in super::kuhn_dirs().into_iter().enumerate() {
        out[2 * k] = d.to_array();
        out[2 * k + 1] = (-d).to_array();
    }
    out
}

impl Tiled {
    /// The empty set on `t` tiles.
    pub fn new(t: [usize; 3]) -> Self {
        Self {
            t,
            grid: vec![ZERO; t[0] * t[1] * t[2]],
            pool: Vec::new(),
        }
    }

    /// Number of tiles.
    #[inline]
    pub fn tiles(&self) -> usize {
        self.grid.len()
    }

    /// Index of tile `(x, y, z)`, `None` beyond the grid.
    #[inline]
    pub fn tile_at(&self, x: i64, y: i64, z: i64) -> Option<usize> {
        let [a, b, c] = self.t;
        (x >= 0 && y >= 0 && z >= 0 && (x as usize) < a && (y as usize) < b && (z as usize) < c)
            .then(|| (z as usize * b + y as usize) * a + x as usize)
    }

    /// Coordinates of tile `i`.
    #[inline]
    pub fn tile_coords(&self, i: usize) -> [i64; 3] {
        let [a, b, _] = self.t;
        [(i % a) as i64, (i / a % b) as i64, (i / (a * b)) as i64]
    }

    /// Whether tile `i` is full.
    #[inline]
    fn is_one(&self, i: usize) -> bool {
        self.grid[i] == ONE
    }

    /// Word `r` of tile `i`.
    #[inline]
    pub fn word(&self, i: usize, r: usize) -> u64 {
        match self.grid[i] {
            ZERO => 0,
            ONE => u64::MAX,
            p => self.pool[p as usize * ROWS + r],
        }
    }

    /// The rows of tile `i`, made dense.
    fn dense_mut(&mut self, i: usize) -> &mut [u64] {
        let g = self.grid[i];
        let p = if g == ZERO || g == ONE {
            let p = self.pool.len() / ROWS;
            let fill = if g == ONE { u64::MAX } else { 0 };
            self.pool.resize(self.pool.len() + ROWS, fill);
            self.grid[i] = p as u32;
            p
        } else {
            g as usize
        };
        &mut self.pool[p * ROWS..(p + 1) * ROWS]
    }

    /// Sets the `bits` of word `r` of tile `i`.
    #[inline]
    pub fn or_word(&mut self, i: usize, r: usize, bits: u64) {
        if bits == 0 || self.grid[i] == ONE {
            return;
        }
        self.dense_mut(i)[r] |= bits;
    }

    /// Clears the `bits` of word `r` of tile `i`.
    #[inline]
    fn clear_word(&mut self, i: usize, r: usize, bits: u64) {
        if bits == 0 || self.grid[i] == ZERO {
            return;
        }
        self.dense_mut(i)[r] &= !bits;
    }

    /// Sets cell `(x, y, z)` of the box.
    pub fn set(&mut self, x: usize, y: usize, z: usize) {
        let i = (z / TZ * self.t[1] + y / TY) * self.t[0] + x / TX;
        self.or_word(i, (z % TZ) * TY + y % TY, 1 << (x % TX));
    }

    /// Number of set cells.
    pub fn count(&self) -> u64 {
        self.grid
            .iter()
            .map(|&g| match g {
                ZERO => 0,
                ONE => TILE_CELLS,
                p => self.pool[p as usize * ROWS..(p as usize + 1) * ROWS]
                    .iter()
                    .map(|w| u64::from(w.count_ones()))
                    .sum(),
            })
            .sum()
    }

    /// Makes every clear or full dense tile uniform and drops the rows it held.
    pub fn compact(&mut self) {
        let old = std::mem::take(&mut self.pool);
        for g in &mut self.grid {
            if *g == ZERO || *g == ONE {
                continue;
            }
            let rows = &old[*g as usize * ROWS..(*g as usize + 1) * ROWS];
            *g = if rows.iter().all(|&w| w == 0) {
                ZERO
            } else if rows.iter().all(|&w| w == u64::MAX) {
                ONE
            } else {
                let p = self.pool.len() / ROWS;
                self.pool.extend_from_slice(rows);
                p as u32
            };
        }
        self.pool.shrink_to_fit();
    }

    /// The set combined tile by tile with `other` by `f` (on words).
    fn combine(&self, other: &Self, f: impl Fn(u64, u64) -> u64) -> Self {
        let mut out = Self::new(self.t);
        for i in 0..self.tiles() {
            let (a, b) = (self.grid[i], other.grid[i]);
            let uniform = |g: u32| g == ZERO || g == ONE;
            if uniform(a) && uniform(b) {
                let w = f(self.word(i, 0), other.word(i, 0));
                out.grid[i] = if w == 0 {
                    ZERO
                } else if w == u64::MAX {
                    ONE
                } else {
                    unreachable!("combine of uniform words is uniform")
                };
                continue;
            }
            let mut rows = [0u64; ROWS];
            for (r, w) in rows.iter_mut().enumerate() {
                *w = f(self.word(i, r), other.word(i, r));
            }
            if rows.iter().all(|&w| w == 0) {
                continue;
            }
            if rows.iter().all(|&w| w == u64::MAX) {
                out.grid[i] = ONE;
                continue;
            }
            out.dense_mut(i).copy_from_slice(&rows);
        }
        out
    }

    /// Cells in `self` or `other`.
    pub fn or(&self, other: &Self) -> Self {
        self.combine(other, |a, b| a | b)
    }

    /// Cells in `self` and not in `other`.
    pub fn and_not(&self, other: &Self) -> Self {
        self.combine(other, |a, b| a & !b)
    }

    /// Cells in `self` and `other`.
    pub fn and(&self, other: &Self) -> Self {
        self.combine(other, |a, b| a & b)
    }

    /// Cells in neither `self` nor `other`.
    pub fn nor(&self, other: &Self) -> Self {
        self.combine(other, |a, b| !(a | b))
    }

    /// The set dilated by `k` cells (L∞); cells beyond the grid count as set when `beyond`.
    pub fn dilate(&self, k: usize, beyond: bool) -> Self {
        if k == 0 {
            return self.clone();
        }
        let mut out = self.dilate_step(k.min(STEP), beyond);
        let mut left = k - k.min(STEP);
        while left > 0 {
            let step = left.min(STEP);
            out = out.dilate_step(step, beyond);
            left -= step;
        }
        out
    }

    /// One dilation by `k ≤ STEP` cells: each tile from the tiles around it.
    fn dilate_step(&self, k: usize, beyond: bool) -> Self {
        let mut out = Self::new(self.t);
        let (hx, hy, hz) = (TX + 2 * k, TY + 2 * k, TZ + 2 * k);
        let mut halo = BitBox::new([hx, hy, hz]);
        for i in 0..self.tiles() {
            if self.grid[i] == ONE {
                out.grid[i] = ONE;
                continue;
            }
            let [tx, ty, tz] = self.tile_coords(i);
            let mut all_zero = true;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        match self.tile_at(tx + dx, ty + dy, tz + dz) {
                            Some(j) => all_zero &= self.grid[j] == ZERO,
                            None => all_zero &= !beyond,
                        }
                    }
                }
            }
            if all_zero {
                continue;
            }
            // The tile and `k` cells around it, dilated, then its centre.
            let kk = k as i64;
            for hzi in 0..hz {
                let gz = tz * TZ as i64 + hzi as i64 - kk;
                for hyi in 0..hy {
                    let gy = ty * TY as i64 + hyi as i64 - kk;
                    let word_of = |x: i64| -> u64 {
                        let (ox, oy, oz) = (x, gy.div_euclid(TY as i64), gz.div_euclid(TZ as i64));
                        match self.tile_at(ox, oy, oz) {
                            Some(j) => {
                                let r = gz.rem_euclid(TZ as i64) as usize * TY
                                    + gy.rem_euclid(TY as i64) as usize;
                                self.word(j, r)
                            }
                            None if beyond => u64::MAX,
                            None => 0,
                        }
                    };
                    let (wl, wc, wr) = (word_of(tx - 1), word_of(tx), word_of(tx + 1));
                    let h = u128::from(wl >> (64 - k))
                        | (u128::from(wc) << k)
                        | (u128::from(wr & ((1u64 << k) - 1)) << (64 + k));
                    let row = halo.row_mut(hzi * hy + hyi);
                    row[0] = h as u64;
                    row[1] = (h >> 64) as u64 & ((1u64 << (2 * k)) - 1);
                }
            }
            halo.dilate(k);
            let mut full = true;
            let mut rows = [0u64; ROWS];
            for (r, o) in rows.iter_mut().enumerate() {
                let (y, z) = (r % TY, r / TY);
                let row = halo.row((z + k) * hy + y + k);
                let h = u128::from(row[0]) | (u128::from(row[1]) << 64);
                *o = (h >> k) as u64;
                full &= *o == u64::MAX;
            }
            if full {
                out.grid[i] = ONE;
            } else if rows.iter().any(|&w| w != 0) {
                out.dense_mut(i).copy_from_slice(&rows);
            }
        }
        out
    }
}

/// A flood fill through the set cells of a [`Tiled`] `free`, a row (or a whole full tile)
/// at a time. In `reached`, a full tile of `free` is always clear or full.
pub(crate) struct TiledFlood {
    stack: Vec<(u32, u32)>,
    dirs: [[i32; 3]; 14],
}

impl TiledFlood {
    pub fn new() -> Self {
        Self {
            stack: Vec::new(),
            dirs: kuhn_dirs(),
        }
    }

    /// Adds to `reached` the free cells of word `r` of tile `i` in runs (within the word)
    /// that hold a bit of `seed` — the whole tile when it is full in `free` — and queues
    /// them; calls `on_new(tile, row, bits)` for what is new (`row` [`WHOLE`] for a whole
    /// tile).
    pub fn seed(
        &mut self,
        free: &Tiled,
        reached: &mut Tiled,
        i: usize,
        r: usize,
        seed: u64,
        on_new: &mut impl FnMut(usize, u32, u64),
    ) {
        match free.grid[i] {
            ZERO => {}
            ONE => {
                if reached.is_one(i) || seed == 0 {
                    return;
                }
                debug_assert_eq!(reached.grid[i], ZERO);
                reached.grid[i] = ONE;
                on_new(i, WHOLE, u64::MAX);
                self.stack.push((i as u32, WHOLE));
            }
            _ => {
                let f = free.word(i, r);
                let have = reached.word(i, r);
                let a = seed & f & !have;
                if a == 0 {
                    return;
                }
                let mut run = [0u64];
                fill_runs(&[a], &[f], &mut run);
                let nw = run[0] & !have;
                reached.or_word(i, r, nw);
                on_new(i, r as u32, nw);
                self.stack.push((i as u32, r as u32));
            }
        }
    }

    /// Runs the fill to completion from the queued rows and tiles.
    pub fn run(
        &mut self,
        free: &Tiled,
        reached: &mut Tiled,
        on_new: &mut impl FnMut(usize, u32, u64),
    ) {
        while let Some((i, r)) = self.stack.pop() {
            let i = i as usize;
            let [tx, ty, tz] = free.tile_coords(i);
            if r == WHOLE {
                for k in 0..14 {
                    let d = self.dirs[k];
                    let Some(j) = free.tile_at(
                        tx + i64::from(d[0]),
                        ty + i64::from(d[1]),
                        tz + i64::from(d[2]),
                    ) else {
                        continue;
                    };
                    if free.grid[j] == ZERO {
                        continue;
                    }
                    if free.grid[j] == ONE {
                        self.seed(free, reached, j, 0, u64::MAX, on_new);
                        continue;
                    }
                    // The cells of tile j next to tile i: first/last along each axis d moves.
                    let mask = match d[0] {
                        1 => 1u64,
                        -1 => 1 << 63,
                        _ => u64::MAX,
                    };
                    let ys: &[usize] = match d[1] {
                        1 => &[0],
                        -1 => &[TY - 1],
                        _ => &ALL_Y,
                    };
                    let zs: &[usize] = match d[2] {
                        1 => &[0],
                        -1 => &[TZ - 1],
                        _ => &ALL_Z,
                    };
                    for &z in zs {
                        for &y in ys {
                            self.seed(free, reached, j, z * TY + y, mask, on_new);
                        }
                    }
                }
                continue;
            }
            let r = r as usize;
            let cur = reached.word(i, r);
            let (y, z) = ((r % TY) as i64, (r / TY) as i64);
            for k in 0..14 {
                let [dx, dy, dz] = self.dirs[k];
                let (ny, nz) = (y + i64::from(dy), z + i64::from(dz));
                let (oy, oz) = (ty + ny.div_euclid(TY as i64), tz + nz.div_euclid(TZ as i64));
                let q = nz.rem_euclid(TZ as i64) as usize * TY + ny.rem_euclid(TY as i64) as usize;
                let (main, carry, cx) = match dx {
                    1 => (cur << 1, cur >> 63, 1),
                    -1 => (cur >> 1, cur << 63, -1),
                    _ => (cur, 0, 0),
                };
                if main != 0
                    && let Some(j) = free.tile_at(tx, oy, oz)
                {
                    self.seed(free, reached, j, q, main, on_new);
                }
                if carry != 0
                    && let Some(j) = free.tile_at(tx + cx, oy, oz)
                {
                    self.seed(free, reached, j, q, carry, on_new);
                }
            }
        }
    }
}

const ALL_Y: [usize; TY] = {
    let mut a = [0; TY];
    let mut i = 0;
    while i < TY {
        a[i] = i;
        i += 1;
    }
    a
};
const ALL_Z: [usize; TZ] = {
    let mut a = [0; TZ];
    let mut i = 0;
    while i < TZ {
        a[i] = i;
        i += 1;
    }
    a
};

/// Clears the connected groups (Kuhn connectivity) of set cells with fewer than `min`
/// cells.
pub(crate) fn remove_small_groups(b: &mut Tiled, min: usize) {
    if min <= 1 {
        return;
    }
    let min = min as u64;
    let mut visited = Tiled::new(b.t);
    let mut flood = TiledFlood::new();
    let mut drop: Vec<(usize, u32, u64)> = Vec::new();
    let mut group: Vec<(usize, u32, u64)> = Vec::new();
    for i in 0..b.tiles() {
        if b.grid[i] == ZERO {
            continue;
        }
        for r in 0..ROWS {
            loop {
                let open = b.word(i, r) & !visited.word(i, r);
                if open == 0 {
                    break;
                }
                group.clear();
                let mut size = 0u64;
                let mut record = |tile: usize, row: u32, bits: u64| {
                    size += if row == WHOLE {
                        TILE_CELLS
                    } else {
                        u64::from(bits.count_ones())
                    };
                    if size < min {
                        group.push((tile, row, bits));
                    }
                };
                flood.seed(
                    b,
                    &mut visited,
                    i,
                    r,
                    open & open.wrapping_neg(),
                    &mut record,
                );
                flood.run(b, &mut visited, &mut record);
                if size < min {
                    drop.extend_from_slice(&group);
                }
            }
            if b.is_one(i) {
                break;
            }
        }
    }
    for (tile, row, bits) in drop {
        if row == WHOLE {
            b.grid[tile] = ZERO;
        } else {
            b.clear_word(tile, row as usize, bits);
        }
    }
    b.compact();
}

/// The cells the outside cannot reach in the tiled box (see the dense `enclosed` of the
/// parent module, whose box is this one's plus a one-cell border): the outside floods the
/// set's complement (dilated marked cells are walls) from the box's faces — the bottom face
/// only when not `closed_bottom` — and what it reached, with everything beyond the box, is
/// grown back by `gap`; the enclosed cells are neither that nor marked.
pub(crate) fn enclosed(marked: &Tiled, closed_bottom: bool, gap: u32) -> Tiled {
    let walls = marked.dilate(gap as usize, false);
    let free = walls.nor(&Tiled::new(marked.t));
    drop(walls);
    let mut reached = Tiled::new(marked.t);
    let mut flood = TiledFlood::new();
    let [ax, ay, az] = marked.t;
    let none = &mut |_: usize, _: u32, _: u64| {};
    for tz in 0..az {
        for ty in 0..ay {
            for tx in 0..ax {
                let i = (tz * ay + ty) * ax + tx;
                let faces = [
                    tx == 0,
                    tx == ax - 1,
                    ty == 0 && !closed_bottom,
                    ty == ay - 1,
                    tz == 0,
                    tz == az - 1,
                ];
                if !faces.iter().any(|&f| f) {
                    continue;
                }
                for r in 0..ROWS {
                    let (y, z) = (r % TY, r / TY);
                    let mut seed = 0u64;
                    if faces[0] {
                        seed |= 1;
                    }
                    if faces[1] {
                        seed |= 1 << 63;
                    }
                    if (faces[2] && y == 0)
                        || (faces[3] && y == TY - 1)
                        || (faces[4] && z == 0)
                        || (faces[5] && z == TZ - 1)
                    {
                        seed = u64::MAX;
                    }
                    if seed != 0 {
                        flood.seed(&free, &mut reached, i, r, seed, none);
                    }
                }
            }
        }
    }
    flood.run(&free, &mut reached, none);
    drop(free);
    let outside = if gap > 0 {
        reached.dilate(gap as usize, true)
    } else {
        reached
    };
    outside.nor(marked)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dense_of(t: &Tiled) -> Vec<bool> {
        let [a, b, c] = t.t;
        let n = [a * TX, b * TY, c * TZ];
        let mut out = vec![false; n[0] * n[1] * n[2]];
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let i = (z / TZ * b + y / TY) * a + x / TX;
                    out[(z * n[1] + y) * n[0] + x] =
                        t.word(i, (z % TZ) * TY + y % TY) >> (x % TX) & 1 == 1;
                }
            }
        }
        out
    }

    /// Cells reached from `start` through `free` by a breadth-first search over cells.
    fn brute_flood(free: &[bool], n: [usize; 3], start: usize) -> Vec<bool> {
        let mut seen = vec![false; free.len()];
        let mut queue = vec![start];
        seen[start] = true;
        while let Some(c) = queue.pop() {
            let p = [c % n[0], c / n[0] % n[1], c / (n[0] * n[1])];
            for d in kuhn_dirs() {
                let q: Vec<i64> = (0..3).map(|a| p[a] as i64 + i64::from(d[a])).collect();
                if (0..3).any(|a| q[a] < 0 || q[a] >= n[a] as i64) {
                    continue;
                }
                let j = (q[2] as usize * n[1] + q[1] as usize) * n[0] + q[0] as usize;
                if free[j] && !seen[j] {
                    seen[j] = true;
                    queue.push(j);
                }
            }
        }
        seen
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
        /// The tiled flood reaches exactly the cells a flood over cells reaches, through
        /// clear, full and mixed tiles (mixed ones with sparse free cells, so that many
        /// paths run through a single face, edge or corner between tiles).
        #[test]
        fn flood_matches_brute_force(
            kinds in proptest::collection::vec(0u8..4, 12),
            seed in proptest::prelude::any::<u64>(),
            start in proptest::prelude::any::<u32>(),
        ) {
            let t = [3, 2, 2];
            let mut free = Tiled::new(t);
            let mut h = seed | 1;
            for (i, &kind) in kinds.iter().enumerate() {
                match kind {
                    0 => {}
                    1 => free.grid[i] = ONE,
                    k => {
                        for r in 0..ROWS {
                            h ^= h << 13;
                            h ^= h >> 7;
                            h ^= h << 17;
                            let a = h;
                            h ^= h << 13;
                            h ^= h >> 7;
                            h ^= h << 17;
                            // About 3/4 or 1/4 of the cells free.
                            free.or_word(i, r, if k == 2 { a | h } else { a & h });
                        }
                    }
                }
            }
            let n = [t[0] * TX, t[1] * TY, t[2] * TZ];
            let cells = dense_of(&free);
            let free_cells: Vec<usize> = (0..cells.len()).filter(|&c| cells[c]).collect();
            proptest::prop_assume!(!free_cells.is_empty());
            let start = free_cells[start as usize % free_cells.len()];
            let want = brute_flood(&cells, n, start);
            let mut reached = Tiled::new(t);
            let mut flood = TiledFlood::new();
            let p = [start % n[0], start / n[0] % n[1], start / (n[0] * n[1])];
            let i = (p[2] / TZ * t[1] + p[1] / TY) * t[0] + p[0] / TX;
            let r = (p[2] % TZ) * TY + p[1] % TY;
            let none = &mut |_: usize, _: u32, _: u64| {};
            flood.seed(&free, &mut reached, i, r, 1 << (p[0] % TX), none);
            flood.run(&free, &mut reached, none);
            proptest::prop_assert!(dense_of(&reached) == want);
        }
    }

    #[test]
    fn dilation_matches_brute_force() {
        let t = [2, 3, 2];
        let mut s = Tiled::new(t);
        let pts = [
            (0, 0, 0),
            (63, 15, 15),
            (64, 16, 16),
            (100, 40, 3),
            (127, 47, 31),
        ];
        for &(x, y, z) in &pts {
            s.set(x, y, z);
        }
        let n = [t[0] * TX, t[1] * TY, t[2] * TZ];
        for (k, beyond) in [(1, false), (3, true), (20, false)] {
            let d = dense_of(&s.dilate(k, beyond));
            for z in 0..n[2] {
                for y in 0..n[1] {
                    for x in 0..n[0] {
                        let near = |a: usize, b: usize| a.abs_diff(b) <= k;
                        let edge = |a: usize, len: usize| a < k || a + k >= len;
                        let want = pts
                            .iter()
                            .any(|&(px, py, pz)| near(px, x) && near(py, y) && near(pz, z))
                            || (beyond && (edge(x, n[0]) || edge(y, n[1]) || edge(z, n[2])));
                        assert_eq!(d[(z * n[1] + y) * n[0] + x], want, "{x} {y} {z} k {k}");
                    }
                }
            }
        }
    }
}
