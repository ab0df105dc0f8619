//! From marked cells to the cell field that is marched: weak-cell rejection, small-component
//! removal, floor, and the flood fill that separates the outside from enclosed space: over a
//! dense box of bits (the `bitbox` module) while the cells' box is small, in tiles (the
//! `tiled` module, memory that follows the marked cells) past [`FILL_LIMIT`]; both give the
//! same cells.

use std::borrow::Cow;
use std::collections::HashMap;

use voxoct_core::glam::{IVec3, UVec3};
use voxoct_core::{Cell, GridSpec};

use crate::bitbox::{BitBox, Flood, remove_small_groups};
use crate::march::Inside;
use crate::mesh::Dsu;
use crate::options::{Floor, MeshError, MeshOptions, Placement};
use crate::par;
use crate::tables::corner_offset;

mod tiled;

/// Largest box (in cells) the fill works on densely, at under 2 bytes per cell; a larger box
/// is filled in tiles (the `tiled` module), whose memory follows the marked cells instead of
/// the box. Both give the same cells; the dense box is faster while it fits.
pub const FILL_LIMIT: u64 = 1 << 28;

/// Largest tile grid the tiled fill will allocate (4 bytes a tile of
/// [`tiled::TILE_CELLS`] cells): past it the box is absurd, not a scene.
const TILE_GRID_LIMIT: u64 = 1 << 26;

/// The seven positive Kuhn edge directions (the mesh's connectivity between cells).
fn kuhn_dirs() -> [IVec3; 7] {
    [1u8, 2, 3, 4, 5, 6, 7].map(|d| IVec3::from_array(corner_offset(d)))
}

#[inline]
fn pack(c: UVec3) -> u64 {
    u64::from(c.x) | (u64::from(c.y) << 21) | (u64::from(c.z) << 42)
}

/// The grid and the options, checked before any work: [`MeshError::InvalidArgument`]
/// names the first bad one.
fn check_arguments(grid: &GridSpec, opts: &MeshOptions) -> Result<(), MeshError> {
    let bad = |name, value: f32, reason| {
        Err(MeshError::InvalidArgument {
            name,
            value: f64::from(value),
            reason,
        })
    };
    for (name, value) in [
        ("grid.origin.x", grid.origin.x),
        ("grid.origin.y", grid.origin.y),
        ("grid.origin.z", grid.origin.z),
    ] {
        if !value.is_finite() {
            return bad(name, value, "must be finite");
        }
    }
    if !(grid.cell.is_finite() && grid.cell > 0.0) {
        return bad("grid.cell", grid.cell, "must be finite and positive");
    }
    if grid.resolution == 0 || grid.resolution > 1 << 20 {
        return Err(MeshError::InvalidArgument {
            name: "grid.resolution",
            value: f64::from(grid.resolution),
            reason: "must be in 1..=2^20",
        });
    }
    if let Some(t) = opts.smoothing {
        if !(t.lambda > 0.0 && t.lambda < 1.0) {
            return bad("smoothing.lambda", t.lambda, "must be in (0, 1)");
        }
        if !(t.mu < -t.lambda && t.mu > -1.0) {
            return bad("smoothing.mu", t.mu, "must be in (-1, -lambda)");
        }
    }
    if let Floor::Y(y) = opts.floor
        && !y.is_finite()
    {
        return bad("floor", y, "Floor::Y must be finite");
    }
    Ok(())
}

