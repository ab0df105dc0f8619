//! Continuing a wall's measured thickness behind the part of it that the views saw from one
//! side only.
//!
//! The cut of [`super::close_cells`] puts unseen surface next to seen surface. Behind a wall
//! seen from one side (the outer wall of a bowl below the part of its inside that the views
//! reached) that is the wall's own back: a wall about a cell thin, whatever the object's
//! wall is. Where the views saw the same wall from both sides, they measured its thickness;
//! [`continue_walls`] carries that thickness on behind the one-sided part, so that the
//! unseen inner surface continues the seen one instead of stepping back to the outer wall.
//! (This is the volumetric hole filling of J. Davis, S. Marschner, M. Garr, M. Levoy,
//! "Filling Holes in Complex Surfaces Using Volumetric Diffusion", 3DPVT 2002, in its
//! simplest form: the distance field of the observed wall extended by its observed
//! thickness, along the wall's normal.)
//!
//! Everything is decided on the cells of the closure's box, after the cut:
//! - **One-sided wall**: a run of inside cells along a grid axis, all marked, between a cell
//!   seen empty (or outside a marked cell's surface) and an unknown cell the cut left
//!   outside, whose signed distance falls by at least half a cell from the seen end to the
//!   unknown one (the run goes through the surface, not along it). The seen end is the
//!   wall's *front*.
//! - **Measured thickness**: an unmarked inside cell whose runs along all three axes have
//!   seen cells at both ends lies inside a wall seen from both sides; a slab of thickness
//!   `t` and unit normal `n` has runs `t / |n_k|` long, so `t = (Σ 1 / L_k²)^(-1/2)` (exact
//!   for a plane slab). A thickness below twice the carving margin (the sensor's uncertainty
//!   of a surface's position) less half a cell diagonal is not resolved from one noisy
//!   surface and is not taken ([`resolved_thickness`]). Each patch of one-sided wall cells takes the median of
//!   the measurements within a few resolved thicknesses of it, through inside cells: the
//!   wall next to it where both sides were seen.
//! - A front is continued only where the space behind its wall cell, along the wall's
//!   inward normal (minus the gradient of the marked cells' signed distances), is unknown
//!   for more than the thickness: a narrower unseen gap is the cut's to close, not a wall's
//!   inside. And only in patches of such wall cells at least as many cells as the thickness
//!   squared: a patch narrower than the wall is thick is not a sheet to continue.
//! - **The continued wall**: the unknown cells the cut left outside whose centre lies within
//!   the thickness (plus the half cell from the front cell's centre to the surface, on a
//!   3-4-5 chamfer through inside and unknown cells) of a front, within 45° of its wall's
//!   inward normal, and not next to a cell seen empty: what the views saw empty stays
//!   empty, with a cell of clearance. Each such cell is solid, with the signed distance of
//!   the continued inner surface (how much of the thickness is left at it), so that the
//!   mesher places that surface between cells rather than on their faces.

use std::collections::HashMap;

use super::Known;
use crate::par;

/// Cosine of the widest angle between a wall's inward normal and the direction from its
/// cell to a cell it makes solid (45°: the normal comes from differences of noisy signed
/// distances).
const NORMAL_CONE_COS: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Half a cell's diagonal, in cells.
const HALF_DIAGONAL: f32 = voxoct_core::HALF_CELL_DIAGONAL;

/// The least wall thickness, in cells, that counts as measured when a surface's position is
/// uncertain by `margin` cells (the carving margin: two standard deviations of the sensor's
/// depth noise plus half a cell's diagonal): the noise spreads one surface's readings over
/// ±2σ, so a wall thinner than that band plus the half diagonal cannot be told from one
/// noisy surface (unmarked cells open up inside such a band: on the vase's body at 0.5 mm,
/// seen from outside only, they measured 4–5 cells where the carving margin is 4).
#[must_use]
pub(super) fn resolved_thickness(margin: f32) -> f32 {
    2.0 * margin - HALF_DIAGONAL
}

/// Largest budget of a front's growth, thirds of a cell (a thickness of 84 cells).
const MAX_BUDGET: u8 = 254;

/// Steps of the closure's 3-4-5 chamfer ([`super::CHAMFER_FACE`] for a face step, thirds
/// of a cell) by how many coordinates change.
const CHAMFER: [usize; 4] = [
    0,
    super::CHAMFER_FACE as usize,
    super::CHAMFER_FACE as usize + 1,
    super::CHAMFER_FACE as usize + 2,
];

