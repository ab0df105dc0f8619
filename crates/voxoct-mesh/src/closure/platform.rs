//! The object stands on the platform: what the clip box hid of its foot, and the platform
//! inside its footprint that no view saw.
//!
//! Two rules, each from how a turntable scan sees an object's bottom:
//! - **The clipped band reaches the platform** ([`extend_into_band`], before the cut). The
//!   clip box drops every reading within its margin over the platform (3 mm by default),
//!   where the sensor cannot tell the object's foot from the platform, so no triangle marks
//!   the foot there, and the cut ended a leg, a foot ring or the wall of a vase where the
//!   readings end, 2–3 mm above the platform. A column of cells whose lowest solid cell
//!   lies in that band, that is solid from there up through the layer above the band (the
//!   first one whose readings are whole: something stands on the column, not a lone cell
//!   of noise beside a face), or up through the band's highest layer under a cell seen
//!   empty where most of its neighbours in that layer are solid too (the seen top of an
//!   object whose readings end in the first layer that has any: a 60 mm disc 4 mm thick
//!   came out as a 1.3 cm³ shell, 11.3 in truth, now 10.4), and below which nothing was
//!   seen empty, is continued down to the platform: the object rests on it.
//! - **A vessel's hidden inside gets a bottom** ([`cover_footprints`], after the cut). On
//!   the platform's layer, a region that the object's foot encloses (the outline of what is
//!   solid from the platform up to a carving margin over the band), where no view saw the
//!   platform, and whose space above (what the cut left outside) reaches space seen empty,
//!   is a passage from the platform into the object's seen inside: a vase, cup or bowl whose
//!   inside no view saw down to its floor, which the cut left open onto the platform (the
//!   platform borders seen-empty space), so that a vase came out as a tube and a bowl with a
//!   hole through its floor. The region becomes solid: a bottom one cell thick, or up to
//!   where a view saw the space over it within the band (the floor's own readings were
//!   clipped; the cells in front of them were seen). The cavity keeps the shape the cut
//!   gave it otherwise. A hollow under the object that reaches nothing seen (the underside
//!   of a figure standing on its rim) stays as the cut left it, and so does a region where
//!   a view saw the platform through the object (a ring or a tube on its end, wide enough
//!   to look into): a reading further than the carving margin from the foot can only be
//!   the platform's.

use voxoct_core::Seen;

use super::Known;
use crate::bitbox::{BitBox, Flood};

/// Where the platform is in a box of cells given to [`super::close_cells`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Platform {
    /// The layer of cells on the platform (grid coordinates); cells below it are excluded.
    pub floor: u32,
    /// How many layers above `floor` lost their readings to the clip box (the object's foot
    /// there is unobserved); 0 when the clip box keeps everything above the platform.
    pub clipped: u32,
}

/// The layers of a box (its cells x fastest, then y, then z) from the platform's `floor`
/// (box coordinates) up through the clipped band and the layer above it, the first whose
/// readings are whole.
struct Band {
    dims: [usize; 3],
    floor: usize,
    /// The highest clipped layer.
    clipped_top: usize,
    /// The layer above it.
    top: usize,
}

impl Band {
    /// `None` when the floor is not in the box.
    fn new(dims: [usize; 3], floor: usize, clipped: usize) -> Option<Self> {
        (floor < dims[1]).then(|| Self {
            dims,
            floor,
            clipped_top: (floor + clipped).min(dims[1] - 1),
            top: (floor + clipped + 1).min(dims[1] - 1),
        })
    }

    fn at(&self, x: usize, y: usize, z: usize) -> usize {
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    /// The cells of column `(x, z)` in the band, from the floor up.
    fn column(&self, x: usize, z: usize) -> impl Iterator<Item = usize> + '_ {
        (self.floor..=self.top).map(move |y| self.at(x, y, z))
    }
}

