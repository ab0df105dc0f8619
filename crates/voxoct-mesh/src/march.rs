//! Marching tetrahedra over sparse 8×8×8 bricks of pseudo-voxels.
//!
//! Cells are stored in bricks keyed by integer brick coordinates (a hash map per brick, not
//! per cell). Every brick owns the pseudo-voxels (cubes) whose minimum corner lies in it and
//! the grid edges `(p, p + dir)` whose lower end `p` lies in it, so each cube and each edge is
//! visited exactly once, by integer key. For every brick that holds a cell, its seven
//! "minus" neighbours exist too, so every cube that has a cell as a corner is visited.
//!
//! Before the passes, in solid signed-distance mode, the cell field is cleaned up: the
//! unobserved cells in the one-cell dents of the observed surface are turned outside
//! (`peel_unobserved`), and absent cells are filled where a tetrahedron's diagonal would
//! let the outside through a wall that inside cells close on every face path
//! (`diagonal_leaks`).
//!
//! Pass 1 marks, per brick, the edges whose ends differ in inside-ness (bit rows: eight
//! edges per XOR) and numbers them by prefix sums: a vertex's index is its brick's prefix
//! plus a popcount, so welding needs no hash map. Pass 2 places the vertices, pass 3 emits
//! the triangles of the active cubes from the case table, each brick into its own range of
//! the output (counted in pass 1), so the triangles are stored once.
//!
//! Memory follows the surface: a brick without cells (a minus neighbour) stores no values,
//! and only a brick with vertices stores its edge rows (3 bytes a row); values and cells go
//! as soon as the passes that read them are done (one-shot meshing).

use std::collections::HashMap;

use voxoct_core::GridSpec;
use voxoct_core::glam::{DVec3, UVec3, Vec3};

use crate::backs::{self, Back};
use crate::mesh::Mesh;
use crate::options::Placement;
use crate::par;
use crate::tables::{CASES, CaseTable, corner_offset};

/// Grid coordinates are shifted by this so that cube minimum corners at −1 stay positive and
/// every brick's minus neighbours have non-negative keys.
const SHIFT: u32 = 8;
/// Slots per brick for edge bits: 7 directions × 64 rows.
const ROWS: usize = 7 * 64;
/// Vertices never come closer to an edge end than this fraction of the edge.
pub(crate) const T_MIN: f32 = 0.02;
const NONE: u32 = u32::MAX;

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
    /// Per brick: its block of 512 values in `vals`, or `NONE` (no cell: every value
    /// `+inf`).
    block: Vec<u32>,
    /// Values, 512 per brick that holds a cell, `[z][y][x]`.
    vals: Vec<f32>,
    /// Inside bits, `[brick][z * 8 + y]`, bit `x`.
    rows: Vec<u8>,
    /// `[brick][o]`: the brick at `key + offset(o)`, or `NONE`.
    nb: Vec<[u32; 8]>,
}

