//! Marching tetrahedra over sparse 8×8×8 bricks of pseudo-voxels.
//!
//! Cells are stored in bricks keyed by integer brick coordinates (a hash map per brick, not
//! per cell). Every brick owns the pseudo-voxels (cubes) whose minimum corner lies in it and
//! the grid edges `(p, p + dir)` whose lower end `p` lies in it, so each cube and each edge is
//! visited exactly once, by integer key. For every brick that holds a cell, its seven
//! "minus" neighbours exist too, so every cube that has a cell as a corner is visited.
//!
//! Pass 1 marks, per brick, the edges whose ends differ in inside-ness (bit rows: eight
//! edges per XOR) and numbers them by prefix sums: a vertex's index is its brick's prefix
//! plus a popcount, so welding needs no hash map. Pass 2 places the vertices, pass 3 emits
//! the triangles of the active cubes from the case table.

use std::collections::HashMap;

use voxoct_core::GridSpec;
use voxoct_core::glam::{DVec3, UVec3, Vec3};

use crate::mesh::Mesh;
use crate::options::Placement;
use crate::par;
use crate::tables::{CASES, corner_offset};

/// Grid coordinates are shifted by this so that cube minimum corners at −1 stay positive and
/// every brick's minus neighbours have non-negative keys.
const SHIFT: u32 = 8;
/// Slots per brick for edge bits: 7 directions × 64 rows.
const ROWS: usize = 7 * 64;
/// Vertices never come closer to an edge end than this fraction of the edge.
pub(crate) const T_MIN: f32 = 0.02;
const NONE: u32 = u32::MAX;
/// Bricks per parallel task of the triangle pass (the result does not depend on it).
const BRICKS_PER_TASK: usize = 64;

/// Bits set in each byte (a table: the baseline x86-64 target has no `popcnt`).
static POP8: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (i as u8).count_ones() as u8;
        i += 1;
    }
    t
};

/// Which cells count as inside, from their stored value (finite: a marked cell's mean signed
/// distance in cells; `-inf`: an enclosed unmarked cell; `+inf`: outside / absent).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Inside {
    /// Marked cells only (hollow shell).
    Marked,
    /// Marked and enclosed cells (solid, midpoint).
    NotExterior,
    /// Enclosed cells and marked cells whose centre is inside the surface (solid, sdf).
    NonPositive,
}

impl Inside {
    #[inline]
    pub(crate) fn test(self, f: f32) -> bool {
        match self {
            Self::Marked => f.is_finite(),
            Self::NotExterior => f != f32::INFINITY,
            Self::NonPositive => f <= 0.0,
        }
    }
}

#[inline]
fn brick_key(b: [u32; 3]) -> u64 {
    u64::from(b[0]) | (u64::from(b[1]) << 21) | (u64::from(b[2]) << 42)
}

#[inline]
const fn local(x: u32, y: u32, z: u32) -> usize {
    ((z as usize * 8) + y as usize) * 8 + x as usize
}

#[derive(Debug, Default)]
struct Bricks {
    map: HashMap<u64, u32>,
    keys: Vec<[u32; 3]>,
    vals: Vec<f32>,
    /// Inside bits, `[brick][z * 8 + y]`, bit `x`.
    rows: Vec<u8>,
    /// `[brick][o]`: the brick at `key + offset(o)`, or `NONE`.
    nb: Vec<[u32; 8]>,
}