/// The first rule (module docs): every column of `known` (a box of `dims` cells) whose lowest
/// solid cell lies in the band of `clipped` layers over the layer `floor` (box coordinates),
/// that is solid from there up through the layer above the band (or is a low top:
/// [`low_top`]), and whose cells below it are all unknown, is made solid down to `floor`.
pub(super) fn extend_into_band(
    dims: [usize; 3],
    known: &mut [Known],
    floor: usize,
    clipped: usize,
) {
    let Some(band) = Band::new(dims, floor, clipped) else {
        return;
    };
    for z in 0..dims[2] {
        for x in 0..dims[0] {
            let Some(lowest) = band.column(x, z).position(|i| known[i] == Known::Solid) else {
                continue;
            };
            // Solid from there up through the layer above the band: something stands on the
            // column (a lone cell of noise beside a face, or a ledge, does not).
            let stands = lowest + band.floor <= band.clipped_top
                && (band
                    .column(x, z)
                    .skip(lowest)
                    .all(|i| known[i] == Known::Solid)
                    || low_top(&band, known, (x, z), lowest));
            if stands
                && band
                    .column(x, z)
                    .take(lowest)
                    .all(|i| known[i] == Known::Unknown)
            {
                for i in band.column(x, z).take(lowest) {
                    known[i] = Known::Solid;
                }
            }
        }
    }
}

/// Whether column `(x, z)` of `band`, solid from its cell `lowest` up through the highest
/// clipped layer, ends there under a cell seen empty, inside a face seen from above: the
/// top of an object whose readings end in the first layer that has any (a disc as thick as
/// the band and a leaf), with most of its eight neighbours in that layer solid too (a lone
/// cell of noise, or the edge of a ledge, has not).
fn low_top(band: &Band, known: &[Known], (x, z): (usize, usize), lowest: usize) -> bool {
    let top = band.clipped_top;
    // `band.top` is the layer above `top` unless the box ends at `top`.
    if band.top == top
        || known[band.at(x, band.top, z)] != Known::Empty
        || !(band.floor + lowest..=top).all(|y| known[band.at(x, y, z)] == Known::Solid)
    {
        return false;
    }
    // A column at the box's side is not inside a face (the box is grown by a cell).
    if x == 0 || z == 0 || x + 1 == band.dims[0] || z + 1 == band.dims[2] {
        return false;
    }
    let solid = (x - 1..=x + 1)
        .flat_map(|a| (z - 1..=z + 1).map(move |b| (a, b)))
        .filter(|&(a, b)| (a, b) != (x, z) && known[band.at(a, top, b)] == Known::Solid)
        .count();
    solid >= 6
}

