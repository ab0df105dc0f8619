//! From marked cells to the cell field that is marched: weak-cell rejection, small-component
//! removal, floor, and the flood fill that separates the outside from enclosed space (over a
//! dense box of bits, see the `bitbox` module).

use std::collections::HashMap;

use voxoct_core::glam::{IVec3, UVec3};
use voxoct_core::{Cell, GridSpec};

use crate::bitbox::{BitBox, Flood, remove_small_groups};
use crate::march::Inside;
use crate::mesh::Dsu;
use crate::options::{Floor, MeshError, MeshOptions, Placement};
use crate::tables::corner_offset;

/// Largest dense box (in cells) the flood fill will allocate, at under 2 bytes per cell.
pub const FILL_LIMIT: u64 = 1 << 28;

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
/// value in cells (mean signed distance / cell edge, 0 when not finite), and the inside rule.
pub(crate) fn prepare(
    cells: &[Cell],
    grid: &GridSpec,
    opts: &MeshOptions,
    out: &mut Vec<(UVec3, f32)>,
) -> Result<Inside, MeshError> {
    check_arguments(grid, opts)?;
    let min_hits = opts.min_hits.max(1);
    let inv = 1.0 / grid.cell;
    out.clear();
    out.reserve(cells.len());
    for (index, c) in cells.iter().enumerate() {
        if c.coord.max_element() >= grid.resolution {
            return Err(MeshError::CellOutsideGrid {
                index,
                coord: c.coord,
                resolution: grid.resolution,
            });
        }
        if c.hits >= min_hits {
            let v = c.mean_sdf() * inv;
            out.push((c.coord, if v.is_finite() { v } else { 0.0 }));
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
        fill_enclosed(
            out,
            floor_layer,
            opts.close_gaps,
            opts.min_component_cells,
            specks,
        )?;
    } else if opts.min_component_cells > 1 {
        remove_small_components(out, opts.min_component_cells, |_| true);
    }
    Ok(inside)
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

/// Adds the enclosed cells as `-inf` (see [`enclosed`]), closing gaps only as far as needed:
/// with the widest closing `max_gap` as reference, the smallest closing whose enclosed space
/// is at least half of that is used. A shell that is already closed keeps its concavities (no
/// fill in the wedge at the floor); one that leaks gets its gaps closed.
///
/// Connected groups of marked cells smaller than `min_component` are dropped first. With
/// `specks = Some((min, inside))`, connected groups of inside cells smaller than `min` are
/// dropped at the end. The cells come out in z, y, x order.
fn fill_enclosed(
    cells: &mut Vec<(UVec3, f32)>,
    floor: Option<u32>,
    max_gap: u32,
    min_component: usize,
    specks: Option<(usize, Inside)>,
) -> Result<(), MeshError> {
    let (lo, n) = fill_box(cells, floor, max_gap)?;
    let values = BoxValues::new(cells, lo, n);
    let mut marked = values.marked.clone();
    remove_small_groups(&mut marked, min_component);
    let chosen = narrowest_closing(&marked, floor.is_some(), max_gap);
    // Kept cells: marked or enclosed, minus the specks.
    let mut keep = marked.clone();
    for (k, e) in keep.bits.iter_mut().zip(&chosen.bits) {
        *k |= e;
    }
    if let Some((min, inside)) = specks {
        drop_specks(&mut keep, &marked, &chosen, &values, min, inside);
    }
    values.write_cells(cells, &keep, &marked);
    Ok(())
}

/// The box the flood fill runs in: the cells' bounds padded by one free layer beyond any
/// closing plus the sentinel border, cut at the floor (its minimum corner and size).
fn fill_box(
    cells: &[(UVec3, f32)],
    floor: Option<u32>,
    max_gap: u32,
) -> Result<(IVec3, [usize; 3]), MeshError> {
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
    let total = u64::from(dim.x) * u64::from(dim.y) * u64::from(dim.z);
    if total > FILL_LIMIT {
        return Err(MeshError::FillTooLarge {
            cells: total,
            limit: FILL_LIMIT,
        });
    }
    Ok((lo, [dim.x as usize, dim.y as usize, dim.z as usize]))
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
fn narrowest_closing(marked: &BitBox, floor: bool, max_gap: u32) -> BitBox {
    let widest = enclosed(marked, floor, max_gap);
    let reference = widest.count();
    for gap in 0..max_gap {
        let v = enclosed(marked, floor, gap);
        if 2 * v.count() >= reference {
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
