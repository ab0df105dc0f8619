//! From marked cells to the cell field that is marched: weak-cell rejection, small-component
//! removal, floor, and the flood fill that separates the outside from enclosed space.

use std::collections::HashMap;

use voxoct_core::glam::{IVec3, UVec3};
use voxoct_core::{Cell, GridSpec};

use crate::march::Inside;
use crate::mesh::Dsu;
use crate::options::{Floor, MeshError, MeshOptions, Placement};
use crate::tables::corner_offset;

/// Largest dense box (in cells) the flood fill will allocate, at about 7 bytes per cell.
pub const FILL_LIMIT: u64 = 1 << 28;

/// The seven positive Kuhn edge directions (the mesh's connectivity between cells).
fn kuhn_dirs() -> [IVec3; 7] {
    [1u8, 2, 3, 4, 5, 6, 7].map(|d| IVec3::from_array(corner_offset(d)))
}

#[inline]
fn pack(c: UVec3) -> u64 {
    u64::from(c.x) | (u64::from(c.y) << 21) | (u64::from(c.z) << 42)
}

/// Validates the grid and the cells; returns the marked cells as `(coord, value)` with the
/// value in cells (mean signed distance / cell edge, 0 when not finite), and the inside rule.
pub(crate) fn prepare(
    cells: &[Cell],
    grid: &GridSpec,
    opts: &MeshOptions,
    out: &mut Vec<(UVec3, f32)>,
) -> Result<Inside, MeshError> {
    if !grid.origin.is_finite() {
        return Err(MeshError::InvalidGrid("origin is not finite"));
    }
    if !(grid.cell.is_finite() && grid.cell > 0.0) {
        return Err(MeshError::InvalidGrid(
            "cell edge is not finite and positive",
        ));
    }
    if grid.resolution == 0 || grid.resolution > 1 << 20 {
        return Err(MeshError::InvalidGrid("resolution must be in 1..=2^20"));
    }
    if let Some(t) = opts.smoothing
        && !(t.lambda > 0.0 && t.lambda < 1.0 && t.mu < -t.lambda && t.mu > -1.0)
    {
        return Err(MeshError::InvalidOption {
            field: "smoothing",
            reason: "need 0 < lambda < 1 and -1 < mu < -lambda",
        });
    }
    if let Floor::Y(y) = opts.floor
        && !y.is_finite()
    {
        return Err(MeshError::InvalidOption {
            field: "floor",
            reason: "Floor::Y must be finite",
        });
    }
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
        Floor::Y(y) => {
            let l = ((y - grid.origin.y) * inv - 0.5).ceil();
            Some(if l <= 0.0 {
                0
            } else {
                l.min(u32::MAX as f32) as u32
            })
        }
    };
    if let Some(f) = floor_layer {
        out.retain(|c| c.0.y >= f);
    }
    if opts.min_component_cells > 1 {
        remove_small_components(out, opts.min_component_cells, |_| true);
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
        fill_enclosed(out, floor_layer, opts.close_gaps, specks)?;
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

/// Dilates the non-zero cells of a dense `nx × ny × nz` box by `k` cells (L∞), in place.
fn dilate(a: &mut [u8], n: [usize; 3], k: usize) {
    if k == 0 {
        return;
    }
    let stride = [1, n[0], n[0] * n[1]];
    let mut line = Vec::new();
    for axis in 0..3 {
        let (len, s) = (n[axis], stride[axis]);
        let others: Vec<usize> = (0..3).filter(|&a| a != axis).collect();
        for j in 0..n[others[1]] {
            for i in 0..n[others[0]] {
                let base = i * stride[others[0]] + j * stride[others[1]];
                line.clear();
                line.extend((0..len).map(|t| u32::from(a[base + t * s] != 0)));
                // Sliding count of set cells in [t - k, t + k].
                let mut count: u32 = line[..k.min(len)].iter().sum();
                for t in 0..len {
                    if t + k < len {
                        count += line[t + k];
                    }
                    if t > k {
                        count -= line[t - k - 1];
                    }
                    a[base + t * s] = u8::from(count > 0);
                }
            }
        }
    }
}

/// A dense box of cells: the marked cells' bounding box, padded.
struct Dense {
    lo: IVec3,
    n: [usize; 3],
}

impl Dense {
    fn len(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    #[inline]
    fn index(&self, p: IVec3) -> usize {
        let q = (p - self.lo).as_uvec3();
        (q.z as usize * self.n[1] + q.y as usize) * self.n[0] + q.x as usize
    }

    /// Index offsets of the 14 Kuhn neighbours.
    fn offsets(&self) -> [isize; 14] {
        let (sy, sz) = (self.n[0] as isize, (self.n[0] * self.n[1]) as isize);
        let mut out = [0isize; 14];
        for (k, d) in kuhn_dirs().iter().enumerate() {
            let o = d.x as isize + d.y as isize * sy + d.z as isize * sz;
            out[2 * k] = o;
            out[2 * k + 1] = -o;
        }
        out
    }

    /// Whether cell `i` lies on the box's outer layer (the sentinel border).
    #[inline]
    fn on_border(&self, i: usize) -> bool {
        let [nx, ny, nz] = self.n;
        let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
        x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1
    }
}

/// Marks (1) every unmarked cell that the outside cannot reach.
///
/// The outside is flooded through unmarked cells along the mesh's own connectivity (the 14
/// Kuhn neighbours) from the boundary of the padded box (equivalent to the grid boundary:
/// everything beyond is unmarked), never from below the floor (the box's bottom layer when
/// `closed_bottom`). With `gap > 0`, the flood may not pass within `gap` cells (L∞) of a
/// marked cell, and what it reached is grown back by `gap` afterwards: holes in the shell up
/// to `2 · gap` cells wide no longer let the outside in.
fn enclosed(dense: &Dense, marked: &[u8], closed_bottom: bool, gap: u32) -> Vec<u8> {
    let [nx, ny, nz] = dense.n;
    // 1 = blocked (marked or within `gap` of it), 2 = reached by the outside, 3 = the
    // sentinel border (never entered, so neighbours need no bounds checks).
    let mut state = marked.to_vec();
    dilate(&mut state, dense.n, gap as usize);
    const OUT: u8 = 2;
    const WALL: u8 = 3;
    let mut stack: Vec<u32> = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let i = (z * ny + y) * nx + x;
                if x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1 {
                    state[i] = WALL;
                    continue;
                }
                let on_side = x == 1 || x == nx - 2 || z == 1 || z == nz - 2 || y == ny - 2;
                let on_bottom = y == 1 && !closed_bottom;
                if (on_side || on_bottom) && state[i] == 0 {
                    state[i] = OUT;
                    stack.push(i as u32);
                }
            }
        }
    }
    let offsets = dense.offsets();
    while let Some(i) = stack.pop() {
        for o in offsets {
            let j = (i as isize + o) as usize;
            if state[j] == 0 {
                state[j] = OUT;
                stack.push(j as u32);
            }
        }
    }
    // Outside = reached, grown back by `gap`; enclosed = neither outside, marked nor border.
    for s in &mut state {
        *s = u8::from(*s == OUT || *s == WALL);
    }
    dilate(&mut state, dense.n, gap as usize);
    for (s, &m) in state.iter_mut().zip(marked) {
        *s = u8::from(*s == 0 && m == 0);
    }
    state
}