/// The second rule (module docs) on `inside`, the cut's result on a box of `dims` cells
/// whose layer `floor` is the platform's and the `clipped` layers above it lost their
/// readings. The object's foot is every column inside somewhere from the platform up to
/// `margin` cells (the carving margin) above the clipped band: the lowest triangles end
/// above the clip plane by up to a pixel row's height and the depth noise, and a wall that
/// slants steps in and out from layer to layer, so no one layer closes the outline. A flood
/// over the platform's layer around the foot starts from the box's border and from the
/// cells where the platform was seen (empty to `known`, or in front of or on some reading
/// by `seen`, further than `margin` from the foot: not the foot's own readings); each region
/// it does not reach, whose space above reaches a cell seen empty, is made inside (only
/// unknown cells, no view saw): its cell on the platform, and up through the band to the
/// first cell a view saw there if there is one. Returns how many cells.
pub(super) fn cover_footprints(
    dims: [usize; 3],
    inside: &mut [bool],
    known: &[Known],
    seen: &[Seen],
    (floor, clipped): (usize, usize),
    margin: f32,
) -> usize {
    let Some(band) = Band::new(dims, floor, clipped) else {
        return 0;
    };
    let [nx, _, nz] = dims;
    let foot_top = (band
        .clipped_top
        .saturating_add(margin.max(1.0).ceil() as usize))
    .min(dims[1] - 1);
    // (`margin` is at least one cell: the layer above the band.)
    let foot: Vec<bool> = (0..nx * nz)
        .map(|c| (floor..=foot_top).any(|y| inside[band.at(c % nx, y, c / nx)]))
        .collect();
    // The cells within the margin of the foot (L∞, whole cells): a reading there may be the
    // foot's own.
    let mut near_foot = BitBox::new([nx, 1, nz]);
    for (c, _) in foot.iter().enumerate().filter(|(_, f)| **f) {
        near_foot.set(c % nx, c / nx);
    }
    near_foot.dilate((margin.max(0.0).floor() as usize).min(nx.max(nz)));
    let platform_seen = |x: usize, z: usize| {
        let i = band.at(x, floor, z);
        (known[i] == Known::Empty || matches!(seen[i], Seen::Surface | Seen::Empty))
            && !near_foot.get(x, z)
    };
    let mut reached = vec![false; nx * nz];
    let seeds = (0..nx * nz).filter(|&c| {
        let (x, z) = (c % nx, c / nx);
        let border = x == 0 || z == 0 || x + 1 == nx || z + 1 == nz;
        !foot[c] && (border || platform_seen(x, z))
    });
    spread(seeds.collect(), &mut reached, &foot, nx, nz);
    // Each enclosed region, with the space over it that the cut left outside: covered if
    // that space reaches space seen empty (a passage from the platform into the object's
    // seen inside: a vessel without its bottom); a hollow under the object that no view
    // saw into stays as the cut left it (the underside of a figure standing on its rim).
    let mut covered = vec![false; nx * nz];
    let mut reach = None;
    for start in 0..nx * nz {
        if reached[start] || foot[start] {
            continue;
        }
        let region = spread(vec![start], &mut reached, &foot, nx, nz);
        let reach: &BitBox =
            reach.get_or_insert_with(|| reaching_seen_space(dims, inside, known, seen));
        let row = |c: usize| (c / nx) * dims[1] + floor;
        if region.iter().any(|&c| reach.get(c % nx, row(c))) {
            for &c in &region {
                covered[c] = true;
            }
        }
    }
    // The foot's own cells on the platform that the cut left outside, next to a covered
    // region, are covered with it (the bottom meets the foot).
    let next_to_covered = |c: usize| layer_neighbours(c, nx, nz).any(|n| covered[n] && !foot[n]);
    let mut count = 0;
    for z in 0..nz {
        for x in 0..nx {
            let c = z * nx + x;
            if !(covered[c] || (foot[c] && next_to_covered(c))) {
                continue;
            }
            // The platform's layer, and up through the band to a cell that a view saw
            // there (the cells in front of the object's floor, whose own readings the clip
            // removed): the floor is below it. Without one (no view saw into the cavity down
            // to the band), the least bottom: the platform's layer alone.
            let seen_at = band
                .column(x, z)
                .skip(1)
                .position(|i| !(inside[i] || known[i] == Known::Unknown && hidden(seen[i])))
                .map_or(1, |p| p + 1);
            for (k, i) in band.column(x, z).take(seen_at).enumerate() {
                let bottom = k == 0 || hidden(seen[i]);
                if !inside[i] && known[i] == Known::Unknown && bottom {
                    inside[i] = true;
                    count += 1;
                }
            }
        }
    }
    count
}

/// The cells of a box of `dims` cells that `inside` leaves outside (and `known` does not
/// exclude) connected to a cell that some view saw empty (`seen`: in front of a reading by
/// more than the carving margin; a cell only outside an observed surface does not count,
/// the back of a thin wall can touch it), along the mesher's Kuhn connectivity: one
/// row-at-a-time flood from the cells seen empty.
fn reaching_seen_space(
    dims: [usize; 3],
    inside: &[bool],
    known: &[Known],
    seen: &[Seen],
) -> BitBox {
    let nx = dims[0];
    let mut free = BitBox::new(dims);
    for r in 0..dims[1] * dims[2] {
        for x in 0..nx {
            let i = r * nx + x;
            if !inside[i] && known[i] != Known::Excluded {
                free.set(x, r);
            }
        }
    }
    let mut reached = BitBox::new(dims);
    let mut flood = Flood::new(&free);
    let mut seeds = vec![0u64; free.w];
    for r in 0..dims[1] * dims[2] {
        seeds.fill(0);
        for x in (0..nx).filter(|&x| seen[r * nx + x] == Seen::Empty) {
            seeds[x / 64] |= 1 << (x % 64);
        }
        if seeds.iter().any(|&w| w != 0) {
            flood.seed(&free, &mut reached, r, &seeds, &mut |_, _, _| {});
        }
    }
    flood.run(&free, &mut reached, &mut |_, _, _| {});
    reached
}

