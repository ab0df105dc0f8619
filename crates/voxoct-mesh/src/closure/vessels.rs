//! Vessels: the lid the cut puts where the views stop seeing into a thin-walled vessel is
//! taken off, and the vessel is opened below it, its wall kept at the thickness the views
//! measured where they saw both its sides.
//!
//! The views see into a cup only so far: below a depth that grows with its width, neither
//! its inner wall nor its floor is seen, only its outer wall, from outside. The cut then
//! closes the seen part of the inside with a lid across the cup (its area is a fraction of
//! the unseen inner wall's, so it costs less however the faces are priced), and everything
//! below the lid is solid: a deep cup (60 mm wide, 90 mm deep) came out a jar filled to
//! 15 mm below its rim. A lid across a vessel has two signs that a surface the cut invents
//! on a solid has not: it faces up, since the views look down into a vessel (a surface
//! invented under an overhang faces down, one between legs sideways), and all around its
//! rim the wall it meets was seen from both sides, and is thin.
//!
//! - **Lids**: the inside cells of the cut's invented surface (unknown cells it put inside,
//!   next to an unknown or seen-empty cell it left outside), in their 26-connected patches;
//!   only a patch at least as many cells as the square of a thin wall's greatest thickness
//!   ([`open_lids`]'s `thin`), whose faces toward the outside mostly face up (+y), is
//!   looked at.
//! - **A vessel's lid**: at least nine in ten of the patch's rim cells (those next to a
//!   marked cell; the tenth allows for the noise) lie within two cells of a cell inside a
//!   thin wall seen from both sides: a cell inside (marked or put inside by the cut: where
//!   the views saw both sides of a wall two cells thin, it is all marked) from which a run
//!   of inside cells along some axis ends in cells seen empty at both ends (the platform
//!   does not count as seen), with `t = (Σ 1/L²)^(-1/2)` over such axes (exact for a flat
//!   slab, as the continued walls' measurement) at most `thin`. Runs are followed for at
//!   most four times `thin` cells: a longer one carries no thickness. A cell inside a solid
//!   seen from all around has no such run shorter than the solid is wide. A run that the
//!   space around it crosses next to it (more than half of the run beside it, on one of
//!   the four sides across it, is outside) goes along a layer, not through a wall: the
//!   rough layer of a surface seen face-on, whose height varies by the noise, has short
//!   runs seen empty at both ends along the surface, with air just above them (they
//!   opened a solid to a shell at 0.5 mm leaves: a cylinder whose dimple's floor was seen
//!   only around an unseen middle).
//! - **Opening**: the cells the cut put inside that lie more than `t − 1` cells (3-4-5
//!   chamfer) from every marked cell and above the band over the platform whose readings
//!   the clip box removed, reached from the lid through such cells, are put outside, `t`
//!   being the median of the thicknesses next to the rim: what stays of the fill is a wall
//!   `t` cells thick behind the seen outer surface (the marked cell and `t − 1` more, whose
//!   inner surface the mesher puts half a cell further). Under each cell opened in the
//!   layer just above the band, the band is opened straight down to the platform's layer:
//!   no reading says anything there, so the wall goes on down as it is above the band, and
//!   the floor is the platform's layer, the bottom that a vessel the cut left open onto the
//!   platform gets (`platform`): one floor whichever way a vessel is opened. (The opening
//!   stopped above the band before, a floor as thick as the band: the development vase came
//!   out 0.45 / 1.76 leaf that way, with its 6 mm floor's top 1.8 leaves over ours, and
//!   0.40 / 0.97 with the one-cell floor; procedural cups with 4–5 mm floors went the other
//!   way, 0.28–0.29 to 0.31–0.33 leaf.) A lid with no cell that far from the marked cells
//!   has nothing behind it to open.
//!
//! A jar, bottle or vase whose neck is narrower than its body is opened too when the
//! neck's wall was seen from both sides around the lid: the opening reaches the body
//! through the neck, and the body's wall is kept as thick as the neck's (the opening knows
//! no other). Where no view saw a vessel's floor it is taken to be on the platform: a solid
//! whose top is a deep thin-walled crown is opened down to the platform (the README gives
//! the figures).

