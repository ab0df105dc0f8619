//! Slabs: a slab seen from above and all around is solid, not a shell over its shadow.
//!
//! A cap on a stem (a mushroom, a table's top, a stool's seat) is seen from above and on
//! its side, never from below: the space under it and inside it is hidden by the slab
//! itself. The cut prices the back of a seen surface as surface next to an observation, so
//! it closed the slab right behind its seen top and side and left the inside hollow, open
//! to the shadow under it: a 70 mm cap 12 mm thick came out as an 8.9 cm³ shell (54 in
//! truth). A horizontal layer of such a slab has what a layer of no other unseen space has:
//! its unseen inside is enclosed, within the layer, by the solid the cut kept (the seen
//! side all around), and covered, straight above every cell, by that solid (the seen top),
//! with nothing seen empty between. Such a pocket is filled, layer by layer, down to the
//! slab's seen side's lower edge, where the layer is no longer enclosed; the shadow under
//! the slab, open to space seen empty beside it, stays outside.
//!
//! The inside of a vessel is not covered (the views look into it from above, and the
//! opened inside reaches up to space seen empty), nor is the space between legs enclosed.
//! What no view can tell apart is a slab from a bowl upside down: that comes out solid.

use super::Known;
use super::platform::{layer_neighbours, spread};
use crate::bitbox::BitBox;
use crate::par;

