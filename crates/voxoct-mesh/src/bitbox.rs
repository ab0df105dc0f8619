//! A dense box of cells as bits (rows along x, 64 cells a word), with the operations the
//! solid fill needs: L∞ dilation, and flood fills along the mesh's Kuhn connectivity that
//! work a whole row at a time (runs of free cells are filled with one carry chain).

use crate::tables::corner_offset;

/// One bit per cell of an `nx × ny × nz` box; row `(y, z)` is `w` words, bit `x`.
#[derive(Debug, Clone)]
pub(crate) struct BitBox {
    pub n: [usize; 3],
    pub w: usize,
    pub bits: Vec<u64>,
}

/// The neighbour rows of a row along the 14 Kuhn directions other than ±x: `(dy, dz)` and
/// whether the x shift of the diagonal is `+1` (else `-1`); the straight neighbour (dx = 0)
/// is always included.
fn neighbour_rows() -> [(isize, isize, bool); 6] {
    let mut out = [(0isize, 0isize, false); 6];
    let mut k = 0;
    for d in 1..8u8 {
        let [dx, dy, dz] = corner_offset(d);
        if (dy, dz) != (0, 0) && dx == 0 {
            out[k] = (dy as isize, dz as isize, true);
            out[k + 1] = (-dy as isize, -dz as isize, false);
            k += 2;
        }
    }
    debug_assert_eq!(k, 6);
    out
}

impl BitBox {
    pub fn new(n: [usize; 3]) -> Self {
        let w = n[0].div_ceil(64).max(1);
        Self {
            n,
            w,
            bits: vec![0; w * n[1] * n[2]],
        }
    }

    #[inline]
    pub fn rows(&self) -> usize {
        self.n[1] * self.n[2]
    }

    #[inline]
    pub fn row(&self, r: usize) -> &[u64] {
        &self.bits[r * self.w..(r + 1) * self.w]
    }

    #[inline]
    pub fn row_mut(&mut self, r: usize) -> &mut [u64] {
        &mut self.bits[r * self.w..(r + 1) * self.w]
    }

    #[inline]
    pub fn set(&mut self, x: usize, r: usize) {
        self.bits[r * self.w + x / 64] |= 1 << (x % 64);
    }

    #[inline]
    pub fn get(&self, x: usize, r: usize) -> bool {
        self.bits[r * self.w + x / 64] >> (x % 64) & 1 == 1
    }

    /// Mask of the valid bits of word `i` of a row.
    #[inline]
    pub fn word_mask(&self, i: usize) -> u64 {
        let rest = self.n[0] - 64 * i;
        if rest >= 64 {
            u64::MAX
        } else {
            (1u64 << rest) - 1
        }
    }

    pub fn count(&self) -> usize {
        self.bits.iter().map(|b| b.count_ones() as usize).sum()
    }

    /// Dilates the set bits by `k` cells (L∞), clipped to the box.
    pub fn dilate(&mut self, k: usize) {
        if k == 0 {
            return;
        }
        let w = self.w;
        let mut tmp = vec![0u64; w];
        let mut down = vec![0u64; w];
        for r in 0..self.rows() {
            for _ in 0..k {
                let row = self.row(r);
                shift_up(row, &mut tmp);
                shift_down(row, &mut down);
                let row = self.row_mut(r);
                for i in 0..w {
                    row[i] |= tmp[i] | down[i];
                }
            }
            for i in 0..w {
                let m = self.word_mask(i);
                self.bits[r * w + i] &= m;
            }
        }
        let [_, ny, nz] = self.n;
        // y, then z: each output row is the OR of the source rows within k.
        // (Which axis a pass is on is told by the pass, not by its stride: with one layer,
        // ny = 1, both strides are 1 and the z pass took y for its coordinate.)
        for (along_y, stride, len) in [(true, 1usize, ny), (false, ny, nz)] {
            let src = self.bits.clone();
            for r in 0..self.rows() {
                let (y, z) = (r % ny, r / ny);
                let t = if along_y { y } else { z };
                let lo = t.saturating_sub(k);
                let hi = (t + k).min(len - 1);
                let row = &mut self.bits[r * w..(r + 1) * w];
                for s in lo..=hi {
                    let q = r + s * stride - t * stride;
                    for (o, &b) in row.iter_mut().zip(&src[q * w..(q + 1) * w]) {
                        *o |= b;
                    }
                }
            }
        }
    }
}