/// Validates the grid and the cells; returns the marked cells as `(coord, value)` with the
/// value in cells (mean signed distance / cell edge; `-inf` kept, a solid cell without an
/// observed surface such as the closure adds, `closure::CLOSED_SDF`; 0 when NaN or `+inf`),
/// the inside rule and the floor layer, if any (cells below it are dropped). Owned cells
/// are given back part by part as they are converted, before the fill (they and their
/// conversion are the two largest arrays of a solid's meshing, and are never both whole).
pub(crate) fn prepare(
    cells: Cow<'_, [Cell]>,
    grid: &GridSpec,
    opts: &MeshOptions,
    out: &mut Vec<(UVec3, f32)>,
) -> Result<(Inside, Option<u32>), MeshError> {
    check_arguments(grid, opts)?;
    if let Some(index) = par::position_first(&cells, |c| c.coord.max_element() >= grid.resolution) {
        return Err(MeshError::CellOutsideGrid {
            index,
            coord: cells[index].coord,
            resolution: grid.resolution,
        });
    }
    let min_hits = opts.min_hits.max(1);
    let inv = 1.0 / grid.cell;
    let entry = |c: &Cell| {
        let v = c.mean_sdf() * inv;
        let v = if v.is_finite() || v == f32::NEG_INFINITY {
            v
        } else {
            0.0
        };
        (c.coord, v)
    };
    let counted = |c: &Cell| c.hits >= min_hits;
    out.clear();
    out.reserve_exact(par::count(&cells, counted));
    match cells {
        Cow::Borrowed(cells) => {
            out.extend(cells.iter().filter(|c| counted(c)).map(entry));
        }
        Cow::Owned(mut cells) => {
            // From the back, an eighth of what is left at a time, each part's memory given
            // back before the next is converted: the cells (20 bytes) and their conversion
            // (16 bytes) are never both whole (a solid's interior, at fine leaves the
            // largest arrays of the meshing). Reversed at the end: the order is kept. A
            // part whose cells are all counted (the closure's interior) is converted in
            // parallel, each entry written in its place.
            while !cells.is_empty() {
                let from = cells.len() - cells.len().div_ceil(8);
                let part = &cells[from..];
                if par::all(part.len(), |i| counted(&part[i])) {
                    par::extend_map_rev(out, part, entry);
                } else {
                    out.extend(part.iter().rev().filter(|c| counted(c)).map(entry));
                }
                cells.truncate(from);
                cells.shrink_to_fit();
            }
            out.reverse();
        }
    }
    let flood = opts.solid || opts.placement == Placement::SignedDistance;
    let floor_layer = match opts.floor {
        Floor::None => None,
        Floor::LowestMarked => out.iter().map(|c| c.0.y).min(),
        Floor::Y(y) => Some(Floor::y_layer(y, grid)),
    };
    if let Some(f) = floor_layer {
        out.retain(|c| c.0.y >= f);
    }
    let inside = match (opts.solid, opts.placement) {
        (false, _) => Inside::Marked,
        (true, Placement::Midpoint) => Inside::NotExterior,
        (true, Placement::SignedDistance) => Inside::NonPositive,
    };
    if flood && !out.is_empty() {
        // Filling and the signed distance can leave specks of inside apart from the body.
        let specks = (opts.solid && opts.min_component_cells > 1)
            .then_some((opts.min_component_cells, inside));
        let rule = FillRule {
            floor: floor_layer,
            max_gap: opts.close_gaps,
            min_component: opts.min_component_cells,
            specks,
        };
        fill_enclosed(out, &rule)?;
    } else if opts.min_component_cells > 1 {
        remove_small_components(out, opts.min_component_cells, |_| true);
    }
    Ok((inside, floor_layer))
}

/// Drops the cells `member` accepts that belong to connected groups (of such cells) smaller
/// than `min`; other cells are kept.
fn remove_small_components(
    cells: &mut Vec<(UVec3, f32)>,
    min: usize,
    member: impl Fn(f32) -> bool,
) {
    let index: HashMap<u64, u32> = cells
        .iter()
        .enumerate()
        .filter(|(_, c)| member(c.1))
        .map(|(i, c)| (pack(c.0), i as u32))
        .collect();
    let mut dsu = Dsu::new(cells.len());
    let dirs = kuhn_dirs();
    for (i, c) in cells.iter().enumerate() {
        if !member(c.1) {
            continue;
        }
        for d in dirs {
            let n = c.0.as_ivec3() + d;
            if let Some(&j) = index.get(&pack(n.as_uvec3())) {
                dsu.union(i as u32, j);
            }
        }
    }
    let mut size = vec![0usize; cells.len()];
    for i in 0..cells.len() as u32 {
        size[dsu.find(i) as usize] += 1;
    }
    let keep: Vec<bool> = (0..cells.len() as u32)
        .map(|i| !member(cells[i as usize].1) || size[dsu.find(i) as usize] >= min)
        .collect();
    let mut k = keep.iter();
    cells.retain(|_| *k.next().unwrap_or(&true));
}