impl Bricks {
    fn build(&mut self, entries: &[(UVec3, f32)], inside: Inside, peel: Option<usize>) {
        let Self {
            map,
            keys,
            block,
            vals,
            rows,
            nb,
        } = self;
        map.clear();
        keys.clear();
        block.clear();
        vals.clear();
        let mut last = ([u32::MAX; 3], 0usize);
        for &(c, f) in entries {
            let g = c + UVec3::splat(SHIFT);
            let k = [g.x >> 3, g.y >> 3, g.z >> 3];
            let v = if k == last.0 {
                last.1
            } else {
                let v = held_brick(map, keys, block, vals, k).1;
                last = (k, v);
                v
            };
            vals[v * 512 + local(g.x & 7, g.y & 7, g.z & 7)] = f;
        }
        for b in 0..keys.len() {
            keep_minus_neighbours(map, keys, block, b);
        }
        if let Some(min_piece) = peel.filter(|_| inside == Inside::NonPositive) {
            let floor = entries.iter().map(|e| e.0.y + SHIFT).min().unwrap_or(0);
            let mut field = Field { map, block, vals };
            peel_unobserved(&mut field, keys, floor, min_piece);
        }
        if inside == Inside::NonPositive {
            // The first round looks at every brick, a later one only around the cells the
            // round before filled (nothing else changed).
            let mut look: Vec<usize> = (0..keys.len()).collect();
            for _ in 0..SEAL_ROUNDS {
                let fills = diagonal_leaks(&Field { map, block, vals }, keys, &look);
                if fills.is_empty() {
                    break;
                }
                for &g in &fills {
                    let g = g.map(|c| c as u32);
                    let k = [g[0] >> 3, g[1] >> 3, g[2] >> 3];
                    let (b, v) = held_brick(map, keys, block, vals, k);
                    vals[v * 512 + local(g[0] & 7, g[1] & 7, g[2] & 7)] = 0.0;
                    keep_minus_neighbours(map, keys, block, b);
                }
                look.clear();
                for g in &fills {
                    for o in 0..27 {
                        let k = [0, 1, 2].map(|a| (g[a] >> 3) + [o % 3, o / 3 % 3, o / 9][a] - 1);
                        if let Some(&b) = k
                            .iter()
                            .all(|&c| c >= 0)
                            .then(|| map.get(&brick_key(k.map(|c| c as u32))))
                            .flatten()
                        {
                            look.push(b as usize);
                        }
                    }
                }
                look.sort_unstable();
                look.dedup();
            }
        }
        let n = keys.len();
        rows.clear();
        rows.resize(n * 64, 0);
        let absent = if inside.test(f32::INFINITY) { 0xFF } else { 0 };
        for (b, r) in rows.chunks_exact_mut(64).enumerate() {
            if block[b] == NONE {
                r.fill(absent);
                continue;
            }
            let v = &vals[block[b] as usize * 512..][..512];
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

    /// Value of the cell at global (shifted) coordinates `g` (`+inf` where no brick holds
    /// it).
    fn value_at(&self, g: [i64; 3]) -> f32 {
        slot_in(&self.map, &self.block, g).map_or(f32::INFINITY, |i| self.vals[i])
    }

    /// Value of the cell at global (shifted) coordinates `g`, near brick `b` whose first
    /// cell is `base`: [`Self::value`] where `g` is within the brick's padded reach (no
    /// hash lookup), else [`Self::value_at`]; the same value either way.
    #[inline]
    fn value_near(&self, b: usize, base: [u32; 3], g: [i64; 3]) -> f32 {
        let p = [0, 1, 2].map(|k| g[k] - i64::from(base[k]));
        if p.iter().all(|c| (0..=8).contains(c)) {
            self.value(b, p.map(|c| c as u32))
        } else {
            self.value_at(g)
        }
    }

    /// Value of the cell at padded local coordinates `p` (0..=8) of brick `b`.
    #[inline]
    fn value(&self, b: usize, p: [u32; 3]) -> f32 {
        let o = (p[0] >> 3) | ((p[1] >> 3) << 1) | ((p[2] >> 3) << 2);
        let bb = self.nb[b][o as usize];
        let v = if bb == NONE {
            NONE
        } else {
            self.block[bb as usize]
        };
        if v == NONE {
            f32::INFINITY
        } else {
            self.vals[v as usize * 512 + local(p[0] & 7, p[1] & 7, p[2] & 7)]
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
/// below its negative (`-inf` for an enclosed cell or one the closure adds) is an
/// inside cell that no triangle observed. (A thousandth of a cell over the half diagonal:
/// the mean of the triangles' distances carries rounding.)
const HALF_DIAGONAL: f32 = voxoct_core::HALF_CELL_DIAGONAL + 1e-3;

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

/// The brick at key `k` (added when missing) and its block of values (allocated, all
/// `+inf`, when it had none).
fn held_brick(
    map: &mut HashMap<u64, u32>,
    keys: &mut Vec<[u32; 3]>,
    block: &mut Vec<u32>,
    vals: &mut Vec<f32>,
    k: [u32; 3],
) -> (usize, usize) {
    let b = brick_index(map, keys, block, k);
    if block[b] == NONE {
        block[b] = (vals.len() / 512) as u32;
        vals.resize(vals.len() + 512, f32::INFINITY);
    }
    (b, block[b] as usize)
}

/// The index of the brick at key `k`, added (without values) when missing.
fn brick_index(
    map: &mut HashMap<u64, u32>,
    keys: &mut Vec<[u32; 3]>,
    block: &mut Vec<u32>,
    k: [u32; 3],
) -> usize {
    *map.entry(brick_key(k)).or_insert_with(|| {
        keys.push(k);
        block.push(NONE);
        (keys.len() - 1) as u32
    }) as usize
}

/// Adds the seven minus neighbours of brick `b` when it holds values, so that every cube
/// with a cell as a corner is visited.
fn keep_minus_neighbours(
    map: &mut HashMap<u64, u32>,
    keys: &mut Vec<[u32; 3]>,
    block: &mut Vec<u32>,
    b: usize,
) {
    if block[b] == NONE {
        return;
    }
    let k = keys[b];
    for o in 1..8u8 {
        let d = corner_offset(o);
        brick_index(map, keys, block, [0, 1, 2].map(|i| k[i] - d[i] as u32));
    }
}

/// The slot in [`Bricks::vals`] of the cell at global (shifted) coordinates `g`, `None`
/// where no brick holds it (its value is `+inf`).
fn slot_in(map: &HashMap<u64, u32>, block: &[u32], g: [i64; 3]) -> Option<usize> {
    if g.iter().any(|&c| !(0..1 << 24).contains(&c)) {
        return None;
    }
    let g = g.map(|c| c as u32);
    let b = *map.get(&brick_key([g[0] >> 3, g[1] >> 3, g[2] >> 3]))?;
    let v = block[b as usize];
    (v != NONE).then(|| v as usize * 512 + local(g[0] & 7, g[1] & 7, g[2] & 7))
}

/// Cell values by global (shifted) grid coordinates, over the bricks of [`Bricks::build`].
struct Field<'a> {
    map: &'a HashMap<u64, u32>,
    /// [`Bricks::block`].
    block: &'a [u32],
    vals: &'a mut [f32],
}

impl Field<'_> {
    /// The slot of cell `g`, `None` where no brick holds it (its value is `+inf`).
    fn slot(&self, g: [i64; 3]) -> Option<usize> {
        slot_in(self.map, self.block, g)
    }
}

/// Most rounds of [`diagonal_leaks`] and filling: a round's fills close the face paths of a
/// few other diagonals (the bowl scan fills 5509, 29 and 3 cells in three rounds, the vase
/// scan 5026 and 8 in two).
const SEAL_ROUNDS: usize = 8;

/// The absent cells that [`Bricks::build`] fills (with value 0) so that the outside does
/// not pass through a wall that only the tetrahedra's diagonals cross.
///
/// The marcher's tetrahedra join cells along 7 directions and their opposites: the faces and
/// the diagonals `(1, 1, 0)`, `(1, 0, 1)`, `(0, 1, 1)`, `(1, 1, 1)`. Two outside cells at the
/// ends of such a diagonal are joined even when inside cells block every face path between
/// them within their cube — and the closure (whose cut joins cells through faces only) and
/// the walls it puts behind observed surfaces assume they are not. A wall one or two cells
/// thick across such a diagonal (a bowl's flaring side, normal near `±(1, 1, 1)`, is one)
/// then lets the outside through at every such diagonal: pinholes, each a handle of the
/// surface (a simulated bowl had 2530, its true genus is 0), where the cut had closed the
/// wall. Filling one end of every such diagonal makes the outside join through faces only,
/// as the cut does.
///
/// Which end: an absent one (a marked cell keeps its measured distance) that no marked cell
/// outside its surface touches (that side of the wall was observed, and filling it would
/// move the observed surface out): the back of the wall, where no view saw anything. When
/// both ends qualify, the one more enclosed by inside cells. The surface then passes within
/// [`T_MIN`] of the filled cell's centre: the wall grows by the least the tetrahedra allow,
/// one layer of cells along the diagonal (1/√3 cell across a wall normal to `(1, 1, 1)`).
///
/// Looks at the diagonals whose lower end lies in the bricks `look` (indices into `keys`);
/// returns global shifted coordinates, sorted, each once.
fn diagonal_leaks(field: &Field<'_>, keys: &[[u32; 3]], look: &[usize]) -> Vec<[i64; 3]> {
    let mut out = Vec::new();
    par::extend_in_order(&mut out, look.len(), PEEL_BRICKS_PER_TASK, |i, out| {
        leaks_in_brick(field, keys[look[i]], out);
    });
    out.sort_unstable();
    out.dedup();
    out
}

/// Which end of a leaking diagonal [`diagonal_leaks`] fills: one that `back` allows, of
/// two the more enclosed (lower `enclosure`), the upper `q` on a tie.
fn end_to_fill<T: Copy>(
    p: T,
    q: T,
    back: impl Fn(T) -> bool,
    enclosure: impl Fn(T) -> f32,
) -> Option<T> {
    match (back(p), back(q)) {
        (true, true) => Some(if enclosure(p) < enclosure(q) { p } else { q }),
        (true, false) => Some(p),
        (false, true) => Some(q),
        (false, false) => None,
    }
}

/// The 6 face steps.
const FACE_STEPS: [[i64; 3]; 6] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
];

/// [`diagonal_leaks`] for the diagonals whose lower end lies in the brick at key `k`.
fn leaks_in_brick(field: &Field<'_>, k: [u32; 3], out: &mut Vec<[i64; 3]>) {
    // The 27 bricks around this one (blocks or `None`): a value is an array read. A
    // diagonal's cells lie at offsets 0 or 1 from its lower end, the ends' face neighbours
    // one further.
    let mut around = [None; 27];
    for (i, slot) in around.iter_mut().enumerate() {
        let d = [i % 3, (i / 3) % 3, i / 9].map(|c| i64::from(c as u8) - 1);
        let n = [0, 1, 2].map(|a| i64::from(k[a]) + d[a]);
        if n.iter().any(|&c| c < 0) {
            continue;
        }
        *slot = field
            .map
            .get(&brick_key(n.map(|c| c as u32)))
            .map(|&x| field.block[x as usize])
            .filter(|&v| v != NONE)
            .map(|v| v as usize);
    }
    // No cell in this brick or on its plus sides: no diagonal with inside cells starts here.
    if (0..8u8).all(|o| {
        let d = corner_offset(o).map(|c| c as usize + 1);
        around[d[2] * 9 + d[1] * 3 + d[0]].is_none()
    }) {
        return;
    }
    // The value of the cell at local coordinates `q` (each in -8..16).
    let value = |q: [i64; 3]| -> f32 {
        let b = q.map(|c| (c.div_euclid(8) + 1) as usize);
        around[b[2] * 9 + b[1] * 3 + b[0]].map_or(f32::INFINITY, |v| {
            let l = q.map(|c| (c & 7) as u32);
            field.vals[v * 512 + local(l[0], l[1], l[2])]
        })
    };
    // Inside bits of the 9 × 9 × 9 cells from this brick's first: `rows[z][y]`, bit x.
    let mut rows = [[0u16; 9]; 9];
    for (z, plane) in rows.iter_mut().enumerate() {
        for (y, row) in plane.iter_mut().enumerate() {
            for x in 0..9 {
                if value([x, y as i64, z as i64]) <= 0.0 {
                    *row |= 1 << x;
                }
            }
        }
    }
    let base = k.map(|c| i64::from(c) * 8);
    let at = |c: [i64; 3], s: [i64; 3]| [c[0] + s[0], c[1] + s[1], c[2] + s[2]];
    // An end that may be filled: absent, and no marked cell outside its surface beside it
    // (that side was observed, and filling it would move the observed surface out).
    let back = |c: [i64; 3]| {
        value(c) == f32::INFINITY
            && !FACE_STEPS.iter().any(|&s| {
                let f = value(at(c, s));
                f.is_finite() && f > 0.0
            })
    };
    // How enclosed an end is: its face neighbours' values, absent ones as 2, unobserved
    // inside ones as -2 (lower: more enclosed).
    let enclosure = |c: [i64; 3]| -> f32 {
        FACE_STEPS
            .iter()
            .map(|&s| value(at(c, s)).clamp(-2.0, 2.0))
            .sum()
    };
    let mut leak = |p: [i64; 3], d: [i64; 3]| {
        let Some(fill) = end_to_fill(p, at(p, d), back, enclosure) else {
            return;
        };
        let g = at(base, fill);
        // Not before the grid's first cell (no brick there keeps its minus neighbours).
        if g.iter().all(|&c| c >= i64::from(SHIFT)) {
            out.push(g);
        }
    };
    for z in 0..8 {
        for y in 0..8 {
            let r = |dy: usize, dz: usize| u32::from(rows[z + dz][y + dy]);
            // Outside lower ends (bit x: the cell at x).
            let out0 = !r(0, 0) & 0xFF;
            if out0 == 0 {
                continue;
            }
            // Inside bits of the lower end's cube corners, shifted to bit x.
            let (ix, iy, iz) = (r(0, 0) >> 1, r(1, 0), r(0, 1));
            let (ixy, ixz, iyz, ixyz) = (r(1, 0) >> 1, r(0, 1) >> 1, r(1, 1), r(1, 1) >> 1);
            // A face diagonal leaks when both cells beside it are inside and its upper end
            // is outside; the body diagonal when no monotone face path through the cube is
            // outside all along.
            let open = (!ix & (!ixy | !ixz)) | (!iy & (!ixy | !iyz)) | (!iz & (!ixz | !iyz));
            let leaks = [
                (out0 & ix & iy & !ixy, [1, 1, 0]),
                (out0 & ix & iz & !ixz, [1, 0, 1]),
                (out0 & iy & iz & !iyz, [0, 1, 1]),
                (out0 & !ixyz & !open, [1, 1, 1]),
            ];
            for (mask, d) in leaks {
                let mut m = mask & 0xFF;
                while m != 0 {
                    let x = i64::from(m.trailing_zeros());
                    m &= m - 1;
                    leak([x, y as i64, z as i64], d);
                }
            }
        }
    }
}

/// Bricks per parallel task of [`peel_unobserved`]'s search (the result does not depend on
/// it).
const PEEL_BRICKS_PER_TASK: usize = 32;

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
    // Brick by brick (in parallel, the cells found appended in brick order).
    let mut peeled = Vec::new();
    let shared: &Field<'_> = field;
    par::extend_in_order(&mut peeled, keys.len(), PEEL_BRICKS_PER_TASK, |b, out| {
        peel_in_brick(shared, b, keys[b], floor, out);
    });
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
    // Flags by slot: the cells of pieces known to be large, and those of the piece being
    // searched (cleared after each search). Every inside cell has a slot, and no slot
    // changes here.
    let words = field.vals.len().div_ceil(64);
    let (mut big, mut member) = (vec![0u64; words], vec![0u64; words]);
    let test = |bits: &[u64], i: usize| bits[i / 64] >> (i % 64) & 1 == 1;
    let set = |bits: &mut [u64], i: usize| bits[i / 64] |= 1 << (i % 64);
    // The piece's cells and their slots.
    let mut piece: Vec<([i64; 3], usize)> = Vec::new();
    for g in peeled {
        for d in &kuhn {
            let start = [g[0] + d[0], g[1] + d[1], g[2] + d[2]];
            let Some(s) = field.slot(start).filter(|&i| inside(field.vals[i])) else {
                continue;
            };
            if test(&big, s) {
                continue;
            }
            // The inside piece from `start`, searched until it reaches `min_piece` cells or a
            // piece already known to be that large.
            piece.clear();
            piece.push((start, s));
            set(&mut member, s);
            let mut next = 0;
            let mut joined = false;
            'search: while next < piece.len() && piece.len() < min_piece {
                let c = piece[next].0;
                next += 1;
                for d in &kuhn {
                    let n = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
                    let Some(i) = field.slot(n) else {
                        continue;
                    };
                    if test(&big, i) {
                        joined = true;
                        break 'search;
                    }
                    if inside(field.vals[i]) && !test(&member, i) {
                        set(&mut member, i);
                        piece.push((n, i));
                    }
                }
            }
            for &(_, i) in &piece {
                member[i / 64] &= !(1 << (i % 64));
            }
            if joined || piece.len() >= min_piece {
                for &(_, i) in &piece {
                    set(&mut big, i);
                }
                continue;
            }
            for &(_, i) in &piece {
                field.vals[i] = f32::INFINITY;
            }
        }
    }
}