/// What lies at one end of a run of inside cells.
#[derive(Clone, Copy, PartialEq, Eq)]
enum End {
    /// Seen empty, outside a marked cell's surface, or beyond a side of the box.
    Seen,
    /// Unknown, and outside by the cut.
    Unknown,
    /// The platform or an excluded cell.
    Other,
}

/// The cells of a box, `dims` in x-fastest order.
#[derive(Clone, Copy)]
pub(super) struct BoxGrid {
    pub(super) dims: [usize; 3],
    pub(super) strides: [usize; 3],
}

impl BoxGrid {
    pub(super) fn new(dims: [usize; 3]) -> Self {
        Self {
            dims,
            strides: [1, dims[0], dims[0] * dims[1]],
        }
    }

    pub(super) fn coord(&self, i: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [i % nx, (i / nx) % ny, i / (nx * ny)]
    }

    /// The cell at `c + d`, if in the box.
    pub(super) fn offset(&self, c: [usize; 3], d: [i64; 3]) -> Option<usize> {
        let mut i = 0;
        for a in 0..3 {
            let q = c[a] as i64 + d[a];
            if q < 0 || q >= self.dims[a] as i64 {
                return None;
            }
            i += q as usize * self.strides[a];
        }
        Some(i)
    }

    /// The (up to six) cells that share a face with the cell at `c`.
    pub(super) fn face_neighbours(&self, c: [usize; 3]) -> impl Iterator<Item = usize> + '_ {
        (0..6).filter_map(move |k| {
            let mut d = [0i64; 3];
            d[k / 2] = if k % 2 == 0 { -1 } else { 1 };
            self.offset(c, d)
        })
    }

    /// Every line of cells along `axis`: its first cell.
    fn lines(&self, axis: usize) -> impl Iterator<Item = usize> + '_ {
        let (a1, a2) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        (0..self.dims[a2]).flat_map(move |c2| {
            (0..self.dims[a1]).map(move |c1| c1 * self.strides[a1] + c2 * self.strides[a2])
        })
    }

    /// The runs of consecutive cells for which `inside` holds on the line from `start` along
    /// `axis`: `(first, past the last)` positions on the line.
    fn runs<'a>(
        &self,
        start: usize,
        axis: usize,
        inside: &'a [bool],
    ) -> impl Iterator<Item = (usize, usize)> + 'a {
        let (len, stride) = (self.dims[axis], self.strides[axis]);
        let mut k = 0;
        std::iter::from_fn(move || {
            while k < len && !inside[start + k * stride] {
                k += 1;
            }
            if k == len {
                return None;
            }
            let k0 = k;
            while k < len && inside[start + k * stride] {
                k += 1;
            }
            Some((k0, k))
        })
    }
}

/// The views' verdicts and the cut's result that [`continue_walls`] reads.
pub(super) struct Box3<'a> {
    /// Cells of the box, x fastest.
    pub dims: [usize; 3],
    /// The cut's inside cells (changed by [`continue_walls`]).
    pub inside: &'a mut [bool],
    /// What the views and the marked cells said of each cell.
    pub known: &'a [Known],
    /// Cells marked by triangles.
    pub marked: &'a [bool],
    /// The least thickness that counts as measured, in cells ([`resolved_thickness`]).
    pub resolved: f32,
}

/// The marked cells' mean signed distances in cells, by box index (increasing).
struct Values(Vec<(u32, f32)>);

impl Values {
    fn get(&self, i: usize) -> Option<f32> {
        let i = u32::try_from(i).ok()?;
        self.0
            .binary_search_by_key(&i, |v| v.0)
            .ok()
            .map(|k| self.0[k].1)
    }
}