/// Marks every unmarked cell of the box that the outside cannot reach.
///
/// The outside is flooded through unmarked cells along the mesh's own connectivity (the 14
/// Kuhn neighbours) from the boundary of the padded box (equivalent to the grid boundary:
/// everything beyond is unmarked), never from below the floor (the box's bottom layer when
/// `closed_bottom`). The box's outer layer is a sentinel border, never entered. With
/// `gap > 0`, the flood may not pass within `gap` cells (L∞) of a marked cell, and what it
/// reached (with the border) is grown back by `gap` afterwards: holes in the shell up to
/// `2 · gap` cells wide no longer let the outside in.
fn enclosed(marked: &BitBox, closed_bottom: bool, gap: u32) -> BitBox {
    let [nx, ny, nz] = marked.n;
    let w = marked.w;
    let interior_row = |r: usize| {
        let (y, z) = (r % ny, r / ny);
        y > 0 && z > 0 && y < ny - 1 && z < nz - 1
    };
    // Valid bits of each word minus the border columns x = 0 and x = nx - 1.
    let inner: Vec<u64> = (0..w)
        .map(|i| {
            let mut m = marked.word_mask(i);
            if i == 0 {
                m &= !1;
            }
            if i == (nx - 1) / 64 {
                m &= !(1u64 << ((nx - 1) % 64));
            }
            m
        })
        .collect();
    let mut free = marked.clone();
    free.dilate(gap as usize);
    for r in 0..free.rows() {
        let keep = interior_row(r);
        for (b, &m) in free.row_mut(r).iter_mut().zip(&inner) {
            *b = if keep { !*b & m } else { 0 };
        }
    }
    let mut reached = BitBox::new(marked.n);
    let mut flood = Flood::new(&free);
    let mut seed = vec![0u64; w];
    let mut sides = vec![0u64; w];
    sides[0] |= 1 << 1;
    sides[(nx - 2) / 64] |= 1 << ((nx - 2) % 64);
    for r in 0..free.rows() {
        if !interior_row(r) {
            continue;
        }
        let (y, z) = (r % ny, r / ny);
        let whole = z == 1 || z == nz - 2 || y == ny - 2 || (y == 1 && !closed_bottom);
        if whole {
            seed.copy_from_slice(free.row(r));
        } else {
            seed.copy_from_slice(&sides);
        }
        flood.seed(&free, &mut reached, r, &seed, &mut |_, _, _| {});
    }
    flood.run(&free, &mut reached, &mut |_, _, _| {});
    // Outside = reached or border, grown back; enclosed = neither outside nor marked.
    let mut outside = reached;
    for r in 0..outside.rows() {
        let keep = interior_row(r);
        for (i, b) in outside.row_mut(r).iter_mut().enumerate() {
            let m = marked.word_mask(i);
            *b = if keep { *b | (m & !inner[i]) } else { m };
        }
    }
    outside.dilate(gap as usize);
    for (i, (o, &m)) in outside.bits.iter_mut().zip(&marked.bits).enumerate() {
        *o = !*o & !m & marked.word_mask(i % w);
    }
    outside
}

/// What [`fill_enclosed`] fills and drops (the same for its dense and its tiled path).
#[derive(Debug, Clone, Copy)]
struct FillRule {
    /// The floor layer the outside cannot enter from below, if any.
    floor: Option<u32>,
    /// The widest gap closing tried.
    max_gap: u32,
    /// Connected groups of marked cells smaller than this are dropped first.
    min_component: usize,
    /// `Some((min, inside))`: connected groups of inside cells smaller than `min` are
    /// dropped at the end.
    specks: Option<(usize, Inside)>,
}