/// The cells of brick `b` (key `k`) that [`peel_unobserved`] turns outside, appended to
/// `peeled` in the brick's order.
fn peel_in_brick(field: &Field<'_>, b: usize, k: [u32; 3], floor: u32, peeled: &mut Vec<[i64; 3]>) {
    let floor = i64::from(floor);
    // A brick without a block of values holds no cell.
    let Some(b) = field.block.get(b).copied().filter(|&v| v != NONE) else {
        return;
    };
    let b = b as usize;
    let vals = &field.vals[b * 512..(b + 1) * 512];
    // Only unobserved inside cells can be peeled.
    if !vals.iter().any(|&f| unobserved_inside(f)) {
        return;
    }
    let base = [0, 1, 2].map(|a| i64::from(k[a] * 8));
    // The bricks across each face, `[axis][0: minus, 1: plus]`.
    let faces: [[Option<usize>; 2]; 3] = std::array::from_fn(|a| {
        [-1i64, 1].map(|d| {
            let mut n = k.map(i64::from);
            n[a] += d;
            let n = n.map(|c| u32::try_from(c).ok());
            let n = [n[0]?, n[1]?, n[2]?];
            field
                .map
                .get(&brick_key(n))
                .map(|&x| field.block[x as usize])
                .filter(|&v| v != NONE)
                .map(|v| v as usize)
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
                base[1] + out[1] >= floor && value(out) == f32::INFINITY && observed(value(back))
            })
        });
        if between {
            peeled.push([base[0] + p[0], base[1] + p[1], base[2] + p[2]]);
        }
    }
}