impl Box3<'_> {
    fn end(&self, i: Option<usize>, platform: bool) -> End {
        match i {
            None if platform => End::Other,
            None => End::Seen,
            Some(i) => match self.known[i] {
                Known::Empty if !self.inside[i] => End::Seen,
                Known::Unknown if !self.inside[i] => End::Unknown,
                _ => End::Other,
            },
        }
    }

    /// The wall's inward unit normal at the marked cell `w`: minus the gradient of the
    /// marked cells' signed distances (zero when no neighbour is marked).
    fn inward(&self, g: &BoxGrid, v: &Values, w: usize) -> [f32; 3] {
        let c = g.coord(w);
        let here = v.get(w).unwrap_or(0.0);
        let mut grad = [0f32; 3];
        for (a, slot) in grad.iter_mut().enumerate() {
            let mut d = [0i64; 3];
            d[a] = -1;
            let lo = g.offset(c, d).and_then(|j| v.get(j));
            d[a] = 1;
            let hi = g.offset(c, d).and_then(|j| v.get(j));
            *slot = match (lo, hi) {
                (Some(l), Some(h)) => (h - l) / 2.0,
                (Some(l), None) => here - l,
                (None, Some(h)) => h - here,
                (None, None) => 0.0,
            };
        }
        let len = grad.iter().map(|x| x * x).sum::<f32>().sqrt();
        if len > 0.0 {
            grad.map(|x| -x / len)
        } else {
            [0.0; 3]
        }
    }

    /// Whether the space behind wall cell `w` along `normal` is unknown and outside for more
    /// than `t` cells once past the wall (at most two cells of the wall itself).
    fn deep_behind(&self, g: &BoxGrid, w: usize, normal: [f32; 3], t: f32) -> bool {
        if normal == [0.0; 3] {
            return false;
        }
        let c = g.coord(w);
        let mut left_wall = false;
        for k in 1.. {
            let s = k as f32 * 0.5;
            if s > t + 2.0 {
                break;
            }
            let d = [0, 1, 2].map(|a| (c[a] as f32 + normal[a] * s).round() as i64 - c[a] as i64);
            let Some(j) = g.offset(c, d) else {
                return false;
            };
            if self.inside[j] {
                if left_wall || s > 2.0 {
                    return false;
                }
            } else if self.known[j] == Known::Unknown {
                left_wall = true;
            } else {
                return false;
            }
        }
        left_wall
    }
}

/// Lines of cells per parallel task of the scans along an axis.
const LINES_PER_TASK: usize = 256;

/// The candidate fronts of one-sided walls, line by line along each axis: `(front cell,
/// the run's cell next to it, the run's cell next to the unknown end)` for every run of
/// marked inside cells between a seen cell and an unknown one.
fn candidates(b: &Box3<'_>, g: &BoxGrid) -> Vec<[usize; 3]> {
    let mut out = Vec::new();
    for axis in 0..3 {
        let stride = g.strides[axis];
        let len = g.dims[axis];
        let lines: Vec<usize> = g.lines(axis).collect();
        par::extend_in_order(&mut out, lines.len(), LINES_PER_TASK, |l, out| {
            let start = lines[l];
            for (k0, k1) in g.runs(start, axis, b.inside) {
                let at = |k: usize| start + k * stride;
                let before = b.end((k0 > 0).then(|| at(k0 - 1)), axis == 1);
                let after = b.end((k1 < len).then(|| at(k1)), false);
                let run = match (before, after) {
                    (End::Seen, End::Unknown) if k0 > 0 => [at(k0 - 1), at(k0), at(k1 - 1)],
                    (End::Unknown, End::Seen) if k1 < len => [at(k1), at(k1 - 1), at(k0)],
                    _ => continue,
                };
                if (k0..k1).all(|k| b.marked[at(k)]) {
                    out.push(run);
                }
            }
        });
    }
    out
}

/// The fronts of one-sided walls among the candidates: `(front cell, wall cell next to
/// it)` where the run goes through the surface, its signed distance falling by at least
/// half a cell from the seen end to the unknown one (a front cell seen empty, not marked,
/// counts as a cell in front of the run's first).
fn fronts(candidates: &[[usize; 3]], v: &Values) -> Vec<(usize, usize)> {
    candidates
        .iter()
        .filter_map(|&[front, first, last]| {
            let (v_first, v_last) = (v.get(first)?, v.get(last)?);
            let v_front = v.get(front).unwrap_or(v_first + 1.0);
            (v_front - v_last >= 0.5).then_some((front, first))
        })
        .collect()
}

/// Steps, in multiples of the least resolved thickness, that [`thickness`] searches from a
/// patch of one-sided wall for the measurements of its wall.
const SEARCH_THICKNESSES: f32 = 4.0;