use super::Known;
use super::walls::{BoxGrid as Grid, neighbours26};
use crate::par;

/// Share of a lid's rim cells (tenths) that must lie next to a thin wall seen from both
/// sides.
const WALLED_TENTHS: usize = 9;

/// How far from a rim cell (cells, along each axis) a wall cell seen from both sides is
/// looked for.
const RIM_REACH: i64 = 2;

/// The thickness, in cells, of a wall seen from both sides at the inside cell `i`
/// (module docs), runs followed for at most `longest` cells; `None` when no axis's run is
/// seen empty at both ends.
fn two_sided(g: &Grid, known: &[Known], inside: &[bool], i: usize, longest: usize) -> Option<f32> {
    let mut inv2 = 0.0f32;
    for (a, ((ca, stride), len)) in g
        .coord(i)
        .into_iter()
        .zip(g.strides)
        .zip(g.dims)
        .enumerate()
    {
        // The run's inside cells on one side of `i`, and whether the cell that ends it was
        // seen empty; `None` when it goes on past `longest` cells.
        let end = |forward: bool| -> Option<(usize, bool)> {
            let mut k = 0;
            loop {
                k += 1;
                if k > longest {
                    return None;
                }
                let at = if forward {
                    (ca + k < len).then(|| i + k * stride)
                } else {
                    (ca >= k).then(|| i - k * stride)
                };
                match at {
                    // The box's sides are outside what anything marked; its bottom is the
                    // platform.
                    None => return Some((k - 1, a != 1 || forward)),
                    Some(j) if inside[j] => {}
                    Some(j) => return Some((k - 1, known[j] == Known::Empty)),
                }
            }
        };
        if let (Some((lo, true)), Some((hi, true))) = (end(false), end(true))
            && !bridged(g, inside, i - lo * stride, (a, lo + hi + 1))
        {
            let l = (lo + hi + 1) as f32;
            inv2 += 1.0 / (l * l);
        }
    }
    (inv2 > 0.0).then(|| 1.0 / inv2.sqrt())
}

/// Whether the run of `len` inside cells from `first` along `axis` lies in a layer that the
/// space around it crosses next to it: along one of the four directions across the axis,
/// more than half of the neighbouring run's cells are outside. A run through a wall has
/// the wall beside it on every side; one through the rough layer of a surface seen
/// face-on (a floor seen from above, its height varying by the noise) has air just above.
fn bridged(g: &Grid, inside: &[bool], first: usize, (axis, len): (usize, usize)) -> bool {
    let c = g.coord(first);
    (0..3).filter(|&b| b != axis).any(|b| {
        [-1i64, 1].into_iter().any(|s| {
            let mut d = [0i64; 3];
            d[b] = s;
            let outside = (0..len)
                .filter(|&k| {
                    let mut q = c;
                    q[axis] += k;
                    g.offset(q, d).is_none_or(|j| !inside[j])
                })
                .count();
            2 * outside > len
        })
    })
}

/// Rows (x runs of the box) per parallel task of the search for lid cells.
const ROWS_PER_TASK: usize = 256;