/// The crossing edges of a brick with vertices: per edge row (`(dir - 1) · 64 + z · 8 + y`),
/// the index of the row's first vertex relative to the brick's first, and the row's mask
/// (bit `x`: the edge from `(x, y, z)` has a vertex).
#[derive(Debug, Clone)]
struct EdgeRows {
    off: [u16; ROWS],
    mask: [u8; ROWS],
}

impl EdgeRows {
    /// The rows of brick `b`, from its padded inside bits.
    fn new(p: &[[u16; 9]; 9]) -> Self {
        let mut e = Self {
            off: [0; ROWS],
            mask: [0; ROWS],
        };
        let mut count = 0u16;
        for d in 1..8u8 {
            let [dx, dy, dz] = corner_offset(d).map(|v| v as usize);
            for z in 0..8 {
                for y in 0..8 {
                    let m = ((p[z][y] ^ (p[z + dz][y + dy] >> dx)) & 0xFF) as u8;
                    let r = (d as usize - 1) * 64 + z * 8 + y;
                    e.off[r] = count;
                    e.mask[r] = m;
                    count += u16::from(POP8[m as usize]);
                }
            }
        }
        e
    }
}

/// Vertices on the crossing edges of a brick with padded inside bits `p` (at most
/// 7 · 512), and triangles of its active cubes.
fn brick_counts(p: &[[u16; 9]; 9], table: &CaseTable) -> (u32, u32) {
    let mut vertices = 0u32;
    for d in 1..8u8 {
        let [dx, dy, dz] = corner_offset(d).map(|v| v as usize);
        for z in 0..8 {
            for y in 0..8 {
                let m = ((p[z][y] ^ (p[z + dz][y + dy] >> dx)) & 0xFF) as u8;
                vertices += u32::from(POP8[m as usize]);
            }
        }
    }
    let mut triangles = 0u32;
    if vertices > 0 {
        for_each_active_cube(p, |_, _, _, case| {
            triangles += u32::from(table.start[case + 1] - table.start[case]);
        });
    }
    (vertices, triangles)
}

/// `f(x, y, z, case)` for every active cube (corners not all alike) of a brick with padded
/// inside bits `p`, in z, y, x order.
#[inline]
fn for_each_active_cube(p: &[[u16; 9]; 9], mut f: impl FnMut(u32, usize, usize, usize)) {
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
                f(x, y, z, case);
            }
        }
    }
}

/// Buffers reused from one meshing to the next.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    /// The cells to march (grid coordinates and value, see [`Inside`]).
    pub entries: Vec<(UVec3, f32)>,
    bricks: Bricks,
    /// Per brick: its vertex and triangle counts, then (prefix sums) its first vertex and
    /// first triangle; one more entry holds the totals.
    first: Vec<(u32, u32)>,
    /// Per brick: its rows in `edges`, or `NONE` (no vertex).
    slot: Vec<u32>,
    /// The edge rows of the bricks with vertices.
    edges: Vec<EdgeRows>,
}

/// Marches `scratch.entries` into `out` (cleared first). With [`Inside::NonPositive`] and
/// `peel = Some(min_piece)`, the unobserved cells in the dents of the observed surface are
/// turned outside first, and the inside pieces of fewer than `min_piece` cells this cuts off
/// dropped (see [`peel_unobserved`]); `None` marches the cells as they are. With
/// [`Inside::NonPositive`], either way, the absent cells that close the tetrahedra's
/// diagonals through thin walls are then filled (see [`diagonal_leaks`]). Without `keep`,
/// each buffer is freed as soon as the passes that read it are done (lower peak memory for
/// a one-shot mesher; `scratch` is then empty).
///
/// Returns the vertices on the backs of walls that no view saw, with the planes of the
/// surfaces seen in front of them (see [`crate::backs`]; only with [`Inside::NonPositive`]
/// and [`Placement::SignedDistance`], else none). `floor` is the field's floor layer (grid
/// coordinates), if it has one: the base of the object, whose edges into the layers below
/// are never backs, and whose plane is the seen surface of a cavity's floor resting on it.
pub(crate) fn march(
    scratch: &mut Scratch,
    grid: &GridSpec,
    (inside, peel): (Inside, Option<usize>),
    placement: Placement,
    floor: Option<u32>,
    out: &mut Mesh,
    keep: bool,
) -> Vec<Back> {
    let Scratch {
        entries,
        bricks,
        first,
        slot,
        edges,
    } = scratch;
    bricks.build(entries, inside, peel);
    if !keep {
        *entries = Vec::new();
    }
    number_vertices(bricks, first, slot, edges);
    let backs = place_vertices(
        bricks,
        first,
        slot,
        edges,
        grid,
        (inside, placement, floor),
        &mut out.vertices,
    );
    if !keep {
        bricks.vals = Vec::new();
        bricks.block = Vec::new();
        bricks.map = HashMap::new();
    }
    emit_triangles(bricks, first, slot, edges, &mut out.triangles);
    if !keep {
        *scratch = Scratch::default();
    }
    backs
}