/// Adds the enclosed cells as `-inf` (see [`enclosed`]), closing gaps only as far as needed:
/// with the widest closing `max_gap` as reference, the smallest closing whose enclosed space
/// is at least half of that is used. A shell that is already closed keeps its concavities (no
/// fill in the wedge at the floor); one that leaks gets its gaps closed.
///
/// Connected groups of marked cells smaller than `min_component` are dropped first. With
/// `specks = Some((min, inside))`, connected groups of inside cells smaller than `min` are
/// dropped at the end. The cells come out in z, y, x order. Boxes past [`FILL_LIMIT`] cells
/// are filled in tiles ([`fill_enclosed_tiled`]), to the same cells.
///
/// # Errors
/// [`MeshError::FillTooLarge`] only past [`TILE_GRID_LIMIT`] tiles.
fn fill_enclosed(cells: &mut Vec<(UVec3, f32)>, rule: &FillRule) -> Result<(), MeshError> {
    let (lo, n) = fill_box(cells, rule.floor, rule.max_gap);
    let total = n.iter().map(|&d| d as u64).product::<u64>();
    if total > FILL_LIMIT {
        fill_enclosed_tiled(cells, (lo, n), rule)
    } else {
        fill_enclosed_dense(cells, (lo, n), rule);
        Ok(())
    }
}

/// [`fill_enclosed`] on a dense box of `n` cells from `lo` (border included).
fn fill_enclosed_dense(
    cells: &mut Vec<(UVec3, f32)>,
    (lo, n): (IVec3, [usize; 3]),
    rule: &FillRule,
) {
    let values = BoxValues::new(cells, lo, n);
    let mut marked = values.marked.clone();
    remove_small_groups(&mut marked, rule.min_component);
    let chosen = narrowest_closing(rule.max_gap, |gap| {
        let e = enclosed(&marked, rule.floor.is_some(), gap);
        let count = e.count() as u64;
        (e, count)
    });
    // Kept cells: marked or enclosed, minus the specks.
    let mut keep = marked.clone();
    for (k, e) in keep.bits.iter_mut().zip(&chosen.bits) {
        *k |= e;
    }
    if let Some((min, inside)) = rule.specks {
        drop_specks(&mut keep, &marked, &chosen, &values, min, inside);
    }
    values.write_cells(cells, &keep, &marked);
}