/// Takes the lids off vessels whose walls are at most `thin` cells thick (module docs):
/// puts outside the cells of `inside` that the opening reaches, none below the layer
/// `lowest` (the first above the platform's clipped band), and below each one it reaches in
/// that layer the unknown cells of its column down to the layer over `floor` (the
/// platform's; `None`: no platform in the box). `distance` gives each cell's
/// 3-4-5 chamfer distance from the nearest marked cell, in thirds of a cell (called only
/// when there is a vessel to open). Returns the cells put outside.
pub(super) fn open_lids(
    dims: [usize; 3],
    inside: &mut [bool],
    known: &[Known],
    marked: &[bool],
    (thin, lowest, floor): (f32, usize, Option<usize>),
    distance: impl FnOnce() -> Vec<u16>,
) -> usize {
    if !(thin.is_finite() && thin >= 1.0) {
        return 0;
    }
    let g = Grid::new(dims);
    let n = inside.len();
    // The cut's invented surface, row by row. Every closure looks for it: the six
    // neighbours are taken from the row's coordinates rather than `Grid::face_neighbours`,
    // whose divisions per cell took twice the time (bunny: 5.5 against 2.4 ms).
    let mut lid: Vec<usize> = Vec::new();
    {
        let inside = &*inside;
        let [nx, ny, nz] = dims;
        let open = |j: usize| left_open(known, inside, j);
        par::extend_in_order(&mut lid, ny * nz, ROWS_PER_TASK, |r, out| {
            let (y, z) = (r % ny, r / ny);
            for x in 0..nx {
                let i = r * nx + x;
                if known[i] != Known::Unknown || !inside[i] {
                    continue;
                }
                let next = (x > 0 && open(i - 1))
                    || (x + 1 < nx && open(i + 1))
                    || (y > 0 && open(i - nx))
                    || (y + 1 < ny && open(i + nx))
                    || (z > 0 && open(i - nx * ny))
                    || (z + 1 < nz && open(i + nx * ny));
                if next {
                    out.push(i);
                }
            }
        });
    }
    if lid.is_empty() {
        return 0;
    }
    let longest = (4.0 * thin).ceil() as usize;
    let wide = thin * thin;
    // Lid cells not yet in a patch, a bit per cell of the box.
    let mut open_cell = vec![0u64; n.div_ceil(64)];
    for &i in &lid {
        open_cell[i / 64] |= 1 << (i % 64);
    }
    let mut take = |j: usize| {
        let (w, b) = (j / 64, 1u64 << (j % 64));
        let was = open_cell[w] & b != 0;
        open_cell[w] &= !b;
        was
    };
    let mut openings: Vec<(Vec<usize>, f32)> = Vec::new();
    for &start in &lid {
        if !take(start) {
            continue;
        }
        let mut patch = vec![start];
        let mut k = 0;
        while k < patch.len() {
            let c = g.coord(patch[k]);
            k += 1;
            for d in neighbours26() {
                if let Some(j) = g.offset(c, d)
                    && take(j)
                {
                    patch.push(j);
                }
            }
        }
        if (patch.len() as f32) < wide || !faces_up(&g, known, &*inside, &patch) {
            continue;
        }
        let vw = vessel_wall(&g, (known, &*inside, marked), &patch, thin, longest);
        // Only a lid with a cell further than the wall from every marked cell has a
        // vessel's inside behind it to open.
        if let Some(t) = vw
            && let offsets = ball(keep(t))
            && patch.iter().any(|&i| !near_marked(&g, marked, i, &offsets))
        {
            openings.push((patch, t));
        }
    }
    if openings.is_empty() {
        return 0;
    }
    let dist = distance();
    let mut opened = 0;
    for (patch, t) in openings {
        let far = keep(t);
        let opens = |j: usize, inside: &[bool]| {
            known[j] == Known::Unknown && inside[j] && dist[j] > far && g.coord(j)[1] >= lowest
        };
        let mut stack: Vec<usize> = patch.into_iter().filter(|&i| opens(i, inside)).collect();
        for &i in &stack {
            inside[i] = false;
        }
        while let Some(i) = stack.pop() {
            opened += 1;
            let c = g.coord(i);
            for j in g.face_neighbours(c) {
                if opens(j, inside) {
                    inside[j] = false;
                    stack.push(j);
                }
            }
            // Straight down through the band to the platform's layer: the band's readings
            // were clipped, so the wall goes on down as seen above it, and the floor is the
            // one cell on the platform that a vessel the cut left open gets
            // (`platform::cover_footprints`).
            if let Some(floor) = floor
                && c[1] == lowest
            {
                for y in (floor + 1..lowest).rev() {
                    let j = i - (lowest - y) * g.strides[1];
                    if known[j] != Known::Unknown || !inside[j] {
                        break;
                    }
                    inside[j] = false;
                    opened += 1;
                }
            }
        }
    }
    opened
}