impl Bricks {
    fn build(&mut self, entries: &[(UVec3, f32)], inside: Inside, min_piece: usize) {
        let Self {
            map,
            keys,
            vals,
            rows,
            nb,
        } = self;
        map.clear();
        keys.clear();
        vals.clear();
        let mut get = |k: [u32; 3], keys: &mut Vec<[u32; 3]>, vals: &mut Vec<f32>| -> usize {
            *map.entry(brick_key(k)).or_insert_with(|| {
                keys.push(k);
                vals.resize(vals.len() + 512, f32::INFINITY);
                (keys.len() - 1) as u32
            }) as usize
        };
        let mut last = ([u32::MAX; 3], 0usize);
        for &(c, f) in entries {
            let g = c + UVec3::splat(SHIFT);
            let k = [g.x >> 3, g.y >> 3, g.z >> 3];
            let b = if k == last.0 {
                last.1
            } else {
                let b = get(k, keys, vals);
                last = (k, b);
                b
            };
            vals[b * 512 + local(g.x & 7, g.y & 7, g.z & 7)] = f;
        }
        let occupied = keys.len();
        for b in 0..occupied {
            let k = keys[b];
            for o in 1..8u8 {
                let d = corner_offset(o);
                let m = [0, 1, 2].map(|i| k[i] - d[i] as u32);
                get(m, keys, vals);
            }
        }
        if inside == Inside::NonPositive {
            let floor = entries.iter().map(|e| e.0.y + SHIFT).min().unwrap_or(0);
            let mut field = Field { map, vals };
            peel_unobserved(&mut field, keys, floor, min_piece);
        }
        let n = keys.len();
        rows.clear();
        rows.resize(n * 64, 0);
        for (b, r) in rows.chunks_exact_mut(64).enumerate() {
            let v = &vals[b * 512..(b + 1) * 512];
            for (row, bits) in r.iter_mut().enumerate() {
                let mut m = 0u8;
                for x in 0..8 {
                    if inside.test(v[row * 8 + x]) {
                        m |= 1 << x;
                    }
                }
                *bits = m;
            }
        }
        nb.clear();
        nb.extend(keys.iter().map(|k| {
            let mut out = [NONE; 8];
            for (o, slot) in out.iter_mut().enumerate() {
                let d = corner_offset(o as u8);
                let m = [0, 1, 2].map(|i| k[i] + d[i] as u32);
                if let Some(&i) = map.get(&brick_key(m)) {
                    *slot = i;
                }
            }
            out
        }));
    }

    /// Inside bits of the 9×9×9 padded block `[z][y]`, bit `x` (0..9).
    fn padded_rows(&self, b: usize) -> [[u16; 9]; 9] {
        let mut p = [[0u16; 9]; 9];
        let nb = &self.nb[b];
        for (z, pz) in p.iter_mut().enumerate() {
            for (y, pyz) in pz.iter_mut().enumerate() {
                let o = (usize::from(y == 8) << 1) | (usize::from(z == 8) << 2);
                let row = (z & 7) * 8 + (y & 7);
                let mut bits = 0u16;
                let b0 = nb[o];
                if b0 != NONE {
                    bits = u16::from(self.rows[b0 as usize * 64 + row]);
                }
                let b1 = nb[o | 1];
                if b1 != NONE {
                    bits |= u16::from(self.rows[b1 as usize * 64 + row] & 1) << 8;
                }
                *pyz = bits;
            }
        }
        p
    }

    /// Value of the cell at padded local coordinates `p` (0..=8) of brick `b`.
    #[inline]
    fn value(&self, b: usize, p: [u32; 3]) -> f32 {
        let o = (p[0] >> 3) | ((p[1] >> 3) << 1) | ((p[2] >> 3) << 2);
        let bb = self.nb[b][o as usize];
        if bb == NONE {
            f32::INFINITY
        } else {
            self.vals[bb as usize * 512 + local(p[0] & 7, p[1] & 7, p[2] & 7)]
        }
    }
}

/// Where the surface crosses the edge from a cell of value `fp` to one of value `fq`
/// (exactly one of them inside), as a fraction from the first; `len` is the edge length in
/// cells.
#[inline]
pub(crate) fn crossing(placement: Placement, fp: f32, fq: f32, len: f32) -> f32 {
    match placement {
        Placement::Midpoint => 0.5,
        Placement::SignedDistance => {
            let t = match (fp.is_finite(), fq.is_finite()) {
                (true, true) => fp / (fp - fq),
                // Towards an outside cell the surface is at -d; towards an enclosed one at +d.
                (true, false) => (if fq > 0.0 { -fp } else { fp }) / len,
                (false, true) => 1.0 - (if fp > 0.0 { -fq } else { fq }) / len,
                (false, false) => 0.5,
            };
            if t.is_nan() {
                0.5
            } else {
                t.clamp(T_MIN, 1.0 - T_MIN)
            }
        }
    }
}