/// [`fill_enclosed`] on tiles ([`tiled::Tiled`]) for a box of `n` cells from `lo` (border
/// included): the same cells in the same order, with memory that follows the marked cells
/// instead of the box. The tiled box is the dense one without its border (everything beyond
/// counts as the border did), rounded up to whole tiles at its far faces: the added cells
/// are free and next to the faces the outside starts from, so they change nothing inside.
fn fill_enclosed_tiled(
    cells: &mut Vec<(UVec3, f32)>,
    (lo, n): (IVec3, [usize; 3]),
    rule: &FillRule,
) -> Result<(), MeshError> {
    let origin = lo + IVec3::ONE;
    let t = [
        (n[0] - 2).div_ceil(tiled::TX),
        (n[1] - 2).div_ceil(tiled::TY),
        (n[2] - 2).div_ceil(tiled::TZ),
    ];
    let tiles = t.iter().map(|&a| a as u64).product::<u64>();
    if tiles > TILE_GRID_LIMIT {
        return Err(MeshError::FillTooLarge {
            cells: n.iter().map(|&a| a as u64).product(),
            limit: TILE_GRID_LIMIT * tiled::TILE_CELLS,
        });
    }
    // Box order (z, y, x); of repeated coordinates the last counts, as in the dense box.
    cells.sort_by_key(|c| (c.0.z, c.0.y, c.0.x));
    // `dedup_by` keeps the first of a run: carry each later value onto it.
    cells.dedup_by(|later, first| {
        let same = later.0 == first.0;
        if same {
            *first = *later;
        }
        same
    });
    let local = |c: UVec3| (c.as_ivec3() - origin).as_uvec3();
    let mut marked = tiled::Tiled::new(t);
    for c in cells.iter() {
        let q = local(c.0);
        marked.set(q.x as usize, q.y as usize, q.z as usize);
    }
    tiled::remove_small_groups(&mut marked, rule.min_component);
    let chosen = narrowest_closing(rule.max_gap, |gap| {
        let e = tiled::enclosed(&marked, rule.floor.is_some(), gap);
        let count = e.count();
        (e, count)
    });
    let mut keep = marked.or(&chosen);
    if let Some((min, inside)) = rule.specks {
        let mut by_value = tiled::Tiled::new(t);
        for c in cells.iter().filter(|c| inside.test(c.1)) {
            let q = local(c.0);
            by_value.set(q.x as usize, q.y as usize, q.z as usize);
        }
        let mut ins = by_value.and(&marked);
        drop(by_value);
        if inside.test(f32::NEG_INFINITY) {
            ins = ins.or(&chosen);
        }
        let mut big = ins.clone();
        tiled::remove_small_groups(&mut big, min);
        keep = keep.and_not(&ins.and_not(&big));
    }
    drop(chosen);
    // The kept cells in box order, in place: the kept marked cells (sorted) stay, then the
    // enclosed ones are merged in from the back (each written slot is at or after the
    // marked cell still to be read).
    let (tx_, ty_, tz_) = (tiled::TX, tiled::TY, tiled::TZ);
    let slot = |c: UVec3| {
        let q = local(c);
        let (x, y, z) = (q.x as usize, q.y as usize, q.z as usize);
        (
            (z / tz_ * t[1] + y / ty_) * t[0] + x / tx_,
            (z % tz_) * ty_ + y % ty_,
            x % tx_,
        )
    };
    cells.retain(|c| {
        let (i, r, b) = slot(c.0);
        (keep.word(i, r) & marked.word(i, r)) >> b & 1 == 1
    });
    let mut j = cells.len();
    let mut w = keep.count() as usize;
    cells.resize(w, (UVec3::ZERO, 0.0));
    for tz in (0..t[2]).rev() {
        for lz in (0..tz_).rev() {
            for ty in (0..t[1]).rev() {
                for ly in (0..ty_).rev() {
                    let r = lz * ty_ + ly;
                    for tx in (0..t[0]).rev() {
                        let i = (tz * t[1] + ty) * t[0] + tx;
                        let mut bits = keep.word(i, r);
                        let m = marked.word(i, r);
                        while bits != 0 {
                            let b = 63 - bits.leading_zeros() as usize;
                            bits &= !(1u64 << b);
                            w -= 1;
                            cells[w] = if m >> b & 1 == 1 {
                                j -= 1;
                                cells[j]
                            } else {
                                let d = IVec3::new(
                                    (tx * tx_ + b) as i32,
                                    (ty * ty_ + ly) as i32,
                                    (tz * tz_ + lz) as i32,
                                );
                                ((origin + d).as_uvec3(), f32::NEG_INFINITY)
                            };
                        }
                    }
                }
            }
        }
    }
    debug_assert!(j == 0 && w == 0);
    Ok(())
}

/// The box the flood fill runs in: the cells' bounds padded by one free layer beyond any
/// closing plus the sentinel border, cut at the floor (its minimum corner and size).
fn fill_box(cells: &[(UVec3, f32)], floor: Option<u32>, max_gap: u32) -> (IVec3, [usize; 3]) {
    let mut lo = IVec3::splat(i32::MAX);
    let mut hi = IVec3::splat(i32::MIN);
    for c in cells {
        lo = lo.min(c.0.as_ivec3());
        hi = hi.max(c.0.as_ivec3());
    }
    let pad = IVec3::splat(max_gap.min(1 << 16) as i32 + 2);
    lo -= pad;
    hi += pad;
    if let Some(f) = floor {
        lo.y = f as i32 - 1;
    }
    let dim = (hi - lo + IVec3::ONE).as_uvec3();
    (lo, [dim.x as usize, dim.y as usize, dim.z as usize])
}

/// The input cells as bits of the fill box, and their values in box order: cell `k` of
/// `marked` has `vals[rank(k)]`.
struct BoxValues {
    lo: IVec3,
    n: [usize; 3],
    /// The input cells (before any group is removed).
    marked: BitBox,
    /// Marked cells before each word of `marked`.
    rank: Vec<u32>,
    vals: Vec<f32>,
}