/// Pass 1: every brick's vertex and triangle counts and, by prefix sums, its first vertex
/// and triangle (`first`, one entry more for the totals); the edge rows of the bricks with
/// vertices (`edges`, indexed by `slot`).
fn number_vertices(
    bricks: &Bricks,
    first: &mut Vec<(u32, u32)>,
    slot: &mut Vec<u32>,
    edges: &mut Vec<EdgeRows>,
) {
    let n = bricks.keys.len();
    let table = &*CASES;
    par::map_into(first, n, |b| brick_counts(&bricks.padded_rows(b), table));
    slot.clear();
    let mut active = Vec::new();
    let mut acc = (0u32, 0u32);
    for (b, c) in first.iter_mut().enumerate() {
        let counts = *c;
        if counts.0 > 0 {
            slot.push(active.len() as u32);
            active.push(b);
        } else {
            slot.push(NONE);
        }
        *c = acc;
        acc.0 += counts.0;
        acc.1 += counts.1;
    }
    first.push(acc);
    par::map_into(edges, active.len(), |i| {
        EdgeRows::new(&bricks.padded_rows(active[i]))
    });
}

/// Pass 2: vertex positions, in index order (each brick fills its own range of
/// `vertices`, which is cleared first), and the backs of unseen walls among them (see
/// [`march`]).
fn place_vertices(
    bricks: &Bricks,
    first: &[(u32, u32)],
    slot: &[u32],
    edges: &[EdgeRows],
    grid: &GridSpec,
    (inside, placement, floor): (Inside, Placement, Option<u32>),
    vertices: &mut Vec<Vec3>,
) -> Vec<Back> {
    let n = bricks.keys.len();
    let count = first[n].0;
    let cell = f64::from(grid.cell);
    // World position of grid point g (shifted coordinates): origin + (g - SHIFT + 0.5) · cell.
    let offset = grid.origin.as_dvec3() + DVec3::splat((0.5 - f64::from(SHIFT)) * cell);
    vertices.clear();
    vertices.resize(count as usize, Vec3::ZERO);
    let backs_wanted = inside == Inside::NonPositive && placement == Placement::SignedDistance;
    let floor = floor.map(|f| i64::from(f + SHIFT));
    let mut backs: Vec<Vec<Back>> = (0..edges.len()).map(|_| Vec::new()).collect();
    let mut ranges = Vec::with_capacity(edges.len());
    let mut rest = &mut vertices[..];
    let mut brick_backs = backs.iter_mut();
    for b in 0..n {
        let (head, tail) = rest.split_at_mut((first[b + 1].0 - first[b].0) as usize);
        if slot[b] != NONE
            && let Some(out) = brick_backs.next()
        {
            ranges.push((b, head, out));
        }
        rest = tail;
    }
    par::for_each_zip(ranges, 0..edges.len(), |_, (b, dst, brick_backs), i| {
        let rows = &edges[i];
        let key = bricks.keys[b];
        let base = [key[0] * 8, key[1] * 8, key[2] * 8];
        let mut next = dst.iter_mut();
        for d in 1..8u8 {
            let dir = corner_offset(d);
            let dirf = DVec3::new(f64::from(dir[0]), f64::from(dir[1]), f64::from(dir[2]));
            let len = ((dir[0] + dir[1] + dir[2]) as f32).sqrt();
            for z in 0..8u32 {
                for y in 0..8u32 {
                    let mut m = rows.mask[(d as usize - 1) * 64 + (z * 8 + y) as usize];
                    while m != 0 {
                        let x = m.trailing_zeros();
                        m &= m - 1;
                        let mut back = None;
                        let t = if placement == Placement::Midpoint {
                            0.5
                        } else {
                            let p = [x, y, z];
                            let q = [x + dir[0] as u32, y + dir[1] as u32, z + dir[2] as u32];
                            let fp = bricks.value(b, p);
                            let fq = bricks.value(b, q);
                            let end =
                                |l: [u32; 3], f| (f, [0, 1, 2].map(|k| i64::from(base[k] + l[k])));
                            // From the inside end, turned back into a fraction from `p`.
                            let from_p = inside.test(fp);
                            let (i, o) = if from_p {
                                (end(p, fp), end(q, fq))
                            } else {
                                (end(q, fq), end(p, fp))
                            };
                            let value = |g| bricks.value_near(b, base, g);
                            // The cell beyond the inside end on the edge's line, where `i` is
                            // marked and `o` absent: read once for both tests of a back.
                            let beyond = (inside == Inside::NonPositive
                                && observed(i.0)
                                && o.0 == f32::INFINITY)
                                .then(|| value([0, 1, 2].map(|k| 2 * i.1[k] - o.1[k])));
                            let t = edge_crossing(placement, i.0, o.0, beyond, len);
                            if backs_wanted && o.0 == f32::INFINITY {
                                back = back_plane(value, inside, floor, (i, o.1), beyond, t);
                            }
                            if from_p { t } else { 1.0 - t }
                        };
                        let t = f64::from(t);
                        let g = DVec3::new(
                            f64::from(base[0] + x) + t * dirf.x,
                            f64::from(base[1] + y) + t * dirf.y,
                            f64::from(base[2] + z) + t * dirf.z,
                        );
                        let pos = offset + g * cell;
                        if let Some((normal, depth)) = back {
                            brick_backs.push(Back {
                                at: pos.as_vec3(),
                                normal: normal.as_vec3(),
                                offset: (normal.dot(pos) - depth * cell) as f32,
                            });
                        }
                        if let Some(v) = next.next() {
                            *v = pos.as_vec3();
                        }
                    }
                }
            }
        }
        debug_assert!(next.next().is_none());
    });
    backs.concat()
}