/// Largest signed distance a cell marked by triangles can hold, in cells: the plane of a
/// triangle that touches the cell passes within half its diagonal of its centre. A value
/// below its negative (`-inf` for an enclosed cell, `-1` for one the closure adds) is an
/// inside cell that no triangle observed.
const HALF_DIAGONAL: f32 = 0.867;

/// Whether `f` is an inside cell that no triangle observed (see [`HALF_DIAGONAL`]).
#[inline]
fn unobserved_inside(f: f32) -> bool {
    f < -HALF_DIAGONAL
}

/// Whether `f` is a cell marked by triangles (its mean signed distance, see [`HALF_DIAGONAL`]).
#[inline]
fn observed(f: f32) -> bool {
    f.is_finite() && f >= -HALF_DIAGONAL
}

/// Cell values by global (shifted) grid coordinates, over the bricks of [`Bricks::build`].
struct Field<'a> {
    map: &'a HashMap<u64, u32>,
    vals: &'a mut [f32],
}

impl Field<'_> {
    /// The slot of cell `g`, `None` where no brick holds it (its value is `+inf`).
    fn slot(&self, g: [i64; 3]) -> Option<usize> {
        if g.iter().any(|&c| !(0..1 << 24).contains(&c)) {
            return None;
        }
        let g = g.map(|c| c as u32);
        let b = *self
            .map
            .get(&brick_key([g[0] >> 3, g[1] >> 3, g[2] >> 3]))?;
        Some(b as usize * 512 + local(g[0] & 7, g[1] & 7, g[2] & 7))
    }

    fn get(&self, g: [i64; 3]) -> f32 {
        self.slot(g).map_or(f32::INFINITY, |i| self.vals[i])
    }
}