/// `out = row << 1` (each cell moves to x + 1).
#[inline]
fn shift_up(row: &[u64], out: &mut [u64]) {
    let mut carry = 0;
    for (o, &b) in out.iter_mut().zip(row) {
        *o = (b << 1) | carry;
        carry = b >> 63;
    }
}

/// `out = row >> 1` (each cell moves to x − 1).
#[inline]
fn shift_down(row: &[u64], out: &mut [u64]) {
    let mut carry = 0;
    for (o, &b) in out.iter_mut().zip(row).rev() {
        *o = (b >> 1) | carry;
        carry = b << 63;
    }
}

/// `out` = the runs of `free` (along x) that contain a bit of `seed`.
pub(crate) fn fill_runs(seed: &[u64], free: &[u64], out: &mut [u64]) {
    let w = free.len();
    // Up: adding the seeds to the free mask clears each run from its lowest seed upwards.
    let mut carry = false;
    for i in 0..w {
        let a = seed[i] & free[i];
        let (s1, c1) = free[i].overflowing_add(a);
        let (s2, c2) = s1.overflowing_add(u64::from(carry));
        carry = c1 || c2;
        out[i] = ((s2 ^ free[i]) | a) & free[i];
    }
    // Down: the same on the bit-reversed row.
    let mut carry = false;
    for i in (0..w).rev() {
        let f = free[i].reverse_bits();
        let a = (seed[i] & free[i]).reverse_bits();
        let (s1, c1) = f.overflowing_add(a);
        let (s2, c2) = s1.overflowing_add(u64::from(carry));
        carry = c1 || c2;
        out[i] |= (((s2 ^ f) | a) & f).reverse_bits();
    }
}

/// A row-at-a-time flood fill through the bits of `free`.
pub(crate) struct Flood {
    stack: Vec<u32>,
    queued: Vec<bool>,
    nbs: [(isize, isize, bool); 6],
    cur: Vec<u64>,
    up: Vec<u64>,
    down: Vec<u64>,
    cand: Vec<u64>,
    new: Vec<u64>,
}

impl Flood {
    pub fn new(b: &BitBox) -> Self {
        Self {
            stack: Vec::new(),
            queued: vec![false; b.rows()],
            nbs: neighbour_rows(),
            cur: vec![0; b.w],
            up: vec![0; b.w],
            down: vec![0; b.w],
            cand: vec![0; b.w],
            new: vec![0; b.w],
        }
    }

    /// Adds to `reached` the free cells of row `r` in runs that hold a bit of `seed`, and
    /// queues the row; calls `on_new(row, word, bits)` for every newly reached word. Returns
    /// the number of new cells.
    pub fn seed(
        &mut self,
        free: &BitBox,
        reached: &mut BitBox,
        r: usize,
        seed: &[u64],
        on_new: &mut impl FnMut(usize, usize, u64),
    ) -> usize {
        fill_runs(seed, free.row(r), &mut self.new);
        let mut added = 0;
        for (i, (dst, &nw)) in reached.row_mut(r).iter_mut().zip(&self.new).enumerate() {
            let nw = nw & !*dst;
            if nw != 0 {
                *dst |= nw;
                added += nw.count_ones() as usize;
                on_new(r, i, nw);
            }
        }
        if added > 0 && !self.queued[r] {
            self.queued[r] = true;
            self.stack.push(r as u32);
        }
        added
    }