/// The plane of the seen surface in front of the vertex at fraction `t` of the edge from
/// the inside cell `i` to the absent cell `o` (global coordinates), if the vertex is on the
/// back of a wall no view saw: its unit normal and the vertex's signed distance from it, in
/// cells. The plane fitted to the marked cells around `i` ([`backs::observed_plane`]);
/// where none was seen near, and the edge rises from the floor layer into space above the
/// object's base (the floor-layer cell under `o` is inside: a cavity's floor), the base's
/// plane half a cell below the floor layer's centres, where the vertices into the layer
/// below are put. Edges into the layers below the floor are the base itself: `None`.
///
/// Most such edges are fronts, the surface seen from `o`'s side, and are told apart before
/// the fit (27 cells) by one more: `i` is marked and the cell beyond it on the same line is
/// inside and no nearer the surface (an inside cell no triangle marked, or a marked one at
/// most as far in front), so the surface lies between `i` and `o`.
///
/// `value`: the cells' values by global coordinates; `i`: the inside end's value and
/// coordinates; `beyond`: the value of the cell beyond it on the edge's line where `i` is
/// marked, as [`edge_crossing`] takes it.
fn back_plane(
    value: impl Fn([i64; 3]) -> f32 + Copy,
    inside: Inside,
    floor: Option<i64>,
    ((fi, i), o): ((f32, [i64; 3]), [i64; 3]),
    beyond: Option<f32>,
    t: f32,
) -> Option<(DVec3, f64)> {
    if floor.is_some_and(|f| o[1] < f) {
        return None;
    }
    if let Some(fr) = beyond
        && (fr == f32::NEG_INFINITY || (observed(fr) && fr <= fi))
    {
        return None;
    }
    backs::observed_plane(value, observed, i, o, t).or_else(|| {
        let f = floor?;
        let over_base = i[1] == f && o[1] > f && inside.test(value([o[0], f, o[2]]));
        let height = 0.5 + f64::from(t) * (o[1] - i[1]) as f64;
        over_base.then_some((DVec3::NEG_Y, -height))
    })
}

/// How far behind an observed surface the back of a wall that no view saw is put, in cells
/// (see [`edge_crossing`]).
const UNSEEN_BACK_CELLS: f32 = 0.5;

/// How much nearer the observed surface the cell beyond an edge's inside end must be for the
/// edge to cross the back of a wall, in cells (see [`edge_crossing`]).
const BACK_STEP_CELLS: f32 = 0.5;

/// Where the surface crosses the edge from the inside cell `i` to the outside cell `o`
/// (values `fi`, `fo`), as a fraction from `i`: [`crossing`], except across the
/// back of an observed wall. There `i` is marked (its value is its distance behind the
/// observed surface), `o` is absent (no reading came near it) and the cell `r` beyond `i`
/// on the same line is marked and at least half a cell nearer that surface (or outside
/// it): the surface `i` measured lies on `r`'s side, and nothing was observed on `o`'s. (A
/// step along the edge changes the distance by up to its length when the surface lies
/// across it; a cell deep in a noisy shell, marked by a few stray readings, can read
/// slightly nearer than `i`, and must not turn a seen face into a back.) [`crossing`] would mirror
/// the measured distance onto `o`'s side, a wall up to a cell and a half thick that no
/// view saw (the inside of a bowl or a vase whose outer wall alone was seen). The back is put
/// [`UNSEEN_BACK_CELLS`] behind the observed surface instead (at `i`'s centre when that is
/// farther): a wall of half a cell where the grid allows it, as close to the seen surface as
/// the closure's prior (unseen surface next to seen surface) asks. Where it does not,
/// [`crate::backs`] moves the finished mesh's vertex there ([`back_plane`] records how).
/// `beyond`: the value of `r`, the cell beyond `i`, given exactly where the test applies
/// (solid signed-distance mode, `i` marked, `o` absent).
fn edge_crossing(placement: Placement, fi: f32, fo: f32, beyond: Option<f32>, len: f32) -> f32 {
    if let Some(fr) = beyond
        && observed(fr)
        && fr > fi + BACK_STEP_CELLS
    {
        return ((UNSEEN_BACK_CELLS + fi) / len).clamp(T_MIN, 1.0 - T_MIN);
    }
    crossing(placement, fi, fo, len)
}