/// Whether no view saw the cell: it is behind every reading that covers it, or covered by
/// none.
fn hidden(seen: Seen) -> bool {
    matches!(seen, Seen::BehindSurface | Seen::Unseen)
}

/// The (up to four) cells that share an edge with cell `c` of an `nx` × `nz` layer.
pub(super) fn layer_neighbours(c: usize, nx: usize, nz: usize) -> impl Iterator<Item = usize> {
    let (x, z) = (c % nx, c / nx);
    [
        (x > 0).then(|| c - 1),
        (x + 1 < nx).then(|| c + 1),
        (z > 0).then(|| c - nx),
        (z + 1 < nz).then(|| c + nx),
    ]
    .into_iter()
    .flatten()
}

/// Marks in `reached` (an `nx` × `nz` layer) the cells 4-connected to `from` through cells
/// that are neither `wall` nor already reached, `from` included (each marked as reached);
/// returns them.
pub(super) fn spread(
    from: Vec<usize>,
    reached: &mut [bool],
    wall: &[bool],
    nx: usize,
    nz: usize,
) -> Vec<usize> {
    let mut out = from;
    for &c in &out {
        reached[c] = true;
    }
    let mut k = 0;
    while k < out.len() {
        for n in layer_neighbours(out[k], nx, nz) {
            if !reached[n] && !wall[n] {
                reached[n] = true;
                out.push(n);
            }
        }
        k += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const DIMS: [usize; 3] = [12, 8, 12];

    fn at(x: usize, y: usize, z: usize) -> usize {
        (z * DIMS[1] + y) * DIMS[0] + x
    }

    /// A box with a square ring of solid cells (`x, z` in 2..=9 on its border, every
    /// layer), unknown elsewhere, and no cell seen.
    fn ring() -> (Vec<Known>, Vec<Seen>) {
        let n = DIMS.iter().product();
        let mut known = vec![Known::Unknown; n];
        for y in 0..DIMS[1] {
            for a in 2..=9 {
                for (x, z) in [(a, 2), (a, 9), (2, a), (9, a)] {
                    known[at(x, y, z)] = Known::Solid;
                }
            }
        }
        (known, vec![Seen::Unseen; n])
    }

    /// The cells inside the ring (`x, z` in 3..=8) in layer `y`.
    fn within_ring(y: usize) -> impl Iterator<Item = usize> {
        (3..=8).flat_map(move |z| (3..=8).map(move |x| at(x, y, z)))
    }

    #[test]
    fn the_clipped_band_is_extended_to_the_floor() {
        let n = DIMS.iter().product();
        let mut known = vec![Known::Unknown; n];
        // A leg: solid from layer 2 up through the layer above the band (3 + 1): extended.
        for y in 2..DIMS[1] {
            known[at(1, y, 1)] = Known::Solid;
        }
        // A cell below it was seen empty: kept.
        for y in 2..DIMS[1] {
            known[at(4, y, 4)] = Known::Solid;
        }
        known[at(4, 0, 4)] = Known::Empty;
        // A lone cell in the band (noise beside a face, or a ledge): kept.
        known[at(7, 3, 2)] = Known::Solid;
        // Above the band: kept.
        for y in 5..DIMS[1] {
            known[at(7, y, 7)] = Known::Solid;
        }
        let before = known.iter().filter(|&&k| k == Known::Solid).count();
        extend_into_band(DIMS, &mut known, 0, 3);
        assert!((0..2).all(|y| known[at(1, y, 1)] == Known::Solid));
        assert!(known[at(4, 1, 4)] == Known::Unknown && known[at(4, 0, 4)] == Known::Empty);
        assert!((0..3).all(|y| known[at(7, y, 2)] == Known::Unknown));
        assert!((0..5).all(|y| known[at(7, y, 7)] == Known::Unknown));
        let solid = known.iter().filter(|&&k| k == Known::Solid).count();
        assert_eq!(solid, before + 2, "nothing else changed");
    }

    /// An object whose readings end in the highest clipped layer (a disc as thick as the
    /// band and a leaf): the columns under its seen top are extended where the top is a face
    /// (six of eight neighbours solid in that layer), not at its edge nor under a lone cell.
    #[test]
    fn a_top_in_the_highest_clipped_layer_is_extended_to_the_floor() {
        let n = DIMS.iter().product();
        let mut known = vec![Known::Unknown; n];
        for z in 0..DIMS[2] {
            for x in 0..DIMS[0] {
                known[at(x, 4, z)] = Known::Empty;
            }
        }
        for z in 3..=8 {
            for x in 3..=8 {
                known[at(x, 3, z)] = Known::Solid;
            }
        }
        known[at(10, 3, 10)] = Known::Solid;
        extend_into_band(DIMS, &mut known, 0, 3);
        for z in 3..=8 {
            for x in 3..=8 {
                let face = (4..=7).contains(&x) && (4..=7).contains(&z);
                for y in 0..3 {
                    assert_eq!(known[at(x, y, z)] == Known::Solid, face, "({x}, {y}, {z})");
                }
            }
        }
        assert!((0..3).all(|y| known[at(10, y, 10)] == Known::Unknown));
    }

    /// The inside of the ring on the floor (6 × 6 cells), after `cover_footprints` with the
    /// ring's inside seen as `floor_seen` and a cell seen empty above it or not.
    fn covered(floor_seen: Seen, seen_empty_above: bool) -> usize {
        let (mut known, mut seen) = ring();
        for i in within_ring(0) {
            seen[i] = floor_seen;
        }
        if seen_empty_above {
            seen[at(5, 6, 5)] = Seen::Empty;
            known[at(5, 6, 5)] = Known::Empty;
        }
        let mut inside: Vec<bool> = known.iter().map(|&k| k == Known::Solid).collect();
        let count = cover_footprints(DIMS, &mut inside, &known, &seen, (0, 3), 1.0);
        let on_floor = within_ring(0).filter(|&i| inside[i]).count();
        assert_eq!(on_floor, count, "only the floor's cells are covered");
        count
    }

    #[test]
    fn a_cavity_open_to_seen_space_gets_a_bottom() {
        assert_eq!(covered(Seen::Unseen, true), 36);
        assert_eq!(covered(Seen::BehindSurface, true), 36);
    }

    /// A bottom whose top the views saw in the band (the cells in front of it, layer 3):
    /// the hidden cells below it are covered, three layers.
    #[test]
    fn a_bottom_seen_in_the_band_reaches_up_to_it() {
        let (known, mut seen) = ring();
        for y in 0..DIMS[1] {
            let verdict = if y < 3 {
                Seen::BehindSurface
            } else {
                Seen::Surface
            };
            for i in within_ring(y) {
                seen[i] = verdict;
            }
        }
        seen[at(5, 6, 5)] = Seen::Empty;
        let mut inside: Vec<bool> = known.iter().map(|&k| k == Known::Solid).collect();
        assert_eq!(
            cover_footprints(DIMS, &mut inside, &known, &seen, (0, 3), 1.0),
            36 * 3
        );
        assert!((0..3).all(|y| within_ring(y).all(|i| inside[i])));
    }

    #[test]
    fn a_hollow_under_the_object_stays_open() {
        assert_eq!(covered(Seen::Unseen, false), 0);
    }

    #[test]
    fn a_platform_seen_through_the_object_stays_open() {
        assert_eq!(covered(Seen::Surface, true), 0);
    }

    /// A box of `dims` cells from `codes` (two bits of what is known, two of what was
    /// seen, per cell; cells below `floor` excluded).
    fn random_box(dims: [usize; 3], codes: &[u8], floor: usize) -> (Vec<Known>, Vec<Seen>) {
        let n = dims.iter().product();
        let (mut known, mut seen) = (vec![Known::Unknown; n], vec![Seen::Unseen; n]);
        for i in 0..n {
            let c = codes[i % codes.len()];
            known[i] = match c & 3 {
                0 if (i / dims[0]) % dims[1] >= floor => Known::Solid,
                1 if (i / dims[0]) % dims[1] >= floor => Known::Empty,
                _ if (i / dims[0]) % dims[1] < floor => Known::Excluded,
                _ => Known::Unknown,
            };
            seen[i] = match (c >> 2) & 3 {
                0 => Seen::Empty,
                1 => Seen::Surface,
                2 => Seen::BehindSurface,
                _ => Seen::Unseen,
            };
            if known[i] == Known::Empty {
                seen[i] = Seen::Empty;
            }
        }
        (known, seen)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Whatever the box holds: the band rule makes only unknown cells solid, in the
        /// clipped layers, each below a solid cell of its column in the band and above no cell
        /// seen empty.
        #[test]
        fn the_band_rule_fills_only_unknown_cells_under_a_solid_one(
            nx in 3usize..9, ny in 3usize..9, nz in 3usize..9,
            floor in 0usize..2, clipped in 0usize..4,
            codes in proptest::collection::vec(0u8..16, 64..256),
        ) {
            let dims = [nx, ny, nz];
            let (mut known, _) = random_box(dims, &codes, floor);
            let before = known.clone();
            extend_into_band(dims, &mut known, floor, clipped);
            let at = |x: usize, y: usize, z: usize| (z * ny + y) * nx + x;
            for (i, (&a, &b)) in before.iter().zip(&known).enumerate() {
                if a == b {
                    continue;
                }
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                proptest::prop_assert!(a == Known::Unknown && b == Known::Solid);
                proptest::prop_assert!(y >= floor && y < floor + clipped);
                proptest::prop_assert!((y + 1..=(floor + clipped).min(ny - 1))
                    .any(|u| before[at(x, u, z)] == Known::Solid));
                proptest::prop_assert!((floor..y).all(|u| before[at(x, u, z)] != Known::Empty));
            }
        }

        /// Whatever the box holds: the bottom rule makes only unknown cells inside, in the
        /// band, never a cell some view saw empty, and only hidden cells above the platform's
        /// layer; applied again, it finds nothing more to cover. (30 of the 64 cases cover
        /// something.)
        #[test]
        fn the_bottom_rule_covers_only_hidden_unknown_cells_once(
            nx in 3usize..9, ny in 3usize..9, nz in 3usize..9,
            floor in 0usize..2, clipped in 0usize..4, margin in 0.5f32..3.0,
            codes in proptest::collection::vec(0u8..16, 64..256),
            solid in proptest::collection::vec(proptest::bool::ANY, 64..256),
        ) {
            let dims = [nx, ny, nz];
            let (known, seen) = random_box(dims, &codes, floor);
            let mut inside: Vec<bool> = known
                .iter()
                .enumerate()
                .map(|(i, &k)| k == Known::Solid || (k == Known::Unknown && solid[i % solid.len()]))
                .collect();
            let before = inside.clone();
            let count = cover_footprints(dims, &mut inside, &known, &seen, (floor, clipped), margin);
            let changed: Vec<usize> = (0..inside.len()).filter(|&i| inside[i] != before[i]).collect();
            proptest::prop_assert_eq!(changed.len(), count);
            for &i in &changed {
                let y = (i / nx) % ny;
                proptest::prop_assert!(inside[i] && known[i] == Known::Unknown);
                proptest::prop_assert!(seen[i] != Seen::Empty || y == floor);
                proptest::prop_assert!(y >= floor && y <= floor + clipped + 1);
                proptest::prop_assert!(y == floor || hidden(seen[i]));
            }
            let again = cover_footprints(dims, &mut inside, &known, &seen, (floor, clipped), margin);
            proptest::prop_assert_eq!(again, 0);
        }
    }
}