/// Whether the cut left cell `j` outside where it had a choice or saw it empty (not a
/// solid, nor a cell below the platform): the side of an invented surface a lid faces.
fn left_open(known: &[Known], inside: &[bool], j: usize) -> bool {
    !inside[j] && matches!(known[j], Known::Unknown | Known::Empty)
}

/// Whether most faces of the lid `patch` toward cells outside face up (+y): the views look
/// down into a vessel, so the seen part of its inside is above the lid (the invented
/// surface under an overhang faces down, one between legs sideways).
fn faces_up(g: &Grid, known: &[Known], inside: &[bool], patch: &[usize]) -> bool {
    let open = |j: usize| left_open(known, inside, j);
    let (mut up, mut all) = (0usize, 0usize);
    for &i in patch {
        let c = g.coord(i);
        all += g.face_neighbours(c).filter(|&j| open(j)).count();
        up += usize::from(g.offset(c, [0, 1, 0]).is_some_and(open));
    }
    2 * up > all
}

/// The chamfer distance (thirds of a cell) within which a cell next to a vessel's wall of
/// thickness `t` stays inside: the marked cell and `t - 1` more behind it.
fn keep(t: f32) -> u16 {
    ((t - 1.0).max(0.0) * 3.0).round() as u16
}

/// The offsets within the 3-4-5 chamfer distance `far` (thirds of a cell) of a cell,
/// nearest first: `3a + b + c` for the offset's sorted magnitudes `a ≥ b ≥ c`, the distance
/// the closure's chamfer transform gives.
fn ball(far: u16) -> Vec<[i64; 3]> {
    let r = i64::from(far / 3);
    let mut out: Vec<(i64, [i64; 3])> = Vec::new();
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                let mut m = [dx.abs(), dy.abs(), dz.abs()];
                m.sort_unstable_by(|a, b| b.cmp(a));
                let d = 3 * m[0] + m[1] + m[2];
                if d <= i64::from(far) {
                    out.push((d, [dx, dy, dz]));
                }
            }
        }
    }
    out.sort_by_key(|o| o.0);
    out.into_iter().map(|o| o.1).collect()
}

/// Whether a marked cell lies at one of the `offsets` from cell `i`.
fn near_marked(g: &Grid, marked: &[bool], i: usize, offsets: &[[i64; 3]]) -> bool {
    let c = g.coord(i);
    offsets
        .iter()
        .any(|&d| g.offset(c, d).is_some_and(|j| marked[j]))
}