/// Pass 3: triangles, each brick into its own range of `triangles` (cleared first), in
/// brick order.
fn emit_triangles(
    bricks: &Bricks,
    first: &[(u32, u32)],
    slot: &[u32],
    edges: &[EdgeRows],
    triangles: &mut Vec<[u32; 3]>,
) {
    let n = bricks.keys.len();
    let table = &*CASES;
    triangles.clear();
    triangles.resize(first[n].1 as usize, [0; 3]);
    let mut ranges = Vec::with_capacity(edges.len());
    let mut rest = &mut triangles[..];
    for b in 0..n {
        let (head, tail) = rest.split_at_mut((first[b + 1].1 - first[b].1) as usize);
        if !head.is_empty() {
            ranges.push((b, head));
        }
        rest = tail;
    }
    let count = ranges.len();
    par::for_each_zip(ranges, 0..count, |_, (b, dst), _| {
        let p = bricks.padded_rows(b);
        // The eight bricks this brick's cubes reach into.
        let nb = bricks.nb[b];
        let mut next = dst.iter_mut();
        for_each_active_cube(&p, |x, y, z, case| {
            let cube_edges =
                &table.edges[table.edge_start[case] as usize..table.edge_start[case + 1] as usize];
            let mut ids = [0u32; 19];
            for (id, e) in ids.iter_mut().zip(cube_edges) {
                let (px, py, pz) = (x + e.ox, y as u32 + e.oy, z as u32 + e.oz);
                let o = (px >> 3) | ((py >> 3) << 1) | ((pz >> 3) << 2);
                let nbo = nb[o as usize] as usize;
                let rows = &edges[slot[nbo] as usize];
                let r = e.row + ((pz & 7) * 8 + (py & 7)) as usize;
                let m = u32::from(rows.mask[r]);
                debug_assert!(m >> (px & 7) & 1 == 1, "edge without a vertex");
                *id = first[nbo].0
                    + u32::from(rows.off[r])
                    + u32::from(POP8[(m & ((1u32 << (px & 7)) - 1)) as usize]);
            }
            let local = &table.local[table.start[case] as usize..table.start[case + 1] as usize];
            for l in local {
                if let Some(t) = next.next() {
                    *t = [ids[l[0] as usize], ids[l[1] as usize], ids[l[2] as usize]];
                }
            }
        });
        debug_assert!(next.next().is_none());
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tables::{TETS, tet_triangles};
    use proptest::prelude::*;
    use voxoct_core::glam::IVec3;

    /// A triangle as its three corner positions, turned so that the smallest comes first
    /// (orientation kept).
    fn canonical(t: [Vec3; 3]) -> [[u32; 3]; 3] {
        let k = t.map(|p| p.to_array().map(f32::to_bits));
        let i = (0..3).min_by_key(|&i| k[i]).unwrap_or(0);
        [k[i], k[(i + 1) % 3], k[(i + 2) % 3]]
    }

    /// Marching without bricks: every cube with a cell at a corner, split into its six
    /// tetrahedra, one vertex per grid edge (keyed by its lower end and direction), placed
    /// as the marcher places it. Returns the triangles (canonical, sorted) and the number of
    /// distinct vertices.
    fn reference(
        cells: &HashMap<[i32; 3], f32>,
        grid: &GridSpec,
        inside: Inside,
        placement: Placement,
    ) -> (Vec<[[u32; 3]; 3]>, usize) {
        let mut sealed;
        let cells = if inside == Inside::NonPositive {
            sealed = cells.clone();
            reference_seal(&mut sealed);
            &sealed
        } else {
            cells
        };
        let value = |p: IVec3| cells.get(&p.to_array()).copied().unwrap_or(f32::INFINITY);
        let mut cubes: Vec<IVec3> = Vec::new();
        for c in cells.keys() {
            for o in 0..8u8 {
                cubes.push(IVec3::from_array(*c) - IVec3::from_array(corner_offset(o)));
            }
        }
        cubes.sort_by_key(|c| c.to_array());
        cubes.dedup();
        let cell = f64::from(grid.cell);
        let offset = grid.origin.as_dvec3() + DVec3::splat((0.5 - f64::from(SHIFT)) * cell);
        let mut keys = HashMap::new();
        let mut out = Vec::new();
        let mut tris = Vec::new();
        for m in cubes {
            let mut case = 0u8;
            for i in 0..8u8 {
                if inside.test(value(m + IVec3::from_array(corner_offset(i)))) {
                    case |= 1 << i;
                }
            }
            for t in TETS {
                tris.clear();
                tet_triangles(t, case, &mut tris);
                for tri in &tris {
                    let pos = tri.map(|(corner, dir)| {
                        let p = m + IVec3::from_array(corner_offset(corner));
                        let d = corner_offset(dir);
                        keys.insert((p.to_array(), dir), ());
                        let q = p + IVec3::from_array(d);
                        let len = ((d[0] + d[1] + d[2]) as f32).sqrt();
                        let (fp, fq) = (value(p), value(q));
                        // From the inside end `i` to the outside end `o`; the back of an
                        // observed wall (the cell beyond `i` nearer its surface, `o` absent)
                        // half a cell behind the surface.
                        let from_inside = |i: IVec3, fi: f32, o: IVec3, fo: f32| {
                            let fr = value(i + i - o);
                            let back = inside == Inside::NonPositive
                                && observed(fi)
                                && fo == f32::INFINITY
                                && observed(fr)
                                && fr > fi + BACK_STEP_CELLS;
                            if back {
                                ((UNSEEN_BACK_CELLS + fi) / len).clamp(T_MIN, 1.0 - T_MIN)
                            } else {
                                crossing(placement, fi, fo, len)
                            }
                        };
                        let t = f64::from(if inside.test(fp) {
                            from_inside(p, fp, q, fq)
                        } else {
                            1.0 - from_inside(q, fq, p, fp)
                        });
                        let s = p + IVec3::splat(SHIFT as i32);
                        let g = DVec3::new(
                            f64::from(s.x) + t * f64::from(d[0]),
                            f64::from(s.y) + t * f64::from(d[1]),
                            f64::from(s.z) + t * f64::from(d[2]),
                        );
                        (offset + g * cell).as_vec3()
                    });
                    out.push(canonical(pos));
                }
            }
        }
        out.sort_unstable();
        (out, keys.len())
    }

    /// [`diagonal_leaks`]'s fills, round by round, cell by cell over every cell: every
    /// diagonal between two outside cells that inside cells block on every face path through
    /// its cube gets the end that may be filled (absent, no marked cell outside its surface
    /// beside it; [`end_to_fill`] chooses) filled with 0.
    fn reference_seal(cells: &mut HashMap<[i32; 3], f32>) {
        let value =
            |c: &HashMap<[i32; 3], f32>, p: [i32; 3]| c.get(&p).copied().unwrap_or(f32::INFINITY);
        let add = |a: [i32; 3], b: [i32; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
        let faces = FACE_STEPS.map(|s| s.map(|c| c as i32));
        for _ in 0..SEAL_ROUNDS {
            let c = &*cells;
            let ins = |p: [i32; 3]| value(c, p) <= 0.0;
            // Absent, and no marked cell outside its surface beside it.
            let back = |p: [i32; 3]| {
                value(c, p) == f32::INFINITY
                    && !faces.iter().any(|&s| {
                        let f = value(c, add(p, s));
                        f.is_finite() && f > 0.0
                    })
            };
            let enclosure = |p: [i32; 3]| -> f32 {
                faces
                    .iter()
                    .map(|&s| value(c, add(p, s)).clamp(-2.0, 2.0))
                    .sum()
            };
            let mut ends: Vec<[i32; 3]> = c
                .keys()
                .flat_map(|&k| {
                    (0..8u8).map(move |o| {
                        let d = corner_offset(o);
                        [k[0] - d[0], k[1] - d[1], k[2] - d[2]]
                    })
                })
                .collect();
            ends.sort_unstable();
            ends.dedup();
            let (x, y, z) = ([1, 0, 0], [0, 1, 0], [0, 0, 1]);
            let mut fills = Vec::new();
            for p in ends {
                if ins(p) {
                    continue;
                }
                let mut leaks = Vec::new();
                for (a, b) in [(x, y), (x, z), (y, z)] {
                    if ins(add(p, a)) && ins(add(p, b)) && !ins(add(add(p, a), b)) {
                        leaks.push(add(add(p, a), b));
                    }
                }
                let q = add(add(p, x), add(y, z));
                let open = [(x, y), (x, z), (y, x), (y, z), (z, x), (z, y)]
                    .iter()
                    .any(|&(a, b)| !ins(add(p, a)) && !ins(add(add(p, a), b)));
                if !ins(q) && !open {
                    leaks.push(q);
                }
                for q in leaks {
                    if let Some(fill) = end_to_fill(p, q, back, enclosure)
                        && fill.iter().all(|&c| c >= 0)
                    {
                        fills.push(fill);
                    }
                }
            }
            if fills.is_empty() {
                break;
            }
            for f in fills {
                cells.insert(f, 0.0);
            }
        }
    }

    /// A wall seen from one side (−x): a layer of cells in front of its surface and one
    /// behind it, nothing beyond. The front crossing interpolates the two; the back, which
    /// no reading reached, is half a cell behind the surface (the mirror of the measured
    /// distance would put it 0.2 behind); without the front layer the side is unknown and
    /// the distance is mirrored as before.
    #[test]
    fn the_unseen_back_of_a_wall_is_half_a_cell_behind_its_surface() {
        let grid = GridSpec {
            origin: Vec3::ZERO,
            cell: 1.0,
            resolution: 64,
        };
        let xs_on_axis_edges = |front: bool| {
            let mut cells = Vec::new();
            for z in 4..12u32 {
                for y in 4..12u32 {
                    if front {
                        cells.push((UVec3::new(5, y, z), 0.4));
                    }
                    cells.push((UVec3::new(6, y, z), -0.2));
                }
            }
            let mut scratch = Scratch {
                entries: cells,
                ..Scratch::default()
            };
            let mesh = marched(&mut scratch, &grid, Inside::NonPositive, false);
            // Vertices on x edges through the middle of the wall (cell centres at +0.5).
            let mut xs: Vec<f32> = mesh
                .vertices
                .iter()
                .filter(|v| v.y == 8.5 && v.z == 8.5)
                .map(|v| v.x - 0.5)
                .collect();
            xs.sort_by(f32::total_cmp);
            xs
        };
        let close = |a: &[f32], b: &[f32]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5)
        };
        let seen_front = xs_on_axis_edges(true);
        assert!(
            close(&seen_front, &[5.0 + 0.4 / 0.6, 6.3]),
            "{seen_front:?}"
        );
        let no_front = xs_on_axis_edges(false);
        assert!(close(&no_front, &[5.8, 6.2]), "{no_front:?}");
    }

    /// A wall two cells thick across the tetrahedra's long diagonal (cells with
    /// `x + y + z` = 36 or 37 inside, the layer in front of it marked outside, each with its
    /// distance to the plane it saw, nothing behind it: a bowl's flaring side seen from
    /// outside). Every cube with a corner on each
    /// side lets the outside through along its diagonal unless one end is filled: the
    /// marched surface then has a handle per such cube (genus 75 here). Sealed, it is one closed sheet of
    /// genus 0, and the front (observed) side is where it was.
    #[test]
    fn a_wall_across_the_long_diagonal_has_no_pinholes() {
        let grid = GridSpec {
            origin: Vec3::ZERO,
            cell: 1.0,
            resolution: 64,
        };
        let mut cells = Vec::new();
        for z in 8..20u32 {
            for y in 8..20u32 {
                for x in 8..20u32 {
                    // The distance in cells to the plane x + y + z = 35.7, positive in
                    // front of it.
                    let v = match x + y + z {
                        s @ 35..=37 => (35.7 - s as f32) / 3f32.sqrt(),
                        _ => continue,
                    };
                    cells.push((UVec3::new(x, y, z), v));
                }
            }
        }
        let mut scratch = Scratch {
            entries: cells.clone(),
            ..Scratch::default()
        };
        let mesh = marched(&mut scratch, &grid, Inside::NonPositive, false);
        let stats = mesh.stats();
        assert_eq!((stats.components, stats.genus()), (1, Some(0)), "{stats:?}");
        // Without the seal (the plain tetrahedra), the same wall is full of holes.
        let mut map: HashMap<[i32; 3], f32> = cells
            .iter()
            .map(|(c, v)| (c.as_ivec3().to_array(), *v))
            .collect();
        let before = map.len();
        reference_seal(&mut map);
        let filled: Vec<_> = map
            .iter()
            .filter(|(_, v)| **v == 0.0)
            .map(|(k, _)| *k)
            .collect();
        assert!(filled.len() > 50, "{} of {before}", filled.len());
        // Every filled cell is behind the wall (x + y + z = 38), none on its observed side.
        assert!(
            filled.iter().all(|k| k[0] + k[1] + k[2] == 38),
            "{filled:?}"
        );
    }

    fn marched(scratch: &mut Scratch, grid: &GridSpec, inside: Inside, keep: bool) -> Mesh {
        let mut mesh = Mesh::default();
        march(
            scratch,
            grid,
            (inside, None),
            Placement::SignedDistance,
            None,
            &mut mesh,
            keep,
        );
        mesh
    }

    fn cells_strategy() -> impl Strategy<Value = HashMap<[i32; 3], f32>> {
        // Across several bricks (8 cells, shifted by 8) along every axis; values finite,
        // enclosed (-inf) or outside (+inf, as if absent).
        let value = prop_oneof![
            6 => -1.5f32..1.5,
            1 => Just(f32::NEG_INFINITY),
            1 => Just(f32::INFINITY),
        ];
        prop::collection::hash_map(prop::array::uniform3(0i32..21), value, 1..250)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// The bricked marcher gives exactly the triangles of the brick-free reference, with
        /// one vertex per crossing edge; a reused scratch (after another input) gives the
        /// same mesh as a fresh one, and frees nothing it should keep.
        #[test]
        fn bricks_match_the_reference_and_scratch_reuse_changes_nothing(
            cells in cells_strategy(),
            other in cells_strategy(),
            rule in 0usize..3,
        ) {
            let inside = [Inside::Marked, Inside::NotExterior, Inside::NonPositive][rule];
            let grid = GridSpec { origin: Vec3::new(-0.3, 0.1, 2.0), cell: 0.001, resolution: 64 };
            let entries = |c: &HashMap<[i32; 3], f32>| -> Vec<(UVec3, f32)> {
                c.iter().map(|(p, &v)| (IVec3::from_array(*p).as_uvec3(), v)).collect()
            };
            let mut fresh = Scratch { entries: entries(&cells), ..Scratch::default() };
            let mesh = marched(&mut fresh, &grid, inside, false);
            prop_assert!(fresh.entries.capacity() == 0 && fresh.edges.capacity() == 0);
            let (want, vertices) = reference(&cells, &grid, inside, Placement::SignedDistance);
            prop_assert_eq!(mesh.vertices.len(), vertices);
            let mut got: Vec<_> = mesh
                .triangles
                .iter()
                .map(|t| canonical(t.map(|k| mesh.vertices[k as usize])))
                .collect();
            got.sort_unstable();
            prop_assert_eq!(got, want);

            let mut reused = Scratch { entries: entries(&other), ..Scratch::default() };
            let _ = marched(&mut reused, &grid, inside, true);
            reused.entries = entries(&cells);
            let again = marched(&mut reused, &grid, inside, true);
            prop_assert_eq!(&again.vertices, &mesh.vertices);
            prop_assert_eq!(&again.triangles, &mesh.triangles);
        }
    }
}