/// The wall's thickness at the unmarked inside cell `i`, in cells, if the views saw it from
/// both sides: its runs of inside cells along all three axes end in seen cells at both ends
/// (`(Σ 1/L²)^(-1/2)`, exact for a flat slab), and it is at least the resolved thickness.
fn measured_at(b: &Box3<'_>, g: &BoxGrid, i: usize) -> Option<f32> {
    if b.marked[i] || !b.inside[i] {
        return None;
    }
    let c = g.coord(i);
    let mut inv2 = 0.0f32;
    for (a, (&ca, (&stride, &len))) in c.iter().zip(g.strides.iter().zip(&g.dims)).enumerate() {
        let mut lo = ca;
        while lo > 0 && b.inside[i - (ca - lo + 1) * stride] {
            lo -= 1;
        }
        let mut hi = ca;
        while hi + 1 < len && b.inside[i + (hi + 1 - ca) * stride] {
            hi += 1;
        }
        let before = b.end((lo > 0).then(|| i - (ca - lo + 1) * stride), a == 1);
        let after = b.end((hi + 1 < len).then(|| i + (hi + 1 - ca) * stride), false);
        if before != End::Seen || after != End::Seen {
            return None;
        }
        let l = (hi - lo + 1) as f32;
        inv2 += 1.0 / (l * l);
    }
    let t = 1.0 / inv2.sqrt();
    (t >= b.resolved).then_some(t)
}

/// The thickness measured for each cell of `wanted` (increasing), in cells (0: none): for
/// each of its `patches` ([`patches`]), the median, each wall's area counting once, of the
/// thicknesses measured ([`measured_at`]) at the inside cells within
/// [`SEARCH_THICKNESSES`] resolved thicknesses of the patch (26-connected steps through
/// inside cells): the wall next to it where the views saw both its sides.
///
/// A median over a band rather than the nearest measurement: next to where the views stop
/// seeing the wall's other side, the runs are cut short by the edge of what they saw, and
/// the nearest measurements are the worst ones (at 0.5 mm the bowl's lower wall took 6.7
/// cells from them where its wall is 12). A band rather than the whole piece of inside
/// cells: the wall next to the patch is what it continues, and a large solid's whole
/// inside is too much to search (a dragon at 0.5 mm: over half a second).
fn thickness(b: &Box3<'_>, g: &BoxGrid, wanted: &[usize], patches: &[Vec<usize>]) -> Vec<f32> {
    let n = b.inside.len();
    let depth = (SEARCH_THICKNESSES * b.resolved).ceil() as usize;
    let mut out = vec![0f32; wanted.len()];
    let mut seen = vec![0u64; n.div_ceil(64)];
    let mut touched: Vec<usize> = Vec::new();
    let mut frontier: Vec<usize> = Vec::new();
    let mut next: Vec<usize> = Vec::new();
    for members in patches {
        // The measurements within `depth` steps of it.
        frontier.clear();
        for &k in members {
            let i = wanted[k];
            seen[i / 64] |= 1 << (i % 64);
            touched.push(i);
            frontier.push(i);
        }
        let mut samples: Vec<(f32, f32)> = Vec::new();
        for step in 0..=depth {
            next.clear();
            for &i in &frontier {
                if let Some(t) = measured_at(b, g, i) {
                    samples.push((t, 1.0 / t));
                }
                if step == depth {
                    continue;
                }
                let c = g.coord(i);
                for d in neighbours26() {
                    if let Some(j) = g.offset(c, d)
                        && b.inside[j]
                        && seen[j / 64] & (1 << (j % 64)) == 0
                    {
                        seen[j / 64] |= 1 << (j % 64);
                        touched.push(j);
                        next.push(j);
                    }
                }
            }
            std::mem::swap(&mut frontier, &mut next);
        }
        for &i in &touched {
            seen[i / 64] &= !(1 << (i % 64));
        }
        touched.clear();
        if samples.is_empty() {
            continue;
        }
        samples.sort_by(|x, y| x.0.total_cmp(&y.0));
        let half = samples.iter().map(|s| s.1).sum::<f32>() / 2.0;
        let mut sum = 0.0;
        let t = samples
            .iter()
            .find(|s| {
                sum += s.1;
                sum >= half
            })
            .map_or(0.0, |s| s.0);
        for &k in members {
            out[k] = t;
        }
    }
    out
}