/// The median thickness of the thin walls seen from both sides next to the rim of the lid
/// `patch`, if they lie along enough of it to make it a vessel's lid (module docs).
fn vessel_wall(
    g: &Grid,
    (known, inside, marked): (&[Known], &[bool], &[bool]),
    patch: &[usize],
    thin: f32,
    longest: usize,
) -> Option<f32> {
    let mut memo: std::collections::HashMap<usize, Option<f32>> = std::collections::HashMap::new();
    // The rim, then the walls next to it; given up once too many rim cells have none.
    let rim: Vec<[usize; 3]> = patch
        .iter()
        .map(|&i| g.coord(i))
        .filter(|&c| neighbours26().any(|d| g.offset(c, d).is_some_and(|j| marked[j])))
        .collect();
    let mut unwalled = 0;
    let mut ts: Vec<f32> = Vec::new();
    for &c in &rim {
        let mut found = false;
        for dz in -RIM_REACH..=RIM_REACH {
            for dy in -RIM_REACH..=RIM_REACH {
                for dx in -RIM_REACH..=RIM_REACH {
                    let Some(j) = g.offset(c, [dx, dy, dz]) else {
                        continue;
                    };
                    if !inside[j] {
                        continue;
                    }
                    let t = *memo
                        .entry(j)
                        .or_insert_with(|| two_sided(g, known, inside, j, longest));
                    if let Some(t) = t.filter(|&t| t <= thin) {
                        ts.push(t);
                        found = true;
                    }
                }
            }
        }
        if !found {
            unwalled += 1;
            if unwalled * 10 > rim.len() * (10 - WALLED_TENTHS) {
                return None;
            }
        }
    }
    if rim.is_empty() || ts.is_empty() {
        return None;
    }
    ts.sort_by(f32::total_cmp);
    let t = ts[ts.len() / 2];
    (t > 1.0).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    const DIMS: [usize; 3] = [40, 50, 40];
    /// The layer where the views stop seeing into the cup.
    const SEEN_FROM: usize = 35;

    fn at(x: usize, y: usize, z: usize) -> usize {
        (z * DIMS[1] + y) * DIMS[0] + x
    }

    /// A cup's cells as the cut leaves them (upside down: mirrored in y): a wall from radius
    /// 10 to 14 cells (axis at the box's centre), its outer surface marked all the way up,
    /// its inner one from [`SEEN_FROM`] up, where the inside is seen empty; the outside is
    /// seen empty; the cut put inside everything under the inner surface's lowest seen
    /// layer (the lid) and in the wall. Returns (known, inside, marked).
    fn cup(upside_down: bool) -> (Vec<Known>, Vec<bool>, Vec<bool>) {
        cup_with_inner_radius(upside_down, 10.0)
    }

    /// [`cup`] with the inner surface at radius `ri` cells.
    fn cup_with_inner_radius(upside_down: bool, ri: f32) -> (Vec<Known>, Vec<bool>, Vec<bool>) {
        let n = DIMS[0] * DIMS[1] * DIMS[2];
        let (mut known, mut inside, mut marked) =
            (vec![Known::Unknown; n], vec![false; n], vec![false; n]);
        for z in 0..DIMS[2] {
            for y in 0..DIMS[1] - 3 {
                for x in 0..DIMS[0] {
                    let r = ((x as f32 - 20.0).powi(2) + (z as f32 - 20.0).powi(2)).sqrt();
                    let yy = if upside_down { DIMS[1] - 4 - y } else { y };
                    let i = at(x, yy, z);
                    let seen = y >= SEEN_FROM;
                    if r >= 14.5 {
                        known[i] = Known::Empty;
                    } else if r >= 13.5 || (seen && (ri - 0.5..ri + 0.5).contains(&r)) {
                        (known[i], marked[i], inside[i]) = (Known::Solid, true, true);
                    } else if seen && r < ri - 0.5 {
                        known[i] = Known::Empty;
                    } else {
                        inside[i] = true;
                    }
                }
            }
        }
        (known, inside, marked)
    }

    fn open(known: &[Known], inside: &mut [bool], marked: &[bool]) -> usize {
        open_lids(DIMS, inside, known, marked, (8.0, 1, None), || {
            super::super::chamfer_distance(DIMS, marked)
        })
    }

    #[test]
    fn a_cup_seen_from_above_is_opened_below_its_lid_and_keeps_its_wall() {
        let (known, mut inside, marked) = cup(false);
        let opened = open(&known, &mut inside, &marked);
        assert!(opened > 5000, "opened {opened}");
        // The inside below the lid, down to the platform's layer, is open; the wall keeps
        // its thickness (four cells) behind the outer surface.
        for y in [1, 10, 20, 34] {
            assert!(!inside[at(20, y, 20)], "axis at y = {y}");
            assert!(!inside[at(25, y, 20)], "inside at y = {y}");
            for x in [7, 8, 9] {
                assert!(inside[at(x, y, 20)], "wall at x = {x}, y = {y}");
            }
        }
        // The platform's layer is not opened.
        assert!(inside[at(20, 0, 20)]);
    }

    /// Over a clipped band (layers 1–3 over the platform's layer 0), the opening goes on
    /// straight down through the band: the wall goes on down as it is above the band, and
    /// the floor is the platform's layer alone.
    #[test]
    fn a_cup_is_opened_straight_down_through_the_clipped_band() {
        let (known, mut inside, marked) = cup(false);
        let opened = open_lids(
            DIMS,
            &mut inside,
            &known,
            &marked,
            (8.0, 4, Some(0)),
            || super::super::chamfer_distance(DIMS, &marked),
        );
        assert!(opened > 5000, "opened {opened}");
        for y in 1..4 {
            assert!(!inside[at(20, y, 20)], "axis at y = {y}");
            assert!(!inside[at(25, y, 20)], "inside at y = {y}");
            for x in [7, 8, 9] {
                assert!(inside[at(x, y, 20)], "wall at x = {x}, y = {y}");
            }
        }
        assert!(inside[at(20, 0, 20)]);
        assert!(inside[at(25, 0, 20)]);
    }

    #[test]
    fn a_lid_facing_down_or_next_to_a_thick_solid_stays() {
        // Upside down: the invented surface faces down, as under an overhang.
        let (known, mut inside, marked) = cup(true);
        let before = inside.clone();
        assert_eq!(open(&known, &mut inside, &marked), 0);
        assert_eq!(inside, before);
        // A solid whose top is seen only on a ring: the invented patch inside the ring faces
        // up, but the wall next to its rim is the whole solid, seen from both sides 29 cells
        // apart.
        let (mut known, mut inside, marked) = cup(false);
        for (i, k) in known.iter_mut().enumerate() {
            if *k == Known::Empty && !marked[i] {
                let (x, z) = (i % DIMS[0], i / (DIMS[0] * DIMS[1]));
                let r = ((x as f32 - 20.0).powi(2) + (z as f32 - 20.0).powi(2)).sqrt();
                if r < 10.5 {
                    *k = Known::Unknown;
                    inside[i] = (i / DIMS[0]) % DIMS[1] < SEEN_FROM + 5;
                }
            }
        }
        let before = inside.clone();
        assert_eq!(open(&known, &mut inside, &marked), 0);
        assert_eq!(inside, before);
    }

    #[test]
    fn a_cup_whose_wall_is_two_marked_cells_is_opened() {
        // Where the views see both sides, the wall is its two surfaces' marked cells and
        // nothing between them.
        let (known, mut inside, marked) = cup_with_inner_radius(false, 13.0);
        assert!(open(&known, &mut inside, &marked) > 5000);
        for y in [1, 20, 34] {
            assert!(!inside[at(20, y, 20)], "axis at y = {y}");
            assert!(!inside[at(9, y, 20)], "inside at y = {y}");
            // The marked outer cell and the one behind it stay.
            assert!(
                inside[at(6, y, 20)] && inside[at(7, y, 20)],
                "wall at y = {y}"
            );
        }
    }

    #[test]
    fn a_solid_whose_rough_top_was_seen_around_an_unseen_patch_stays() {
        // A solid block (radius 14.5 cells, 30 high, its side marked) whose top was seen
        // face-on through noise: its top two layers marked, the upper one in 2 x 2 blocks of
        // a checkerboard, seen empty between them, seen empty above; in the middle an unseen
        // patch (radius 6) the cut closed flat.
        // Across the rough layer every run is two cells long and seen empty at both ends,
        // but the air above crosses over each of them: no wall.
        let n = DIMS[0] * DIMS[1] * DIMS[2];
        let (mut known, mut inside, mut marked) =
            (vec![Known::Empty; n], vec![false; n], vec![false; n]);
        for z in 0..DIMS[2] {
            for x in 0..DIMS[0] {
                let r = ((x as f32 - 20.0).powi(2) + (z as f32 - 20.0).powi(2)).sqrt();
                if r >= 14.5 {
                    continue;
                }
                for y in 0..30 {
                    let i = at(x, y, z);
                    inside[i] = true;
                    if r >= 13.5 || (y == 29 && r >= 6.0) {
                        (known[i], marked[i]) = (Known::Solid, true);
                    } else {
                        known[i] = Known::Unknown;
                    }
                }
                let top = at(x, 30, z);
                if r < 6.0 {
                    (known[top], inside[top]) = (Known::Unknown, true);
                    known[at(x, 31, z)] = Known::Unknown;
                } else if (x / 2 + z / 2) % 2 == 0 {
                    (known[top], marked[top], inside[top]) = (Known::Solid, true, true);
                }
            }
        }
        let before = inside.clone();
        assert_eq!(open(&known, &mut inside, &marked), 0);
        assert_eq!(inside, before);
    }
}