/// Turns outside every unobserved inside cell that lies, along a grid axis, between the
/// outside (an absent cell at or above the layer `floor`, shifted coordinates) and an
/// observed cell; then drops the pieces of inside cells smaller than `min_piece` cells that
/// this cuts off (as the fill drops specks, see `MeshOptions::min_component_cells`).
///
/// Why: the fill's gap closing and the closure put unobserved cells into the one-cell dents
/// of the observed shell's ragged outer face. The observed cell's surface passes within half
/// a diagonal of its centre and the outside lies beyond it, so the unobserved cell, a whole
/// cell further out, lies outside that surface. Kept inside, such cells move the surface out
/// by up to a cell wherever the outer face is ragged: over whole faces where noise or depth
/// quantisation makes the shell two layers thick in patches.
fn peel_unobserved(field: &mut Field<'_>, keys: &[[u32; 3]], floor: u32, min_piece: usize) {
    let below_floor = |g: [i64; 3]| g[1] < i64::from(floor);
    let mut peeled = Vec::new();
    for (b, k) in keys.iter().enumerate() {
        let vals = &field.vals[b * 512..(b + 1) * 512];
        // Only unobserved inside cells can be peeled.
        if !vals.iter().any(|&f| unobserved_inside(f)) {
            continue;
        }
        let base = [0, 1, 2].map(|a| i64::from(k[a] * 8));
        // The bricks across each face, `[axis][0: minus, 1: plus]`.
        let faces: [[Option<usize>; 2]; 3] = std::array::from_fn(|a| {
            [-1i64, 1].map(|d| {
                let mut n = k.map(i64::from);
                n[a] += d;
                let n = n.map(|c| u32::try_from(c).ok());
                let n = [n[0]?, n[1]?, n[2]?];
                field.map.get(&brick_key(n)).map(|&x| x as usize)
            })
        });
        for (i, &f) in vals.iter().enumerate() {
            if !unobserved_inside(f) {
                continue;
            }
            let p = [(i & 7) as i64, ((i >> 3) & 7) as i64, (i >> 6) as i64];
            // The value of the cell at local offset `q` (at most one step out of the brick,
            // along one axis: a face neighbour's brick).
            let value = |q: [i64; 3]| {
                let mut nb = b;
                for (a, c) in q.iter().enumerate() {
                    if !(0..8).contains(c) {
                        match faces[a][usize::from(*c > 0)] {
                            Some(n) => nb = n,
                            None => return f32::INFINITY,
                        }
                    }
                }
                let q = q.map(|c| (c & 7) as u32);
                field.vals[nb * 512 + local(q[0], q[1], q[2])]
            };
            let between = (0..3).any(|axis| {
                [-1, 1].into_iter().any(|sign| {
                    let (mut out, mut back) = (p, p);
                    out[axis] += sign;
                    back[axis] -= sign;
                    !below_floor([0, base[1] + out[1], 0])
                        && value(out) == f32::INFINITY
                        && observed(value(back))
                })
            });
            if between {
                peeled.push([base[0] + p[0], base[1] + p[1], base[2] + p[2]]);
            }
        }
    }
    for &g in &peeled {
        if let Some(i) = field.slot(g) {
            field.vals[i] = f32::INFINITY;
        }
    }
    if min_piece < 2 {
        return;
    }
    // The mesh connects cells along the 14 Kuhn directions.
    let kuhn: Vec<[i64; 3]> = (1..8u8)
        .flat_map(|d| {
            let o = corner_offset(d).map(i64::from);
            [o, o.map(|c| -c)]
        })
        .collect();
    let inside = |f: f32| f <= 0.0;
    let mut big = std::collections::HashSet::new();
    let mut piece = Vec::new();
    let mut member = std::collections::HashSet::new();
    for g in peeled {
        for d in &kuhn {
            let start = [g[0] + d[0], g[1] + d[1], g[2] + d[2]];
            if !inside(field.get(start)) || big.contains(&start) {
                continue;
            }
            // The inside piece from `start`, searched until it reaches `min_piece` cells or a
            // piece already known to be that large.
            piece.clear();
            member.clear();
            piece.push(start);
            member.insert(start);
            let mut next = 0;
            let mut joined = false;
            'search: while next < piece.len() && piece.len() < min_piece {
                let c = piece[next];
                next += 1;
                for d in &kuhn {
                    let n = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
                    if big.contains(&n) {
                        joined = true;
                        break 'search;
                    }
                    if inside(field.get(n)) && member.insert(n) {
                        piece.push(n);
                    }
                }
            }
            if joined || piece.len() >= min_piece {
                big.extend(piece.iter().copied());
                continue;
            }
            for &c in &piece {
                if let Some(i) = field.slot(c) {
                    field.vals[i] = f32::INFINITY;
                }
            }
        }
    }
}

/// A brick's edge rows and inside bits.
#[derive(Debug, Clone)]
struct BrickRows {
    /// Per edge row: the index of the row's first vertex (low 32 bits) and the row's
    /// crossing-edge mask (bits 32..40), in one word so a lookup is one load.
    rows: [u64; ROWS],
    /// [`Bricks::padded_rows`].
    padded: [[u16; 9]; 9],
    /// Vertices on the brick's edges.
    count: u32,
}

/// Buffers reused from one meshing to the next.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    /// The cells to march (grid coordinates and value, see [`Inside`]).
    pub entries: Vec<(UVec3, f32)>,
    bricks: Bricks,
    per_brick: Vec<BrickRows>,
}