/// Makes solid the unknown cells the cut left outside behind walls seen from one side, to
/// the thickness the views measured where they saw the wall from both sides (module docs).
/// Returns the cells made solid, by box index (increasing), each with its signed distance in
/// cells (negative: inside the continued surface). `values` gives the marked cells' mean
/// signed distances in cells by box index, increasing (called only when a run of marked
/// cells could be a wall).
pub(super) fn continue_walls(
    b: &mut Box3<'_>,
    values: impl FnOnce() -> Vec<(u32, f32)>,
) -> Vec<(usize, f32)> {
    let g = BoxGrid::new(b.dims);
    if !(b.resolved.is_finite() && b.resolved > 0.0) {
        return Vec::new();
    }
    let candidates = candidates(b, &g);
    if candidates.is_empty() {
        return Vec::new();
    }
    let values = Values(values());
    let fronts = fronts(&candidates, &values);
    drop(candidates);
    if fronts.is_empty() {
        return Vec::new();
    }
    let mut walls: Vec<usize> = fronts.iter().map(|f| f.1).collect();
    walls.sort_unstable();
    walls.dedup();
    // First with the least thickness that counts (most closed objects stop here: what
    // fronts they have are scattered cells with little or no unseen space behind them),
    // then with the thickness measured for each wall cell.
    let normals: HashMap<usize, [f32; 3]> = walls
        .iter()
        .map(|&w| (w, b.inward(&g, &values, w)))
        .collect();
    drop(values);
    let deep: Vec<usize> = walls
        .iter()
        .copied()
        .filter(|&w| b.deep_behind(&g, w, normals[&w], b.resolved))
        .collect();
    let wanted: Vec<usize> = patches(&g, &deep)
        .into_iter()
        .filter(|p| is_sheet(p.len(), b.resolved))
        .flat_map(|p| p.into_iter().map(|k| deep[k]))
        .collect::<std::collections::BTreeSet<usize>>()
        .into_iter()
        .collect();
    if wanted.is_empty() {
        return Vec::new();
    }
    let thick = thickness(b, &g, &wanted, &patches(&g, &wanted));
    let measured: Vec<(usize, f32)> = wanted
        .iter()
        .zip(thick)
        .filter(|&(&w, t)| t >= b.resolved && b.deep_behind(&g, w, normals[&w], t))
        .map(|(&w, t)| (w, t))
        .collect();
    // Kept in sheets of their median thickness.
    let cells: Vec<usize> = measured.iter().map(|m| m.0).collect();
    let mut valid: HashMap<usize, f32> = HashMap::new();
    for p in patches(&g, &cells) {
        let mut ts: Vec<f32> = p.iter().map(|&k| measured[k].1).collect();
        ts.sort_by(f32::total_cmp);
        if is_sheet(p.len(), ts[ts.len() / 2]) {
            valid.extend(p.iter().map(|&k| measured[k]));
        }
    }
    // The fronts that grow, each with its wall cell's index in `sources` (wall cell, inward
    // normal) and its budget: the thickness plus the half cell from the front cell's centre
    // to the surface, in thirds of a cell (at most [`MAX_BUDGET`]).
    let mut sources: Vec<(usize, [f32; 3])> = Vec::new();
    let mut source_of: HashMap<usize, u32> = HashMap::new();
    let mut starts: Vec<(usize, u32, u8)> = Vec::new();
    for &(f, w) in &fronts {
        let Some(&t) = valid.get(&w) else {
            continue;
        };
        let budget = ((t + 0.5) * 3.0).round().min(f32::from(MAX_BUDGET)) as u8;
        let s = *source_of.entry(w).or_insert_with(|| {
            sources.push((w, normals[&w]));
            (sources.len() - 1) as u32
        });
        starts.push((f, s, budget));
    }
    drop((source_of, valid, normals));
    if starts.is_empty() {
        return Vec::new();
    }
    // The growth stays within the fronts' box grown by the largest budget: dense arrays over
    // that region (the budget left plus one, 0 where not reached; the source).
    let reach = usize::from(starts.iter().map(|s| s.2).max().unwrap_or(0)) / 3 + 1;
    let mut rlo = g.coord(starts[0].0);
    let mut rhi = rlo;
    for &(f, _, _) in &starts {
        let c = g.coord(f);
        for a in 0..3 {
            rlo[a] = rlo[a].min(c[a]);
            rhi[a] = rhi[a].max(c[a]);
        }
    }
    for a in 0..3 {
        rlo[a] = rlo[a].saturating_sub(reach);
        rhi[a] = (rhi[a] + reach).min(g.dims[a] - 1);
    }
    let rd = [0, 1, 2].map(|a| rhi[a] - rlo[a] + 1);
    let local =
        |c: [usize; 3]| (c[0] - rlo[0]) + (c[1] - rlo[1]) * rd[0] + (c[2] - rlo[2]) * rd[0] * rd[1];
    let mut left = vec![0u8; rd[0] * rd[1] * rd[2]];
    let mut from = vec![0u32; left.len()];
    let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); usize::from(MAX_BUDGET) + 1];
    for &(f, s, budget) in &starts {
        let l = local(g.coord(f));
        if left[l] < budget + 1 {
            left[l] = budget + 1;
            from[l] = s;
            buckets[usize::from(budget)].push(f);
        }
    }
    // A cell the growth may enter from source `s`: an inside one, or an open one (unknown,
    // outside by the cut; the cells below the platform are excluded, never open) within the cone around the source's inward
    // normal and not next to a cell seen empty. Checked before a cell is reached, so that a
    // cell out of one wall's cone stays open to another's.
    let open = |j: usize| !b.inside[j] && b.known[j] == Known::Unknown;
    let enterable = |j: usize, c: [usize; 3], s: u32| {
        if b.inside[j] {
            return true;
        }
        if !open(j) {
            return false;
        }
        let beside_empty = g
            .face_neighbours(c)
            .any(|k| !b.inside[k] && b.known[k] == Known::Empty);
        let (w, normal) = sources[s as usize];
        let cw = g.coord(w);
        let dir = [0, 1, 2].map(|a| c[a] as f32 - cw[a] as f32);
        let len = dir.iter().map(|x| x * x).sum::<f32>().sqrt();
        let along = (0..3).map(|a| dir[a] * normal[a]).sum::<f32>();
        !beside_empty && along >= NORMAL_CONE_COS * len
    };
    // The 26 steps: offset, chamfer price, and index offsets in the box and in the region.
    let steps: Vec<([i64; 3], usize, isize, isize)> = neighbours26()
        .map(|d| {
            let price = CHAMFER[d.iter().filter(|&&x| x != 0).count()];
            let box_off = d[0] as isize
                + d[1] as isize * g.strides[1] as isize
                + d[2] as isize * g.strides[2] as isize;
            let region_off = d[0] as isize
                + d[1] as isize * rd[0] as isize
                + d[2] as isize * (rd[0] * rd[1]) as isize;
            (d, price, box_off, region_off)
        })
        .collect();
    let mut filled = Vec::new();
    for level in (0..buckets.len()).rev() {
        for i in std::mem::take(&mut buckets[level]) {
            let c = g.coord(i);
            let l = local(c);
            if usize::from(left[l]) != level + 1 {
                continue;
            }
            let s = from[l];
            if open(i) {
                filled.push((i, -(level as f32) / 3.0));
            }
            for &(d, price, box_off, region_off) in &steps {
                if price > level {
                    continue;
                }
                let rest = level - price;
                let cj = [0, 1, 2].map(|a| c[a] as i64 + d[a]);
                if (0..3).any(|a| cj[a] < rlo[a] as i64 || cj[a] > rhi[a] as i64) {
                    continue;
                }
                let lj = l.wrapping_add_signed(region_off);
                if usize::from(left[lj]) > rest {
                    continue;
                }
                let j = i.wrapping_add_signed(box_off);
                if enterable(j, cj.map(|v| v as usize), s) {
                    left[lj] = (rest + 1) as u8;
                    from[lj] = s;
                    buckets[rest].push(j);
                }
            }
        }
    }
    // A cell is taken at the one level it was last raised to: no repeats.
    filled.sort_unstable_by_key(|f| f.0);
    for &(i, _) in &filled {
        b.inside[i] = true;
    }
    filled
}