impl BoxValues {
    fn new(cells: &[(UVec3, f32)], lo: IVec3, n: [usize; 3]) -> Self {
        let mut marked = BitBox::new(n);
        let place = |c: UVec3| {
            let q = (c.as_ivec3() - lo).as_uvec3();
            (q.x as usize, q.z as usize * n[1] + q.y as usize)
        };
        for c in cells {
            let (x, r) = place(c.0);
            marked.set(x, r);
        }
        let mut rank = Vec::with_capacity(marked.bits.len());
        let mut acc = 0u32;
        for b in &marked.bits {
            rank.push(acc);
            acc += b.count_ones();
        }
        let mut out = Self {
            lo,
            n,
            marked,
            rank,
            vals: vec![0.0f32; acc as usize],
        };
        for c in cells {
            let (x, r) = place(c.0);
            let i = out.index(x, r);
            out.vals[i] = c.1;
        }
        out
    }

    /// Index in `vals` of the marked cell at bit `x` of row `r`.
    #[inline]
    fn index(&self, x: usize, r: usize) -> usize {
        let k = r * self.marked.w + x / 64;
        self.rank[k] as usize
            + (self.marked.bits[k] & ((1u64 << (x % 64)) - 1)).count_ones() as usize
    }

    /// Replaces `cells` by the cells of `keep` in z, y, x order: a marked cell with its
    /// value, any other with `-inf` (enclosed).
    fn write_cells(&self, cells: &mut Vec<(UVec3, f32)>, keep: &BitBox, marked: &BitBox) {
        let (n, w) = (self.n, keep.w);
        cells.clear();
        cells.reserve_exact(keep.count());
        for r in 0..keep.rows() {
            let (y, z) = (r % n[1], r / n[1]);
            for i in 0..w {
                let mut bits = keep.bits[r * w + i];
                let m = marked.bits[r * w + i];
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let x = 64 * i + b;
                    let v = if m >> b & 1 == 1 {
                        self.vals[self.index(x, r)]
                    } else {
                        f32::NEG_INFINITY
                    };
                    let p = self.lo + IVec3::new(x as i32, y as i32, z as i32);
                    cells.push((p.as_uvec3(), v));
                }
            }
        }
    }
}

/// The enclosed cells of the smallest closing (from 0) whose enclosed space is at least
/// half that of the widest, `max_gap`.
/// `enclosed(gap)` gives the enclosed cells of a closing and their count (the dense or the
/// tiled fill's).
fn narrowest_closing<S>(max_gap: u32, enclosed: impl Fn(u32) -> (S, u64)) -> S {
    let (widest, reference) = enclosed(max_gap);
    for gap in 0..max_gap {
        let (v, count) = enclosed(gap);
        if 2 * count >= reference {
            return v;
        }
    }
    widest
}