/// Marches `scratch.entries` into `out` (cleared first). With [`Inside::NonPositive`], the
/// unobserved cells in the dents of the observed surface are turned outside first, and the
/// inside pieces of fewer than `min_piece` cells this cuts off dropped (see
/// [`peel_unobserved`]).
pub(crate) fn march(
    scratch: &mut Scratch,
    grid: &GridSpec,
    (inside, min_piece): (Inside, usize),
    placement: Placement,
    out: &mut Mesh,
) {
    let Scratch {
        entries,
        bricks,
        per_brick,
    } = scratch;
    bricks.build(entries, inside, min_piece);
    let brick_first = number_vertices(bricks, per_brick);
    place_vertices(
        bricks,
        per_brick,
        &brick_first,
        grid,
        inside,
        placement,
        &mut out.vertices,
    );
    let vertex_count = brick_first[bricks.keys.len()];
    emit_triangles(bricks, per_brick, vertex_count, &mut out.triangles);
}

/// Pass 1, per brick: the crossing-edge masks of its rows and their vertex indices (the
/// brick's first vertex, from a prefix sum over the bricks, plus the offset within the
/// brick). Returns the first vertex of every brick and, last, the vertex count.
fn number_vertices(bricks: &Bricks, per_brick: &mut Vec<BrickRows>) -> Vec<u32> {
    let n = bricks.keys.len();
    par::map_into(per_brick, n, |b| {
        let p = bricks.padded_rows(b);
        let mut rows = [0u64; ROWS];
        let mut count = 0u32;
        for d in 1..8u8 {
            let [dx, dy, dz] = corner_offset(d).map(|v| v as usize);
            for z in 0..8 {
                for y in 0..8 {
                    let a = p[z][y];
                    let c = p[z + dz][y + dy] >> dx;
                    let m = ((a ^ c) & 0xFF) as u8;
                    rows[(d as usize - 1) * 64 + z * 8 + y] =
                        u64::from(count) | (u64::from(m) << 32);
                    count += u32::from(POP8[m as usize]);
                }
            }
        }
        BrickRows {
            rows,
            padded: p,
            count,
        }
    });
    let mut brick_first = vec![0u32; n + 1];
    for b in 0..n {
        brick_first[b + 1] = brick_first[b] + per_brick[b].count;
    }
    par::for_each_zip(per_brick.iter_mut(), 0..n, |b, br, _| {
        let first = u64::from(brick_first[b]);
        for r in &mut br.rows {
            *r += first;
        }
    });
    brick_first
}

/// Pass 2: vertex positions, in index order (each brick fills its own range of
/// `vertices`, which is cleared first).
fn place_vertices(
    bricks: &Bricks,
    per_brick: &[BrickRows],
    brick_first: &[u32],
    grid: &GridSpec,
    inside: Inside,
    placement: Placement,
    vertices: &mut Vec<Vec3>,
) {
    let n = bricks.keys.len();
    let count = brick_first[n];
    let cell = f64::from(grid.cell);
    // World position of grid point g (shifted coordinates): origin + (g - SHIFT + 0.5) · cell.
    let offset = grid.origin.as_dvec3() + DVec3::splat((0.5 - f64::from(SHIFT)) * cell);
    vertices.clear();
    vertices.resize(count as usize, Vec3::ZERO);
    let mut ranges = Vec::with_capacity(n);
    let mut rest = &mut vertices[..];
    for b in 0..n {
        let (head, tail) = rest.split_at_mut((brick_first[b + 1] - brick_first[b]) as usize);
        ranges.push(head);
        rest = tail;
    }
    par::for_each_zip(ranges.iter_mut(), 0..n, |b, dst, _| {
        let key = bricks.keys[b];
        let base = [key[0] * 8, key[1] * 8, key[2] * 8];
        let mut next = dst.iter_mut();
        for d in 1..8u8 {
            let dir = corner_offset(d);
            let dirf = DVec3::new(f64::from(dir[0]), f64::from(dir[1]), f64::from(dir[2]));
            let len = ((dir[0] + dir[1] + dir[2]) as f32).sqrt();
            for z in 0..8u32 {
                for y in 0..8u32 {
                    let mut m = (per_brick[b].rows[(d as usize - 1) * 64 + (z * 8 + y) as usize]
                        >> 32) as u8;
                    while m != 0 {
                        let x = m.trailing_zeros();
                        m &= m - 1;
                        let t = if placement == Placement::Midpoint {
                            0.5
                        } else {
                            let p = [x, y, z];
                            let q = [x + dir[0] as u32, y + dir[1] as u32, z + dir[2] as u32];
                            let fp = bricks.value(b, p);
                            let fq = bricks.value(b, q);
                            if inside.test(fp) {
                                crossing(placement, fp, fq, len)
                            } else {
                                1.0 - crossing(placement, fq, fp, len)
                            }
                        };
                        let t = f64::from(t);
                        let g = DVec3::new(
                            f64::from(base[0] + x) + t * dirf.x,
                            f64::from(base[1] + y) + t * dirf.y,
                            f64::from(base[2] + z) + t * dirf.z,
                        );
                        let pos = offset + g * cell;
                        if let Some(v) = next.next() {
                            *v = pos.as_vec3();
                        }
                    }
                }
            }
        }
        debug_assert!(next.next().is_none());
    });
}