/// The patches of `cells` (box indices, increasing): their 26-connected pieces, each as
/// positions in `cells`, in the order of their first cell.
fn patches(g: &BoxGrid, cells: &[usize]) -> Vec<Vec<usize>> {
    let mut done = vec![false; cells.len()];
    let mut out = Vec::new();
    for k0 in 0..cells.len() {
        if done[k0] {
            continue;
        }
        done[k0] = true;
        let mut members = vec![k0];
        let mut m = 0;
        while m < members.len() {
            let c = g.coord(cells[members[m]]);
            m += 1;
            for d in neighbours26() {
                if let Some(j) = g.offset(c, d)
                    && let Ok(k) = cells.binary_search(&j)
                    && !done[k]
                {
                    done[k] = true;
                    members.push(k);
                }
            }
        }
        out.push(members);
    }
    out
}

/// Whether a patch of wall cells of thickness `t` (cells) is a sheet to continue: at least
/// as many cells as `t²`, as wide as the wall is thick.
fn is_sheet(cells: usize, t: f32) -> bool {
    cells as f32 >= t * t
}

/// The 26 offsets to a cell's neighbours.
pub(super) fn neighbours26() -> impl Iterator<Item = [i64; 3]> {
    (0..27)
        .map(|k| [k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1])
        .filter(|d| *d != [0, 0, 0])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box of 40³ cells holding a flat wall of thickness `t` cells with normal
    /// (1, 1, 1)/√3 (so that every axis crosses it), its outer surface at depth `s = 0`
    /// (`s` grows into the wall), seen from the front (`s < 0`) everywhere. Where
    /// `x >= two_sided_from` the views also saw its inner surface (`s = t`) and the space
    /// behind it; elsewhere only the cells the outer surface marked are inside, and
    /// everything behind them is unknown up to depth `unknown_to` (seen empty beyond). What
    /// the cut would leave: (dims, inside, known, marked, the marked cells' values).
    struct Slab {
        dims: [usize; 3],
        inside: Vec<bool>,
        known: Vec<Known>,
        marked: Vec<bool>,
        values: Vec<(u32, f32)>,
        depth: Vec<f32>,
    }

    fn slab(t: f32, two_sided_from: usize, unknown_to: f32) -> Slab {
        slab_along([1.0, 1.0, 1.0], t, two_sided_from, unknown_to)
    }

    /// [`slab`] with the wall's normal along `normal` (positive components: the front faces
    /// the box's low corner).
    fn slab_along(normal: [f32; 3], t: f32, two_sided_from: usize, unknown_to: f32) -> Slab {
        let len = normal.iter().map(|x| x * x).sum::<f32>().sqrt();
        let normal = normal.map(|x| x / len);
        let n = 40usize;
        let dims = [n; 3];
        let g = BoxGrid::new(dims);
        let total = n * n * n;
        let (mut inside, mut known, mut marked) = (
            vec![false; total],
            vec![Known::Empty; total],
            vec![false; total],
        );
        let (mut values, mut depth) = (Vec::new(), vec![0f32; total]);
        for i in 0..total {
            let c = g.coord(i).map(|v| v as f32 + 0.5);
            let s = c[0] * normal[0] + c[1] * normal[1] + c[2] * normal[2] - 30.0;
            depth[i] = s;
            let two_sided = g.coord(i)[0] >= two_sided_from;
            // Marked by the outer surface, and by the inner one where it was seen.
            let value = if s.abs() <= HALF_DIAGONAL {
                Some(-s)
            } else if two_sided && (s - t).abs() <= HALF_DIAGONAL {
                Some(s - t)
            } else {
                None
            };
            if let Some(v) = value {
                marked[i] = true;
                values.push((i as u32, v));
                known[i] = if v <= 0.0 { Known::Solid } else { Known::Empty };
            } else if s < 0.0 || (two_sided && s > t) || (!two_sided && s > unknown_to) {
                known[i] = Known::Empty;
            } else if two_sided {
                known[i] = Known::Solid;
            } else {
                known[i] = Known::Unknown;
            }
            inside[i] = known[i] == Known::Solid;
        }
        Slab {
            dims,
            inside,
            known,
            marked,
            values,
            depth,
        }
    }

    /// Whether cell `i` of `s` shares a face with a cell seen empty (`before`: the cut's
    /// inside cells).
    fn beside_seen_empty(s: &Slab, before: &[bool], i: usize) -> bool {
        let g = BoxGrid::new(s.dims);
        let c = g.coord(i);
        (0..3).any(|a| {
            [-1i64, 1].into_iter().any(|d| {
                let mut o = [0i64; 3];
                o[a] = d;
                g.offset(c, o)
                    .is_some_and(|j| s.known[j] == Known::Empty && !before[j])
            })
        })
    }

    fn continued(s: &mut Slab, margin: f32) -> Vec<(usize, f32)> {
        let values = s.values.clone();
        continue_walls(
            &mut Box3 {
                dims: s.dims,
                inside: &mut s.inside,
                known: &s.known,
                marked: &s.marked,
                resolved: resolved_thickness(margin),
            },
            move || values,
        )
    }

    /// Behind the part seen from one side, the wall goes on to the thickness measured where
    /// both sides were seen, with the signed distance of the continued inner surface; no
    /// cell that the views saw empty, nor one next to it, is made solid.
    #[test]
    fn a_wall_seen_in_part_from_both_sides_keeps_its_thickness() {
        let t = 8.0;
        let mut s = slab(t, 24, 100.0);
        let before = s.inside.clone();
        let out = continued(&mut s, 2.0);
        assert!(!out.is_empty(), "nothing continued");
        let g = BoxGrid::new(s.dims);
        for &(i, v) in &out {
            assert!(
                !before[i] && s.known[i] == Known::Unknown,
                "cell {i} was not open"
            );
            assert!(s.inside[i]);
            assert!(
                !beside_seen_empty(&s, &before, i),
                "cell {i} is next to seen-empty space"
            );
            // Inside the continued inner surface, which lies no deeper than the measured
            // thickness (within the chamfer's error and a cell), and at it away from the
            // box's sides and the edge of the one-sided part.
            let want = s.depth[i] - t;
            assert!(
                v <= 0.0 && v >= want - 1.5,
                "cell {i}: value {v}, depth - t {want}"
            );
            let c = g.coord(i);
            if (4..14).contains(&c[0]) && c.iter().all(|&x| (4..36).contains(&x)) {
                assert!(
                    (v - want).abs() <= 1.5,
                    "cell {c:?}: value {v}, depth - t {want}"
                );
            }
        }
        // Away from the edges of the one-sided part, the wall is whole to its thickness.
        let filled: std::collections::HashSet<usize> = out.iter().map(|o| o.0).collect();
        for i in 0..s.inside.len() {
            let c = g.coord(i);
            if !(4..14).contains(&c[0]) || c.iter().any(|&v| !(4..36).contains(&v)) {
                continue;
            }
            let d = s.depth[i];
            if (1.5..t - 1.5).contains(&d) {
                assert!(filled.contains(&i), "cell {c:?} at depth {d} not continued");
            }
            if d > t + 1.5 {
                assert!(!filled.contains(&i), "cell {c:?} at depth {d} continued");
            }
        }
    }

    /// A wall seen from both sides everywhere, or thinner than the noise lets one measure,
    /// or with only a narrow unknown gap behind its one-sided part: nothing is continued.
    #[test]
    fn nothing_is_continued_without_a_measured_wall_and_deep_unseen_space_behind() {
        // Seen from both sides everywhere.
        let mut s = slab(8.0, 0, 100.0);
        assert!(continued(&mut s, 2.0).is_empty());
        // Thinner than twice the margin less half a diagonal (8 < 2 * 5 - 0.87).
        let mut s = slab(8.0, 24, 100.0);
        assert!(continued(&mut s, 5.0).is_empty());
        // The unseen space behind the one-sided part is 4 cells deep, less than the wall.
        let mut s = slab(8.0, 24, 4.0);
        assert!(continued(&mut s, 2.0).is_empty());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]

        /// Whatever the wall's direction, thickness, the part seen from both sides, the depth
        /// of the unseen space behind and the sensor's margin: only cells that were unknown
        /// and outside are made solid, none of them next to a cell seen empty, all behind the
        /// wall's observed outer surface, each with a signed distance between minus the
        /// largest growth and zero.
        #[test]
        fn continued_cells_are_unknown_behind_the_wall_and_clear_of_seen_space(
            nx in 1u8..4, ny in 1u8..4, nz in 1u8..4,
            t in 4.0f32..10.0,
            from in 10usize..34,
            unknown_to in 2.0f32..40.0,
            margin in 1.5f32..4.0,
        ) {
            let mut s = slab_along([f32::from(nx), f32::from(ny), f32::from(nz)], t, from, unknown_to);
            let before = s.inside.clone();
            let out = continued(&mut s, margin);
            let most = f32::from(MAX_BUDGET) / 3.0;
            for &(i, v) in &out {
                proptest::prop_assert!(!before[i] && s.known[i] == Known::Unknown);
                proptest::prop_assert!(s.inside[i]);
                proptest::prop_assert!(s.depth[i] > 0.0, "cell {} in front of the wall", i);
                proptest::prop_assert!(v <= 0.0 && v >= -most, "value {}", v);
                proptest::prop_assert!(
                    !beside_seen_empty(&s, &before, i),
                    "cell {} next to seen-empty space", i
                );
            }
            // Nothing but those cells changed.
            let changed = (0..s.inside.len()).filter(|&i| s.inside[i] != before[i]).count();
            proptest::prop_assert_eq!(changed, out.len());
        }
    }
}