/// Adds the enclosed cells as `-inf` (see [`enclosed`]), closing gaps only as far as needed:
/// with the widest closing `max_gap` as reference, the smallest closing whose enclosed space
/// is at least half of that is used. A shell that is already closed keeps its concavities (no
/// fill in the wedge at the floor); one that leaks gets its gaps closed.
///
/// With `specks = Some((min, inside))`, connected groups of inside cells smaller than `min`
/// are then dropped. The cells come out in z, y, x order.
fn fill_enclosed(
    cells: &mut Vec<(UVec3, f32)>,
    floor: Option<u32>,
    max_gap: u32,
    specks: Option<(usize, Inside)>,
) -> Result<(), MeshError> {
    let mut lo = IVec3::splat(i32::MAX);
    let mut hi = IVec3::splat(i32::MIN);
    for c in cells.iter() {
        lo = lo.min(c.0.as_ivec3());
        hi = hi.max(c.0.as_ivec3());
    }
    // Padding: one free layer beyond any closing, plus the sentinel border.
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
    let dense = Dense {
        lo,
        n: [dim.x as usize, dim.y as usize, dim.z as usize],
    };
    let mut val = vec![f32::INFINITY; dense.len()];
    let mut marked = vec![0u8; dense.len()];
    for c in cells.iter() {
        let i = dense.index(c.0.as_ivec3());
        marked[i] = 1;
        val[i] = c.1;
    }
    let count = |m: &[u8]| m.iter().filter(|&&v| v != 0).count();
    let mut chosen = enclosed(&dense, &marked, floor.is_some(), max_gap);
    let widest = count(&chosen);
    for gap in 0..max_gap {
        let v = enclosed(&dense, &marked, floor.is_some(), gap);
        if 2 * count(&v) >= widest {
            chosen = v;
            break;
        }
    }
    for (v, &e) in val.iter_mut().zip(&chosen) {
        if e != 0 {
            *v = f32::NEG_INFINITY;
        }
    }
    if let Some((min, inside)) = specks {
        // Reuse `chosen` as the visited flags.
        let visited = &mut chosen;
        visited.fill(0);
        let offsets = dense.offsets();
        let mut stack = Vec::new();
        let mut group = Vec::new();
        for start in 0..val.len() {
            if visited[start] != 0 || !inside.test(val[start]) {
                continue;
            }
            visited[start] = 1;
            stack.push(start);
            group.clear();
            while let Some(i) = stack.pop() {
                group.push(i);
                debug_assert!(!dense.on_border(i));
                for o in offsets {
                    let j = (i as isize + o) as usize;
                    if visited[j] == 0 && inside.test(val[j]) {
                        visited[j] = 1;
                        stack.push(j);
                    }
                }
            }
            if group.len() < min {
                for &i in &group {
                    val[i] = f32::INFINITY;
                }
            }
        }
    }
    cells.clear();
    let [nx, ny, _] = dense.n;
    for (i, &v) in val.iter().enumerate() {
        if v != f32::INFINITY {
            let p = lo
                + IVec3::new(
                    (i % nx) as i32,
                    ((i / nx) % ny) as i32,
                    (i / (nx * ny)) as i32,
                );
            cells.push((p.as_uvec3(), v));
        }
    }
    Ok(())
}
