//! The leaf grid's geometry: the candidate cells of a box and the regions they fall in.

use glam::{UVec3, Vec3};

use crate::geometry::{GridSpec, Real};
use crate::intersection_test_aabb_triangle::TriangleSat;

/// Depth of the dense top level: the root is split into `8^SPLIT_DEPTH` regions, each
/// an independent sparse subtree (this is the unit of parallel insertion).
pub(super) const SPLIT_DEPTH: u32 = 3;

/// Geometry shared by all regions of one octree.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layout {
    /// The leaf grid.
    pub(super) grid: GridSpec,
    /// `depth - split`: leaf coordinate `>> region_shift` is the region coordinate.
    pub(super) region_shift: u32,
    /// Interior levels of a region's brick tree.
    pub(super) levels: u32,
    /// About `1 / grid.cell` (first guesses of cell indices only).
    pub(super) inv_cell: Real,
}

impl GridSpec {
    /// Plane `i` on axis `a`: the same value as `corner(..)[a]`.
    #[inline]
    pub(super) fn plane(&self, a: usize, i: u32) -> Real {
        self.origin[a] + i as Real * self.cell
    }
}

/// On one axis of a grid (planes `o + i * cell`, `i = 0..=res`), the cells `a..=b` whose
/// closed extent meets `[lo, hi]`; `None` when the interval misses the grid. `inv` is
/// about `1 / cell`: it only makes the first guesses, which the loops make exact.
#[inline(always)]
pub(super) fn cell_range_1d(
    o: Real,
    cell: Real,
    inv: Real,
    res: u32,
    lo: Real,
    hi: Real,
) -> Option<(u32, u32)> {
    // The same expression as `GridSpec::corner`, component-wise.
    let plane = |i: u32| o + i as Real * cell;
    // (NaN fails both comparisons.)
    if !(hi >= o && lo <= plane(res)) {
        return None;
    }
    let last = res - 1;
    // Truncating guesses (`as` saturates: negative and NaN give 0).
    let guess = |v: Real| (((v - o) * inv) as u32).min(last);
    // Each loop sits behind its first test so that the compiler does not turn it into
    // a vectorised search (which costs far more than the usual zero or one step).
    let mut a = guess(lo);
    if a < last && plane(a + 1) < lo {
        while a < last && plane(a + 1) < lo {
            a += 1;
        }
    } else if a > 0 && plane(a) >= lo {
        while a > 0 && plane(a) >= lo {
            a -= 1;
        }
    }
    let mut b = guess(hi);
    if b > 0 && plane(b) > hi {
        while b > 0 && plane(b) > hi {
            b -= 1;
        }
    } else if b < last && plane(b + 1) <= hi {
        while b < last && plane(b + 1) <= hi {
            b += 1;
        }
    }
    Some((a, b))
}

impl Layout {
    /// The leaf cells whose closed boxes meet the closed box `bmin..=bmax`, clamped to
    /// the grid; `None` when the box misses the root. Exactly the cells whose boxes
    /// pass the three box-normal axes of the overlap test.
    #[inline]
    pub(super) fn candidates_of_box(&self, bmin: Vec3, bmax: Vec3) -> Option<(UVec3, UVec3)> {
        let (g, inv) = (&self.grid, self.inv_cell);
        let (x0, x1) = cell_range_1d(g.origin.x, g.cell, inv, g.resolution, bmin.x, bmax.x)?;
        let (y0, y1) = cell_range_1d(g.origin.y, g.cell, inv, g.resolution, bmin.y, bmax.y)?;
        let (z0, z1) = cell_range_1d(g.origin.z, g.cell, inv, g.resolution, bmin.z, bmax.z)?;
        Some((UVec3::new(x0, y0, z0), UVec3::new(x1, y1, z1)))
    }

    #[inline]
    pub(super) fn candidates(&self, sat: &TriangleSat) -> Option<(UVec3, UVec3)> {
        self.candidates_of_box(sat.bmin, sat.bmax)
    }

    /// The regions (first and last region coordinates) that the candidate cells of
    /// the box `bmin..=bmax` (finite) may reach: a superset, from truncated guesses
    /// widened by two cells each way (they are within one cell of the exact ranges);
    /// `None` only when the box is surely outside the root.
    #[cfg(feature = "parallel")]
    #[inline]
    pub(super) fn regions_near(&self, bmin: Vec3, bmax: Vec3) -> Option<(UVec3, UVec3)> {
        let g = &self.grid;
        let last = i64::from(g.resolution - 1);
        let mut r = [(0u32, 0u32); 3];
        for (a, r) in r.iter_mut().enumerate() {
            // `as` saturates; the inputs are finite.
            let guess = |v: Real| ((v - g.origin[a]) * self.inv_cell) as i64;
            let (lo, hi) = (guess(bmin[a]) - 2, guess(bmax[a]) + 2);
            if hi < 0 || lo > last {
                return None;
            }
            *r = (
                (lo.max(0) as u32) >> self.region_shift,
                (hi.min(last) as u32) >> self.region_shift,
            );
        }
        Some((
            UVec3::new(r[0].0, r[1].0, r[2].0),
            UVec3::new(r[0].1, r[1].1, r[2].1),
        ))
    }

    /// First and last leaf coordinates of region `rc`.
    #[inline]
    pub(super) fn region_span(&self, rc: UVec3) -> (UVec3, UVec3) {
        let base = rc << self.region_shift;
        (base, base + UVec3::splat((1 << self.region_shift) - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Octree;
    #[test]
    fn candidate_range_is_closed() {
        let t = Octree::new(Vec3::ZERO, 1.0, 0.25).unwrap();
        let lay = t.layout;
        // A box touching the plane x = 0.5 from below reaches cell 2 too.
        let (lo, hi) = lay
            .candidates_of_box(Vec3::new(0.3, 0.1, 0.1), Vec3::new(0.5, 0.1, 0.1))
            .unwrap();
        assert_eq!((lo.x, hi.x), (1, 2));
        assert_eq!((lo.y, hi.y), (0, 0));
        assert!(
            lay.candidates_of_box(Vec3::splat(1.01), Vec3::splat(2.0))
                .is_none()
        );
        let (lo, hi) = lay
            .candidates_of_box(Vec3::splat(-5.0), Vec3::splat(5.0))
            .unwrap();
        assert_eq!((lo, hi), (UVec3::ZERO, UVec3::splat(3)));
    }
}