    /// Runs the fill to completion from the queued rows; returns the number of new cells.
    pub fn run(
        &mut self,
        free: &BitBox,
        reached: &mut BitBox,
        on_new: &mut impl FnMut(usize, usize, u64),
    ) -> usize {
        let [_, ny, nz] = free.n;
        let mut added = 0;
        while let Some(r) = self.stack.pop() {
            let r = r as usize;
            self.queued[r] = false;
            self.cur.copy_from_slice(reached.row(r));
            shift_up(&self.cur, &mut self.up);
            shift_down(&self.cur, &mut self.down);
            let (y, z) = ((r % ny) as isize, (r / ny) as isize);
            for k in 0..6 {
                let (dy, dz, plus) = self.nbs[k];
                let (yy, zz) = (y + dy, z + dz);
                if yy < 0 || zz < 0 || yy >= ny as isize || zz >= nz as isize {
                    continue;
                }
                let q = zz as usize * ny + yy as usize;
                let (fr, rr) = (free.row(q), reached.row(q));
                let shifted = if plus { &self.up } else { &self.down };
                let mut any = 0;
                for i in 0..self.cand.len() {
                    let c = (self.cur[i] | shifted[i]) & fr[i] & !rr[i];
                    self.cand[i] = c;
                    any |= c;
                }
                if any != 0 {
                    let cand = std::mem::take(&mut self.cand);
                    added += self.seed(free, reached, q, &cand, on_new);
                    self.cand = cand;
                }
            }
        }
        added
    }
}

/// Clears the connected groups (Kuhn connectivity) of set bits with fewer than `min` cells.
pub(crate) fn remove_small_groups(b: &mut BitBox, min: usize) {
    if min <= 1 {
        return;
    }
    let free = b.clone();
    let mut visited = BitBox::new(b.n);
    let mut flood = Flood::new(b);
    let mut group: Vec<(usize, usize, u64)> = Vec::new();
    let mut seed = vec![0u64; b.w];
    for r in 0..b.rows() {
        for i in 0..b.w {
            loop {
                let open = free.bits[r * b.w + i] & !visited.bits[r * b.w + i];
                if open == 0 {
                    break;
                }
                seed.fill(0);
                seed[i] = open & open.wrapping_neg();
                group.clear();
                let mut size = 0usize;
                let mut record = |row: usize, word: usize, bits: u64| {
                    size += bits.count_ones() as usize;
                    if size < min {
                        group.push((row, word, bits));
                    }
                };
                flood.seed(&free, &mut visited, r, &seed, &mut record);
                flood.run(&free, &mut visited, &mut record);
                if size < min {
                    for &(row, word, bits) in &group {
                        b.bits[row * b.w + word] &= !bits;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A single layer (ny = 1) dilates along z too: one set cell becomes a square.
    #[test]
    fn a_single_layer_dilates_in_x_and_z() {
        let mut b = BitBox::new([9, 1, 9]);
        b.set(4, 4);
        b.dilate(2);
        for z in 0..9usize {
            for x in 0..9usize {
                let want = x.abs_diff(4) <= 2 && z.abs_diff(4) <= 2;
                assert_eq!(b.get(x, z), want, "({x}, {z})");
            }
        }
    }

    #[test]
    fn fill_runs_fills_whole_runs_across_words() {
        let free = [!0u64 << 60, 0b1111 | (0b111 << 10)];
        let mut seed = [0u64; 2];
        seed[0] = 1 << 62;
        let mut out = [0u64; 2];
        fill_runs(&seed, &free, &mut out);
        assert_eq!(out, [!0u64 << 60, 0b1111]);
        seed = [0, 1 << 11];
        fill_runs(&seed, &free, &mut out);
        assert_eq!(out, [0, 0b111 << 10]);
    }

    #[test]
    fn small_groups_go_big_ones_stay() {
        let mut b = BitBox::new([70, 5, 5]);
        let r = |y: usize, z: usize| z * 5 + y;
        b.set(3, r(1, 1)); // a lone cell
        for x in 60..68 {
            b.set(x, r(2, 2)); // a run of 8 across a word boundary
        }
        b.set(69, r(3, 3)); // alone: its Kuhn neighbours below are x = 69 and 68, unset
        b.set(67, r(3, 3)); // the (0, +1, +1) neighbour of x = 67: joins the run
        remove_small_groups(&mut b, 5);
        assert!(!b.get(3, r(1, 1)));
        assert!(b.get(60, r(2, 2)) && b.get(67, r(3, 3)));
        assert!(!b.get(69, r(3, 3)));
        assert_eq!(b.count(), 9);
    }
}