/// Removes from `keep` the connected groups of inside cells (enclosed ones when `-inf`
/// counts as inside, marked ones by their value) smaller than `min`.
fn drop_specks(
    keep: &mut BitBox,
    marked: &BitBox,
    chosen: &BitBox,
    values: &BoxValues,
    min: usize,
    inside: Inside,
) {
    let w = keep.w;
    let enclosed_in = inside.test(f32::NEG_INFINITY);
    let mut ins = BitBox::new(values.n);
    for (k, o) in ins.bits.iter_mut().enumerate() {
        let (m, e) = (marked.bits[k], chosen.bits[k]);
        let mut bits = if enclosed_in { e } else { 0 };
        let mut rest = m;
        while rest != 0 {
            let b = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if inside.test(values.vals[values.index(64 * (k % w) + b, k / w)]) {
                bits |= 1 << b;
            }
        }
        *o = bits;
    }
    let before = ins.clone();
    remove_small_groups(&mut ins, min);
    for ((k, b), a) in keep.bits.iter_mut().zip(&before.bits).zip(&ins.bits) {
        *k &= !(b & !a);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Random cells: blobs (hollow shells with holes, solid lumps) and specks in a small box.
    fn scene() -> impl Strategy<Value = Vec<(UVec3, f32)>> {
        // Across tiles along every axis (64 × 16 × 16 cells each).
        let blob = (2u32..150, 2u32..40, 2u32..40, 1u32..12, 0u8..3);
        let specks = prop::collection::vec((0u32..160, 0u32..50, 0u32..50, -1.0f32..1.0), 0..40);
        (prop::collection::vec(blob, 1..6), specks, any::<u64>()).prop_map(|(blobs, sp, seed)| {
            let mut out = Vec::new();
            let mut h = seed | 1;
            let mut rnd = move || {
                h ^= h << 13;
                h ^= h >> 7;
                h ^= h << 17;
                h
            };
            for (cx, cy, cz, r, kind) in blobs {
                let r = r as i32;
                for z in -r..=r {
                    for y in -r..=r {
                        for x in -r..=r {
                            let d2 = x * x + y * y + z * z;
                            let shell = d2 <= r * r && d2 > (r - 1) * (r - 1);
                            let keep = match kind {
                                0 => shell,
                                1 => shell && rnd() % 7 != 0,
                                _ => d2 <= r * r && rnd() % 3 != 0,
                            };
                            let p = IVec3::new(cx as i32 + x, cy as i32 + y, cz as i32 + z);
                            if keep && p.cmpge(IVec3::ZERO).all() {
                                let v = (rnd() % 200) as f32 / 100.0 - 1.0;
                                out.push((p.as_uvec3(), v));
                            }
                        }
                    }
                }
            }
            out.extend(sp.into_iter().map(|(x, y, z, v)| (UVec3::new(x, y, z), v)));
            out
        })
    }

    /// Both fills on `cells`; asserts they agree and returns the count of enclosed cells.
    fn both(cells: &[(UVec3, f32)], floor: Option<u32>, gap: u32, min: usize) -> usize {
        let rule = FillRule {
            floor,
            max_gap: gap,
            min_component: min,
            specks: Some((min, Inside::NonPositive)),
        };
        both_with(cells, &rule)
    }

    /// Both fills on `cells` with `rule`; asserts they give the same cells, values and order,
    /// and returns the count of enclosed cells.
    fn both_with(cells: &[(UVec3, f32)], rule: &FillRule) -> usize {
        let boxed = fill_box(cells, rule.floor, rule.max_gap);
        let mut dense = cells.to_vec();
        fill_enclosed_dense(&mut dense, boxed, rule);
        let mut tiles = cells.to_vec();
        fill_enclosed_tiled(&mut tiles, boxed, rule).unwrap();
        assert_eq!(dense.len(), tiles.len());
        assert!(
            dense
                .iter()
                .zip(&tiles)
                .all(|(a, b)| a.0 == b.0 && a.1.to_bits() == b.1.to_bits())
        );
        dense.iter().filter(|c| c.1 == f32::NEG_INFINITY).count()
    }

    /// A long box shell (whole tiles inside it, full and clear ones) with a hole: closed by
    /// the gap, or open without; a cavity in a solid wall; the floor as its bottom.
    #[test]
    fn large_shells_agree_with_dense() {
        let (a, b) = (UVec3::new(3, 5, 4), UVec3::new(200, 60, 45));
        let mut cells = Vec::new();
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    let p = UVec3::new(x, y, z);
                    let face = p.cmpeq(a).any() || p.cmpeq(b).any();
                    let hole = x == 100 && y == 30 && z == a.z;
                    if face && !hole {
                        cells.push((p, -0.25));
                    }
                }
            }
        }
        let inner = (b - a - UVec3::splat(1)).as_ivec3();
        let volume = (inner.x * inner.y * inner.z) as usize;
        assert_eq!(both(&cells, None, 1, 8), volume + 1);
        assert_eq!(both(&cells, None, 0, 8), 0);
        // Without its bottom face, standing on the floor.
        let open: Vec<_> = cells.iter().copied().filter(|c| c.0.y != a.y).collect();
        assert!(both(&open, Some(a.y), 1, 8) > volume / 2);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The tiled fill gives exactly the dense fill's cells, values and order.
        #[test]
        fn tiled_fill_equals_dense(
            cells in scene(),
            floor in prop::option::of(0u32..20),
            gap in 0u32..4,
            min_component in 0usize..30,
            specks in prop::option::of((1usize..40, 0u8..3)),
        ) {
            let mut cells = cells;
            if let Some(f) = floor {
                cells.retain(|c| c.0.y >= f);
            }
            prop_assume!(!cells.is_empty());
            let specks = specks.map(|(m, k)| {
                (m, [Inside::Marked, Inside::NotExterior, Inside::NonPositive][k as usize])
            });
            both_with(&cells, &FillRule { floor, max_gap: gap, min_component, specks });
        }
    }
}