/// Fills the pockets of `inside` (a box of `dims` cells, x fastest; `known` the views'
/// verdicts, `marked` the cells triangles marked) that a layer's solid encloses and its
/// solid covers (module docs): each 4-connected patch, within one layer, of unknown cells
/// the cut left outside, away from the box's sides, bordered in the layer by inside or
/// marked cells only (the seen side's marked cells hold its surface, whichever side of it
/// their centres lie), with an inside cell the first above each of its cells that is not
/// such a cell; of these, only where at least `min_run` of them lie one over another (a
/// slab's inside thinner than the noise band cannot be told from one noisy surface: at
/// 2 mm leaves a rocker's pivot hole, whose ends the triangles closed, met the rules in one
/// layer under its top). Returns the cells filled.
pub(super) fn fill_covered_pockets(
    dims: [usize; 3],
    inside: &mut [bool],
    known: &[Known],
    marked: &[bool],
    min_run: usize,
) -> usize {
    let [nx, ny, nz] = dims;
    let at = |x: usize, y: usize, z: usize| (z * ny + y) * nx + x;
    let hollow = |inside: &[bool], i: usize| !inside[i] && known[i] == Known::Unknown;
    // Which hollow cells are covered: down each column, the last cell that is not hollow
    // was inside (not a marked cell the cut left outside, nor one seen empty: counting
    // marked cells as a roof, a rocker's pivot hole, its ends closed by triangles, was
    // filled at 1 mm, 0.23 -> 0.35 leaf). Cell `(x, y, z)` is bit `x` of row `z * ny + y`.
    let mut covered = BitBox::new(dims);
    let mut roof = vec![false; nx];
    for z in 0..nz {
        roof.fill(false);
        for y in (0..ny).rev() {
            for (x, r) in roof.iter_mut().enumerate() {
                let i = at(x, y, z);
                if hollow(inside, i) {
                    if *r {
                        covered.set(x, z * ny + y);
                    }
                } else {
                    *r = inside[i];
                }
            }
        }
    }
    if covered.count() == 0 {
        return 0;
    }
    // Each layer's pockets, the layers in parallel (a patch lies in one layer).
    let mut found: Vec<usize> = Vec::new();
    {
        let inside = &*inside;
        par::extend_in_order(&mut found, ny, 1, |y, out| {
            // The layer's hollow cells (`x + z * nx`); the others bound the patches.
            let wall: Vec<bool> = (0..nx * nz)
                .map(|c| !hollow(inside, at(c % nx, y, c / nx)))
                .collect();
            let mut done = wall.clone();
            for start in 0..nx * nz {
                if done[start] {
                    continue;
                }
                let patch = spread(vec![start], &mut done, &wall, nx, nz);
                // Enclosed (away from the box's sides, bordered by inside or marked cells
                // only) and covered.
                let pocket = patch.iter().all(|&c| {
                    let (x, z) = (c % nx, c / nx);
                    covered.get(x, z * ny + y)
                        && x > 0
                        && z > 0
                        && x + 1 < nx
                        && z + 1 < nz
                        && layer_neighbours(c, nx, nz).all(|q| {
                            let q = at(q % nx, y, q / nx);
                            hollow(inside, q) || inside[q] || marked[q]
                        })
                });
                if pocket {
                    out.extend(patch.iter().map(|&c| at(c % nx, y, c / nx)));
                }
            }
        });
    }
    if found.is_empty() {
        return 0;
    }
    let mut pockets = BitBox::new(dims);
    for &i in &found {
        pockets.set(i % nx, i / nx);
    }
    // The columns' runs of pocket cells at least `min_run` long, filled (each column's run
    // so far kept for a whole row at once).
    let mut filled = 0;
    let mut run = vec![0usize; nx];
    for z in 0..nz {
        run.fill(0);
        for y in 0..=ny {
            for (x, r) in run.iter_mut().enumerate() {
                if y < ny && pockets.get(x, z * ny + y) {
                    *r += 1;
                    continue;
                }
                if *r >= min_run.max(1) {
                    for yy in y - *r..y {
                        inside[at(x, yy, z)] = true;
                    }
                    filled += *r;
                }
                *r = 0;
            }
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    const DIMS: [usize; 3] = [24, 24, 24];

    fn at(x: usize, y: usize, z: usize) -> usize {
        (z * DIMS[1] + y) * DIMS[0] + x
    }

    /// A cap (x, z in 4..20, layers 12..20) on a stem (x, z in 10..14, below), as the cut
    /// leaves it: the cap's top and side and the stem inside, the cap's inside and the
    /// shadow under it unknown and outside, the rest seen empty. Returns (inside, known,
    /// marked).
    fn cap() -> (Vec<bool>, Vec<Known>, Vec<bool>) {
        let n = DIMS.iter().product();
        let (mut inside, mut known, mut marked) =
            (vec![false; n], vec![Known::Empty; n], vec![false; n]);
        for z in 0..DIMS[2] {
            for y in 0..DIMS[1] {
                for x in 0..DIMS[0] {
                    let i = at(x, y, z);
                    let in_cap = (4..20).contains(&x) && (4..20).contains(&z);
                    let rim = in_cap && !((5..19).contains(&x) && (5..19).contains(&z));
                    let stem = (10..14).contains(&x) && (10..14).contains(&z);
                    if in_cap && (y == 19 || (rim && (12..20).contains(&y))) || stem && y < 8 {
                        (inside[i], known[i], marked[i]) = (true, Known::Solid, true);
                    } else if in_cap && (8..19).contains(&y) {
                        known[i] = Known::Unknown;
                    }
                }
            }
        }
        (inside, known, marked)
    }

    #[test]
    fn a_cap_seen_from_above_and_around_is_filled_down_to_its_side() {
        let (mut inside, known, marked) = cap();
        let filled = fill_covered_pockets(DIMS, &mut inside, &known, &marked, 4);
        // Inside the rim, layers 12..19: 14 x 14 x 7 cells; the shadow under it stays.
        assert_eq!(filled, 14 * 14 * 7);
        assert!(inside[at(12, 12, 12)] && inside[at(5, 18, 5)]);
        assert!(!inside[at(12, 11, 12)] && !inside[at(5, 8, 5)]);
    }

    #[test]
    fn a_pocket_open_above_or_too_thin_stays() {
        // A hole seen empty through the top: the cells under it are not covered, and the
        // layers' patches hold them.
        let (mut inside, mut known, marked) = cap();
        known[at(12, 19, 12)] = Known::Empty;
        inside[at(12, 19, 12)] = false;
        let before = inside.clone();
        assert_eq!(
            fill_covered_pockets(DIMS, &mut inside, &known, &marked, 4),
            0
        );
        assert_eq!(inside, before);
        // Thinner than the noise band: seven layers under a band of eight.
        let (mut inside, known, marked) = cap();
        assert_eq!(
            fill_covered_pockets(DIMS, &mut inside, &known, &marked, 8),
            0
        );
    }
}