/// Pass 3: triangles, per group of bricks, joined in brick order (`triangles` is
/// cleared first; `count` vertices make the capacity guess).
fn emit_triangles(
    bricks: &Bricks,
    per_brick: &[BrickRows],
    count: u32,
    triangles: &mut Vec<[u32; 3]>,
) {
    let n = bricks.keys.len();
    let table = &*CASES;
    let brick_triangles = |b: usize, triangles: &mut Vec<[u32; 3]>| {
        let p = &per_brick[b].padded;
        // The eight bricks this brick's cubes reach into.
        let nb = bricks.nb[b];
        for z in 0..8usize {
            for y in 0..8usize {
                let r = [[p[z][y], p[z][y + 1]], [p[z + 1][y], p[z + 1][y + 1]]];
                let any = r[0][0] | r[0][1] | r[1][0] | r[1][1];
                let all = r[0][0] & r[0][1] & r[1][0] & r[1][1];
                let mut active = ((any | (any >> 1)) & !(all & (all >> 1))) & 0xFF;
                while active != 0 {
                    let x = active.trailing_zeros();
                    active &= active - 1;
                    // Corner i = ox + 2 oy + 4 oz: two x-neighbour bits from each row.
                    let case = usize::from((r[0][0] >> x) & 3)
                        | usize::from((r[0][1] >> x) & 3) << 2
                        | usize::from((r[1][0] >> x) & 3) << 4
                        | usize::from((r[1][1] >> x) & 3) << 6;
                    let edges = &table.edges
                        [table.edge_start[case] as usize..table.edge_start[case + 1] as usize];
                    let mut ids = [0u32; 19];
                    for (id, e) in ids.iter_mut().zip(edges) {
                        let (px, py, pz) = (x + e.ox, y as u32 + e.oy, z as u32 + e.oz);
                        let o = (px >> 3) | ((py >> 3) << 1) | ((pz >> 3) << 2);
                        let w = per_brick[nb[o as usize] as usize].rows
                            [e.row + ((pz & 7) * 8 + (py & 7)) as usize];
                        let m = (w >> 32) as u32;
                        debug_assert!(m >> (px & 7) & 1 == 1, "edge without a vertex");
                        *id = w as u32 + u32::from(POP8[(m & ((1u32 << (px & 7)) - 1)) as usize]);
                    }
                    let local =
                        &table.local[table.start[case] as usize..table.start[case + 1] as usize];
                    triangles.extend(
                        local
                            .iter()
                            .map(|l| [ids[l[0] as usize], ids[l[1] as usize], ids[l[2] as usize]]),
                    );
                }
            }
        }
    };
    triangles.clear();
    // A closed piece of genus g has 2 (V - 2 + 2g) triangles: twice the vertices, plus slack
    // for handles, so that the buffer need not double.
    triangles.reserve(count as usize * 2 + count as usize / 32 + 64);
    par::extend_in_order(triangles, n, BRICKS_PER_TASK, brick_triangles);
}
